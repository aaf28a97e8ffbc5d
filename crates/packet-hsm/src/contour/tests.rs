//! Unit tests of the contour module: sector areas, cell edges, exact full/empty cover and
//! hierarchical against flat extraction.
use super::*;

fn grid_of(r: u32, mut f: impl FnMut(i32, i32) -> f32) -> Vec<f32> {
    let mut d = vec![f32::INFINITY; (r * r) as usize];
    for j in 0..r as i32 {
        for i in 0..r as i32 {
            d[(j * r as i32 + i) as usize] = f(i, j);
        }
    }
    d
}

#[test]
fn sector_of_full_turn_is_light_area() {
    let h = DVec2::new(0.7, 0.3);
    // Four quarter turns around the origin.
    let pts = [
        DVec2::new(1.0, 0.1),
        DVec2::new(-0.1, 1.0),
        DVec2::new(-1.0, -0.1),
        DVec2::new(0.1, -1.0),
    ];
    let s: f64 = (0..4)
        .map(|i| sector_rect(pts[i], pts[(i + 1) % 4], h))
        .sum();
    assert!((s - 4.0 * h.x * h.y).abs() < 1e-12, "{s}");
    // Reversed sweep is negative.
    let s2 = sector_rect(pts[1], pts[0], h);
    assert!((s2 + sector_rect(pts[0], pts[1], h)).abs() < 1e-12);
}

/// The trigonometry-free sector equals the angle-based one on random sweeps, including
/// corners on the sweep's rays and sweeps near a half turn.
#[test]
fn sector_fast_path_matches_angles() {
    let mut seed = 99u64;
    let mut rnd = || {
        seed = seed
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (seed >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
    };
    for k in 0..20000 {
        let h = DVec2::new(0.1 + rnd().abs(), 0.1 + rnd().abs());
        let a = DVec2::new(rnd(), rnd()) * 3.0;
        let b = match k % 4 {
            0 => DVec2::new(h.x, -h.y) * (1.0 + rnd().abs()), // on a corner's ray
            1 => -a + DVec2::new(rnd(), rnd()) * 1e-9,        // nearly a half turn
            _ => DVec2::new(rnd(), rnd()) * 3.0,
        };
        let (f, r) = (sector_rect(a, b, h), sector_rect_by_angle(a, b, h));
        assert!(
            (f - r).abs() <= 1e-12 * (1.0 + h.x * h.y),
            "{a} {b} {h}: {f} vs {r}"
        );
    }
}

#[test]
fn cell_edges_orientation() {
    // Only c0 occludes: the edge cuts corner c0 with c0 on the left.
    let (e, n) = cell_edges(0, 0, [true, false, false, false], [1.0; 4]);
    assert_eq!(n, 1);
    let c0 = DVec2::new(0.5, 0.5);
    assert!(side(&e[0], c0) > 0.0);
    assert!(side(&e[0], DVec2::new(1.5, 1.5)) < 0.0);
    // Saddle: two edges, each cutting a free corner.
    let (e, n) = cell_edges(0, 0, [true, false, true, false], [1.0; 4]);
    assert_eq!(n, 2);
    for ed in &e[..2] {
        assert!(
            side(ed, DVec2::new(1.0, 1.0)) > 0.0,
            "centre occluded (connected)"
        );
    }
}

#[test]
fn full_cover_and_empty_are_exact() {
    let r = 16;
    let d = grid_of(r, |_, _| 1.0);
    let g = SampleGrid {
        size: r,
        depth: &d,
        class: &d,
    };
    let dm = PaddedDualMssm::build(&d, r, r + 2);
    let rec = Receiver::new(&g, DVec2::new(8.3, 8.1), 2.0, 2.0);
    assert!(rec.centre);
    let h = &Emitter::Rect(DVec2::new(0.5, 0.5));
    for t in [Traversal::Flat, Traversal::Hierarchical] {
        // Kernel inside the map: no edges, centre occluded.
        let (v, _) = pixel_visibility(&g, &dm, None, None, &[4, 4, 12, 12], &rec, 0.01, h, t);
        assert_eq!(v, 0.0);
        // Threshold below every sample: lit.
        let rec2 = Receiver::new(&g, DVec2::new(8.3, 8.1), 2.0, 0.5);
        let (v, _) = pixel_visibility(&g, &dm, None, None, &[-1, -1, 16, 16], &rec2, 0.01, h, t);
        assert_eq!(v, 1.0);
    }
}

#[test]
fn hierarchical_equals_flat_on_random_maps() {
    let r = 24u32;
    let mut seed = 12345u64;
    let mut rnd = || {
        seed = seed
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((seed >> 33) as f64 / (1u64 << 31) as f64) as f32
    };
    for _ in 0..20 {
        let d = grid_of(r, |_, _| 1.0 + rnd());
        let g = SampleGrid {
            size: r,
            depth: &d,
            class: &d,
        };
        let dm = PaddedDualMssm::build(&d, r, r + 2);
        // Levels capped below the kernel's span: the kernel is tiled with top-level roots.
        let capped = PaddedDualMssm::build(&d, r, 4);
        assert_eq!(capped.mssm.levels(), 3);
        let uv = DVec2::new(1.0 + 22.0 * rnd() as f64, 1.0 + 22.0 * rnd() as f64);
        let rec = Receiver::new(&g, uv, 3.0, 1.5);
        let cr = [-1, 2, 20, 24];
        for h in [&Emitter::Rect(DVec2::new(0.4, 0.6)), &Emitter::Disk(0.45)] {
            let (vf, nf) =
                pixel_visibility(&g, &dm, None, None, &cr, &rec, 0.02, h, Traversal::Flat);
            let (vh, _) = pixel_visibility(
                &g,
                &dm,
                None,
                None,
                &cr,
                &rec,
                0.02,
                h,
                Traversal::Hierarchical,
            );
            let (vc, _) = pixel_visibility(
                &g,
                &capped,
                None,
                None,
                &cr,
                &rec,
                0.02,
                h,
                Traversal::Hierarchical,
            );
            assert!((vf - vh).abs() < 1e-6, "{vf} {vh}");
            assert!((vf - vc).abs() < 1e-6, "{vf} {vc}");
            assert_eq!(nf, 21 * 22);
        }
    }
}
