//! # packet-hsm
//!
//! Packet-based hierarchical soft shadow mapping (Yang, Feng, Guennebaud, Liu 2009): occluder
//! contours backprojected onto a rectangle light and radially integrated (Guennebaud et al. 2007,
//! [`contour`]), with tight kernels from the MSSM, fully lit / fully occluded classification,
//! packets of w x h pixels, hierarchical contour extraction over the dual-grid MSSM, the
//! coherence test and S x S multi-view sub-lights: [`CpuPacketHsm`].
//!
//! A complete example: load a fixture, cast the camera's rays for receivers, run it.
//!
//! ```
//! use packet_hsm::CpuPacketHsm;
//! use shadow_map_core::{run, Receivers, Scene, SceneBvh, SoftShadowEstimator};
//!
//! let mut scene = Scene::load(concat!(env!("CARGO_MANIFEST_DIR"), "/../../fixtures/parallel-squares/parallel-squares.toml"))?;
//! scene.camera.width = 64;
//! scene.camera.height = 48;
//! let bvh = SceneBvh::new(&scene);
//! let receivers = Receivers::from_camera(&scene, &bvh);
//! let mut hsm = CpuPacketHsm::new()?;
//! hsm.set_param("resolution", "256")?;
//! hsm.set_param("packet", "4x4")?;
//! hsm.set_param("sublights", "2")?;
//! let (v, report) = run(&mut hsm, &scene, &receivers)?;
//! assert!(v.iter().zip(&receivers.active).all(|(v, a)| !a || (0.0..=1.0).contains(v)));
//! println!("build {:.1} ms, estimate {:.1} ms", report.total_ms("build"), report.total_ms("estimate"));
//! # Ok::<(), shadow_map_core::Error>(())
//! ```
#![warn(missing_docs)]
// `!(a > b)` is deliberate: true for NaN, which must take the safe branch.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

pub mod contour;
pub mod cpu;
#[cfg(feature = "gpu")]
pub mod gpu;

pub use cpu::CpuPacketHsm;
#[cfg(feature = "gpu")]
pub use gpu::GpuPacketHsm;
pub use shadow_map_core::SoftShadowEstimator;
