//! Rendering a fixture on the CPU with any registered estimator, as a library user would: load the
//! scene, cast the camera's rays for receivers, build and estimate, read the stage times.
//!
//! ```text
//! cargo run --release --example render_cpu -- fixtures/bunny/bunny.toml pcss resolution=512
//! ```
use shadow_map_core::{run, Receivers, Scene, SceneBvh};
use softshadow::{estimator, Backend};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let path = args
        .first()
        .map(String::as_str)
        .unwrap_or("fixtures/parallel-squares/parallel-squares.toml");
    let algo = args.get(1).map(String::as_str).unwrap_or("pcss");
    let scene = Scene::load(path)?;
    let receivers = Receivers::from_camera(&scene, &SceneBvh::new(&scene));
    let mut est = estimator(algo, Backend::Cpu)?;
    for kv in args.iter().skip(2) {
        let (k, v) = shadow_map_core::params::parse_assignment(kv)?;
        est.set_param(k, v)?;
    }
    let (v, report) = run(est.as_mut(), &scene, &receivers)?;
    let lit: Vec<f32> = v.iter().copied().filter(|x| !x.is_nan()).collect();
    let mean = lit.iter().sum::<f32>() / lit.len().max(1) as f32;
    println!(
        "{algo} on {path}: {} receivers, mean V {mean:.4}, build {:.1} ms, estimate {:.1} ms",
        lit.len(),
        report.total_ms("build"),
        report.total_ms("estimate")
    );
    for (k, v) in &report.notes {
        println!("  {k} = {v}");
    }
    Ok(())
}
