//! Scenes shared by the integration tests: `test-support`'s ground quad, square occluders and
//! rect light, and the CPU estimator configured.
#![allow(dead_code, unused_imports)]
use packet_hsm::CpuPacketHsm;
use shadow_map_core::{run, Params, Receivers, Scene};
pub use test_support::fixtures::{
    assert_rmse_within, assert_valid, camera, errors, light_of_shape, line_receivers, oracle, quad,
    rect_light, scene_with, sphere_light_over_square, traced, Occ, SQUARE,
};

/// The CPU estimator with the parameters `kv`.
pub fn hsm(kv: &[(&str, &str)]) -> CpuPacketHsm {
    test_support::fixtures::with_params(CpuPacketHsm::new().unwrap(), kv)
}

/// V of [`hsm`] with `kv` on `s` at `r`.
pub fn hsm_v(kv: &[(&str, &str)], s: &Scene, r: &Receivers) -> Vec<f32> {
    run(&mut hsm(kv), s, r).unwrap().0
}

/// `kv` as a parameter table of packet-hsm's specs.
pub fn table_of(kv: &[(&str, &str)]) -> Params {
    test_support::fixtures::param_table(packet_hsm::settings::SPECS, kv)
}
