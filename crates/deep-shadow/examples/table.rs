//! Deep-shadow's measurements: RMSE against the ray-traced reference (DSM, PCF 3/5/7, EDSM 3/5/7,
//! S = 2, 3 soft transmittance, the multi-sample baseline) on the strands and hair fixtures, a
//! Table 1.1-shaped speed table, and the two speed-ups (neighbour links vs naive at 7x7;
//! truncation vs none), on the CPU as fractions of an in-run ceiling. `--gpu` times the
//! registry's GPU estimator (the engine path, one frame per run, V read back) instead; its
//! report has no list counts, so its ceiling columns are `-`.
//!
//! `cargo run --release -p deep-shadow --example table -- [accuracy|extra|speed|speedups|all] [--gpu]`
//! (`speedups`: only the two speed-up ratios, no Table 1.1).
//! Environment: `DS_W`, `DS_H` (image size, default 160x120), `DS_RES` (map resolution for the
//! accuracy table, default 1024), `DS_SPP` (reference spp, default 256),
//! `DS_SPEED_W`/`DS_SPEED_H` (receivers for the speed table, default 1280x720),
//! `DS_SPEED_RES` (comma-separated resolutions, default 256,512,1024).
use deep_shadow::CpuDeepShadow;
use shadow_map_core::{run, Receivers, Scene, SoftShadowEstimator};
use std::time::Instant;
use test_support::fixtures::{configure, fixture, max_abs_diff, rmse};

fn env(k: &str, d: u32) -> u32 {
    std::env::var(k)
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(d)
}

/// The ray-traced reference's V with parameters `kv`.
fn reference_v(scene: &Scene, rec: &Receivers, kv: &[(&str, &str)]) -> Vec<f32> {
    let mut reference = reference::ReferenceEstimator::new().unwrap();
    configure(&mut reference, kv);
    run(&mut reference, scene, rec).unwrap().0
}

/// A CPU deep shadow map with each parameter list of `kvs` set in turn.
fn cpu_ds(kvs: &[&[(&str, &str)]]) -> CpuDeepShadow {
    let mut e = CpuDeepShadow::new().unwrap();
    for kv in kvs {
        configure(&mut e, kv);
    }
    e
}

/// The registry's GPU estimator: the engine path run by the core's `FrameTwin`.
#[cfg(feature = "gpu")]
fn gpu_est() -> Option<Box<dyn SoftShadowEstimator>> {
    let ctx = shadow_map_core::gpu::GpuContext::shared().ok()?;
    deep_shadow::DESCRIPTOR.gpu(ctx)?.ok()
}
#[cfg(not(feature = "gpu"))]
fn gpu_est() -> Option<Box<dyn SoftShadowEstimator>> {
    None
}

/// Milliseconds of a run's build: the CPU twin's `build` stages, the GPU estimator's `upload`
/// and `fit` (its one-time `prepare`, pipelines and maps, left out).
fn build_ms(rep: &shadow_map_core::Report) -> f64 {
    rep.total_ms("build") + rep.total_ms("upload") + rep.total_ms("fit")
}

fn accuracy() {
    let (w, h) = (env("DS_W", 160), env("DS_H", 120));
    let res = env("DS_RES", 1024).to_string();
    let spp = env("DS_SPP", 256).to_string();
    let rows: Vec<(&str, Vec<(&str, &str)>)> = vec![
        ("DSM", vec![("filter", "none")]),
        ("DSM PCF 3", vec![("filter", "pcf"), ("kernel", "3")]),
        ("DSM PCF 5", vec![("filter", "pcf"), ("kernel", "5")]),
        ("DSM PCF 7", vec![("filter", "pcf"), ("kernel", "7")]),
        ("EDSM 3", vec![("filter", "edsm"), ("kernel", "3")]),
        ("EDSM 5", vec![("filter", "edsm"), ("kernel", "5")]),
        ("EDSM 7", vec![("filter", "edsm"), ("kernel", "7")]),
        ("DSM S=2", vec![("filter", "none"), ("sublights", "2")]),
        ("DSM S=3", vec![("filter", "none"), ("sublights", "3")]),
        (
            "PCF 3 S=2",
            vec![("filter", "pcf"), ("kernel", "3"), ("sublights", "2")],
        ),
        (
            "PCF 3 S=3",
            vec![("filter", "pcf"), ("kernel", "3"), ("sublights", "3")],
        ),
        ("DSM S=4", vec![("filter", "none"), ("sublights", "4")]),
        ("DSM eps=0", vec![("filter", "none"), ("epsilon", "0")]),
    ];
    println!(
        "## Accuracy: RMSE of V against reference (spp {spp}), {w}x{h} receivers, resolution {res}"
    );
    println!("| fixture | estimator | RMSE | build ms | estimate ms |");
    println!("|---|---|---|---|---|");
    for name in ["strands", "hair"] {
        let (scene, rec) = fixture(name, w, h);
        let vref = reference_v(&scene, &rec, &[("spp", &spp)]);
        // The reference's own noise: a second, independent run.
        let vref2 = reference_v(&scene, &rec, &[("spp", &spp), ("seed", "12345")]);
        println!(
            "| {name} | reference vs itself (other seed), / sqrt 2 | {:.4} | | |",
            rmse(&vref, &vref2, rec.active()) / 2f64.sqrt()
        );
        for (label, kv) in &rows {
            let mut e = cpu_ds(&[&[("resolution", &res)], kv]);
            let (v, rep) = run(&mut e, &scene, &rec).unwrap();
            println!(
                "| {name} | {label} | {:.4} | {:.1} | {:.1} |",
                rmse(&v, &vref, rec.active()),
                rep.total_ms("build"),
                rep.total_ms("estimate")
            );
        }
        for s in ["2", "4"] {
            let mut ms = baselines::MultiSample::new().unwrap();
            configure(&mut ms, &[("resolution", res.as_str()), ("sublights", s)]);
            let (v, rep) = run(&mut ms, &scene, &rec).unwrap();
            println!(
                "| {name} | multi-sample S={s} (opaque) | {:.4} | {:.1} | {:.1} |",
                rmse(&v, &vref, rec.active()),
                rep.total_ms("build"),
                rep.total_ms("estimate")
            );
        }
    }
}

/// One timed configuration: median of `reps` runs of build + estimate (ms), and the report.
fn time(
    est: &mut dyn SoftShadowEstimator,
    scene: &Scene,
    rec: &Receivers,
    reps: usize,
) -> (f64, f64, shadow_map_core::Report) {
    let mut b = Vec::new();
    let mut e = Vec::new();
    let mut last = None;
    for _ in 0..reps {
        let (_, rep) = run(est, scene, rec).unwrap();
        b.push(build_ms(&rep));
        e.push(rep.total_ms("estimate"));
        last = Some(rep);
    }
    b.sort_by(f64::total_cmp);
    e.sort_by(f64::total_cmp);
    (b[reps / 2], e[reps / 2], last.unwrap())
}

fn note<'a>(rep: &'a shadow_map_core::Report, k: &str) -> &'a str {
    rep.notes
        .iter()
        .find(|n| n.0 == k)
        .map(|n| n.1.as_str())
        .unwrap_or("-")
}

/// In-run ceilings on this machine, in this process: bare list inserts per second (counter +
/// head exchange + element write at random texels, one thread, as the CPU build's insert pass),
/// and element reads per second streaming through memory on every core (rayon), an upper bound
/// for list elements visited by lookups.
fn ceilings() -> (f64, f64) {
    use rayon::prelude::*;
    use std::sync::atomic::{AtomicU32, Ordering};
    let n = 1 << 22;
    let head: Vec<AtomicU32> = (0..1 << 20).map(|_| AtomicU32::new(u32::MAX)).collect();
    let mut nodes = vec![[0u32; 8]; n];
    let counter = AtomicU32::new(0);
    let mut x = 12345u32;
    let mut inserts = 0.0f64;
    for _ in 0..3 {
        counter.store(0, Ordering::Relaxed);
        let t = Instant::now();
        for _ in 0..n {
            x ^= x << 13;
            x ^= x >> 17;
            x ^= x << 5;
            let i = counter.fetch_add(1, Ordering::Relaxed) as usize;
            nodes[i][3] = head[(x >> 12) as usize].swap(i as u32, Ordering::Relaxed);
            nodes[i][0] = x;
        }
        inserts = inserts.max(n as f64 / t.elapsed().as_secs_f64());
    }
    let mut taps = 0.0f64;
    for _ in 0..3 {
        let t = Instant::now();
        let s: u64 = nodes.par_iter().map(|e| e[0] as u64 + e[3] as u64).sum();
        taps = taps.max(n as f64 / t.elapsed().as_secs_f64());
        std::hint::black_box(s);
    }
    (inserts, taps)
}

/// What the speed tables share: the hair fixture at the speed size, the estimator factory and
/// the ceilings.
struct SpeedRun<'a> {
    scene: Scene,
    rec: Receivers,
    resolutions: Vec<String>,
    backend: &'static str,
    mk: &'a dyn Fn() -> Box<dyn SoftShadowEstimator>,
    /// List inserts per second on the CPU (`None` on the GPU: no in-run ceiling there).
    ins: Option<f64>,
    /// CPU element reads per second (`None` on the GPU).
    taps: Option<f64>,
}

impl SpeedRun<'_> {
    /// [`time`] (3 runs) of a fresh estimator with each parameter list of `kvs` set in turn.
    fn time(&self, kvs: &[&[(&str, &str)]]) -> (f64, f64, shadow_map_core::Report) {
        let mut e = (self.mk)();
        for kv in kvs {
            configure(e.as_mut(), kv);
        }
        time(e.as_mut(), &self.scene, &self.rec, 3)
    }
}

fn speed(use_gpu: bool, table: bool) {
    let (w, h) = (env("DS_SPEED_W", 1280), env("DS_SPEED_H", 720));
    let resolutions: Vec<String> = std::env::var("DS_SPEED_RES")
        .unwrap_or_else(|_| "256,512,1024".into())
        .split(',')
        .map(|s| s.trim().to_string())
        .collect();
    let (scene, rec) = fixture("hair", w, h);
    let backend = if use_gpu { "gpu" } else { "cpu" };
    let mk = || -> Box<dyn SoftShadowEstimator> {
        if use_gpu {
            gpu_est().expect("no GPU adapter")
        } else {
            Box::new(CpuDeepShadow::new().unwrap())
        }
    };
    println!("## Speed ({backend}), hair fixture, {w}x{h} receivers ({} active); median of 3; ms = build + estimate", rec.active_count());
    let (ins, taps) = if use_gpu {
        (None, None)
    } else {
        let (ins, taps) = ceilings();
        println!(
            "in-run ceilings (CPU): {:.1} M list inserts/s (1 thread), {:.1} M element reads/s (streaming, all cores)",
            ins / 1e6,
            taps / 1e6
        );
        (Some(ins), Some(taps))
    };
    let run = SpeedRun {
        scene,
        rec,
        resolutions,
        backend,
        mk: &mk,
        ins,
        taps,
    };
    if table {
        speed_table(&run);
    }
    speedups(&run);
}

/// Table 1.1: build + estimate per configuration and resolution, with the last (EDSM7) run's
/// fragments and throughputs as fractions of the ceilings, then its stages.
fn speed_table(run: &SpeedRun) {
    let cols: Vec<(&str, Vec<(&str, &str)>)> = vec![
        ("SM", vec![("filter", "first")]),
        ("DSM", vec![("filter", "none")]),
        ("DSM3", vec![("filter", "pcf"), ("kernel", "3")]),
        ("DSM5", vec![("filter", "pcf"), ("kernel", "5")]),
        ("EDSM", vec![("filter", "edsm"), ("kernel", "1")]),
        ("EDSM3", vec![("filter", "edsm"), ("kernel", "3")]),
        ("EDSM5", vec![("filter", "edsm"), ("kernel", "5")]),
        ("EDSM7", vec![("filter", "edsm"), ("kernel", "7")]),
    ];
    print!("| SM res |");
    for c in &cols {
        print!(" {} ms |", c.0);
    }
    println!(" fragments | build ms | inserts/s as fraction of insert ceiling | EDSM7 element visits/s as fraction of CPU read ceiling |");
    println!("|{}", "---|".repeat(cols.len() + 5));
    let mut breakdown = Vec::new();
    for res in &run.resolutions {
        print!("| {res} |");
        let mut last = None;
        for (_, kv) in &cols {
            let (b, est, rep) = run.time(&[&[("resolution", res)], kv]);
            print!(" {:.1} |", b + est);
            last = Some((b, est, rep));
        }
        let (b, est, rep) = last.unwrap();
        breakdown.push((
            res.clone(),
            rep.stages
                .iter()
                .map(|(k, v)| format!("{k} {v:.1}"))
                .collect::<Vec<_>>()
                .join(", "),
        ));
        let frags: Option<f64> = note(&rep, "fragments").parse().ok();
        let visits: Option<f64> = note(&rep, "elements_per_lookup")
            .parse()
            .ok()
            .map(|e: f64| e * run.rec.active_count() as f64);
        let fraction = |x: Option<f64>, ms: f64, ceiling: Option<f64>| {
            x.zip(ceiling).map_or("-".to_string(), |(x, c)| {
                format!("{:.3}", x / (ms / 1e3) / c)
            })
        };
        println!(
            " {} | {b:.1} | {} | {} |",
            frags.map_or("-".to_string(), |f| f.to_string()),
            fraction(frags, b, run.ins),
            fraction(visits, est, run.taps)
        );
    }
    println!();
    println!("Stages of the last EDSM7 run (ms):");
    for (res, b) in &breakdown {
        println!("- {res}: {b}");
    }
    println!();
}

/// The two speed-ups at PCF 7x7: neighbour links vs naive traversal, truncation vs none.
fn speedups(run: &SpeedRun) {
    let backend = run.backend;
    println!("| speed-up ({backend}) | res | config A ms (estimate) | config B ms (estimate) | B/A - 1 | elements visited per lookup A / B | paper |");
    println!("|---|---|---|---|---|---|---|");
    for res in &run.resolutions {
        let pcf7 = [
            ("resolution", res.as_str()),
            ("filter", "pcf"),
            ("kernel", "7"),
        ];
        let (_, ea, ra) = run.time(&[&pcf7, &[("traversal", "linked")]]);
        let (_, eb, rb) = run.time(&[&pcf7, &[("traversal", "naive")]]);
        println!(
            "| links (A) vs naive (B), PCF 7x7 | {res} | {ea:.1} | {eb:.1} | {:+.0}% | {} / {} | +50% (720p), +100% (1080p) |",
            (eb / ea - 1.0) * 100.0,
            note(&ra, "elements_per_lookup"),
            note(&rb, "elements_per_lookup")
        );
        let (ba, ea, ra) = run.time(&[&pcf7, &[("epsilon", "0.001")]]);
        let (bb, eb, rb) = run.time(&[&pcf7, &[("epsilon", "0")]]);
        println!(
            "| truncation eps=1e-3 (A) vs none (B), PCF 7x7, build+estimate | {res} | {:.1} | {:.1} | {:+.0}% | {} / {} | about +40% frame time |",
            ba + ea,
            bb + eb,
            ((bb + eb) / (ba + ea) - 1.0) * 100.0,
            note(&ra, "elements_per_lookup"),
            note(&rb, "elements_per_lookup")
        );
    }
}

/// Truncation error against no truncation, and EDSM's c, on both fixtures.
fn extra() {
    let (w, h) = (env("DS_W", 160), env("DS_H", 120));
    let res = env("DS_RES", 1024).to_string();
    let spp = env("DS_SPP", 256).to_string();
    println!("## Truncation and EDSM c ({w}x{h}, resolution {res}, reference spp {spp})");
    println!("| fixture | what | value |");
    println!("|---|---|---|");
    for name in ["strands", "hair"] {
        let (scene, rec) = fixture(name, w, h);
        let vref = reference_v(&scene, &rec, &[("spp", &spp)]);
        for filter in [
            &[("filter", "none")][..],
            &[("filter", "pcf"), ("kernel", "7")][..],
        ] {
            let mut a = cpu_ds(&[&[("resolution", &res), ("epsilon", "0.001")], filter]);
            let (va, ra) = run(&mut a, &scene, &rec).unwrap();
            let mut b = cpu_ds(&[&[("resolution", &res), ("epsilon", "0")], filter]);
            let (vb, _) = run(&mut b, &scene, &rec).unwrap();
            let worst = max_abs_diff(&va, &vb);
            println!(
                "| {name} | {filter:?}: truncation eps=1e-3 vs none: max abs dV, RMS dV, fragments truncated of all | {worst:.2e}, {:.2e}, {} of {} |",
                rmse(&va, &vb, rec.active()),
                note(&ra, "truncated"),
                note(&ra, "fragments")
            );
        }
        for c in ["20", "80", "300", "1000", "10000"] {
            let kv = [
                ("resolution", res.as_str()),
                ("filter", "edsm"),
                ("kernel", "5"),
                ("c", c),
            ];
            let (v, _) = run(&mut cpu_ds(&[&kv]), &scene, &rec).unwrap();
            println!(
                "| {name} | EDSM 5, c = {c}: RMSE | {:.4} |",
                rmse(&v, &vref, rec.active())
            );
        }
    }
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let what = args.first().map(String::as_str).unwrap_or("all");
    let gpu = args.iter().any(|a| a == "--gpu");
    if what == "accuracy" || what == "all" {
        accuracy();
    }
    if what == "extra" || what == "all" {
        extra();
    }
    if what == "speed" || what == "all" {
        speed(gpu, true);
    }
    if what == "speedups" {
        speed(gpu, false);
    }
}
