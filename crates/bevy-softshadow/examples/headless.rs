//! A headless Bevy app (no window; the camera renders into an image) that loads a fixture
//! scene, renders `--frames` frames with each method through `SoftShadowPlugin`, then reads the
//! method's V texture back once and compares it with the CPU twin on the same receivers (the ones
//! Bevy's prepass gave) in the same light views (`tests/common/headless.rs`, shared with the
//! tests).
//!
//! ```text
//! cargo run --release --example headless -- --json
//! cargo run --release --example headless -- --fixture ../../fixtures/sun-bunny/sun-bunny.toml --frames 30
//! ```
//!
//! `--json`: one line per method, `{"algo", "frames", "ms_per_frame", "rmse_vs_cpu", ...}`
//! (the fields of `headless::Comparison`; `error` instead for a light the method does not
//! model; `bevy_alone_ms_per_frame`: the same frames with the plugin's work off). `--size WxH`: another image size than the fixture's. `--screenshot FILE.png`: the last method's final image (the composite applied).
#[path = "../tests/common/fixture.rs"]
mod fixture;
#[path = "../tests/common/headless.rs"]
mod headless;

use bevy_softshadow::Method;
use serde_json::json;
use shadow_map_core::Scene;

struct Args {
    fixture: String,
    frames: u32,
    json: bool,
    methods: Vec<Method>,
    screenshot: Option<String>,
    size: Option<(u32, u32)>,
    max_distance: Option<f32>,
}

fn args() -> Result<Args, String> {
    let mut a = Args {
        fixture: concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../fixtures/bunny/bunny.toml"
        )
        .into(),
        frames: 10,
        json: false,
        methods: Method::ALL.to_vec(),
        screenshot: None,
        size: None,
        max_distance: None,
    };
    let mut it = std::env::args().skip(1);
    while let Some(k) = it.next() {
        let mut val = || it.next().ok_or(format!("{k} needs a value"));
        match k.as_str() {
            "--json" => a.json = true,
            "--fixture" => a.fixture = val()?,
            "--frames" => a.frames = val()?.parse().map_err(|e| format!("--frames: {e}"))?,
            "--methods" => {
                a.methods = val()?
                    .split(',')
                    .map(|n| Method::from_name(n).ok_or(format!("--methods: unknown method {n:?}")))
                    .collect::<Result<_, _>>()?
            }
            "--screenshot" => a.screenshot = Some(val()?),
            "--max-distance" => {
                a.max_distance = Some(val()?.parse().map_err(|e| format!("--max-distance: {e}"))?)
            }
            "--size" => {
                let v = val()?;
                let (w, h) = v
                    .split_once('x')
                    .ok_or(format!("--size: {v:?} is not WxH"))?;
                let p = |x: &str| x.parse::<u32>().map_err(|e| format!("--size: {e}"));
                a.size = Some((p(w)?, p(h)?));
            }
            _ => {
                return Err(format!(
                    "unknown argument {k:?} (--json, --fixture PATH, --frames N, --methods a,b, \
                     --size WxH, --max-distance D, --screenshot FILE.png)"
                ))
            }
        }
    }
    Ok(a)
}

fn main() {
    if let Err(e) = run() {
        eprintln!("headless: {e}");
        std::process::exit(1);
    }
}

fn run() -> Result<(), String> {
    let args = args()?;
    let mut scene = Scene::load(&args.fixture).map_err(|e| e.to_string())?;
    if let Some((w, h)) = args.size {
        scene.set_resolution(w, h).unwrap();
    }
    let (w, h) = (scene.camera().width, scene.camera().height);
    let out = headless::run(
        &scene,
        &args.methods,
        args.frames,
        args.screenshot.is_some(),
        args.max_distance,
    )?;
    for r in &out.runs {
        let mut line = json!({
            "algo": r.method.name(),
            "frames": r.frames,
            "ms_per_frame": r.ms_per_frame,
            "bevy_alone_ms_per_frame": out.bevy_alone_ms,
            "width": w,
            "height": h,
        });
        let fields = match &r.result {
            Ok(c) => json!({
                "rmse_vs_cpu": c.rmse_vs_cpu,
                "max_abs_vs_cpu": c.max_abs_vs_cpu,
                "receivers": c.receivers,
                "nan": c.nan,
                "status_left_nan": c.status_left_nan,
                "keeps_status": c.keeps_status,
                "views": c.views,
                "mean_v": c.mean_v,
                "frac_below_half": c.frac_below_half,
                "prepass_vs_raytraced": {
                    "pixels_covered_by_one": c.pixels_covered_by_one,
                    "pixels_apart_1e-3": c.pixels_apart,
                    "max_position_rel": c.max_position_rel,
                },
                "rmse_vs_cpu_render": c.rmse_vs_cpu_render,
            }),
            Err(e) => json!({ "error": e }),
        };
        line.as_object_mut()
            .unwrap()
            .extend(fields.as_object().unwrap().clone());
        if args.json {
            println!("{line}");
        } else {
            match &r.result {
                Ok(c) => println!(
                    "{:<15} {:>8.2} ms/frame (Bevy alone {:.2})  rmse_vs_cpu {:.2e}  vs render --backend cpu {:.4}",
                    r.method.name(),
                    r.ms_per_frame,
                    out.bevy_alone_ms,
                    c.rmse_vs_cpu,
                    c.rmse_vs_cpu_render
                ),
                Err(e) => println!("{:<15} {e}", r.method.name()),
            }
        }
    }
    if let (Some(path), Some(rgba)) = (&args.screenshot, out.screenshot) {
        image::save_buffer(path, &rgba, w, h, image::ExtendedColorType::Rgba8)
            .map_err(|e| format!("{path}: {e}"))?;
    }
    Ok(())
}
