//! # shadow-map-core
//!
//! The ground every softshadow algorithm stands on: the scene model of the project's contract
//! (TOML + OBJ, one area light, one camera), receivers (the camera's G-buffer or a user's points),
//! the light view (perspective projection through the light centre onto the plane z = n, fitted
//! tightly), the CPU rasteriser with its fill rule, bias and culling, depth peeling, midpoint
//! layers, the MSSM family, estimator parameters and the [`SoftShadowEstimator`] trait.
#![warn(missing_docs)]
// `!(a > b)` is deliberate throughout: it is true for NaN, which must take the safe branch.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

pub mod bvh;
pub mod camera;
pub mod error;
pub mod estimator;
pub mod light;
pub mod light_space;
pub mod light_view;
pub mod mssm;
pub mod params;
pub mod peeling;
pub mod raster;
pub mod receivers;
pub mod scene;

pub use bvh::SceneBvh;
pub use camera::Camera;
pub use error::{Error, Result};
pub use estimator::{default_sweep, run, Backend, Report, SoftShadowEstimator};
pub use light::{Light, LightFrame, LightShape};
pub use light_space::{LightSpace, LightSpaceRequest};
pub use light_view::LightView;
pub use params::{ParamKind, ParamSpec, ParamValue, Params};
pub use raster::{Cull, DepthBias, DepthMap, RasterOptions};
pub use receivers::{ImageLayout, Receivers};
pub use scene::Scene;
#[cfg(feature = "gpu")]
pub mod gpu;
