//! Cancellation of a CPU render: every CPU estimator of the registry, bare and as the
//! registry hands it out (wrapped in `Cascaded` when it has a map), returns `Err(Cancelled)` under
//! a cancelled token, never a V, and renders again, bit for bit as before, under a fresh one; a
//! long render cancelled from another thread while it runs stops with `Err(Cancelled)`. The GPU
//! twins take the token too (they hand it to their CPU twins and check it between views).
use crate::support;
use shadow_map_core::{run, Cancel, Receivers, Scene, SceneBvh, SoftShadowEstimator};
use softshadow::{backends, estimator, registry, Backend, Error, ALGOS, METHODS};

fn scene(width: u32, height: u32) -> (Scene, Receivers) {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/fixtures/parallel-squares/parallel-squares.toml"
    );
    let mut scene = Scene::load(path).unwrap();
    scene.set_resolution(width, height).unwrap();
    let rec = Receivers::from_camera(&scene, &SceneBvh::new(&scene));
    (scene, rec)
}

/// Cheap settings for the suite (only keys the estimator declares are set).
fn quick(e: &mut dyn SoftShadowEstimator) {
    for (k, v) in [("spp", "16"), ("resolution", "256")] {
        if e.params().get(k).is_some() {
            e.set_param(k, v).unwrap();
        }
    }
}

/// `e` renders, refuses under a cancelled token, then renders the same V under a fresh one.
fn honours_cancel(label: &str, e: &mut dyn SoftShadowEstimator, scene: &Scene, rec: &Receivers) {
    quick(e);
    let before = run(e, scene, rec)
        .unwrap_or_else(|err| panic!("{label}: {err}"))
        .0;
    let cancel = Cancel::new();
    e.set_cancel(cancel.clone());
    cancel.cancel();
    match run(e, scene, rec) {
        Err(Error::Cancelled) => {}
        Err(err) => panic!("{label}: cancelled, but the error is {err}"),
        Ok(_) => panic!("{label}: a cancelled token rendered V as if done"),
    }
    // A token set after `build`: `estimate` alone must see it.
    let cancel = Cancel::new();
    e.set_cancel(cancel.clone());
    e.build(scene, rec).unwrap();
    cancel.cancel();
    let mut v = vec![f32::NAN; rec.len()];
    assert!(
        matches!(e.estimate(scene, rec, &mut v), Err(Error::Cancelled)),
        "{label}: estimate ignored a token cancelled after build"
    );
    e.set_cancel(Cancel::new());
    let after = run(e, scene, rec)
        .unwrap_or_else(|err| panic!("{label}: after a fresh token: {err}"))
        .0;
    assert_eq!(before.len(), after.len());
    for (k, (a, b)) in before.iter().zip(&after).enumerate() {
        assert_eq!(a.to_bits(), b.to_bits(), "{label}: receiver {k}: {a} / {b}");
    }
}

#[test]
fn every_cpu_estimator_honours_a_cancelled_token_and_stays_usable() {
    let (scene, rec) = scene(40, 30);
    // Bare: the estimator's own loops (not a wrapper's check) must stop.
    for m in METHODS {
        let mut e = m.cpu().unwrap();
        honours_cancel(m.name(), e.as_mut(), &scene, &rec);
    }
    // As the registry hands them out (`Cascaded` forwards the token and checks it too).
    let all = registry().unwrap();
    assert_eq!(all.len(), ALGOS.len());
    for mut e in all {
        let label = format!("{} (registry)", e.name());
        honours_cancel(&label, e.as_mut(), &scene, &rec);
    }
    // Several cascades: the wrapper's loop over slices.
    let mut e = estimator("pcss", Backend::Cpu).unwrap();
    e.set_param("cascades", "3").unwrap();
    honours_cancel("pcss cascades=3", e.as_mut(), &scene, &rec);
}

/// A render far too long to finish during the test (the reference at 65536 samples per receiver,
/// multi-sample at 64 x 64 sub-lights), cancelled from this thread once its token shows progress:
/// it returns, with `Err(Cancelled)`, having done only part of the work. No wall time is asserted.
#[test]
fn a_long_render_cancelled_from_another_thread_stops() {
    let (scene, rec) = scene(64, 48);
    let active = rec.active_count() as u64;
    for (algo, key, value, total) in [
        ("reference", "spp", "65536", active),
        (
            "multi-sample",
            "sublights",
            "64",
            64 * 64 * rec.len() as u64,
        ),
    ] {
        let cancel = Cancel::new();
        let out = std::thread::scope(|s| {
            let token = cancel.clone();
            let (scene, rec) = (&scene, &rec);
            let h = s.spawn(move || {
                let mut e = estimator(algo, Backend::Cpu).unwrap();
                e.set_param(key, value).unwrap();
                e.set_cancel(token);
                run(e.as_mut(), scene, rec).map(|_| ())
            });
            // Started: some receivers are done.
            while cancel.progress() == 0 && !h.is_finished() {
                std::thread::sleep(std::time::Duration::from_millis(1));
            }
            cancel.cancel();
            h.join().expect("the render panicked")
        });
        assert!(
            matches!(out, Err(Error::Cancelled)),
            "{algo}: expected Err(Cancelled), got {out:?}"
        );
        let done = cancel.progress();
        assert!(done > 0 && done < total, "{algo}: {done} of {total} done");
        println!("{algo}: cancelled after {done} of {total} receiver passes");
    }
}

#[test]
fn every_gpu_estimator_honours_a_cancelled_token_and_stays_usable() {
    let Some(gpu) = support::runnable(
        "gpu",
        "every_gpu_estimator_honours_a_cancelled_token_and_stays_usable",
    ) else {
        return;
    };
    let (scene, rec) = scene(40, 30);
    for &algo in ALGOS.iter().filter(|a| backends(a).contains(&"gpu")) {
        let mut e = estimator(algo, gpu).unwrap();
        honours_cancel(&format!("{algo} (gpu)"), e.as_mut(), &scene, &rec);
    }
}
