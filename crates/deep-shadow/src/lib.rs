//! # deep-shadow
//!
//! Real-time deep shadow maps for semi-transparent geometry (René Fürst, Oliver Mattausch,
//! Daniel Scherzer, "Real-Time Deep Shadow Maps"): every fragment seen from the light goes into a
//! per-texel linked list (head buffer + element buffer + one counter, §1.3.1); the lists are
//! sorted, turned into cumulative transmittance `tau_k = prod_{i<=k} (1 - alpha_i)` (Eq. 1.1) and
//! truncated (§1.3.2), linked to their right and upper neighbours (§1.3.3), and looked up at the
//! receiver's depth with no filter, PCF or exponential filtering (EDSM), guided by the links or
//! naively (§1.3.4, §1.3.5). Beyond the paper: S x S point sub-lights on the area light, one deep
//! shadow map each, averaged into soft, partially transmitted shadows.
//!
//! | module | what |
//! |---|---|
//! | [`raster`] | every fragment of every mesh from the light, with its opacity |
//! | [`dsm`] | the lists: build with capacity growth, process, link, lookup |
//! | [`cpu`] | [`CpuDeepShadow`], sub-lights, the receivers' queries |
//! | `gpu` | `GpuDeepShadow` (feature `gpu`): the same stages in `deep_shadow.wgsl` |
//! | [`params`], [`shared`] | the parameter table and the list element both twins share |
//!
//! ```
//! use deep_shadow::CpuDeepShadow;
//! use shadow_map_core::{run, Receivers, Scene, SceneBvh, SoftShadowEstimator};
//!
//! let mut scene = Scene::load(concat!(env!("CARGO_MANIFEST_DIR"), "/../../fixtures/strands/strands.toml"))?;
//! scene.camera.width = 40;
//! scene.camera.height = 30;
//! let receivers = Receivers::from_camera(&scene, &SceneBvh::new(&scene));
//! let mut dsm = CpuDeepShadow::new()?;
//! dsm.set_param("resolution", "256")?;
//! dsm.set_param("filter", "edsm")?;
//! dsm.set_param("sublights", "2")?;
//! let (v, report) = run(&mut dsm, &scene, &receivers)?;
//! assert!(v.iter().zip(&receivers.active).all(|(v, a)| !a || (0.0..=1.0).contains(v)));
//! println!("build {:.1} ms, estimate {:.1} ms", report.total_ms("build"), report.total_ms("estimate"));
//! # Ok::<(), shadow_map_core::Error>(())
//! ```
#![warn(missing_docs)]
// `!(a > b)` is deliberate: true for NaN, which must take the safe branch.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

pub mod cpu;
pub mod dsm;
#[cfg(feature = "gpu")]
pub mod gpu;
pub mod params;
pub mod raster;
pub mod shared;

pub use cpu::CpuDeepShadow;
#[cfg(feature = "gpu")]
pub use gpu::GpuDeepShadow;
pub use shadow_map_core::SoftShadowEstimator;
