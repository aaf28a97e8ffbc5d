//! GPU benchmark of the shadow-map core, with the adapter's ceilings measured in the same run so
//! every stage is reported as a fraction of the limit that bounds it, and the same stages on the
//! CPU backend beside a CPU tap ceiling, so the CPU/GPU ratio to each machine's limit is visible.
//!
//! Run (lavapipe, small): `SOFTSHADOW_BENCH_RES=512 cargo bench --bench gpu`; prints a markdown
//! table and writes JSON to `$OUT/gpu-bench.json` (or `target/gpu-bench.json`). Environment and
//! the meaning of each row: `benches/README.md`. A plain `fn main` (`harness = false`): GPU time
//! is taken from timestamp queries or from many iterations between one submit and one wait, which
//! criterion's per-iteration closure does not fit; readback, device creation and shader
//! compilation are never timed.
//!
//! Bench ids are `<algo>/<backend>/<stage>/<size>`. This file runs the bench; its parts live in
//! `benches/gpu/`: `config.rs` (environment), `timing.rs` (how time is taken), `ceilings.rs`
//! (the adapter's limits), `stages.rs` (the stages measured against them), `report.rs` (rows,
//! tables, JSON).
#[path = "gpu/ceilings.rs"]
mod ceilings;
#[path = "gpu/config.rs"]
mod config;
#[path = "gpu/report.rs"]
mod report;
#[path = "gpu/stages.rs"]
mod stages;
#[path = "gpu/timing.rs"]
mod timing;

use ceilings::K;
use config::Config;
use report::{Ceilings, Facts, Row};
use shadow_map_core::{
    gpu::{GpuContext, GpuScene, GpuShadowMapper},
    LightSpaceRequest, LightView, Receivers, Scene, SceneBvh,
};
use stages::StageEnv;
use std::{sync::Arc, time::Instant};
use timing::Gpu;

type BenchResult<T> = Result<T, Box<dyn std::error::Error>>;

/// The device: the shared test context in a smoke run (`None`: no adapter, a loud skip), else a
/// fresh one.
fn open_device(smoke: bool) -> BenchResult<Option<Arc<GpuContext>>> {
    if smoke {
        Ok(test_support::gate::context_for_tests("benches/gpu")?)
    } else {
        Ok(Some(Arc::new(GpuContext::new()?)))
    }
}

/// Adapter and device facts, printed.
fn facts(ctx: &GpuContext, g: &Gpu) -> Facts {
    let facts = Facts {
        describe: ctx.describe(),
        driver: ctx
            .adapter
            .as_ref()
            .map(|a| format!("{} {}", a.driver, a.driver_info))
            .unwrap_or_default(),
        pass_stamps: g.pass_stamps,
        encoder_stamps: g.encoder_stamps,
        max_binding: ctx.limits().max_storage_buffer_binding_size,
    };
    println!("adapter: {} [{}]", facts.describe, facts.driver.trim());
    println!(
        "timestamps: pass {} / inside encoders {} (period {} ns); max storage binding {} MiB",
        facts.pass_stamps,
        facts.encoder_stamps,
        g.period_ns,
        facts.max_binding >> 20
    );
    facts
}

/// The fixture with the configured receiver grid, its receivers, and the configuration.
fn load_fixture(smoke: bool, cpu_adapter: bool) -> BenchResult<(Config, Scene, Receivers)> {
    let fixture = config::fixture_path();
    let mut scene = Scene::load(&fixture)?;
    let mut cfg = Config::from_env(
        fixture,
        (scene.camera().width, scene.camera().height),
        if cpu_adapter { 1024 } else { 2048 },
    )?;
    if smoke {
        println!("smoke run (no --bench argument): tiny sizes, no JSON; `cargo bench --bench gpu` measures");
        cfg.shrink_for_smoke();
    }
    scene.set_resolution(cfg.width, cfg.height).unwrap();
    let bvh = SceneBvh::new(&scene);
    let receivers = Receivers::from_camera(&scene, &bvh);
    Ok((cfg, scene, receivers))
}

/// The three GPU ceilings, their rows and the atomic-insert check. Returns the GPU lit-tap count
/// (checked against the CPU twin later).
fn gpu_ceilings(
    g: &Gpu,
    cfg: &Config,
    map: &[f32],
    rows: &mut Vec<Row>,
    checks: &mut Vec<(String, bool)>,
) -> BenchResult<(Ceilings, u64)> {
    let module = ceilings::ceilings_module(g.ctx)?;
    let (taps, gpu_lit) = ceilings::ceiling_taps(g, cfg, map, &module)?;
    let tris = ceilings::ceiling_triangles(g, cfg, &module)?;
    let (inserts, counter) = ceilings::ceiling_inserts(g, cfg, &module)?;
    checks.push((
        format!(
            "atomic-insert counter {counter} == {} inserts",
            inserts.work
        ),
        counter as f64 == inserts.work,
    ));
    let c = Ceilings {
        gpu_taps: taps.rate(),
        gpu_triangles: tris.rate(),
        gpu_inserts: inserts.rate(),
        cpu_taps: f64::NAN,
    };
    rows.extend([taps, tris, inserts]);
    Ok((c, gpu_lit))
}

/// Prints the tables, notes and checks; writes the JSON unless this is a smoke run.
fn report(
    smoke: bool,
    facts: &Facts,
    cfg: &Config,
    c: &Ceilings,
    rows: &[Row],
    checks: &[(String, bool)],
) -> BenchResult<()> {
    println!();
    print!("{}", report::table(rows, c));
    if cfg.cpu {
        println!();
        print!("{}", report::comparison(rows, c));
    }
    println!();
    for r in rows {
        if let Some(n) = &r.timing.note {
            println!("note: {}: {n}", r.id);
        }
    }
    for (what, ok) in checks {
        println!("check: {what}: {}", if *ok { "ok" } else { "FAILED" });
    }
    if !smoke {
        let path = report::out_path();
        if let Some(dir) = path.parent() {
            std::fs::create_dir_all(dir)?;
        }
        std::fs::write(&path, report::json(facts, cfg, c, rows, checks))?;
        println!("wrote {}", path.display());
    }
    Ok(())
}

fn main() -> BenchResult<()> {
    let t_start = Instant::now();
    // `cargo bench` passes `--bench`; `cargo test --benches` does not. Without it this is a smoke
    // run (as criterion's test mode): tiny sizes, every kernel run and checked, no JSON written,
    // and a missing adapter is a loud skip (a failure under SOFTSHADOW_REQUIRE_GPU=1).
    let smoke = !std::env::args().any(|a| a == "--bench");
    let Some(ctx) = open_device(smoke)? else {
        return Ok(());
    };
    let g = Gpu::new(&ctx, 1.0);
    let facts = facts(&ctx, &g);

    // Fixture, receivers and view: outside every timed region.
    let (cfg, scene, receivers) = load_fixture(smoke, g.cpu_adapter)?;
    let g = Gpu::new(&ctx, cfg.budget_s);
    let light = scene.light();
    let (view, _fit) = LightView::fit(
        &scene,
        &receivers,
        light.frame(),
        light.half_extent(),
        cfg.res,
    )?;
    println!(
        "fixture: {} ({} triangles), shadow map {r}x{r}, receivers {}x{} ({} active), kernel {K}x{K}",
        cfg.fixture,
        scene.triangles().len(),
        cfg.width,
        cfg.height,
        receivers.active_count(),
        r = cfg.res,
    );

    // Ceilings.
    let map = ceilings::random_map(cfg.res);
    let mut rows = Vec::new();
    let mut checks = Vec::new();
    let (mut c, gpu_lit) = gpu_ceilings(&g, &cfg, &map, &mut rows, &mut checks)?;

    // Stages on the GPU.
    let gpu_scene = GpuScene::upload(&ctx, &scene)?;
    let mapper = GpuShadowMapper::new(&ctx)?;
    let base =
        mapper.render_layers(&ctx, &gpu_scene, &view, &LightSpaceRequest::single(cfg.res))?;
    ctx.wait()?;
    let layer0 = base.layers[0].clone();
    let env = StageEnv {
        g: &g,
        cfg: &cfg,
        scene: &scene,
        receivers: &receivers,
        view,
        gpu_scene,
        mapper,
        layer0,
    };
    rows.extend(stages::gpu_stages(&env)?);
    rows.extend(stages::estimate_stages(&env)?);
    rows.extend(stages::frame_stages(&env, cfg.cpu)?);

    // CPU: the tap ceiling (the twin of taps_kernel, checked against it) and the same stages.
    if cfg.cpu {
        let (row, cpu_lit) = ceilings::ceiling_cpu_taps(g.budget_ms, &cfg, &map);
        checks.push((
            format!("taps_kernel lit taps: GPU {gpu_lit} == CPU {cpu_lit}"),
            gpu_lit == cpu_lit,
        ));
        c.cpu_taps = row.rate();
        rows.push(row);
        rows.extend(stages::cpu_stages(&env));
    }

    report(smoke, &facts, &cfg, &c, &rows, &checks)?;
    println!("{:.1} s in all", t_start.elapsed().as_secs_f64());
    if checks.iter().any(|(_, ok)| !ok) {
        return Err("a ceiling check failed".into());
    }
    Ok(())
}
