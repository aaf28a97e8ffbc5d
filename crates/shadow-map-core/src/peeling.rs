//! Depth peeling (Bavoil, Callahan, Silva 2008, §4.1; Everitt 2001): k layers per texel, nearest
//! first, layer m+1 the nearest surface strictly behind layer m, `z > z_m (1 + PEEL_EPS_REL)`
//! (see [`crate::raster::PEEL_EPS_REL`]). One rasterisation pass per layer, as on a GPU.
use crate::{
    light_view::{LightView, BIAS, SLOPE_BIAS},
    raster::{DepthBias, DepthMap, PreparedScene},
    receiver_plane::RECEIVER_PLANE,
    ParamSpec,
};

/// `self_shadow`: how an estimator with midpoint layers tells a receiver's own surface from an
/// occluder (Bavoil §4.2): by the midpoint layers (parameter-free) or by a receiver bias.
pub const SELF_SHADOW: ParamSpec = ParamSpec::choice(SelfShadow::WORDS, "midpoint").named(
    "self_shadow",
    "classify samples by midpoint layers (Bavoil §4.2, parameter-free) or by a receiver bias",
);
/// How receivers are told from occluders ([`SELF_SHADOW`]).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub enum SelfShadow {
    /// By the midpoint layers (parameter-free), the default.
    #[default]
    Midpoint,
    /// By a receiver bias.
    Bias,
}

crate::param_words!(SelfShadow { Midpoint = "midpoint", Bias = "bias" });

/// `max_bias`: the clamp of [`midpoint`], in texel footprints at the far plane.
pub const MAX_BIAS: ParamSpec = ParamSpec::float(0.0, 1e6, "4.0").named(
    "max_bias",
    "midpoint clamp in texel footprints at the far plane: midpoint <= z_1 + max_bias w far / (n r)",
);
/// [`BIAS`] where it applies only under `self_shadow=bias`.
pub const SELF_SHADOW_BIAS: ParamSpec = ParamSpec {
    help: "self_shadow=bias: constant depth bias, in world-space texel footprints at the receiver (w z / (n r))",
    ..BIAS
};
/// [`SLOPE_BIAS`] where it applies only under `self_shadow=bias`.
pub const SELF_SHADOW_SLOPE_BIAS: ParamSpec = ParamSpec {
    help: "self_shadow=bias: slope-scaled bias, texel footprints times min(tan(theta), 10)",
    ..SLOPE_BIAS
};

crate::typed_params! {
    /// How an estimator with midpoint layers tells a receiver's own surface from a caster
    /// (backprojection, packet-hsm): midpoints or a receiver bias ([`SELF_SHADOW`]), the midpoint
    /// clamp, the bias pair and receiver-plane rejection ([`crate::receiver_plane`]); the
    /// `shadow` group of their parameters, declared once here.
    pub struct SelfShadowSettings {
        /// Midpoint classification or a receiver bias.
        self_shadow: SelfShadow = SELF_SHADOW,
        /// Midpoint clamp, in texel footprints at the far plane.
        max_bias: f32 = MAX_BIAS,
        /// Constant receiver bias b0 (`self_shadow=bias`); with `receiver_plane=true`, the
        /// receiver plane's tolerance in texel footprints (both modes).
        bias: f32 = SELF_SHADOW_BIAS,
        /// Slope-scaled receiver bias b1 (`self_shadow=bias`, `receiver_plane=false`).
        slope_bias: f32 = SELF_SHADOW_SLOPE_BIAS,
        /// Receiver-plane rejection ([`crate::receiver_plane`]).
        receiver_plane: bool = RECEIVER_PLANE,
    }
}

impl SelfShadowSettings {
    /// Whether receivers are classified by midpoint layers (`self_shadow=midpoint`; else bias).
    pub fn midpoint(&self) -> bool {
        self.self_shadow == SelfShadow::Midpoint
    }
    /// The midpoint clamp in light-space depth for `view` (`max_bias` texel footprints at the far
    /// plane, `w far / (n r)` each), or `None` under `self_shadow=bias`: the `midpoints` of a
    /// [`LightSpaceRequest`](crate::light_space::LightSpaceRequest).
    pub fn midpoint_clamp(&self, view: &LightView) -> Option<f32> {
        let footprint = view.texel_at(view.far);
        self.midpoint()
            .then_some((self.max_bias * footprint).min(f32::MAX))
    }
}

/// Peels `k` layers (k >= 1). Layer 0 is the ordinary shadow map. Texels with fewer than m+1
/// surfaces hold +inf in layer m.
pub fn peel(prepared: &PreparedScene, bias: DepthBias, k: u32) -> Vec<DepthMap> {
    peel_layers(prepared, bias, k, false).0
}

/// [`peel`], and each layer's per-texel opacity ([`PreparedScene::rasterize_with_opacity`]): what
/// semi-transparent occluders need.
pub fn peel_with_opacity(
    prepared: &PreparedScene,
    bias: DepthBias,
    k: u32,
) -> (Vec<DepthMap>, Vec<Vec<f32>>) {
    peel_layers(prepared, bias, k, true)
}

fn peel_layers(
    prepared: &PreparedScene,
    bias: DepthBias,
    k: u32,
    opacity: bool,
) -> (Vec<DepthMap>, Vec<Vec<f32>>) {
    let mut layers: Vec<DepthMap> = Vec::with_capacity(k as usize);
    let mut alphas: Vec<Vec<f32>> = Vec::new();
    for m in 0..k {
        let (layer, alpha) = if opacity {
            prepared.rasterize_with_opacity(bias, layers.last())
        } else {
            (prepared.rasterize(bias, layers.last()), Vec::new())
        };
        let empty = layer.depth.iter().all(|d| d.is_infinite());
        let size = layer.size;
        layers.push(layer);
        if opacity {
            alphas.push(alpha);
        }
        if empty {
            // Every further layer is empty too: no need to rasterise them.
            for _ in m + 1..k {
                layers.push(DepthMap::empty(size));
                if opacity {
                    alphas.push(vec![0.0; size as usize * size as usize]);
                }
            }
            break;
        }
    }
    (layers, alphas)
}

/// Midpoint layers (Bavoil §4.2, after Woo 1992): `M_m = min((L_m + L_{m+1}) / 2, L_m + max_bias)`
/// per texel, with `L_{m+1} = +inf` where there is no next layer, so a lone surface gets
/// `L_m + max_bias` (the maximum-bias clamp keeps thick occluders from shifting their shadow far
/// behind them). Needs `layers.len() >= k + 1` to give k midpoint layers (the last given layer is
/// only used as the upper neighbour).
pub fn midpoints(layers: &[DepthMap], max_bias: f32) -> Vec<DepthMap> {
    let k = layers.len().saturating_sub(1);
    (0..k)
        .map(|m| {
            let (a, b) = (&layers[m], &layers[m + 1]);
            let depth = a
                .depth
                .iter()
                .zip(&b.depth)
                .map(|(&za, &zb)| midpoint(za, zb, max_bias))
                .collect();
            DepthMap {
                size: a.size,
                depth,
            }
        })
        .collect()
}

/// One midpoint: `min((a + b)/2, a + max_bias)`; +inf when `a` is empty.
#[inline]
pub fn midpoint(a: f32, b: f32, max_bias: f32) -> f32 {
    if a.is_infinite() {
        return f32::INFINITY;
    }
    let clamp = a + max_bias;
    if b.is_infinite() {
        clamp
    } else {
        (0.5 * (a + b)).min(clamp)
    }
}
