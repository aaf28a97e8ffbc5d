//! What the four baselines share: parameter declarations, the raster options, and the
//! per-receiver loop that guarantees V in [0, 1] and NaN only for inactive receivers.
use glam::Vec3;
use rayon::prelude::*;
use shadow_map_core::{
    light_space::LightSpaceRequest, Cull, DepthBias, Error, ParamKind, ParamSpec, Params,
    RasterOptions, Receivers, Result,
};

pub use shadow_map_core::light_view::{BIAS, RESOLUTION, SLOPE_BIAS};

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
/// at the receiver, see [`shadow_map_core::LightView::receiver_bias`]).
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
