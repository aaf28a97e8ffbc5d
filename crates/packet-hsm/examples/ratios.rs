//! Packet-hsm's measurements, each section in one run on one machine:
//!
//! - `speed`: packets + hierarchy vs per-pixel GBP07, hierarchy alone, packets alone, for light
//!   sizes from small to large on the same scene (Yang Fig. 13: up to 20x; hierarchy 1.5-4x), with
//!   the largest |dV| between the variants (exactness in the same run) and the visited nodes per
//!   penumbra pixel.
//! - `visits`: visited samples (nodes) per penumbra pixel: flat kernel scan (GBP07 + MSSM
//!   kernels), hierarchical over the dual-grid MSSM (Yang §4.2), and a plain min/max mip (HSM)
//!   traversal from the root as in DU07 (Yang Fig. 8).
//! - `sweep`: packet-size sweep at two image sizes (Yang Fig. 12), hierarchy off and on.
//! - `tune`: the Q_e, Q_v grid of the cost model (eq. 6; Q_n = 1): estimate time per pair, the
//!   argmin printed.
//! - `gpu`: per-pixel GBP07 against the hierarchy on the registry's GPU estimator (the frame;
//!   lavapipe here): estimate ms per variant, the largest |dV| against the CPU.
//! - `accuracy`: RMSE against the ray-traced reference and time on every fixture: GBP07 per pixel,
//!   packet-hsm S = 1, 2, 4, micropatch backprojection with 1, 3 and 4 layers, PCSS, multi-sample;
//!   and Yang's Fig. 11 claim (S = 2 faster than and as accurate as 4-layer peeling) on the
//!   overlapping fixture.
//!
//! ```text
//! cargo run --release -p packet-hsm --example ratios -- [speed|visits|sweep|tune|accuracy|all]
//! ```
//! Environment: `HSM_SCENE` (fixture name for speed/visits/sweep/tune, default bunny), `HSM_W`,
//! `HSM_H` (image, default 160x120), `HSM_RES` (map resolution, default 512), `HSM_RUNS`
//! (median of, default 3), `HSM_SPP` (reference spp, default 256), `HSM_FIXTURES`
//! (comma-separated fixture names for `accuracy`, default all).
// `!(a < b)` is deliberate: true for NaN, which must take the safe branch.
#![allow(clippy::neg_cmp_op_on_partial_ord)]
use backprojection::CpuBackprojection;
use baselines::{MultiSample, PcssShadow};
use packet_hsm::cpu::extract::{extract, Planes, Traversal};
use packet_hsm::cpu::{prepare, Prep, SubView};
use packet_hsm::math::CellRect;
use packet_hsm::settings::Config;
use packet_hsm::CpuPacketHsm;
use reference::ReferenceEstimator;
use shadow_map_core::{mssm::MinMax, Receivers, Scene, SoftShadowEstimator};
use std::time::Instant;
use test_support::fixtures::{fixture, note};

fn env(k: &str, d: &str) -> String {
    std::env::var(k).unwrap_or_else(|_| d.to_string())
}
fn envu(k: &str, d: u32) -> u32 {
    env(k, &d.to_string()).parse().unwrap_or(d)
}

/// The settings of the speed, tune and gpu sections (see the module docs).
struct Settings {
    name: String,
    w: u32,
    h: u32,
    res: String,
    runs: u32,
}

fn settings() -> Settings {
    Settings {
        name: env("HSM_SCENE", "bunny"),
        w: envu("HSM_W", 160),
        h: envu("HSM_H", 120),
        res: env("HSM_RES", "512"),
        runs: envu("HSM_RUNS", 3),
    }
}

/// The settings (name, width, height, resolution, runs) with their fixture's scene and receivers.
fn setup() -> (String, u32, u32, String, u32, Scene, Receivers) {
    let s = settings();
    let (scene, rec) = fixture(&s.name, s.w, s.h);
    (s.name, s.w, s.h, s.res, s.runs, scene, rec)
}

/// Runs `f` with the scene's light scaled by each factor, small to large (the speed, visits and
/// gpu sections' rows).
fn each_light_scale(scene: &mut Scene, mut f: impl FnMut(f32, &Scene)) {
    let base_light = *scene.light();
    for scale in [0.25f32, 0.5, 1.0, 2.0, 4.0] {
        scene.set_light(base_light.scaled(scale)).unwrap();
        f(scale, scene);
    }
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// Median estimate and frame times over `runs` (after one warm-up), V and the last report.
fn time(
    e: &mut dyn SoftShadowEstimator,
    scene: &Scene,
    rec: &Receivers,
    runs: u32,
) -> (f64, f64, Vec<f32>, shadow_map_core::Report) {
    let mut v = vec![0.0f32; rec.len()];
    e.build(scene, rec).expect("build");
    e.estimate(scene, rec, &mut v).expect("estimate");
    let (mut est, mut frame) = (Vec::new(), Vec::new());
    for _ in 0..runs.max(1) {
        let t = Instant::now();
        e.build(scene, rec).expect("build");
        e.estimate(scene, rec, &mut v).expect("estimate");
        frame.push(t.elapsed().as_secs_f64() * 1e3);
        est.push(e.report().total_ms("estimate"));
    }
    (median(est), median(frame), v, e.report())
}

fn hsm(kv: &[(&str, &str)]) -> CpuPacketHsm {
    let mut e = CpuPacketHsm::new().expect("new");
    for (k, v) in kv {
        e.set_param(k, v).expect("param");
    }
    e
}

fn boxed(e: impl SoftShadowEstimator + 'static) -> Box<dyn SoftShadowEstimator> {
    Box::new(e)
}

/// Micropatch backprojection with the parameters `kv`.
fn bp(kv: &[(&str, &str)]) -> Box<dyn SoftShadowEstimator> {
    let mut e = CpuBackprojection::new().expect("bp");
    for (k, v) in kv {
        e.set_param(k, v).expect("p");
    }
    Box::new(e)
}

fn max_diff(a: &[f32], b: &[f32]) -> f32 {
    a.iter()
        .zip(b)
        .filter(|(x, _)| x.is_finite())
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f32::max)
}

fn rmse(a: &[f32], b: &[f32], active: &[bool]) -> f64 {
    let (mut s, mut n) = (0.0, 0usize);
    for k in 0..a.len() {
        if active[k] && b[k].is_finite() {
            let d = a[k] as f64 - b[k] as f64;
            s += d * d;
            n += 1;
        }
    }
    (s / n.max(1) as f64).sqrt()
}

/// The speed tables' four variants: GBP07 per pixel, hierarchy alone, packets alone, packets +
/// hierarchy.
const VARIANTS: [&[(&str, &str)]; 4] = [
    &[
        ("packet", "1x1"),
        ("hierarchy", "false"),
        ("coherence", "false"),
    ],
    &[("packet", "1x1"), ("hierarchy", "true")],
    &[("packet", "3x3"), ("hierarchy", "false")],
    &[("packet", "3x3"), ("hierarchy", "true")],
];

/// The speed tables' time columns from the [`VARIANTS`]' estimate ms: the four times, then GBP07
/// over each of the other three.
fn variant_columns(ms: [f64; 4]) -> String {
    format!(
        "{:.1} | {:.1} | {:.1} | {:.1} | {:.2} | {:.2} | {:.2}",
        ms[0],
        ms[1],
        ms[2],
        ms[3],
        ms[0] / ms[1],
        ms[0] / ms[2],
        ms[0] / ms[3],
    )
}

fn speed() {
    let (name, w, h, res, runs, mut scene, rec) = setup();
    println!("\n## speed: {name}, {w}x{h}, r = {res}, estimate ms (median of {runs}), one shadow map (S = 1), 3x3 packets");
    println!("| light scale | GBP07 per pixel | hierarchy alone | packets alone | packets + hierarchy | GBP07 / hierarchy | GBP07 / packets | GBP07 / both | max dV | penumbra px | visited/px GBP07 | visited/px both | coherent packets |");
    println!("|---|---|---|---|---|---|---|---|---|---|---|---|---|");
    each_light_scale(&mut scene, |scale, scene| {
        let mut out = Vec::new();
        for kv in VARIANTS {
            let mut kv = kv.to_vec();
            kv.push(("resolution", &res));
            let mut e = hsm(&kv);
            out.push(time(&mut e, scene, &rec, runs));
        }
        let dv = out
            .iter()
            .map(|o| max_diff(&o.2, &out[0].2))
            .fold(0.0, f32::max);
        let coh = note(&out[3].3, "packets_coherent").unwrap_or_default();
        let pk = note(&out[3].3, "packets").unwrap_or_default();
        println!(
            "| {scale} | {} | {dv:.1e} | {} | {} | {} | {coh}/{pk} |",
            variant_columns([out[0].0, out[1].0, out[2].0, out[3].0]),
            note(&out[0].3, "penumbra_evaluations").unwrap_or_default(),
            note(&out[0].3, "visited_per_penumbra_pixel").unwrap_or_default(),
            note(&out[3].3, "visited_per_penumbra_pixel").unwrap_or_default(),
        );
    });
    println!("Yang 2009 Fig. 13 (GTX 280, 1280x1024, 3x3 packets): hierarchy 1.5-4x on top of packets; packets + hierarchy up to an order of magnitude for large lights, 20x in Fig. 1-c.");
}

/// A min/max mip (HSM) over the padded dual cells: level l node (x, y) covers anchors
/// `[x 2^l, (x+1) 2^l)`; built from the dual-grid MSSM's level 0.
struct CellPyramid {
    levels: Vec<(usize, Vec<MinMax>)>,
}

impl CellPyramid {
    fn build(sv: &SubView) -> CellPyramid {
        let d = &sv.dual.mssm;
        let p = d.size() as usize;
        let (mn, mx) = d.level(0);
        let base: Vec<MinMax> = mn
            .iter()
            .zip(mx)
            .map(|(&a, &b)| MinMax { min: a, max: b })
            .collect();
        let mut levels = vec![(p, base)];
        while levels.last().map(|l| l.0).unwrap_or(1) > 1 {
            let (s, prev) = levels.last().expect("level");
            let n = s.div_ceil(2);
            let mut next = vec![MinMax::EMPTY; n * n];
            for y in 0..n {
                for x in 0..n {
                    let mut acc = MinMax::EMPTY;
                    for (dx, dy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
                        let (cx, cy) = (2 * x + dx, 2 * y + dy);
                        if cx < *s && cy < *s {
                            acc = acc.union(prev[cy * s + cx]);
                        }
                    }
                    next[y * n + x] = acc;
                }
            }
            levels.push((n, next));
        }
        CellPyramid { levels }
    }
    /// Nodes a DU07-style traversal from the root visits for the kernel `cr` and threshold `t`.
    fn visits(&self, cr: &CellRect, t: f32) -> u64 {
        let (x0, y0, x1, y1) = (cr[0] + 1, cr[1] + 1, cr[2] + 1, cr[3] + 1);
        let top = self.levels.len() - 1;
        let mut stack = vec![(0usize, 0usize, top)];
        let mut n = 0;
        while let Some((x, y, l)) = stack.pop() {
            let (s, data) = &self.levels[l];
            if x >= *s || y >= *s {
                continue;
            }
            let span = 1i32 << l;
            let (ax, ay) = (x as i32 * span, y as i32 * span);
            if ax >= x1 || ay >= y1 || ax + span <= x0 || ay + span <= y0 {
                continue;
            }
            n += 1;
            let m = data[y * s + x];
            if m.max < t || !(m.min < t) || l == 0 {
                continue;
            }
            for (dx, dy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
                stack.push((2 * x + dx, 2 * y + dy, l - 1));
            }
        }
        n
    }
}

fn visits() {
    let (name, w, h, res, _, mut scene, rec) = setup();
    let res: u32 = res.parse().unwrap_or(512);
    println!(
        "\n## visited nodes per penumbra pixel: {name}, {w}x{h}, r = {res}, per pixel (no packets)"
    );
    println!("| light scale | penumbra px | kernel cells (flat scan) | MSSM hierarchy (Yang) | min/max mip from root (DU07) | flat / MSSM | mip / MSSM |");
    println!("|---|---|---|---|---|---|---|");
    each_light_scale(&mut scene, |scale, scene| {
        let cfg = Config::from_params(hsm(&[]).params()).expect("cfg");
        let sv = SubView::build(
            scene,
            &rec,
            (res, glam::Vec2::ZERO, scene.light().half_extent()),
            &cfg,
            packet_hsm::cpu::OwnPlane::Auto,
        )
        .expect("view");
        let grid = sv.grid(&cfg);
        let pyr = CellPyramid::build(&sv);
        let (mut flat, mut hier, mut mip, mut pen) = (0u64, 0u64, 0u64, 0u64);
        for k in 0..rec.len() {
            if !rec.active()[k] {
                continue;
            }
            let mut out = false;
            if let Prep::Penumbra { rec: r, cr, .. } = prepare(
                &sv,
                &grid,
                &cfg,
                rec.position()[k],
                rec.normal()[k],
                &mut out,
            ) {
                pen += 1;
                flat += ((cr[2] - cr[0]) as u64) * ((cr[3] - cr[1]) as u64);
                let mut n = 0;
                let one = [r.test()];
                extract(
                    &grid,
                    &sv.dual,
                    &cr,
                    [r.t, r.t],
                    Planes {
                        members: if r.plane.is_some() { &one } else { &[] },
                        class_is_depth: grid.class_is_depth(),
                        depth: Some(&sv.mssm),
                        fit: sv.fit.as_ref(),
                    },
                    Traversal::Hierarchical,
                    &mut n,
                    |_, _, _| {},
                );
                hier += n;
                mip += pyr.visits(&cr, r.t);
            }
        }
        let p = pen.max(1) as f64;
        println!(
            "| {scale} | {pen} | {:.1} | {:.1} | {:.1} | {:.2} | {:.2} |",
            flat as f64 / p,
            hier as f64 / p,
            mip as f64 / p,
            flat as f64 / hier.max(1) as f64,
            mip as f64 / hier.max(1) as f64
        );
    });
    println!(
        "Yang 2009 Fig. 8: visited samples, ours < DU07 < MSSM-only (no figures given in numbers)."
    );
}

fn sweep() {
    let name = env("HSM_SCENE", "bunny");
    let res = env("HSM_RES", "512");
    let runs = envu("HSM_RUNS", 3);
    let sizes = ["1x1", "2x1", "2x2", "3x3", "4x4", "5x5", "6x6", "8x8"];
    println!("\n## packet-size sweep: {name}, r = {res}, estimate ms (median of {runs}), S = 1");
    println!("| image | hierarchy | {} |", sizes.join(" | "));
    println!("|---|---|{}", "---|".repeat(sizes.len()));
    for (w, h) in [(160u32, 120u32), (320, 240)] {
        let (scene, rec) = fixture(&name, w, h);
        for hier in ["false", "true"] {
            let mut row = format!("| {w}x{h} | {hier} |");
            let mut best = (f64::INFINITY, "");
            for p in sizes {
                let mut e = hsm(&[("resolution", &res), ("packet", p), ("hierarchy", hier)]);
                let (t, ..) = time(&mut e, &scene, &rec, runs);
                if t < best.0 {
                    best = (t, p);
                }
                row += &format!(" {t:.1} |");
            }
            println!("{row} best {}", best.1);
        }
    }
    println!("Yang 2009 Fig. 12 (no hierarchy): larger images favour larger packets; 2x2 or 3x3 as defaults.");
}

fn tune() {
    let (name, w, h, res, runs, mut scene, rec) = setup();
    scene.set_light(scene.light().scaled(2.0)).unwrap();
    let grid = ["0", "1", "2", "4", "8", "16"];
    println!("\n## Q_e, Q_v tuning (eq. 6, Q_n = 1): {name} under a 2x light, {w}x{h}, r = {res}, 3x3 packets, hierarchy on; estimate ms (median of {runs})");
    println!("| Q_e \\ Q_v | {} |", grid.join(" | "));
    println!("|---|{}", "---|".repeat(grid.len()));
    let mut best = (f64::INFINITY, "", "");
    for qe in grid {
        let mut row = format!("| {qe} |");
        for qv in grid {
            let mut e = hsm(&[("resolution", &res), ("qe", qe), ("qv", qv)]);
            let (t, ..) = time(&mut e, &scene, &rec, runs);
            if t < best.0 {
                best = (t, qe, qv);
            }
            row += &format!(" {t:.1} |");
        }
        println!("{row}");
    }
    println!(
        "chosen: qe = {}, qv = {} ({:.1} ms)",
        best.1, best.2, best.0
    );
}

fn accuracy() {
    let (w, h) = (envu("HSM_W", 160), envu("HSM_H", 120));
    let res = env("HSM_RES", "512");
    let spp = env("HSM_SPP", "256");
    let runs = envu("HSM_RUNS", 3);
    let dir = format!("{}/../../fixtures", env!("CARGO_MANIFEST_DIR"));
    let mut names: Vec<String> = std::fs::read_dir(&dir)
        .expect("fixtures")
        .flatten()
        .filter(|e| {
            e.path()
                .join(format!("{}.toml", e.file_name().to_string_lossy()))
                .exists()
        })
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    if let Ok(only) = std::env::var("HSM_FIXTURES") {
        let only: Vec<&str> = only.split(',').collect();
        names.retain(|n| only.contains(&n.as_str()));
    }
    println!("\n## accuracy: RMSE vs the reference ({spp} spp), {w}x{h}, r = {res}; frame ms = build + estimate (median of {runs})");
    println!("| fixture | estimator | RMSE | frame ms |");
    println!("|---|---|---|---|");
    type Make = Box<dyn Fn() -> Box<dyn SoftShadowEstimator>>;
    let rows: Vec<(&str, Make)> = vec![
        (
            "GBP07 per pixel (S=1)",
            Box::new(|| boxed(hsm(VARIANTS[0]))),
        ),
        (
            "packet-hsm S=1 (3x3, hierarchy)",
            Box::new(|| boxed(hsm(&[("sublights", "1")]))),
        ),
        (
            "packet-hsm S=2",
            Box::new(|| boxed(hsm(&[("sublights", "2")]))),
        ),
        (
            "packet-hsm S=4",
            Box::new(|| boxed(hsm(&[("sublights", "4")]))),
        ),
        (
            "backprojection 1 layer",
            Box::new(|| bp(&[("layers", "1")])),
        ),
        (
            "backprojection 3 layers",
            Box::new(|| bp(&[("layers", "3")])),
        ),
        (
            "backprojection 4 layers",
            Box::new(|| bp(&[("layers", "4")])),
        ),
        (
            "backprojection 4 layers, max_nspp 4096 (no adaptive step up to 64x64 kernels)",
            Box::new(|| bp(&[("layers", "4"), ("max_nspp", "4096")])),
        ),
        ("PCSS", Box::new(|| boxed(PcssShadow::new().expect("pcss")))),
        (
            "multi-sample (4x4)",
            Box::new(|| boxed(MultiSample::new().expect("ms"))),
        ),
    ];
    let mut fig11 = Vec::new();
    for name in &names {
        let (scene, rec) = fixture(name, w, h);
        let mut reference = ReferenceEstimator::new().expect("reference");
        reference.set_param("spp", &spp).expect("spp");
        let t = Instant::now();
        let (vref, _) = shadow_map_core::run(&mut reference, &scene, &rec).expect("reference");
        println!(
            "| {name} | reference | 0 | {:.0} |",
            t.elapsed().as_secs_f64() * 1e3
        );
        for (label, make) in &rows {
            let mut e = make();
            e.set_param("resolution", &res).expect("resolution");
            let mut v = vec![0.0; rec.len()];
            if let Err(err) = e
                .build(&scene, &rec)
                .and_then(|_| e.estimate(&scene, &rec, &mut v))
            {
                println!("| {name} | {label} | - | rejected: {err} |");
                continue;
            }
            let (_, frame, v, _) = time(e.as_mut(), &scene, &rec, runs);
            let r = rmse(&v, &vref, rec.active());
            println!("| {name} | {label} | {r:.4} | {frame:.1} |");
            if name == "overlapping" && (label.contains("S=2") || label.contains("4 layers")) {
                fig11.push((label.to_string(), r, frame));
            }
        }
    }
    if let Some(s2) = fig11.first() {
        for bp4 in &fig11[1..] {
            let faster = s2.2 < bp4.2;
            let as_accurate = s2.1 <= bp4.1 * 1.05;
            println!(
                "\nFig. 11 claim on overlapping: {} RMSE {:.4} in {:.1} ms vs {} RMSE {:.4} in {:.1} ms: faster {}, as accurate (within 5%) {} -> {}",
                s2.0, s2.1, s2.2, bp4.0, bp4.1, bp4.2, faster, as_accurate,
                if faster && as_accurate { "confirmed" } else { "refuted" }
            );
        }
    }
}

#[cfg(feature = "gpu")]
fn gpu() {
    let ctx = match shadow_map_core::gpu::GpuContext::shared() {
        Ok(c) => c,
        Err(e) => {
            println!("\n## gpu: no adapter ({e})");
            return;
        }
    };
    let (name, w, h, res, runs, mut scene, rec) = setup();
    println!("\n## gpu ({}): {name}, {w}x{h}, r = {res}, the registry's GPU estimator (the frame: maps rendered on the GPU, no packets), estimate ms (median of {runs}; upload, frame and readback), S = 1", ctx.describe());
    println!("| light scale | GBP07 per pixel | hierarchy | GBP07 / hierarchy | max dV vs CPU | receivers redone on the CPU (loop limit), per variant |");
    println!("|---|---|---|---|---|---|");
    each_light_scale(&mut scene, |scale, scene| {
        let mut cpu = hsm(&[("resolution", &res)]);
        let (_, _, vc, _) = time(&mut cpu, scene, &rec, 1);
        let mut out = Vec::new();
        for kv in &VARIANTS[..2] {
            let mut e = packet_hsm::DESCRIPTOR
                .gpu(ctx.clone())
                .expect("a frame")
                .expect("gpu");
            e.set_param("resolution", &res).expect("res");
            for (k, v) in kv.iter() {
                e.set_param(k, v).expect("param");
            }
            out.push(time(e.as_mut(), scene, &rec, runs));
        }
        let dv = out.iter().map(|o| max_diff(&o.2, &vc)).fold(0.0, f32::max);
        let fb: Vec<String> = out
            .iter()
            .map(|o| note(&o.3, "frame_cpu_redo").unwrap_or_else(|| "0".into()))
            .collect();
        println!(
            "| {scale} | {:.1} | {:.1} | {:.2} | {dv:.1e} | {} |",
            out[0].0,
            out[1].0,
            out[0].0 / out[1].0,
            fb.join(" / ")
        );
    });
}

#[cfg(not(feature = "gpu"))]
fn gpu() {
    println!("\n## gpu: built without the `gpu` feature");
}

fn main() {
    let what = std::env::args().nth(1).unwrap_or_else(|| "all".into());
    println!(
        "packet-hsm measurements ({} threads)",
        rayon::current_num_threads()
    );
    let sections: [(&str, fn()); 6] = [
        ("speed", speed),
        ("visits", visits),
        ("sweep", sweep),
        ("tune", tune),
        ("gpu", gpu),
        ("accuracy", accuracy),
    ];
    for (name, section) in sections {
        if what == "all" || what == name {
            section();
        }
    }
}
