//! The fuzz's mutators: weird numbers, structural scene edits, text and OBJ edits, parameter
//! values, and glTF documents built from triangles and then edited.
use toml::{Table, Value as T};

pub(super) fn pick<'a, X>(rng: &mut fastrand::Rng, xs: &'a [X]) -> &'a X {
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

/// Paths (table keys and array indices) of every value in `v` that `keep` accepts, the root
/// included, depth first in key order.
fn paths_where(v: &T, keep: fn(&T) -> bool) -> Vec<Vec<String>> {
    fn walk(v: &T, keep: fn(&T) -> bool, path: &mut Vec<String>, out: &mut Vec<Vec<String>>) {
        if keep(v) {
            out.push(path.clone());
        }
        let children: Vec<(String, &T)> = match v {
            T::Array(a) => a
                .iter()
                .enumerate()
                .map(|(k, x)| (k.to_string(), x))
                .collect(),
            T::Table(t) => t.iter().map(|(k, x)| (k.clone(), x)).collect(),
            _ => Vec::new(),
        };
        for (k, x) in children {
            path.push(k);
            walk(x, keep, path, out);
            path.pop();
        }
    }
    let mut out = Vec::new();
    walk(v, keep, &mut vec![], &mut out);
    out
}

/// Paths of every number in `v`.
fn number_paths(v: &T) -> Vec<Vec<String>> {
    paths_where(v, |x| x.is_integer() || x.is_float())
}

/// A table of `v` picked at random (the root included), with its path.
fn random_table<'a>(rng: &mut fastrand::Rng, v: &'a mut T) -> (Vec<String>, Option<&'a mut Table>) {
    let tables = paths_where(v, T::is_table);
    let p = pick(rng, &tables).clone();
    let table = match at(v, &p) {
        Some(T::Table(t)) => Some(t),
        _ => None,
    };
    (p, table)
}

pub(super) fn at<'a>(v: &'a mut T, path: &[String]) -> Option<&'a mut T> {
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

fn vec3(rng: &mut fastrand::Rng, scale: f64) -> T {
    T::Array(
        (0..3)
            .map(|_| T::Float((rng.f64() * 2.0 - 1.0) * scale))
            .collect(),
    )
}

/// `line`'s whitespace-separated fields joined by single spaces, a random one after the first
/// (the OBJ keyword) replaced by `value` (none when the line has no such field).
fn replace_field(rng: &mut fastrand::Rng, line: &str, value: &str) -> String {
    let mut parts: Vec<&str> = line.split_whitespace().collect();
    let j = 1 + rng.usize(..parts.len().saturating_sub(1).max(1));
    if j < parts.len() {
        parts[j] = value;
    }
    parts.join(" ")
}

/// One structural mutation of the scene table.
pub(super) fn mutate_scene(rng: &mut fastrand::Rng, scene: &mut T, what: &mut Vec<String>) {
    match rng.u32(..10) {
        0 | 1 => {
            let paths = number_paths(scene);
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
            if let (p, Some(t)) = random_table(rng, scene) {
                let keys: Vec<String> = t.keys().cloned().collect();
                if !keys.is_empty() {
                    let k = pick(rng, &keys).clone();
                    t.remove(&k);
                    what.push(format!("removed {}.{k}", p.join(".")));
                }
            }
        }
        3 => {
            if let (p, Some(t)) = random_table(rng, scene) {
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
            let paths = number_paths(scene);
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
pub(super) fn mutate_text(rng: &mut fastrand::Rng, bytes: &mut Vec<u8>, what: &mut Vec<String>) {
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
pub(super) fn mutate_obj(rng: &mut fastrand::Rng, text: &str, what: &mut Vec<String>) -> Vec<u8> {
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
            lines[k] = replace_field(rng, &lines[k], c);
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
            lines[k] = replace_field(rng, &lines[k], &idx);
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
pub(super) fn param_value(
    rng: &mut fastrand::Rng,
    key: &str,
    default: &str,
    range: &str,
) -> String {
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

/// `tris` as a binary glTF 2.0 file (one mesh, one node, one scene; positions and indices).
pub(super) fn glb_of(tris: &[[glam::Vec3; 3]]) -> Vec<u8> {
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
pub(super) fn gltf_parts(tris: &[[glam::Vec3; 3]], data_uri: Option<()>) -> (String, Vec<u8>) {
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
pub(super) fn mutate_gltf_json(
    rng: &mut fastrand::Rng,
    json: &str,
    what: &mut Vec<String>,
) -> String {
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
