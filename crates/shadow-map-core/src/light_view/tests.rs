//! The light view's unit tests: bounds fitting, parameters, near planes.
use super::*;
use crate::scene::Aabb;

mod bounds_tests {
    use super::*;
    use crate::bvh::SceneBvh;

    fn fixture(name: &str) -> Scene {
        let path = format!(
            "{}/../../fixtures/{name}/{name}.toml",
            env!("CARGO_MANIFEST_DIR")
        );
        Scene::load(&path).unwrap_or_else(|e| panic!("{path}: {e}"))
    }

    /// Window in x/z units: (lo, hi).
    fn tan_window(v: &LightView) -> (Vec2, Vec2) {
        (v.window_min / v.n, (v.window_min + Vec2::splat(v.w)) / v.n)
    }

    /// Asserts the window of `vb` (from bounds) holds the window of `vr` (from receivers) in x/z
    /// units and every active receiver's footprint at `vb`'s own n.
    fn assert_covers(vb: &LightView, vr: &LightView, rec: &Receivers, half: Vec2, what: &str) {
        let (lb, hb) = tan_window(vb);
        let (lr, hr) = tan_window(vr);
        let slack = 1e-5 * (hb - lb).max_element();
        assert!(vb.n <= vr.n * (1.0 + 1e-6), "{what}: n {} > {}", vb.n, vr.n);
        assert!(
            vb.far >= vr.far * (1.0 - 1e-6),
            "{what}: far {} < {}",
            vb.far,
            vr.far
        );
        assert!(
            lb.cmple(lr + slack).all() && hb.cmpge(hr - slack).all(),
            "{what}: bounds window {lb}..{hb} misses receivers window {lr}..{hr}"
        );
        let mut checked = 0;
        for (p, &a) in rec.position().iter().zip(rec.active()) {
            if !a {
                continue;
            }
            let q = vb.frame.to_light(*p);
            let t = Vec2::new(q.x, q.y) / q.z;
            let f = half * (1.0 / vb.n - 1.0 / q.z).max(0.0);
            assert!(
                (t - f).cmpge(lb - slack).all() && (t + f).cmple(hb + slack).all(),
                "{what}: footprint of {p} ({}..{}) outside {lb}..{hb}",
                t - f,
                t + f
            );
            checked += 1;
        }
        assert!(checked > 0, "{what}: no receiver checked");
    }

    /// The receivers' fit a bounds fit with `opts` must hold: the same options, except that
    /// `stable` is compared with `receivers` (each snaps its own square to the power-of-two
    /// lattice, so two stable windows of the same side need not nest; the bounds' stable window
    /// holds the bounds' square, which holds the receivers').
    fn reference(opts: ViewOptions) -> ViewOptions {
        ViewOptions {
            fit: match opts.fit {
                FitMode::Stable => FitMode::Receivers,
                f => f,
            },
            ..opts
        }
    }

    #[test]
    fn bounds_window_holds_the_receivers_window_on_fixtures() {
        for name in ["parallel-squares", "stacked", "overlapping"] {
            let scene = fixture(name);
            let rec = Receivers::from_camera(&scene, &SceneBvh::new(&scene));
            let b = receiver_bounds(&rec);
            let light = scene.light();
            for fit in [FitMode::Receivers, FitMode::Scene, FitMode::Stable] {
                for nearfar in [NearFar::Clipped, NearFar::Aabb, NearFar::Frustum] {
                    let opts = ViewOptions { fit, nearfar };
                    let what = format!("{name} {fit:?} {nearfar:?}");
                    let half = light.half_extent();
                    let (vr, _) = LightView::fit_with(
                        &scene,
                        &rec,
                        light.frame(),
                        half,
                        256,
                        &reference(opts),
                    )
                    .expect("receivers fit");
                    let (vb, rep) =
                        LightView::fit_bounds(&scene, &b, light.frame(), half, 256, &opts)
                            .expect("bounds fit");
                    assert_eq!(rep.behind + rep.out_of_frustum, 0, "{what}");
                    assert_covers(&vb, &vr, &rec, half, &what);
                }
            }
        }
    }

    /// Points scattered inside a box under a tilted light (a fixed pseudo-random sequence, the
    /// box's corners among them): the bounds window holds their window and footprints.
    #[test]
    fn bounds_window_holds_scattered_points() {
        let mut scene = fixture("parallel-squares");
        let mut light = *scene.light();
        light.normal = Vec3::new(0.3, -1.0, 0.2).normalize();
        light.shape = crate::LightShape::Rect { size: [0.8, 0.5] };
        scene.set_light(light).unwrap();
        let b = Aabb {
            min: Vec3::new(-1.5, 0.0, -1.2),
            max: Vec3::new(1.3, 1.2, 1.6),
        };
        let mut seed = 0x2545_f491_u32;
        let mut unit = move || {
            seed = seed.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            (seed >> 8) as f32 / (1u32 << 24) as f32
        };
        let mut pts: Vec<Vec3> = (0..8)
            .map(|k| {
                Vec3::new(
                    if k & 1 == 0 { b.min.x } else { b.max.x },
                    if k & 2 == 0 { b.min.y } else { b.max.y },
                    if k & 4 == 0 { b.min.z } else { b.max.z },
                )
            })
            .collect();
        pts.extend((0..500).map(|_| b.min + (b.max - b.min) * Vec3::new(unit(), unit(), unit())));
        // Half of them only, so the receivers' window is strictly smaller than the box's.
        let inner: Vec<Vec3> = pts[8..258].to_vec();
        let light = scene.light();
        let half = light.half_extent();
        for (set, label) in [(pts, "with corners"), (inner, "inside")] {
            let n = set.len();
            let rec = Receivers::from_points(set, vec![Vec3::Y; n]).expect("points");
            for fit in [FitMode::Receivers, FitMode::Scene, FitMode::Stable] {
                let opts = ViewOptions {
                    fit,
                    nearfar: NearFar::Clipped,
                };
                let (vr, _) =
                    LightView::fit_with(&scene, &rec, light.frame(), half, 128, &reference(opts))
                        .expect("receivers fit");
                let (vb, _) = LightView::fit_bounds(&scene, &b, light.frame(), half, 128, &opts)
                    .expect("bounds fit");
                assert_covers(&vb, &vr, &rec, half, &format!("{label} {fit:?}"));
            }
        }
    }

    #[test]
    fn bad_bounds_are_typed_errors() {
        let scene = fixture("parallel-squares");
        let light = scene.light();
        let fit = |min: Vec3, max: Vec3| {
            LightView::fit_bounds(
                &scene,
                &Aabb { min, max },
                light.frame(),
                light.half_extent(),
                64,
                &ViewOptions::default(),
            )
        };
        let receivers_err = |r: Result<(LightView, FitReport)>, needle: &str| match r {
            Err(Error::Receivers(m)) => assert!(m.contains(needle), "{m}"),
            other => panic!("expected Error::Receivers({needle}), got {other:?}"),
        };
        let view_err = |r: Result<(LightView, FitReport)>, needle: &str| match r {
            Err(Error::LightView(m)) => {
                assert!(m.contains(needle), "{m}");
                assert!(m.contains("tighter bounds"), "{m}");
            }
            other => panic!("expected Error::LightView({needle}), got {other:?}"),
        };
        receivers_err(
            LightView::fit_bounds(
                &scene,
                &Aabb::EMPTY,
                light.frame(),
                light.half_extent(),
                64,
                &ViewOptions::default(),
            ),
            "inverted or empty",
        );
        receivers_err(fit(Vec3::ONE, Vec3::ZERO), "inverted or empty");
        receivers_err(fit(Vec3::new(f32::NAN, 0.0, 0.0), Vec3::ONE), "not finite");
        receivers_err(
            fit(Vec3::ZERO, Vec3::new(1.0, f32::INFINITY, 1.0)),
            "not finite",
        );
        // Finite in the world, past f32 in a tilted light's frame.
        let mut tilted = fixture("parallel-squares");
        let mut light = *tilted.light();
        light.normal = Vec3::new(0.6, -0.8, 0.0);
        tilted.set_light(light).unwrap();
        receivers_err(
            LightView::fit_bounds(
                &tilted,
                &Aabb {
                    min: Vec3::new(3e38, -3e38, 0.0),
                    max: Vec3::new(3.1e38, -2.9e38, 1.0),
                },
                tilted.light().frame(),
                tilted.light().half_extent(),
                64,
                &ViewOptions::default(),
            ),
            "overflows in light space",
        );
        // The light sits at y = 3 facing down: a box reaching above y = 3 crosses its plane.
        view_err(
            fit(Vec3::new(-1.0, 0.0, -1.0), Vec3::new(1.0, 3.5, 1.0)),
            "cross the light plane",
        );
        view_err(
            fit(Vec3::new(-1.0, 3.0, -1.0), Vec3::new(1.0, 3.0, 1.0)),
            "cross the light plane",
        );
        // Just below the light plane and far to the side: beyond MAX_TAN.
        view_err(
            fit(Vec3::new(-1.0, 2.9, -1.0), Vec3::new(100.0, 2.99, 1.0)),
            "leave the light frustum",
        );
        // A box holding a single point in front of the light is fine.
        let p = Vec3::new(0.2, 0.5, -0.3);
        let (v, rep) = fit(p, p).expect("point box");
        assert_eq!(rep.behind + rep.out_of_frustum, 0);
        assert!(v.contains(v.project(v.frame.to_light(p))));
    }
}

mod param_tests {
    use super::*;
    use crate::{precision::DEPTH, Cull, DepthPrecision, FromParam, ParamKind, ParamValue};

    /// Every word of a choice converts, nothing else does.
    fn words_convert<T: FromParam>(spec: &ParamSpec) {
        let ParamKind::Choice(words) = spec.kind else {
            panic!("{} is not a choice", spec.key);
        };
        for w in words {
            assert!(
                T::from_param(ParamValue::Choice(w)).is_some(),
                "{}={w}",
                spec.key
            );
        }
        assert!(T::from_param(ParamValue::Choice("nonsense")).is_none());
        assert!(T::from_param(ParamValue::Int(0)).is_none());
    }

    #[test]
    fn choice_enums_cover_their_words() {
        words_convert::<FitMode>(&FIT);
        words_convert::<NearFar>(&NEARFAR);
        words_convert::<DepthPrecision>(&DEPTH);
        let cull = ParamSpec::choice(Cull::WORDS, "none").named("cull", "");
        words_convert::<Cull>(&cull);
        words_convert::<crate::peeling::SelfShadow>(&crate::peeling::SELF_SHADOW);
        for w in ["midpoint", "bias"] {
            let s = crate::peeling::SelfShadow::from_param(ParamValue::Choice(w)).unwrap();
            assert_eq!(s.word(), w);
        }
        assert_eq!(
            FitMode::from_param(ParamValue::Choice("receivers")),
            Some(FitMode::default())
        );
        assert_eq!(
            NearFar::from_param(ParamValue::Choice("clipped")),
            Some(NearFar::default())
        );
    }
}

mod near_tests {
    use super::*;

    /// Clipping a triangle to a tan-space window: a ground triangle that reaches the light's
    /// plane far outside the window gives the depth where it enters the window, not its nearest
    /// vertex; one wholly outside gives nothing; one wholly inside gives its vertices' range.
    #[test]
    fn clipped_depth_range_is_the_depth_inside_the_window() {
        let window = |lo: f64, hi: f64| -> [Plane; 4] {
            [
                [1.0, 0.0, -lo, 0.0],
                [-1.0, 0.0, hi, 0.0],
                [0.0, 1.0, -lo, 0.0],
                [0.0, -1.0, hi, 0.0],
            ]
        };
        // A plane x = 1 (light space) from z = 0.01 to z = 10: inside |x/z| <= 0.5 only for
        // z >= 2.
        let t = [
            Vec3::new(1.0, -0.1, 0.01),
            Vec3::new(1.0, 0.1, 0.01),
            Vec3::new(1.0, 0.0, 10.0),
        ];
        let (a, b) = clipped_depth_range(&t, &window(-0.5, 0.5)).unwrap();
        assert!((a - 2.0).abs() < 1e-3, "near {a}");
        assert!((b - 10.0).abs() < 1e-3, "far {b}");
        assert!(clipped_depth_range(&t, &window(-0.05, 0.05)).is_none());
        let inside = [
            Vec3::new(0.0, 0.0, 1.0),
            Vec3::new(0.1, 0.0, 2.0),
            Vec3::new(0.0, 0.1, 3.0),
        ];
        let (a, b) = clipped_depth_range(&inside, &window(-1.0, 1.0)).unwrap();
        assert!(
            (0.9999..=1.0).contains(&a) && (3.0..3.0001).contains(&b),
            "{a} {b}"
        );
    }

    /// The occluder hull holds every segment from the light to a receiver (sampled), and a point
    /// beside the light, off every such segment, lies outside it.
    #[test]
    fn occluder_hull_holds_every_light_to_receiver_segment() {
        let half = DVec2::new(0.5, 0.3);
        let rec: Vec<(DVec2, f64)> = [(0.2, -0.1, 2.0), (-1.5, 0.4, 5.0), (3.0, 2.0, 0.7)]
            .iter()
            .map(|&(x, y, z)| (DVec2::new(x, y) / z, z))
            .collect();
        let hull = occluder_hull(&rec, half);
        let inside = |p: DVec3| {
            hull.iter()
                .all(|pl| pl[0] * p.x + pl[1] * p.y + pl[2] * p.z + pl[3] >= -1e-9)
        };
        for &(t, z) in &rec {
            let p = (t * z).extend(z);
            for cx in [-1.0, 0.0, 1.0] {
                for cy in [-1.0, 0.0, 1.0] {
                    let c = DVec3::new(cx * half.x, cy * half.y, 0.0);
                    for k in 0..=10 {
                        let s = k as f64 / 10.0;
                        assert!(inside(c + (p - c) * s), "segment point {s} to {p}");
                    }
                }
            }
        }
        // Beside the light at a small depth: between no receiver and the light.
        assert!(!inside(DVec3::new(3.0, 0.0, 0.01)));
    }

    /// A ground running past the light's plane (the backlit-stone kind) no longer pulls the near
    /// plane down to where it crosses: the near plane is the nearest geometry that can shadow a
    /// receiver.
    #[test]
    fn a_ground_past_the_light_plane_does_not_set_the_near_plane() {
        let path = format!(
            "{}/../../fixtures/backlit-stone/backlit-stone.toml",
            env!("CARGO_MANIFEST_DIR")
        );
        let scene = Scene::load(&path).unwrap();
        let bvh = crate::bvh::SceneBvh::new(&scene);
        let rec = Receivers::from_camera(&scene, &bvh);
        let light = scene.light();
        let (view, _) =
            LightView::fit(&scene, &rec, light.frame(), light.half_extent(), 256).unwrap();
        // The ground crosses the light's plane: its nearest vertex in front of the light is a
        // few 1e-4 deep; the nearest geometry that matters is far deeper.
        assert!(view.n > 0.01, "near {}", view.n);
    }
}
