#![doc = include_str!("../README.md")]
#![warn(missing_docs)]
// `!(a > b)` is deliberate throughout: it is true for NaN, which must take the safe branch.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

pub mod bitmask;
pub mod bvh;
pub mod camera;
pub mod cancel;
pub mod cascades;
pub mod error;
pub mod estimator;
pub mod light;
pub mod light_space;
pub mod light_view;
pub mod method;
pub mod mssm;
pub mod overlap;
pub mod params;
pub mod peeling;
pub mod precision;
pub mod raster;
pub mod receiver_plane;
pub mod receivers;
pub mod scene;
pub mod settle;
pub mod silhouette;
pub mod soft_transmittance;
#[cfg(test)]
mod test_geometry;

pub use bvh::SceneBvh;
pub use camera::Camera;
pub use cancel::Cancel;
pub use error::{Error, Result};
pub use estimator::{run, Backend, Report, SoftShadowEstimator, Warning};
pub use light::{Light, LightFrame, LightShape};
pub use light_space::{LightSpace, LightSpaceRequest};
pub use light_view::LightView;
pub use method::{MethodDescriptor, Setting};
pub use params::{Configured, FromParam, ParamKind, ParamSpec, ParamValue, Params, TypedParams};
pub use precision::{DepthLookup, DepthPrecision, Unorm16Map};
pub use raster::{Cull, DepthBias, DepthMap, RasterOptions};
pub use receiver_plane::ReceiverPlane;
pub use receivers::{ImageLayout, Receivers};
pub use scene::{OpacityLevel, Scene};
#[cfg(feature = "gpu")]
pub mod gpu;
