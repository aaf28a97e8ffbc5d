//! The GPU estimator on its own: the typed capacity error, every fit and near/far choice
//! against the CPU twin (and on the frame's own map), and receivers beyond the light view's
//! reach.
#![cfg(feature = "gpu")]
use crate::common::*;
use crate::on_map::{assert_fixture_within, frame_on_its_map, raster_bound};
use deep_shadow::{CpuDeepShadow, DeepShadowFrame};
use shadow_map_core::{gpu::frame::FrameEstimator, run, Error, SoftShadowEstimator, Warning};

/// A `max_capacity` below the fragments one view needs is a typed error on the GPU estimator too:
/// the frame's element buffer takes at most `max_capacity` elements, the overflowing frame
/// leaves its receivers for the redo, and the CPU twin's build refuses with the need.
#[test]
fn gpu_max_capacity_below_the_need_is_a_typed_error() {
    let Some(ctx) = test_support::gpu("gpu_max_capacity_below_the_need_is_a_typed_error") else {
        return;
    };
    let (scene, rec) = fixture("strands", 32, 24);
    let kv = [("resolution", "64"), ("filter", "none")];
    let mut c = CpuDeepShadow::new().unwrap();
    let mut g = deep_shadow::DESCRIPTOR.gpu(ctx).unwrap().unwrap();
    for (k, v) in kv {
        c.set_param(k, v).unwrap();
        g.set_param(k, v).unwrap();
    }
    let (_, rc) = run(&mut c, &scene, &rec).unwrap();
    let need: u64 = note(&rc, "fragments").unwrap().parse().unwrap();
    g.set_param("max_capacity", "100").unwrap();
    match run(&mut *g, &scene, &rec) {
        Err(Error::Limit { requested, max, .. }) => {
            assert_eq!(requested, need);
            assert_eq!(max, 100);
        }
        Err(e) => panic!("expected a limit error, got {e}"),
        Ok(_) => panic!("expected a limit error"),
    }
}

/// Every `fit` x `nearfar` combination on a semi-transparent fixture (deep lists) and an opaque
/// one, through both estimators, with a filter margin (`pcf`/`edsm`, the stable fit's lattice
/// margin included): V in [0, 1] and finite for every active receiver, within [`raster_bound`]
/// of the CPU twin's and with one view the CPU twin's on the frame's own map
/// ([`frame_on_its_map`]), the frame's views those of the CPU twin (`near`, `far`), and
/// the choices reach the view (`fit=receivers` has window_scale 1 before the filter margin,
/// `fit=stable` more).
#[test]
fn every_fit_and_nearfar_match_on_both_estimators() {
    let Some(ctx) = test_support::gpu("every_fit_and_nearfar_match_on_both_estimators") else {
        return;
    };
    for (name, kv) in [
        ("strands", &[("filter", "pcf"), ("kernel", "5")][..]),
        (
            "bunny",
            &[("filter", "edsm"), ("kernel", "7"), ("sublights", "2")][..],
        ),
    ] {
        let (scene, rec) = fixture(name, 32, 24);
        for fit in ["receivers", "scene", "stable"] {
            let mut planes = Vec::new();
            for nearfar in ["clipped", "aabb", "frustum"] {
                let mut c = CpuDeepShadow::new().unwrap();
                let mut g = deep_shadow::DESCRIPTOR.gpu(ctx.clone()).unwrap().unwrap();
                let all = [("resolution", "128"), ("fit", fit), ("nearfar", nearfar)];
                let all: Vec<(&str, &str)> = kv.iter().chain(&all).copied().collect();
                for (k, v) in &all {
                    c.set_param(k, v).unwrap();
                    g.set_param(k, v).unwrap();
                }
                let what = format!("{name} {kv:?} fit={fit} nearfar={nearfar}");
                let (vc, rc) = run(&mut c, &scene, &rec).unwrap();
                let (vg, _) = run(&mut *g, &scene, &rec).unwrap();
                check_contract(&vc, &rec);
                check_contract(&vg, &rec);
                let table = params(&all);
                let frame =
                    DeepShadowFrame::prepare(ctx.clone(), &table, rec.len() as u32).unwrap();
                let views = frame.fit_views(&scene, &rec).unwrap();
                let n = views.iter().flatten().map(|v| v.n).fold(f32::MAX, f32::min);
                let far = views.iter().flatten().map(|v| v.far).fold(0.0, f32::max);
                assert_eq!(note(&rc, "near"), Some(n.to_string()), "{what}: near");
                assert_eq!(note(&rc, "far"), Some(far.to_string()), "{what}: far");
                assert_fixture_within(&what, &vc, &vg, &rec, raster_bound(&scene, &all));
                frame_on_its_map(&what, &ctx, (&frame, &table), &scene, &rec, &vg);
                let ws: f32 = note(&rc, "window_scale").unwrap().parse().unwrap();
                // The pcf/edsm margin widens a receivers window by r / (r - 2 margin).
                let widen = 128.0 / (128.0 - 2.0 * (kv[1].1.parse::<f32>().unwrap() / 2.0).floor());
                match fit {
                    "receivers" => assert!((ws - widen).abs() < 1e-3, "{what}: {ws}"),
                    // Power of two, 3-texel margins, a texel of snapping; the filter margin
                    // may double the side once more.
                    "stable" => {
                        let max = 4.0 * (1.0 + 6.0 / 128.0) * 128.0 / 127.0;
                        assert!(ws > 1.0 && ws <= max, "{what}: {ws}")
                    }
                    _ => assert!(ws >= widen - 1e-3, "{what}: {ws}"),
                }
                planes.push((note(&rc, "near"), note(&rc, "far")));
            }
            assert!(
                planes[0] != planes[1] || planes[0] != planes[2],
                "{name} fit={fit}: nearfar did not change the planes {planes:?}"
            );
        }
    }
}

/// Receivers beyond the light view's reach (`tests/cpu.rs`
/// `receivers_beyond_the_view_are_settled_or_refused`): the GPU estimator's frame looks the far
/// receiver up outside its map and settles it on the device (`gpu::settle`): on the open side it
/// is counted (`OutsideViews`) and given its facing fraction, the CPU twin's settled V; on the
/// walled side the frame leaves it NaN, and the GPU estimator, redoing it with the CPU twin,
/// refuses as the CPU twin does (no map defines its transmittance).
#[test]
fn gpu_receivers_beyond_the_view_are_settled_or_refused() {
    let Some(ctx) = test_support::gpu("gpu_receivers_beyond_the_view_are_settled_or_refused")
    else {
        return;
    };
    let outside = |r: &shadow_map_core::Report| {
        r.warnings
            .iter()
            .find_map(|w| match w {
                Warning::OutsideViews { receivers } => Some(*receivers),
                _ => None,
            })
            .unwrap_or(0)
    };
    let (open, rec) = beyond_reach(false);
    let mut g = deep_shadow::DESCRIPTOR.gpu(ctx.clone()).unwrap().unwrap();
    let (v, rep) = run(&mut *g, &open, &rec).unwrap();
    let (vc, rc) = run(&mut CpuDeepShadow::new().unwrap(), &open, &rec).unwrap();
    assert_eq!(note(&rc, "settled_outside").as_deref(), Some("1"));
    assert!((v[0] - vc[0]).abs() <= 1e-4, "{} vs {}", v[0], vc[0]);
    assert!((v[1] - vc[1]).abs() <= 1e-6, "{} vs {}", v[1], vc[1]);
    assert_eq!(outside(&rep), 1, "{rep:?}");
    let (walled, rec) = beyond_reach(true);
    assert!(matches!(
        run(&mut CpuDeepShadow::new().unwrap(), &walled, &rec),
        Err(Error::Receivers(_))
    ));
    assert!(matches!(
        run(&mut *g, &walled, &rec),
        Err(Error::Receivers(_))
    ));
}
