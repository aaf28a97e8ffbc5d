//! # deep-shadow
//!
//! Real-time deep shadow maps for semi-transparent geometry: atomic per-texel linked lists, sorting, truncation, neighbour links, PCF and exponential filtering (Fuerst et al.), plus soft transmittance from area lights.
#![warn(missing_docs)]
pub use shadow_map_core::SoftShadowEstimator;
