//! CPU baselines against closed forms and their limits (docs/methods.md §5, §6, §10).
use baselines::{HardShadow, MultiSample, PcfShadow, PcssShadow};
use glam::Vec3;
use shadow_map_core::{run, Receivers, Scene, SoftShadowEstimator};
use test_support::fixtures::{configure, errors, line_receivers, rect_light, scene_with, SQUARE};

/// Rect light `l x l` at height 3 pointing down, over a square occluder at 1.5 (its +x edge
/// deliberately off the texel grid) and a ground.
fn parallel_squares(l: f32) -> Scene {
    scene_with(rect_light(l, 3.0), &[SQUARE], 8, 8)
}

/// The closed form of [`parallel_squares`] at each receiver.
fn oracle(scene: &Scene, r: &Receivers) -> Vec<f64> {
    test_support::fixtures::oracle(scene, &[SQUARE], r)
}

fn estimate(est: &mut dyn SoftShadowEstimator, scene: &Scene, r: &Receivers) -> Vec<f32> {
    run(est, scene, r).unwrap().0
}

/// `errors` (RMS, max) of `est` with the parameters `kv` against the closed form, on the
/// parallel squares under the unit light at the line receivers.
fn closed_form_errors(mut est: impl SoftShadowEstimator, kv: &[(&str, String)]) -> (f64, f64) {
    configure(&mut est, kv);
    let s = parallel_squares(1.0);
    let r = line_receivers();
    errors(&estimate(&mut est, &s, &r), &oracle(&s, &r))
}

/// PCSS is exact for one planar blocker parallel to the light (docs/methods.md §5), up to the
/// rasterisation of the occluder's edge, which the map places within half a texel.
#[test]
fn pcss_matches_the_parallel_plane_closed_form() {
    let mut prev = f64::INFINITY;
    for res in [128, 512, 2048] {
        let kv = [("resolution", res.to_string()), ("max_taps", "1024".into())];
        let (rms, max) = closed_form_errors(PcssShadow::new().unwrap(), &kv);
        eprintln!("pcss r={res}: rms {rms:.5} max {max:.5}");
        // The penumbra on the ground is 1 world unit wide and V changes by 1 per world unit across
        // it; the occluder's rasterised edge is off by at most half a texel, a world distance of
        // about 1.2 / r here, so |dV| <= ~1.2 / r plus float noise. Allow 3 / r + 0.01.
        assert!(max <= 0.01 + 3.0 / res as f64, "r={res}: max error {max}");
        assert!(
            rms <= prev * 1.01,
            "error must not grow with resolution: {rms} after {prev}"
        );
        prev = rms;
    }
}

/// As the light shrinks, PCSS and multi-sample converge to the hard shadow map
/// (docs/methods.md §10.4) away from the hard edge.
#[test]
fn tiny_light_converges_to_the_hard_shadow() {
    let s = parallel_squares(1e-4);
    let r = line_receivers();
    let mut hard = HardShadow::new().unwrap();
    let vh = estimate(&mut hard, &s, &r);
    let o = oracle(&s, &r);
    let mut pcss = PcssShadow::new().unwrap();
    let vp = estimate(&mut pcss, &s, &r);
    let mut ms = MultiSample::new().unwrap();
    ms.set_param("sublights", "2").unwrap();
    let vm = estimate(&mut ms, &s, &r);
    for k in 0..r.len() {
        let x = r.position()[k].x;
        // More than a texel footprint away from the hard edges at x = -1 and x = 1.0246.
        if (x + 1.0).abs() > 0.02 && (x - 1.0246).abs() > 0.02 {
            assert!(
                (vh[k] as f64 - o[k]).abs() < 1e-3,
                "hard at x={x}: {} vs {}",
                vh[k],
                o[k]
            );
            assert_eq!(vp[k], vh[k], "pcss at x={x}");
            assert_eq!(vm[k], vh[k], "multi-sample at x={x}");
        }
    }
}

/// Multi-sample shadows converge to the closed form as S grows, the sub-lights being jittered
/// strata (docs/methods.md §6).
#[test]
fn multi_sample_converges_with_more_sub_lights() {
    let mut last = f64::INFINITY;
    for sub in [2, 4, 8] {
        let kv = [("sublights", sub.to_string()), ("resolution", "512".into())];
        let (rms, _) = closed_form_errors(MultiSample::new().unwrap(), &kv);
        eprintln!("multi-sample S={sub}: rms {rms:.5}");
        assert!(rms < last, "S={sub}: {rms} not below {last}");
        last = rms;
    }
    assert!(last < 0.02);
}

fn all() -> Vec<Box<dyn SoftShadowEstimator>> {
    vec![
        Box::new(HardShadow::new().unwrap()),
        Box::new(PcfShadow::new().unwrap()),
        Box::new(PcssShadow::new().unwrap()),
        Box::new(MultiSample::new().unwrap()),
    ]
}

/// Without occluders every receiver facing the light sees all of it: V = 1 exactly.
#[test]
fn empty_scene_is_fully_lit() {
    let s = scene_with(rect_light(1.0, 3.0), &[], 8, 8);
    let r = line_receivers();
    for mut e in all() {
        let v = estimate(e.as_mut(), &s, &r);
        assert!(
            v.iter().all(|&x| x == 1.0),
            "{}: {:?}",
            e.name(),
            v.iter().find(|&&x| x != 1.0)
        );
    }
}

/// Receivers behind the (one-sided) light get 0, inactive slots NaN, umbra 0.
#[test]
fn behind_inactive_and_umbra() {
    let s = parallel_squares(1.0);
    let mut r = Receivers::from_points(
        vec![
            Vec3::new(0.0, 0.0, 2.0),
            Vec3::new(0.0, 5.0, 0.0),
            Vec3::new(3.0, 0.0, 0.0),
            Vec3::new(0.2, 0.0, 0.0),
        ],
        vec![Vec3::Y; 4],
    )
    .unwrap();
    r.active_mut()[2] = false;
    for mut e in all() {
        let v = estimate(e.as_mut(), &s, &r);
        assert_eq!(v[1], 0.0, "{}: receiver above the light", e.name());
        assert!(v[2].is_nan(), "{}: inactive slot", e.name());
        assert_eq!(v[3], 0.0, "{}: umbra receiver", e.name());
        assert!((0.0..=1.0).contains(&v[0]));
    }
}

/// Bad parameters are errors naming the key, never panics.
#[test]
fn bad_parameters() {
    for mut e in all() {
        for (k, v, needle) in [
            ("resolution", "0", "out of range"),
            ("resolution", "99999", "out of range"),
            ("bias", "nan", "out of range"),
            ("nope", "1", "unknown parameter"),
            ("cull", "sideways", "expected one of"),
        ] {
            let err = e.set_param(k, v).unwrap_err().to_string();
            assert!(
                err.contains(k) && err.contains(needle),
                "{}: {err}",
                e.name()
            );
        }
    }
}

/// The trait's estimate must be given a slice of the right length.
#[test]
fn output_length_is_checked() {
    let s = parallel_squares(1.0);
    let r = line_receivers();
    for mut e in all() {
        e.build(&s, &r).unwrap();
        let mut v = vec![0.0; r.len() - 1];
        assert!(e.estimate(&s, &r, &mut v).is_err());
    }
}

/// When no receiver needs a map (none at all, or all behind the one-sided light), every estimator
/// still answers: V = 0 behind the light, and an empty output for no receivers.
#[test]
fn no_receiver_in_front_of_the_light() {
    let s = parallel_squares(1.0);
    let behind = Receivers::from_points(
        vec![Vec3::new(0.0, 5.0, 0.0), Vec3::new(1.0, 4.0, 0.0)],
        vec![Vec3::Y; 2],
    )
    .unwrap();
    let none = Receivers::from_points(vec![], vec![]).unwrap();
    for mut e in all() {
        let v = estimate(e.as_mut(), &s, &behind);
        assert_eq!(v, vec![0.0, 0.0], "{}", e.name());
        let v = estimate(e.as_mut(), &s, &none);
        assert!(v.is_empty(), "{}", e.name());
    }
}

/// The square at half opacity (a ground and one semi-transparent mesh), under the unit light.
fn half_opaque_square() -> Scene {
    use test_support::fixtures::{camera, quad};
    let meshes = vec![
        (quad(-4.0, -4.0, 4.0, 4.0, 0.0), 1.0),
        (quad(-0.5, -0.5, 0.5, 0.5, 1.5), 0.5),
    ];
    Scene::from_meshes("half", camera(8, 8), rect_light(1.0, 3.0), meshes).unwrap()
}

/// Every baseline casts a semi-transparent mesh as opaque and says so with a typed warning
/// counting it; an opaque scene gives none.
#[test]
fn semi_transparent_casters_are_warned() {
    use shadow_map_core::Warning;
    let r = line_receivers();
    for mut e in all() {
        let (_, rep) = run(e.as_mut(), &half_opaque_square(), &r).unwrap();
        assert_eq!(
            rep.warning(Warning::OpaqueCasters { meshes: 0 }),
            Some(Warning::OpaqueCasters { meshes: 1 }),
            "{}",
            e.name()
        );
        let (_, rep) = run(e.as_mut(), &parallel_squares(1.0), &r).unwrap();
        assert!(rep.warnings.is_empty(), "{}: {:?}", e.name(), rep.warnings);
    }
}

/// A receiver far beyond the light's frustum (100 to the side of a light 3 above it) is given
/// its facing fraction and counted as a warning.
#[test]
fn receivers_outside_the_light_view_are_warned() {
    use shadow_map_core::Warning;
    let r = Receivers::from_points(
        vec![Vec3::new(0.2, 0.0, 0.0), Vec3::new(100.0, 0.0, 0.0)],
        vec![Vec3::Y; 2],
    )
    .unwrap();
    for mut e in all() {
        let (v, rep) = run(e.as_mut(), &parallel_squares(1.0), &r).unwrap();
        assert_eq!(
            rep.warnings,
            vec![Warning::OutsideViews { receivers: 1 }],
            "{}",
            e.name()
        );
        assert!(v[1] > 0.0, "{}: the outside receiver is lit", e.name());
    }
}
