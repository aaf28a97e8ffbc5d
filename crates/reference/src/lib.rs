//! # reference
//!
//! The ray-traced ground truth every softshadow estimator is scored against, and the closed-form
//! oracles that check the ground truth itself.
//!
//! - [`trace`]: V exactly as the contract defines it (contract.md, "Visibility image"): the
//!   fraction of the light's area visible from each receiver, by `s x s` stratified
//!   (correlated multi-jittered) light samples and shadow rays through the scene's BVH. Samples behind
//!   the receiver's tangent plane are blocked; rect and disk lights are one-sided; a sphere light
//!   is sampled on its silhouette disk perpendicular to receiver -> centre; semi-transparent
//!   surfaces pass `1 - opacity` each. Deterministic for a given seed.
//! - [`estimator`]: the same as a [`SoftShadowEstimator`](shadow_map_core::SoftShadowEstimator)
//!   named `reference` (parameters `spp`, `seed`).
//! - [`oracle`]: closed forms from background.md §9-§10 (rect light behind rect occluders, disk
//!   light behind a disk or polygon occluder, sphere light with an on-axis sphere occluder).
//!
//! This crate depends on no estimator, so it stays an independent oracle.
//!
//! ```
//! use glam::Vec3;
//! use reference::{visibility, TraceOptions};
//! use shadow_map_core::{camera::Camera, Light, LightShape, Receivers, Scene, SceneBvh};
//!
//! # fn main() -> shadow_map_core::Result<()> {
//! let light = Light {
//!     shape: LightShape::Rect { size: [1.0, 1.0] },
//!     center: Vec3::new(0.0, 3.0, 0.0),
//!     normal: Vec3::NEG_Y,
//!     tangent: Vec3::X,
//! };
//! let camera = Camera {
//!     eye: Vec3::new(0.0, 2.0, 5.0),
//!     target: Vec3::ZERO,
//!     up: Vec3::Y,
//!     fov_y_deg: 40.0,
//!     width: 4,
//!     height: 4,
//! };
//! // A 1 x 1 opaque square halfway between the light and the ground.
//! let (a, b, c, d) = (
//!     Vec3::new(-0.5, 1.5, -0.5),
//!     Vec3::new(0.5, 1.5, -0.5),
//!     Vec3::new(0.5, 1.5, 0.5),
//!     Vec3::new(-0.5, 1.5, 0.5),
//! );
//! let scene = Scene::from_meshes("doc", camera, light, vec![(vec![[a, b, c], [a, c, d]], 1.0)])?;
//! let bvh = SceneBvh::new(&scene);
//! let receivers = Receivers::from_points(
//!     vec![Vec3::ZERO, Vec3::new(3.0, 0.0, 0.0)],
//!     vec![Vec3::Y, Vec3::Y],
//! )?;
//! let mut v = vec![0.0; receivers.len()];
//! visibility(&scene, &bvh, &receivers, &TraceOptions::default(), &mut v, false)?;
//! assert_eq!(v[0], 0.0); // umbra: the square's shadow from (0, 0, 0) covers the whole light
//! assert_eq!(v[1], 1.0); // fully lit
//! # Ok(()) }
//! ```
#![warn(missing_docs)]

pub mod estimator;
pub mod oracle;
pub mod trace;

pub use estimator::ReferenceEstimator;
pub use oracle::{
    disk_occluder_visibility, lens_area, polygon_disk_area, polygon_occluder_disk_visibility,
    rect_occluder_visibility, sphere_occluder_on_axis_visibility, union_area, RectOccluder,
};
pub use trace::{receiver_visibility, visibility, TraceOptions};
