//! The GPU gate of every GPU test.

// `super`: the crate root here; shadow-map-core's tests compile this file by path into their own
// `common::gpu`, which imports the same constant.
use super::REQUIRE_GPU_ENV;
use shadow_map_core::{gpu::GpuContext, Result};
use std::sync::Arc;

/// The shared Vulkan context the GPU tests run on.
pub type SharedContext = Arc<GpuContext>;

/// The shared context, or `None` after printing a loud skip message (`SKIPPED (no Vulkan
/// adapter): <test>: ...` on stderr). With `SOFTSHADOW_REQUIRE_GPU=1` a missing adapter is a
/// failure (an `Err`), never a skip.
pub fn context_for_tests(test: &str) -> Result<Option<SharedContext>> {
    match GpuContext::shared() {
        Ok(c) => Ok(Some(c)),
        Err(e) => {
            if std::env::var(REQUIRE_GPU_ENV).is_ok_and(|v| v == "1") {
                Err(e)
            } else {
                eprintln!("SKIPPED (no Vulkan adapter): {test}: {e}");
                Ok(None)
            }
        }
    }
}

/// The shared Vulkan context for test `test` ([`context_for_tests`], a failure a panic).
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
