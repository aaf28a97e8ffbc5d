//! What the workspace's integration tests share (`publish = false`, a dev-dependency only).
//!
//! - `bench` (feature `bench`): the criterion rows every method's bench shares (build and
//!   estimate, one engine-path frame).
//! - [`config`]: the number of random cases (`SOFTSHADOW_PROPTEST_CASES`) and the proptest
//!   configuration, failures persisted beside the test file.
//! - [`tolerance`]: the one twin tolerance ([`Tolerance`]): a per-receiver bound on |dV|, the
//!   fraction of receivers that must lie within it, an optional bound on every receiver, and the
//!   rule that explains each receiver beyond it as a tie.
//! - [`scenes`]: random scenes for the twins (a light over boxes on a ground, receivers on the
//!   ground, on box tops, grazing and outside the light's frustum), with each method's ranges.
//! - [`fixtures`]: the small fixed scenes of the accuracy tests (horizontal quads, a rect light,
//!   square occluders, a line of receivers) and the scene fixtures under `fixtures/`.
//! - `gate` (feature `gpu`): the shared Vulkan context, a loud skip without an adapter, a
//!   failure instead under `SOFTSHADOW_REQUIRE_GPU=1`.
//! - `frame_run` (feature `gpu`): one frame of a `FrameEstimator` as a renderer records it
//!   (`FrameRig`, `run_frame`): inputs uploaded, one submit, V and the status read back.
//! - [`wgsl`]: naga's checks of WGSL without a device (shaders parse and validate, `#[repr(C)]`
//!   mirrors match their WGSL structs: [`assert_wgsl_layout!`]), for every crate's shader tests.
//! - `conformance` (feature `gpu`): the CPU-vs-GPU conformance suite every method's twins pass:
//!   random scenes, empty and inactive receivers, one name and parameter table, the CLI path
//!   and the loop-limit redo; the macro `twin_suite!` instantiates it per
//!   algorithm, in a module `twin::<algorithm>`, so that test names carry the algorithm.
#![warn(missing_docs)]

#[cfg(feature = "bench")]
pub mod bench;
pub mod config;
#[cfg(feature = "gpu")]
pub mod conformance;
pub mod fixtures;
#[cfg(feature = "gpu")]
pub mod frame_run;
#[cfg(feature = "gpu")]
pub mod gate;
pub mod scenes;
pub mod tolerance;
pub mod wgsl;

pub use config::{cases, proptest_config, REQUIRE_GPU_ENV};
#[cfg(feature = "gpu")]
pub use gate::gpu;
pub use tolerance::{CaseStats, Comparison, RunStats, Tie, Tolerance, Verdict};
