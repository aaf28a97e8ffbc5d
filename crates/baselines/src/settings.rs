//! The settings both twins read: the table every baseline shares ([`MapSettings`]), the own
//! parameters of hard shadows ([`Hard`], none), PCF ([`Pcf`]), PCSS ([`Pcss`]) and multi-sample
//! ([`MultiSampleParams`]), and multi-sample's name, description and full table
//! ([`MultiSampleSettings`]; the others' are their [`Filter`](crate::cpu::Filter) identity).
//! The choice words (`cull`, `depth`) are the core's enums ([`Cull`], [`DepthPrecision`]).
use crate::math;
use shadow_map_core::{
    light_space::LightSpaceRequest, light_view::ViewOptions, precision::DEPTH,
    receiver_plane::RECEIVER_PLANE, Cull, DepthBias, DepthPrecision, ParamSpec, RasterOptions,
};

pub use shadow_map_core::light_view::{BIAS, RESOLUTION, SLOPE_BIAS};

/// `cull`: face culling while rasterising the shadow map.
pub const CULL: ParamSpec = ParamSpec::choice(Cull::WORDS, "none").named(
    "cull",
    "face culling in the shadow-map pass (winding-based, as seen from the light)",
);

shadow_map_core::typed_params! {
    /// The parameters every baseline shares, the head of each baseline's table (its own follow,
    /// see [`shadow_map_core::concat_specs!`]).
    pub struct MapSettings {
        /// Shadow-map resolution r (texels per side).
        resolution: u32 = RESOLUTION,
        /// Constant receiver bias b0, in texel footprints.
        bias: f32 = BIAS,
        /// Slope-scaled receiver bias b1, in texel footprints.
        slope_bias: f32 = SLOPE_BIAS,
        /// Receiver-plane rejection ([`shadow_map_core::receiver_plane`]).
        receiver_plane: bool = RECEIVER_PLANE,
        /// Face culling in the shadow-map pass.
        cull: Cull = CULL,
        /// Stored shadow-map depth precision.
        depth: DepthPrecision = DEPTH,
        ;
        /// Light-view window and near/far choice.
        view: ViewOptions,
    }
}

impl MapSettings {
    /// The light-space request every baseline makes: one shadow map at `resolution`, rasterised
    /// with [`raster`](Self::raster). Shared by the CPU twins and the frames so both ask for the
    /// same map.
    pub fn request(&self) -> LightSpaceRequest {
        let mut req = LightSpaceRequest::single(self.resolution);
        req.raster = self.raster();
        req
    }
    /// Raster options from `cull` (the map itself is stored unbiased; the bias is applied at the
    /// receiver, see [`shadow_map_core::LightView::receiver_bias`]).
    pub fn raster(&self) -> RasterOptions {
        RasterOptions {
            bias: DepthBias::default(),
            cull: self.cull,
        }
    }
    /// `(bias, slope_bias)`: the receiver bias terms (b0, b1).
    pub fn biases(&self) -> (f32, f32) {
        (self.bias, self.slope_bias)
    }
    /// The caster test's settings, `(receiver_plane, (b0, b1))`, as
    /// [`ReceiverPlane::new`](shadow_map_core::ReceiverPlane::new) takes them.
    pub fn caster_test(&self) -> (bool, (f32, f32)) {
        (self.receiver_plane, self.biases())
    }
}

shadow_map_core::typed_params! {
    /// The hard shadow map's own parameters: none (its table is the shared [`MapSettings`]).
    pub struct Hard {}
}

shadow_map_core::typed_params! {
    /// `V = (1/N^2) sum_{|di|,|dj| <= (N-1)/2} [z_p - eps <= D(i + di, j + dj)]`; PCF's own
    /// parameter (after the shared [`MapSettings`]).
    pub struct Pcf {
        /// filter size N (texels per side; even N rounds up to N+1)
        kernel: i32 = ParamSpec::int(1, 63, "5"),
    }
}

impl Pcf {
    /// The block's half width ([`math::pcf_half`]): the block is `2 half + 1` texels per side.
    pub fn half(&self) -> i32 {
        math::pcf_half(self.kernel)
    }
}

shadow_map_core::typed_params! {
    /// PCSS, step by step (docs/methods.md §5):
    /// 1. blocker search over the cut of the receiver-light pyramid at the near plane,
    ///    `W_search = l (z_r - n) / z_r` on the plane z = n (per axis for rect lights);
    /// 2. `z_avg` = mean depth of the samples with `z_i < z_r - eps` (none: V = 1);
    /// 3. penumbra at the receiver `w_p = (z_r - z_avg) l / z_avg`;
    /// 4. PCF over a box of full width `W_filter = w_p n / z_r` on the plane (a disk of that diameter
    ///    for disk and sphere lights, with a one-texel soft edge), each texel weighted by its overlap
    ///    with the box, so a single planar blocker parallel to the light is reproduced exactly.
    ///
    /// Both regions are sampled texel by texel up to `max_taps` texels per side, and by `max_taps`
    /// equal cells beyond (a documented approximation for very wide penumbrae).
    ///
    /// PCSS's own parameter (after the shared [`MapSettings`]).
    pub struct Pcss {
        /// most samples per side in the blocker search and in the filter
        max_taps: u32 = ParamSpec::int(1, 1024, "32"),
    }
}

/// Registry name of multi-sample shadows.
pub const MULTI_SAMPLE_NAME: &str = "multi-sample";
/// One-line description of multi-sample shadows.
pub const MULTI_SAMPLE_DESCRIPTION: &str =
    "average of S x S hard shadow maps from jittered points on the light (Heckbert & Herf 1997)";

shadow_map_core::typed_params! {
    /// The own parameters of multi-sample shadows (after the shared [`MapSettings`]).
    pub struct MultiSampleParams {
        /// S: S x S light samples, one hard shadow map each
        sublights: u32 = ParamSpec::int(1, 64, "4"),
        /// seed of the stratum jitter (fixed, so images are deterministic)
        seed: u64 = ParamSpec::int(0, 1 << 31, "7"),
    }
}

shadow_map_core::typed_params! {
    /// All the settings of multi-sample shadows, one table ([`MULTI_SAMPLE_SPECS`]): the shared
    /// ones, then its own.
    pub struct MultiSampleSettings {
        ;
        /// The settings every baseline shares.
        map: MapSettings,
        /// Multi-sample's own.
        sample: MultiSampleParams,
    }
}

/// The parameters of multi-sample shadows (also its frame's): [`MapSettings::SPECS`],
/// then [`MultiSampleParams::SPECS`].
pub const MULTI_SAMPLE_SPECS: &[ParamSpec] = MultiSampleSettings::SPECS;
