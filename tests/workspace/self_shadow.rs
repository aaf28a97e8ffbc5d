//! Self-shadowing at any angle (docs/methods.md §2 "Receiver plane"): a receiver plane
//! lit from 60, 75, 85 and 89 degrees off its normal, one-sided (a quad) or the top of a closed
//! slab, with and without a thin post standing on it, at shadow-map resolutions 256 to 4096.
//! Every registered estimator, at its defaults otherwise, on every backend it has: no receiver
//! that is truly lit may be darkened by more than 0.02 below its facing fraction.
//!
//! "Truly lit": with no post, every receiver (the light is wholly in front of the plane); with
//! the post, the receivers whose ray-traced reference is 1 and whose grid neighbours within two
//! cells are all 1 too (so penumbra edges, where the light is partly hidden, do not count).
//!
//! Where the truth has no shadow on the plane (no post), each estimator's RMSE against the exact
//! V (the facing fraction) may exceed the hard shadow map's on the same case, resolution and
//! backend by at most 0.005 (the bar for soft estimators).
//!
//! `cargo test --test workspace self_shadow:: -- --nocapture` prints the worst darkening and the worst RMSE
//! excess over the hard map per estimator.
use crate::support;
use glam::Vec3;
use shadow_map_core::{run, Light, LightShape, Receivers, Scene};
use softshadow::{estimator, Backend, SoftShadowEstimator, ALGOS};
use test_support::fixtures::{camera, cuboid, quad};

/// Receiver grid side.
const N: usize = 24;
/// Distance of the light centre from the plane's centre.
const D: f32 = 4.0;
/// Most darkening allowed on a truly lit receiver.
const TOL: f32 = 0.02;
/// Most a soft estimator's RMSE may exceed the hard map's where the truth is unshadowed.
const RMSE_EXCESS: f64 = 0.005;

struct Case {
    name: String,
    scene: Scene,
    rec: Receivers,
    /// Per receiver: whether it counts, and its facing fraction (the exact V when unoccluded).
    lit: Vec<Option<f32>>,
    /// Whether the post stands on the plane (else the truth is the facing fraction everywhere).
    occluded: bool,
}

/// A light `deg` degrees off the plane's normal (+y), seen from the plane's centre, with its
/// normal towards the centre; its side keeps it wholly above the plane.
fn light(deg: f32) -> Light {
    let t = deg.to_radians();
    let center = D * Vec3::new(0.0, t.cos(), -t.sin());
    let normal = -center.normalize();
    Light {
        shape: LightShape::Rect {
            size: [(4.8 * t.cos()).min(0.5); 2],
        },
        center,
        normal,
        tangent: Vec3::X,
    }
}

fn case(deg: f32, closed: bool, post: bool) -> Case {
    let receiver = if closed {
        cuboid(Vec3::new(-2.0, -0.1, -2.0), Vec3::new(2.0, 0.0, 2.0))
    } else {
        quad(-2.0, -2.0, 2.0, 2.0, 0.0)
    };
    let mut meshes = vec![(receiver, 1.0)];
    if post {
        meshes.push((
            cuboid(Vec3::new(-0.015, 0.0, -0.015), Vec3::new(0.015, 0.4, 0.015)),
            1.0,
        ));
    }
    let l = light(deg);
    let name = format!(
        "{deg} deg, {}, {}",
        if closed {
            "closed slab"
        } else {
            "one-sided quad"
        },
        if post { "thin post" } else { "no occluder" }
    );
    let scene = Scene::from_meshes(&name, camera(8, 8), l, meshes).unwrap();
    // Receivers on a jittered grid over [-1.5, 1.5]^2, off the post's footprint.
    let mut p = Vec::new();
    for j in 0..N {
        for i in 0..N {
            let x = -1.5 + 3.0 * (i as f32 + 0.37) / N as f32;
            let z = -1.5 + 3.0 * (j as f32 + 0.61) / N as f32;
            p.push(Vec3::new(x, 0.0, z));
        }
    }
    let n = vec![Vec3::Y; p.len()];
    let rec = Receivers::from_points(p, n).unwrap();
    let facing: Vec<f32> = rec
        .position()
        .iter()
        .map(|&q| l.front_fraction_world(q, Vec3::Y))
        .collect();
    let lit = if post {
        let mut r = estimator("reference", Backend::Cpu).unwrap();
        r.set_param("spp", "256").unwrap();
        let truth = run(r.as_mut(), &scene, &rec).unwrap().0;
        let one = |i: i64, j: i64| {
            i < 0
                || j < 0
                || i >= N as i64
                || j >= N as i64
                || truth[j as usize * N + i as usize] >= 1.0
        };
        (0..N * N)
            .map(|k| {
                let (i, j) = ((k % N) as i64, (k / N) as i64);
                let clear = (-2..=2).all(|dj| (-2..=2).all(|di| one(i + di, j + dj)));
                clear.then_some(facing[k])
            })
            .collect()
    } else {
        facing.iter().map(|&f| Some(f)).collect()
    };
    Case {
        name,
        scene,
        rec,
        lit,
        occluded: post,
    }
}

/// The catalogue: every angle, receiver kind and occluder, each with the resolutions it runs at:
/// 256, 1024 and 4096 on the unoccluded 89-degree quad and 85-degree slab (self-shadowing alone),
/// 1024 elsewhere. (With the post, a fixed filter such as PCF's 5 x 5 blurs the real streak over
/// texels that at r = 256 and 89 degrees stretch about 0.7 m along the ground: filter error, not
/// self-shadowing; measured 0.08 for PCF there.)
fn catalogue() -> Vec<(Case, &'static [&'static str])> {
    let mut out = Vec::new();
    for deg in [60.0, 75.0, 85.0, 89.0] {
        for closed in [false, true] {
            for post in [false, true] {
                let res: &'static [&'static str] =
                    if !post && ((deg == 89.0 && !closed) || (deg == 85.0 && closed)) {
                        &["256", "1024", "4096"]
                    } else {
                        &["1024"]
                    };
                out.push((case(deg, closed, post), res));
            }
        }
    }
    out
}

fn estimators() -> Vec<(Box<dyn SoftShadowEstimator>, &'static str)> {
    let algos = ALGOS.iter().copied().filter(|n| *n != "reference");
    support::estimators(algos, "self_shadow (gpu rows)")
}

#[test]
fn no_estimator_darkens_a_truly_lit_receiver() {
    let cases = catalogue();
    for (c, _) in &cases {
        let counted = c.lit.iter().flatten().count();
        assert!(
            counted > N * N / 2,
            "{}: only {counted} truly lit receivers",
            c.name
        );
    }
    let mut failures = Vec::new();
    let mut limits = Vec::new();
    // RMSE against the facing fraction of the hard map per (case, resolution, backend), filled
    // first (hard is the first estimator of the registry after the reference).
    let mut hard_rmse = std::collections::HashMap::new();
    for (mut e, backend) in estimators() {
        let mut worst = (0.0f32, String::new());
        let mut excess = f64::NEG_INFINITY;
        for (c, resolutions) in &cases {
            for r in *resolutions {
                if e.params().get("resolution").is_some() {
                    e.set_param("resolution", r).unwrap();
                }
                let tag = format!("{} {backend} / {} / r {r}", e.name(), c.name);
                let v = match run(e.as_mut(), &c.scene, &c.rec) {
                    Ok((v, _)) => v,
                    // A device limit named in a one-line error is reported, not hidden: lavapipe's
                    // 128 MiB storage binding cannot hold packet-hsm's r = 4096 pyramid.
                    Err(err) if err.to_string().contains("max_storage_buffer_binding_size") => {
                        limits.push(format!("{tag}: {err}"));
                        continue;
                    }
                    Err(err) => {
                        failures.push(format!("{tag}: error {err}"));
                        continue;
                    }
                };
                let dark = v
                    .iter()
                    .zip(&c.lit)
                    .filter_map(|(&vk, l)| l.map(|f| f - vk))
                    .fold(0.0f32, f32::max);
                if dark > worst.0 {
                    worst = (dark, tag.clone());
                }
                if !c.occluded {
                    let rmse = (v
                        .iter()
                        .zip(&c.lit)
                        .filter_map(|(&vk, l)| l.map(|f| f64::from(f - vk).powi(2)))
                        .sum::<f64>()
                        / c.lit.len() as f64)
                        .sqrt();
                    let key = (c.name.clone(), *r, backend);
                    if e.name() == "hard" {
                        hard_rmse.insert(key, rmse);
                    } else if let Some(h) = hard_rmse.get(&key) {
                        excess = excess.max(rmse - h);
                        if rmse > h + RMSE_EXCESS {
                            failures.push(format!("{tag}: RMSE {rmse:.4} vs hard {h:.4}"));
                        }
                    } else {
                        failures.push(format!("{tag}: no hard-map row to compare with"));
                    }
                }
                if v.iter().any(|x| !x.is_finite()) {
                    failures.push(format!("{tag}: non-finite V"));
                } else if dark > TOL {
                    failures.push(format!("{tag}: a truly lit receiver darkened by {dark:.3}"));
                }
            }
        }
        println!(
            "{} {backend}: worst darkening {:.4} ({}); worst unshadowed RMSE over hard {excess:.4}",
            e.name(),
            worst.0,
            worst.1
        );
    }
    for l in &limits {
        println!("device limit (reported, not a pass): {l}");
    }
    assert!(
        limits
            .iter()
            .all(|l| l.contains(" gpu /") && l.contains("/ r 4096")),
        "device limits below r = 4096: {limits:?}"
    );
    assert!(
        failures.is_empty(),
        "{} failures:\n{}",
        failures.len(),
        failures.join("\n")
    );
}
