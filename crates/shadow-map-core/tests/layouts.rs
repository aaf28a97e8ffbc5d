//! Host-shareable layouts: every struct shared between Rust and WGSL has the same span,
//! alignment, member offsets and member sizes on both sides, WGSL's taken from naga's layouter
//! (after wgsl_to_wgpu). No GPU needed.
#![cfg(feature = "gpu")]
use shadow_map_core::gpu::{
    midpoint::MidpointParams,
    mssm::MinMaxParams,
    raster::RasterParams,
    shared::{LightViewUniform, ReceiverGpu},
};

mod common;
use common::check_layout;

#[test]
fn light_view_uniform_matches_wgsl() {
    check_layout!("shared", "LightViewUniform", LightViewUniform, [
        "origin" => origin, "n" => n, "ex" => ex, "w" => w, "ey" => ey, "far" => far,
        "ez" => ez, "r" => r, "window_min" => window_min, "delta" => delta, "_pad0" => _pad0,
    ]);
}

#[test]
fn receiver_gpu_matches_wgsl() {
    // `active` is a WGSL reserved word: the WGSL member is `is_active`.
    check_layout!("shared", "ReceiverGpu", ReceiverGpu, [
        "position" => position, "is_active" => active, "normal" => normal, "_pad0" => _pad0,
    ]);
}

#[test]
fn raster_params_match_wgsl() {
    check_layout!("raster", "RasterParams", RasterParams, [
        "bias_constant" => bias_constant, "bias_slope" => bias_slope,
        "_pad0" => _pad0, "_pad1" => _pad1,
    ]);
}

#[test]
fn midpoint_params_match_wgsl() {
    check_layout!("midpoint", "MidpointParams", MidpointParams, [
        "size" => size, "max_bias" => max_bias, "_pad0" => _pad0, "_pad1" => _pad1,
    ]);
}

#[test]
fn minmax_params_match_wgsl() {
    check_layout!("mssm", "MinMaxParams", MinMaxParams, [
        "size" => size, "out_size" => out_size, "h" => h, "row0" => row0, "rows" => rows,
        "top_base" => top_base, "bot_base" => bot_base, "out_base" => out_base,
        "empty_depth" => empty_depth, "_pad0" => _pad0, "_pad1" => _pad1, "_pad2" => _pad2,
    ]);
}
