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
use exr::prelude::{ReadChannels, ReadLayers};
use serde_json::Value;
use std::collections::BTreeMap;
use std::io::Read;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Mutex;
use std::time::{Duration, Instant};
use toml::{Table, Value as T};

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

fn pick<'a, X>(rng: &mut fastrand::Rng, xs: &'a [X]) -> &'a X {
    &xs[rng.usize(..xs.len())]
}

/// A weird number: zero, a sign flip, far too large or small, non-finite, or a random one.
fn weird_number(rng: &mut fastrand::Rng, x: f64) -> T {
    match rng.u32(..12) {
        0 => T::Float(0.0),
        1 => T::Float(-x),
        2 => T::Float(x * 1e6),
        3 => T::Float(x * 1e-6),
        4 => T::Float(f64::NAN),
        5 => T::Float(f64::INFINITY),
        6 => T::Float(f64::NEG_INFINITY),
        7 => T::Float(1e30),
        8 => T::Float(-1e-30),
        9 => T::Integer(x as i64),
        10 => T::String("1.0".into()),
        _ => T::Float(rng.f64() * 20.0 - 10.0),
    }
}

/// Paths (table keys and array indices) of every number in `v`.
fn number_paths(v: &T, path: &mut Vec<String>, out: &mut Vec<Vec<String>>) {
    match v {
        T::Integer(_) | T::Float(_) => out.push(path.clone()),
        T::Array(a) => {
            for (k, x) in a.iter().enumerate() {
                path.push(k.to_string());
                number_paths(x, path, out);
                path.pop();
            }
        }
        T::Table(t) => {
            for (k, x) in t {
                path.push(k.clone());
                number_paths(x, path, out);
                path.pop();
            }
        }
        _ => {}
    }
}

fn at<'a>(v: &'a mut T, path: &[String]) -> Option<&'a mut T> {
    let mut cur = v;
    for p in path {
        cur = match cur {
            T::Table(t) => t.get_mut(p)?,
            T::Array(a) => a.get_mut(p.parse::<usize>().ok()?)?,
            _ => return None,
        };
    }
    Some(cur)
}

/// Every table in `v` (as paths), the root included.
fn table_paths(v: &T, path: &mut Vec<String>, out: &mut Vec<Vec<String>>) {
    match v {
        T::Table(t) => {
            out.push(path.clone());
            for (k, x) in t {
                path.push(k.clone());
                table_paths(x, path, out);
                path.pop();
            }
        }
        T::Array(a) => {
            for (k, x) in a.iter().enumerate() {
                path.push(k.to_string());
                table_paths(x, path, out);
                path.pop();
            }
        }
        _ => {}
    }
}

fn vec3(rng: &mut fastrand::Rng, scale: f64) -> T {
    T::Array(
        (0..3)
            .map(|_| T::Float((rng.f64() * 2.0 - 1.0) * scale))
            .collect(),
    )
}

/// One structural mutation of the scene table.
fn mutate_scene(rng: &mut fastrand::Rng, scene: &mut T, what: &mut Vec<String>) {
    match rng.u32(..10) {
        0 | 1 => {
            let mut paths = Vec::new();
            number_paths(scene, &mut vec![], &mut paths);
            if let Some(p) = paths.get(rng.usize(..paths.len().max(1))) {
                if let Some(x) = at(scene, p) {
                    let old = match x {
                        T::Integer(i) => *i as f64,
                        T::Float(f) => *f,
                        _ => 1.0,
                    };
                    *x = weird_number(rng, old);
                    what.push(format!("{} = {x}", p.join(".")));
                }
            }
        }
        2 => {
            // Delete a key anywhere.
            let mut tables = Vec::new();
            table_paths(scene, &mut vec![], &mut tables);
            let p = pick(rng, &tables).clone();
            if let Some(T::Table(t)) = at(scene, &p) {
                let keys: Vec<String> = t.keys().cloned().collect();
                if !keys.is_empty() {
                    let k = pick(rng, &keys).clone();
                    t.remove(&k);
                    what.push(format!("removed {}.{k}", p.join(".")));
                }
            }
        }
        3 => {
            let mut tables = Vec::new();
            table_paths(scene, &mut vec![], &mut tables);
            let p = pick(rng, &tables).clone();
            if let Some(T::Table(t)) = at(scene, &p) {
                t.insert("bogus".into(), T::Integer(1));
                what.push(format!("added {}.bogus", p.join(".")));
            }
        }
        4 => {
            // Another light shape, with or without its keys.
            let shape = *pick(
                rng,
                &["rect", "disk", "sphere", "directional", "cone", "RECT"],
            );
            if let Some(T::Table(light)) = at(scene, &["light".into()]) {
                light.insert("shape".into(), T::String(shape.into()));
                if shape == "directional" && rng.bool() {
                    for k in ["center", "normal", "tangent", "size", "radius"] {
                        light.remove(k);
                    }
                    light.insert("direction".into(), vec3(rng, 1.0));
                    let a = *pick(rng, &[0.53, 3.0, 30.0, 89.9, 0.0, 90.0, -1.0, 1e-6]);
                    light.insert("angle_deg".into(), T::Float(a));
                } else if rng.bool() {
                    light.insert("radius".into(), T::Float(rng.f64() * 2.0));
                    light.remove("size");
                    light.remove("tangent");
                }
            }
            what.push(format!("light.shape = {shape}"));
        }
        5 => {
            // The mesh list.
            if let Some(T::Array(meshes)) = at(scene, &["mesh".into()]) {
                match rng.u32(..6) {
                    0 => meshes.clear(),
                    1 if !meshes.is_empty() => {
                        let m = meshes[rng.usize(..meshes.len())].clone();
                        meshes.push(m);
                    }
                    2 if !meshes.is_empty() => {
                        let k = rng.usize(..meshes.len());
                        if let T::Table(m) = &mut meshes[k] {
                            let p =
                                *pick(rng, &["missing.obj", ".", "", "scene.toml", "/dev/null"]);
                            m.insert("path".into(), T::String(p.into()));
                        }
                    }
                    _ if !meshes.is_empty() => {
                        let k = rng.usize(..meshes.len());
                        if let T::Table(m) = &mut meshes[k] {
                            let (key, val) = match rng.u32(..4) {
                                0 => ("opacity", T::Float(rng.f64() * 2.0 - 0.5)),
                                1 => ("scale", T::Float(*pick(rng, &[0.0, -1.0, 1e-9, 1e9, 3.0]))),
                                2 => ("rotate_y_deg", T::Float(rng.f64() * 1e4 - 5e3)),
                                _ => {
                                    let scale = *pick(rng, &[1.0, 100.0, 1e7]);
                                    ("translate", vec3(rng, scale))
                                }
                            };
                            m.insert(key.into(), val);
                        }
                    }
                    _ => {}
                }
            }
            what.push("mesh list".into());
        }
        6 => {
            // The camera: degenerate frames and sizes.
            if let Some(T::Table(cam)) = at(scene, &["camera".into()]) {
                match rng.u32(..5) {
                    0 => {
                        if let Some(t) = cam.get("target").cloned() {
                            cam.insert("eye".into(), t);
                        }
                    }
                    1 => {
                        if let (Some(T::Array(e)), Some(T::Array(t))) =
                            (cam.get("eye"), cam.get("target"))
                        {
                            let d: Vec<T> = e
                                .iter()
                                .zip(t)
                                .map(|(a, b)| match (a.as_float(), b.as_float()) {
                                    (Some(a), Some(b)) => T::Float(b - a),
                                    _ => T::Float(0.0),
                                })
                                .collect();
                            cam.insert("up".into(), T::Array(d));
                        }
                    }
                    2 => {
                        let f = *pick(rng, &[0.0, 180.0, 179.99, 1e-4, -40.0, 360.0]);
                        cam.insert("fov_y_deg".into(), T::Float(f));
                    }
                    3 => {
                        let k = *pick(rng, &["width", "height"]);
                        let n = *pick(rng, &[0, -3, 1, 100_000, 4_000_000_000i64]);
                        cam.insert(k.into(), T::Integer(n));
                    }
                    _ => {
                        cam.insert("eye".into(), vec3(rng, 1e3));
                    }
                }
            }
            what.push("camera".into());
        }
        7 => {
            // A vector of the wrong length or type.
            let mut paths = Vec::new();
            number_paths(scene, &mut vec![], &mut paths);
            let arrays: Vec<Vec<String>> = paths
                .iter()
                .filter(|p| p.last().is_some_and(|k| k.parse::<usize>().is_ok()))
                .map(|p| p[..p.len() - 1].to_vec())
                .collect();
            if !arrays.is_empty() {
                let p = pick(rng, &arrays).clone();
                if let Some(T::Array(a)) = at(scene, &p) {
                    match rng.u32(..3) {
                        0 => {
                            a.pop();
                        }
                        1 => a.push(T::Float(1.0)),
                        _ => a[0] = T::Boolean(true),
                    }
                    what.push(format!("{} arity/type", p.join(".")));
                }
            }
        }
        8 => {
            // A light moved into or behind the scene, or rotated.
            if let Some(T::Table(light)) = at(scene, &["light".into()]) {
                let k = *pick(rng, &["center", "normal", "tangent", "direction"]);
                let s = *pick(rng, &[1.0, 0.0, 1e-6, 1e6]);
                light.insert(k.into(), vec3(rng, s));
                what.push(format!("light.{k}"));
            }
        }
        _ => {
            // A size of the light.
            if let Some(T::Table(light)) = at(scene, &["light".into()]) {
                let x = *pick(rng, &[0.0, 1e-7, 1e-3, 50.0, -1.0, 1e8]);
                if rng.bool() {
                    light.insert("radius".into(), T::Float(x));
                } else {
                    light.insert("size".into(), T::Array(vec![T::Float(x), T::Float(1.0)]));
                }
                what.push(format!("light size {x}"));
            }
        }
    }
}

/// One text-level mutation (truncation, byte flip, deleted or duplicated line).
fn mutate_text(rng: &mut fastrand::Rng, bytes: &mut Vec<u8>, what: &mut Vec<String>) {
    if bytes.is_empty() {
        return;
    }
    match rng.u32(..4) {
        0 => {
            let n = rng.usize(..bytes.len());
            bytes.truncate(n);
            what.push(format!("truncated at {n}"));
        }
        1 => {
            let k = rng.usize(..bytes.len());
            bytes[k] = rng.u8(..);
            what.push(format!("byte {k} flipped"));
        }
        _ => {
            let text = String::from_utf8_lossy(bytes).into_owned();
            let mut lines: Vec<&str> = text.lines().collect();
            if lines.is_empty() {
                return;
            }
            let k = rng.usize(..lines.len());
            if rng.bool() {
                lines.remove(k);
                what.push(format!("line {k} removed"));
            } else {
                lines.insert(k, lines[k]);
                what.push(format!("line {k} duplicated"));
            }
            *bytes = (lines.join("\n") + "\n").into_bytes();
        }
    }
}

/// One mutation of an OBJ's content.
fn mutate_obj(rng: &mut fastrand::Rng, text: &str, what: &mut Vec<String>) -> Vec<u8> {
    let mut lines: Vec<String> = text.lines().map(str::to_string).collect();
    let nv = lines.iter().filter(|l| l.starts_with("v ")).count() as i64;
    let verts: Vec<usize> = (0..lines.len())
        .filter(|&k| lines[k].starts_with("v "))
        .collect();
    let faces: Vec<usize> = (0..lines.len())
        .filter(|&k| lines[k].starts_with("f "))
        .collect();
    match rng.u32(..9) {
        0 if !verts.is_empty() => {
            let k = *pick(rng, &verts);
            let c = *pick(rng, &["nan", "inf", "-inf", "1e30", "1e-30", "x", "1e400"]);
            let mut parts: Vec<String> = lines[k].split_whitespace().map(String::from).collect();
            let j = 1 + rng.usize(..parts.len().saturating_sub(1).max(1));
            if j < parts.len() {
                parts[j] = c.into();
            }
            lines[k] = parts.join(" ");
            what.push(format!("obj vertex {k}: {c}"));
        }
        1 if !faces.is_empty() => {
            let k = *pick(rng, &faces);
            let idx = pick(
                rng,
                &[
                    "0".to_string(),
                    format!("{}", nv + 5),
                    "-1".into(),
                    format!("{}", -(nv + 5)),
                    "1.5".into(),
                    "1/2/3".into(),
                    "".into(),
                ],
            )
            .clone();
            let mut parts: Vec<String> = lines[k].split_whitespace().map(String::from).collect();
            let j = 1 + rng.usize(..parts.len().saturating_sub(1).max(1));
            if j < parts.len() {
                parts[j] = idx.clone();
            }
            lines[k] = parts.join(" ");
            what.push(format!("obj face {k}: index {idx}"));
        }
        2 => {
            let extra = *pick(
                rng,
                &[
                    "f 1 1 1",
                    "f 1 2",
                    "f 1 2 3 4 5",
                    "l 1 2",
                    "p 1",
                    "mtllib missing.mtl",
                    "usemtl nothing",
                    "o other",
                    "vn 0 1 0",
                    "vt 0.5 0.5",
                    "f 1/1/1 2/2/2 3/3/3",
                    "v 1 2",
                ],
            );
            let k = rng.usize(..=lines.len());
            lines.insert(k, extra.into());
            what.push(format!("obj line inserted: {extra}"));
        }
        3 => {
            let s = *pick(rng, &[1e-20, 1e20, 0.0, -1.0]);
            for &k in &verts {
                let parts: Vec<String> = lines[k]
                    .split_whitespace()
                    .enumerate()
                    .map(|(j, p)| match (j, p.parse::<f64>()) {
                        (0, _) | (_, Err(_)) => p.to_string(),
                        (_, Ok(x)) => format!("{}", x * s),
                    })
                    .collect();
                lines[k] = parts.join(" ");
            }
            what.push(format!("obj scaled by {s}"));
        }
        4 => {
            lines.retain(|l| !l.starts_with("f "));
            what.push("obj faces removed".into());
        }
        5 => {
            lines.clear();
            what.push("obj emptied".into());
        }
        _ => {
            let mut bytes = (lines.join("\n") + "\n").into_bytes();
            mutate_text(rng, &mut bytes, what);
            return bytes;
        }
    }
    (lines.join("\n") + "\n").into_bytes()
}

/// A parameter assignment: usually in range, sometimes not.
fn param_value(rng: &mut fastrand::Rng, key: &str, default: &str, range: &str) -> String {
    let bad = rng.u32(..8) == 0;
    if let Some((lo, hi)) = range.split_once("..=") {
        let (lo, hi): (i64, i64) = (lo.parse().unwrap(), hi.parse().unwrap());
        if bad {
            return pick(
                rng,
                &[
                    (lo - 1).to_string(),
                    (hi + 1).to_string(),
                    "abc".into(),
                    "".into(),
                    "2.5".into(),
                ],
            )
            .clone();
        }
        // Sizes stay small: the fuzz is about code paths, not about allocating gigabytes.
        let cap = match key {
            "resolution" => 512,
            "spp" => 64,
            "sublights" => 16,
            "capacity" | "max_capacity" => 1 << 20,
            _ => hi.min(lo + 64).max(default.parse().unwrap_or(lo)),
        };
        let hi = hi.min(cap.max(lo));
        return match rng.u32(..4) {
            0 => lo.to_string(),
            1 => hi.to_string(),
            _ => rng.i64(lo..=hi).to_string(),
        };
    }
    if let Some(inner) = range.strip_prefix('[').and_then(|r| r.strip_suffix(']')) {
        let (lo, hi) = inner.split_once(", ").unwrap();
        let (lo, hi): (f64, f64) = (lo.parse().unwrap(), hi.parse().unwrap());
        if bad {
            return pick(
                rng,
                &[
                    format!("{}", lo - 1.0),
                    format!("{}", hi * 2.0 + 1.0),
                    "nan".into(),
                    "inf".into(),
                    "1e400".into(),
                ],
            )
            .clone();
        }
        let hi = hi.min(lo + 100.0);
        return match rng.u32(..4) {
            0 => lo.to_string(),
            1 => hi.to_string(),
            _ => format!("{}", lo + rng.f64() * (hi - lo)),
        };
    }
    let choices: Vec<&str> = range.split('|').collect();
    if bad {
        return pick(rng, &["bogus", "", "TRUE"]).to_string();
    }
    pick(rng, &choices).to_string()
}

enum Outcome {
    Rendered,
    /// Its error line.
    CleanError(String),
    Failure(String),
}

/// `tris` as a binary glTF 2.0 file (one mesh, one node, one scene; positions and indices).
fn glb_of(tris: &[[glam::Vec3; 3]]) -> Vec<u8> {
    let (json, bin) = gltf_parts(tris, None);
    let mut js = json.into_bytes();
    js.resize(js.len().div_ceil(4) * 4, b' ');
    let mut bin = bin;
    bin.resize(bin.len().div_ceil(4) * 4, 0);
    let mut body = Vec::new();
    body.extend((js.len() as u32).to_le_bytes());
    body.extend(b"JSON");
    body.extend(&js);
    body.extend((bin.len() as u32).to_le_bytes());
    body.extend(b"BIN\0");
    body.extend(&bin);
    let mut out = b"glTF".to_vec();
    out.extend(2u32.to_le_bytes());
    out.extend((12 + body.len() as u32).to_le_bytes());
    out.extend(body);
    out
}

/// The JSON of a glTF 2.0 file holding `tris` and its buffer's bytes; the buffer is the GLB's
/// BIN chunk when `data_uri` is `None`, else a base64 `data:` URI (a `.gltf` on its own).
fn gltf_parts(tris: &[[glam::Vec3; 3]], data_uri: Option<()>) -> (String, Vec<u8>) {
    let pos: Vec<u8> = tris
        .iter()
        .flatten()
        .flat_map(|v| v.to_array())
        .flat_map(f32::to_le_bytes)
        .collect();
    let n = 3 * tris.len() as u32;
    let mut bin = pos.clone();
    bin.extend((0..n).flat_map(u32::to_le_bytes));
    let (mut lo, mut hi) = (glam::Vec3::splat(f32::MAX), glam::Vec3::splat(f32::MIN));
    for v in tris.iter().flatten() {
        lo = lo.min(*v);
        hi = hi.max(*v);
    }
    let uri = match data_uri {
        Some(()) => {
            use base64::Engine as _;
            format!(
                "\"uri\":\"data:application/octet-stream;base64,{}\",",
                base64::engine::general_purpose::STANDARD.encode(&bin)
            )
        }
        None => String::new(),
    };
    let json = format!(
        "{{\"asset\":{{\"version\":\"2.0\"}},\"scene\":0,\"scenes\":[{{\"nodes\":[0]}}],\"nodes\":[{{\"mesh\":0}}],\"meshes\":[{{\"primitives\":[{{\"attributes\":{{\"POSITION\":0}},\"indices\":1,\"mode\":4}}]}}],\"buffers\":[{{{uri}\"byteLength\":{}}}],\"bufferViews\":[{{\"buffer\":0,\"byteOffset\":0,\"byteLength\":{}}},{{\"buffer\":0,\"byteOffset\":{},\"byteLength\":{}}}],\"accessors\":[{{\"bufferView\":0,\"componentType\":5126,\"count\":{n},\"type\":\"VEC3\",\"min\":[{},{},{}],\"max\":[{},{},{}]}},{{\"bufferView\":1,\"componentType\":5125,\"count\":{n},\"type\":\"SCALAR\"}}]}}",
        bin.len(),
        pos.len(),
        pos.len(),
        bin.len() - pos.len(),
        lo.x, lo.y, lo.z, hi.x, hi.y, hi.z
    );
    (json, bin)
}

/// One edit of a glTF document's JSON text.
fn mutate_gltf_json(rng: &mut fastrand::Rng, json: &str, what: &mut Vec<String>) -> String {
    let edits: [(&str, &str); 12] = [
        ("\"mode\":4", "\"mode\":1"),
        ("\"mode\":4", "\"mode\":0"),
        ("\"mode\":4", "\"mode\":6"),
        ("\"scene\":0", "\"scene\":5"),
        (
            "\"nodes\":[{\"mesh\":0}]",
            "\"nodes\":[{\"mesh\":0,\"children\":[0]}]",
        ),
        (
            "\"nodes\":[{\"mesh\":0}]",
            "\"nodes\":[{\"mesh\":0,\"scale\":[0,0,0]}]",
        ),
        (
            "\"nodes\":[{\"mesh\":0}]",
            "\"nodes\":[{\"mesh\":0,\"translation\":[1e39,0,0]}]",
        ),
        ("\"indices\":1,", ""),
        ("\"componentType\":5125", "\"componentType\":5123"),
        ("\"type\":\"VEC3\"", "\"type\":\"VEC2\""),
        ("\"byteOffset\":0", "\"byteOffset\":4"),
        ("\"uri\":\"data:", "\"uri\":\"missing.bin\",\"x\":\""),
    ];
    let (from, to) = edits[rng.usize(..edits.len())];
    if json.contains(from) {
        what.push(format!("gltf json {from} -> {to}"));
        return json.replacen(from, to, 1);
    }
    // A count grown past the data.
    what.push("gltf json count".into());
    json.replacen("\"count\":", "\"count\":9", 1)
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
    let image = exr::prelude::read()
        .no_deep_data()
        .largest_resolution_level()
        .all_channels()
        .first_valid_layer()
        .all_attributes()
        .from_file(path)
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
