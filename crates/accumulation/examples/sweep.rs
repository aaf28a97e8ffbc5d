//! Accumulation's K x resolution sweep: RMSE against the ray-traced reference and estimate time,
//! for both variants and both kernel modes, on every fixture with a sphere or disk light
//! (sphere-light, strands), with PCSS and multi-sample (baselines) beside them.
//!
//! ```text
//! cargo run --release -p accumulation --example sweep -- [--size 96x72] [--spp 1024]
//!     [--res 256,512,1024,2048] [--k 3,5,7,10,15] [--fixtures sphere-light,strands] [--extra]
//! ```
//!
//! Camera images are shrunk to `--size` (default 96x72) to keep the run to a few minutes on two
//! cores. Times are CPU wall-clock of `estimate` (the map build is listed separately). `--extra`
//! adds the layers study (exact variant, 1..4 layers, on the overlapping fixture) and the sphere
//! model comparison (contract vs paper).
use accumulation::CpuAccumulation;
use baselines::{MultiSample, PcssShadow};
use reference::ReferenceEstimator;
use shadow_map_core::{run, Receivers, Scene, SceneBvh, SoftShadowEstimator};
use std::time::Instant;

mod common;

struct Args {
    size: (u32, u32),
    spp: u32,
    res: Vec<u32>,
    ks: Vec<u32>,
    fixtures: Vec<String>,
    extra: bool,
}

fn list(s: &str) -> Vec<u32> {
    s.split(',').filter_map(|x| x.trim().parse().ok()).collect()
}

fn args() -> Args {
    let mut a = Args {
        size: (96, 72),
        spp: 1024,
        res: vec![256, 512, 1024, 2048],
        ks: vec![3, 5, 7, 10, 15],
        fixtures: vec!["sphere-light".into(), "strands".into()],
        extra: false,
    };
    for (flag, value) in common::flags(&["--extra"]) {
        match flag.as_str() {
            "--size" => a.size = common::size(&value),
            "--spp" => a.spp = value.parse().unwrap_or(a.spp),
            "--res" => a.res = list(&value),
            "--k" => a.ks = list(&value),
            "--fixtures" => a.fixtures = value.split(',').map(String::from).collect(),
            "--extra" => a.extra = true,
            other => panic!("unknown argument {other}"),
        }
    }
    a
}

fn rmse(v: &[f32], r: &[f32], active: &[bool]) -> f64 {
    let (mut s, mut n) = (0.0f64, 0usize);
    for k in 0..v.len() {
        if active[k] {
            let d = v[k] as f64 - r[k] as f64;
            s += d * d;
            n += 1;
        }
    }
    (s / n.max(1) as f64).sqrt()
}

/// Runs an estimator with parameters; returns (RMSE, build ms, estimate ms). Estimate time is the
/// best of `reps` runs.
fn measure(
    e: &mut dyn SoftShadowEstimator,
    kv: &[(&str, String)],
    scene: &Scene,
    rec: &Receivers,
    reference: &[f32],
) -> (f64, f64, f64) {
    for (k, v) in kv {
        e.set_param(k, v).unwrap();
    }
    let (v, report) = match run(e, scene, rec) {
        Ok(x) => x,
        Err(err) => {
            println!("  {} {kv:?}: error {err}", e.name());
            return (f64::NAN, f64::NAN, f64::NAN);
        }
    };
    let mut best = report.total_ms("estimate");
    for _ in 0..1 {
        let mut w = vec![0.0; rec.len()];
        let t = Instant::now();
        e.estimate(scene, rec, &mut w).unwrap();
        best = best.min(t.elapsed().as_secs_f64() * 1e3);
    }
    (
        rmse(&v, reference, rec.active()),
        report.total_ms("build"),
        best,
    )
}

fn fixture(name: &str) -> String {
    format!(
        "{}/../../fixtures/{name}/{name}.toml",
        env!("CARGO_MANIFEST_DIR")
    )
}

fn load(name: &str, a: &Args) -> (Scene, Receivers, Vec<f32>) {
    let mut scene = Scene::load(fixture(name)).unwrap();
    scene.set_resolution(a.size.0, a.size.1).unwrap();
    let rec = Receivers::from_camera(&scene, &SceneBvh::new(&scene));
    let mut re = ReferenceEstimator::new().unwrap();
    re.set_param("spp", &a.spp.to_string()).unwrap();
    let t = Instant::now();
    let (reference, _) = run(&mut re, &scene, &rec).unwrap();
    eprintln!(
        "{name}: {} active receivers, reference {} spp in {:.1} s",
        rec.active_count(),
        a.spp,
        t.elapsed().as_secs_f64()
    );
    (scene, rec, reference)
}

fn main() {
    let a = args();
    println!(
        "# accumulation sweep: camera {}x{}, reference {} spp, CPU times (ms, estimate stage)",
        a.size.0, a.size.1, a.spp
    );
    for name in a.fixtures.iter().filter(|f| !f.is_empty()) {
        let (scene, rec, reference) = load(name, &a);
        println!("\n## {name} ({} receivers)\n", rec.active_count());
        println!("| method | variant | kernel | K | res | RMSE | build ms | estimate ms |");
        println!("|---|---|---|---|---|---|---|---|");
        for &res in &a.res {
            for variant in ["additive", "exact"] {
                for kernel in ["fixed", "adaptive", "lexels"] {
                    for &k in &a.ks {
                        let mut e = CpuAccumulation::new().unwrap();
                        let kv = [
                            ("resolution", res.to_string()),
                            ("variant", variant.to_string()),
                            ("kernel", kernel.to_string()),
                            ("k", k.to_string()),
                        ];
                        let (r, b, t) = measure(&mut e, &kv, &scene, &rec, &reference);
                        println!("| accumulation | {variant} | {kernel} | {k} | {res} | {r:.4} | {b:.1} | {t:.1} |");
                    }
                }
            }
            let mut e = PcssShadow::new().unwrap();
            let (r, b, t) = measure(
                &mut e,
                &[("resolution", res.to_string())],
                &scene,
                &rec,
                &reference,
            );
            println!("| pcss | - | - | - | {res} | {r:.4} | {b:.1} | {t:.1} |");
            for sub in [2u32, 4, 8] {
                let mut e = MultiSample::new().unwrap();
                let kv = [
                    ("resolution", res.to_string()),
                    ("sublights", sub.to_string()),
                ];
                let (r, b, t) = measure(&mut e, &kv, &scene, &rec, &reference);
                println!(
                    "| multi-sample {sub}x{sub} | - | - | - | {res} | {r:.4} | {b:.1} | {t:.1} |"
                );
            }
        }
    }
    if a.extra {
        extra(&a);
    }
}

/// Layers on the overlapping and stacked fixtures, and the sphere models on the sphere-light
/// fixture.
fn extra(a: &Args) {
    for name in ["overlapping", "stacked"] {
        layers(a, name);
    }
    spheres(a);
}

fn layers(a: &Args, name: &str) {
    let (scene, rec, reference) = load(name, a);
    println!("\n## {name}: exact variant, peeled layers (adaptive kernel, K = 10)\n");
    println!("| variant | layers | res | RMSE | estimate ms |");
    println!("|---|---|---|---|---|");
    for res in [512u32, 1024] {
        let mut e = CpuAccumulation::new().unwrap();
        let kv = [
            ("resolution", res.to_string()),
            ("kernel", "adaptive".into()),
        ];
        let (r, _, t) = measure(&mut e, &kv, &scene, &rec, &reference);
        println!("| additive | 1 | {res} | {r:.4} | {t:.1} |");
        for layers in 1..=4u32 {
            let mut e = CpuAccumulation::new().unwrap();
            let kv = [
                ("resolution", res.to_string()),
                ("variant", "exact".into()),
                ("kernel", "adaptive".into()),
                ("layers", layers.to_string()),
            ];
            let (r, _, t) = measure(&mut e, &kv, &scene, &rec, &reference);
            println!("| exact | {layers} | {res} | {r:.4} | {t:.1} |");
        }
    }
}

fn spheres(a: &Args) {
    let (scene, rec, reference) = load("sphere-light", a);
    println!("\n## sphere-light: sphere model (adaptive kernel, 1024)\n");
    println!("| sphere | variant | RMSE | estimate ms |");
    println!("|---|---|---|---|");
    for model in ["contract", "paper"] {
        for variant in ["additive", "exact"] {
            let mut e = CpuAccumulation::new().unwrap();
            let kv = [
                ("resolution", "1024".to_string()),
                ("variant", variant.into()),
                ("kernel", "adaptive".into()),
                ("sphere", model.into()),
            ];
            let (r, _, t) = measure(&mut e, &kv, &scene, &rec, &reference);
            println!("| {model} | {variant} | {r:.4} | {t:.1} |");
        }
    }
}
