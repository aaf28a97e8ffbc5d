//! Percentage-closer soft transmittance (docs/methods.md §5 "PCSS, step by step", §8
//! "Percentage-closer soft transmittance"): PCSS's blocker search, penumbra estimate and filter
//! over any map that answers [`SoftTaps`] (a shadow map: PCSS; a deep shadow map's lists:
//! deep-shadow's `filter=pcss`), with the window splitting ([`cells`]) and the Kahan sums both
//! backends share. Its WGSL twin (`Cells`, `Sum`) is [`crate::gpu::estimate::CELLS_WGSL`].
use crate::{DepthLookup, Light, LightShape, ReceiverPlane};
use glam::Vec2;

/// Splits `[a, b)` (texel coordinates) into at most `max` cells: whole texels clipped to the
/// interval when it spans at most `max` texels, equal cells otherwise. Yields
/// `(texel index sampled, weight = cell length)`.
pub fn cells(a: f32, b: f32, max: u32, mut f: impl FnMut(i32, f32)) {
    // A window past 2^24 texels (an absurd light size: the fuzz met one 1e30 wide) is cut there:
    // f32 texel coordinates are exact up to 2^24, every map is far smaller, and the cells stay
    // finite.
    const LIM: f32 = 16_777_216.0;
    let (a, b) = (a.clamp(-LIM, LIM), b.clamp(-LIM, LIM));
    let len = b - a;
    if !(len > 0.0) {
        f(a.floor() as i32, 1.0);
        return;
    }
    // Saturating casts: a kernel grown past i64 (an absurd light size) still splits into cells.
    let first = a.floor() as i64;
    let last = (b.ceil() as i64).saturating_sub(1).max(first);
    if (last as i128 - first as i128 + 1) <= max as i128 {
        for i in first..=last {
            let lo = (i as f32).max(a);
            let hi = ((i + 1) as f32).min(b);
            if hi > lo {
                f(i as i32, hi - lo);
            }
        }
    } else {
        let step = len / max as f32;
        for k in 0..max {
            let c = a + (k as f32 + 0.5) * step;
            f(c.floor() as i32, step);
        }
    }
}

/// The blocker-search width on the plane z = n, in texels (docs/methods.md §5 step 1): the cut of
/// the pyramid from the receiver at depth `zr` to the light of extent `l` (per axis, light-plane
/// units), `W_search = l (z_r - n) / z_r`, times `to_texels = r / w`.
///
/// The sun (`ortho`, docs/methods.md §14 "PCSS"): `l` is the diameter `2 tan(angle / 2)` of its disk of
/// directions at unit distance and the map is in world units, so the cut of the receiver's
/// occluder prism at the near plane is `W_search = l (z_r - n)` world units.
#[inline]
pub fn search_width(l: Vec2, zr: f32, n: f32, to_texels: f32, ortho: bool) -> Vec2 {
    if ortho {
        l * (zr - n) * to_texels
    } else {
        l * ((zr - n) / zr) * to_texels
    }
}

/// The filter width on the plane z = n, in texels (docs/methods.md §5 steps 3 and 4): penumbra
/// `w_p = (z_r - z_avg) l / z_avg` at the receiver, `W_filter = w_p n / z_r`, times `to_texels`.
///
/// The sun (`ortho`, docs/methods.md §14 "PCSS"): the penumbra of a blocker at depth `z_avg` is
/// `w_p = (z_r - z_avg) l` world units wide at the receiver, `l = 2 tan(angle / 2)`, and an
/// orthographic map keeps world widths: `W_filter = w_p`.
#[inline]
pub fn filter_width(l: Vec2, zr: f32, z_avg: f32, n: f32, to_texels: f32, ortho: bool) -> Vec2 {
    if ortho {
        l * (zr - z_avg) * to_texels
    } else {
        l * ((zr - z_avg) / z_avg) * (n / zr) * to_texels
    }
}

/// True for the lights whose PCSS filter is a disk (disk, sphere and directional lights; a
/// rect's is a box).
#[inline]
pub fn is_disk(light: &Light) -> bool {
    matches!(
        light.shape,
        LightShape::Disk { .. } | LightShape::Sphere { .. } | LightShape::Directional { .. }
    )
}

/// The weight of texel (i, j) in a disk filter of diameter `wf.x` texels centred on `uv`, with a
/// one-texel soft edge (continuous in the filter width, so rounding in z_avg moves V by a
/// rounding error, not a texel); 1 for a box filter (`disk` false) or a filter within a texel.
#[inline]
pub fn disk_edge(disk: bool, wf: Vec2, i: i32, j: i32, uv: Vec2) -> f32 {
    if disk && wf.x > 1.0 {
        let rad = 0.5 * wf.x;
        let c = Vec2::new(i as f32 + 0.5, j as f32 + 0.5) - uv;
        (rad + 0.5 - c.length()).clamp(0.0, 1.0)
    } else {
        1.0
    }
}

/// Kahan-compensated f32 sum. PCSS accumulates its weights with it, in the same order as its GPU
/// twin, so both backends get the same blocker depth and filter width bit for bit (an f64 sum
/// on one side only moved the filter's cells and flipped sampled texels).
/// Public so that other PCSS-style filters (deep-shadow's `filter=pcss`) sum the same way; its
/// WGSL twin is `Sum` / `sum_add` in [`crate::gpu::estimate::CELLS_WGSL`].
#[derive(Debug, Clone, Copy, Default)]
pub struct Kahan {
    s: f32,
    c: f32,
}

impl Kahan {
    /// The sum so far.
    #[inline]
    pub fn sum(&self) -> f32 {
        self.s
    }
    /// Adds `x`.
    #[inline]
    pub fn add(&mut self, x: f32) {
        let y = x - self.c;
        let t = self.s + y;
        self.c = (t - self.s) - y;
        self.s = t;
    }
}

/// What [`soft_transmittance`] needs to size its blocker search and its kernel, per view
/// (docs/methods.md §5 "PCSS, step by step", §8 "Percentage-closer soft transmittance").
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct SoftLookup {
    /// The extent `l` (per axis, light-plane units) of the light each view stands for: the whole
    /// light for one view, one stratum (`l / S`) for S x S sub-lights.
    pub light: Vec2,
    /// The view's near plane n, where widths are measured.
    pub near: f32,
    /// `r / w`: texels per unit length on the plane z = n.
    pub to_texels: f32,
    /// Most cells per side in the search and in the kernel (PCSS's `max_taps`); 0 samples
    /// nothing (T = 1).
    pub max_taps: u32,
    /// A disk kernel (disk and sphere lights) instead of a box (rect lights).
    pub disk: bool,
    /// An orthographic view (the sun): widths in world units ([`search_width`],
    /// [`filter_width`]).
    pub ortho: bool,
}

/// What [`soft_transmittance`] reads from a map: a shadow map ([`DepthTaps`], each texel a
/// one-element list with alpha = 1: PCSS), or a deep shadow map's lists (deep-shadow's
/// `filter=pcss`).
pub trait SoftTaps {
    /// Depth of the first (nearest) fragment of texel (i, j); `None` when the texel is empty or
    /// outside the map.
    fn first_depth(&self, i: i32, j: i32) -> Option<f32>;
    /// `T` of tap (i, j) for the receiver's caster test (`tau` of the last caster, 1 when none),
    /// and the list elements visited.
    fn tap(&self, i: i32, j: i32, plane: &ReceiverPlane) -> (f32, u32);
}

/// Percentage-closer soft transmittance (docs/methods.md §8 "Percentage-closer soft
/// transmittance"; PCSS itself, §5, when every tap is 0 or 1), for the receiver at depth `zr` and
/// continuous texel coordinates `uv` with caster test `plane`:
/// 1. blocker search: PCSS's region `W_search = l (z_r - n) / z_r` on the plane z = n
///    ([`search_width`]), sampled by [`cells`] (whole texels, or `max_taps` equal cells);
/// 2. `z_avg`, the cell-weighted mean of the first-fragment depth `z_0` of the lists whose
///    `z_0` is a caster (`plane.caster`); none: T = 1 (no fragment of any list is a caster);
/// 3. kernel width `W_filter = (z_r - z_avg) l / z_avg * n / z_r` ([`filter_width`]);
/// 4. the weighted mean of `T(d)` of each tap over that kernel (a box, or a disk with a one-texel
///    soft edge for disk and sphere lights: [`disk_edge`]), as PCSS means its binary test.
///
/// Sums are Kahan-compensated f32 in the GPU twins' order; taps with T = 0 are not added (a
/// Kahan add of 0 still folds the compensation in), so a binary map sums as PCSS always has. As
/// `l -> 0` both regions shrink to the receiver's texel and the result is that texel's T; under one
/// uniform sheet of opacity a every tap is `1 - a` and so is the mean. Returns `(T, taps or list
/// elements visited)`.
pub fn soft_transmittance<M: SoftTaps>(
    map: &M,
    uv: Vec2,
    zr: f32,
    plane: &ReceiverPlane,
    p: &SoftLookup,
) -> (f32, u32) {
    let ws = search_width(p.light, zr, p.near, p.to_texels, p.ortho);
    let (mut sum, mut count) = (Kahan::default(), Kahan::default());
    let mut steps = 0u32;
    cells(uv.y - 0.5 * ws.y, uv.y + 0.5 * ws.y, p.max_taps, |j, wy| {
        cells(uv.x - 0.5 * ws.x, uv.x + 0.5 * ws.x, p.max_taps, |i, wx| {
            if let Some(z) = map.first_depth(i, j) {
                steps = steps.saturating_add(1);
                if plane.caster(i, j, z) {
                    let w = wx * wy;
                    sum.add(w * z);
                    count.add(w);
                }
            }
        })
    });
    if !(count.sum() > 0.0) {
        return (1.0, steps);
    }
    let z_avg = sum.sum() / count.sum();
    let wf = filter_width(p.light, zr, z_avg, p.near, p.to_texels, p.ortho);
    let (mut lit, mut total) = (Kahan::default(), Kahan::default());
    cells(uv.y - 0.5 * wf.y, uv.y + 0.5 * wf.y, p.max_taps, |j, wy| {
        cells(uv.x - 0.5 * wf.x, uv.x + 0.5 * wf.x, p.max_taps, |i, wx| {
            let edge = disk_edge(p.disk, wf, i, j, uv);
            if edge <= 0.0 {
                return;
            }
            let w = wx * wy * edge;
            total.add(w);
            let (t, st) = map.tap(i, j, plane);
            steps = steps.saturating_add(st);
            if t != 0.0 {
                lit.add(w * t);
            }
        })
    });
    if !(total.sum() > 0.0) {
        return (1.0, steps);
    }
    let t = lit.sum() / total.sum();
    (
        if t.is_finite() {
            t.clamp(0.0, 1.0)
        } else {
            1.0
        },
        steps,
    )
}

/// A shadow map read as [`SoftTaps`]: each texel a one-element list of alpha 1 (empty where the
/// depth is +inf).
#[derive(Debug, Clone, Copy)]
pub struct DepthTaps<'a, M: DepthLookup>(pub &'a M);

impl<M: DepthLookup> SoftTaps for DepthTaps<'_, M> {
    fn first_depth(&self, i: i32, j: i32) -> Option<f32> {
        let z = self.0.at(i, j);
        z.is_finite().then_some(z)
    }
    fn tap(&self, i: i32, j: i32, plane: &ReceiverPlane) -> (f32, u32) {
        (
            if plane.caster(i, j, self.0.at(i, j)) {
                0.0
            } else {
                1.0
            },
            1,
        )
    }
}
