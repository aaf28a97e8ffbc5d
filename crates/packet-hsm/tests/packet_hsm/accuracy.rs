//! The contour estimator against closed forms (docs/methods.md §10), the micropatch estimator on
//! flat occluders, and the hard cases (touching occluders, the map border, stacked squares).
use crate::common;
use backprojection::CpuBackprojection;
use baselines::HardShadow;
use common::*;
use glam::Vec3;
use packet_hsm::cpu::SubView;
use packet_hsm::settings::Config;
use shadow_map_core::{run, Error, LightShape, Receivers, Scene, SoftShadowEstimator};
use test_support::fixtures::assert_opacity_weighted;

/// World size on the light plane of one texel at the occluder depth seen from the receiver:
/// `S = k z_o z_p / (z_p - z_o)`, `k = w / (n r)`.
fn texel_on_light(scene: &Scene, r: &Receivers, res: u32, zo: f32, zp: f32) -> f64 {
    let cfg = Config::from_params(hsm(&[]).params()).unwrap();
    let sv = SubView::build(
        scene,
        r,
        (res, glam::Vec2::ZERO, scene.light().half_extent()),
        &cfg,
        packet_hsm::cpu::OwnPlane::Auto,
    )
    .unwrap();
    let v = sv.ls.view;
    let k = v.delta() / v.n;
    (k * zo * zp / (zp - zo)) as f64
}

/// A fronto-parallel square occluder: contour vertices lie on texel boundaries, within half a
/// texel of the true edge, so `|dV| <= S / (2 l)` (one edge inside the light at a time for these
/// receivers; the corner cut of marching squares is inside that strip). 1e-4 float slack.
#[test]
fn flat_occluder_matches_the_closed_form() {
    let s = scene_with(rect_light(1.0, 3.0), &[SQUARE], 8, 8);
    let r = line_receivers();
    let o = oracle(&s, &[SQUARE], &r);
    let mut maxes = Vec::new();
    for res in [128u32, 256, 512] {
        let (v, _) = run(&mut hsm(&[("resolution", &res.to_string())]), &s, &r).unwrap();
        let bound = texel_on_light(&s, &r, res, 1.5, 3.0) / 2.0 + 1e-4;
        let (rms, max) = errors(&v, &o);
        eprintln!("flat occluder r={res}: rms {rms:.5} max {max:.5} bound {bound:.5}");
        assert!(max <= bound, "r={res}: {max} > {bound}");
        maxes.push(max);
    }
    assert!(maxes[2] < maxes[0], "{maxes:?}");
}

/// A disk light (radius 0.5, 3 above the ground) over the fronto-parallel square: the closed form
/// is the area of the square's projection inside the disk
/// (`reference::oracle::polygon_occluder_disk_visibility`, via `oracle_disk`). As for the rect
/// light the contour lies within half a texel strip `S / 2` of the true edge, and moving an edge
/// by `S / 2` changes the occluded area of the disk by at most `S / 2 * 2R`: `|dV| <= S / (pi R)`,
/// asserted with 1e-4 slack, and RMSE <= 0.02. Packets and per pixel alike.
#[test]
fn disk_light_matches_the_closed_form() {
    let mut light = rect_light(1.0, 3.0);
    let rad = 0.5f32;
    light.shape = LightShape::Disk { radius: rad };
    let s = scene_with(light, &[SQUARE], 8, 8);
    let r = line_receivers();
    let o = test_support::fixtures::oracle_disk(&s, SQUARE, &r);
    let mut maxes = Vec::new();
    for res in [128u32, 256, 512] {
        let bound =
            texel_on_light(&s, &r, res, 1.5, 3.0) / (std::f64::consts::PI * rad as f64) + 1e-4;
        for p in ["1x1", "3x3"] {
            let v = hsm_v(&[("resolution", &res.to_string()), ("packet", p)], &s, &r);
            assert_valid(&v, "disk light");
            let (rms, max) = errors(&v, &o);
            eprintln!("disk light r={res} {p}: rms {rms:.5} max {max:.5} bound {bound:.5}");
            assert!(max <= bound, "r={res} {p}: max error {max} > bound {bound}");
            assert!(rms <= 0.02, "r={res} {p}: RMSE {rms}");
            maxes.push(max);
        }
    }
    assert!(maxes[4] < maxes[0], "{maxes:?}");
}

/// A semi-transparent square (opacity 0.4) over the opaque ground: two opacity levels, all casters
/// with weight 0.4 and the ground alone (which shadows none of its own receivers) with 0.6, so
/// V = 1 - 0.4 (1 - V_opaque) receiver by receiver, packets and per pixel, to 1e-5. With every
/// mesh at 0.5 (no opaque mesh) the second level has no caster at all and V = 1 - 0.5 (1 -
/// V_opaque) still. Three distinct opacities exceed the default `opacity_levels=2`: treated as
/// opaque, and the report says so.
#[test]
fn semi_transparent_occluders_by_opacity_levels() {
    let s1 = scene_with(rect_light(1.0, 3.0), &[SQUARE], 8, 8);
    let r = line_receivers();
    for p in ["1x1", "3x3"] {
        let kv = [("resolution", "256"), ("packet", p)];
        let v1 = hsm_v(&kv, &s1, &r);
        let mut s4 = s1.clone();
        s4.set_mesh_opacity(1, 0.4).unwrap();
        let mut e = hsm(&kv);
        let (v4, rep) = run(&mut e, &s4, &r).unwrap();
        assert_eq!(
            test_support::fixtures::note_as::<u32>(&rep, "opacity_levels_run"),
            2
        );
        let mut all = s1.clone();
        for k in 0..all.meshes().len() {
            all.set_mesh_opacity(k, 0.5).unwrap();
        }
        let v5 = hsm_v(&kv, &all, &r);
        let penumbra = assert_opacity_weighted(&v4, &v1, 0.4, &r, p);
        assert_opacity_weighted(&v5, &v1, 0.5, &r, p);
        assert!(penumbra > 0, "{p}: no penumbra");
    }
    let mut s3 = scene_with(
        rect_light(1.0, 3.0),
        &[SQUARE, (1.0, -0.5, 1.5, 0.5, 1.2)],
        8,
        8,
    );
    s3.set_mesh_opacity(1, 0.4).unwrap();
    s3.set_mesh_opacity(2, 0.7).unwrap();
    let (v, rep) = run(&mut hsm(&[("resolution", "128")]), &s3, &r).unwrap();
    assert_valid(&v, "three opacities");
    assert_eq!(
        rep.warnings,
        vec![shadow_map_core::Warning::OpacityLevelsCapped {
            needed: 3,
            allowed: 2
        }]
    );
    let (v8, rep8) = run(
        &mut hsm(&[("resolution", "128"), ("opacity_levels", "8")]),
        &s3,
        &r,
    )
    .unwrap();
    assert_valid(&v8, "three opacities, three levels");
    assert!(rep8.warnings.is_empty(), "{:?}", rep8.warnings);
}

/// A sphere light (radius 0.4, 3 above the ground) over the square, against the ray-traced
/// reference at 4096 samples (noise about 0.008 at V = 0.5): each receiver's edges are carried
/// onto its own silhouette disk (docs/methods.md §3 "Sphere lights"). RMSE <= 0.02, packets and
/// per pixel alike.
#[test]
fn sphere_light_matches_the_reference() {
    let (s, r, truth) = sphere_light_over_square();
    for p in ["1x1", "3x3"] {
        let v = hsm_v(&[("resolution", "512"), ("packet", p)], &s, &r);
        assert_rmse_within(&format!("sphere light r=512 {p}"), &v, &truth, 0.02);
    }
}

/// Flat occluders: the contour and the micropatches have the same straight edges (texel
/// boundaries); they differ only by the marching-squares corner cuts (1/8 texel each, four
/// corners): `|dV| <= 4 S^2 / (8 l^2)` plus float slack.
#[test]
fn flat_occluder_matches_micropatches() {
    let occ = [SQUARE, (1.2, -0.3, 1.6, 0.4, 0.9)];
    let s = scene_with(rect_light(1.0, 3.0), &occ, 8, 8);
    let r = line_receivers();
    // (At r = 256 the micropatch kernel passes max_nspp = 4096 and its adaptive step changes it.)
    for res in [64u32, 128] {
        let mut bp = CpuBackprojection::new().unwrap();
        bp.set_param("resolution", &res.to_string()).unwrap();
        bp.set_param("layers", "1").unwrap();
        bp.set_param("max_nspp", "4096").unwrap();
        // Exact micropatch areas (bits would add their quantisation).
        bp.set_param("occlusion", "additive").unwrap();
        let (vb, _) = run(&mut bp, &s, &r).unwrap();
        let (vc, _) = run(&mut hsm(&[("resolution", &res.to_string())]), &s, &r).unwrap();
        let st = texel_on_light(&s, &r, res, 1.5, 3.0).max(texel_on_light(&s, &r, res, 2.1, 3.0));
        let bound = 0.5 * st * st + 1e-4;
        let max = vb
            .iter()
            .zip(&vc)
            .map(|(a, b)| (a - b).abs() as f64)
            .fold(0.0, f64::max);
        eprintln!("contour vs micropatch r={res}: max {max:.6} bound {bound:.6}");
        assert!(max <= bound, "r={res}: {max} > {bound}");
    }
}

/// Light size -> 0: V equals the hard shadow away from the hard edge (docs/methods.md §10 item 4).
#[test]
fn tiny_light_converges_to_hard_shadows() {
    let s = scene_with(rect_light(1e-4, 3.0), &[SQUARE], 8, 8);
    let r = line_receivers();
    let mut hard = HardShadow::new().unwrap();
    hard.set_param("resolution", "512").unwrap();
    let vh = run(&mut hard, &s, &r).unwrap().0;
    let v = hsm_v(&[("resolution", "512")], &s, &r);
    let foot = texel_on_light(&s, &r, 512, 3.0 - 1e-3, 3.0) * 1e-3; // ~ one texel on the ground
    let mut compared = 0;
    for k in 0..r.len() {
        let x = r.position()[k].x;
        if (x + 1.0).abs() > 0.02 && (x - 1.0246).abs() > 0.02 {
            assert!((v[k] - vh[k]).abs() < 1e-6, "x={x}: {} vs {}", v[k], vh[k]);
            compared += 1;
        }
    }
    assert!(compared > 200, "{compared} {foot}");
}

/// An occluder touching the receiver. 1e-5 above: closer than the peeling epsilon and the bias
/// can resolve (no shadow-map method separates it from the ground), so only finite V in [0, 1] is
/// asserted. 0.05 above (a few texel footprints): a hard shadow, V = oracle away from the edges.
#[test]
fn occluder_touching_the_receiver() {
    let r = line_receivers();
    for gap in [1e-5f32, 0.05] {
        let occ = (-0.5, -0.5, 0.5, 0.5, gap);
        let s = scene_with(rect_light(1.0, 3.0), &[occ], 8, 8);
        let o = oracle(&s, &[occ], &r);
        for ss in ["midpoint", "bias"] {
            let v = hsm_v(&[("resolution", "256"), ("self_shadow", ss)], &s, &r);
            assert_valid(&v, "touching");
            if gap < 1e-3 {
                continue;
            }
            for k in 0..r.len() {
                let x = r.position()[k].x;
                if (x.abs() - 0.5).abs() > 0.05 {
                    assert!(
                        (v[k] as f64 - o[k]).abs() < 1e-3,
                        "{ss} x={x}: {} vs {}",
                        v[k],
                        o[k]
                    );
                }
            }
        }
    }
}

/// The receiver's projection exactly on a contour edge or a sample centre: the nudge keeps V
/// continuous (equal to its neighbours' limit) and finite.
#[test]
fn contour_through_the_receiver() {
    let s = scene_with(rect_light(0.5, 3.0), &[SQUARE], 8, 8);
    let r0 = line_receivers();
    let cfg = Config::from_params(hsm(&[]).params()).unwrap();
    let sv = SubView::build(
        &s,
        &r0,
        (128, glam::Vec2::ZERO, s.light().half_extent()),
        &cfg,
        packet_hsm::cpu::OwnPlane::Auto,
    )
    .unwrap();
    let view = sv.ls.view;
    // Receivers on the ground whose projections are u = integer (a contour vertex column) and
    // u = i + 1/2 (a sample centre), next to the occluder's edge x = 0.5123 (u of that edge).
    let f = view.frame;
    let mut pts = Vec::new();
    let edge = view.project(f.to_light(Vec3::new(0.5123, 1.5, 0.13)));
    for du in [0.0f32, 0.5, -0.5, 1.0] {
        let u = edge.x.floor() + du;
        for eps in [0.0f32, 1e-3, -1e-3] {
            // Ground point projecting to texel column u + eps at v of the line.
            let dir = view.unproject_dir(glam::Vec2::new(u + eps, edge.y.floor() + 0.5));
            let pl = dir * (f.to_light(Vec3::ZERO).z / dir.z);
            pts.push(f.to_world(pl));
        }
    }
    let rr = Receivers::from_points(pts.clone(), vec![Vec3::Y; pts.len()]).unwrap();
    let v = hsm_v(&[("resolution", "128")], &s, &rr);
    assert_valid(&v, "on the contour");
    for c in v.chunks(3) {
        // The exact hit is between (or within 1e-3 of) its two neighbours 1e-3 texel away.
        let (lo, hi) = (c[1].min(c[2]), c[1].max(c[2]));
        assert!(c[0] >= lo - 1e-3 && c[0] <= hi + 1e-3, "{c:?}");
    }
}

/// Receivers at the shadow-map border and huge kernels (occluder almost at the light): finite,
/// V in [0, 1], and the map border closes contours (an occluder cut by the border still shadows).
#[test]
fn border_and_huge_kernels() {
    let r = line_receivers();
    // Occluder almost touching the light: kernels span the whole map.
    let s = scene_with(
        rect_light(1.0, 3.0),
        &[(-0.5, -0.5, 0.5, 0.5, 3.0 - 1e-4)],
        8,
        8,
    );
    for h in ["true", "false"] {
        let v = hsm_v(&[("resolution", "128"), ("hierarchy", h)], &s, &r);
        assert_valid(&v, "huge kernels");
    }
    // Border: the line's ends are the extreme receivers, so they sit at the map's border.
    let s = scene_with(rect_light(1.0, 3.0), &[SQUARE], 8, 8);
    let v = hsm_v(&[("resolution", "64")], &s, &r);
    assert_valid(&v, "border");
    let o = oracle(&s, &[SQUARE], &r);
    assert!((v[0] as f64 - o[0]).abs() < 0.05 && (v[240] as f64 - o[240]).abs() < 0.05);
    // Behind the light and on its plane: 0; inactive: NaN.
    let mut pts = r.position().to_vec();
    pts.extend([Vec3::new(0.0, 5.0, 0.0), Vec3::new(0.2, 3.0, 0.1)]);
    let mut rr = Receivers::from_points(pts.clone(), vec![Vec3::Y; pts.len()]).unwrap();
    rr.active_mut()[3] = false;
    let v = hsm_v(&[("resolution", "64"), ("sublights", "2")], &s, &rr);
    assert!(v[3].is_nan());
    assert_eq!(v[v.len() - 2], 0.0);
    assert_eq!(v[v.len() - 1], 0.0);
}

/// Two stacked squares: one shadow map misses the far occluder behind the near one (the single
/// light sample artifact, Yang §5); S = 2 sub-lights see around it and reduce the error.
#[test]
fn sublights_reduce_the_single_view_error() {
    let occ: [Occ; 2] = [(-0.3, -0.3, 0.3, 0.3, 2.4), (-0.5, -0.5, 0.5, 0.5, 1.2)];
    let s = scene_with(rect_light(1.0, 3.0), &occ, 8, 8);
    let r = line_receivers();
    let o = oracle(&s, &occ, &r);
    let mut rm = Vec::new();
    for sl in ["1", "2", "4"] {
        let v = hsm_v(&[("resolution", "256"), ("sublights", sl)], &s, &r);
        let (rms, max) = errors(&v, &o);
        eprintln!("stacked squares S={sl}: rmse {rms:.5} max {max:.5}");
        rm.push(rms);
    }
    assert!(rm[1] < rm[0] && rm[2] < rm[0], "{rm:?}");
}

/// Bad input: disk and sphere lights cut into sub-lights and out-of-range parameters are errors
/// naming the key.
#[test]
fn bad_input() {
    for (shape, sl, want) in [
        (LightShape::Sphere { radius: 0.5 }, "2", "sublights"),
        (LightShape::Disk { radius: 0.5 }, "4", "sublights"),
    ] {
        let mut light = rect_light(1.0, 3.0);
        light.shape = shape;
        let s = scene_with(light, &[SQUARE], 8, 8);
        let err = run(&mut hsm(&[("sublights", sl)]), &s, &line_receivers()).unwrap_err();
        assert!(
            matches!(&err, Error::Param { key, .. } if key == want),
            "{err}"
        );
    }
    let mut e = packet_hsm::CpuPacketHsm::new().unwrap();
    for (k, v) in [
        ("packet", "9x1"),
        ("packet", "0x2"),
        ("packet", "4"),
        ("sublights", "5"),
        ("td", "1.5"),
    ] {
        let err = e.set_param(k, v).unwrap_err();
        assert!(
            matches!(&err, Error::Param { key, .. } if key == k),
            "{err}"
        );
    }
    let mut v = vec![0.0; 3];
    let s = scene_with(rect_light(1.0, 3.0), &[SQUARE], 8, 8);
    assert!(e.estimate(&s, &line_receivers(), &mut v).is_err());
}

/// Receiver-plane rejection: an unoccluded plane lit at 85 degrees from its normal,
/// at the defaults, is never shadowed by its own samples: every receiver keeps V >= facing - 0.02,
/// with midpoints and with the bias. Without the plane test (`receiver_plane=false`) the
/// kernel's texels of the receiver's own surface nearer the light shadow it.
#[test]
fn grazing_plane_is_not_self_shadowed() {
    test_support::fixtures::assert_grazing_plane_lit(hsm);
}
