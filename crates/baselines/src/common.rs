//! What the four baselines share: parameter declarations, the raster options, and the
//! per-receiver loop that guarantees V in [0, 1] and NaN only for inactive receivers.
use glam::Vec3;
use shadow_map_core::{
    light_space::LightSpaceRequest, light_view::ViewOptions, precision::DEPTH,
    receiver_plane::RECEIVER_PLANE, Cancel, Cull, DepthBias, DepthPrecision, ParamSpec, Params,
    RasterOptions, Receivers, Result,
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

/// [`MapSettings::request`] of a baseline's parameters (`p` must hold the [`MapSettings`] table).
pub fn map_request(p: &Params) -> Result<LightSpaceRequest> {
    Ok(MapSettings::from_params(p)?.request())
}

/// Runs `f(position, normal)` for every active receiver in parallel, writes NaN for inactive ones,
/// and clamps results into [0, 1]. Returns how many results were not finite (they are written as
/// 0 and must be reported: a non-zero count is a bug). Checks `cancel` between chunks of
/// receivers ([`Cancel::par_sum`]): `Err(Cancelled)` once it is set.
pub fn for_each_receiver(
    cancel: &Cancel,
    receivers: &Receivers,
    v: &mut [f32],
    f: impl Fn(Vec3, Vec3) -> f32 + Sync + Send,
) -> Result<usize> {
    cancel.par_sum(v, |k, out| {
        if !receivers.active()[k] {
            *out = f32::NAN;
            return 0;
        }
        let x = f(receivers.position()[k], receivers.normal()[k]);
        if x.is_finite() {
            *out = x.clamp(0.0, 1.0);
            0
        } else {
            *out = 0.0;
            1
        }
    })
}
