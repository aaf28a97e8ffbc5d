//! Umbrella crate: re-exports the member crates.
pub use baselines;
pub use reference;
pub use shadow_map_core as core;
