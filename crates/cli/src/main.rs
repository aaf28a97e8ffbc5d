//! `softshadow`: render a scene's visibility with any estimator, list the estimators, score an
//! image against a reference (docs/methods.md §11, "The command line").
mod exr_io;
mod path;
mod report;
mod score;

use clap::{Parser, Subcommand};
use serde_json::{json, Map, Value};
use shadow_map_core::{Backend, Receivers, Scene, SceneBvh};
use softshadow::{estimator, registry};
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Instant;

#[derive(Parser)]
#[command(
    name = "softshadow",
    version,
    about = "Physically based soft shadows, measured against a ray-traced ground truth"
)]
struct Cli {
    #[command(subcommand)]
    cmd: Cmd,
}

#[derive(Subcommand)]
enum Cmd {
    /// Render the visibility image V (and view depth Z) of a scene with one estimator.
    #[command(after_help = algos_help())]
    Render {
        /// Scene file (TOML, see docs/methods.md §11).
        scene: PathBuf,
        /// Estimator name (`softshadow algos` lists them).
        #[arg(long)]
        algo: String,
        /// Backend.
        #[arg(long, default_value = "cpu", value_parser = ["cpu", "gpu"])]
        backend: String,
        /// Estimator parameter KEY=VALUE (repeatable).
        #[arg(long = "param", value_name = "KEY=VALUE")]
        params: Vec<String>,
        /// Output OpenEXR (channels V and Z).
        #[arg(long)]
        out: PathBuf,
        /// Optional PNG preview of V.
        #[arg(long)]
        png: Option<PathBuf>,
        /// Print one JSON line with the algorithm, backend, parameters and stage times.
        #[arg(long)]
        stats: bool,
        /// Render a camera path of N frames into numbered files (OUT.0000.exr, ...) and print a
        /// JSON line with the frame-to-frame flicker of V at the same world points.
        #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..=100000))]
        frames: u32,
        /// Camera path: orbit about the vertical axis through the target, DEGREES over the path.
        #[arg(
            long,
            value_name = "DEGREES",
            conflicts_with = "pan",
            allow_hyphen_values = true
        )]
        orbit: Option<f32>,
        /// Camera path: move eye and target by X,Y,Z over the path.
        #[arg(long, value_name = "X,Y,Z", allow_hyphen_values = true)]
        pan: Option<String>,
    },
    /// Run every estimator over its parameter sweep on every fixture, score each image against
    /// the ray-traced reference, and write results.csv, results.json, flicker.csv, index.md and
    /// the time-vs-RMSE plots.
    Report {
        /// Directory of fixtures (NAME/NAME.toml).
        #[arg(long, default_value = "fixtures")]
        fixtures: PathBuf,
        /// Output directory.
        #[arg(long, default_value = "report")]
        out: PathBuf,
        /// Backends to run.
        #[arg(long, default_value = "cpu", value_parser = ["cpu", "gpu", "both"])]
        backend: String,
        /// The CI subset: half-size images, 256-sample references, quick sweeps, 3-frame pans of
        /// the CPU backend only.
        #[arg(long)]
        quick: bool,
    },
    /// List every estimator with its parameters, defaults, ranges and a description.
    Algos {
        /// Print JSON instead of text.
        #[arg(long)]
        json: bool,
    },
    /// Compare a candidate EXR with a reference EXR; prints one JSON line.
    Score {
        /// Candidate image.
        candidate: PathBuf,
        /// Reference image.
        reference: PathBuf,
        /// Write a false-colour error image (a diverging map: blue too dark, red too bright).
        #[arg(long)]
        err_png: Option<PathBuf>,
        /// The error mapped to the colour map's ends in the error image (errors beyond are
        /// clamped).
        #[arg(long, value_name = "E", default_value_t = score::DEFAULT_ERR_RANGE)]
        err_range: f64,
    },
}

fn algos_help() -> String {
    let mut s = String::from(
        "Estimators (name: description [backends]) and their parameters \
         (key=default (range or choices): meaning; set with --param KEY=VALUE):\n",
    );
    if let Ok(all) = registry() {
        for e in all {
            s.push_str(&format!(
                "  {}: {} [backends: {}]\n",
                e.name(),
                e.description(),
                softshadow::backends(e.name()).join(", ")
            ));
            for p in e.params().specs() {
                s.push_str(&format!(
                    "      {}={} ({}): {}\n",
                    p.key,
                    p.default,
                    p.range(),
                    p.help
                ));
            }
        }
    }
    s
}

fn main() -> ExitCode {
    let cli = match Cli::try_parse() {
        Ok(cli) => cli,
        Err(e) => return usage_error(e),
    };
    let result = match cli.cmd {
        Cmd::Render {
            scene,
            algo,
            backend,
            params,
            out,
            png,
            stats,
            frames,
            orbit,
            pan,
        } => camera_path(orbit, pan.as_deref(), frames).and_then(|path| {
            render(
                &scene,
                &algo,
                &backend,
                &params,
                &out,
                png.as_deref(),
                stats,
                path.map(|p| (p, frames as usize)),
            )
        }),
        Cmd::Report {
            fixtures,
            out,
            backend,
            quick,
        } => report::report(&report::ReportArgs {
            fixtures,
            out,
            backends: match backend.as_str() {
                "gpu" => vec![Backend::Gpu],
                "both" => vec![Backend::Cpu, Backend::Gpu],
                _ => vec![Backend::Cpu],
            },
            quick,
        }),
        Cmd::Algos { json } => algos(json),
        Cmd::Score {
            candidate,
            reference,
            err_png,
            err_range,
        } => score_cmd(&candidate, &reference, err_png.as_deref(), err_range),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(_) if interrupt().is_cancelled() => {
            eprintln!("softshadow: interrupted (Ctrl-C): the frame being rendered was not written");
            ExitCode::from(130)
        }
        Err(e) => {
            eprintln!("softshadow: {}", e.replace('\n', " "));
            ExitCode::FAILURE
        }
    }
}

/// The token Ctrl-C (SIGINT) cancels: `render` hands it to its estimator, which stops at its
/// next check ([`shadow_map_core::Cancel`]) and returns `Error::Cancelled`; the frame being
/// rendered is then not written (frames of a camera path already written stay, each complete)
/// and the exit status is 130. A second Ctrl-C exits at once.
fn interrupt() -> &'static shadow_map_core::Cancel {
    static TOKEN: std::sync::OnceLock<shadow_map_core::Cancel> = std::sync::OnceLock::new();
    TOKEN.get_or_init(shadow_map_core::Cancel::new)
}

/// Installs the Ctrl-C handler of [`interrupt`] (once; an error installing it is ignored: the
/// default handler, which ends the process, stays).
fn catch_interrupt() {
    let token = interrupt().clone();
    let _ = ctrlc::set_handler(move || {
        if token.is_cancelled() {
            std::process::exit(130);
        }
        token.cancel();
    });
}

/// A command line clap refuses: help and version print as clap prints them; every other error
/// is one line on standard error (the contract's rule), exit status 2.
fn usage_error(e: clap::Error) -> ExitCode {
    use clap::error::ErrorKind;
    if matches!(
        e.kind(),
        ErrorKind::DisplayHelp
            | ErrorKind::DisplayVersion
            | ErrorKind::DisplayHelpOnMissingArgumentOrSubcommand
    ) {
        e.exit();
    }
    let text = e.render().to_string();
    let line: Vec<&str> = text
        .lines()
        .map(str::trim)
        .filter(|l| {
            !l.is_empty() && !l.starts_with("For more information") && !l.starts_with("Usage:")
        })
        .collect();
    let line = line.join(" ");
    eprintln!(
        "softshadow: {}",
        line.strip_prefix("error: ").unwrap_or(&line)
    );
    ExitCode::from(2)
}

fn camera_path(
    orbit: Option<f32>,
    pan: Option<&str>,
    frames: u32,
) -> Result<Option<path::CameraPath>, String> {
    let p = match (orbit, pan) {
        (Some(d), _) if !d.is_finite() => return Err(format!("--orbit {d}: not a finite angle")),
        (Some(d), _) => Some(path::CameraPath::Orbit(d)),
        (None, Some(s)) => Some(path::CameraPath::Pan(path::CameraPath::parse_pan(s)?)),
        (None, None) => None,
    };
    match (p, frames) {
        (None, f) if f > 1 => Err(format!(
            "--frames {f} needs a camera path: --orbit DEGREES or --pan X,Y,Z"
        )),
        (Some(_), 1) => Err("--orbit/--pan need --frames N with N >= 2".into()),
        (p, _) => Ok(p),
    }
}

#[allow(clippy::too_many_arguments)]
fn render(
    scene_path: &std::path::Path,
    algo: &str,
    backend: &str,
    params: &[String],
    out: &std::path::Path,
    png: Option<&std::path::Path>,
    stats: bool,
    cam_path: Option<(path::CameraPath, usize)>,
) -> Result<(), String> {
    let t_all = Instant::now();
    let backend = if backend == "gpu" {
        Backend::Gpu
    } else {
        Backend::Cpu
    };
    let mut est = estimator(algo, backend).map_err(|e| e.to_string())?;
    catch_interrupt();
    est.set_cancel(interrupt().clone());
    for kv in params {
        let (k, v) = shadow_map_core::params::parse_assignment(kv).map_err(|e| e.to_string())?;
        est.set_param(k, v).map_err(|e| e.to_string())?;
    }
    let t = Instant::now();
    let mut scene = Scene::load(scene_path).map_err(|e| e.to_string())?;
    let load_ms = ms(t);
    let Some((cam_path, frames)) = cam_path else {
        return render_frame(
            &scene,
            est.as_mut(),
            scene_path,
            out,
            png,
            stats,
            load_ms,
            t_all,
            None,
        )
        .map(|_| ());
    };
    let base = *scene.camera();
    let mut flicker = path::Flicker::default();
    for k in 0..frames {
        scene
            .set_camera(cam_path.camera(&base, k, frames))
            .map_err(|e| e.to_string())?;
        let out_k = path::numbered(out, k);
        let png_k = png.map(|p| path::numbered(p, k));
        let frame = render_frame(
            &scene,
            est.as_mut(),
            scene_path,
            &out_k,
            png_k.as_deref(),
            stats,
            if k == 0 { load_ms } else { 0.0 },
            Instant::now(),
            Some(k),
        )?;
        flicker.push(frame);
    }
    let (mean, p99, pairs) = flicker.summary();
    let num = |x: f64| if x.is_finite() { json!(x) } else { Value::Null };
    println!(
        "{}",
        json!({
            "flicker": {
                "algo": est.name(),
                "backend": est.backend().to_string(),
                "scene": scene_path.display().to_string(),
                "frames": frames,
                "path": format!("{cam_path:?}"),
                "mean_abs_dv": num(mean),
                "p99_abs_dv": num(p99),
                "pairs": pairs,
            }
        })
    );
    let _ = t_all;
    Ok(())
}

/// Renders one frame of `scene` (its camera) and writes it; returns what the flicker measure needs.
#[allow(clippy::too_many_arguments)]
fn render_frame(
    scene: &Scene,
    est: &mut dyn shadow_map_core::SoftShadowEstimator,
    scene_path: &std::path::Path,
    out: &std::path::Path,
    png: Option<&std::path::Path>,
    stats: bool,
    load_ms: f64,
    t_all: Instant,
    frame: Option<usize>,
) -> Result<path::Frame, String> {
    let mut stages: Vec<(String, f64)> = vec![("load".into(), load_ms)];
    let (receivers, v, mut report) = match engine_frame(scene, est).map_err(|e| e.to_string())? {
        Engine::Done(receivers, v, report) => (receivers, v, report),
        Engine::Twin(receivers, gbuffer_ms) => {
            stages.push(("gbuffer".into(), gbuffer_ms));
            let (v, report) = run_with_progress(est, scene, &receivers)?;
            (receivers, v, report)
        }
    };
    stages.extend(report.stages.iter().cloned());
    // What the estimator could not model, always (one line each).
    for w in &report.warnings {
        eprintln!("warning: {}: {w}", est.name());
    }
    if stats {
        let params = est.params();
        if let Some((m, p95)) =
            shadow_map_core::cascades::texel_density_summary(scene, &receivers, params)
        {
            report.note("texel_density_median", format!("{m:.3}"));
            report.note("texel_density_p95", format!("{p95:.3}"));
        }
    }
    let t = Instant::now();
    let (w, h) = (
        scene.camera().width as usize,
        scene.camera().height as usize,
    );
    let mut img = report::visibility_image(scene, &receivers, v.clone())?;
    img.attributes = provenance(est, scene_path);
    exr_io::write_exr(out, &img).map_err(|e| e.to_string())?;
    if let Some(p) = png {
        exr_io::write_png_preview(p, w, h, &v).map_err(|e| e.to_string())?;
    }
    stages.push(("write".into(), ms(t)));
    if stats {
        let mut st = Map::new();
        for (k, v) in &stages {
            let e = st.entry(k.clone()).or_insert(json!(0.0));
            *e = json!(e.as_f64().unwrap_or(0.0) + v);
        }
        let params: Map<String, Value> = est
            .params()
            .iter()
            .map(|(k, v)| (k.to_string(), json!(v.to_string())))
            .collect();
        let notes: Map<String, Value> = report
            .notes
            .iter()
            .map(|(k, v)| (k.clone(), json!(v)))
            .collect();
        let mut line = json!({
            "algo": est.name(),
            "backend": est.backend().to_string(),
            "scene": scene_path.display().to_string(),
            "width": w, "height": h,
            "receivers": receivers.active_count(),
            "triangles": scene.triangles().len(),
            "skipped_degenerate_triangles": scene.skipped_degenerate(),
            "params": params,
            "stages_ms": st,
            "total_ms": ms(t_all),
            "light_space_bytes": report.light_space_bytes,
            "notes": notes,
            "warnings": report.warnings.iter().map(|w| w.to_string()).collect::<Vec<_>>(),
        });
        if let Some(k) = frame {
            line["frame"] = json!(k);
        }
        println!("{line}");
    }
    Ok(path::Frame {
        camera: *scene.camera(),
        position: receivers.position().to_vec(),
        active: receivers.active().to_vec(),
        v,
    })
}

/// `shadow_map_core::run`, with a progress bar on standard error for the ray-traced reference
/// (a render of minutes): the estimator counts the receivers it has finished in its
/// [`Cancel`](shadow_map_core::Cancel) token (the one Ctrl-C cancels, [`interrupt`]), which a
/// thread draws every 100 ms. indicatif draws
/// only to a terminal, so a script's or CI's standard error stays one line on failure.
fn run_with_progress(
    est: &mut dyn shadow_map_core::SoftShadowEstimator,
    scene: &Scene,
    receivers: &Receivers,
) -> Result<(Vec<f32>, shadow_map_core::Report), String> {
    if est.name() != "reference" {
        return shadow_map_core::run(est, scene, receivers).map_err(|e| e.to_string());
    }
    // The token `render` handed the estimator (Ctrl-C's), which also counts its progress.
    let token = interrupt();
    let start = token.progress();
    let total = receivers.len() as u64;
    let done = std::sync::atomic::AtomicBool::new(false);
    std::thread::scope(|s| {
        s.spawn(|| {
            let bar = indicatif::ProgressBar::with_draw_target(
                Some(total),
                indicatif::ProgressDrawTarget::stderr(),
            );
            if let Ok(style) = indicatif::ProgressStyle::with_template(
                "reference {bar:40} {pos}/{len} receivers ({percent}%, {elapsed} elapsed, ~{eta} left)",
            ) {
                bar.set_style(style);
            }
            while !done.load(std::sync::atomic::Ordering::Relaxed) {
                bar.set_position((token.progress() - start).min(total));
                std::thread::sleep(std::time::Duration::from_millis(100));
            }
            bar.finish_and_clear();
        });
        let out = shadow_map_core::run(est, scene, receivers).map_err(|e| e.to_string());
        done.store(true, std::sync::atomic::Ordering::Relaxed);
        out
    })
}

/// The contract's provenance attributes of an image `est` rendered from `scene_path`
/// ([`exr_io::PROVENANCE`]): the algorithm, the backend, every parameter's value as a JSON
/// object, this crate's version and the scene file as given.
fn provenance(
    est: &dyn shadow_map_core::SoftShadowEstimator,
    scene_path: &std::path::Path,
) -> Vec<(String, String)> {
    let params: Map<String, Value> = est
        .params()
        .iter()
        .map(|(k, v)| (k.to_string(), json!(v.to_string())))
        .collect();
    let values = [
        est.name().to_string(),
        est.backend().to_string(),
        Value::Object(params).to_string(),
        env!("CARGO_PKG_VERSION").to_string(),
        scene_path.display().to_string(),
    ];
    exr_io::PROVENANCE
        .iter()
        .zip(values)
        .map(|(k, v)| (k.to_string(), v))
        .collect()
}

/// The provenance attributes of `img` present, as a JSON object (`params` parsed), or `None`.
fn provenance_json(img: &exr_io::VisibilityImage) -> Option<Value> {
    let mut out = Map::new();
    for key in exr_io::PROVENANCE {
        if let Some((_, v)) = img.attributes.iter().find(|(k, _)| k == key) {
            let short = key.trim_start_matches("softshadow.").to_string();
            let value = if short == "params" {
                serde_json::from_str(v).unwrap_or_else(|_| json!(v))
            } else {
                json!(v)
            };
            out.insert(short, value);
        }
    }
    (!out.is_empty()).then_some(Value::Object(out))
}

/// What [`engine_frame`] did.
#[cfg_attr(not(feature = "gpu"), allow(dead_code))]
enum Engine {
    /// The frame was rendered on the engine path: receivers, V and the report (stages included).
    Done(Receivers, Vec<f32>, shadow_map_core::Report),
    /// The estimator's `build` and `estimate` are to run on these receivers (the G-buffer took
    /// the milliseconds given).
    Twin(Receivers, f64),
}

/// `--backend gpu` for an estimator with an engine path (`softshadow::FRAME_ALGOS`) whose
/// cascade settings resolve to one view set on this frame
/// (`shadow_map_core::cascades::is_one_view`): the G-buffer rendered on the GPU stays there, its
/// receiver buffer handed to the frame API (`FrameEstimator::encode` into one command encoder,
/// one submit), and only V is read back (with the frame's few status words). What the CPU needs
/// besides, the view fit (as the estimator's `build` fits it), the EXR's Z channel and the
/// background mask, comes from the camera's ray-cast receivers, the CPU backend's own: both
/// backends render in the same views, and no G-buffer travels back. Where the two G-buffers
/// disagree (silhouette pixels), the ray-cast one decides: V is NaN where it sees background, and
/// active receivers the frame leaves NaN (the rasterised pixel missed, the device's loop budget
/// cut it, or accumulation's frustum left it lit) are redone by the CPU twin in the same views
/// (`frame_cpu_redo` in the notes). Every other case (among them a semi-transparent scene for a
/// frame that casts every caster opaque, `FrameEstimator::models_opacity`) ray casts the
/// receivers ([`camera_receivers`]) and leaves the estimator to its twin path.
#[cfg_attr(not(feature = "gpu"), allow(unused_variables))]
fn engine_frame(
    scene: &Scene,
    est: &dyn shadow_map_core::SoftShadowEstimator,
) -> shadow_map_core::Result<Engine> {
    let t = Instant::now();
    #[cfg(feature = "gpu")]
    if est.backend() == Backend::Gpu && softshadow::FRAME_ALGOS.contains(&est.name()) {
        use shadow_map_core::gpu::{frame::FrameInputs, raster::GpuScene, GpuContext, GpuGBuffer};
        let ctx = GpuContext::shared()?;
        // The CPU's receivers: the view fit, Z and the background mask (no G-buffer readback).
        let receivers = camera_receivers(scene);
        let cpu_receivers_ms = ms(t);
        let inner = softshadow::own_params(est.name(), est.params())?;
        if !shadow_map_core::cascades::is_one_view(est.params(), scene, &receivers, &inner)? {
            return Ok(Engine::Twin(receivers, ms(t)));
        }
        let n = receivers.len();
        let Some(frame) = softshadow::frame_estimator(est.name(), ctx.clone(), &inner, n as u32)?
        else {
            return Ok(Engine::Twin(receivers, ms(t)));
        };
        // A light or setting the engine path does not model (packet-hsm: sub-lights of a light
        // that is not a rect, which its CPU twin refuses too), or semi-transparent casters a frame would cast opaque: the twin path,
        // decided before anything is uploaded or rasterised.
        if frame.refuses(scene).is_some() || !(scene.is_opaque() || frame.models_opacity()) {
            return Ok(Engine::Twin(receivers, ms(t)));
        }
        // The frame's receivers: rasterised, and left on the device.
        let t_gbuffer = Instant::now();
        let casters = GpuScene::upload(&ctx, scene)?;
        let image = GpuGBuffer::new(&ctx)?.render(&ctx, &casters, scene.camera())?;
        let gbuffer_ms = cpu_receivers_ms + ms(t_gbuffer);
        let mut report = shadow_map_core::Report::default();
        report.warn_all(frame.scene_warnings(scene));
        report.light_space_bytes = frame.light_space_bytes();
        report.stages.push(("gbuffer".into(), gbuffer_ms));
        let t = Instant::now();
        let views = frame.fit_views(scene, &receivers)?;
        report.stages.push(("fit".into(), ms(t)));
        let t = Instant::now();
        let v_buf = ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("softshadow render V"),
            size: 4 * n.max(1) as u64,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        let mut enc = ctx.device.create_command_encoder(&Default::default());
        frame.encode(
            &mut enc,
            &FrameInputs {
                casters: &casters,
                views: &views,
                light: scene.light(),
                receivers: &image.receivers.buffer,
                count: image.receivers.count,
                v: &v_buf,
                timestamps: None,
            },
        )?;
        ctx.queue.submit([enc.finish()]);
        report.stages.push(("encode".into(), ms(t)));
        let t = Instant::now();
        let mut v: Vec<f32> = ctx.read_buffer(&v_buf, 4 * n as u64)?;
        report.stages.push(("frame".into(), ms(t)));
        // Background where the ray-cast G-buffer sees none (a rasterised silhouette pixel);
        // active receivers the frame left NaN redone by its CPU twin.
        shadow_map_core::gpu::frame::finish_on_cpu(
            &*frame,
            &ctx,
            scene,
            &receivers,
            &views,
            &mut v,
            &mut report,
        )?;
        report.note(
            "engine_path",
            "frame API: one encode into one command encoder, one submit, only V read back (views, Z and background from the ray-cast G-buffer)",
        );
        report.note("views", views.iter().flatten().count());
        return Ok(Engine::Done(receivers, v, report));
    }
    Ok(Engine::Twin(camera_receivers(scene), ms(t)))
}

/// The camera's G-buffer, ray cast through the BVH for either backend: both backends render the
/// same receivers, which the scoring tools compare pixel by pixel (a rasterised G-buffer differs
/// from the ray cast one on silhouette and sub-pixel-thin geometry, which would make a pixel
/// background on one backend and ground on the other).
fn camera_receivers(scene: &Scene) -> Receivers {
    Receivers::from_camera(scene, &SceneBvh::new(scene))
}

fn ms(t: Instant) -> f64 {
    t.elapsed().as_secs_f64() * 1e3
}

fn algos(as_json: bool) -> Result<(), String> {
    let all = registry().map_err(|e| e.to_string())?;
    if as_json {
        let list: Vec<Value> = all
            .iter()
            .map(|e| {
                json!({
                    "name": e.name(),
                    "description": e.description(),
                    "backends": softshadow::backends(e.name()),
                    "params": e.params().specs().iter().map(|p| json!({
                        "key": p.key, "default": p.default, "range": p.range(), "help": p.help
                    })).collect::<Vec<_>>(),
                })
            })
            .collect();
        println!("{}", Value::Array(list));
    } else {
        print!("{}", algos_help());
    }
    Ok(())
}

fn score_cmd(
    cand: &std::path::Path,
    reference: &std::path::Path,
    err_png: Option<&std::path::Path>,
    err_range: f64,
) -> Result<(), String> {
    let c = exr_io::read_visibility_exr(cand).map_err(|e| e.to_string())?;
    let r = exr_io::read_visibility_exr(reference).map_err(|e| e.to_string())?;
    let s = score::score(&c, &r).map_err(|e| e.to_string())?;
    if let Some(p) = err_png {
        score::write_error_png(p, &c, &r, err_range).map_err(|e| e.to_string())?;
    }
    // The score's JSON (its fields in declaration order), with each image's provenance after
    // them when the file carries it.
    let mut line = score::score_json(&s);
    for (key, img) in [("candidate_provenance", &c), ("reference_provenance", &r)] {
        if let Some(p) = provenance_json(img) {
            if line.ends_with('}') {
                line.pop();
                line.push_str(&format!(",\"{key}\":{p}}}"));
            }
        }
    }
    println!("{line}");
    Ok(())
}
