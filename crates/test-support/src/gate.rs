//! The GPU gate of every GPU test.

use shadow_map_core::gpu::{context_for_tests, GpuContext};
use std::sync::Arc;

/// The shared Vulkan context the GPU tests run on.
pub type SharedContext = Arc<GpuContext>;

/// The shared Vulkan context for test `test`.
///
/// `None` only after a loud skip (`SKIPPED (no Vulkan adapter): <test>: ...` on stderr): no
/// adapter, and the GPU not required. Under `SOFTSHADOW_REQUIRE_GPU=1` a missing adapter panics
/// instead, naming the test, so CI never passes by skipping.
pub fn gpu(test: &str) -> Option<SharedContext> {
    match context_for_tests(test) {
        Ok(c) => c,
        Err(e) => panic!("{test}: {e}"),
    }
}
