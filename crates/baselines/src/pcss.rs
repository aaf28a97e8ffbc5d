//! Percentage-closer soft shadows (Fernando 2005), in the exact form of docs/methods.md §5: all
//! depths linear light-space z, lengths on the plane z = n, filter widths (not radii).
use crate::common::MapSettings;
use crate::map_estimator::{Filter, MapEstimator, ReceiverSample};
use shadow_map_core::light_view::LightView;
use shadow_map_core::{DepthLookup, Light, ParamSpec, Params, Result};

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

/// The PCSS estimator.
pub type PcssShadow = MapEstimator<Pcss>;

impl Filter for Pcss {
    const NAME: &'static str = "pcss";
    const DESCRIPTION: &'static str =
        "percentage-closer soft shadows: blocker search, penumbra estimate, PCF (Fernando 2005)";
    const SPECS: &'static [ParamSpec] =
        shadow_map_core::concat_specs!(MapSettings::SPECS, Pcss::SPECS);
    fn from_params(p: &Params) -> Result<Self> {
        Pcss::from_params(p)
    }
    fn visibility<M: DepthLookup>(
        &self,
        view: &LightView,
        map: &M,
        light: &Light,
        r: &ReceiverSample,
    ) -> f32 {
        let soft = SoftLookup {
            light: 2.0 * light.half_extent(), // (l_x, l_y)
            near: view.n,
            to_texels: view.r as f32 / view.w,
            max_taps: self.max_taps,
            disk: is_disk(light),
            ortho: view.is_ortho(),
        };
        soft_transmittance(&DepthTaps(map), r.uv, r.p.z, &r.plane, &soft).0
    }
}

pub use shadow_map_core::soft_transmittance::{
    disk_edge, filter_width, is_disk, search_width, soft_transmittance, DepthTaps, Kahan,
    SoftLookup, SoftTaps,
};
