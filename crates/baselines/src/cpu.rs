//! The CPU twins: hard, PCF and PCSS, each a [`Filter`] over the one-map estimator
//! ([`MapEstimator`], `map_estimator.rs`), and multi-sample ([`MultiSample`]), which averages
//! one hard map per sub-light. What they share is here: the per-receiver loop that guarantees V
//! in [0, 1] and NaN only for inactive receivers, and the 16-bit encoding of a built map.
use crate::settings::{Hard, Pcf, Pcss};
use glam::Vec3;
use shadow_map_core::{
    light_space::LightSpace, Cancel, DepthPrecision, Receivers, Result, Unorm16Map,
};

pub mod hard;
pub mod map_estimator;
pub mod multi_sample;
pub mod pcf;
pub mod pcss;

pub use map_estimator::{Filter, MapEstimator, MapLookup, ReceiverSample};
pub use multi_sample::MultiSample;

/// The hard shadow-map estimator ([`Hard`]).
pub type HardShadow = MapEstimator<Hard>;
/// The PCF estimator ([`Pcf`]).
pub type PcfShadow = MapEstimator<Pcf>;
/// The PCSS estimator ([`Pcss`]).
pub type PcssShadow = MapEstimator<Pcss>;

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

/// Encodes layer 0 of `ls` to 16-bit codes under [`DepthPrecision::Unorm16`] and frees the f32
/// layer (its `size` is kept); `None` under f32.
pub fn encode_layer0(ls: &mut LightSpace, precision: DepthPrecision) -> Option<Unorm16Map> {
    if precision != DepthPrecision::Unorm16 {
        return None;
    }
    let l0 = ls.layers.first_mut()?;
    let q = Unorm16Map::encode(l0, ls.view.n, ls.view.far);
    l0.depth = Vec::new();
    Some(q)
}
