//! The CPU twins: hard, PCF and PCSS, each a [`Filter`] over the one-map estimator
//! ([`MapEstimator`], `map_estimator.rs`), and multi-sample ([`MultiSample`]), which averages
//! one hard map per sub-light. What they share is here: the 16-bit encoding of a built map (the
//! per-receiver loop is the core's [`Receivers::estimate_each`](shadow_map_core::Receivers::estimate_each)).
use crate::settings::{Hard, Pcf, Pcss};
use shadow_map_core::{light_space::LightSpace, DepthPrecision, Unorm16Map};

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
