//! `depth=f32` against `depth=unorm16`: estimate time (median of interleaved runs), build time
//! (on the GPU the f32 build is only submitted, and its work lands in the estimate, while the
//! 16-bit build waits for its encoder: compare build + estimate there) and light-space bytes of
//! each single-map baseline, on the CPU and (feature `gpu`, with an
//! adapter) the GPU, at the fixture's full image size and r = 1024 (or `--resolution R`).
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
    use baselines::{GpuHardShadow, GpuMultiSample, GpuPcfShadow, GpuPcssShadow};
    use shadow_map_core::gpu::GpuContext;
    if GpuContext::shared().is_err() {
        eprintln!("no GPU adapter: CPU rows only");
        return Vec::new();
    }
    vec![
        ("hard", || {
            Ok(Box::new(GpuHardShadow::new(GpuContext::shared()?)?))
        }),
        ("pcf", || {
            Ok(Box::new(GpuPcfShadow::new(GpuContext::shared()?)?))
        }),
        ("pcss", || {
            Ok(Box::new(GpuPcssShadow::new(GpuContext::shared()?)?))
        }),
        ("multi-sample", || {
            Ok(Box::new(GpuMultiSample::new(GpuContext::shared()?)?))
        }),
    ]
}
#[cfg(not(feature = "gpu"))]
fn gpu_estimators() -> Vec<(&'static str, Make)> {
    Vec::new()
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
                        build[i].push(r.total_ms("build"));
                        total[i].push(r.total_ms("build") + r.total_ms("estimate"));
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
