//! Scenes shared by the integration tests: `test-support`'s ground quad, square occluders and
//! rect light, and the CPU estimator configured.
#![allow(dead_code, unused_imports)]
use packet_hsm::CpuPacketHsm;
pub use test_support::fixtures::{
    assert_valid, camera, errors, line_receivers, oracle, quad, rect_light, scene_with, Occ, SQUARE,
};

/// The CPU estimator with the parameters `kv`.
pub fn hsm(kv: &[(&str, &str)]) -> CpuPacketHsm {
    test_support::fixtures::with_params(CpuPacketHsm::new().unwrap(), kv)
}
