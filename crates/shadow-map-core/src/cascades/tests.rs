/// Direction tiles: receivers spread over tan-space [-8, 8] x [-1, 1] under a light looking
/// down. `tiles=0` splits only when asked by the density, into tiles of at most `tile_span`
/// (or 8 of them), `tiles=k` gives k, receivers behind the light go to tile 0, and every tile
/// holds receivers.
#[test]
fn direction_tiles_split_wide_receiver_sets() {
    use crate::light::{Light, LightShape};
    use glam::Vec3;
    let light = Light {
        shape: LightShape::Rect { size: [1.0, 1.0] },
        center: Vec3::new(0.0, 10.0, 0.0),
        normal: -Vec3::Y,
        tangent: Vec3::X,
    };
    let mut pos = Vec::new();
    for a in 0..=64 {
        for b in 0..=8 {
            // Light space: x = world x, y = world z (or its negative), z = 10 - world y.
            pos.push(Vec3::new(
                -8.0 + a as f32 * 0.25,
                9.0,
                -1.0 + b as f32 * 0.25,
            ));
        }
    }
    pos.push(Vec3::new(0.0, 11.0, 0.0)); // behind the light
    let n = pos.len();
    let rec = Receivers::from_points(pos, vec![Vec3::Y; n]).unwrap();
    let mut scene = crate::scene::Scene::from_meshes(
        "tiles",
        Camera {
            eye: Vec3::new(0.0, 5.0, 5.0),
            target: Vec3::ZERO,
            up: Vec3::Y,
            fov_y_deg: 45.0,
            width: 8,
            height: 8,
        },
        light,
        vec![(vec![[Vec3::ZERO, Vec3::X, Vec3::Z]], 1.0)],
    )
    .unwrap();
    scene.set_light(light).unwrap();
    let settings = |tiles: u32| CascadeSettings {
        cascades: 0,
        cascade_lambda: 0.75,
        cascade_blend: 0.1,
        tiles,
        tile_span: 2.0,
        casters: Casters::Off,
    };
    let dense = || Some(5.0);
    assert_eq!(
        direction_tiles(&settings(0), &scene, &rec, || Some(1.5)).count,
        1
    );
    assert_eq!(direction_tiles(&settings(1), &scene, &rec, dense).count, 1);
    let t = direction_tiles(&settings(0), &scene, &rec, dense);
    assert_eq!(t.count, 8, "16 wide over a span of 2: the cap");
    let t4 = direction_tiles(&settings(4), &scene, &rec, dense);
    assert_eq!(t4.count, 4);
    for t in [&t, &t4] {
        let mut seen = vec![0usize; t.count];
        for &k in &t.of {
            seen[k as usize] += 1;
        }
        assert!(seen.iter().all(|&s| s > 0), "an empty tile: {seen:?}");
        assert_eq!(t.of[n - 1], 0, "behind the light: tile 0");
    }
    // A narrow set keeps one tile.
    let narrow =
        Receivers::from_points(vec![Vec3::new(0.5, 0.0, 0.5); 3], vec![Vec3::Y; 3]).unwrap();
    assert_eq!(
        direction_tiles(&settings(0), &scene, &narrow, dense).count,
        1
    );
}

use super::*;

#[test]
fn splits_run_from_near_to_far_and_mix_log_and_uniform() {
    let s = practical_splits(1.0, 16.0, 4, 1.0);
    for (a, b) in s.iter().zip([1.0, 2.0, 4.0, 8.0, 16.0]) {
        assert!((a - b).abs() < 1e-5, "{s:?}");
    }
    let u = practical_splits(1.0, 17.0, 4, 0.0);
    for (a, b) in u.iter().zip([1.0, 5.0, 9.0, 13.0, 17.0]) {
        assert!((a - b).abs() < 1e-5, "{u:?}");
    }
    let m = practical_splits(1.0, 16.0, 4, 0.5);
    assert!((m[1] - 0.5 * (2.0 + 4.75)).abs() < 1e-5, "{m:?}");
}

#[test]
fn auto_count_follows_the_depth_ratio() {
    let dense = || Some(6.0);
    assert_eq!(auto_count(1.0, 8.0, dense), 1);
    assert_eq!(auto_count(1.0, 8.1, dense), 2);
    assert_eq!(auto_count(1.0, 60.0, dense), 3);
    assert_eq!(auto_count(0.7, 190.0, dense), 4);
    assert_eq!(auto_count(0.0, 1.0, dense), 1);
    assert_eq!(auto_count(1.0, 60.0, || Some(1.9)), 1);
    assert_eq!(auto_count(1.0, 60.0, || None), 1);
}

#[test]
fn weights_sum_to_one_and_are_continuous() {
    let s = practical_splits(1.0, 64.0, 3, 0.75);
    let h = blend_half_widths(&s, 0.1);
    let mut last: Option<f32> = None;
    let mut d = 1.0f32;
    while d <= 64.0 {
        let w = cascade_weights(d, &s, &h);
        assert!((w[0].1 + w[1].1 - 1.0).abs() < 1e-6, "{d}: {w:?}");
        // The weight of cascade 0 as a function of d moves by at most the band's slope.
        let w0: f32 = w.iter().filter(|x| x.0 == 0).map(|x| x.1).sum();
        if let Some(l) = last {
            assert!((w0 - l).abs() <= 0.01 / (2.0 * h[1]) + 1e-4, "{d}");
        }
        last = Some(w0);
        d += 0.01;
    }
    assert_eq!(cascade_weights(1.0, &s, &h), [(0, 1.0), (0, 0.0)]);
    assert_eq!(cascade_weights(64.0, &s, &h)[0], (2, 1.0));
}

/// Light and camera both straight above a ground point, looking down: one texel covers
/// `(w / (n r)) H` on the ground, one pixel `2 tan(fov / 2) / height * Hc`.
#[test]
fn texel_density_has_its_closed_form_on_axis() {
    use crate::light::LightFrame;
    use glam::{Vec2, Vec3};
    let (h, hc) = (10.0f32, 4.0f32);
    let frame = LightFrame {
        origin: Vec3::new(0.0, h, 0.0),
        ex: Vec3::X,
        ey: Vec3::Z,
        ez: -Vec3::Y,
    };
    let view = LightView {
        frame,
        n: 1.0,
        far: 20.0,
        window_min: Vec2::splat(-0.5),
        w: 1.0,
        r: 100,
        projection: Default::default(),
    };
    let camera = Camera {
        eye: Vec3::new(0.0, hc, 0.0),
        target: Vec3::ZERO,
        up: Vec3::Z,
        fov_y_deg: 60.0,
        width: 80,
        height: 60,
    };
    let rec = Receivers::from_points(vec![Vec3::ZERO, Vec3::new(0.0, 0.0, 9.0)], vec![Vec3::Y; 2])
        .unwrap();
    let d = texel_density(&view, &camera, &rec);
    let want = (0.01 * h) / (2.0 * 30f32.to_radians().tan() / 60.0 * hc);
    assert!((d[0] - want).abs() < 1e-4 * want, "{} vs {want}", d[0]);
    assert!(d[1].is_nan(), "outside the window: {}", d[1]);
}

#[test]
fn median_and_p95_ignore_nan() {
    let d: Vec<f32> = (1..=100).map(|x| x as f32).chain([f32::NAN]).collect();
    let (m, p) = median_p95(&d).unwrap();
    assert!(
        (50.0..=51.0).contains(&m) && (95.0..=96.0).contains(&p),
        "{m} {p}"
    );
    assert!(median_p95(&[f32::NAN]).is_none());
}
