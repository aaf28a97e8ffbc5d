//! `depth=f32` against `depth=unorm16`: estimate time (median of interleaved runs), build time
//! and light-space bytes of each baseline, on the CPU and (feature `gpu`, with an adapter) the
//! GPU, at the fixture's full image size and r = 1024 (or `--resolution R`). The GPU rows run the
//! registry's GPU estimator, the method's frame: its build only fits the views and uploads the
//! casters (pipeline compilation, `prepare`, is left out), and the maps are rendered within the
//! frame, so their time lands in the estimate: compare build + estimate there.
//!
//! ```sh
//! WGPU_BACKEND=vulkan cargo run --release -p softshadow-baselines --example depth_speed -- [--runs N] [--resolution R] [fixture ...]
//! ```
use baselines::{HardShadow, MultiSample, PcfShadow, PcssShadow};
use shadow_map_core::{run, Receivers, Scene, SceneBvh, SoftShadowEstimator};

type Make = fn() -> shadow_map_core::Result<Box<dyn SoftShadowEstimator>>;

fn cpu_estimators() -> Vec<(&'static str, Make)> {
    vec![
        ("hard", || Ok(Box::new(HardShadow::new()?))),
        ("pcf", || Ok(Box::new(PcfShadow::new()?))),
        ("pcss", || Ok(Box::new(PcssShadow::new()?))),
        ("multi-sample", || Ok(Box::new(MultiSample::new()?))),
    ]
}

#[cfg(feature = "gpu")]
fn gpu_estimators() -> Vec<(&'static str, Make)> {
    use shadow_map_core::gpu::GpuContext;
    if GpuContext::shared().is_err() {
        eprintln!("no GPU adapter: CPU rows only");
        return Vec::new();
    }
    fn gpu(
        d: shadow_map_core::MethodDescriptor,
    ) -> shadow_map_core::Result<Box<dyn SoftShadowEstimator>> {
        d.gpu(GpuContext::shared()?)
            .unwrap_or_else(|| Err(shadow_map_core::Error::param("backend", "no GPU estimator")))
    }
    vec![
        ("hard", || gpu(baselines::HARD)),
        ("pcf", || gpu(baselines::PCF)),
        ("pcss", || gpu(baselines::PCSS)),
        ("multi-sample", || gpu(baselines::MULTI_SAMPLE)),
    ]
}
#[cfg(not(feature = "gpu"))]
fn gpu_estimators() -> Vec<(&'static str, Make)> {
    Vec::new()
}

/// The build's time: the CPU twins' `build` stage, the GPU estimators' `upload` and `fit`.
fn build_ms(r: &shadow_map_core::Report) -> f64 {
    r.total_ms("build") + r.total_ms("upload") + r.total_ms("fit")
}

fn median(mut x: Vec<f64>) -> f64 {
    x.sort_by(f64::total_cmp);
    x[x.len() / 2]
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut runs = 5usize;
    let mut resolution = "1024".to_string();
    let mut fixtures = Vec::new();
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        match a.as_str() {
            "--runs" => runs = args.next().ok_or("--runs N")?.parse()?,
            "--resolution" => resolution = args.next().ok_or("--resolution R")?,
            f => fixtures.push(f.to_string()),
        }
    }
    if fixtures.is_empty() {
        fixtures = vec!["bunny".into(), "hair".into(), "sphere-light".into()];
    }
    let dir = concat!(env!("CARGO_MANIFEST_DIR"), "/../../fixtures");
    println!("| fixture | algo | backend | estimate ms f32 | estimate ms unorm16 | u16/f32 | build ms f32 / u16 | build+estimate u16/f32 | bytes f32 -> u16 |");
    println!("|---|---|---|---|---|---|---|---|---|");
    for f in &fixtures {
        let scene = Scene::load(format!("{dir}/{f}/{f}.toml"))?;
        let rec = Receivers::from_camera(&scene, &SceneBvh::new(&scene));
        for (backend, list) in [("cpu", cpu_estimators()), ("gpu", gpu_estimators())] {
            for (name, make) in list {
                let mut e = make()?;
                e.set_param("resolution", &resolution)?;
                // Warm-up (pipelines, caches), then interleaved runs.
                for depth in ["f32", "unorm16"] {
                    e.set_param("depth", depth)?;
                    run(e.as_mut(), &scene, &rec)?;
                }
                let mut est = [Vec::new(), Vec::new()];
                let mut build = [Vec::new(), Vec::new()];
                let mut total = [Vec::new(), Vec::new()];
                let mut bytes = [0usize; 2];
                for _ in 0..runs {
                    for (i, depth) in ["f32", "unorm16"].iter().enumerate() {
                        e.set_param("depth", depth)?;
                        let (_, r) = run(e.as_mut(), &scene, &rec)?;
                        est[i].push(r.total_ms("estimate"));
                        build[i].push(build_ms(&r));
                        total[i].push(build_ms(&r) + r.total_ms("estimate"));
                        bytes[i] = r.light_space_bytes;
                    }
                }
                let [e0, e1] = est.map(median);
                let [b0, b1] = build.map(median);
                let [t0, t1] = total.map(median);
                println!(
                    "| {f} | {name} | {backend} | {e0:.1} | {e1:.1} | {:.2} | {b0:.1} / {b1:.1} | {:.2} | {} -> {} |",
                    e1 / e0,
                    t1 / t0,
                    bytes[0],
                    bytes[1]
                );
            }
        }
    }
    Ok(())
}
