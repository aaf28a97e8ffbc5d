//! The method's pure functions, shared by both twins: the lookups of one list and of one opaque
//! texel (Fürst et al. §1.3.4, §1.3.5; EDSM, docs/methods.md §7), the sort order and the
//! truncation window of processing (§1.3.2), the list element ([`node`]), and the sub-light views
//! and each receiver's query in them ([`view`]).
use crate::settings::{Filter, Traversal};
use glam::Vec2;
pub use node::{Node, NIL};
pub use shadow_map_core::soft_transmittance::{
    soft_transmittance, DepthTaps, SoftLookup, SoftTaps,
};
use shadow_map_core::{DepthMap, ReceiverPlane};

pub mod node;
pub mod view;

/// Settings of one lookup.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LookupSettings {
    /// Filter.
    pub filter: Filter,
    /// Kernel side N (odd); ignored by [`Filter::First`] and [`Filter::None`].
    pub kernel: u32,
    /// EDSM sharpness in world units: `c' = c / (far - n)` for the notes' c over normalised depth.
    pub c_world: f32,
    /// Traversal.
    pub traversal: Traversal,
    /// The light and the view as [`Filter::Pcss`] sizes its regions (read by no other filter).
    pub soft: SoftLookup,
}

impl LookupSettings {
    /// Taps per side of the kernel (§1.3.5): 1 for [`Filter::First`] and [`Filter::None`], N for
    /// the filters over N x N texels.
    pub fn taps(&self) -> i32 {
        match self.filter {
            Filter::First | Filter::None => 1,
            _ => self.kernel.max(1) as i32,
        }
    }

    /// The kernel's first tap (i, j) around continuous texel coordinates `uv`: the receiver's
    /// texel less half the kernel on each axis; the taps run row by row from it.
    pub fn first_tap(&self, uv: Vec2) -> (i32, i32) {
        let h = self.taps() / 2;
        (uv.x.floor() as i32 - h, uv.y.floor() as i32 - h)
    }
}

/// `o_c` is evaluated only for `c' (d - z) < EDSM_CUTOFF`: beyond it `exp(-c' t) < 1.2e-7` and the
/// fragment counts as a hard step, so its factor is read from the stored `tau`.
pub const EDSM_CUTOFF: f32 = 16.0;

/// The depth EDSM measures a tap's fragments from, in texel (i, j): the plane's caster-depth bound
/// at the texel centre ([`ReceiverPlane::threshold_at`]: `z_p - eps` under the classic test;
/// `z_p` where the ray does not descend towards the tangent plane).
#[inline]
pub fn caster_depth(plane: &ReceiverPlane, i: i32, j: i32) -> f32 {
    plane.threshold_at(Vec2::new(i as f32 + 0.5, j as f32 + 0.5))
}

/// The caster test of a plain depth `d`: `z < d` (the form the lookups took before receiver-plane
/// rejection; [`ReceiverPlane::caster`] of it is exactly `z < d` for finite z).
pub fn depth_test(d: f32) -> ReceiverPlane {
    ReceiverPlane {
        g0: 1.0,
        gu: 0.0,
        gv: 0.0,
        c: d,
        cu: 0.0,
        cv: 0.0,
        zp: d,
        hs: 0.0,
    }
}

/// The last element of a sorted list with `depth < d` ([`NIL`] when none), searched from `start`
/// (any element of the list) along `next` or `prev`. Returns it and the elements visited.
#[inline]
pub fn find(nodes: &[Node], start: u32, d: f32) -> (u32, u32) {
    find_by(nodes, start, |z| z < d)
}

/// [`find`] with any test `caster(depth)` that holds for a prefix of the sorted list (true up to
/// some depth, false beyond, as [`ReceiverPlane::caster`] in one texel): the last element that
/// passes ([`NIL`] when none). Returns it and the elements visited.
#[inline]
pub fn find_by(nodes: &[Node], start: u32, caster: impl Fn(f32) -> bool) -> (u32, u32) {
    let mut s = start;
    let mut steps = 1;
    if caster(nodes[s as usize].depth) {
        loop {
            let nx = nodes[s as usize].next;
            if nx != NIL && caster(nodes[nx as usize].depth) {
                s = nx;
                steps += 1;
            } else {
                return (s, steps);
            }
        }
    }
    loop {
        let pv = nodes[s as usize].prev;
        if pv == NIL {
            return (NIL, steps);
        }
        s = pv;
        steps += 1;
        if caster(nodes[s as usize].depth) {
            return (s, steps);
        }
    }
}

/// The depth window [`DeepShadowMap::process`](crate::cpu::dsm::DeepShadowMap::process) keeps behind the truncation point for a lookup
/// with EDSM's `c'` (`c_world`): `EDSM_CUTOFF / c'` under [`Filter::Edsm`], 0 (truncate right
/// after it) for the hard filters.
pub fn truncation_window(filter: Filter, c_world: f32) -> f32 {
    if filter == Filter::Edsm && c_world > 0.0 {
        EDSM_CUTOFF / c_world
    } else {
        0.0
    }
}

/// EDSM transmittance of one tap (docs/methods.md §7, the soft-tested product):
/// `tau_c(d) = prod_{z_j < d} (1 - alpha_j o_c(d - z_j))`, `o_c(t) = 1 - exp(-c' t)`.
///
/// Only the exponent `-c' (d - z_j) <= 0` is ever evaluated (the log-space form: `exp(c z)` on its
/// own, which overflows f32 once `c z > 88.7`, never appears). Walking back from `k` (the last
/// fragment in front of d), the first fragment with `c' (d - z_j) >= EDSM_CUTOFF` and every one
/// before it count as hard steps, whose product is the stored `tau_j`.
#[inline]
pub fn soft_tau(nodes: &[Node], k: u32, d: f32, c_world: f32) -> f32 {
    let mut prod = 1.0f32;
    let mut j = k;
    while j != NIL {
        let e = &nodes[j as usize];
        let t = (d - e.depth) * c_world;
        if t >= EDSM_CUTOFF {
            return e.tau * prod;
        }
        prod *= 1.0 - e.alpha * (1.0 - (-t.max(0.0)).exp());
        j = e.prev;
    }
    prod
}

/// The sort order of list payloads: depth, then alpha (a total order on the values, so the
/// CPU twin and the engine path's `process` sort any insertion order to the same list).
#[inline]
pub fn less(a: (f32, f32), b: (f32, f32)) -> bool {
    a.0 < b.0 || (a.0 == b.0 && a.1 < b.1)
}

/// The opaque path: no lists, an ordinary shadow map (the nearest depth per texel) read with the
/// same filters; each texel acts as a one-element list with alpha = 1.
pub fn transmittance_opaque(map: &DepthMap, uv: Vec2, d: f32, s: &LookupSettings) -> f32 {
    transmittance_opaque_plane(map, uv, &depth_test(d), s)
}

/// [`transmittance_opaque`] with the caster test `plane`: a tap's sample occludes when
/// `plane.caster(i, j, z)`; EDSM's soft factor `exp(-c' (d - z))` measures from the tap's
/// threshold depth `d` ([`caster_depth`], as [`DeepShadowMap::transmittance_plane`](crate::cpu::dsm::DeepShadowMap::transmittance_plane)).
pub fn transmittance_opaque_plane(
    map: &DepthMap,
    uv: Vec2,
    plane: &ReceiverPlane,
    s: &LookupSettings,
) -> f32 {
    if s.filter == Filter::Pcss {
        return soft_transmittance(&DepthTaps(map), uv, plane.zp, plane, &s.soft).0;
    }
    let (n, (i0, j0)) = (s.taps(), s.first_tap(uv));
    let mut sum = 0.0;
    for b in 0..n {
        for a in 0..n {
            let (i, j) = (i0 + a, j0 + b);
            let z = map.at(i, j);
            sum += if plane.caster(i, j, z) {
                if s.filter == Filter::Edsm {
                    let d = caster_depth(plane, i, j);
                    let t = ((d - z) * s.c_world).max(0.0);
                    if t >= EDSM_CUTOFF {
                        0.0
                    } else {
                        (-t).exp()
                    }
                } else {
                    0.0
                }
            } else {
                1.0
            };
        }
    }
    (sum / (n * n) as f32).clamp(0.0, 1.0)
}
