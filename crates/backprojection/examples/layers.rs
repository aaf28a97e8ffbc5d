//! Cost of depth layers, in one run: frame time (build + estimate) of the backprojection
//! estimator with k = 1..=4 layers on both backends, and the 3-layer / 1-layer ratio beside
//! Bavoil 2008 Fig. 6 (Buddha: 10.8 fps with 1 layer, 7.6 fps with 3, a ratio of 1.42). The GPU
//! row is the registry's GPU estimator (the engine path run by the core's `FrameTwin`): its
//! `build` fits the light view, its `estimate` records the whole frame (layers, midpoints, MSSM,
//! kernel), submits it and reads V back.
//!
//! ```text
//! WGPU_BACKEND=vulkan cargo run --release -p backprojection --example layers [SCENE] [WxH] [RES] [RUNS]
//! ```
//! Defaults: the bunny fixture, its camera (320x240), r = 1024, 5 runs (median reported).
use backprojection::CpuBackprojection;
use shadow_map_core::{Receivers, Scene, SceneBvh, SoftShadowEstimator};
use std::time::Instant;

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn main() -> shadow_map_core::Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let scene_path = args.first().cloned().unwrap_or_else(|| {
        concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../fixtures/bunny/bunny.toml"
        )
        .into()
    });
    let mut scene = Scene::load(&scene_path)?;
    if let Some((w, h)) = args.get(1).and_then(|s| s.split_once('x')) {
        let size = |s: &str| {
            s.parse()
                .map_err(|_| shadow_map_core::Error::param("size", "WxH"))
        };
        scene.set_resolution(size(w)?, size(h)?)?;
    }
    let res = args.get(2).cloned().unwrap_or_else(|| "1024".into());
    let runs: usize = args.get(3).and_then(|s| s.parse().ok()).unwrap_or(5).max(1);
    let receivers = Receivers::from_camera(&scene, &SceneBvh::new(&scene));
    println!(
        "{scene_path}: {}x{} camera, {} active receivers, r = {res}, median of {runs}",
        scene.camera().width,
        scene.camera().height,
        receivers.active_count()
    );
    let mut estimators: Vec<Box<dyn SoftShadowEstimator>> =
        vec![Box::new(CpuBackprojection::new()?)];
    #[cfg(feature = "gpu")]
    match shadow_map_core::gpu::GpuContext::shared() {
        Ok(ctx) => {
            println!("GPU: {}", ctx.describe());
            if let Some(gpu) = backprojection::DESCRIPTOR.gpu(ctx) {
                estimators.push(gpu?);
            }
        }
        Err(e) => println!("GPU: none ({e})"),
    }
    println!("| backend | layers | build ms | estimate ms | frame ms | frame / 1-layer frame |");
    println!("|---|---|---|---|---|---|");
    let mut v = vec![0.0f32; receivers.len()];
    for e in &mut estimators {
        e.set_param("resolution", &res)?;
        let mut one = f64::NAN;
        for k in 1..=4 {
            e.set_param("layers", &k.to_string())?;
            // Warm-up (pipelines, allocations).
            e.build(&scene, &receivers)?;
            e.estimate(&scene, &receivers, &mut v)?;
            let (mut b, mut s, mut f) = (Vec::new(), Vec::new(), Vec::new());
            for _ in 0..runs {
                let t = Instant::now();
                e.build(&scene, &receivers)?;
                let tb = t.elapsed().as_secs_f64() * 1e3;
                e.estimate(&scene, &receivers, &mut v)?;
                let tf = t.elapsed().as_secs_f64() * 1e3;
                b.push(tb);
                s.push(tf - tb);
                f.push(tf);
            }
            let frame = median(f);
            if k == 1 {
                one = frame;
            }
            println!(
                "| {} | {k} | {:.2} | {:.2} | {frame:.2} | {:.2} |",
                e.backend(),
                median(b),
                median(s),
                frame / one
            );
        }
    }
    println!("Bavoil 2008 Fig. 6 (GeForce 8800 GTX, Buddha): 3-layer frame / 1-layer frame = 10.8 / 7.6 = 1.42");
    Ok(())
}
