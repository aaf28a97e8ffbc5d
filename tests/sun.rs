//! The sun (issue 19; the contract's directional light), first step: scenes load it, the
//! ray-traced reference renders it (checked against a closed form in `crates/reference`), and
//! every estimator that has no orthographic light view yet refuses it with a one-line typed error
//! naming the light, on every backend: no panic, no NaN, no image of a light centre that does
//! not exist.
mod support;
use glam::Vec3;
use shadow_map_core::{run, Light, Receivers, Scene, SceneBvh};
use softshadow::{backends, estimator, Backend, ALGOS};
use test_support::fixtures::fixture;

/// The bunny fixture under a low 3-degree sun.
fn sunny_bunny() -> (Scene, Receivers) {
    let (mut scene, _) = fixture("bunny", 40, 30);
    scene.light = Light::directional(Vec3::new(0.6, -0.5, 0.3), 3.0);
    let rec = Receivers::from_camera(&scene, &SceneBvh::new(&scene));
    (scene, rec)
}

#[test]
fn the_reference_renders_the_sun() {
    let (scene, rec) = sunny_bunny();
    let mut e = estimator("reference", Backend::Cpu).unwrap();
    e.set_param("spp", "64").unwrap();
    let (v, _) = run(e.as_mut(), &scene, &rec).unwrap();
    let (mut lit, mut dark) = (0, 0);
    for (k, x) in v.iter().enumerate() {
        if rec.active[k] {
            assert!((0.0..=1.0).contains(x), "receiver {k}: {x}");
            lit += usize::from(*x == 1.0);
            dark += usize::from(*x == 0.0);
        } else {
            assert!(x.is_nan());
        }
    }
    assert!(
        lit > 0 && dark > 0,
        "lit {lit}, dark {dark}: no shadow under the sun?"
    );
}

#[test]
fn estimators_without_an_orthographic_view_refuse_the_sun() {
    let (scene, rec) = sunny_bunny();
    let mut failures = Vec::new();
    for &name in ALGOS.iter().filter(|n| **n != "reference") {
        for &b in backends(name) {
            let Some(backend) =
                support::runnable(b, "estimators_without_an_orthographic_view_refuse_the_sun")
            else {
                continue;
            };
            let mut e = estimator(name, backend).unwrap();
            match run(e.as_mut(), &scene, &rec) {
                Ok(_) => failures.push(format!("{name} {b}: rendered a directional light")),
                Err(err) => {
                    let msg = err.to_string();
                    if !(msg.contains("directional")
                        && msg.contains("light")
                        && !msg.contains('\n'))
                    {
                        failures.push(format!("{name} {b}: {msg:?}"));
                    }
                }
            }
        }
    }
    assert!(failures.is_empty(), "{failures:#?}");
}
