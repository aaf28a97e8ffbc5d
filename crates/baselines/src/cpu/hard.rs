//! The hard shadow map (Williams 1978): one binary depth test at the receiver's texel, the
//! point-light limit every soft estimator must reach as the light shrinks (docs/methods.md §10.4).
use super::map_estimator::{filter_identity, Filter, MapLookup, ReceiverSample};
use crate::settings::Hard;
use glam::Vec3;
use shadow_map_core::{DepthLookup, Light};

/// The hard test: `V = [z_p - eps <= D(floor u, floor v)]`, and 0 when the light centre (the
/// sun's centre direction) is behind the receiver's tangent plane.
impl Filter for Hard {
    filter_identity!(
        "hard",
        "hard shadow map: one binary depth test from the light centre (Williams 1978)"
    );
    fn visibility<M: DepthLookup>(&self, at: &MapLookup<'_, M>, r: &ReceiverSample) -> f32 {
        let (i, j) = r.texel();
        at.lit(i, j, r)
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
