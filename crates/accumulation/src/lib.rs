//! # accumulation
//!
//! Soft shadows by shadow accumulation over a KxK kernel of elementary casters, additive and exact occlusion-bit variants (Aszodi & Szirmay-Kalos 2006).
#![warn(missing_docs)]
pub use shadow_map_core::SoftShadowEstimator;
