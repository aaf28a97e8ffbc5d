//! Cascades along the camera's depth (docs/methods.md §1 "Cascades and texel density").
//!
//! On `long-ground` (a 200 m ground seen from 0.7 m up, a depth ratio of about 60), with
//! caster-aware fitting off, three cascades at r = 512 must at least halve the RMSE of one view for every soft estimator with a
//! light-centre or sub-light map, on every backend, and must raise the texel density (fewer
//! pixels per texel); V must stay continuous across each split (mean difference between the two
//! cascades over the blend bands at most 0.01). With one cascade the wrapper is the estimator
//! itself, bit for bit.
//!
//! `cargo test --test workspace cascades:: -- --nocapture` prints the figures.
// `!(a <= b)` is deliberate: it is true for NaN, which must fail.
#![allow(clippy::neg_cmp_op_on_partial_ord)]
use crate::support;
use shadow_map_core::{run, Receivers, Scene, SoftShadowEstimator};
use softshadow::{estimator, Backend};
use test_support::fixtures::fixture;

/// Image size (a quarter of the fixture's 160 x 120 per side would lose the far posts).
const W: u32 = 80;
const H: u32 = 60;

fn rmse(v: &[f32], reference: &[f32], rec: &Receivers) -> f64 {
    let (mut s, mut n) = (0.0f64, 0usize);
    for k in 0..v.len() {
        if rec.active()[k] {
            s += ((v[k] - reference[k]) as f64).powi(2);
            n += 1;
        }
    }
    (s / n.max(1) as f64).sqrt()
}

fn note(e: &dyn SoftShadowEstimator, key: &str) -> Option<String> {
    e.report()
        .notes
        .iter()
        .find(|n| n.0 == key)
        .map(|n| n.1.clone())
}

/// The estimator's `settled_without_map` note (0 without one).
fn settled_note(e: &dyn SoftShadowEstimator) -> usize {
    note(e, "settled_without_map")
        .and_then(|s| s.parse().ok())
        .unwrap_or(0)
}

/// Adds a failure naming `what` when an active receiver's V is outside [0, 1] (or NaN).
fn check_unit_v(failures: &mut Vec<String>, what: &str, v: &[f32], rec: &Receivers) {
    if (0..rec.len()).any(|k| rec.active()[k] && !(0.0..=1.0).contains(&v[k])) {
        failures.push(format!("{what}: an active receiver without a V in [0, 1]"));
    }
}

/// Runs `check` on each fixture of `names` at W x H with its ray-traced reference, gathering the
/// failures it reports; the test fails at the end with all of them.
fn on_fixtures(
    names: &[&str],
    mut check: impl FnMut(&str, &Scene, &Receivers, &[f32], &mut Vec<String>),
) {
    let mut failures = Vec::new();
    for &name in names {
        let (scene, rec) = fixture(name, W, H);
        let truth = reference(&scene, &rec);
        check(name, &scene, &rec, &truth, &mut failures);
    }
    assert!(failures.is_empty(), "{failures:#?}");
}

fn reference(scene: &Scene, rec: &Receivers) -> Vec<f32> {
    let mut e = estimator("reference", Backend::Cpu).unwrap();
    e.set_param("spp", "256").unwrap();
    run(e.as_mut(), scene, rec).unwrap().0
}

fn run_with(
    algo: &str,
    backend: Backend,
    kv: &[(&str, &str)],
    scene: &Scene,
    rec: &Receivers,
) -> (Vec<f32>, Box<dyn SoftShadowEstimator>) {
    let mut e = estimator(algo, backend).unwrap();
    for (k, v) in kv {
        e.set_param(k, v).unwrap();
    }
    let (v, _) = run(e.as_mut(), scene, rec).unwrap();
    (v, e)
}

#[test]
fn cascades_halve_the_error_on_a_long_ground() {
    on_fixtures(&["long-ground"], |_, scene, rec, truth, failures| {
        for algo in [
            "pcss",
            "multi-sample",
            "backprojection",
            "accumulation",
            "packet-hsm",
        ] {
            for (b, backend) in
                support::runnable_backends(algo, "cascades_halve_the_error_on_a_long_ground")
            {
                // One light view each (no tiles by direction): the cascades alone.
                let one = [
                    ("resolution", "512"),
                    ("cascades", "1"),
                    ("tiles", "1"),
                    ("casters", "off"),
                ];
                let three = [
                    ("resolution", "512"),
                    ("cascades", "3"),
                    ("tiles", "1"),
                    ("casters", "off"),
                ];
                let (v1, _) = run_with(algo, backend, &one, scene, rec);
                let (v3, e3) = run_with(algo, backend, &three, scene, rec);
                let (r1, r3) = (rmse(&v1, truth, rec), rmse(&v3, truth, rec));
                let jump: f64 = note(e3.as_ref(), "cascade_jump_mean")
                    .unwrap()
                    .parse()
                    .unwrap();
                let d1 = shadow_map_core::cascades::texel_density_of(scene, rec, &{
                    let (_, e) = run_with(algo, backend, &one, scene, rec);
                    e.params().clone()
                });
                let d3 = shadow_map_core::cascades::texel_density_of(scene, rec, e3.params());
                let med = |d: Option<Vec<f32>>| {
                    shadow_map_core::cascades::median_p95(&d.unwrap()).unwrap()
                };
                let (m1, m3) = (med(d1), med(d3));
                println!(
                "{algo} {b}: RMSE {r1:.4} -> {r3:.4}, texel density median/p95 {:.2}/{:.2} -> {:.2}/{:.2}, band jump mean {jump:.4}",
                m1.0, m1.1, m3.0, m3.1
            );
                if !(r3 <= 0.5 * r1) {
                    failures.push(format!("{algo} {b}: RMSE {r1:.4} -> {r3:.4}, not halved"));
                }
                if !(m3.0 < m1.0 && m3.1 < m1.1) {
                    failures.push(format!("{algo} {b}: texel density {m1:?} -> {m3:?}"));
                }
                if !(jump <= 0.01) {
                    failures.push(format!("{algo} {b}: band jump mean {jump}"));
                }
            }
        }
    });
}

#[test]
fn one_cascade_is_the_estimator_itself() {
    let (scene, rec) = fixture("bunny", 48, 36);
    for algo in ["hard", "pcss", "backprojection", "deep-shadow"] {
        let (v, e) = run_with(algo, Backend::Cpu, &[("resolution", "256")], &scene, &rec);
        assert_eq!(note(e.as_ref(), "cascades").as_deref(), Some("1"), "{algo}");
        let mut inner = match algo {
            "hard" => {
                Box::new(baselines::HardShadow::new().unwrap()) as Box<dyn SoftShadowEstimator>
            }
            "pcss" => Box::new(baselines::PcssShadow::new().unwrap()),
            "backprojection" => Box::new(backprojection::CpuBackprojection::new().unwrap()),
            _ => Box::new(deep_shadow::CpuDeepShadow::new().unwrap()),
        };
        inner.set_param("resolution", "256").unwrap();
        let (w, _) = run(inner.as_mut(), &scene, &rec).unwrap();
        let same = v.iter().zip(&w).all(|(a, b)| a.to_bits() == b.to_bits());
        assert!(same, "{algo}: the one-cascade wrapper changed V");
    }
}

#[test]
fn cascade_parameters_are_checked() {
    let mut e = estimator("pcss", Backend::Cpu).unwrap();
    for (k, v) in [
        ("cascades", "9"),
        ("cascade_lambda", "1.5"),
        ("cascade_blend", "0.6"),
    ] {
        assert!(e.set_param(k, v).is_err(), "{k}={v}");
    }
    e.set_param("cascades", "2").unwrap();
    e.set_param("max_taps", "8").unwrap();
    assert_eq!(e.params().int("cascades").unwrap(), 2);
    assert_eq!(e.params().int("max_taps").unwrap(), 8);
    assert!(e.set_param("max_tapz", "8").is_err());
    // The reference has no map and no cascades.
    let r = estimator("reference", Backend::Cpu).unwrap();
    assert!(r.params().get("cascades").is_none());
}

/// Tiles by direction (docs/methods.md §1 "Tiles by direction"): on `backlit-stone` (looked at
/// while building) and `backlit-pair` (held out), receivers up to 90 degrees off the light's
/// axis, `tiles=4` at r = 512 runs four views, serves every active receiver (V in [0, 1]) and
/// lowers multi-sample's RMSE against one view by a quarter or more, on every backend.
#[test]
fn tiles_help_the_backlit_scenes() {
    on_fixtures(
        &["backlit-stone", "backlit-pair"],
        |name, scene, rec, truth, failures| {
            for (b, backend) in
                support::runnable_backends("multi-sample", "tiles_help_the_backlit_scenes")
            {
                let one = [("resolution", "512"), ("tiles", "1"), ("casters", "off")];
                let four = [("resolution", "512"), ("tiles", "4"), ("casters", "off")];
                let (v1, _) = run_with("multi-sample", backend, &one, scene, rec);
                let (v4, e4) = run_with("multi-sample", backend, &four, scene, rec);
                let (r1, r4) = (rmse(&v1, truth, rec), rmse(&v4, truth, rec));
                println!("{name} multi-sample {b}: RMSE one view {r1:.4}, 4 tiles {r4:.4}");
                let tiles = note(e4.as_ref(), "light_tiles");
                if tiles.as_deref() != Some("4") {
                    failures.push(format!("{name} {b}: light_tiles {tiles:?}"));
                }
                check_unit_v(failures, &format!("{name} {b}"), &v4, rec);
                if !(r4 <= 0.75 * r1) {
                    failures.push(format!("{name} {b}: RMSE {r1:.4} -> {r4:.4} with 4 tiles"));
                }
            }
        },
    );
}

/// Receivers no view holds (docs/methods.md §1 "Receivers outside every view"): on
/// `backlit-stone` and `backlit-pair` the ground runs past the light's plane, so some lit
/// receivers lie beyond 87 degrees off its axis, outside accumulation's one view. Accumulation
/// now renders both on every backend, settling those receivers without a map
/// (`settled_without_map` > 0), and each settled receiver's V (its facing fraction) agrees with the
/// ray-traced reference: mean |difference| at most 0.01 over them.
#[test]
fn accumulation_settles_receivers_beyond_its_view() {
    use shadow_map_core::{light_view::MAX_TAN, settle::Settler};
    on_fixtures(
        &["backlit-stone", "backlit-pair"],
        |name, scene, rec, truth, failures| {
            let settler = Settler::new(scene);
            let frame = scene.light().frame();
            // The receivers beyond every view that the settle test proves unshadowed.
            let beyond: Vec<usize> = (0..rec.len())
                .filter(|&k| {
                    let q = frame.to_light(rec.position()[k]);
                    rec.active()[k]
                        && q.z > 0.0
                        && q.x.abs().max(q.y.abs()) > MAX_TAN * q.z
                        && scene
                            .light()
                            .front_fraction_world(rec.position()[k], rec.normal()[k])
                            > 0.0
                        && settler.unshadowed(rec.position()[k], rec.normal()[k])
                })
                .collect();
            if beyond.is_empty() {
                failures.push(format!(
                    "{name}: no receiver beyond the view (the fixture changed?)"
                ));
            }
            for (b, backend) in support::runnable_backends(
                "accumulation",
                "accumulation_settles_receivers_beyond_its_view",
            ) {
                let mut e = estimator("accumulation", backend).unwrap();
                e.set_param("resolution", "512").unwrap();
                let v = match run(e.as_mut(), scene, rec) {
                    Ok((v, _)) => v,
                    Err(err) => {
                        failures.push(format!("{name} {b}: {err}"));
                        continue;
                    }
                };
                let settled = settled_note(e.as_ref());
                let diff = beyond
                    .iter()
                    .map(|&k| (v[k] - truth[k]).abs() as f64)
                    .sum::<f64>()
                    / beyond.len().max(1) as f64;
                println!(
                "{name} accumulation {b}: settled {settled}, {} beyond the view and unshadowed, mean |V - reference| there {diff:.4}, RMSE {:.4}",
                beyond.len(),
                rmse(&v, truth, rec)
            );
                if settled == 0 {
                    failures.push(format!("{name} {b}: settled_without_map missing or 0"));
                }
                if !(diff <= 0.01) {
                    failures.push(format!("{name} {b}: settled receivers off by {diff:.4}"));
                }
                check_unit_v(failures, &format!("{name} {b}"), &v, rec);
            }
        },
    );
}

/// Caster-aware fitting (docs/methods.md §1 "Caster-aware fitting"): on the long
/// grounds most receivers see the light past every caster. `casters=on` settles them without a
/// map, exactly (mean |V - reference| over them at most 0.005, none off by more than 0.05: the
/// reference's 256 stratified samples of the facing fraction), fits the views to the rest, lowers
/// the texel density's p95, and does not raise any soft estimator's RMSE by more than 0.002 over
/// `casters=off` (both with cascades and tiles at auto), on every backend.
#[test]
fn caster_aware_fitting_settles_exactly_and_fits_the_rest() {
    on_fixtures(
        &["long-ground", "long-yard"],
        |name, scene, rec, truth, failures| {
            for algo in ["pcss", "multi-sample", "packet-hsm"] {
                for (b, backend) in support::runnable_backends(
                    algo,
                    "caster_aware_fitting_settles_exactly_and_fits_the_rest",
                ) {
                    let off = [("resolution", "512"), ("casters", "off")];
                    let on = [("resolution", "512"), ("casters", "on")];
                    let (v0, e0) = run_with(algo, backend, &off, scene, rec);
                    let (v1, e1) = run_with(algo, backend, &on, scene, rec);
                    let settled = shadow_map_core::cascades::settle(
                        &shadow_map_core::cascades::CascadeSettings::from_params(e1.params())
                            .unwrap(),
                        scene,
                        rec,
                        || shadow_map_core::cascades::one_view_p95(scene, rec, e1.params()),
                    );
                    let Some(settled) = settled else {
                        failures.push(format!("{name} {algo} {b}: nothing settled"));
                        continue;
                    };
                    let n = settled_note(e1.as_ref());
                    let (mut sum, mut worst) = (0.0f64, 0.0f32);
                    for (k, s) in settled.v.iter().enumerate() {
                        if let Some(s) = s {
                            if v1[k].to_bits() != s.to_bits() {
                                failures
                                    .push(format!("{name} {algo} {b}: receiver {k} not settled"));
                                break;
                            }
                            let d = (v1[k] - truth[k]).abs();
                            sum += d as f64;
                            worst = worst.max(d);
                        }
                    }
                    let mean = sum / settled.count().max(1) as f64;
                    let (r0, r1) = (rmse(&v0, truth, rec), rmse(&v1, truth, rec));
                    let p95 = |e: &dyn SoftShadowEstimator| {
                        let d = shadow_map_core::cascades::texel_density_of(scene, rec, e.params());
                        shadow_map_core::cascades::median_p95(&d.unwrap())
                            .unwrap()
                            .1
                    };
                    let (d0, d1) = (p95(e0.as_ref()), p95(e1.as_ref()));
                    println!(
                    "{name} {algo} {b}: settled {n} of {}, mean |V - ref| there {mean:.4} (max {worst:.4}), RMSE off {r0:.4} on {r1:.4}, density p95 {d0:.2} -> {d1:.2}",
                    rec.active().iter().filter(|a| **a).count()
                );
                    if n != settled.count() {
                        failures.push(format!(
                            "{name} {algo} {b}: note {n} vs {}",
                            settled.count()
                        ));
                    }
                    if !(mean <= 0.005 && worst <= 0.05) {
                        failures.push(format!(
                            "{name} {algo} {b}: settled off by {mean} / {worst}"
                        ));
                    }
                    if !(r1 <= r0 + 0.002) {
                        failures.push(format!("{name} {algo} {b}: RMSE {r0:.4} -> {r1:.4}"));
                    }
                    if !(d1 < d0) {
                        failures.push(format!("{name} {algo} {b}: density p95 {d0} -> {d1}"));
                    }
                }
            }
        },
    );
}
