//! # backprojection
//!
//! Soft shadows by backprojecting shadow-map micropatches onto a rectangle light (Guennebaud,
//! Barthe, Paulin 2006), with Bavoil's (2008) depth-peeled layers, midpoint layers and adaptive
//! sampling step: [`CpuBackprojection`]. The geometry is in [`math`] (background.md §2).
//!
//! A complete example: load a fixture, cast the camera's rays for receivers, run it.
//!
//! ```
//! use backprojection::CpuBackprojection;
//! use shadow_map_core::{run, Receivers, Scene, SceneBvh, SoftShadowEstimator};
//!
//! let scene = Scene::load(concat!(env!("CARGO_MANIFEST_DIR"), "/../../fixtures/parallel-squares/parallel-squares.toml"))?;
//! let bvh = SceneBvh::new(&scene);
//! let receivers = Receivers::from_camera(&scene, &bvh);
//! let mut bp = CpuBackprojection::new()?;
//! bp.set_param("resolution", "256")?;
//! let (v, report) = run(&mut bp, &scene, &receivers)?;
//! assert!(v.iter().zip(&receivers.active).all(|(v, a)| !a || (0.0..=1.0).contains(v)));
//! println!("build {:.1} ms, estimate {:.1} ms", report.total_ms("build"), report.total_ms("estimate"));
//! # Ok::<(), shadow_map_core::Error>(())
//! ```
#![warn(missing_docs)]
// `!(a > b)` is deliberate: true for NaN, which must take the safe branch.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

pub mod cpu;
#[cfg(feature = "gpu")]
pub mod gpu;
pub mod math;

pub use cpu::CpuBackprojection;
#[cfg(feature = "gpu")]
pub use gpu::GpuBackprojection;
pub use shadow_map_core::SoftShadowEstimator;
