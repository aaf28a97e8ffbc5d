//! # packet-hsm
//!
//! Packet-based hierarchical soft shadow mapping: contour backprojection over a dual-grid MSSM, pixel packets, coherence tests, multi-view sub-lights (Yang et al. 2009).
#![warn(missing_docs)]
pub use shadow_map_core::SoftShadowEstimator;
