//! Percentage-closer soft shadows (Fernando 2005), in the exact form of docs/methods.md §5: all
//! depths linear light-space z, lengths on the plane z = n, filter widths (not radii). The steps
//! are the core's [`soft_transmittance`] over the map's texels ([`DepthTaps`]), which
//! deep-shadow's `filter=pcss` shares; the widths are in [`crate::math`].
use super::map_estimator::{filter_identity, Filter, MapLookup, ReceiverSample};
use crate::math::is_disk;
use crate::settings::Pcss;
use shadow_map_core::DepthLookup;

pub use shadow_map_core::soft_transmittance::{
    soft_transmittance, DepthTaps, Kahan, SoftLookup, SoftTaps,
};

impl Filter for Pcss {
    filter_identity!(
        "pcss",
        "percentage-closer soft shadows: blocker search, penumbra estimate, PCF (Fernando 2005)"
    );
    fn visibility<M: DepthLookup>(&self, at: &MapLookup<'_, M>, r: &ReceiverSample) -> f32 {
        let (view, light) = (at.view, at.light);
        let soft = SoftLookup {
            light: 2.0 * light.half_extent(), // (l_x, l_y)
            near: view.n,
            to_texels: view.r as f32 / view.w,
            max_taps: self.max_taps,
            disk: is_disk(light),
            ortho: view.is_ortho(),
        };
        soft_transmittance(&DepthTaps(at.map), r.uv, r.p.z, &r.plane, &soft).0
    }
}
