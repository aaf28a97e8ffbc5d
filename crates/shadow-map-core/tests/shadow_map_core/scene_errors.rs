//! Every way a scene file or an OBJ can be wrong gets a one-line error naming the file and the
//! key or line; zero-area triangles are skipped and counted; nothing panics.
use crate::common;

use common::{good_scene_toml, QUAD};
use shadow_map_core::{Error, Scene};
use std::path::Path;

const GOOD: &str = concat!("\n", good_scene_toml!());

fn write_scene(dir: &Path, toml: &str, obj: &str) -> std::path::PathBuf {
    std::fs::write(dir.join("quad.obj"), obj).unwrap();
    let p = dir.join("scene.toml");
    std::fs::write(&p, toml).unwrap();
    p
}

/// Loads and expects an error whose one-line message contains every `needle`.
fn expect_err(toml: &str, obj: &str, needles: &[&str]) -> Error {
    let dir = tempfile::tempdir().unwrap();
    let p = write_scene(dir.path(), toml, obj);
    let e = Scene::load(&p).expect_err("must fail");
    let msg = e.to_string();
    assert!(!msg.contains('\n'), "multi-line error: {msg}");
    for n in needles {
        assert!(msg.contains(n), "error {msg:?} should mention {n:?}");
    }
    e
}

#[test]
fn good_scene_loads() {
    let dir = tempfile::tempdir().unwrap();
    let p = write_scene(dir.path(), GOOD, QUAD);
    let s = Scene::load(&p).unwrap();
    assert_eq!(s.triangles().len(), 2);
    assert_eq!(s.skipped_degenerate(), 0);
    assert!(s.is_opaque());
}

/// One `GOOD.replace(from, to)` edit per row, each expected to fail with every needle.
type Edit<'a> = (&'a str, &'a str, &'a [&'a str]);

fn expect_edit_errs(edits: &[Edit]) {
    for &(from, to, needles) in edits {
        assert!(GOOD.contains(from), "edit {from:?} does not apply");
        expect_err(&GOOD.replace(from, to), QUAD, needles);
    }
}

#[test]
fn unknown_key() {
    expect_edit_errs(&[(
        "fov_y_deg = 40.0",
        "fov_y_deg = 40.0\nzoom = 2.0",
        &["scene.toml", "zoom", "line"],
    )]);
}

#[test]
fn missing_key() {
    expect_edit_errs(&[("target = [0.0, 0.5, 0.0]\n", "", &["scene.toml", "target"])]);
}

#[test]
fn wrong_type() {
    expect_edit_errs(&[(
        "width = 32",
        "width = \"wide\"",
        &["scene.toml", "line 7", "expected u32"],
    )]);
}

#[test]
fn non_finite_numbers() {
    expect_edit_errs(&[
        (
            "center = [0.0, 6.0, 0.0]",
            "center = [0.0, nan, 0.0]",
            &["light.center", "finite"],
        ),
        ("fov_y_deg = 40.0", "fov_y_deg = inf", &["camera.fov_y_deg"]),
    ]);
}

#[test]
fn zero_size_and_degenerate_lights() {
    expect_edit_errs(&[
        (
            "size = [2.0, 2.0]",
            "size = [0.0, 2.0]",
            &["light.size", "> 0"],
        ),
        (
            "tangent = [1.0, 0.0, 0.0]",
            "tangent = [0.0, 2.0, 0.0]",
            &["light.tangent", "parallel"],
        ),
        (
            "normal = [0.0, -1.0, 0.0]",
            "normal = [0.0, 0.0, 0.0]",
            &["light.normal", "zero"],
        ),
        (
            "shape = \"rect\"",
            "shape = \"tube\"",
            &["light.shape", "tube"],
        ),
        (
            "size = [2.0, 2.0]",
            "size = [2.0, 2.0]\nradius = 1.0",
            &["light.radius", "rect"],
        ),
    ]);
    let disk = GOOD
        .replace("shape = \"rect\"", "shape = \"disk\"")
        .replace(
            "tangent = [1.0, 0.0, 0.0]\nsize = [2.0, 2.0]",
            "radius = -1.0",
        );
    expect_err(&disk, QUAD, &["light.radius"]);
}

#[test]
fn bad_camera() {
    expect_edit_errs(&[
        ("width = 32", "width = 0", &["camera.width"]),
        (
            "up = [0.0, 1.0, 0.0]",
            "up = [0.0, 2.5, 6.0]",
            &["camera.up", "parallel"],
        ),
        (
            "target = [0.0, 0.5, 0.0]",
            "target = [0.0, 3.0, 6.0]",
            &["camera.target"],
        ),
    ]);
}

#[test]
fn bad_mesh_keys() {
    expect_edit_errs(&[
        (
            "path = \"quad.obj\"",
            "path = \"quad.obj\"\nopacity = 1.5",
            &["mesh[0].opacity"],
        ),
        (
            "path = \"quad.obj\"",
            "path = \"quad.obj\"\nscale = 0.0",
            &["mesh[0].scale"],
        ),
        (
            "[[mesh]]\npath = \"quad.obj\"\n",
            "",
            &["mesh", "no [[mesh]]"],
        ),
    ]);
}

#[test]
fn unreadable_files() {
    let e = Scene::load("/nonexistent/dir/scene.toml").unwrap_err();
    assert!(e.to_string().contains("/nonexistent/dir/scene.toml"));
    expect_err(
        &GOOD.replace("quad.obj", "missing.obj"),
        QUAD,
        &["missing.obj", "cannot read"],
    );
}

#[test]
fn malformed_obj_names_the_line() {
    expect_err(
        GOOD,
        "v 0 0 0\nv 1 0 0\nv 0 0 x\nf 1 2 3\n",
        &["quad.obj:3", "not a finite number"],
    );
    expect_err(
        GOOD,
        "v 0 0 0\nv 1 0 0\nv 0 0 1\nf 1 2 9\n",
        &["quad.obj:4", "out of range"],
    );
    expect_err(
        GOOD,
        "v 0 0 0\nv 1 0 0\nv 0 0 nan\nf 1 2 3\n",
        &["quad.obj:3"],
    );
    expect_err(
        GOOD,
        "v 0 0 0\nv 1 0 0\nf 1 2\n",
        &["quad.obj:3", "at least 3"],
    );
    expect_err(GOOD, "# nothing\n", &["quad.obj", "no faces"]);
}

#[test]
fn zero_area_triangles_are_skipped_and_counted() {
    let obj = format!("{QUAD}v 0 0 0\nv 1 1 1\nv 2 2 2\nf 5 6 7\nf 1 1 2\n");
    let dir = tempfile::tempdir().unwrap();
    let p = write_scene(dir.path(), GOOD, &obj);
    let s = Scene::load(&p).unwrap();
    assert_eq!(s.triangles().len(), 2);
    assert_eq!(s.skipped_degenerate(), 2);
}

#[test]
fn only_degenerate_triangles_is_an_empty_scene() {
    let e = expect_err(
        GOOD,
        "v 0 0 0\nv 1 1 1\nv 2 2 2\nf 1 2 3\n",
        &["no triangles", "1 degenerate"],
    );
    assert!(matches!(e, Error::EmptyScene { skipped: 1, .. }));
}

#[test]
fn polygons_are_triangulated() {
    let dir = tempfile::tempdir().unwrap();
    let p = write_scene(
        dir.path(),
        GOOD,
        "v -1 0 -1\nv -1 0 1\nv 1 0 1\nv 1 0 -1\nf 1 2 3 4\n",
    );
    assert_eq!(Scene::load(&p).unwrap().triangles().len(), 2);
}

/// The contract's directional light (the sun): `direction` and `angle_deg` only.
const SUN: &str = "shape = \"directional\"\ndirection = [0.3, -1.0, 0.2]\nangle_deg = 0.53\n";

fn with_light(light: &str) -> String {
    let start = GOOD.find("[light]").unwrap() + "[light]\n".len();
    let end = GOOD.find("[[mesh]]").unwrap();
    format!("{}{light}\n{}", &GOOD[..start], &GOOD[end..])
}

#[test]
fn directional_light_loads() {
    let dir = tempfile::tempdir().unwrap();
    let p = write_scene(dir.path(), &with_light(SUN), QUAD);
    let s = Scene::load(&p).unwrap();
    let l = *s.light();
    assert!(l.is_directional());
    let d = glam::Vec3::new(0.3, -1.0, 0.2).normalize();
    assert!((l.normal - d).length() < 1e-6, "{}", l.normal);
    assert!(l.tangent.dot(l.normal).abs() < 1e-6);
    let t = l.shape.tan_half();
    assert!((t - (0.265f32).to_radians().tan()).abs() < 1e-9, "{t}");
}

#[test]
fn malformed_directional_lights() {
    for (light, needles) in [
        (
            SUN.replace(
                "direction = [0.3, -1.0, 0.2]",
                "direction = [0.0, 0.0, 0.0]",
            ),
            &["light.direction", "zero"][..],
        ),
        (
            SUN.replace(
                "direction = [0.3, -1.0, 0.2]",
                "direction = [0.3, nan, 0.2]",
            ),
            &["light.direction", "finite"],
        ),
        (SUN.replace("0.53", "0.0"), &["light.angle_deg", "(0, 90)"]),
        (SUN.replace("0.53", "90.0"), &["light.angle_deg", "(0, 90)"]),
        (SUN.replace("0.53", "-3.0"), &["light.angle_deg", "(0, 90)"]),
        (SUN.replace("0.53", "inf"), &["light.angle_deg"]),
        (
            SUN.replace("angle_deg = 0.53\n", ""),
            &["light.angle_deg", "missing"],
        ),
        (
            SUN.replace("direction = [0.3, -1.0, 0.2]\n", ""),
            &["light.direction", "missing"],
        ),
        (
            format!("{SUN}center = [0.0, 6.0, 0.0]\n"),
            &["light.center", "directional"],
        ),
        (
            format!("{SUN}normal = [0.0, -1.0, 0.0]\n"),
            &["light.normal", "directional"],
        ),
        (
            format!("{SUN}tangent = [1.0, 0.0, 0.0]\n"),
            &["light.tangent", "directional"],
        ),
        (
            format!("{SUN}size = [1.0, 1.0]\n"),
            &["light.size", "directional"],
        ),
        (
            format!("{SUN}radius = 1.0\n"),
            &["light.radius", "directional"],
        ),
    ] {
        expect_err(&with_light(&light), QUAD, needles);
    }
    // Sun keys on an area light.
    let t = GOOD.replace("size = [2.0, 2.0]", "size = [2.0, 2.0]\nangle_deg = 1.0");
    expect_err(&t, QUAD, &["light.angle_deg", "rect"]);
    let t = GOOD.replace(
        "size = [2.0, 2.0]",
        "size = [2.0, 2.0]\ndirection = [0.0, -1.0, 0.0]",
    );
    expect_err(&t, QUAD, &["light.direction", "rect"]);
}
