//! The deep shadow map of Fürst et al. on the CPU: per-texel linked lists in a head buffer and an
//! element buffer with one counter (§1.3.1), processed by sorting, cumulative transmittance and
//! truncation (§1.3.2), linked to the right and upper neighbours (§1.3.3), and looked up with PCF
//! or exponential filtering, with link-guided or naive traversal (§1.3.4, §1.3.5; the per-list
//! steps in [`crate::math`]).
use super::raster::Fragment;
use crate::math::{
    caster_depth, depth_test, find, find_by, less, soft_tau, soft_transmittance, LookupSettings,
    Node, SoftTaps, NIL,
};
use crate::settings::{Filter, Traversal};
use glam::Vec2;
use rayon::prelude::*;
use shadow_map_core::{Error, ReceiverPlane, Result};

impl SoftTaps for DeepShadowMap {
    fn first_depth(&self, i: i32, j: i32) -> Option<f32> {
        let r = self.r as i32;
        if i < 0 || j < 0 || i >= r || j >= r {
            return None;
        }
        let hd = self.head[(j * r + i) as usize];
        (hd != NIL).then(|| self.nodes[hd as usize].depth)
    }
    fn tap(&self, i: i32, j: i32, plane: &ReceiverPlane) -> (f32, u32) {
        let r = self.r as i32;
        if i < 0 || j < 0 || i >= r || j >= r {
            return (1.0, 0);
        }
        let hd = self.head[(j * r + i) as usize];
        if hd == NIL {
            return (1.0, 0);
        }
        let (k, st) = find_by(&self.nodes, hd, |z| plane.caster(i, j, z));
        (
            if k == NIL {
                1.0
            } else {
                self.nodes[k as usize].tau
            },
            st,
        )
    }
}

/// Statistics of a build.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct BuildStats {
    /// Fragments rasterised (the counter after the last pass).
    pub fragments: u64,
    /// Element-buffer capacity of the last pass.
    pub capacity: u64,
    /// Passes needed (1 + rebuilds after an overflow).
    pub passes: u32,
    /// Elements left in the lists after truncation.
    pub kept: u64,
    /// Longest list before truncation.
    pub max_len: u32,
    /// Non-empty lists.
    pub lists: u64,
}

/// A deep shadow map: `head[j r + i]` is the first element of texel (i, j)'s list in `nodes`
/// ([`NIL`] when empty).
///
/// Invariant (kept by every constructor, relied on by the parallel passes): `head` has `r * r`
/// entries; every `head` entry and every link (`next`, `prev`, `right`, `upper`) of an element is
/// [`NIL`] or an index into `nodes`; the lists reached from `head` through `next` are acyclic and
/// pairwise disjoint. The fields are private so safe code cannot break it.
#[derive(Debug, Clone, PartialEq)]
pub struct DeepShadowMap {
    /// Side r in texels.
    r: u32,
    /// Head buffer.
    head: Vec<u32>,
    /// List element buffer (its length is the capacity).
    nodes: Vec<Node>,
    /// Build statistics.
    stats: BuildStats,
}

/// One pass of §1.3.1 (Listing 1.2), sequential: for each fragment, `i = counter++`; if
/// `i < capacity` the element is written and pushed at the head of its texel's list (the
/// `InterlockedExchange`); otherwise only the counter moves, so an overflow is detected
/// (`counter > capacity`) and never leaves a broken list. Returns the counter.
fn insert_pass(frags: &[Fragment], head: &mut [u32], nodes: &mut Vec<Node>, capacity: u64) -> u64 {
    head.fill(NIL);
    nodes.clear();
    let mut counter: u64 = 0;
    for f in frags {
        let i = counter;
        counter += 1;
        if i >= capacity {
            continue;
        }
        let h = &mut head[f.texel as usize];
        nodes.push(Node::fragment(f.depth, f.alpha, *h));
        *h = i as u32;
    }
    counter
}

/// Raw element-buffer pointer and length shared by the per-texel passes, which touch disjoint
/// lists. Fields are read and written through the raw pointer (never through `&mut Node`), so
/// two passes touching different fields of one element never alias.
#[derive(Clone, Copy)]
struct NodesPtr(*mut Node, usize);
// SAFETY: every per-texel pass below writes only the elements of its own texel's list (lists are
// disjoint, a `DeepShadowMap` invariant) and reads other lists only in fields no pass writes
// concurrently.
unsafe impl Send for NodesPtr {}
unsafe impl Sync for NodesPtr {}

impl NodesPtr {
    /// Pointer to element `i`; panics (never reads out of bounds) when `i` is past the buffer.
    #[inline]
    fn at(self, i: u32) -> *mut Node {
        assert!((i as usize) < self.1, "list element {i} out of bounds");
        // SAFETY: `i < len` of the buffer `self.0` points at.
        unsafe { self.0.add(i as usize) }
    }
}

impl DeepShadowMap {
    /// Builds the lists from fragments with the capacity rule of §1.3.1: a pass at
    /// `initial_capacity` elements (0: `max(4 r^2, 1024)`); when the counter passes the capacity,
    /// the buffer grows to the counter and the pass is rebuilt. A need above `max_capacity` is an
    /// [`Error::Limit`]; fragments are never dropped silently.
    pub fn build(
        frags: &[Fragment],
        r: u32,
        initial_capacity: u64,
        max_capacity: u64,
    ) -> Result<Self> {
        let texels = r as usize * r as usize;
        if let Some(f) = frags.iter().find(|f| f.texel as usize >= texels) {
            return Err(Error::param(
                "fragments",
                format!("texel {} outside a {r}x{r} map", f.texel),
            ));
        }
        let mut capacity = if initial_capacity == 0 {
            (4 * texels as u64).max(1024)
        } else {
            initial_capacity
        }
        .min(max_capacity);
        let mut head = vec![NIL; texels];
        let mut nodes = Vec::new();
        let mut passes = 0;
        loop {
            passes += 1;
            let counter = insert_pass(frags, &mut head, &mut nodes, capacity);
            if counter <= capacity {
                let stats = BuildStats {
                    fragments: counter,
                    capacity,
                    passes,
                    ..Default::default()
                };
                return Ok(DeepShadowMap {
                    r,
                    head,
                    nodes,
                    stats,
                });
            }
            if counter > max_capacity || counter >= NIL as u64 {
                return Err(Error::Limit {
                    what: "deep shadow map list elements (raise max_capacity or lower resolution)",
                    requested: counter,
                    max: max_capacity.min(NIL as u64 - 1),
                });
            }
            capacity = counter;
        }
    }

    /// A map from raw buffers (e.g. a GPU map read back), checked against the invariant of
    /// [`DeepShadowMap`]: fails with [`Error::Gpu`] on a wrong head length, an index out of range
    /// or lists that cycle or share elements.
    pub fn from_parts(r: u32, head: Vec<u32>, nodes: Vec<Node>, stats: BuildStats) -> Result<Self> {
        let bad = |reason: String| Error::Gpu {
            stage: "deep shadow map lists".into(),
            reason,
        };
        if head.len() != r as usize * r as usize {
            return Err(bad(format!("{} heads for a {r}x{r} map", head.len())));
        }
        if nodes.len() >= NIL as usize {
            return Err(bad(format!("{} elements", nodes.len())));
        }
        let n = nodes.len() as u32;
        let ok = |i: u32| i == NIL || i < n;
        for (k, e) in nodes.iter().enumerate() {
            if !(ok(e.next) && ok(e.prev) && ok(e.right) && ok(e.upper)) {
                return Err(bad(format!("element {k} links past {n} elements")));
            }
        }
        // Each element is reached from at most one head, at most once: disjoint and acyclic.
        let mut seen = vec![false; nodes.len()];
        for (t, &h) in head.iter().enumerate() {
            let mut e = h;
            while e != NIL {
                if e >= n {
                    return Err(bad(format!("head {t} points past {n} elements")));
                }
                if std::mem::replace(&mut seen[e as usize], true) {
                    return Err(bad(format!("element {e} is reached twice (texel {t})")));
                }
                e = nodes[e as usize].next;
            }
        }
        Ok(DeepShadowMap {
            r,
            head,
            nodes,
            stats,
        })
    }

    /// Side r in texels.
    pub fn r(&self) -> u32 {
        self.r
    }

    /// Head buffer: the first element of each texel's list, [`NIL`] when empty.
    pub fn head(&self) -> &[u32] {
        &self.head
    }

    /// The element buffer.
    pub fn nodes(&self) -> &[Node] {
        &self.nodes
    }

    /// Build statistics.
    pub fn stats(&self) -> &BuildStats {
        &self.stats
    }

    /// Indices of texel `t`'s list, in list order (empty for a texel past the map).
    pub fn list(&self, t: usize) -> Vec<u32> {
        let mut out = Vec::new();
        let mut e = self.head.get(t).copied().unwrap_or(NIL);
        while e != NIL {
            out.push(e);
            e = self.nodes[e as usize].next;
        }
        out
    }

    /// Processing (§1.3.2), one texel at a time in parallel: sort the list by depth (insertion
    /// sort of its payloads, ties broken by alpha so any insertion order gives the same list),
    /// store `tau_k = prod_{i<=k} (1 - alpha_i)` (Eq. 1.1) and the `prev` links, and truncate
    /// (`epsilon` 0 disables) once `tau_K <= epsilon` at an element K:
    ///
    /// - `window = 0` (the hard lookups: first, none, pcf, pcss): right after K. Every later
    ///   fragment lies behind a transmittance `tau_K <= epsilon`, so the lookup error is at most
    ///   `epsilon`.
    /// - `window > 0` (EDSM, [`truncation_window`](crate::math::truncation_window)): before the first element at or beyond
    ///   `z_K + window`. EDSM's soft product ([`soft_tau`]) weights a fragment at `z_j` by
    ///   `o_c(d - z_j)`, small just behind it, so truncating right after K is not bounded by
    ///   epsilon (two coincident opaque fragments give `e^{-c't}` instead of `e^{-2c't}`: an
    ///   error up to 1/4; a run of m coincident fragments up to nearly 1). With the window every
    ///   fragment within `EDSM_CUTOFF / c'` of K is kept, so for `d < z_K + window` the product
    ///   is exact, and beyond it the walk from the receiver meets a hard element at or after K,
    ///   so the truncated value is at most `tau_K <= epsilon` and at least the full one: the error
    ///   is again at most `epsilon`.
    pub fn process(&mut self, epsilon: f32, window: f32) {
        let ptr = NodesPtr(self.nodes.as_mut_ptr(), self.nodes.len());
        let res: Vec<(u64, u32)> = self
            .head
            .par_iter()
            .map_init(
                || (Vec::new(), Vec::new()),
                |scratch, &h| {
                    // SAFETY: the lists are disjoint and in bounds (the type's invariant, which
                    // processing keeps: it only reorders payloads and cuts `next`), so only this
                    // texel's elements are touched.
                    unsafe { process_list(ptr, h, (epsilon, window), scratch) }
                },
            )
            .collect();
        self.stats.kept = res.iter().map(|r| r.0).sum();
        self.stats.max_len = res.iter().map(|r| r.1).max().unwrap_or(0);
        self.stats.lists = res.iter().filter(|r| r.1 > 0).count() as u64;
    }

    /// Neighbour links (§1.3.3): for every element, the depth-nearest element of the lists of the
    /// right (i+1, j) and upper (i, j+1) texels (ties to the shallower), found by walking both
    /// sorted lists together.
    pub fn link(&mut self) {
        let r = self.r as usize;
        let ptr = NodesPtr(self.nodes.as_mut_ptr(), self.nodes.len());
        let head = &self.head;
        (0..head.len()).into_par_iter().for_each(|t| {
            let p = ptr;
            let (i, j) = (t % r, t / r);
            let right = if i + 1 < r { head[t + 1] } else { NIL };
            let upper = if j + 1 < r { head[t + r] } else { NIL };
            // SAFETY: the lists are disjoint and in bounds (the type's invariant); this writes
            // only `right`/`upper` of this texel's elements and reads only `depth` and `next` of
            // the neighbours' elements, which this pass never writes.
            unsafe {
                link_list(p, head[t], right, false);
                link_list(p, head[t], upper, true);
            }
        });
    }

    /// Transmittance at light-space depth `d` for the point with continuous texel coordinates
    /// `uv`, filtered as `s` says: [`DeepShadowMap::transmittance_plane`] with the plain depth
    /// test `z < d` ([`depth_test`]). Returns `(T, elements visited)`.
    pub fn transmittance(&self, uv: Vec2, d: f32, s: &LookupSettings) -> (f32, u32) {
        self.transmittance_plane(uv, &depth_test(d), s)
    }

    /// Transmittance for the receiver with continuous texel coordinates `uv` and caster test
    /// `plane` ([`ReceiverPlane`]: receiver-plane rejection, or the classic `z < z_p - eps`),
    /// filtered as `s` says. In tap (i, j) a fragment attenuates only when it is a caster,
    /// `plane.caster(i, j, z)` (`first`, `none`, `pcf`); EDSM, continuous in depth, measures
    /// `d - z_j` from the tap's threshold depth `d` ([`caster_depth`]: `plane.threshold_at` at
    /// the texel centre), the per-texel form of `z_p - eps`. Returns `(T, elements visited)`.
    pub fn transmittance_plane(
        &self,
        uv: Vec2,
        plane: &ReceiverPlane,
        s: &LookupSettings,
    ) -> (f32, u32) {
        if s.filter == Filter::Pcss {
            return soft_transmittance(self, uv, plane.zp, plane, &s.soft);
        }
        let r = self.r as i32;
        let (n, (i0, j0)) = (s.taps(), s.first_tap(uv));
        let mut sum = 0.0f32;
        let mut steps = 0u32;
        let mut row_anchor = NIL;
        for b in 0..n {
            let j = j0 + b;
            let mut anchor = NIL;
            for a in 0..n {
                let i = i0 + a;
                if i < 0 || j < 0 || i >= r || j >= r {
                    sum += 1.0;
                    anchor = NIL;
                    if a == 0 {
                        row_anchor = NIL;
                    }
                    continue;
                }
                let hd = self.head[(j * r + i) as usize];
                if hd == NIL {
                    sum += 1.0;
                    anchor = NIL;
                    if a == 0 {
                        row_anchor = NIL;
                    }
                    continue;
                }
                if s.filter == Filter::First {
                    steps += 1;
                    sum += if plane.caster(i, j, self.nodes[hd as usize].depth) {
                        0.0
                    } else {
                        1.0
                    };
                    continue;
                }
                let start = match s.traversal {
                    Traversal::Naive => hd,
                    Traversal::Linked => {
                        let from = if a == 0 { row_anchor } else { anchor };
                        let link = if from == NIL {
                            NIL
                        } else if a == 0 {
                            self.nodes[from as usize].upper
                        } else {
                            self.nodes[from as usize].right
                        };
                        if link == NIL {
                            hd
                        } else {
                            link
                        }
                    }
                };
                let (k, st, d) = if s.filter == Filter::Edsm {
                    let d = caster_depth(plane, i, j);
                    let (k, st) = find(&self.nodes, start, d);
                    (k, st, d)
                } else {
                    let (k, st) = find_by(&self.nodes, start, |z| plane.caster(i, j, z));
                    (k, st, 0.0)
                };
                steps += st;
                sum += match s.filter {
                    Filter::Edsm => soft_tau(&self.nodes, k, d, s.c_world),
                    _ => {
                        if k == NIL {
                            1.0
                        } else {
                            self.nodes[k as usize].tau
                        }
                    }
                };
                anchor = if k == NIL { hd } else { k };
                if a == 0 {
                    row_anchor = anchor;
                }
            }
        }
        ((sum / (n * n) as f32).clamp(0.0, 1.0), steps)
    }

    /// Bytes of the head and element buffers.
    pub fn bytes(&self) -> usize {
        self.head.len() * 4 + self.nodes.len() * std::mem::size_of::<Node>()
    }
}

/// Sorts, accumulates and truncates one list; returns (elements kept, length before truncation).
///
/// # Safety
/// `nodes` must describe the live element buffer, the list from `head` must be acyclic, and no
/// other thread may touch this list's elements.
unsafe fn process_list(
    nodes: NodesPtr,
    head: u32,
    (epsilon, window): (f32, f32),
    (idx, pay): &mut (Vec<u32>, Vec<(f32, f32)>),
) -> (u64, u32) {
    if head == NIL {
        return (0, 0);
    }
    // SAFETY: in bounds (`NodesPtr::at` checks) and owned by this thread (the caller's contract).
    let at = |i: u32| unsafe { &mut *nodes.at(i) };
    idx.clear();
    pay.clear();
    let mut e = head;
    while e != NIL {
        idx.push(e);
        let n = at(e);
        pay.push((n.depth, n.alpha));
        e = n.next;
    }
    // Insertion sort (the paper's choice, §1.3.2), by (depth, alpha).
    for a in 1..pay.len() {
        let x = pay[a];
        let mut b = a;
        while b > 0 && less(x, pay[b - 1]) {
            pay[b] = pay[b - 1];
            b -= 1;
        }
        pay[b] = x;
    }
    let mut tau = 1.0f32;
    let mut kept = idx.len();
    // z_K + window once tau_K <= epsilon (window > 0).
    let mut cut_at: Option<f32> = None;
    for (k, (&i, &(z, al))) in idx.iter().zip(pay.iter()).enumerate() {
        if cut_at.is_some_and(|c| z >= c) {
            at(idx[k - 1]).next = NIL;
            kept = k;
            break;
        }
        tau *= 1.0 - al;
        let n = at(i);
        n.depth = z;
        n.alpha = al;
        n.tau = tau;
        n.prev = if k == 0 { NIL } else { idx[k - 1] };
        if cut_at.is_none() && epsilon > 0.0 && tau <= epsilon {
            if window > 0.0 {
                cut_at = Some(z + window);
            } else {
                n.next = NIL;
                kept = k + 1;
                break;
            }
        }
    }
    (kept as u64, idx.len() as u32)
}

/// Links every element of list `a` to its depth-nearest element of list `b`.
///
/// # Safety
/// As [`DeepShadowMap::link`].
unsafe fn link_list(nodes: NodesPtr, a: u32, b: u32, upper: bool) {
    // SAFETY (both closures): in bounds (`NodesPtr::at` checks); fields are accessed through the raw
    // pointer, never a reference, and no other thread writes `depth`/`next` during the pass or
    // the `right`/`upper` of list `a`.
    let depth = |i: u32| unsafe { (*nodes.at(i)).depth };
    let next = |i: u32| unsafe { (*nodes.at(i)).next };
    let mut cur = b;
    let mut e = a;
    while e != NIL {
        let z = depth(e);
        let best = if cur == NIL {
            NIL
        } else {
            loop {
                let nx = next(cur);
                if nx != NIL && depth(nx) <= z {
                    cur = nx;
                } else {
                    break;
                }
            }
            let zc = depth(cur);
            let nx = next(cur);
            if zc <= z && nx != NIL && depth(nx) - z < z - zc {
                nx
            } else {
                cur
            }
        };
        let p = nodes.at(e);
        // SAFETY: `e` is this thread's own element (see above).
        unsafe {
            if upper {
                (*p).upper = best;
            } else {
                (*p).right = best;
            }
        }
        e = next(e);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn frag(texel: u32, depth: f32) -> Fragment {
        Fragment {
            texel,
            depth,
            alpha: 0.5,
        }
    }

    /// Bad buffers cannot become a map: a fragment past the map is a typed error, and a
    /// read-back with a wrong head length, a dangling link, a cycle or a shared element is
    /// refused, so `process` and `link` only ever see valid, disjoint lists.
    #[test]
    fn invalid_maps_are_refused() {
        assert!(matches!(
            DeepShadowMap::build(&[frag(4, 1.0)], 2, 0, 1 << 20),
            Err(Error::Param { .. })
        ));
        let m = DeepShadowMap::build(&[frag(0, 2.0), frag(0, 1.0), frag(3, 1.0)], 2, 0, 1 << 20)
            .unwrap();
        let parts = |m: &DeepShadowMap| (m.head().to_vec(), m.nodes().to_vec());
        let ok = |h: Vec<u32>, n: Vec<Node>| DeepShadowMap::from_parts(2, h, n, *m.stats());
        let (h, n) = parts(&m);
        let mut back = ok(h.clone(), n.clone()).unwrap();
        back.process(0.0, 0.0);
        back.link();
        // What `m.nodes.clear(); m.process(..)` used to do.
        assert!(ok(h.clone(), Vec::new()).is_err());
        assert!(ok(h[..3].to_vec(), n.clone()).is_err());
        let mut dangling = n.clone();
        dangling[0].right = 7;
        assert!(ok(h.clone(), dangling).is_err());
        let mut cycle = n.clone();
        let first = h[0] as usize;
        let second = cycle[first].next as usize;
        cycle[second].next = first as u32;
        assert!(ok(h.clone(), cycle).is_err());
        let mut shared = h.clone();
        shared[1] = shared[0];
        assert!(ok(shared, n).is_err());
        // Out of range reads are empty, not a panic.
        assert!(m.list(99).is_empty());
    }
}
