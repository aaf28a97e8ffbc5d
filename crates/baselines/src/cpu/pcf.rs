//! Percentage-closer filtering (Reeves, Salesin, Cook 1987; docs/methods.md §5): compare first,
//! then filter, over an N x N block of texels centred on the receiver's texel.
use super::map_estimator::{filter_identity, Filter, MapLookup, ReceiverSample};
use crate::settings::Pcf;
use shadow_map_core::DepthLookup;

impl Filter for Pcf {
    filter_identity!(
        "pcf",
        "percentage-closer filtering over an N x N texel block (Reeves et al. 1987)"
    );
    fn visibility<M: DepthLookup>(&self, at: &MapLookup<'_, M>, r: &ReceiverSample) -> f32 {
        let (i0, j0) = r.texel();
        let mut sum = 0.0;
        let half = self.half();
        for dj in -half..=half {
            for di in -half..=half {
                sum += at.lit(i0 + di, j0 + dj, r);
            }
        }
        let side = (2 * half + 1) as f32;
        sum / (side * side)
    }
}
