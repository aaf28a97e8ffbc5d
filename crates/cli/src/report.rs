//! `softshadow report`: every registered estimator over the parameter sweep it declares
//! (its descriptor's [`sweep`](softshadow::MethodDescriptor::sweep)), on every fixture, on the chosen backends; each image scored
//! against the ray-traced reference; the speed-versus-error picture written out.
//!
//! **Reference.** Rendered by the `reference` crate (never by the code under test) and cached in
//! `OUT/cache/` under a SHA-256 key over the parsed scene, every mesh file's bytes, the sample
//! count and the reference crate's version and revision ([`cache_key`]), so a second report
//! reuses it and an edited scene, mesh or tracer gets a new one.
//!
//! **Times.** `build ms` and `estimate ms` are the estimator's own stage times (its
//! [`Report`](shadow_map_core::Report): GPU rows include upload, dispatch and readback); `frame ms`
//! is the wall clock of `build` + `estimate` as a renderer would call them. Loading, the camera
//! G-buffer and scoring are outside every time. One run per setting, so on a busy machine compare
//! ratios within one report.
//!
//! **Outputs** (in `OUT`): `results.csv` and `results.json` (one row per run), `flicker.csv` (the
//! frame-to-frame |dV| of each fit mode on a camera pan, see [`crate::path`]), `index.md` (per
//! fixture: the time-vs-RMSE plot `plot-FIXTURE.svg` with its Pareto front (a colour per
//! algorithm, circles CPU and triangles GPU), the memory-vs-RMSE plot `memory-FIXTURE.svg`
//! (`light_space_bytes`), the Pareto table, an
//! image grid of the reference, each algorithm's most accurate setting and its error image; then
//! the summary: the most accurate setting within each time budget, and each seed algorithm
//! against PCSS and multi-sample at matched time).
use crate::{exr_io, path, score};
use serde::Serialize;
use shadow_map_core::{Backend, Receivers, Scene, SceneBvh, SoftShadowEstimator};
use softshadow::{backends, estimator, Setting, METHODS};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::Instant;

mod index_md;
mod outputs;
mod plot;

use outputs::write_outputs;

/// The baselines, marked as such in plots and tables.
pub const BASELINES: &[&str] = &["hard", "pcf", "pcss", "multi-sample"];

/// What `softshadow report` was asked for.
#[derive(Debug, Clone)]
pub struct ReportArgs {
    /// Directory of fixtures (`NAME/NAME.toml`).
    pub fixtures: PathBuf,
    /// Output directory.
    pub out: PathBuf,
    /// Backends to run.
    pub backends: Vec<Backend>,
    /// The CI subset: half-size images, 256-sample references, the quick sweeps, 3-frame pans
    /// of the CPU backend only.
    pub quick: bool,
}

/// One run.
#[derive(Debug, Clone, Serialize)]
pub struct Row {
    /// Fixture name.
    pub fixture: String,
    /// Estimator name.
    pub algo: String,
    /// Backend.
    pub backend: String,
    /// The overrides of this setting (`defaults` when none), `k=v;k=v`.
    pub setting: String,
    /// Every parameter as run.
    pub params: BTreeMap<String, String>,
    /// `ok`, or why there is no score (`rejected: ...`).
    pub status: String,
    /// Estimator build stage(s), ms.
    pub build_ms: f64,
    /// Estimator estimate stage(s), ms.
    pub estimate_ms: f64,
    /// Wall clock of build + estimate, ms.
    pub frame_ms: f64,
    /// RMSE against the reference.
    pub rmse: f64,
    /// Mean absolute error.
    pub mae: f64,
    /// 99th percentile of the absolute error.
    pub p99: f64,
    /// Fraction of pixels with |error| > 0.1.
    pub frac_gt_0_1: f64,
    /// Candidate hit pixels whose V is not finite.
    pub nonfinite: usize,
    /// Light-space bytes at the peak.
    pub light_space_bytes: usize,
    /// Median and 95th percentile of the texel density (camera pixels per texel side,
    /// docs/methods.md §1) of the light-centre views the estimator fits; NaN without a map.
    pub texel_density: (f64, f64),
    /// The run's warnings as `kind=count`, `;`-separated (empty when none).
    pub warnings: String,
}

/// One flicker measurement.
#[derive(Debug, Clone, Serialize)]
pub struct FlickerRow {
    /// Fixture name.
    pub fixture: String,
    /// Estimator name.
    pub algo: String,
    /// Backend.
    pub backend: String,
    /// Fit mode.
    pub fit: String,
    /// Mean |dV| between consecutive frames at the same world points.
    pub mean_abs_dv: f64,
    /// Its 99th percentile.
    pub p99_abs_dv: f64,
    /// Pairs measured.
    pub pairs: usize,
}

/// The fixtures under `dir`, sorted: every `NAME/NAME.toml`.
pub fn fixtures(dir: &Path) -> Result<Vec<PathBuf>, String> {
    let rd = std::fs::read_dir(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    let mut out: Vec<PathBuf> = rd
        .filter_map(|d| {
            let d = d.ok()?.path();
            let name = d.file_name()?.to_str()?.to_string();
            let t = d.join(format!("{name}.toml"));
            t.exists().then_some(t)
        })
        .collect();
    out.sort();
    if out.is_empty() {
        return Err(format!("{}: no fixtures (NAME/NAME.toml)", dir.display()));
    }
    Ok(out)
}

/// The key under which the reference image of `scene` at `spp` samples is cached: SHA-256 over
/// the parsed scene (camera, light, every world-space triangle and each mesh's opacity and
/// triangle range), every mesh file's bytes, the sample count and the reference crate's version
/// and revision ([`reference::VERSION`], [`reference::REVISION`]); 128 bits of it as hex. A
/// change to any of them (a TOML value, a mesh, the tracer) misses the cache; a TOML edit that
/// parses to the same scene (a comment, spacing) hits it.
pub fn cache_key(scene: &Scene, spp: u32) -> Result<String, String> {
    use sha2::{Digest, Sha256};
    let mut h = Sha256::new();
    h.update(b"softshadow reference cache\0");
    h.update(reference::VERSION.as_bytes());
    h.update(reference::REVISION.to_le_bytes());
    h.update(spp.to_le_bytes());
    // Debug of f32 is the shortest text that reads back to the same bits: a faithful encoding.
    h.update(format!("{:?}\0{:?}\0", *scene.camera(), *scene.light()).as_bytes());
    for t in scene.triangles() {
        for v in t {
            for x in v.to_array() {
                h.update(x.to_le_bytes());
            }
        }
    }
    for m in scene.meshes() {
        h.update(m.opacity.to_le_bytes());
        h.update((m.triangles.start as u64).to_le_bytes());
        h.update((m.triangles.end as u64).to_le_bytes());
        if m.source.is_file() {
            let bytes =
                std::fs::read(&m.source).map_err(|e| format!("{}: {e}", m.source.display()))?;
            h.update((bytes.len() as u64).to_le_bytes());
            h.update(&bytes);
        }
    }
    let digest = h.finalize();
    Ok(digest[..16].iter().map(|b| format!("{b:02x}")).collect())
}

/// The contract's image of V for `rec` (the camera's receivers): channels `V` and `Z` (view
/// depth, +inf where the receivers carry none).
pub fn visibility_image(
    scene: &Scene,
    rec: &Receivers,
    v: Vec<f32>,
) -> Result<exr_io::VisibilityImage, String> {
    let (w, h) = (
        scene.camera().width as usize,
        scene.camera().height as usize,
    );
    let z = rec
        .view_depth()
        .map_or_else(|| vec![f32::INFINITY; w * h], <[f32]>::to_vec);
    let mut img = exr_io::VisibilityImage::new(w, h);
    img.push_channel("V", v).map_err(|e| e.to_string())?;
    img.push_channel("Z", z).map_err(|e| e.to_string())?;
    Ok(img)
}

fn reference(
    args: &ReportArgs,
    scene: &Scene,
    rec: &Receivers,
) -> Result<exr_io::VisibilityImage, String> {
    let spp: u32 = if args.quick { 256 } else { 1024 };
    let key = cache_key(scene, spp)?;
    let dir = args.out.join("cache");
    std::fs::create_dir_all(&dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    let file = dir.join(format!("reference-{key}.exr"));
    if let Ok(img) = exr_io::read_visibility_exr(&file) {
        return Ok(img);
    }
    let mut r = reference::ReferenceEstimator::new().map_err(|e| e.to_string())?;
    r.set_param("spp", &spp.to_string())
        .map_err(|e| e.to_string())?;
    let (v, _) = shadow_map_core::run(&mut r, scene, rec).map_err(|e| e.to_string())?;
    let img = visibility_image(scene, rec, v)?;
    exr_io::write_exr(&file, &img).map_err(|e| e.to_string())?;
    Ok(img)
}

fn setting_label(s: &[(&'static str, String)]) -> String {
    if s.is_empty() {
        "defaults".into()
    } else {
        s.iter()
            .map(|(k, v)| format!("{k}={v}"))
            .collect::<Vec<_>>()
            .join(";")
    }
}

fn backend_name(b: Backend) -> &'static str {
    match b {
        Backend::Cpu => "cpu",
        Backend::Gpu => "gpu",
    }
}

/// Runs the report and writes its files.
pub fn report(args: &ReportArgs) -> Result<(), String> {
    let t0 = Instant::now();
    let fixtures = fixtures(&args.fixtures)?;
    std::fs::create_dir_all(&args.out).map_err(|e| format!("{}: {e}", args.out.display()))?;
    let img_dir = args.out.join("images");
    std::fs::create_dir_all(&img_dir).map_err(|e| format!("{}: {e}", img_dir.display()))?;
    // The plan: (algo, backend, settings), counted for the progress bar.
    let mut plan: Vec<(&'static str, Backend, Vec<Setting>)> = Vec::new();
    for m in METHODS.iter().filter(|m| m.name() != "reference") {
        let name = m.name();
        for b in &args.backends {
            if !backends(name).contains(&backend_name(*b)) {
                continue;
            }
            let mut settings = vec![Vec::new()];
            settings.extend(m.sweep(args.quick));
            plan.push((name, *b, settings));
        }
    }
    let runs_per_fixture: usize = plan.iter().map(|p| p.2.len()).sum();
    let bar = indicatif::ProgressBar::new((runs_per_fixture * fixtures.len()) as u64);
    bar.set_style(
        indicatif::ProgressStyle::with_template("{elapsed_precise} [{bar:40}] {pos}/{len} {msg}")
            .map_err(|e| e.to_string())?
            .progress_chars("=> "),
    );
    let mut rows: Vec<Row> = Vec::new();
    let mut flicker: Vec<FlickerRow> = Vec::new();
    let mut fixture_names = Vec::new();
    for scene_path in &fixtures {
        let mut scene = Scene::load(scene_path).map_err(|e| e.to_string())?;
        let name = scene_path
            .file_stem()
            .map(|s| s.to_string_lossy().to_string())
            .unwrap_or_default();
        fixture_names.push(name.clone());
        if args.quick {
            let c = *scene.camera();
            scene
                .set_resolution((c.width / 2).max(8), (c.height / 2).max(6))
                .map_err(|e| e.to_string())?;
        }
        let rec = Receivers::from_camera(&scene, &SceneBvh::new(&scene));
        bar.set_message(format!("{name}: reference"));
        let refimg = reference(args, &scene, &rec)?;
        let ref_v = refimg.channel("V").map(|v| v.to_vec()).unwrap_or_default();
        exr_io::write_png_preview(
            &img_dir.join(format!("{name}-reference.png")),
            refimg.width,
            refimg.height,
            &ref_v,
        )
        .map_err(|e| e.to_string())?;
        // Most accurate V per (algo, backend), for the image grid.
        let mut best: BTreeMap<(String, String), (f64, exr_io::VisibilityImage)> = BTreeMap::new();
        for (algo, backend, settings) in &plan {
            for s in settings {
                bar.set_message(format!("{name}: {algo} {backend} {}", setting_label(s)));
                let row = run_one(&name, algo, *backend, s, &scene, &rec, &refimg, &mut best)?;
                rows.push(row);
                bar.inc(1);
            }
        }
        for ((algo, backend), (_, img)) in &best {
            let stem = format!("{name}-{algo}-{backend}");
            if let Some(v) = img.channel("V") {
                exr_io::write_png_preview(
                    &img_dir.join(format!("{stem}.png")),
                    img.width,
                    img.height,
                    v,
                )
                .map_err(|e| e.to_string())?;
            }
            score::write_error_png(
                &img_dir.join(format!("{stem}-error.png")),
                img,
                &refimg,
                score::DEFAULT_ERR_RANGE,
            )
            .map_err(|e| e.to_string())?;
        }
        // Flicker per fit mode: a short pan, every estimator with a `fit` parameter, defaults;
        // the quick report pans the CPU twins only (the GPU twins agree with them within the
        // conformance tolerances, and their pans were most of the quick report's GPU time).
        for (algo, backend, _) in &plan {
            if args.quick && *backend == Backend::Gpu {
                continue;
            }
            let e = estimator(algo, *backend).map_err(|e| e.to_string())?;
            if e.params()
                .get(shadow_map_core::light_view::FIT.key)
                .is_none()
            {
                continue;
            }
            for fit in ["receivers", "scene", "stable"] {
                bar.set_message(format!("{name}: flicker {algo} {backend} fit={fit}"));
                if let Some(f) = flicker_one(&name, algo, *backend, fit, &scene, args.quick)? {
                    flicker.push(f);
                }
            }
        }
    }
    bar.finish_and_clear();
    write_outputs(
        args,
        &fixture_names,
        &rows,
        &flicker,
        t0.elapsed().as_secs_f64(),
    )?;
    eprintln!(
        "softshadow report: {} runs on {} fixtures in {:.0} s; {}",
        rows.len(),
        fixture_names.len(),
        t0.elapsed().as_secs_f64(),
        args.out.join("index.md").display()
    );
    Ok(())
}

#[allow(clippy::too_many_arguments)]
fn run_one(
    fixture: &str,
    algo: &str,
    backend: Backend,
    setting: &[(&'static str, String)],
    scene: &Scene,
    rec: &Receivers,
    refimg: &exr_io::VisibilityImage,
    best: &mut BTreeMap<(String, String), (f64, exr_io::VisibilityImage)>,
) -> Result<Row, String> {
    let mut e = estimator(algo, backend).map_err(|e| e.to_string())?;
    for (k, v) in setting {
        e.set_param(k, v)
            .map_err(|e| format!("{algo} {k}={v}: {e}"))?;
    }
    let params = e
        .params()
        .iter()
        .map(|(k, v)| (k.to_string(), v.to_string()))
        .collect();
    let mut row = Row {
        fixture: fixture.into(),
        algo: algo.into(),
        backend: backend_name(backend).into(),
        setting: setting_label(setting),
        params,
        status: "ok".into(),
        build_ms: f64::NAN,
        estimate_ms: f64::NAN,
        frame_ms: f64::NAN,
        rmse: f64::NAN,
        mae: f64::NAN,
        p99: f64::NAN,
        frac_gt_0_1: f64::NAN,
        nonfinite: 0,
        light_space_bytes: 0,
        texel_density: (f64::NAN, f64::NAN),
        warnings: String::new(),
    };
    let t = Instant::now();
    let mut v = vec![f32::NAN; rec.len()];
    let out = e
        .build(scene, rec)
        .and_then(|_| e.estimate(scene, rec, &mut v));
    let frame_ms = t.elapsed().as_secs_f64() * 1e3;
    if let Err(err) = out {
        row.status = format!("rejected: {err}");
        return Ok(row);
    }
    let rep = e.report();
    row.build_ms = rep.total_ms("build") + rep.total_ms("upload");
    row.estimate_ms = rep.total_ms("estimate") + rep.total_ms("readback");
    // One-time preparation (a frame twin's pipeline compile) is not frame time.
    row.frame_ms = frame_ms - rep.total_ms("prepare");
    row.light_space_bytes = rep.light_space_bytes;
    row.warnings = rep
        .warnings
        .iter()
        .map(|w| format!("{}={}", w.kind(), w.count()))
        .collect::<Vec<_>>()
        .join(";");
    if let Some((m, p95)) = shadow_map_core::cascades::texel_density_summary(scene, rec, e.params())
    {
        row.texel_density = (m as f64, p95 as f64);
    }
    let img = visibility_image(scene, rec, v)?;
    let s = score::score(&img, refimg).map_err(|e| e.to_string())?;
    row.rmse = s.rmse;
    row.mae = s.mae;
    row.p99 = s.p99_abs_error;
    row.frac_gt_0_1 = s.frac_abs_error_gt_0_1;
    row.nonfinite = s.nonfinite_v;
    let key = (algo.to_string(), row.backend.clone());
    if best.get(&key).is_none_or(|b| s.rmse < b.0) {
        best.insert(key, (s.rmse, img));
    }
    Ok(row)
}

fn flicker_one(
    fixture: &str,
    algo: &str,
    backend: Backend,
    fit: &str,
    scene: &Scene,
    quick: bool,
) -> Result<Option<FlickerRow>, String> {
    let mut e = estimator(algo, backend).map_err(|e| e.to_string())?;
    e.set_param("fit", fit).map_err(|e| e.to_string())?;
    let frames = if quick { 3 } else { 6 };
    // A sideways pan of a tenth of the camera's distance to its target.
    let c = *scene.camera();
    let b = c.basis();
    let cam_path = path::CameraPath::Pan(b.right * (0.1 * (c.target - c.eye).length()));
    let mut s = scene.clone();
    let mut flicker = path::Flicker::default();
    // Only the camera moves: one BVH serves every frame.
    let bvh = SceneBvh::new(scene);
    for k in 0..frames {
        s.set_camera(cam_path.camera(&c, k, frames))
            .map_err(|e| e.to_string())?;
        let rec = Receivers::from_camera(&s, &bvh);
        let v = match shadow_map_core::run(e.as_mut(), &s, &rec) {
            Ok((v, _)) => v,
            Err(_) => return Ok(None),
        };
        let f = path::Frame {
            camera: *s.camera(),
            position: rec.position().to_vec(),
            active: rec.active().to_vec(),
            v,
        };
        flicker.push(f);
    }
    let (mean, p99, pairs) = flicker.summary();
    Ok(Some(FlickerRow {
        fixture: fixture.into(),
        algo: algo.into(),
        backend: backend_name(backend).into(),
        fit: fit.into(),
        mean_abs_dv: mean,
        p99_abs_dv: p99,
        pairs,
    }))
}

/// Rows on the Pareto front of (frame ms, RMSE): no other row is both faster and more accurate.
pub fn pareto(rows: &[&Row]) -> Vec<usize> {
    let ok: Vec<usize> = (0..rows.len())
        .filter(|&i| rows[i].rmse.is_finite() && rows[i].frame_ms.is_finite())
        .collect();
    let mut front: Vec<usize> = ok
        .iter()
        .copied()
        .filter(|&i| {
            !ok.iter().any(|&j| {
                j != i
                    && rows[j].frame_ms <= rows[i].frame_ms
                    && rows[j].rmse <= rows[i].rmse
                    && (rows[j].frame_ms < rows[i].frame_ms || rows[j].rmse < rows[i].rmse)
            })
        })
        .collect();
    front.sort_by(|&a, &b| rows[a].frame_ms.total_cmp(&rows[b].frame_ms));
    front
}

#[cfg(test)]
mod tests;
