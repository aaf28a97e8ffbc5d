//! Data shared by the CPU and GPU backends, defined once as `#[repr(C)]` bytemuck structs and
//! mirrored field for field (same names) in `shared.wgsl`. `tests/layouts.rs` checks the WGSL
//! layout with naga against `size_of`/`offset_of!`.
use crate::{light::LightFrame, light_view::LightView, receivers::Receivers};
use bytemuck::{Pod, Zeroable};
use glam::Vec3;

/// WGSL source of the shared structs; prepend it to every shader that uses them.
pub const SHARED_WGSL: &str = include_str!("shared.wgsl");

/// V bits of a receiver whose kernel ran out of the device's loop budget (`loop_limit_hit` in
/// [`SHARED_WGSL`]: llvmpipe ends every loop once 65535 iterations in all have run); a NaN payload
/// no kernel writes otherwise. See [`redo_cut_receivers`](super::redo_cut_receivers).
pub const CUT_BITS: u32 = 0x7fc0_dead;

/// The uniform bound of `loop_limit_hit`'s two-trip probe loop (a uniform, so no compiler can
/// fold the loop away).
pub const LOOP_PROBE: u32 = 2;

/// An orthonormal frame as shaders see it: an origin and three unit axes (world), each padded to
/// 16 bytes like WGSL's `vec3<f32>`. Mirrors `Frame` in [`SHARED_WGSL`], whose members are the
/// four vectors only (the `_pad` fields are WGSL's implicit `vec3` padding); the light view
/// ([`LightViewUniform::frame`]), the estimate kernels' light
/// ([`EstimateUniform::light_frame`](super::estimate::EstimateUniform::light_frame)) and the
/// G-buffer camera ([`GBufferCamera::frame`](super::gbuffer::GBufferCamera::frame)) hold one.
#[repr(C, align(16))]
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable)]
pub struct FrameGpu {
    /// The origin.
    pub origin: [f32; 3],
    /// Padding.
    pub _pad0: f32,
    /// First axis.
    pub ex: [f32; 3],
    /// Padding.
    pub _pad1: f32,
    /// Second axis.
    pub ey: [f32; 3],
    /// Padding.
    pub _pad2: f32,
    /// Third axis.
    pub ez: [f32; 3],
    /// Padding.
    pub _pad3: f32,
}

impl FrameGpu {
    /// The frame at `origin` with axes `ex`, `ey`, `ez` (taken as given: nothing is normalised).
    pub fn new(origin: Vec3, ex: Vec3, ey: Vec3, ez: Vec3) -> Self {
        FrameGpu {
            origin: origin.to_array(),
            _pad0: 0.0,
            ex: ex.to_array(),
            _pad1: 0.0,
            ey: ey.to_array(),
            _pad2: 0.0,
            ez: ez.to_array(),
            _pad3: 0.0,
        }
    }
}

impl From<&LightFrame> for FrameGpu {
    fn from(f: &LightFrame) -> Self {
        FrameGpu::new(f.origin, f.ex, f.ey, f.ez)
    }
}

/// The light view as shaders see it (see [`LightView`] for the meaning of every field).
///
/// Aligned to 16 bytes like its WGSL twin (whose [`FrameGpu`] member aligns it to 16), so
/// `align_of` equals naga's alignment (`tests/layouts.rs`).
#[repr(C, align(16))]
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable)]
pub struct LightViewUniform {
    /// The light-space frame: origin at the centre of projection, `ez` the light normal.
    pub frame: FrameGpu,
    /// Near plane and shadow-map plane distance.
    pub n: f32,
    /// Window side on the plane z = n.
    pub w: f32,
    /// Far plane.
    pub far: f32,
    /// Resolution (texels per side).
    pub r: u32,
    /// Window corner on the plane z = n.
    pub window_min: [f32; 2],
    /// Texel pitch `w / r` (precomputed exactly as the CPU computes it).
    pub delta: f32,
    /// 1 for an orthographic view (the sun, [`crate::light_view::Projection`]), else 0.
    pub ortho: u32,
}

impl From<&LightView> for LightViewUniform {
    fn from(v: &LightView) -> Self {
        LightViewUniform {
            frame: FrameGpu::from(&v.frame),
            n: v.n,
            w: v.w,
            far: v.far,
            r: v.r,
            window_min: v.window_min.to_array(),
            delta: v.delta(),
            ortho: u32::from(v.is_ortho()),
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
            position: r.position()[k].to_array(),
            active: r.active()[k] as u32,
            normal: r.normal()[k].to_array(),
            _pad0: 0.0,
        })
        .collect()
}
