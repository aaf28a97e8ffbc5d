//! glTF 2.0 meshes as the scene contract defines them: the `.glb` bunny is the OBJ
//! bunny, node transforms compose, `data:` and file buffers load, and every malformed file gets
//! one line naming the file and what is wrong.
use base64::Engine as _;
use glam::{Mat4, Quat, Vec3};
use shadow_map_core::scene::{load_gltf_triangles, load_obj_triangles};
use shadow_map_core::{Error, Scene};
use std::path::{Path, PathBuf};

fn fixtures() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fixtures")
}

/// A one-primitive glTF document: positions and indices in one buffer given as `uri` (or a
/// data URI of the bytes when `uri` is `None`), the mesh under `nodes` (JSON), primitive mode
/// `mode`.
fn gltf_json(
    pos: &[[f32; 3]],
    idx: &[u32],
    mode: u32,
    nodes: &str,
    uri: Option<&str>,
) -> (String, Vec<u8>) {
    let mut bin: Vec<u8> = pos.iter().flatten().flat_map(|x| x.to_le_bytes()).collect();
    let pos_len = bin.len();
    bin.extend(idx.iter().flat_map(|i| i.to_le_bytes()));
    let uri = match uri {
        Some(u) => u.to_string(),
        None => format!(
            "data:application/octet-stream;base64,{}",
            base64::engine::general_purpose::STANDARD.encode(&bin)
        ),
    };
    let (mut lo, mut hi) = ([f32::MAX; 3], [f32::MIN; 3]);
    for p in pos {
        for a in 0..3 {
            lo[a] = lo[a].min(p[a]);
            hi[a] = hi[a].max(p[a]);
        }
    }
    let json = format!(
        r#"{{"asset":{{"version":"2.0"}},"scene":0,"scenes":[{{"nodes":[0]}}],"nodes":{nodes},
"meshes":[{{"name":"m","primitives":[{{"attributes":{{"POSITION":0}},"indices":1,"mode":{mode}}}]}}],
"buffers":[{{"uri":"{uri}","byteLength":{}}}],
"bufferViews":[{{"buffer":0,"byteOffset":0,"byteLength":{pos_len}}},{{"buffer":0,"byteOffset":{pos_len},"byteLength":{}}}],
"accessors":[{{"bufferView":0,"componentType":5126,"count":{},"type":"VEC3","min":{lo:?},"max":{hi:?}}},
{{"bufferView":1,"componentType":5125,"count":{},"type":"SCALAR"}}]}}"#,
        bin.len(),
        bin.len() - pos_len,
        pos.len(),
        idx.len()
    );
    (json, bin)
}

const TRI: [[f32; 3]; 3] = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]];

fn write(dir: &Path, name: &str, bytes: impl AsRef<[u8]>) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, bytes).unwrap();
    p
}

/// The error line of loading `path`, which must be `Error::Gltf` naming the file.
fn gltf_err(path: &Path) -> String {
    match load_gltf_triangles(path) {
        Err(e @ Error::Gltf { .. }) => {
            let line = e.to_string();
            assert!(line.contains(&path.display().to_string()), "{line}");
            assert_eq!(line.lines().count(), 1, "{line}");
            line
        }
        other => panic!("{}: expected a glTF error, got {other:?}", path.display()),
    }
}

#[test]
fn bunny_glb_is_the_bunny_obj() {
    let obj = load_obj_triangles(&fixtures().join("bunny/bunny.obj")).unwrap();
    let glb = load_gltf_triangles(&fixtures().join("bunny/bunny.glb")).unwrap();
    assert_eq!(obj.len(), glb.len());
    let max = obj
        .iter()
        .zip(&glb)
        .flat_map(|(a, b)| a.iter().zip(b).map(|(p, q)| (*p - *q).abs().max_element()))
        .fold(0.0f32, f32::max);
    // The converter parses the OBJ's decimals to f64 then f32; tobj parses them to f32.
    assert!(max <= 1e-6, "max coordinate difference {max}");
}

#[test]
fn a_scene_loads_the_glb_bunny_as_its_obj_bunny() {
    let dir = tempfile::tempdir().unwrap();
    let toml = std::fs::read_to_string(fixtures().join("bunny/bunny.toml")).unwrap();
    let common = fixtures().join("common/plane.obj");
    let abs = |s: String| s.replace("../common/plane.obj", &common.display().to_string());
    let via = |mesh: &str| {
        let t = abs(toml.replace(
            "path = \"bunny.obj\"",
            &format!(
                "path = \"{}\"",
                fixtures().join("bunny").join(mesh).display()
            ),
        ));
        Scene::load(write(dir.path(), &format!("{mesh}.toml"), t)).unwrap()
    };
    let (a, b) = (via("bunny.obj"), via("bunny.glb"));
    assert_eq!(a.triangles().len(), b.triangles().len());
    for (p, q) in a.triangles().iter().zip(b.triangles()) {
        for k in 0..3 {
            assert!((p[k] - q[k]).abs().max_element() <= 1e-6, "{p:?} {q:?}");
        }
    }
}

#[test]
fn node_transforms_compose_and_buffers_load_from_files_and_data_uris() {
    let dir = tempfile::tempdir().unwrap();
    // Node 0 (scale 2, translate (0, 1, 0)) has child node 1 (rotate 90 degrees about y, then
    // translate (1, 0, 0)) holding the mesh.
    let nodes = r#"[{"children":[1],"scale":[2,2,2],"translation":[0,1,0]},
{"mesh":0,"translation":[1,0,0],"rotation":[0,0.70710677,0,0.70710677]}]"#;
    let want = {
        let parent =
            Mat4::from_scale_rotation_translation(Vec3::splat(2.0), Quat::IDENTITY, Vec3::Y);
        let child = Mat4::from_rotation_translation(
            Quat::from_rotation_y(std::f32::consts::FRAC_PI_2),
            Vec3::X,
        );
        let m = parent * child;
        TRI.map(|p| m.transform_point3(Vec3::from_array(p)))
    };
    let (json, bin) = gltf_json(&TRI, &[0, 1, 2], 4, nodes, None);
    let data_uri = load_gltf_triangles(&write(dir.path(), "data.gltf", json)).unwrap();
    let (json, _) = gltf_json(&TRI, &[0, 1, 2], 4, nodes, Some("tri.bin"));
    write(dir.path(), "tri.bin", &bin);
    let file = load_gltf_triangles(&write(dir.path(), "file.gltf", json)).unwrap();
    for got in [&data_uri, &file] {
        assert_eq!(got.len(), 1);
        for k in 0..3 {
            assert!(
                (got[0][k] - want[k]).length() < 1e-5,
                "{:?} vs {want:?}",
                got[0]
            );
        }
    }
}

#[test]
fn malformed_gltf_files_are_one_line_each() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let node = r#"[{"mesh":0}]"#;
    let glb = std::fs::read(fixtures().join("bunny/bunny.glb")).unwrap();
    let cases: Vec<(&str, PathBuf, &str)> = vec![
        (
            "truncated",
            write(d, "truncated.glb", &glb[..glb.len() / 2]),
            "",
        ),
        ("header only", write(d, "header.glb", &glb[..12]), ""),
        (
            "wrong magic",
            write(d, "magic.glb", [b"glTX".as_slice(), &glb[4..]].concat()),
            "not a readable glTF",
        ),
        ("empty", write(d, "empty.gltf", ""), "not a readable glTF"),
        (
            "not JSON",
            write(d, "text.gltf", "hello"),
            "not a readable glTF",
        ),
        (
            "missing buffer",
            write(
                d,
                "missing.gltf",
                gltf_json(&TRI, &[0, 1, 2], 4, node, Some("nowhere.bin")).0,
            ),
            "nowhere.bin",
        ),
        (
            "lines",
            write(
                d,
                "lines.gltf",
                gltf_json(&TRI, &[0, 1, 2, 0], 1, node, None).0,
            ),
            "Lines",
        ),
        (
            "points",
            write(
                d,
                "points.gltf",
                gltf_json(&TRI, &[0, 1, 2], 0, node, None).0,
            ),
            "Points",
        ),
        (
            "index past the positions",
            write(
                d,
                "index.gltf",
                gltf_json(&TRI, &[0, 1, 7], 4, node, None).0,
            ),
            "index 7 past the 3 positions",
        ),
        (
            "non-finite position",
            write(
                d,
                "nan.gltf",
                gltf_json(
                    &[[0.0, f32::NAN, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]],
                    &[0, 1, 2],
                    4,
                    node,
                    None,
                )
                .0,
            ),
            "",
        ),
        (
            "no triangles",
            write(d, "none.gltf", gltf_json(&TRI, &[], 4, node, None).0),
            "",
        ),
    ];
    // A buffer shorter than its views: the BIN chunk of the bunny cut, the header patched.
    let mut short = glb.clone();
    let json_len = u32::from_le_bytes(short[12..16].try_into().unwrap()) as usize;
    let bin_at = 20 + json_len;
    let cut = 1000usize;
    short.truncate(short.len() - cut);
    let bin_len = u32::from_le_bytes(short[bin_at..bin_at + 4].try_into().unwrap()) as usize - cut;
    short[bin_at..bin_at + 4].copy_from_slice(&(bin_len as u32).to_le_bytes());
    let total = short.len() as u32;
    short[8..12].copy_from_slice(&total.to_le_bytes());
    let short_path = write(d, "short.glb", &short);
    let mut all = cases;
    all.push(("short BIN chunk", short_path, "bytes"));
    for (what, path, needle) in &all {
        let line = gltf_err(path);
        assert!(line.contains(needle), "{what}: {line}");
        println!("{what}: {line}");
    }
    // A missing file names itself too.
    gltf_err(&d.join("absent.glb"));
}
