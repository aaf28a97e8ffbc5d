//! The hard shadow map (Williams 1978): one binary depth test at the receiver's texel, the
//! point-light limit every soft estimator must reach as the light shrinks (docs/methods.md §10.4).
use crate::common::MapSettings;
use crate::map_estimator::{lit, Filter, MapEstimator, ReceiverSample};
use glam::Vec3;
use shadow_map_core::light_view::LightView;
use shadow_map_core::{DepthLookup, Light, ParamSpec, Params, Result};

/// The hard test: `V = [z_p - eps <= D(floor u, floor v)]`, and 0 when the light centre (the
/// sun's centre direction) is behind the receiver's tangent plane.
pub struct Hard;

/// The hard shadow-map estimator.
pub type HardShadow = MapEstimator<Hard>;

impl Filter for Hard {
    const NAME: &'static str = "hard";
    const DESCRIPTION: &'static str =
        "hard shadow map: one binary depth test from the light centre (Williams 1978)";
    const SPECS: &'static [ParamSpec] = MapSettings::SPECS;
    fn from_params(_: &Params) -> Result<Self> {
        Ok(Hard)
    }
    fn visibility<M: DepthLookup>(
        &self,
        _: &LightView,
        map: &M,
        _: &Light,
        r: &ReceiverSample,
    ) -> f32 {
        lit(map, r.uv.x.floor() as i32, r.uv.y.floor() as i32, r)
    }
    fn facing(&self, light: &Light, p: Vec3, n: Vec3) -> f32 {
        // The sun's centre direction comes from -normal (no point light to face).
        let towards = if light.is_directional() {
            -light.normal
        } else {
            light.center - p
        };
        let behind = light.one_sided() && (p - light.center).dot(light.normal) <= 0.0;
        if behind || n.dot(towards) <= 0.0 {
            0.0
        } else {
            1.0
        }
    }
}
