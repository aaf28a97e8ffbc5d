//! Host-shareable layouts: every struct shared between Rust and WGSL has the same span,
//! alignment, member offsets and member sizes on both sides, WGSL's taken from naga's layouter
//! (after wgsl_to_wgpu). No GPU needed.
#![cfg(feature = "gpu")]
use shadow_map_core::gpu::{
    midpoint::MidpointParams,
    mssm::MinMaxParams,
    raster::RasterParams,
    shared::{LightViewUniform, ReceiverGpu},
    SHADERS,
};
use std::mem::{align_of, offset_of, size_of};

/// naga's view of one struct: (span, alignment, [(member, offset, size)]).
type WgslStruct = (u32, u32, Vec<(String, u32, u32)>);

fn wgsl_struct(shader: &str, name: &str) -> WgslStruct {
    let src = SHADERS
        .iter()
        .find(|(n, _)| *n == shader)
        .unwrap_or_else(|| panic!("no shader {shader}"))
        .1;
    let module = naga::front::wgsl::parse_str(src)
        .unwrap_or_else(|e| panic!("{shader}: {}", e.emit_to_string(src)));
    let mut layouter = naga::proc::Layouter::default();
    layouter.update(module.to_ctx()).expect("layouter");
    let (handle, ty) = module
        .types
        .iter()
        .find(|(_, t)| t.name.as_deref() == Some(name))
        .unwrap_or_else(|| panic!("{shader}: no struct {name}"));
    let naga::TypeInner::Struct { members, span } = &ty.inner else {
        panic!("{name} is not a struct");
    };
    let layout = layouter[handle];
    assert_eq!(layout.size, *span);
    // Alignment as a number: the smallest multiple of it that is >= 1.
    let align = layout.alignment.round_up(1);
    let members = members
        .iter()
        .map(|m| {
            (
                m.name.clone().unwrap_or_default(),
                m.offset,
                layouter[m.ty].size,
            )
        })
        .collect();
    (*span, align, members)
}

/// Asserts that `$rust` mirrors WGSL struct `$wgsl` of shader `$shader`, member by member
/// (`wgsl_name => rust_field`, in declaration order).
macro_rules! check_layout {
    ($shader:literal, $wgsl:literal, $rust:ty, [$($wname:literal => $field:ident),* $(,)?]) => {{
        let (span, align, members) = wgsl_struct($shader, $wgsl);
        assert_eq!(span as usize, size_of::<$rust>(), "{}: span", $wgsl);
        assert_eq!(align as usize, align_of::<$rust>(), "{}: alignment", $wgsl);
        let zero: $rust = bytemuck::Zeroable::zeroed();
        let rust: Vec<(&str, usize, usize)> = vec![
            $(($wname, offset_of!($rust, $field), std::mem::size_of_val(&zero.$field))),*
        ];
        assert_eq!(members.len(), rust.len(), "{}: member count", $wgsl);
        for ((wname, woff, wsize), (rname, roff, rsize)) in members.iter().zip(&rust) {
            assert_eq!(wname, rname, "{}: member order", $wgsl);
            assert_eq!(*woff as usize, *roff, "{}.{}: offset", $wgsl, wname);
            assert_eq!(*wsize as usize, *rsize, "{}.{}: size", $wgsl, wname);
        }
    }};
}

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
