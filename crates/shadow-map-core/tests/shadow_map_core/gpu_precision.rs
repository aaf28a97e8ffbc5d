//! The GPU's 16-bit encoder against the CPU's [`Unorm16Map::encode`]: bit-identical codes for the
//! same f32 depths, on random maps with empty texels, NaN, depths beyond far and below n, odd
//! sides (the last packed word half empty) and sides of 1. Without a Vulkan adapter the test
//! prints `SKIPPED (no Vulkan adapter)` and returns; under `SOFTSHADOW_REQUIRE_GPU=1` it fails.
#![cfg(feature = "gpu")]

use crate::common;
use proptest::prelude::*;
use proptest::test_runner::{Config, TestRunner};

use common::context_for_tests;
use shadow_map_core::{
    gpu::{upload_depth_map, GpuUnorm16Encoder, GpuUnorm16Map},
    DepthMap, Unorm16Map,
};

fn depth() -> impl Strategy<Value = f32> {
    prop_oneof![
        8 => 0.5f32..20.0,
        1 => Just(f32::INFINITY),
        1 => Just(f32::NAN),
        1 => -1.0f32..0.5,
        1 => 20.0f32..1e6,
    ]
}

#[test]
fn gpu_encoder_matches_cpu_codes_bit_for_bit() -> Result<(), Box<dyn std::error::Error>> {
    let Some(ctx) = context_for_tests("gpu_encoder_matches_cpu_codes_bit_for_bit")? else {
        return Ok(());
    };
    let enc = GpuUnorm16Encoder::new(&ctx)?;
    let cases = std::env::var("SOFTSHADOW_PROPTEST_CASES")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(24);
    let mut runner = TestRunner::new(Config {
        cases,
        failure_persistence: None,
        ..Config::default()
    });
    let strategy = (1u32..40, 0.5f32..5.0, 5.0f32..20.0).prop_flat_map(|(size, n, far)| {
        (
            Just(size),
            Just(n),
            Just(far),
            proptest::collection::vec(depth(), (size * size) as usize),
        )
    });
    runner.run(&strategy, |(size, n, far, depth)| {
        let map = DepthMap { size, depth };
        let cpu = Unorm16Map::encode(&map, n, far);
        let gpu = (|| -> shadow_map_core::Result<Unorm16Map> {
            let g = upload_depth_map(&ctx, &map)?;
            enc.encode(&ctx, &g, n, far)?.read(&ctx)
        })()
        .map_err(|e| TestCaseError::fail(e.to_string()))?;
        prop_assert_eq!(cpu.step, gpu.step);
        for k in 0..cpu.codes.len() {
            prop_assert_eq!(
                cpu.codes[k],
                gpu.codes[k],
                "texel {} depth {} (n {}, far {}, step {})",
                k,
                map.depth[k],
                n,
                far,
                cpu.step
            );
        }
        // And the upload of CPU codes round-trips.
        let back = GpuUnorm16Map::upload(&ctx, &cpu)
            .and_then(|g| g.read(&ctx))
            .map_err(|e| TestCaseError::fail(e.to_string()))?;
        prop_assert_eq!(&back.codes, &cpu.codes);
        Ok(())
    })?;
    Ok(())
}
