//! What every per-receiver estimate kernel reads besides [`LightViewUniform`] and
//! [`ReceiverGpu`]: the light and the receiver-bias settings as one `#[repr(C)]` bytemuck struct,
//! [`EstimateUniform`], mirrored field for field (same names) in `estimate.wgsl`; the light-shape
//! codes and the workgroup size, which reach WGSL as pipeline `override` constants (never copied
//! by hand); and `math.wgsl`, the f32 twins of the light geometry and of
//! [`LightView::receiver_bias`](crate::LightView::receiver_bias) that the kernels include.
//!
//! [`LightViewUniform`]: super::shared::LightViewUniform
//! [`ReceiverGpu`]: super::shared::ReceiverGpu
use super::shared::FrameGpu;
use crate::{Light, LightShape};
use bytemuck::{Pod, Zeroable};

// The estimate heads as literals, so that `concat!` can extend them into longer constants
// (`concat!` takes literals only, not constants): the light head (shared structs, estimate
// uniform, math) and the estimate head (the light head, disk-edge, silhouette, overlap).
macro_rules! light_head_wgsl {
    () => {
        concat!(
            include_str!("shared.wgsl"),
            include_str!("estimate.wgsl"),
            include_str!("math.wgsl")
        )
    };
}
macro_rules! estimate_head_wgsl {
    () => {
        concat!(
            light_head_wgsl!(),
            include_str!("disk_edge.wgsl"),
            include_str!("silhouette.wgsl"),
            include_str!("overlap.wgsl")
        )
    };
}

/// The core's shared structs, [`ESTIMATE_WGSL`] and [`MATH_WGSL`], in that order: the start of
/// [`ESTIMATE_HEAD_WGSL`], and of kernels that take the light math without the overlap helpers.
pub const LIGHT_HEAD_WGSL: &str = light_head_wgsl!();

/// WGSL source of [`EstimateUniform`] and the override constants; prepended (after the core's
/// `SHARED_WGSL`) to every estimate kernel.
pub const ESTIMATE_WGSL: &str = include_str!("estimate.wgsl");
/// WGSL twins of the core's light helpers and of the receiver bias, in the CPU's operation order
/// (after [`ESTIMATE_WGSL`]).
pub const MATH_WGSL: &str = include_str!("math.wgsl");
/// WGSL twins of [`crate::overlap::disk_wedge`] and [`crate::overlap::edge_disk_area`],
/// self-contained (builtins only): kernels without the estimate head prepend it alone.
pub const DISK_EDGE_WGSL: &str = include_str!("disk_edge.wgsl");
/// WGSL twins of [`crate::soft_transmittance::cells`] (`Cells`, `cells_new`, `cell`) and of
/// [`crate::soft_transmittance::Kahan`] (`Sum`, `sum_add`): no bindings, so any kernel may include
/// it (the baselines' map estimator, deep-shadow's `filter=pcss`).
pub const CELLS_WGSL: &str = include_str!("cells.wgsl");
/// WGSL twin of [`crate::silhouette::Silhouette::carry`], self-contained like
/// [`DISK_EDGE_WGSL`].
pub const SILHOUETTE_WGSL: &str = include_str!("silhouette.wgsl");
/// WGSL twin of [`crate::silhouette::Silhouette::new`] and its hull (the per-receiver set-up of a
/// sphere light's silhouette disk), after [`MATH_WGSL`] and [`SILHOUETTE_WGSL`]; not in
/// [`ESTIMATE_HEAD_WGSL`]: kernels with sphere lights (backprojection, packet-hsm's frame set-up)
/// append it.
pub const SILHOUETTE_SETUP_WGSL: &str = include_str!("silhouette_setup.wgsl");
/// [`SILHOUETTE_SETUP_WGSL`] after the estimate head, as [`super::SHADERS`] validates it.
pub const SILHOUETTE_SETUP_CHECK_WGSL: &str =
    concat!(estimate_head_wgsl!(), include_str!("silhouette_setup.wgsl"));
/// WGSL twins of the rest of [`crate::overlap`] (after [`MATH_WGSL`] and [`DISK_EDGE_WGSL`]).
pub const OVERLAP_WGSL: &str = include_str!("overlap.wgsl");
/// WGSL twin of [`crate::bitmask`] (containment tests and the mask), self-contained; not in
/// [`ESTIMATE_HEAD_WGSL`]: kernels with occlusion bits append it.
pub const BITMASK_WGSL: &str = include_str!("bitmask.wgsl");
/// The head of every estimate kernel: the core's shared structs, [`ESTIMATE_WGSL`],
/// [`MATH_WGSL`], [`DISK_EDGE_WGSL`], [`SILHOUETTE_WGSL`] and [`OVERLAP_WGSL`], in that order; a
/// kernel appends its own WGSL.
pub const ESTIMATE_HEAD_WGSL: &str = estimate_head_wgsl!();

/// `light_shape` of a rect light (WGSL override `LIGHT_RECT`).
pub const LIGHT_RECT: u32 = 0;
/// `light_shape` of a disk light (WGSL override `LIGHT_DISK`).
pub const LIGHT_DISK: u32 = 1;
/// `light_shape` of a sphere light (WGSL override `LIGHT_SPHERE`).
pub const LIGHT_SPHERE: u32 = 2;
/// `light_shape` of a directional light, the sun (WGSL override `LIGHT_DIRECTIONAL`); its sizes
/// are `tan(angle / 2)`, the radius of its disk of directions at unit distance.
pub const LIGHT_DIRECTIONAL: u32 = 3;

/// Threads per workgroup of every per-receiver estimate kernel (WGSL override `WG`).
pub const WORKGROUP_SIZE: u32 = 64;

/// The pipeline-overridable constants [`ESTIMATE_WGSL`] declares, as wgpu wants them.
pub const OVERRIDES: &[(&str, f64)] = &[
    ("WG", WORKGROUP_SIZE as f64),
    ("LIGHT_RECT", LIGHT_RECT as f64),
    ("LIGHT_DISK", LIGHT_DISK as f64),
    ("LIGHT_SPHERE", LIGHT_SPHERE as f64),
    ("LIGHT_DIRECTIONAL", LIGHT_DIRECTIONAL as f64),
    ("PLANE_ROUNDING", crate::receiver_plane::ROUNDING as f64),
    ("PLANE_SNAP", crate::receiver_plane::SNAP as f64),
];

/// The light and the estimator's settings as the estimate kernels see them.
///
/// The light frame is `Light::frame()` as the CPU computes it (origin the light centre C,
/// `ey = ez x ex` in glam), so the shaders never rebuild it.
#[repr(C, align(16))]
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable)]
pub struct EstimateUniform {
    /// `Light::frame()`: origin the light centre C (world), `ex` the tangent, `ey = ez x ex`,
    /// `ez` the light normal.
    pub light_frame: FrameGpu,
    /// [`LIGHT_RECT`], [`LIGHT_DISK`], [`LIGHT_SPHERE`] or [`LIGHT_DIRECTIONAL`].
    pub light_shape: u32,
    /// Rect: width `size[0]`; disk and sphere: the radius.
    pub light_size_x: f32,
    /// Rect: height `size[1]`; disk and sphere: the radius.
    pub light_size_y: f32,
    /// 1 for one-sided emitters (rect, disk), 0 for a sphere.
    pub light_one_sided: u32,
    /// `Light::half_extent()`: `(l_x / 2, l_y / 2)`.
    pub light_half_extent: [f32; 2],
    /// Constant receiver bias `b0` in texel footprints ([`LightView::receiver_bias`](crate::LightView::receiver_bias)).
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
    /// [`LOOP_PROBE`](super::shared::LOOP_PROBE).
    pub probe: u32,
    /// 1: receiver-plane rejection ([`crate::receiver_plane`], `plane_new` in `math.wgsl`);
    /// 0: the classic depth test against `z - receiver_bias`.
    pub receiver_plane: u32,
    /// Padding.
    pub _pad: [u32; 2],
}

impl EstimateUniform {
    /// The light and the receiver-bias settings; filter fields zero.
    pub fn new(light: &Light, bias: f32, slope_bias: f32) -> Self {
        let (shape, sx, sy) = match light.shape {
            LightShape::Rect { size } => (LIGHT_RECT, size[0], size[1]),
            LightShape::Disk { radius } => (LIGHT_DISK, radius, radius),
            LightShape::Sphere { radius } => (LIGHT_SPHERE, radius, radius),
            LightShape::Directional { .. } => {
                let t = light.shape.tan_half();
                (LIGHT_DIRECTIONAL, t, t)
            }
        };
        EstimateUniform {
            light_frame: FrameGpu::from(&light.frame()),
            light_shape: shape,
            light_size_x: sx,
            light_size_y: sy,
            light_one_sided: u32::from(light.one_sided()),
            light_half_extent: light.half_extent().to_array(),
            bias,
            slope_bias,
            kernel_half: 0,
            max_taps: 0,
            inv_samples: 0.0,
            depth_step: 0.0,
            probe: super::shared::LOOP_PROBE,
            receiver_plane: 0,
            _pad: [0; 2],
        }
    }

    /// The override constant `LIGHT_SHAPE` (`estimate.wgsl`) for this uniform's light: a switch
    /// every pipeline of a module with the estimate head sets
    /// ([`SpecializedKernel`](super::kernel::SpecializedKernel)).
    pub fn shape_switch(&self) -> (&'static str, f64) {
        ("LIGHT_SHAPE", self.light_shape as f64)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn estimate_uniform_layout_matches_wgsl() {
        test_support::assert_wgsl_layout!(
            [super::super::shared::SHARED_WGSL, ESTIMATE_WGSL].concat(),
            EstimateUniform {
                light_frame,
                light_shape,
                light_size_x,
                light_size_y,
                light_one_sided,
                light_half_extent,
                bias,
                slope_bias,
                kernel_half,
                max_taps,
                inv_samples,
                depth_step,
                probe,
                receiver_plane,
            },
            pad _pad: 2
        );
        assert_eq!(std::mem::align_of::<EstimateUniform>(), 16);
    }

    #[test]
    fn head_is_the_parts_in_order() {
        let parts = [
            super::super::shared::SHARED_WGSL,
            ESTIMATE_WGSL,
            MATH_WGSL,
            DISK_EDGE_WGSL,
            SILHOUETTE_WGSL,
            OVERLAP_WGSL,
        ]
        .concat();
        assert_eq!(parts, ESTIMATE_HEAD_WGSL);
    }
}
