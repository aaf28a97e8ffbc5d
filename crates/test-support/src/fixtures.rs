//! Small fixed scenes and helpers of the accuracy and twin tests.
//!
//! The scenes: an opaque ground `[-4, 4]^2` at y = 0, horizontal square occluders ([`Occ`]),
//! a rect light pointing down ([`rect_light`]) and a camera looking at the origin ([`camera`]);
//! the scene fixtures of the repository's `fixtures/` folder ([`fixture`]).

use glam::Vec3;
use shadow_map_core::{
    Camera, Error, Light, LightShape, ParamSpec, Params, Receivers, Report, Scene, SceneBvh,
    SoftShadowEstimator,
};

/// The fixed scenes' camera: from (0, 4, 5) at the origin, 40 degrees vertical field of view,
/// `w x h` pixels.
pub fn camera(w: u32, h: u32) -> Camera {
    Camera {
        eye: Vec3::new(0.0, 4.0, 5.0),
        target: Vec3::ZERO,
        up: Vec3::Y,
        fov_y_deg: 40.0,
        width: w,
        height: h,
    }
}

/// A horizontal quad `[x0, x1] x [z0, z1]` at height y, facing up (+y), as two triangles.
pub fn quad(x0: f32, z0: f32, x1: f32, z1: f32, y: f32) -> Vec<[Vec3; 3]> {
    let (a, b, c, d) = (
        Vec3::new(x0, y, z0),
        Vec3::new(x0, y, z1),
        Vec3::new(x1, y, z1),
        Vec3::new(x1, y, z0),
    );
    vec![[a, b, c], [a, c, d]]
}

/// A closed axis-aligned box from `lo` to `hi`: twelve triangles, counter-clockwise seen from
/// outside (top, bottom, -x, +x, -z, +z).
pub fn cuboid(lo: Vec3, hi: Vec3) -> Vec<[Vec3; 3]> {
    let p = |x: bool, y: bool, z: bool| {
        Vec3::new(
            if x { hi.x } else { lo.x },
            if y { hi.y } else { lo.y },
            if z { hi.z } else { lo.z },
        )
    };
    let f = |a: Vec3, b: Vec3, c: Vec3, d: Vec3| [[a, b, c], [a, c, d]];
    let (o, i) = (false, true);
    [
        f(p(o, i, o), p(o, i, i), p(i, i, i), p(i, i, o)),
        f(p(o, o, o), p(i, o, o), p(i, o, i), p(o, o, i)),
        f(p(o, o, o), p(o, o, i), p(o, i, i), p(o, i, o)),
        f(p(i, o, o), p(i, i, o), p(i, i, i), p(i, o, i)),
        f(p(o, o, o), p(o, i, o), p(i, i, o), p(i, o, o)),
        f(p(o, o, i), p(i, o, i), p(i, i, i), p(o, i, i)),
    ]
    .into_iter()
    .flatten()
    .collect()
}

/// An `l x l` rect light centred at (0, height, 0), pointing down, tangent +x.
pub fn rect_light(l: f32, height: f32) -> Light {
    Light {
        shape: LightShape::Rect { size: [l, l] },
        center: Vec3::new(0.0, height, 0.0),
        normal: -Vec3::Y,
        tangent: Vec3::X,
    }
}

/// [`rect_light`] with shape index `shape` (0: the `l x l` rect; 1: a disk, 2: a sphere, each of
/// radius `l / 2`), the random scenes' light choice.
pub fn light_of_shape(shape: u8, l: f32, height: f32) -> Light {
    let radius = 0.5 * l;
    let shape = match shape {
        1 => LightShape::Disk { radius },
        2 => LightShape::Sphere { radius },
        _ => LightShape::Rect { size: [l, l] },
    };
    Light {
        shape,
        ..rect_light(l, height)
    }
}

/// A horizontal square occluder `(x0, z0, x1, z1, height)`.
pub type Occ = (f32, f32, f32, f32, f32);

/// The occluder of `parallel-squares`: its +x edge deliberately off the texel grid.
pub const SQUARE: Occ = (-0.5, -0.5, 0.5123, 0.5, 1.5);

/// The ground and the occluders `occ` (all opaque) under `light`, seen by [`camera`]`(w, h)`.
pub fn scene_with(light: Light, occ: &[Occ], w: u32, h: u32) -> Scene {
    let mut meshes = vec![(quad(-4.0, -4.0, 4.0, 4.0, 0.0), 1.0)];
    for o in occ {
        meshes.push((quad(o.0, o.1, o.2, o.3, o.4), 1.0));
    }
    match Scene::from_meshes("test", camera(w, h), light, meshes) {
        Ok(s) => s,
        Err(e) => panic!("scene: {e}"),
    }
}

/// 241 ground receivers on the line z = 0.13, x from -1.5 to 1.5, through the umbra, penumbra
/// and lit region of [`SQUARE`].
pub fn line_receivers() -> Receivers {
    let pos: Vec<Vec3> = (0..241)
        .map(|k| Vec3::new(-1.5 + k as f32 * 0.0125, 0.0, 0.13))
        .collect();
    points(pos, Vec3::Y)
}

/// Receivers at `p`, all with the normal `n`, all active.
pub fn points(p: Vec<Vec3>, n: Vec3) -> Receivers {
    let len = p.len();
    match Receivers::from_points(p, vec![n; len]) {
        Ok(r) => r,
        Err(e) => panic!("receivers: {e}"),
    }
}

/// The path of the scene fixture `fixtures/<name>/<name>.toml`.
pub fn fixture_path(name: &str) -> String {
    format!(
        "{}/../../fixtures/{name}/{name}.toml",
        env!("CARGO_MANIFEST_DIR")
    )
}

/// Accumulation's occluded grazing case (its `tests/accuracy.rs` derives the closed form): a
/// disk light of radius 0.5 at (3, 0, 0) facing -x, lying in the ground's plane y = 0, a ground
/// quad over x in [-2, 1], and a thin wall at x = 1.5 from height 0.1 to 2, wide in z; the camera
/// `camera(w, h)`.
pub fn grazing_wall(w: u32, h: u32) -> Scene {
    let normal = -Vec3::X;
    let light = shadow_map_core::Light {
        shape: shadow_map_core::LightShape::Disk { radius: 0.5 },
        center: Vec3::new(3.0, 0.0, 0.0),
        normal,
        tangent: shadow_map_core::light::default_tangent(normal),
    };
    let wall = cuboid(Vec3::new(1.49, 0.1, -3.0), Vec3::new(1.51, 2.0, 3.0));
    let ground = quad(-2.0, -2.0, 1.0, 2.0, 0.0);
    Scene::from_meshes(
        "grazing-wall",
        camera(w, h),
        light,
        vec![(ground, 1.0), (wall, 1.0)],
    )
    .expect("the grazing-wall scene is valid")
}

/// Ground receivers (normal +y) on the `na x nb` grid `x = x0 + dx a`, `z = z0 + dz b`.
pub fn ground_grid(na: u32, nb: u32, (x0, dx): (f32, f32), (z0, dz): (f32, f32)) -> Receivers {
    let mut pos = Vec::new();
    for a in 0..na {
        for b in 0..nb {
            pos.push(Vec3::new(x0 + dx * a as f32, 0.0, z0 + dz * b as f32));
        }
    }
    points(pos, Vec3::Y)
}

/// The names of every scene fixture (each directory `fixtures/<name>` holding `<name>.toml`),
/// sorted.
pub fn fixture_names() -> Vec<String> {
    let dir = concat!(env!("CARGO_MANIFEST_DIR"), "/../../fixtures");
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .unwrap_or_else(|e| panic!("{dir}: {e}"))
        .filter_map(|d| {
            let d = d.ok()?.path();
            let name = d.file_name()?.to_str()?.to_string();
            d.join(format!("{name}.toml")).exists().then_some(name)
        })
        .collect();
    names.sort();
    names
}

/// The scene fixture `name` with its camera set to `w x h` pixels, and the camera's receivers.
pub fn fixture(name: &str, w: u32, h: u32) -> (Scene, Receivers) {
    let mut scene = fixture_scene(name);
    scene.set_resolution(w, h).unwrap();
    with_camera_receivers(scene)
}

/// The scene fixture `name` as its file describes it (image size included), and the camera's
/// receivers.
pub fn authored_fixture(name: &str) -> (Scene, Receivers) {
    with_camera_receivers(fixture_scene(name))
}

/// The scene fixture `name`, loaded; panics, naming it, when it does not load.
fn fixture_scene(name: &str) -> Scene {
    match Scene::load(fixture_path(name)) {
        Ok(s) => s,
        Err(e) => panic!("fixture {name}: {e}"),
    }
}

/// A named scene and its receivers, as the engine-path tests loop over them.
pub type NamedScene = (&'static str, Scene, Receivers);

/// The bunny fixture at `w x h` under three lights, each with its camera receivers: its own rect
/// light (`bunny`), a disk of the rect's larger half extent in its place (`disk-bunny`) and a
/// low 3-degree sun (`sun-bunny`): the engine-path tests' perspective, disk and orthographic
/// cases.
pub fn bunny_under_three_lights(w: u32, h: u32) -> Vec<NamedScene> {
    let (bunny, rec) = fixture("bunny", w, h);
    let lit = |light: Light| {
        let mut s = bunny.clone();
        s.set_light(light).unwrap();
        with_camera_receivers(s)
    };
    let mut disk = *bunny.light();
    disk.shape = LightShape::Disk {
        radius: bunny.light().half_extent().max_element(),
    };
    let (disk, disk_rec) = lit(disk);
    let (sun, sun_rec) = lit(Light::directional(Vec3::new(0.6, -0.5, 0.3), 3.0));
    vec![
        ("bunny", bunny, rec),
        ("disk-bunny", disk, disk_rec),
        ("sun-bunny", sun, sun_rec),
    ]
}

/// The semi-transparent fixtures at `w x h`, each with its receivers: the strands (one mesh of
/// opacity 0.4 over a ground, a disk light) and the hair (four meshes of opacity 0.2 to 0.5, a
/// rect light); panics if either has become opaque.
pub fn semi_transparent_fixtures(w: u32, h: u32) -> Vec<NamedScene> {
    ["strands", "hair"]
        .into_iter()
        .map(|name| {
            let (scene, rec) = fixture(name, w, h);
            assert!(!scene.is_opaque(), "{name}: a semi-transparent fixture");
            (name, scene, rec)
        })
        .collect()
}

/// `scene` and its camera's receivers.
fn with_camera_receivers(scene: Scene) -> (Scene, Receivers) {
    let rec = Receivers::from_camera(&scene, &SceneBvh::new(&scene));
    (scene, rec)
}

/// Sets every `(key, value)` of `kv` on `e`, stopping at the first error.
pub fn set_params<K, V>(
    e: &mut (impl SoftShadowEstimator + ?Sized),
    kv: &[(K, V)],
) -> Result<(), Error>
where
    K: AsRef<str>,
    V: AsRef<str>,
{
    for (k, v) in kv {
        e.set_param(k.as_ref(), v.as_ref())?;
    }
    Ok(())
}

/// Sets every `(key, value)` of `kv` on `e`; a refused one panics, naming it.
pub fn configure<K, V>(e: &mut (impl SoftShadowEstimator + ?Sized), kv: &[(K, V)])
where
    K: AsRef<str>,
    V: AsRef<str>,
{
    for (k, v) in kv {
        let (k, v) = (k.as_ref(), v.as_ref());
        if let Err(err) = e.set_param(k, v) {
            panic!("set {k}={v}: {err}");
        }
    }
}

/// A parameter table of `specs` with every `(key, value)` of `kv` set over the defaults; a
/// refused key or value panics, naming it (a test's bug).
pub fn param_table<K, V>(specs: &'static [ParamSpec], kv: &[(K, V)]) -> Params
where
    K: AsRef<str>,
    V: AsRef<str>,
{
    let mut t = Params::new(specs).expect("parameter table");
    for (k, v) in kv {
        let (k, v) = (k.as_ref(), v.as_ref());
        t.set(k, v).unwrap_or_else(|e| panic!("{k}={v}: {e}"));
    }
    t
}

/// `e` with every `(key, value)` of `kv` set ([`configure`]).
pub fn with_params<E: SoftShadowEstimator>(mut e: E, kv: &[(&str, &str)]) -> E {
    configure(&mut e, kv);
    e
}

/// The value of a report's note `key`, if it has one.
pub fn note(r: &Report, key: &str) -> Option<String> {
    r.notes.iter().find(|n| n.0 == key).map(|n| n.1.clone())
}

/// RMS and maximum of `|v - o|` over all receivers.
pub fn errors(v: &[f32], o: &[f64]) -> (f64, f64) {
    let d: Vec<f64> = v
        .iter()
        .zip(o)
        .map(|(a, b)| (*a as f64 - b).abs())
        .collect();
    let rms = (d.iter().map(|x| x * x).sum::<f64>() / d.len() as f64).sqrt();
    (rms, d.iter().cloned().fold(0.0, f64::max))
}

/// RMS of `a - b` over the active receivers (0 when none is active).
pub fn rmse(a: &[f32], b: &[f32], active: &[bool]) -> f64 {
    let (mut s, mut n) = (0.0f64, 0usize);
    for k in 0..a.len() {
        if active[k] {
            let d = a[k] as f64 - b[k] as f64;
            s += d * d;
            n += 1;
        }
    }
    (s / n.max(1) as f64).sqrt()
}

/// The value of a report's note `key` parsed as a `T`; panics, naming the note, when the report
/// has none or it does not parse.
pub fn note_as<T: std::str::FromStr>(r: &Report, key: &str) -> T
where
    T::Err: std::fmt::Debug,
{
    match note(r, key) {
        Some(v) => v
            .parse()
            .unwrap_or_else(|e| panic!("note {key} = {v:?}: {e:?}")),
        None => panic!("no note {key} in {:?}", r.notes),
    }
}

/// The largest `|a[k] - b[k]|` over the receivers where `a` is finite (0 when none is).
pub fn max_abs_diff(a: &[f32], b: &[f32]) -> f32 {
    a.iter()
        .zip(b)
        .filter(|p| p.0.is_finite())
        .map(|(x, y)| (x - y).abs())
        .fold(0.0f32, f32::max)
}

/// The estimator contract on an output: every active V finite in [0, 1], every inactive one NaN.
pub fn check_contract(v: &[f32], r: &Receivers) {
    for (k, x) in v.iter().enumerate() {
        if r.active()[k] {
            assert!(
                x.is_finite() && (0.0..=1.0).contains(x),
                "receiver {k}: V = {x}"
            );
        } else {
            assert!(x.is_nan(), "inactive receiver {k}: V = {x}");
        }
    }
}

/// Every V finite in [0, 1] (all receivers active); `what` names the case in a failure.
pub fn assert_valid(v: &[f32], what: &str) {
    for (k, x) in v.iter().enumerate() {
        assert!(
            x.is_finite() && (0.0..=1.0).contains(x),
            "{what}: V[{k}] = {x}"
        );
    }
}

/// The light weighting of an occluder at `opacity`: on every active receiver of `r`,
/// `v = 1 - opacity (1 - v_opaque)` within 1e-5, `v_opaque` being the same estimator on the
/// opaque occluder (`what` names the case in a failure). Returns how many active receivers lie
/// in `v_opaque`'s penumbra (0.01 < V < 0.99).
pub fn assert_opacity_weighted(
    v: &[f32],
    v_opaque: &[f32],
    opacity: f32,
    r: &Receivers,
    what: &str,
) -> usize {
    let mut penumbra = 0;
    for k in 0..r.len() {
        if !r.active()[k] {
            continue;
        }
        let want = 1.0 - opacity * (1.0 - v_opaque[k]);
        assert!(
            (v[k] - want).abs() <= 1e-5,
            "{what} #{k}: {} vs {want}",
            v[k]
        );
        penumbra += usize::from(v_opaque[k] > 0.01 && v_opaque[k] < 0.99);
    }
    penumbra
}

/// The ray-traced reference's V of `r` in `scene` at `spp` samples per receiver, as f64.
#[cfg(feature = "oracle")]
pub fn traced(scene: &Scene, r: &Receivers, spp: u32) -> Vec<f64> {
    let mut reference = reference::ReferenceEstimator::new().expect("reference");
    reference.set_param("spp", &spp.to_string()).expect("spp");
    shadow_map_core::run(&mut reference, scene, r)
        .expect("reference")
        .0
        .iter()
        .map(|&x| x as f64)
        .collect()
}

/// The sphere-light reference case of the accuracy tests: a sphere light of radius 0.4, 3 above
/// the ground, over [`SQUARE`] (camera 8 x 8), the [`line_receivers`], and the ray-traced
/// reference's V at 4096 samples (noise about 0.008 at V = 0.5).
#[cfg(feature = "oracle")]
pub fn sphere_light_over_square() -> (Scene, Receivers, Vec<f64>) {
    let light = Light {
        shape: LightShape::Sphere { radius: 0.4 },
        ..rect_light(1.0, 3.0)
    };
    let (s, r) = (scene_with(light, &[SQUARE], 8, 8), line_receivers());
    let truth = traced(&s, &r, 4096);
    (s, r, truth)
}

/// `v` valid ([`assert_valid`]) and its RMSE to `truth` at most `bound`; prints the RMS and the
/// maximum error, `what` naming the case.
pub fn assert_rmse_within(what: &str, v: &[f32], truth: &[f64], bound: f64) {
    assert_valid(v, what);
    let (rms, max) = errors(v, truth);
    eprintln!("{what}: rms {rms:.5} max {max:.5}");
    assert!(rms <= bound, "{what}: RMSE {rms}");
}

/// The closed-form visibility of the rect light of `scene` past the square occluders `occ`
/// (parallel to the light plane) at each receiver.
#[cfg(feature = "oracle")]
pub fn oracle(scene: &Scene, occ: &[Occ], r: &Receivers) -> Vec<f64> {
    use glam::Vec2;
    use reference::oracle::{rect_occluder_visibility, RectOccluder};
    let f = scene.light().frame();
    let occs: Vec<RectOccluder> = occ
        .iter()
        .map(|o| {
            let c = [Vec3::new(o.0, o.4, o.1), Vec3::new(o.2, o.4, o.3)].map(|c| f.to_light(c));
            let (a, b) = (Vec2::new(c[0].x, c[0].y), Vec2::new(c[1].x, c[1].y));
            RectOccluder {
                min: a.min(b),
                max: a.max(b),
                z: c[0].z,
            }
        })
        .collect();
    r.position()
        .iter()
        .map(|p| rect_occluder_visibility(scene.light().half_extent(), &occs, f.to_light(*p)))
        .collect()
}

/// [`oracle`] under a disk light (the scene's, radius from its half extent): exact,
/// `reference::oracle::polygon_occluder_disk_visibility` of each occluder square (one occluder).
#[cfg(feature = "oracle")]
pub fn oracle_disk(scene: &Scene, occ: Occ, r: &Receivers) -> Vec<f64> {
    use glam::Vec2;
    let f = scene.light().frame();
    let corners = [
        (occ.0, occ.1),
        (occ.2, occ.1),
        (occ.2, occ.3),
        (occ.0, occ.3),
    ];
    let poly: Vec<Vec2> = corners
        .iter()
        .map(|&(x, z)| {
            let c = f.to_light(Vec3::new(x, occ.4, z));
            Vec2::new(c.x, c.y)
        })
        .collect();
    let z = f.to_light(Vec3::new(occ.0, occ.4, occ.1)).z;
    let radius = scene.light().half_extent().x;
    r.position()
        .iter()
        .map(|p| {
            reference::oracle::polygon_occluder_disk_visibility(radius, &poly, z, f.to_light(*p))
        })
        .collect()
}

/// An unoccluded one-sided plane through the origin, its normal `deg` degrees from the vertical
/// (towards +x), of opacity `opacity`, under [`rect_light`]`(1, 3)`, with `n x n` receivers on
/// it at in-plane coordinates `start + step k` (plus a small jitter off the texel grid): the
/// scene, the receivers and each receiver's facing fraction (its exact V). The self-shadowing
/// case: at grazing angles a kernel's far texels of the receiver's own surface lie
/// nearer the light than the receiver.
pub fn tilted_plane(
    deg: f32,
    opacity: f32,
    (n, start, step): (usize, f32, f32),
) -> (Scene, Receivers, Vec<f32>) {
    let th = deg.to_radians();
    let normal = Vec3::new(th.sin(), th.cos(), 0.0);
    let t = Vec3::new(th.cos(), -th.sin(), 0.0);
    let c = |a: f32, b: f32| a * t + b * Vec3::Z;
    let (p0, p1, p2, p3) = (c(-2.0, -4.0), c(-2.0, 4.0), c(2.0, 4.0), c(2.0, -4.0));
    // Wound so that the geometric normal is `normal`.
    let tris = if (p1 - p0).cross(p2 - p0).dot(normal) > 0.0 {
        vec![[p0, p1, p2], [p0, p2, p3]]
    } else {
        vec![[p0, p2, p1], [p0, p3, p2]]
    };
    let light = rect_light(1.0, 3.0);
    let s = Scene::from_meshes("tilted", camera(8, 8), light, vec![(tris, opacity)])
        .expect("tilted plane scene");
    let mut pos = Vec::with_capacity(n * n);
    for a in 0..n {
        for b in 0..n {
            pos.push(c(
                start + a as f32 * step + 0.0137,
                start + b as f32 * step + 0.0071,
            ));
        }
    }
    let facing = pos
        .iter()
        .map(|p| light.front_fraction_world(*p, normal))
        .collect();
    let r = Receivers::from_points(pos, vec![normal; n * n]).expect("tilted plane receivers");
    (s, r, facing)
}

/// The most `v` falls below `facing` over the receivers (negative when it never does).
pub fn most_below(v: &[f32], facing: &[f32]) -> f32 {
    v.iter()
        .zip(facing)
        .map(|(x, f)| f - x)
        .fold(f32::NEG_INFINITY, f32::max)
}

/// The grazing-plane check for an estimator with `self_shadow` modes (midpoint, bias): on the
/// [`tilted_plane`] lit at 85 degrees, at the defaults (receiver-plane rejection on), V stays
/// within 0.02 of the facing fraction in both modes. `make` builds the estimator with the given
/// parameters; the classic test's shortfall (`receiver_plane=false`) is printed beside it.
pub fn assert_grazing_plane_lit<E: SoftShadowEstimator>(
    mut make: impl FnMut(&[(&str, &str)]) -> E,
) {
    let (s, r, facing) = tilted_plane(85.0, 1.0, (40, -1.0, 0.05));
    let mut worst = |kv: &[(&str, &str)]| {
        let v = shadow_map_core::run(&mut make(kv), &s, &r)
            .expect("grazing plane")
            .0;
        assert_valid(&v, "grazing plane");
        most_below(&v, &facing)
    };
    let on = worst(&[]);
    let on_bias = worst(&[("self_shadow", "bias")]);
    let off = worst(&[("receiver_plane", "false")]);
    let off_bias = worst(&[("self_shadow", "bias"), ("receiver_plane", "false")]);
    eprintln!(
        "85 deg plane, most below facing: plane {on:.4} (bias mode {on_bias:.4}), \
         classic {off:.4} (bias mode {off_bias:.4})"
    );
    assert!(on <= 0.02, "receiver plane: V below facing by {on}");
    assert!(on_bias <= 0.02, "receiver plane, bias mode: {on_bias}");
}
