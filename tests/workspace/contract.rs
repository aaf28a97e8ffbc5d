//! The contract every estimator keeps (docs/methods.md §11): V in [0, 1] for every camera hit,
//! NaN for background, never inf; the registry lists every estimator with parameters whose
//! defaults parse.
use shadow_map_core::{run, Error, LightShape, Receivers, Scene, SceneBvh};
use softshadow::{registry, Backend, ALGOS};
use test_support::fixtures::{fixture_names, fixture_path};

#[test]
fn registry_is_complete_and_defaults_parse() {
    let all = registry().expect("every default parses");
    let names: Vec<&str> = all.iter().map(|e| e.name()).collect();
    assert_eq!(names, ALGOS);
    for e in &all {
        assert_eq!(e.backend(), Backend::Cpu);
        assert!(!e.description().is_empty());
        for s in e.params().specs() {
            assert!(
                s.parse(s.default).is_ok(),
                "{}: default of {} does not parse",
                e.name(),
                s.key
            );
            assert!(!s.help.is_empty());
        }
    }
}

/// Every key a report setting names is in its method's table and its value parses, so a renamed
/// parameter fails here and not halfway through a report.
#[test]
fn every_report_setting_applies_to_its_method() {
    for m in softshadow::METHODS {
        for quick in [true, false] {
            let sweep = m.sweep(quick);
            assert!(
                m.name() == "reference" || !sweep.is_empty(),
                "{}: nothing to sweep",
                m.name()
            );
            for setting in sweep {
                let mut e = m.cpu().unwrap();
                for (k, v) in &setting {
                    if let Err(err) = e.set_param(k, v) {
                        panic!("{}: report setting {setting:?}: {err}", m.name());
                    }
                }
            }
        }
    }
}

#[test]
fn every_estimator_keeps_the_contract_on_every_fixture() {
    let names = fixture_names();
    assert!(names.len() >= 5, "fixtures missing: {names:?}");
    for name in names {
        let mut scene = Scene::load(fixture_path(&name)).unwrap();
        // Small images keep this fast; the contract does not depend on size.
        scene.set_resolution(40, 30).unwrap();
        let bvh = SceneBvh::new(&scene);
        let rec = Receivers::from_camera(&scene, &bvh);
        assert!(rec.active_count() > 0, "{}: camera sees nothing", name);
        for mut e in registry().unwrap() {
            for (k, v) in [("resolution", "128"), ("spp", "16")] {
                if e.params().get(k).is_some() {
                    e.set_param(k, v).unwrap();
                }
            }
            let rect = matches!(scene.light().shape, LightShape::Rect { .. });
            let v = match run(e.as_mut(), &scene, &rec) {
                Ok((v, _)) => v,
                // Rect-only estimators may refuse other lights, naming the light, and nothing else.
                Err(Error::Param { key, .. }) if !rect && key == "light" => continue,
                Err(err) => panic!("{} on {}: {err}", e.name(), name),
            };
            for (k, x) in v.iter().enumerate() {
                if rec.active()[k] {
                    assert!(
                        (0.0..=1.0).contains(x),
                        "{} on {}: V[{k}] = {x}",
                        e.name(),
                        name
                    );
                } else {
                    assert!(
                        x.is_nan(),
                        "{} on {}: background V[{k}] = {x}",
                        e.name(),
                        name
                    );
                }
            }
        }
    }
}
