//! # baselines
//!
//! What users pick today, so every figure this project reports has them beside it: the hard
//! shadow map, PCF (N x N), PCSS (Fernando 2005) and multi-sample shadows (the average of S x S
//! hard maps from points on the light), each a CPU [`SoftShadowEstimator`].
//!
//! A complete example: load a fixture, cast the camera's rays for receivers, run PCSS.
//!
//! ```
//! use baselines::PcssShadow;
//! use shadow_map_core::{run, Receivers, Scene, SceneBvh, SoftShadowEstimator};
//!
//! let scene = Scene::load(concat!(env!("CARGO_MANIFEST_DIR"), "/../../fixtures/parallel-squares/parallel-squares.toml"))?;
//! let bvh = SceneBvh::new(&scene);
//! let receivers = Receivers::from_camera(&scene, &bvh);
//! let mut pcss = PcssShadow::new()?;
//! pcss.set_param("resolution", "256")?;
//! let (v, report) = run(&mut pcss, &scene, &receivers)?;
//! assert!(v.iter().zip(&receivers.active).all(|(v, a)| !a || (0.0..=1.0).contains(v)));
//! println!("build {:.1} ms, estimate {:.1} ms", report.total_ms("build"), report.total_ms("estimate"));
//! # Ok::<(), shadow_map_core::Error>(())
//! ```
#![warn(missing_docs)]
// `!(a > b)` is deliberate: true for NaN, which must take the safe branch.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

pub mod common;
pub mod hard;
pub mod map_estimator;
pub mod multi_sample;
pub mod pcf;
pub mod pcss;

#[cfg(feature = "gpu")]
pub mod gpu;
#[cfg(feature = "gpu")]
pub use gpu::{GpuHardShadow, GpuMultiSample, GpuPcfShadow, GpuPcssShadow};

pub use hard::HardShadow;
pub use multi_sample::MultiSample;
pub use pcf::PcfShadow;
pub use pcss::PcssShadow;
pub use shadow_map_core::SoftShadowEstimator;
