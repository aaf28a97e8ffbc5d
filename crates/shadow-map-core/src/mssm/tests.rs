//! Tests of every structure in [`super`] against [`super::brute_force`].
use super::*;
use proptest::prelude::*;

type Rect = (i32, i32, i32, i32);

fn depth_value() -> impl Strategy<Value = f32> {
    prop_oneof![4 => 0.1f32..100.0f32, 1 => Just(f32::INFINITY)]
}

fn rect(s: u32) -> BoxedStrategy<Rect> {
    let s = s as i32;
    prop_oneof![
        // Arbitrary corners: partly/fully outside, inverted, zero-sized.
        6 => (-8..s + 8, -8..s + 8, -8..s + 8, -8..s + 8),
        // Non-empty and inside.
        4 => (0..s, 0..s, 1..=s, 1..=s).prop_map(|(x, y, w, h)| (x, y, x + w, y + h)),
        1 => Just((0, 0, s, s)),
        1 => Just((-3, -5, s + 7, s + 2)),
        // Zero width / zero height.
        1 => (-8..s + 8, -8..s + 8, 0..s + 8).prop_map(|(x, y, h)| (x, y, x, y + h)),
        1 => (-8..s + 8, -8..s + 8, 0..s + 8).prop_map(|(x, y, w)| (x, y, x + w, y)),
        1 => Just((i32::MIN, i32::MIN, i32::MAX, i32::MAX)),
    ]
    .boxed()
}

/// (size, depth, max_level, rectangles)
fn case() -> impl Strategy<Value = (u32, Vec<f32>, u32, Vec<Rect>)> {
    (1u32..=70).prop_flat_map(|s| {
        (
            Just(s),
            prop::collection::vec(depth_value(), (s * s) as usize),
            0u32..=8,
            prop::collection::vec(rect(s), 1..12),
        )
    })
}

/// Clamp a dual-cell rectangle to anchors `[0, s)` and return the
/// brute-force min/max over the samples it touches.
fn brute_cells(depth: &[f32], s: u32, r: Rect) -> MinMax {
    let c = |v: i32| v.clamp(0, s as i32);
    let (x0, y0, x1, y1) = (c(r.0), c(r.1), c(r.2), c(r.3));
    if x0 >= x1 || y0 >= y1 {
        return MinMax::EMPTY;
    }
    brute_force(depth, s, x0, y0, x1 + 1, y1 + 1)
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    /// (a) + (b)
    #[test]
    fn mssm_levels_and_queries_match_brute_force((s, depth, max_level, rects) in case()) {
        let m = Mssm::build(&depth, s, max_level);
        prop_assert_eq!(m.size(), s);
        prop_assert_eq!(m.levels(), max_level.min(floor_log2(s as usize)) + 1);
        for l in 0..m.levels() {
            let w = 1i32 << l;
            let (lmin, lmax) = m.level(l);
            prop_assert_eq!(lmin.len(), (s * s) as usize);
            prop_assert_eq!(lmax.len(), (s * s) as usize);
            for y in 0..s {
                for x in 0..s {
                    let (xi, yi) = (x as i32, y as i32);
                    let want = brute_force(&depth, s, xi, yi, xi + w, yi + w);
                    let got = m.fetch(l, x, y);
                    prop_assert_eq!(got, want, "level {} texel ({}, {})", l, x, y);
                    let i = (y * s + x) as usize;
                    prop_assert_eq!(MinMax { min: lmin[i], max: lmax[i] }, want);
                }
            }
        }
        for r in rects {
            let want = brute_force(&depth, s, r.0, r.1, r.2, r.3);
            prop_assert_eq!(m.query(r.0, r.1, r.2, r.3), want, "rect {:?}", r);
            if want.is_empty() {
                prop_assert_eq!(m.fetch_count(r.0, r.1, r.2, r.3), 0);
            } else {
                prop_assert!(m.fetch_count(r.0, r.1, r.2, r.3) >= 1);
            }
        }
    }

    /// (c)
    #[test]
    fn dual_mssm_matches_brute_force((s, depth, max_level, rects) in case()) {
        let m = DualMssm::build(&depth, s, max_level);
        prop_assert_eq!(m.levels(), max_level.min(floor_log2(s as usize)) + 1);
        for l in 0..m.levels() {
            let w = 1i32 << l;
            for y in 0..s {
                for x in 0..s {
                    let (xi, yi) = (x as i32, y as i32);
                    // Inclusive sample window [x, x+2^l] x [y, y+2^l].
                    let want = brute_force(&depth, s, xi, yi, xi + w + 1, yi + w + 1);
                    prop_assert_eq!(m.fetch(l, x, y), want, "level {} anchor ({}, {})", l, x, y);
                }
            }
        }
        for r in rects {
            let want = brute_cells(&depth, s, r);
            prop_assert_eq!(m.query_cells(r.0, r.1, r.2, r.3), want, "cells {:?}", r);
        }
    }

    /// (d)
    #[test]
    fn pyramid_levels_exact_and_query_conservative((s, depth, _ml, rects) in case()) {
        let p = MinMaxPyramid::build(&depth, s);
        prop_assert_eq!(p.levels(), 1 + ceil_log2(s as usize));
        prop_assert_eq!(p.level_size(p.levels() - 1), 1);
        for l in 0..p.levels() {
            let n = p.level_size(l);
            prop_assert_eq!(n, s.div_ceil(1 << l));
            prop_assert_eq!(p.level(l).0.len(), (n * n) as usize);
            let b = 1i32 << l;
            for y in 0..n as i32 {
                for x in 0..n as i32 {
                    let want = brute_force(&depth, s, x * b, y * b, (x + 1) * b, (y + 1) * b);
                    prop_assert_eq!(p.fetch(l, x as u32, y as u32), want);
                }
            }
        }
        for r in rects {
            let truth = brute_force(&depth, s, r.0, r.1, r.2, r.3);
            let got = p.query(r.0, r.1, r.2, r.3);
            prop_assert!(got.contains(&truth), "rect {:?}: {:?} vs {:?}", r, got, truth);
            match p.covered_rect(r.0, r.1, r.2, r.3) {
                None => {
                    prop_assert!(truth.is_empty());
                    prop_assert_eq!(got, MinMax::EMPTY);
                    prop_assert_eq!(p.covered_texels(r.0, r.1, r.2, r.3), 0);
                }
                Some((a, b, c, d)) => {
                    let cov = brute_force(&depth, s, a as i32, b as i32, c as i32, d as i32);
                    prop_assert_eq!(got, cov);
                    let clamped = clamp_rect(s as usize, r.0, r.1, r.2, r.3).unwrap();
                    prop_assert!(a as usize <= clamped[0] && b as usize <= clamped[1]);
                    prop_assert!(c as usize >= clamped[2] && d as usize >= clamped[3]);
                    let (l, t) = p.plan(r.0, r.1, r.2, r.3).unwrap();
                    prop_assert!(t[2] - t[0] <= 1 && t[3] - t[1] <= 1, "level {} texels {:?}", l, t);
                    prop_assert_eq!(
                        p.covered_texels(r.0, r.1, r.2, r.3),
                        u64::from(c - a) * u64::from(d - b)
                    );
                }
            }
        }
    }

    /// (e)
    #[test]
    fn mssm_square_query_fetch_counts(
        (s, depth, squares) in (1u32..=70).prop_flat_map(|s| (
            Just(s),
            prop::collection::vec(depth_value(), (s * s) as usize),
            prop::collection::vec((0u32..=6, 1u32..=70, 0u32..70, 0u32..70), 1..16),
        ))
    ) {
        let m = Mssm::build(&depth, s, u32::MAX);
        for (k, w, ox, oy) in squares {
            // Power-of-two square inside the map: exactly one fetch.
            let p = 1u32 << k;
            if p <= s {
                let (x0, y0) = ((ox % (s - p + 1)) as i32, (oy % (s - p + 1)) as i32);
                let p = p as i32;
                prop_assert_eq!(m.fetch_count(x0, y0, x0 + p, y0 + p), 1);
                prop_assert_eq!(
                    m.query(x0, y0, x0 + p, y0 + p),
                    brute_force(&depth, s, x0, y0, x0 + p, y0 + p)
                );
            }
            // Any square inside the map: at most 4 fetches.
            let w = 1 + (w - 1) % s;
            let (x0, y0) = ((ox % (s - w + 1)) as i32, (oy % (s - w + 1)) as i32);
            let w = w as i32;
            let n = m.fetch_count(x0, y0, x0 + w, y0 + w);
            prop_assert!((1..=4).contains(&n), "square {} at ({}, {}): {} fetches", w, x0, y0, n);
            prop_assert_eq!(
                m.query(x0, y0, x0 + w, y0 + w),
                brute_force(&depth, s, x0, y0, x0 + w, y0 + w)
            );
        }
    }
}

#[test]
fn minmax_basics() {
    let e = MinMax::EMPTY;
    assert!(e.is_empty());
    assert!(e.is_unoccupied());
    assert_eq!(MinMax::empty(), e);
    assert_eq!(MinMax::default(), e);
    let a = MinMax::from_depth(2.0);
    assert_eq!(e.union(a), a);
    assert_eq!(a.union(e), a);
    let inf = MinMax::from_depth(f32::INFINITY);
    assert_eq!(
        inf,
        MinMax {
            min: f32::INFINITY,
            max: f32::INFINITY
        }
    );
    assert!(!inf.is_empty());
    assert!(inf.is_unoccupied());
    assert_eq!(inf.union(inf), inf);
    assert_eq!(
        a.union(inf),
        MinMax {
            min: 2.0,
            max: f32::INFINITY
        }
    );
    assert_eq!(MinMax::from_depth(f32::NAN), inf);
    assert!(a.contains(&e));
}

#[test]
fn all_empty_map_gives_inf_inf() {
    let s = 9u32;
    let d = vec![f32::INFINITY; 81];
    let inf = MinMax {
        min: f32::INFINITY,
        max: f32::INFINITY,
    };
    assert_eq!(brute_force(&d, s, 0, 0, 9, 9), inf);
    assert_eq!(Mssm::build(&d, s, 10).query(1, 2, 7, 5), inf);
    assert_eq!(DualMssm::build(&d, s, 10).query_cells(1, 2, 7, 5), inf);
    assert_eq!(MinMaxPyramid::build(&d, s).query(1, 2, 7, 5), inf);
}

#[test]
fn degenerate_inputs_do_not_panic() {
    // size 0
    let m = Mssm::build(&[], 0, 5);
    assert_eq!((m.levels(), m.size(), m.bytes()), (0, 0, 0));
    assert_eq!(m.query(0, 0, 10, 10), MinMax::EMPTY);
    assert_eq!(m.fetch_count(0, 0, 10, 10), 0);
    assert_eq!(m.fetch(0, 0, 0), MinMax::EMPTY);
    assert_eq!(m.level(0), (&[][..], &[][..]));
    let dm = DualMssm::build(&[], 0, 5);
    assert_eq!(dm.levels(), 0);
    assert_eq!(dm.query_cells(0, 0, 1, 1), MinMax::EMPTY);
    assert_eq!(dm.fetch_count(0, 0, 1, 1), 0);
    let p = MinMaxPyramid::build(&[], 0);
    assert_eq!((p.levels(), p.level_size(0)), (0, 0));
    assert_eq!(p.query(0, 0, 1, 1), MinMax::EMPTY);
    assert_eq!(p.covered_rect(0, 0, 1, 1), None);
    assert_eq!(brute_force(&[], 0, 0, 0, 1, 1), MinMax::EMPTY);

    // Length mismatch: missing texels are empty, extra ignored.
    let short = [1.0f32, 2.0, 3.0];
    let m = Mssm::build(&short, 2, 1);
    assert_eq!(m.fetch(0, 1, 1), MinMax::from_depth(f32::INFINITY));
    assert_eq!(
        m.query(0, 0, 2, 2),
        MinMax {
            min: 1.0,
            max: f32::INFINITY
        }
    );
    assert_eq!(brute_force(&short, 2, 0, 0, 2, 2), m.query(0, 0, 2, 2));
    let long = [1.0f32, 2.0, 3.0, 4.0, -100.0];
    let m = Mssm::build(&long, 2, 1);
    assert_eq!(m.query(0, 0, 2, 2), MinMax { min: 1.0, max: 4.0 });
    assert_eq!(
        MinMaxPyramid::build(&long, 2).query(0, 0, 2, 2),
        MinMax { min: 1.0, max: 4.0 }
    );
    assert_eq!(
        DualMssm::build(&long, 2, 3).query_cells(0, 0, 1, 1),
        MinMax { min: 1.0, max: 4.0 }
    );

    // Unaddressable size: empty structure instead of a panic.
    if usize::BITS == 64 {
        let m = Mssm::build(&short, u32::MAX, 3);
        assert_eq!(m.size(), 0);
        assert_eq!(m.query(0, 0, 5, 5), MinMax::EMPTY);
    }

    // Out-of-range fetches / levels.
    let d: Vec<f32> = (0..16).map(|i| i as f32).collect();
    let m = Mssm::build(&d, 4, 99);
    assert_eq!(m.levels(), 3);
    assert_eq!(m.fetch(3, 0, 0), MinMax::EMPTY);
    assert_eq!(m.fetch(0, 4, 0), MinMax::EMPTY);
    assert_eq!(
        m.fetch(2, 0, 0),
        MinMax {
            min: 0.0,
            max: 15.0
        }
    );
    assert_eq!(
        m.query(i32::MIN, i32::MIN, i32::MAX, i32::MAX),
        MinMax {
            min: 0.0,
            max: 15.0
        }
    );
    assert_eq!(m.query(3, 3, 1, 1), MinMax::EMPTY);
    assert_eq!(m.query(-5, -5, 0, 0), MinMax::EMPTY);
    assert_eq!(m.query(4, 0, 9, 4), MinMax::EMPTY);
    let p = MinMaxPyramid::build(&d, 4);
    assert_eq!(p.fetch(0, 4, 0), MinMax::EMPTY);
    assert_eq!(p.fetch(1, 2, 0), MinMax::EMPTY);
    assert_eq!(p.level_size(9), 0);
    let dm = DualMssm::build(&d, 4, 99);
    assert_eq!(dm.fetch(9, 0, 0), MinMax::EMPTY);
    assert_eq!(dm.fetch(0, 3, 3), MinMax::from_depth(15.0));
}

#[test]
fn memory_accounting() {
    let s = 16u32;
    let d = vec![1.0f32; 256];
    let m = Mssm::build(&d, s, 4);
    assert_eq!(m.levels(), 5);
    assert_eq!(m.bytes(), (2 * 5 - 1) * 256 * 4);
    let dm = DualMssm::build(&d, s, 4);
    assert_eq!(dm.bytes(), 2 * 5 * 256 * 4);
    let p = MinMaxPyramid::build(&d, s);
    assert_eq!(p.bytes(), (256 + 2 * (64 + 16 + 4 + 1)) * 4);
}

#[test]
fn single_texel_map() {
    let d = [3.5f32];
    let one = MinMax::from_depth(3.5);
    let m = Mssm::build(&d, 1, 4);
    assert_eq!(m.levels(), 1);
    assert_eq!(m.query(-1, -1, 2, 2), one);
    assert_eq!(m.fetch_count(-1, -1, 2, 2), 1);
    let dm = DualMssm::build(&d, 1, 4);
    assert_eq!(dm.query_cells(0, 0, 1, 1), one);
    let p = MinMaxPyramid::build(&d, 1);
    assert_eq!(p.levels(), 1);
    assert_eq!(p.query(0, 0, 1, 1), one);
    assert_eq!(p.covered_texels(0, 0, 5, 5), 1);
}

/// The refinement shrinks a kernel to the nearest caster depth it holds, stops when a round no
/// longer shrinks it, and rules the receiver lit when no texel can occlude.
#[test]
fn refine_kernel_shrinks_to_the_nearest_caster_and_rules_out_lit_receivers() {
    // A 16 x 16 map at depth 10 with one caster texel at depth 4.
    let mut depth = vec![10.0f32; 256];
    depth[8 * 16 + 8] = 4.0;
    let m = Mssm::build(&depth, 16, 4);
    // The kernel's half-width falls with the blocker depth z (as a penumbra estimate does).
    let kernel = |z: f32| {
        let h = (16.0 / z).ceil() as i32;
        [8 - h, 8 - h, 8 + h + 1, 8 + h + 1]
    };
    // From the near plane at 1: the wide kernel holds the caster at 4, so it shrinks to
    // kernel(4), which still holds it; the next round finds 4 again and stops.
    assert_eq!(
        refine_kernel(Some(&m), 1.0, kernel, |_| 9.0),
        Some(kernel(4.0))
    );
    // A threshold at or below the nearest caster: nothing in the kernel occludes.
    assert_eq!(refine_kernel(Some(&m), 1.0, kernel, |_| 4.0), None);
    // Without an MSSM the first kernel stands.
    assert_eq!(refine_kernel(None, 1.0, kernel, |_| 9.0), Some(kernel(1.0)));
}
