//! End-to-end fuzz of `softshadow render`: mutated scene TOMLs, OBJs and glTFs (and
//! now and then a mutated command line) rendered with random estimators, random parameters and
//! both backends. Every run must either exit 0 having written a valid EXR (channels V and Z, V in
//! [0, 1] on every hit pixel, V = NaN exactly where Z = +inf, the five provenance attributes) and
//! the PNG asked for, or exit 1 (2 for a command line clap refuses) with exactly one line on
//! standard error and leave no file behind. A panic, a signal, a hang, NaN on a hit pixel or a
//! file left by a failed run is a failure.
//!
//! CI runs [`DEFAULT_RUNS`] runs from a fixed seed, so a failure reproduces. The soak (10^5 runs,
//! outside CI) is the same test with more runs and other seeds:
//!
//! ```text
//! SOFTSHADOW_FUZZ_RUNS=100000 SOFTSHADOW_FUZZ_SEED=7 \
//!   cargo test --release -p softshadow-cli --test cli fuzz -- --nocapture
//! ```
//!
//! Environment: `SOFTSHADOW_FUZZ_RUNS` (runs), `SOFTSHADOW_FUZZ_SEED` (the seed of run 0; run k
//! uses seed + k), `SOFTSHADOW_FUZZ_JOBS` (runs at once, default 2),
//! `SOFTSHADOW_FUZZ_GPU_PERCENT` (the share of runs of a GPU-capable estimator sent to
//! `--backend gpu`, default 50; a GPU run costs a device's start-up), `SOFTSHADOW_FUZZ_KEEP` (a
//! directory where every failing case is kept with its command line). A quarter of the cases turn
//! one mesh into glTF 2.0 (a `.glb`, or a `.gltf` with its buffer in a `data:` URI) before the
//! mutations, which then also flip and cut its bytes or edit its JSON (primitive mode, counts,
//! lengths, URIs, scene and node references).
use serde_json::Value;
use std::collections::BTreeMap;
use std::io::Read;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Mutex;
use std::time::{Duration, Instant};
use toml::{Table, Value as T};

mod mutate;

use mutate::{
    at, glb_of, gltf_parts, mutate_gltf_json, mutate_obj, mutate_scene, mutate_text, param_value,
    pick,
};

/// Runs in CI (about a minute on lavapipe and two cores).
const DEFAULT_RUNS: usize = 160;
/// A run taking longer than this is a hang.
const RUN_TIMEOUT: Duration = Duration::from_secs(180);

/// Fixtures whose scenes seed the mutations (every fixture but hair, whose meshes are 3 MB).
const FIXTURES: &[&str] = &[
    "backlit-bench",
    "backlit-pair",
    "backlit-stone",
    "bunny",
    "bunny-disk",
    "bunny-sphere",
    "field-trees",
    "grazing-posts",
    "grazing-rails",
    "hover-boxes",
    "hover-sphere",
    "long-ground",
    "long-yard",
    "overlapping",
    "parallel-squares",
    "sphere-light",
    "stacked",
    "strands",
    "sun-bunny",
    "sun-fence",
    "sun-half-plane",
    "sun-stone",
    "sun-street",
    "thin-sticks",
];

fn bin() -> Command {
    Command::new(env!("CARGO_BIN_EXE_softshadow"))
}

fn fixtures() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fixtures")
}

fn env_usize(key: &str, default: usize) -> usize {
    std::env::var(key)
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(default)
}

/// One estimator as `softshadow algos --json` lists it.
struct Algo {
    name: String,
    backends: Vec<String>,
    params: Vec<(String, String, String)>, // key, default, range
}

fn algos() -> Vec<Algo> {
    let out = bin().args(["algos", "--json"]).output().unwrap();
    assert!(out.status.success());
    let list: Value = serde_json::from_slice(&out.stdout).unwrap();
    list.as_array()
        .unwrap()
        .iter()
        .map(|e| Algo {
            name: e["name"].as_str().unwrap().to_string(),
            backends: e["backends"]
                .as_array()
                .unwrap()
                .iter()
                .map(|b| b.as_str().unwrap().to_string())
                .collect(),
            params: e["params"]
                .as_array()
                .unwrap()
                .iter()
                .map(|p| {
                    let s = |k: &str| match &p[k] {
                        Value::String(s) => s.clone(),
                        other => other.to_string(),
                    };
                    (s("key"), s("default"), s("range"))
                })
                .collect(),
        })
        .collect()
}

enum Outcome {
    Rendered,
    /// Its error line.
    CleanError(String),
    Failure(String),
}

/// A test case: its directory, arguments and what was mutated.
struct Case {
    args: Vec<String>,
    what: Vec<String>,
    out: PathBuf,
    png: Option<PathBuf>,
    out_dir: PathBuf,
}

/// Builds case `k` (files under `dir`) from its own seed.
fn make_case(seed: u64, dir: &Path, algos: &[Algo], gpu: bool, gpu_percent: u32) -> Case {
    let mut rng = fastrand::Rng::with_seed(seed);
    let mut what = Vec::new();
    let name = *pick(&mut rng, FIXTURES);
    what.push(name.to_string());
    let src_dir = fixtures().join(name);
    let text = std::fs::read_to_string(src_dir.join(format!("{name}.toml"))).unwrap();
    let mut scene = T::Table(text.parse::<Table>().unwrap());
    // Meshes copied beside the scene (mesh0.obj, ...), so mutations touch copies only.
    let mut mesh_files = Vec::new();
    if let Some(T::Array(meshes)) = at(&mut scene, &["mesh".into()]) {
        for (k, m) in meshes.iter_mut().enumerate() {
            if let T::Table(m) = m {
                let p = m["path"].as_str().unwrap().to_string();
                let local = format!("mesh{k}.obj");
                std::fs::copy(src_dir.join(&p), dir.join(&local)).unwrap();
                m.insert("path".into(), T::String(local.clone()));
                mesh_files.push(local);
            }
        }
    }
    // Small images: a run costs milliseconds, not seconds.
    if let Some(T::Table(cam)) = at(&mut scene, &["camera".into()]) {
        cam.insert("width".into(), T::Integer(rng.i64(1..=40)));
        cam.insert("height".into(), T::Integer(rng.i64(1..=30)));
    }
    let n_mut = *pick(&mut rng, &[0, 0, 0, 0, 1, 1, 1, 2, 3]);
    for _ in 0..n_mut {
        mutate_scene(&mut rng, &mut scene, &mut what);
    }
    let mut toml_bytes = toml::to_string(&scene)
        .unwrap_or_else(|_| text.clone())
        .into_bytes();
    if rng.u32(..10) == 0 {
        mutate_text(&mut rng, &mut toml_bytes, &mut what);
    }
    std::fs::write(dir.join("scene.toml"), &toml_bytes).unwrap();
    if !mesh_files.is_empty() && rng.u32(..10) < 3 {
        let f = pick(&mut rng, &mesh_files).clone();
        let text = std::fs::read_to_string(dir.join(&f)).unwrap();
        let bytes = mutate_obj(&mut rng, &text, &mut what);
        std::fs::write(dir.join(&f), bytes).unwrap();
    }
    // One mesh as glTF: the OBJ's triangles written as a .glb or a .gltf, the scene pointed at
    // it (a text replacement, so a mutated TOML stays as mutated), then perhaps mutated.
    if !mesh_files.is_empty() && rng.u32(..4) == 0 {
        let f = pick(&mut rng, &mesh_files).clone();
        if let Ok(tris) = shadow_map_core::scene::load_obj_triangles(&dir.join(&f)) {
            let binary = rng.bool();
            let name = f.replace(".obj", if binary { ".glb" } else { ".gltf" });
            let mut bytes = if binary {
                glb_of(&tris)
            } else {
                gltf_parts(&tris, Some(())).0.into_bytes()
            };
            match rng.u32(..4) {
                0 => mutate_text(&mut rng, &mut bytes, &mut what),
                1 if !binary => {
                    let json = String::from_utf8_lossy(&bytes).into_owned();
                    bytes = mutate_gltf_json(&mut rng, &json, &mut what).into_bytes();
                }
                _ => {}
            }
            std::fs::write(dir.join(&name), bytes).unwrap();
            let toml = String::from_utf8_lossy(&toml_bytes).replace(&f, &name);
            std::fs::write(dir.join("scene.toml"), toml).unwrap();
            what.push(format!("{f} as {name}"));
        }
    }

    let algo = pick(&mut rng, algos);
    let backend = if gpu && algo.backends.iter().any(|b| b == "gpu") && rng.u32(..100) < gpu_percent
    {
        "gpu"
    } else {
        "cpu"
    };
    let out_dir = dir.join("out");
    std::fs::create_dir_all(&out_dir).unwrap();
    let out = out_dir.join("v.exr");
    let mut args: Vec<String> = vec![
        "render".into(),
        dir.join("scene.toml").display().to_string(),
        "--algo".into(),
        algo.name.clone(),
        "--backend".into(),
        backend.into(),
        "--out".into(),
        out.display().to_string(),
    ];
    // The reference at its default sample count would dominate the run time.
    if algo.name == "reference" {
        args.extend(["--param".into(), format!("spp={}", rng.u32(1..=16))]);
    }
    for _ in 0..*pick(&mut rng, &[0, 0, 1, 2, 3]) {
        let (key, default, range) = pick(&mut rng, &algo.params);
        let v = param_value(&mut rng, key, default, range);
        args.extend(["--param".into(), format!("{key}={v}")]);
    }
    let png = rng.bool().then(|| out_dir.join("v.png"));
    if let Some(p) = &png {
        args.extend(["--png".into(), p.display().to_string()]);
    }
    if rng.bool() {
        args.push("--stats".into());
    }
    // Now and then a malformed command line.
    if rng.u32(..20) == 0 {
        match rng.u32(..5) {
            0 => args[3] = "nope".into(),
            1 => args[5] = "tpu".into(),
            2 => args.extend(["--param".into(), "resolution".into()]),
            3 => args.extend(["--frames".into(), "3".into()]),
            _ => args.push("--unknown-flag".into()),
        }
        what.push("command line".into());
    }
    what.push(format!("{} on {backend}", algo.name));
    Case {
        args,
        what,
        out,
        png,
        out_dir,
    }
}

/// Reads the EXR a successful run wrote and checks it against the contract.
fn check_exr(path: &Path) -> Result<(), String> {
    let image = crate::first_layer::read_first_layer(path)
        .map_err(|e| format!("the EXR does not read back: {e}"))?;
    // The contract's provenance: five string attributes in the header.
    let names: Vec<String> = image
        .attributes
        .other
        .keys()
        .chain(image.layer_data.attributes.other.keys())
        .map(|k| k.to_string())
        .collect();
    for key in [
        "softshadow.algo",
        "softshadow.backend",
        "softshadow.params",
        "softshadow.version",
        "softshadow.scene",
    ] {
        if !names.iter().any(|n| n == key) {
            return Err(format!("the EXR lacks the attribute {key}"));
        }
    }
    let layer = image.layer_data;
    let n = layer.size.width() * layer.size.height();
    let mut chans: BTreeMap<String, Vec<f32>> = BTreeMap::new();
    for c in layer.channel_data.list.iter() {
        chans.insert(c.name.to_string(), c.sample_data.values_as_f32().collect());
    }
    let (Some(v), Some(z)) = (chans.get("V"), chans.get("Z")) else {
        return Err(format!("channels {:?}, not V and Z", chans.keys()));
    };
    if v.len() != n || z.len() != n {
        return Err("channel length is not the image size".into());
    }
    for k in 0..n {
        let hit = z[k].is_finite();
        if hit && !(0.0..=1.0).contains(&v[k]) {
            return Err(format!(
                "pixel {k}: V = {} on a hit pixel (Z = {})",
                v[k], z[k]
            ));
        }
        let background = z[k] == f32::INFINITY && v[k].is_nan();
        if !hit && !background {
            return Err(format!(
                "pixel {k}: background with Z = {}, V = {}",
                z[k], v[k]
            ));
        }
    }
    Ok(())
}

fn run_case(case: &Case) -> Outcome {
    let mut child = bin()
        .args(&case.args)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    // Drain both pipes while waiting (a full pipe must not stall the child).
    let mut so = child.stdout.take().unwrap();
    let mut se = child.stderr.take().unwrap();
    let h_out = std::thread::spawn(move || {
        let mut s = Vec::new();
        let _ = so.read_to_end(&mut s);
        s
    });
    let h_err = std::thread::spawn(move || {
        let mut s = Vec::new();
        let _ = se.read_to_end(&mut s);
        s
    });
    let t = Instant::now();
    let status = loop {
        if let Some(s) = child.try_wait().unwrap() {
            break s;
        }
        if t.elapsed() > RUN_TIMEOUT {
            let _ = child.kill();
            let _ = child.wait();
            return Outcome::Failure(format!("hang: no exit after {RUN_TIMEOUT:?}"));
        }
        std::thread::sleep(Duration::from_millis(5));
    };
    let _ = h_out.join();
    let stderr = String::from_utf8_lossy(&h_err.join().unwrap()).into_owned();
    let left: Vec<String> = std::fs::read_dir(&case.out_dir)
        .unwrap()
        .flatten()
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .collect();
    match status.code() {
        Some(0) => {
            if let Err(e) = check_exr(&case.out) {
                return Outcome::Failure(e);
            }
            if let Some(p) = &case.png {
                if !p.exists() {
                    return Outcome::Failure("exit 0 without the PNG asked for".into());
                }
            }
            Outcome::Rendered
        }
        Some(code) => {
            let err = stderr.trim_end();
            // 1: a refused input; 2: a command line clap refuses.
            if code != 1 && code != 2 {
                return Outcome::Failure(format!("exit code {code}: {err}"));
            }
            if err.is_empty() || err.lines().count() != 1 || !err.starts_with("softshadow: ") {
                return Outcome::Failure(format!("not one error line: {err:?}"));
            }
            if err.contains("panicked") {
                return Outcome::Failure(format!("panic: {err}"));
            }
            if !left.is_empty() {
                return Outcome::Failure(format!("failed run left {left:?}: {err}"));
            }
            Outcome::CleanError(err.to_string())
        }
        None => Outcome::Failure(format!("killed by a signal: {status:?}: {stderr}")),
    }
}

/// An error line without its paths and numbers, to count errors by kind.
fn error_kind(line: &str) -> String {
    let body = line.strip_prefix("softshadow: ").unwrap_or(line);
    let words: Vec<String> = body
        .split_whitespace()
        .filter(|w| !w.contains('/'))
        .map(|w| {
            if w.chars().any(|c| c.is_ascii_digit()) {
                "#".to_string()
            } else {
                w.to_string()
            }
        })
        .take(8)
        .collect();
    words.join(" ")
}

#[test]
fn cli_fuzz_renders_or_fails_cleanly() {
    let runs = env_usize("SOFTSHADOW_FUZZ_RUNS", DEFAULT_RUNS);
    let seed = env_usize("SOFTSHADOW_FUZZ_SEED", 1) as u64;
    let jobs = env_usize("SOFTSHADOW_FUZZ_JOBS", 2).max(1);
    let keep = std::env::var_os("SOFTSHADOW_FUZZ_KEEP").map(PathBuf::from);
    let gpu_percent = env_usize("SOFTSHADOW_FUZZ_GPU_PERCENT", 50).min(100) as u32;
    let gpu = match test_support::gate::context_for_tests("cli_fuzz_renders_or_fails_cleanly") {
        Ok(Some(_)) => true,
        Ok(None) => false,
        Err(e) => panic!("{e}"),
    };
    let algos = algos();
    let root = tempfile::tempdir().unwrap();
    let next = AtomicUsize::new(0);
    // Per backend (cpu, gpu): rendered, clean errors, failures.
    let counts = Mutex::new([[0usize; 3]; 2]);
    let errors: Mutex<BTreeMap<String, usize>> = Mutex::new(BTreeMap::new());
    let failures: Mutex<Vec<String>> = Mutex::new(Vec::new());
    let t = Instant::now();
    std::thread::scope(|s| {
        for _ in 0..jobs {
            s.spawn(|| loop {
                let k = next.fetch_add(1, Ordering::Relaxed);
                if k >= runs {
                    break;
                }
                let dir = root.path().join(format!("case{k}"));
                std::fs::create_dir_all(&dir).unwrap();
                let case = make_case(seed + k as u64, &dir, &algos, gpu, gpu_percent);
                let outcome = run_case(&case);
                let mut all = counts.lock().unwrap();
                let c = &mut all[usize::from(case.args.iter().any(|a| a == "gpu"))];
                match outcome {
                    Outcome::Rendered => c[0] += 1,
                    Outcome::CleanError(ref e) => {
                        c[1] += 1;
                        *errors.lock().unwrap().entry(error_kind(e)).or_default() += 1;
                    }
                    Outcome::Failure(why) => {
                        c[2] += 1;
                        let line = format!(
                            "seed {}: {why}\n    mutations: {}\n    args: {}",
                            seed + k as u64,
                            case.what.join("; "),
                            case.args.join(" ")
                        );
                        eprintln!("FAIL {line}");
                        failures.lock().unwrap().push(line);
                        if let Some(keep) = &keep {
                            let dst = keep.join(format!("seed{}", seed + k as u64));
                            let _ = std::fs::create_dir_all(&dst);
                            for f in std::fs::read_dir(&dir).unwrap().flatten() {
                                if f.path().is_file() {
                                    let _ = std::fs::copy(f.path(), dst.join(f.file_name()));
                                }
                            }
                            let _ = std::fs::write(dst.join("args.txt"), case.args.join(" "));
                        }
                    }
                }
                drop(all);
                let _ = std::fs::remove_dir_all(&dir);
            });
        }
    });
    let by = *counts.lock().unwrap();
    let c: Vec<usize> = (0..3).map(|i| by[0][i] + by[1][i]).collect();
    println!(
        "cli fuzz by backend: cpu {} rendered, {} clean errors, {} failures; gpu {} rendered, {} clean errors, {} failures",
        by[0][0], by[0][1], by[0][2], by[1][0], by[1][1], by[1][2]
    );
    println!(
        "cli fuzz: seed {seed}, runs {runs}, rendered {}, clean errors {}, failures {} ({:.1} s, {} jobs, gpu {gpu}, {gpu_percent}% of GPU-capable runs on the GPU)",
        c[0],
        c[1],
        c[2],
        t.elapsed().as_secs_f64(),
        jobs
    );
    let mut kinds: Vec<(String, usize)> = errors.into_inner().unwrap().into_iter().collect();
    kinds.sort_by_key(|k| std::cmp::Reverse(k.1));
    for (kind, n) in kinds.iter().take(40) {
        println!("  {n:6}  {kind}");
    }
    let failures = failures.into_inner().unwrap();
    assert!(
        failures.is_empty(),
        "{} failures:\n{}",
        failures.len(),
        failures.join("\n")
    );
    // The fuzz must exercise both outcomes, or it tests nothing.
    assert!(c[0] > runs / 5, "only {} of {runs} runs rendered", c[0]);
    assert!(
        c[1] > runs / 10,
        "only {} of {runs} runs failed cleanly",
        c[1]
    );
}
