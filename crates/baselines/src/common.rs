//! What the four baselines share: parameter declarations, the receiver-side depth bias, and the
//! per-receiver loop that guarantees V in [0, 1] and NaN only for inactive receivers.
use glam::Vec3;
use rayon::prelude::*;
use shadow_map_core::{
    light_space::LightSpaceRequest, light_view::LightView, Cull, DepthBias, Error, ParamKind,
    ParamSpec, Params, RasterOptions, Receivers, Result,
};

/// `resolution`: shadow-map side in texels.
pub const RESOLUTION: ParamSpec = ParamSpec {
    key: "resolution",
    kind: ParamKind::Int {
        min: 1,
        max: shadow_map_core::light_view::MAX_RESOLUTION as i64,
    },
    default: "1024",
    help: "shadow-map resolution r (texels per side)",
};
/// `bias`: constant receiver bias in texel footprints.
pub const BIAS: ParamSpec = ParamSpec {
    key: "bias",
    kind: ParamKind::Float {
        min: 0.0,
        max: 1000.0,
    },
    default: "1.0",
    help: "constant depth bias, in world-space texel footprints at the receiver (w z / (n r))",
};
/// `slope_bias`: slope-scaled receiver bias in texel footprints.
pub const SLOPE_BIAS: ParamSpec = ParamSpec {
    key: "slope_bias",
    kind: ParamKind::Float { min: 0.0, max: 1000.0 },
    default: "1.0",
    help: "slope-scaled bias: texel footprints times min(tan(theta), 10), theta = angle(normal, light)",
};
/// `cull`: face culling while rasterising the shadow map.
pub const CULL: ParamSpec = ParamSpec {
    key: "cull",
    kind: ParamKind::Choice(&["none", "back", "front"]),
    default: "none",
    help: "face culling in the shadow-map pass (winding-based, as seen from the light)",
};

/// The light-space request every baseline makes: one shadow map at the `resolution` parameter,
/// rasterised with [`raster_options`]. Shared by the CPU and GPU twins so both ask for the same map.
pub fn map_request(p: &Params) -> LightSpaceRequest {
    let mut req = LightSpaceRequest::single(p.int("resolution") as u32);
    req.raster = raster_options(p);
    req
}

/// Raster options from the `cull` parameter (the map itself is stored unbiased; the bias is applied
/// at the receiver, see [`receiver_bias`]).
pub fn raster_options(p: &Params) -> RasterOptions {
    let cull = match p.choice("cull") {
        "back" => Cull::Back,
        "front" => Cull::Front,
        _ => Cull::None,
    };
    RasterOptions {
        bias: DepthBias::default(),
        cull,
    }
}

/// Receiver-side depth bias in world units (background.md §2, "Self-shadowing"):
/// `eps = (w z_p / (n r)) (b0 + b1 min(tan theta, 10))`, where `w z_p/(n r)` is the world size of
/// one texel at the receiver's depth and theta the angle between the receiver normal and the
/// direction to the view's centre of projection. Scale-invariant: the same numbers work for any
/// scene size.
#[inline]
pub fn receiver_bias(view: &LightView, p_light: Vec3, n_light: Vec3, b0: f32, b1: f32) -> f32 {
    let texel = view.w * p_light.z / (view.n * view.r as f32);
    let to_light = (-p_light).normalize_or_zero();
    let cos = n_light.dot(to_light).abs().max(1e-6);
    let tan = ((1.0 - cos * cos).max(0.0)).sqrt() / cos;
    texel * (b0 + b1 * tan.min(10.0))
}

/// Checks the output slice length.
pub fn check_len(receivers: &Receivers, v: &[f32]) -> Result<()> {
    if v.len() != receivers.len() {
        return Err(Error::Receivers(format!(
            "output has {} slots for {} receivers",
            v.len(),
            receivers.len()
        )));
    }
    Ok(())
}

/// Runs `f(position, normal)` for every active receiver in parallel, writes NaN for inactive ones,
/// and clamps results into [0, 1]. Returns how many results were not finite (they are written as
/// 0 and must be reported: a non-zero count is a bug).
pub fn for_each_receiver(
    receivers: &Receivers,
    v: &mut [f32],
    f: impl Fn(Vec3, Vec3) -> f32 + Sync,
) -> usize {
    v.par_iter_mut()
        .enumerate()
        .map(|(k, out)| {
            if !receivers.active[k] {
                *out = f32::NAN;
                return 0;
            }
            let x = f(receivers.position[k], receivers.normal[k]);
            if x.is_finite() {
                *out = x.clamp(0.0, 1.0);
                0
            } else {
                *out = 0.0;
                1
            }
        })
        .sum()
}
