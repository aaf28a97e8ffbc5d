//! The criterion rows every method's bench shares: an estimator's build and estimate, and one
//! frame of an engine path as a renderer runs it.
use criterion::{measurement::WallTime, BenchmarkGroup};
use shadow_map_core::{Receivers, Scene, SoftShadowEstimator};
use std::hint::black_box;

/// A bench group timed by wall clock.
pub type Group<'a> = BenchmarkGroup<'a, WallTime>;

/// `{backend}/build/{label}` and `{backend}/estimate/{label}`: `e`'s light-space build, then its
/// estimate on that build.
pub fn build_and_estimate(
    g: &mut Group<'_>,
    e: &mut dyn SoftShadowEstimator,
    label: &str,
    scene: &Scene,
    receivers: &Receivers,
) {
    let backend = e.backend();
    let mut v = vec![0.0f32; receivers.len()];
    g.bench_function(format!("{backend}/build/{label}"), |b| {
        b.iter(|| e.build(black_box(scene), receivers).expect("build"))
    });
    e.build(scene, receivers).expect("build");
    g.bench_function(format!("{backend}/estimate/{label}"), |b| {
        b.iter(|| {
            e.estimate(scene, receivers, black_box(&mut v))
                .expect("estimate")
        })
    });
}

/// `gpu/frame/{label}`: one frame of `frame` recorded, submitted and waited for (the casters and
/// receivers uploaded once, outside the timed loop; nothing read back).
#[cfg(feature = "gpu")]
pub fn frame_row(
    g: &mut Group<'_>,
    ctx: &shadow_map_core::gpu::GpuContext,
    frame: &dyn shadow_map_core::gpu::frame::FrameEstimator,
    label: &str,
    scene: &Scene,
    receivers: &Receivers,
) {
    let rig = crate::frame_run::FrameRig::new(ctx, frame, scene, receivers).expect("frame inputs");
    g.bench_function(format!("gpu/frame/{label}"), |b| {
        b.iter(|| {
            black_box(&rig).submit(ctx, frame).expect("frame");
            ctx.wait().expect("wait");
        })
    });
}
