//! Data the baselines' shaders read besides the core's [`LightViewUniform`] and [`ReceiverGpu`]:
//! one `#[repr(C)]` bytemuck struct, mirrored field for field (same names) in `shared.wgsl`, and
//! the light-shape codes, which reach WGSL as pipeline `override` constants (never copied by hand).
//!
//! [`LightViewUniform`]: shadow_map_core::gpu::shared::LightViewUniform
//! [`ReceiverGpu`]: shadow_map_core::gpu::shared::ReceiverGpu
use bytemuck::{Pod, Zeroable};
use shadow_map_core::{Light, LightShape};

/// WGSL source of [`EstimateUniform`] and the shape-code overrides; prepended (after the core's
/// `SHARED_WGSL`) to every baseline shader.
pub const SHARED_WGSL: &str = include_str!("shared.wgsl");

/// `light_shape` of a rect light (WGSL override `LIGHT_RECT`).
pub const LIGHT_RECT: u32 = 0;
/// `light_shape` of a disk light (WGSL override `LIGHT_DISK`).
pub const LIGHT_DISK: u32 = 1;
/// `light_shape` of a sphere light (WGSL override `LIGHT_SPHERE`).
pub const LIGHT_SPHERE: u32 = 2;

/// Threads per workgroup of every baseline kernel (WGSL override `WG`).
pub const WORKGROUP_SIZE: u32 = 64;

/// The pipeline-overridable constants every baseline shader declares, as wgpu wants them.
pub const OVERRIDES: &[(&str, f64)] = &[
    ("WG", WORKGROUP_SIZE as f64),
    ("LIGHT_RECT", LIGHT_RECT as f64),
    ("LIGHT_DISK", LIGHT_DISK as f64),
    ("LIGHT_SPHERE", LIGHT_SPHERE as f64),
];

/// The light and the estimator's settings as the baseline shaders see them.
///
/// The light frame is `Light::frame()` as the CPU computes it (`ey = ez x ex` in glam), so the
/// shaders never rebuild it.
#[repr(C, align(16))]
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable)]
pub struct EstimateUniform {
    /// The light centre C (world).
    pub light_center: [f32; 3],
    /// [`LIGHT_RECT`], [`LIGHT_DISK`] or [`LIGHT_SPHERE`].
    pub light_shape: u32,
    /// Light frame `e_x` (the tangent).
    pub light_ex: [f32; 3],
    /// Rect: width `size[0]`; disk and sphere: the radius.
    pub light_size_x: f32,
    /// Light frame `e_y = e_z x e_x`.
    pub light_ey: [f32; 3],
    /// Rect: height `size[1]`; disk and sphere: the radius.
    pub light_size_y: f32,
    /// Light frame `e_z` (the light normal).
    pub light_ez: [f32; 3],
    /// 1 for one-sided emitters (rect, disk), 0 for a sphere.
    pub light_one_sided: u32,
    /// `Light::half_extent()`: `(l_x / 2, l_y / 2)`.
    pub light_half_extent: [f32; 2],
    /// Constant receiver bias `b0` in texel footprints (`common::receiver_bias`).
    pub bias: f32,
    /// Slope-scaled receiver bias `b1` in texel footprints.
    pub slope_bias: f32,
    /// PCF: half the block side (`Pcf::half`); unused elsewhere.
    pub kernel_half: i32,
    /// PCSS: most samples per side (`Pcss::max_taps`); unused elsewhere.
    pub max_taps: u32,
    /// Multi-sample: `1 / N` over the N sub-lights; unused elsewhere.
    pub inv_samples: f32,
    /// The 16-bit map's code step s under `depth=unorm16` (decode `n + q s`, bias `+ s / 2`);
    /// 0 for f32 maps.
    pub depth_step: f32,
    /// The loop-limit probe's bound, always
    /// [`LOOP_PROBE`](shadow_map_core::gpu::shared::LOOP_PROBE).
    pub probe: u32,
    /// Padding.
    pub _pad: [u32; 3],
}

impl EstimateUniform {
    /// The light and the receiver-bias settings; filter fields zero.
    pub fn new(light: &Light, bias: f32, slope_bias: f32) -> Self {
        let f = light.frame();
        let (shape, sx, sy) = match light.shape {
            LightShape::Rect { size } => (LIGHT_RECT, size[0], size[1]),
            LightShape::Disk { radius } => (LIGHT_DISK, radius, radius),
            LightShape::Sphere { radius } => (LIGHT_SPHERE, radius, radius),
        };
        EstimateUniform {
            light_center: light.center.to_array(),
            light_shape: shape,
            light_ex: f.ex.to_array(),
            light_size_x: sx,
            light_ey: f.ey.to_array(),
            light_size_y: sy,
            light_ez: f.ez.to_array(),
            light_one_sided: u32::from(light.one_sided()),
            light_half_extent: light.half_extent().to_array(),
            bias,
            slope_bias,
            kernel_half: 0,
            max_taps: 0,
            inv_samples: 0.0,
            depth_step: 0.0,
            probe: shadow_map_core::gpu::shared::LOOP_PROBE,
            _pad: [0; 3],
        }
    }
}
