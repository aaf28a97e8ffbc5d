//! Geometry shared by this crate's unit tests (they cannot use the `test-support` crate's
//! fixtures: those link a second copy of this crate).
use glam::Vec3;

/// The square `[-h, h]^2` at height `y`, facing up: two triangles, as `test-support`'s
/// `fixtures::quad(-h, -h, h, h, y)` builds it.
pub(crate) fn square(y: f32, h: f32) -> Vec<[Vec3; 3]> {
    vec![
        [
            Vec3::new(-h, y, -h),
            Vec3::new(-h, y, h),
            Vec3::new(h, y, h),
        ],
        [
            Vec3::new(-h, y, -h),
            Vec3::new(h, y, h),
            Vec3::new(h, y, -h),
        ],
    ]
}
