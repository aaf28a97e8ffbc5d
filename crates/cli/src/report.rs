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
use serde_json::json;
use shadow_map_core::{Backend, Receivers, Scene, SceneBvh, SoftShadowEstimator};
use softshadow::{backends, estimator, Setting, ALGOS, METHODS};
use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

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

fn csv_field(s: &str) -> String {
    if s.contains([',', '"', '\n']) {
        format!("\"{}\"", s.replace('"', "\"\""))
    } else {
        s.to_string()
    }
}

fn num(x: f64) -> String {
    if x.is_finite() {
        format!("{x:.6}")
    } else {
        String::new()
    }
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

/// What a plot's x axis shows.
#[derive(Clone, Copy, PartialEq)]
enum PlotX {
    /// `frame_ms`: build + estimate.
    Time,
    /// `light_space_bytes`: the light-space data's memory.
    Memory,
}

impl PlotX {
    fn of(self, r: &Row) -> f64 {
        match self {
            PlotX::Time => r.frame_ms,
            PlotX::Memory => r.light_space_bytes as f64,
        }
    }
    fn desc(self) -> &'static str {
        match self {
            PlotX::Time => "build + estimate, ms (log)",
            PlotX::Memory => "light-space data, bytes (log)",
        }
    }
    fn title(self) -> &'static str {
        match self {
            PlotX::Time => "frame time vs RMSE",
            PlotX::Memory => "light-space memory vs RMSE",
        }
    }
}

/// One fixture's RMSE against `x` (time or memory, log scale) for every run: a colour per
/// algorithm, a marker shape per backend (circle CPU, triangle GPU), filled for the seed methods
/// and hollow for the baselines; the legend draws exactly those markers (the algorithms in
/// their colour as CPU circles, then the two backend shapes in black); the time plot adds the
/// Pareto front over both backends.
fn plot(path: &Path, fixture: &str, rows: &[&Row], x: PlotX) -> Result<(), String> {
    use plotters::prelude::*;
    let ok: Vec<&Row> = rows
        .iter()
        .copied()
        .filter(|r| r.rmse.is_finite() && x.of(r).is_finite() && x.of(r) > 0.0)
        .collect();
    let root = SVGBackend::new(path, (760, 480)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| e.to_string())?;
    let xmin = ok
        .iter()
        .map(|r| x.of(r))
        .fold(f64::INFINITY, f64::min)
        .clamp(1e-3, 1e30);
    let xmax = ok
        .iter()
        .map(|r| x.of(r))
        .fold(0.0, f64::max)
        .max(xmin * 2.0);
    let emax = ok.iter().map(|r| r.rmse).fold(0.0, f64::max).max(1e-3) * 1.1;
    let mut chart = ChartBuilder::on(&root)
        .caption(format!("{fixture}: {}", x.title()), ("sans-serif", 18))
        .margin(10)
        .x_label_area_size(40)
        .y_label_area_size(60)
        .build_cartesian_2d((xmin / 1.5..xmax * 1.5).log_scale(), 0.0..emax)
        .map_err(|e| e.to_string())?;
    chart
        .configure_mesh()
        .x_desc(x.desc())
        .y_desc("RMSE vs reference")
        .draw()
        .map_err(|e| e.to_string())?;
    let algos: Vec<String> = {
        let mut a: Vec<String> = ok.iter().map(|r| r.algo.clone()).collect();
        a.sort();
        a.dedup();
        a
    };
    for (k, algo) in algos.iter().enumerate() {
        let colour = Palette99::pick(k).to_rgba();
        let baseline = BASELINES.contains(&algo.as_str());
        let label = if baseline {
            format!("{algo} (baseline)")
        } else {
            algo.clone()
        };
        // Filled for the seed methods, hollow for the baselines.
        let style = if baseline {
            colour.stroke_width(2)
        } else {
            colour.filled()
        };
        let pts = |gpu: bool| -> Vec<(f64, f64)> {
            ok.iter()
                .filter(|r| &r.algo == algo && (r.backend == "gpu") == gpu)
                .map(|r| (x.of(r), r.rmse))
                .collect()
        };
        chart
            .draw_series(
                pts(true)
                    .into_iter()
                    .map(|at| TriangleMarker::new(at, 5, style)),
            )
            .map_err(|e| e.to_string())?;
        chart
            .draw_series(pts(false).into_iter().map(|at| Circle::new(at, 4, style)))
            .map_err(|e| e.to_string())?
            .label(label)
            .legend(move |at| Circle::new(at, 4, style));
    }
    // The backends' shapes, in black.
    if ok.iter().any(|r| r.backend != "gpu") {
        chart
            .draw_series(std::iter::empty::<Circle<(f64, f64), i32>>())
            .map_err(|e| e.to_string())?
            .label("CPU")
            .legend(|at| Circle::new(at, 4, BLACK.filled()));
    }
    if ok.iter().any(|r| r.backend == "gpu") {
        chart
            .draw_series(std::iter::empty::<Circle<(f64, f64), i32>>())
            .map_err(|e| e.to_string())?
            .label("GPU")
            .legend(|at| TriangleMarker::new(at, 5, BLACK.filled()));
    }
    if x == PlotX::Time {
        let front: Vec<(f64, f64)> = pareto(&ok)
            .iter()
            .map(|&i| (ok[i].frame_ms, ok[i].rmse))
            .collect();
        chart
            .draw_series(LineSeries::new(front, BLACK.stroke_width(1)))
            .map_err(|e| e.to_string())?
            .label("Pareto front")
            .legend(|(x, y)| PathElement::new(vec![(x - 8, y), (x + 8, y)], BLACK));
    }
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .position(SeriesLabelPosition::UpperRight)
        .draw()
        .map_err(|e| e.to_string())?;
    root.present().map_err(|e| e.to_string())?;
    Ok(())
}

fn write_outputs(
    args: &ReportArgs,
    fixtures: &[String],
    rows: &[Row],
    flicker: &[FlickerRow],
    seconds: f64,
) -> Result<(), String> {
    // CSV and JSON.
    write_file(args.out.join("results.csv"), results_csv(rows))?;
    write_file(
        args.out.join("results.json"),
        results_json(args, rows, flicker, seconds)?,
    )?;
    write_file(args.out.join("flicker.csv"), flicker_csv(flicker))?;

    // index.md
    let mut md = index_intro(args, fixtures, rows, seconds);
    let budgets = [10.0, 30.0, 100.0, 300.0, 1000.0, f64::INFINITY];
    let mut summary = summary_header(&budgets);
    let mut matched = matched_header();
    for fx in fixtures {
        let fr: Vec<&Row> = rows.iter().filter(|r| &r.fixture == fx).collect();
        let svg = format!("plot-{fx}.svg");
        plot(&args.out.join(&svg), fx, &fr, PlotX::Time)?;
        let mem = format!("memory-{fx}.svg");
        plot(&args.out.join(&mem), fx, &fr, PlotX::Memory)?;
        fixture_section(&mut md, fx, &svg, &mem, &fr);
        summary_row(&mut summary, fx, &fr, &budgets);
        matched_rows(&mut matched, fx, &fr);
    }
    md.push_str(&summary);
    md.push('\n');
    md.push_str(&matched);
    md.push('\n');
    flicker_section(&mut md, flicker);
    write_file(args.out.join("index.md"), md)?;
    Ok(())
}

/// Writes `s` to `p`, naming the path in the error.
fn write_file(p: PathBuf, s: String) -> Result<(), String> {
    std::fs::write(&p, s).map_err(|e| format!("{}: {e}", p.display()))
}

/// `results.csv`: one line per run.
fn results_csv(rows: &[Row]) -> String {
    let mut csv = String::from("fixture,algo,backend,setting,params,status,build_ms,estimate_ms,frame_ms,rmse,mae,p99,frac_gt_0_1,nonfinite,light_space_bytes,texel_density_median,texel_density_p95,warnings\n");
    for r in rows {
        let params: Vec<String> = r.params.iter().map(|(k, v)| format!("{k}={v}")).collect();
        let _ = writeln!(
            csv,
            "{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{}",
            csv_field(&r.fixture),
            csv_field(&r.algo),
            r.backend,
            csv_field(&r.setting),
            csv_field(&params.join(";")),
            csv_field(&r.status),
            num(r.build_ms),
            num(r.estimate_ms),
            num(r.frame_ms),
            num(r.rmse),
            num(r.mae),
            num(r.p99),
            num(r.frac_gt_0_1),
            r.nonfinite,
            r.light_space_bytes,
            num(r.texel_density.0),
            num(r.texel_density.1),
            csv_field(&r.warnings)
        );
    }
    csv
}

/// A JSON number, or `null` when not finite.
fn json_num(x: f64) -> serde_json::Value {
    if x.is_finite() {
        json!(x)
    } else {
        serde_json::Value::Null
    }
}

/// `results.json`: the runs and flicker rows, pretty-printed.
fn results_json(
    args: &ReportArgs,
    rows: &[Row],
    flicker: &[FlickerRow],
    seconds: f64,
) -> Result<String, String> {
    let jnum = json_num;
    let jrows: Vec<serde_json::Value> = rows
        .iter()
        .map(|r| {
            json!({
                "fixture": r.fixture, "algo": r.algo, "backend": r.backend,
                "setting": r.setting, "params": r.params, "status": r.status,
                "build_ms": jnum(r.build_ms), "estimate_ms": jnum(r.estimate_ms),
                "frame_ms": jnum(r.frame_ms), "rmse": jnum(r.rmse), "mae": jnum(r.mae),
                "p99": jnum(r.p99), "frac_gt_0_1": jnum(r.frac_gt_0_1),
                "nonfinite": r.nonfinite, "light_space_bytes": r.light_space_bytes,
                "texel_density_median": jnum(r.texel_density.0),
                "texel_density_p95": jnum(r.texel_density.1),
                "warnings": r.warnings,
            })
        })
        .collect();
    let jflicker: Vec<serde_json::Value> = flicker
        .iter()
        .map(|f| {
            json!({
                "fixture": f.fixture, "algo": f.algo, "backend": f.backend, "fit": f.fit,
                "mean_abs_dv": jnum(f.mean_abs_dv), "p99_abs_dv": jnum(f.p99_abs_dv),
                "pairs": f.pairs,
            })
        })
        .collect();
    serde_json::to_string_pretty(&json!({
        "quick": args.quick,
        "seconds": seconds,
        "runs": jrows,
        "flicker": jflicker,
    }))
    .map_err(|e| e.to_string())
}

/// `flicker.csv`: one line per flicker measurement.
fn flicker_csv(flicker: &[FlickerRow]) -> String {
    let mut fcsv = String::from("fixture,algo,backend,fit,mean_abs_dv,p99_abs_dv,pairs\n");
    for f in flicker {
        let _ = writeln!(
            fcsv,
            "{},{},{},{},{},{},{}",
            f.fixture,
            f.algo,
            f.backend,
            f.fit,
            num(f.mean_abs_dv),
            num(f.p99_abs_dv),
            f.pairs
        );
    }
    fcsv
}

/// The title and opening paragraph of `index.md`.
fn index_intro(args: &ReportArgs, fixtures: &[String], rows: &[Row], seconds: f64) -> String {
    let mut md = String::new();
    let _ = writeln!(md, "# softshadow report\n");
    let _ =
        writeln!(
        md,
        "{} runs, {} fixtures, {}, {:.0} s. Regenerate: `softshadow report{} --out {}`. Times: \
         build + estimate wall clock of one run (see `crates/cli/src/report.rs`); RMSE against \
         the ray-traced reference ({} spp). Baselines are drawn as crosses.\n",
        rows.len(),
        fixtures.len(),
        if args.quick { "quick (half-size images)" } else { "full" },
        seconds,
        if args.quick { " --quick" } else { "" },
        args.out.display(),
        if args.quick { 256 } else { 1024 }
    );
    md
}

/// The heading and table head of the summary: one column per time budget.
fn summary_header(budgets: &[f64]) -> String {
    let mut summary = String::new();
    let _ = writeln!(
        summary,
        "## Summary: most accurate setting within each time budget\n"
    );
    let _ = write!(summary, "| fixture |");
    for &b in budgets {
        if b.is_finite() {
            let _ = write!(summary, " <= {b} ms |");
        } else {
            let _ = write!(summary, " any time |");
        }
    }
    let _ = writeln!(summary, "\n|---|{}", "---|".repeat(budgets.len()));
    summary
}

/// The heading and table head of the matched-time comparison.
fn matched_header() -> String {
    let mut matched = String::new();
    let _ = writeln!(
        matched,
        "## Each seed algorithm against PCSS and multi-sample at matched time\n\n\
         Per fixture and backend: the seed algorithm's most accurate setting, and the most \
         accurate PCSS and multi-sample setting that is no slower.\n\n\
         | fixture | backend | algorithm (setting) | ms | RMSE | PCSS RMSE within that time | multi-sample RMSE within that time |\n|---|---|---|---|---|---|---|"
    );
    matched
}

/// A fixture's section of `index.md`: its plot, Pareto table, runs not made and best images.
fn fixture_section(md: &mut String, fx: &str, svg: &str, mem: &str, fr: &[&Row]) {
    let _ = writeln!(md, "## {fx}\n\n![{fx}]({svg})\n\n![{fx}: memory]({mem})\n");
    let _ = writeln!(md, "Pareto-optimal settings:\n\n| algo | backend | setting | ms | RMSE | p99 |\n|---|---|---|---|---|---|");
    for i in pareto(fr) {
        let r = fr[i];
        let _ = writeln!(
            md,
            "| {} | {} | {} | {:.1} | {:.4} | {:.3} |",
            r.algo, r.backend, r.setting, r.frame_ms, r.rmse, r.p99
        );
    }
    let rejected: Vec<String> = fr
        .iter()
        .filter(|r| r.status != "ok")
        .map(|r| format!("{} {} ({})", r.algo, r.backend, r.status))
        .collect::<std::collections::BTreeSet<_>>()
        .into_iter()
        .collect();
    if !rejected.is_empty() {
        let _ = writeln!(md, "\nNot run: {}", rejected.join("; "));
    }
    let warned: Vec<String> = fr
        .iter()
        .filter(|r| !r.warnings.is_empty())
        .map(|r| format!("{} {} `{}`: {}", r.algo, r.backend, r.setting, r.warnings))
        .collect();
    if !warned.is_empty() {
        let _ = writeln!(md, "\nWarnings (kind=count): {}", warned.join("; "));
    }
    let _ = writeln!(md, "\nMost accurate setting of each algorithm (V, then error: blue too dark, red too bright):\n");
    let _ = writeln!(
        md,
        "| reference | | |\n|---|---|---|\n| ![ref](images/{fx}-reference.png) | | |"
    );
    let mut algos: Vec<(String, String)> = fr
        .iter()
        .filter(|r| r.status == "ok")
        .map(|r| (r.algo.clone(), r.backend.clone()))
        .collect();
    algos.sort();
    algos.dedup();
    for (a, b) in &algos {
        let best = fr
            .iter()
            .filter(|r| &r.algo == a && &r.backend == b && r.rmse.is_finite())
            .min_by(|x, y| x.rmse.total_cmp(&y.rmse));
        if let Some(r) = best {
            let _ = writeln!(
                md,
                "| {a} {b} `{}` RMSE {:.4} | ![v](images/{fx}-{a}-{b}.png) | ![e](images/{fx}-{a}-{b}-error.png) |",
                r.setting, r.rmse
            );
        }
    }
    let _ = writeln!(md);
}

/// A fixture's summary row: its most accurate run within each time budget.
fn summary_row(summary: &mut String, fx: &str, fr: &[&Row], budgets: &[f64]) {
    let _ = write!(summary, "| {fx} |");
    for &b in budgets {
        let best = fr
            .iter()
            .filter(|r| r.rmse.is_finite() && r.frame_ms <= b)
            .min_by(|x, y| x.rmse.total_cmp(&y.rmse));
        match best {
            Some(r) => {
                let _ = write!(
                    summary,
                    " {} {} `{}` {:.4} |",
                    r.algo, r.backend, r.setting, r.rmse
                );
            }
            None => {
                let _ = write!(summary, " none |");
            }
        }
    }
    let _ = writeln!(summary);
}

/// A fixture's matched-time rows: each seed algorithm's best run per backend against the best
/// PCSS and multi-sample runs that are no slower.
fn matched_rows(matched: &mut String, fx: &str, fr: &[&Row]) {
    for backend in ["cpu", "gpu"] {
        for seed in ALGOS
            .iter()
            .filter(|a| **a != "reference" && !BASELINES.contains(a))
        {
            let best = fr
                .iter()
                .filter(|r| r.algo == *seed && r.backend == backend && r.rmse.is_finite())
                .min_by(|x, y| x.rmse.total_cmp(&y.rmse));
            let Some(s) = best else { continue };
            let within = |algo: &str| {
                fr.iter()
                    .filter(|r| {
                        r.algo == algo
                            && r.backend == backend
                            && r.rmse.is_finite()
                            && r.frame_ms <= s.frame_ms
                    })
                    .map(|r| r.rmse)
                    .fold(f64::INFINITY, f64::min)
            };
            let f = |x: f64| {
                if x.is_finite() {
                    format!("{x:.4}")
                } else {
                    "none that fast".into()
                }
            };
            let _ = writeln!(
                matched,
                "| {fx} | {backend} | {seed} (`{}`) | {:.1} | {:.4} | {} | {} |",
                s.setting,
                s.frame_ms,
                s.rmse,
                f(within("pcss")),
                f(within("multi-sample"))
            );
        }
    }
}

/// The flicker section of `index.md`: one table row per fit-mode measurement.
fn flicker_section(md: &mut String, flicker: &[FlickerRow]) {
    let _ = writeln!(
        md,
        "## Flicker per fit mode\n\nMean and 99th percentile of |dV| between consecutive frames \
         of a sideways camera pan, at the same world points (`crates/cli/src/path.rs`).\n\n\
         | fixture | algo | backend | fit | mean abs dV | p99 abs dV | pairs |\n|---|---|---|---|---|---|---|"
    );
    for f in flicker {
        let _ = writeln!(
            md,
            "| {} | {} | {} | {} | {:.5} | {:.4} | {} |",
            f.fixture, f.algo, f.backend, f.fit, f.mean_abs_dv, f.p99_abs_dv, f.pairs
        );
    }
}

#[cfg(test)]
mod tests {
    use super::cache_key;
    use shadow_map_core::Scene;
    use std::path::Path;

    /// The reference cache's key follows the parsed scene, the mesh files and the sample count:
    /// a comment or spacing in the TOML keeps it, a value, a mesh byte or the sample count moves
    /// it.
    #[test]
    fn cache_key_follows_the_scene_the_meshes_and_the_samples() {
        let dir = tempfile::tempdir().unwrap();
        let fixtures = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fixtures");
        let toml = std::fs::read_to_string(fixtures.join("parallel-squares/parallel-squares.toml"))
            .unwrap();
        let plane = fixtures.join("common/plane.obj");
        let occ = std::fs::read_to_string(fixtures.join("parallel-squares/occluder.obj")).unwrap();
        std::fs::write(dir.path().join("occluder.obj"), &occ).unwrap();
        let toml = toml.replace("../common/plane.obj", &plane.display().to_string());
        let key = |text: &str, spp: u32| {
            let p = dir.path().join("scene.toml");
            std::fs::write(&p, text).unwrap();
            cache_key(&Scene::load(&p).unwrap(), spp).unwrap()
        };
        let base = key(&toml, 256);
        assert_eq!(base.len(), 32);
        assert_eq!(key(&toml, 256), base, "not deterministic");
        let commented = format!("# a comment\n{}", toml.replace(" = ", "   =   "));
        assert_eq!(key(&commented, 256), base, "a comment moved the key");
        assert_ne!(key(&toml, 1024), base, "the sample count");
        assert_ne!(
            key(&toml.replace("fov_y_deg = 40.0", "fov_y_deg = 41.0"), 256),
            base,
            "a camera value"
        );
        // A mesh byte that moves no vertex (a comment) still moves the key: its bytes are hashed.
        std::fs::write(dir.path().join("occluder.obj"), format!("# edited\n{occ}")).unwrap();
        assert_ne!(key(&toml, 256), base, "the mesh file's bytes");
    }
}
