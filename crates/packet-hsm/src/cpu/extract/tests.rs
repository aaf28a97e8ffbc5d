//! Unit tests of the extraction: exact full and empty cover, and hierarchical against flat
//! extraction (with the MSSM's levels capped too).
use super::*;
use glam::DVec2;

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
            let vis = |dm: &PaddedDualMssm, t| {
                pixel_visibility(&g, dm, None, None, &cr, &rec, 0.02, h, t)
            };
            let (vf, nf) = vis(&dm, Traversal::Flat);
            let (vh, _) = vis(&dm, Traversal::Hierarchical);
            let (vc, _) = vis(&capped, Traversal::Hierarchical);
            assert!((vf - vh).abs() < 1e-6, "{vf} {vh}");
            assert!((vf - vc).abs() < 1e-6, "{vf} {vc}");
            assert_eq!(nf, 21 * 22);
        }
    }
}
