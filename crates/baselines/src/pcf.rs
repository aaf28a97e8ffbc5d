//! Percentage-closer filtering (Reeves, Salesin, Cook 1987; docs/methods.md §5): compare first,
//! then filter, over an N x N block of texels centred on the receiver's texel.
use crate::common::MapSettings;
use crate::map_estimator::{lit, Filter, MapEstimator, ReceiverSample};
use shadow_map_core::light_view::LightView;
use shadow_map_core::{DepthLookup, Light, ParamSpec, Params, Result};

shadow_map_core::typed_params! {
    /// `V = (1/N^2) sum_{|di|,|dj| <= (N-1)/2} [z_p - eps <= D(i + di, j + dj)]`; PCF's own
    /// parameter (after the shared [`MapSettings`]).
    pub struct Pcf {
        /// filter size N (texels per side; even N rounds up to N+1)
        kernel: i32 = ParamSpec::int(1, 63, "5"),
    }
}

/// The PCF estimator.
pub type PcfShadow = MapEstimator<Pcf>;

impl Pcf {
    /// `(N - 1) / 2` after rounding even N up: the block is `2 half + 1` texels per side.
    pub fn half(&self) -> i32 {
        self.kernel / 2
    }
}

impl Filter for Pcf {
    const NAME: &'static str = "pcf";
    const DESCRIPTION: &'static str =
        "percentage-closer filtering over an N x N texel block (Reeves et al. 1987)";
    const SPECS: &'static [ParamSpec] =
        shadow_map_core::concat_specs!(MapSettings::SPECS, Pcf::SPECS);
    fn from_params(p: &Params) -> Result<Self> {
        Pcf::from_params(p)
    }
    fn visibility<M: DepthLookup>(
        &self,
        _: &LightView,
        map: &M,
        _: &Light,
        r: &ReceiverSample,
    ) -> f32 {
        let (i0, j0) = (r.uv.x.floor() as i32, r.uv.y.floor() as i32);
        let mut sum = 0.0;
        let half = self.half();
        for dj in -half..=half {
            for di in -half..=half {
                sum += lit(map, i0 + di, j0 + dj, r);
            }
        }
        let side = (2 * half + 1) as f32;
        sum / (side * side)
    }
}
