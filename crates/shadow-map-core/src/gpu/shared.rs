//! Data shared by the CPU and GPU backends, defined once as `#[repr(C)]` bytemuck structs and
//! mirrored field for field (same names) in `shared.wgsl`. `tests/layouts.rs` checks the WGSL
//! layout with naga against `size_of`/`offset_of!`.
use crate::{light_view::LightView, receivers::Receivers};
use bytemuck::{Pod, Zeroable};

/// WGSL source of the shared structs; prepend it to every shader that uses them.
pub const SHARED_WGSL: &str = include_str!("shared.wgsl");

/// V bits of a receiver whose kernel ran out of the device's loop budget (`loop_limit_hit` in
/// [`SHARED_WGSL`]: llvmpipe ends every loop once 65535 iterations in all have run); a NaN payload
/// no kernel writes otherwise. See [`redo_cut_receivers`](super::redo_cut_receivers).
pub const CUT_BITS: u32 = 0x7fc0_dead;

/// The uniform bound of `loop_limit_hit`'s two-trip probe loop (a uniform, so no compiler can
/// fold the loop away).
pub const LOOP_PROBE: u32 = 2;

/// The light view as shaders see it (see [`LightView`] for the meaning of every field).
///
/// Aligned to 16 bytes like its WGSL twin (whose `vec3<f32>` members align it to 16), so
/// `align_of` equals naga's alignment (`tests/layouts.rs`).
#[repr(C, align(16))]
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable)]
pub struct LightViewUniform {
    /// Centre of projection (world).
    pub origin: [f32; 3],
    /// Near plane and shadow-map plane distance.
    pub n: f32,
    /// Light-space x axis (world).
    pub ex: [f32; 3],
    /// Window side on the plane z = n.
    pub w: f32,
    /// Light-space y axis (world).
    pub ey: [f32; 3],
    /// Far plane.
    pub far: f32,
    /// Light-space z axis (world), the light normal.
    pub ez: [f32; 3],
    /// Resolution (texels per side).
    pub r: u32,
    /// Window corner on the plane z = n.
    pub window_min: [f32; 2],
    /// Texel pitch `w / r` (precomputed exactly as the CPU computes it).
    pub delta: f32,
    /// Padding.
    pub _pad0: f32,
}

impl From<&LightView> for LightViewUniform {
    fn from(v: &LightView) -> Self {
        LightViewUniform {
            origin: v.frame.origin.to_array(),
            n: v.n,
            ex: v.frame.ex.to_array(),
            w: v.w,
            ey: v.frame.ey.to_array(),
            far: v.far,
            ez: v.frame.ez.to_array(),
            r: v.r,
            window_min: v.window_min.to_array(),
            delta: v.delta(),
            _pad0: 0.0,
        }
    }
}

/// One receiver as shaders see it (32 bytes, aligned to 16 like its WGSL twin).
#[repr(C, align(16))]
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable)]
pub struct ReceiverGpu {
    /// World position.
    pub position: [f32; 3],
    /// 1 for an active receiver, 0 for a background slot (V = NaN).
    pub active: u32,
    /// Unit normal (world).
    pub normal: [f32; 3],
    /// Padding.
    pub _pad0: f32,
}

/// Packs receivers for upload.
pub fn pack_receivers(r: &Receivers) -> Vec<ReceiverGpu> {
    (0..r.len())
        .map(|k| ReceiverGpu {
            position: r.position[k].to_array(),
            active: r.active[k] as u32,
            normal: r.normal[k].to_array(),
            _pad0: 0.0,
        })
        .collect()
}
