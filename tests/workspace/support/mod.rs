//! What the workspace's integration tests share.
use softshadow::Backend;

/// The backend a registry row names (`"cpu"` or `"gpu"`), or `None` for a GPU row without a
/// Vulkan adapter (a loud skip naming `test`; under `SOFTSHADOW_REQUIRE_GPU=1` a missing adapter
/// fails instead).
pub fn runnable(backend: &str, test: &str) -> Option<Backend> {
    if backend != "gpu" {
        return Some(Backend::Cpu);
    }
    test_support::gate::context_for_tests(test)
        .expect("adapter")
        .map(|_| Backend::Gpu)
}
