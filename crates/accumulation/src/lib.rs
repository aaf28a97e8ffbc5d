//! # accumulation
//!
//! Soft shadows by shadow accumulation (Aszódi & Szirmay-Kalos 2006): every lexel of a kernel
//! around the receiver's projection is an elementary caster, backprojected from the receiver
//! onto the shadow-map plane; the fraction of the light's footprint it covers is its shadowing
//! factor. Two variants: **additive** (the paper's eq. 2 and GPU pseudo-code, factors summed and
//! clamped, with each caster's exact overlap with the footprint or the paper's centre test) and
//! **exact** (eq. 1, occlusion bits on the light, a union, fed by up to 4 peeled layers), over a
//! **fixed** K x K kernel spread over the light's footprint (the paper), an **adaptive** kernel
//! (bounded per receiver by the MSSM's minimum occluder depth, sampled by multi-resolution rings:
//! single lexels next to the receiver, cells doubling outwards) or the paper's **lexels** taken
//! literally (K x K single lexels). Rect, disk and sphere lights (the contract's silhouette disk,
//! or the paper's disk perpendicular to the light normal). The geometry and the derivation of the
//! normalisation are in [`math`]; the estimator in [`cpu`]. CPU: [`CpuAccumulation`]; wgpu twin:
//! `GpuAccumulation` (feature `gpu`), same name (`accumulation`) and parameters.
//!
//! A complete example: load a fixture, cast the camera's rays for receivers, run it.
//!
//! ```
//! use accumulation::CpuAccumulation;
//! use shadow_map_core::{run, Receivers, Scene, SceneBvh, SoftShadowEstimator};
//!
//! let mut scene = Scene::load(concat!(env!("CARGO_MANIFEST_DIR"), "/../../fixtures/sphere-light/sphere-light.toml"))?;
//! scene.camera.width = 64;
//! scene.camera.height = 48;
//! let bvh = SceneBvh::new(&scene);
//! let receivers = Receivers::from_camera(&scene, &bvh);
//! let mut acc = CpuAccumulation::new()?;
//! acc.set_param("resolution", "256")?;
//! acc.set_param("variant", "exact")?;
//! let (v, report) = run(&mut acc, &scene, &receivers)?;
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

pub use cpu::CpuAccumulation;
#[cfg(feature = "gpu")]
pub use gpu::GpuAccumulation;
pub use shadow_map_core::SoftShadowEstimator;
