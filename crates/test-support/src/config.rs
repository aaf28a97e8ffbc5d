//! How many random cases a test runs, and the proptest configuration of the twin tests.

use proptest::test_runner::{Config, FileFailurePersistence};

/// The environment variable that overrides every random test's number of cases.
pub const CASES_ENV: &str = "SOFTSHADOW_PROPTEST_CASES";

/// The environment variable that turns a missing adapter in GPU tests from a loud skip into a
/// failure (`1`).
pub const REQUIRE_GPU_ENV: &str = "SOFTSHADOW_REQUIRE_GPU";

/// The extension of the files that keep failing cases, beside their test file
/// (`tests/gpu_twin.rs` keeps them in `tests/gpu_twin.proptest-regressions`).
pub const REGRESSIONS_EXT: &str = "proptest-regressions";

/// Shrink iterations at most: enough to shrink a failing twin case down to a scene of a few
/// receivers and no boxes, without spending an hour of GPU runs on it.
pub const MAX_SHRINK_ITERS: u32 = 4096;

/// The number of random cases: `SOFTSHADOW_PROPTEST_CASES` when it is set to a number, else
/// `default` (each test's own, small enough for lavapipe on a CI machine).
pub fn cases(default: u32) -> u32 {
    std::env::var(CASES_ENV)
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(default)
}

/// The proptest configuration of a random twin test in `source_file` (pass `file!()`):
/// [`cases`]`(default_cases)` cases, at most [`MAX_SHRINK_ITERS`] shrink steps, and failures
/// persisted in (and replayed first from) the file beside it with the extension
/// [`REGRESSIONS_EXT`]. Everything else is proptest's default (its `PROPTEST_*` variables
/// included).
pub fn proptest_config(source_file: &'static str, default_cases: u32) -> Config {
    Config {
        cases: cases(default_cases),
        source_file: Some(source_file),
        max_shrink_iters: MAX_SHRINK_ITERS,
        failure_persistence: Some(Box::new(FileFailurePersistence::WithSource(
            REGRESSIONS_EXT,
        ))),
        ..Config::default()
    }
}
