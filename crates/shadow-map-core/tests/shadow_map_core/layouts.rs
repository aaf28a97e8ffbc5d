//! Host-shareable layouts: every struct shared between Rust and WGSL has the same span,
//! alignment, member offsets and member sizes on both sides, WGSL's taken from naga's layouter
//! (after wgsl_to_wgpu). No GPU needed.
#![cfg(feature = "gpu")]
use glam::Vec3;
use shadow_map_core::{
    gpu::{
        midpoint::MidpointParams,
        mssm::MinMaxParams,
        raster::RasterParams,
        settle::SettleUniform,
        shared::{FrameGpu, LightViewUniform, ReceiverGpu},
    },
    LightFrame,
};

use crate::common;
use common::check_layout;

#[test]
fn light_view_uniform_matches_wgsl() {
    check_layout!(
        "shared",
        "LightViewUniform",
        LightViewUniform,
        [frame, n, w, far, r, window_min, delta, ortho,]
    );
}

#[test]
fn frame_gpu_matches_wgsl() {
    // The WGSL `Frame` has no padding members: WGSL pads each vec3 to 16 bytes implicitly, where
    // the Rust `FrameGpu` spells it out (`_pad0`..`_pad3`, covered by the span check).
    check_layout!("shared", "Frame", FrameGpu, [origin, ex, ey, ez]);
}

#[test]
fn frame_gpu_holds_the_frame() {
    let f = LightFrame {
        origin: Vec3::new(1.0, 2.0, 3.0),
        ex: Vec3::X,
        ey: Vec3::Y,
        ez: Vec3::Z,
    };
    let g = FrameGpu::from(&f);
    assert_eq!(g, FrameGpu::new(f.origin, f.ex, f.ey, f.ez));
    let words: &[f32] = bytemuck::cast_slice(std::slice::from_ref(&g));
    assert_eq!(
        words,
        &[1.0, 2.0, 3.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0]
    );
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
        "min_opacity" => min_opacity, "_pad1" => _pad1,
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

#[test]
fn settle_uniform_matches_wgsl() {
    check_layout!(
        "settle",
        "SettleUniform",
        SettleUniform,
        [triangles, rows, unsettled_word, _pad,]
    );
}
