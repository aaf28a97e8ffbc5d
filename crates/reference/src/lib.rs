#![doc = include_str!("../README.md")]
#![warn(missing_docs)]

pub mod estimator;
pub mod oracle;
pub mod trace;

pub use estimator::ReferenceEstimator;

/// The ray-traced reference in the registry: `reference`, CPU only, no report sweep.
pub const DESCRIPTOR: shadow_map_core::MethodDescriptor = shadow_map_core::MethodDescriptor::new(
    "reference",
    || Ok(Box::new(ReferenceEstimator::new()?)),
    shadow_map_core::method::Sweep::NONE,
);

/// This crate's version, part of the key under which `softshadow report` caches reference
/// images (with [`REVISION`]).
pub const VERSION: &str = env!("CARGO_PKG_VERSION");

/// The tracer's revision: raise it with any change that moves a reference image (sampling,
/// jitter streams, the light model), so no cached reference from before is reused.
pub const REVISION: u32 = 1;
pub use oracle::{
    disk_occluder_visibility, half_plane_sun_visibility, lens_area, polygon_disk_area,
    polygon_occluder_disk_visibility, rect_occluder_visibility, sphere_occluder_on_axis_visibility,
    union_area, RectOccluder,
};
pub use trace::{receiver_visibility, visibility, TraceOptions};
