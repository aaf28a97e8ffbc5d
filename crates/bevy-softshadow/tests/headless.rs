//! The plugin in a real Bevy app on the GPU (lavapipe in CI): a fixture rendered headless with
//! methods switched between frames; each method's V, read back once, against its CPU twin on
//! the receivers Bevy's prepass gave, in the same views (within RMSE 0.01), and
//! against `softshadow render --backend cpu` end to end. Small images keep it quick.
// `!(x <= bound)` on purpose: a NaN figure fails.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

#[path = "common/fixture.rs"]
mod fixture;
#[path = "common/headless.rs"]
mod headless;

use bevy_softshadow::Method::{
    self, Accumulation, Backprojection, DeepShadow, Hard, MultiSample, PacketHsm, Pcf, Pcss,
};
use shadow_map_core::Scene;

fn fixture(name: &str, w: u32, h: u32) -> Scene {
    let mut s = Scene::load(format!(
        "{}/../../fixtures/{name}/{name}.toml",
        env!("CARGO_MANIFEST_DIR")
    ))
    .unwrap();
    s.set_resolution(w, h).unwrap();
    s
}

/// Bevy panics without an adapter: ask test-support's gate first (skips loudly, or fails when
/// `SOFTSHADOW_REQUIRE_GPU=1`).
fn gpu(name: &str) -> bool {
    test_support::gate::context_for_tests(name)
        .unwrap()
        .is_some()
}

/// One Bevy app at a time (the task pools are the process's).
static ONE_APP: std::sync::Mutex<()> = std::sync::Mutex::new(());

fn check(scene: &Scene, methods: &[Method]) {
    let _one = ONE_APP.lock().unwrap_or_else(|e| e.into_inner());
    let out = headless::run(scene, methods, 2, true, None).unwrap();
    let (runs, shot) = (out.runs, out.screenshot);
    assert!(out.bevy_alone_ms > 0.0);
    assert_eq!(runs.len(), methods.len());
    let mut failures = Vec::new();
    for r in &runs {
        let c = match &r.result {
            Ok(c) => c,
            Err(e) => {
                failures.push(format!("{}: {e}", r.method.name()));
                continue;
            }
        };
        let name = r.method.name();
        eprintln!("{name}: {c:?}");
        // Prepared once when switched to, then kept for every frame (the first method also
        // recorded the warm-up frames).
        if c.frames_recorded < r.frames as u64 {
            failures.push(format!("{name}: {} frames on the view", c.frames_recorded));
        }
        if !(c.rmse_vs_cpu <= 0.01) {
            failures.push(format!("{name}: RMSE {} vs the CPU twin", c.rmse_vs_cpu));
        }
        // Not trivially lit: the fixtures' shadows cover a few percent of the image.
        if !(c.frac_below_half > 0.01 && c.mean_v < 0.99) {
            failures.push(format!("{name}: no shadow ({c:?})"));
        }
        // Receivers cut by the device's loop budget stay NaN: the composite leaves them lit.
        // Counted, bounded.
        if c.nan * 10 > c.receivers {
            failures.push(format!("{name}: {} of {} NaN", c.nan, c.receivers));
        }
        // ... and the view's status, read back without waiting, counted them (the frames are
        // alike, so the status a frame behind counts the same receivers).
        let counted = if c.keeps_status {
            c.status_left_nan
        } else {
            Some(0)
        };
        if counted != Some(c.nan as u32) {
            failures.push(format!(
                "{name}: {} NaN, the status says {:?}",
                c.nan, c.status_left_nan
            ));
        }
        // The prepass is the ray-traced G-buffer but for silhouette pixels.
        if c.pixels_covered_by_one + c.pixels_apart > c.receivers / 50 {
            failures.push(format!("{name}: prepass far from the G-buffer ({c:?})"));
        }
        if !(c.rmse_vs_cpu_render <= 0.1) {
            failures.push(format!("{name}: RMSE {} vs render", c.rmse_vs_cpu_render));
        }
    }
    // The composite darkened the image where V < 1: some pixels are darker than the ground's
    // lit colour (a crude check that the pass ran and wrote its destination).
    let shot = shot.unwrap();
    let (w, h) = (scene.camera().width, scene.camera().height);
    assert_eq!(shot.len(), (4 * w * h) as usize);
    assert!(
        shot.chunks_exact(4).any(|p| p[0] > 100),
        "an all-dark image"
    );
    assert!(failures.is_empty(), "{failures:#?}");
}

/// `methods` in one app on the fixture `name` at 96 x 72 (the GPU gate named `test`).
fn check_fixture(test: &str, name: &str, methods: &[Method]) {
    if gpu(test) {
        check(&fixture(name, 96, 72), methods);
    }
}

#[test]
fn bunny_rect_light_in_bevy() {
    let methods = [Pcss, Backprojection, Accumulation, PacketHsm];
    check_fixture("bunny_rect_light_in_bevy", "bunny", &methods);
}

#[test]
fn sun_bunny_in_bevy() {
    let methods = [Hard, Pcf, MultiSample, DeepShadow];
    check_fixture("sun_bunny_in_bevy", "sun-bunny", &methods);
}

#[test]
fn sphere_light_in_bevy() {
    check_fixture("sphere_light_in_bevy", "bunny-sphere", &[Pcss, PacketHsm]);
}

/// A 200 m ground lit from 10 m up: one view over the whole box cannot hold it (a one-line
/// error per view, no frame), one cut to 30 m of the camera can, close to the CPU render.
#[test]
fn long_yard_needs_max_distance() {
    if !gpu("long_yard_needs_max_distance") {
        return;
    }
    let _one = ONE_APP.lock().unwrap_or_else(|e| e.into_inner());
    let scene = fixture("long-yard", 80, 60);
    let whole = headless::run(&scene, &[Method::Pcss], 2, false, None).unwrap();
    let e = whole.runs[0].result.as_ref().unwrap_err();
    assert!(e.contains("leave the light frustum"), "{e}");
    let cut = headless::run(&scene, &[Method::Pcss], 2, false, Some(30.0)).unwrap();
    let c = cut.runs[0].result.as_ref().unwrap();
    eprintln!("{c:?}");
    assert!(c.rmse_vs_cpu <= 0.01, "{c:?}");
    assert!(c.rmse_vs_cpu_render <= 0.05, "{c:?}");
}
