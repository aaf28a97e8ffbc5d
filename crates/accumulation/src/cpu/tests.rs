//! Unit tests of the CPU estimator's ring kernel ([`super::for_each_ring_cell`]).
use super::*;

/// The rings tile their bound exactly: every texel in exactly one cell, single texels next
/// to the centre, unclipped cells aligned to their side in lattice indices (map index plus
/// phase).
#[test]
fn ring_cells_tile_the_bound_once() {
    for phase in [[0, 0], [1, 3], [5, (1 << 20) - 1]] {
        for (bound, c, m) in [
            ([0, 0, 37, 29], [11, 13], 3),
            ([5, 7, 300, 90], [200, 40], 1),
            ([0, 0, 8, 8], [4, 4], 3),
            ([10, 10, 200, 200], [10, 199], 2),
        ] {
            let (w, h) = (
                (bound[2] - bound[0]) as usize,
                (bound[3] - bound[1]) as usize,
            );
            let mut hits = vec![0u32; w * h];
            let mut cells = 0;
            let mut aligned = 0;
            for_each_ring_cell(bound, c, m, phase, |i0, i1, j0, j1| {
                cells += 1;
                for j in j0..j1 {
                    for i in i0..i1 {
                        hits[(j - bound[1]) as usize * w + (i - bound[0]) as usize] += 1;
                    }
                }
                if (c[0] - m..c[0] + m).contains(&i0) && (c[1] - m..c[1] + m).contains(&j0) {
                    assert_eq!(
                        (i1 - i0, j1 - j0),
                        (1, 1),
                        "cell near the centre is a texel"
                    );
                }
                let side = i1 - i0;
                if side > 1 && i0 > bound[0] && i1 < bound[2] {
                    assert_eq!((i0 + phase[0]) % side, 0, "{phase:?}: cell at {i0}");
                    aligned += 1;
                }
                false
            });
            assert!(
                hits.iter().all(|&h| h == 1),
                "{bound:?} {c:?} {m} {phase:?}"
            );
            assert!(cells <= w * h, "{cells} cells for {} texels", w * h);
            assert!(aligned > 0 || w <= 8, "{bound:?}: no coarse cell checked");
        }
    }
}

/// Moving the map's corner by t texels on a fixed lattice (bound and centre by -t in map
/// indices, the phase by +t) gives the same cells, moved by -t: the `fit=stable` property.
#[test]
fn ring_cells_follow_the_lattice_not_the_map() {
    let cells = |bound: [i32; 4], c: [i32; 2], phase: [i32; 2]| {
        let mut v = Vec::new();
        for_each_ring_cell(bound, c, 2, phase, |i0, i1, j0, j1| {
            v.push([i0, i1, j0, j1]);
            false
        });
        v
    };
    let (bound, c) = ([20, 30, 220, 200], [90, 120]);
    let base = cells(bound, c, [7, 12]);
    for t in [1, 3, 5, 17] {
        let moved = cells(
            [bound[0] - t, bound[1] - t, bound[2] - t, bound[3] - t],
            [c[0] - t, c[1] - t],
            [7 + t, 12 + t],
        );
        let back: Vec<[i32; 4]> = moved
            .iter()
            .map(|q| [q[0] + t, q[1] + t, q[2] + t, q[3] + t])
            .collect();
        assert_eq!(back, base, "shift {t}");
        // Without the phase the cells would change (odd shifts re-align the coarse cells).
        if t % 2 == 1 {
            let unphased = cells(
                [bound[0] - t, bound[1] - t, bound[2] - t, bound[3] - t],
                [c[0] - t, c[1] - t],
                [7, 12],
            );
            assert_ne!(unphased, moved, "shift {t}");
        }
    }
}
