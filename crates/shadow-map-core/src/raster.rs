//! The CPU shadow-map rasteriser: nearest linear light-space depth per texel.
//!
//! **Fill rule.** A texel is covered when its centre `(i + 1/2, j + 1/2)` lies inside the
//! triangle's projection. Centres exactly on an edge follow the top-left rule (as Vulkan and D3D
//! do): with u to the right and v down the rows, and the triangle ordered so that its signed area
//! is positive, an edge `(du, dv)` owns its centres when it is a left edge (`dv < 0`) or a top edge
//! (`dv == 0 && du > 0`). Two triangles sharing an edge therefore never both cover, nor both miss,
//! a centre on it: the edge function is evaluated from the same end of the edge by both (see
//! `edge_function`), so their values are exact opposites.
//!
//! **Row windows.** Per row, each edge's crossing bounds the columns a triangle can cover, and
//! the columns two texels inside every crossing are covered beyond doubt; only the texels between
//! take the per-texel test above, so the windows skip work without changing a texel.
//!
//! **Depth.** Linear light-space z, interpolated perspective-correctly (1/z is affine in u, v),
//! stored in f32; +inf marks an empty texel. Triangles are clipped to the near plane z = n.
//!
//! **Bias.** Optional `constant + slope * max(|dz/du|, |dz/dv|)` added to the stored depth, in
//! world units (slope: world units per unit of texel slope; common-techniques, "slope-scaled
//! bias").
//!
//! **Culling.** Facing is taken from the triangle's winding (its geometric normal), as on a GPU:
//! a triangle is front-facing when its normal points towards the centre of projection.
use crate::{light_view::LightView, scene::Scene};
use glam::{DVec2, DVec3, Vec3};
use rayon::prelude::*;

/// Which faces, as seen from the light, are skipped.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Cull {
    /// Rasterise every triangle.
    #[default]
    None,
    /// Skip triangles facing away from the light.
    Back,
    /// Skip triangles facing the light (keeps second surfaces: fewer acne, more peter-panning).
    Front,
}

crate::param_words!(Cull { None = "none", Back = "back", Front = "front" });

/// Depth bias added to stored depths.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct DepthBias {
    /// Constant term, world units.
    pub constant: f32,
    /// Slope-scale term: multiplies `max(|dz/du|, |dz/dv|)` (world units per texel).
    pub slope: f32,
}

/// Rasteriser options.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct RasterOptions {
    /// Depth bias.
    pub bias: DepthBias,
    /// Face culling.
    pub cull: Cull,
}

/// An `r x r` map of linear light-space depths; texel (i, j) at index `j * r + i`, +inf = empty.
#[derive(Debug, Clone, PartialEq)]
pub struct DepthMap {
    /// Side in texels.
    pub size: u32,
    /// Depths.
    pub depth: Vec<f32>,
}

impl DepthMap {
    /// An empty map (all +inf).
    pub fn empty(size: u32) -> Self {
        DepthMap {
            size,
            depth: vec![f32::INFINITY; size as usize * size as usize],
        }
    }
    /// Depth at texel (i, j); +inf outside the map (samples outside the map are non-occluders,
    /// docs/methods.md §1 "Coverage").
    #[inline]
    pub fn at(&self, i: i32, j: i32) -> f32 {
        if i < 0 || j < 0 || i >= self.size as i32 || j >= self.size as i32 {
            f32::INFINITY
        } else {
            self.depth[j as usize * self.size as usize + i as usize]
        }
    }
    /// Bytes of storage.
    pub fn bytes(&self) -> usize {
        self.depth.len() * 4
    }
}

/// Relative epsilon of depth peeling: layer k+1 keeps the nearest fragment with
/// `z > z_k * (1 + PEEL_EPS_REL)` (about 84 f32 ulps), so coincident or nearly coincident
/// surfaces do not come back as a new layer (Bavoil §4.1, "strictly behind").
pub const PEEL_EPS_REL: f32 = 1e-5;

/// A triangle prepared for rasterisation: light-space vertices after near-plane clipping,
/// projected to (u, v) with 1/z per vertex.
#[derive(Debug, Clone, Copy)]
struct Prepared {
    uv: [DVec2; 3],
    inv_z: [f64; 3],
    /// Opacity of the triangle's mesh ([`Scene::triangle_opacity`]).
    alpha: f32,
}

/// The projection of one view from light space to continuous texel coordinates, in f64: what
/// [`PreparedScene::new`] (and the deep shadow map's rasteriser) applies to every triangle.
#[derive(Debug, Clone, Copy)]
pub struct TexelProjection {
    n: f64,
    delta: f64,
    x0: DVec2,
    r: f64,
    ortho: bool,
}

impl TexelProjection {
    /// The projection of `view`: the plane z = n, the texel pitch, the window corner and the
    /// resolution, widened to f64.
    pub fn new(view: &LightView) -> Self {
        TexelProjection {
            n: view.n as f64,
            delta: view.delta() as f64,
            x0: DVec2::new(view.window_min.x as f64, view.window_min.y as f64),
            r: view.r as f64,
            ortho: view.is_ortho(),
        }
    }

    /// True for an orthographic view: [`clip_project`](Self::clip_project)'s depth term is then
    /// z itself (affine in u, v), not 1/z.
    pub fn is_ortho(&self) -> bool {
        self.ortho
    }

    /// The light-space triangle `l` clipped against z >= n (Sutherland-Hodgman on one plane),
    /// fanned into triangles and projected: each vertex as `(uv, 1/z)`, `uv` in texels. Only
    /// triangles whose bounds are finite and not wholly outside the map `[0, r]^2` come out.
    pub fn clip_project(&self, l: [DVec3; 3]) -> impl Iterator<Item = [(DVec2, f64); 3]> {
        let n = self.n;
        let mut poly = [DVec3::ZERO; 4];
        let mut m = 0;
        for k in 0..3 {
            let a = l[k];
            let b = l[(k + 1) % 3];
            let (ina, inb) = (a.z >= n, b.z >= n);
            if ina {
                poly[m] = a;
                m += 1;
            }
            if ina != inb {
                let s = (n - a.z) / (b.z - a.z);
                let mut p = a + (b - a) * s;
                p.z = n;
                poly[m] = p;
                m += 1;
            }
        }
        let ortho = self.ortho;
        let pts = poly.map(|p| {
            if ortho {
                ((DVec2::new(p.x, p.y) - self.x0) / self.delta, p.z)
            } else {
                (
                    (DVec2::new(p.x, p.y) * (n / p.z) - self.x0) / self.delta,
                    1.0 / p.z,
                )
            }
        });
        let r = self.r;
        // Fewer than three vertices (m < 3) leave no triangle.
        (1..m.max(2) - 1)
            .map(move |k| [pts[0], pts[k], pts[k + 1]])
            .filter(move |tri| {
                // Quick reject outside the map.
                let lo = tri[0].0.min(tri[1].0).min(tri[2].0);
                let hi = tri[0].0.max(tri[1].0).max(tri[2].0);
                !(hi.x < 0.0
                    || hi.y < 0.0
                    || lo.x > r
                    || lo.y > r
                    || !lo.is_finite()
                    || !hi.is_finite())
            })
    }
}

/// Light-space triangles of a scene for one view, clipped and projected once and reused by every
/// peeling pass.
pub struct PreparedScene {
    tris: Vec<Prepared>,
    r: u32,
    /// Orthographic view: the depth term is z, not 1/z.
    ortho: bool,
}

impl PreparedScene {
    /// Transforms, culls, clips (z >= n) and projects the scene's triangles.
    pub fn new(scene: &Scene, view: &LightView, cull: Cull) -> Self {
        let mut tris = Vec::with_capacity(scene.triangles().len());
        let proj = TexelProjection::new(view);
        for (ti, t) in scene.triangles().iter().enumerate() {
            let alpha = scene.triangle_opacity(ti);
            let l: [Vec3; 3] = t.map(|v| view.frame.to_light(v));
            let l = l.map(|v| v.as_dvec3());
            let normal = (l[1] - l[0]).cross(l[2] - l[0]);
            // Towards the centre of projection; orthographic: towards -e_z.
            let facing_light = if proj.is_ortho() {
                normal.z < 0.0
            } else {
                normal.dot(l[0]) < 0.0
            };
            match cull {
                Cull::Back if !facing_light => continue,
                Cull::Front if facing_light => continue,
                _ => {}
            }
            for tri in proj.clip_project(l) {
                tris.push(Prepared {
                    uv: tri.map(|p| p.0),
                    inv_z: tri.map(|p| p.1),
                    alpha,
                });
            }
        }
        PreparedScene {
            tris,
            r: view.r,
            ortho: view.is_ortho(),
        }
    }

    /// Number of prepared (clipped, possibly split) triangles.
    pub fn len(&self) -> usize {
        self.tris.len()
    }
    /// No triangle survived culling and clipping.
    pub fn is_empty(&self) -> bool {
        self.tris.is_empty()
    }

    /// Rasterises the nearest depth per texel. With `behind = Some(prev)`, only fragments strictly
    /// behind `prev` (`z > prev * (1 + PEEL_EPS_REL)`) count: one depth-peeling pass (Bavoil §4.1).
    pub fn rasterize(&self, bias: DepthBias, behind: Option<&DepthMap>) -> DepthMap {
        self.raster(bias, behind, false).0
    }

    /// [`PreparedScene::rasterize`], and the opacity of each texel's nearest stored fragment
    /// (its mesh's `opacity`; 0 where the texel is empty), row-major like the depths. The depths
    /// are the same, bit for bit; of fragments at exactly the same stored depth the first
    /// triangle in scene order gives the opacity. What the transmittance of semi-transparent
    /// occluders needs from one layer.
    pub fn rasterize_with_opacity(
        &self,
        bias: DepthBias,
        behind: Option<&DepthMap>,
    ) -> (DepthMap, Vec<f32>) {
        let (d, a) = self.raster(bias, behind, true);
        (d, a.unwrap_or_default())
    }

    fn raster(
        &self,
        bias: DepthBias,
        behind: Option<&DepthMap>,
        with_alpha: bool,
    ) -> (DepthMap, Option<Vec<f32>>) {
        let r = self.r as usize;
        let band = 16usize;
        let nb = r.div_ceil(band);
        // Bin triangles by row band.
        let mut bins: Vec<Vec<u32>> = vec![Vec::new(); nb];
        for (k, t) in self.tris.iter().enumerate() {
            let vlo = t.uv[0].y.min(t.uv[1].y).min(t.uv[2].y);
            let vhi = t.uv[0].y.max(t.uv[1].y).max(t.uv[2].y);
            let j0 = ((vlo - 0.5).ceil().max(0.0) as usize).min(r);
            let j1 = (((vhi - 0.5).floor() + 1.0).max(0.0) as usize).min(r);
            if j0 >= j1 {
                continue;
            }
            for bin in &mut bins[j0 / band..=(j1 - 1) / band] {
                bin.push(k as u32);
            }
        }
        let mut out = DepthMap::empty(self.r);
        let mut alpha = with_alpha.then(|| vec![0.0f32; r * r]);
        let raster_band = |b: usize, rows: &mut [f32], mut arows: Option<&mut [f32]>| {
            let row0 = b * band;
            for &k in &bins[b] {
                let t = &self.tris[k as usize];
                let out = Band {
                    row0,
                    rows: &mut *rows,
                    alpha: arows.as_deref_mut(),
                };
                raster_triangle(t, r, out, bias, behind, self.ortho);
            }
        };
        match alpha.as_mut() {
            Some(a) => out
                .depth
                .par_chunks_mut(band * r)
                .zip(a.par_chunks_mut(band * r))
                .enumerate()
                .for_each(|(b, (rows, arows))| raster_band(b, rows, Some(arows))),
            None => out
                .depth
                .par_chunks_mut(band * r)
                .enumerate()
                .for_each(|(b, rows)| raster_band(b, rows, None)),
        }
        (out, alpha)
    }
}

/// The edge function of `s -> e` at `p` (positive to the left), always evaluated from the same end
/// of the edge (the lexicographically smaller), so the two triangles sharing an edge get exactly
/// opposite values, bit for bit: no centre is covered by both or missed by both (watertight),
/// whatever the rounding. Evaluating from each triangle's own start vertex is not: measured, it
/// left a row of uncovered texels along the diagonal of a quad whose centres lie on it exactly.
#[inline]
pub fn edge_function(s: DVec2, e: DVec2, p: DVec2) -> f64 {
    if (s.x, s.y) <= (e.x, e.y) {
        (e - s).perp_dot(p - s)
    } else {
        -(s - e).perp_dot(p - e)
    }
}

/// The top-left rule (as Vulkan and D3D): with the triangle's signed area positive, an edge
/// `(du, dv)` owns the texel centres exactly on it when it is a left edge (`dv < 0`) or a top edge
/// (`dv == 0 && du > 0`).
#[inline]
pub fn owns_ties(du: f64, dv: f64) -> bool {
    dv < 0.0 || (dv == 0.0 && du > 0.0)
}

/// The texels whose centres `(i + 0.5, j + 0.5)` can lie in the triangle `uv` (continuous
/// texel coordinates): its bounding box's columns `i` of the `r`-wide map and rows `j` within
/// `rows`, as half-open ranges (empty where the box misses them; a NaN bound counts as 0, or
/// `rows.start`).
pub fn texel_span(
    uv: [DVec2; 3],
    r: usize,
    rows: std::ops::Range<usize>,
) -> (std::ops::Range<usize>, std::ops::Range<usize>) {
    let [a, b, c] = uv;
    let lo = a.min(b).min(c);
    let hi = a.max(b).max(c);
    let i0 = ((lo.x - 0.5).ceil().max(0.0) as usize).min(r);
    let i1 = (((hi.x - 0.5).floor() + 1.0).max(0.0) as usize).min(r);
    let j0 = ((lo.y - 0.5).ceil().max(rows.start as f64) as usize).min(rows.end);
    let j1 = (((hi.y - 0.5).floor() + 1.0).max(0.0) as usize).min(rows.end);
    (i0..i1, j0..j1)
}

/// The rows of the map one band of the raster writes: from row `row0`, depths and (optionally)
/// opacities.
struct Band<'a> {
    row0: usize,
    rows: &'a mut [f32],
    alpha: Option<&'a mut [f32]>,
}

/// The columns of one row a triangle can cover (`maybe`) and, within them, those it covers beyond
/// doubt (`sure`); the fill rule's own test decides the rest, so the window changes no texel.
struct RowWindow {
    maybe: std::ops::Range<usize>,
    sure: std::ops::Range<usize>,
}

/// Texels this far (in texels) from an edge's crossing of the row are decided by the crossing
/// alone: the edge function there is at least `|dv| * WINDOW_MARGIN`, beyond its rounding.
const WINDOW_MARGIN: f64 = 2.0;

/// [`RowWindow`] of the row whose centres lie at `v = pv`, within `cols`, for the positive-area
/// triangle `edges` (`own`: each edge's tie rule); `None` when no centre of the row is covered.
/// Per edge `s -> e` the edge function along the row is affine in u,
/// `(e.u - s.u)(pv - s.v) - dv (u - s.u)` with `dv = e.v - s.v`, so it crosses zero once. An edge
/// with `dv == 0` has the same value at every centre of the row (the `dv` term is exactly 0): it
/// is evaluated once. An edge whose `|dv|` is too small for its crossing to be trusted next to the
/// rounding of coordinates of magnitude `scale` (`|dv| < 1e-12 scale^2`) bounds nothing, and
/// leaves `sure` empty.
fn row_window(
    edges: &[(DVec2, DVec2); 3],
    own: &[bool; 3],
    pv: f64,
    scale: f64,
    cols: std::ops::Range<usize>,
) -> Option<RowWindow> {
    let (mut lo, mut hi) = (cols.start as f64, cols.end as f64 - 1.0);
    let (mut sure_lo, mut sure_hi) = (lo, hi);
    let mut sure_any = true;
    for ((s, e), own) in edges.iter().zip(own) {
        let dv = e.y - s.y;
        if dv == 0.0 {
            let ef = edge_function(*s, *e, DVec2::new(s.x, pv));
            if ef < 0.0 || (ef == 0.0 && !own) {
                return None;
            }
            continue;
        }
        if dv.abs() < 1e-12 * scale * scale {
            sure_any = false;
            continue;
        }
        // The crossing in column index (centre u = i + 0.5).
        let x = s.x + (e.x - s.x) * (pv - s.y) / dv - 0.5;
        if dv > 0.0 {
            hi = hi.min((x + WINDOW_MARGIN).floor());
            sure_hi = sure_hi.min((x - WINDOW_MARGIN).floor());
        } else {
            lo = lo.max((x - WINDOW_MARGIN).ceil());
            sure_lo = sure_lo.max((x + WINDOW_MARGIN).ceil());
        }
    }
    if !(lo <= hi) {
        return None;
    }
    let maybe = lo as usize..hi as usize + 1;
    let sure = if sure_any && sure_lo <= sure_hi {
        sure_lo as usize..sure_hi as usize + 1
    } else {
        0..0
    };
    Some(RowWindow { maybe, sure })
}

/// One triangle into one band. The depth term interpolated over (u, v) is 1/z in perspective,
/// z in an orthographic view (`ortho`); both are affine in (u, v).
fn raster_triangle(
    t: &Prepared,
    r: usize,
    band: Band<'_>,
    bias: DepthBias,
    behind: Option<&DepthMap>,
    ortho: bool,
) {
    let Band {
        row0,
        rows,
        alpha: mut alpha_rows,
    } = band;
    let nrows = rows.len() / r;
    let [mut a, mut b, c] = t.uv;
    let [mut za, mut zb, zc] = t.inv_z;
    let mut area = (b - a).perp_dot(c - a);
    if area == 0.0 || !area.is_finite() {
        return;
    }
    if area < 0.0 {
        std::mem::swap(&mut a, &mut b);
        std::mem::swap(&mut za, &mut zb);
        area = -area;
    }
    // Plane of 1/z over (u, v): iz(p) = za + gu (u - a.u) + gv (v - a.v).
    let e1 = b - a;
    let e2 = c - a;
    let gu = ((zb - za) * e2.y - (zc - za) * e1.y) / area;
    let gv = ((zc - za) * e1.x - (zb - za) * e2.x) / area;
    let (cols, rows_hit) = texel_span([a, b, c], r, row0..row0 + nrows);
    let edges = [(a, b), (b, c), (c, a)];
    let own = edges.map(|(p, q)| owns_ties(q.x - p.x, q.y - p.y));
    let covers = |p: DVec2| {
        edges.iter().zip(own).all(|((s, e), own)| {
            let ef = edge_function(*s, *e, p);
            !(ef < 0.0 || (ef == 0.0 && !own))
        })
    };
    let scale = [a, b, c]
        .iter()
        .fold(r as f64, |m, v| m.max(v.x.abs()).max(v.y.abs()));
    for j in rows_hit {
        let pv = j as f64 + 0.5;
        let Some(w) = row_window(&edges, &own, pv, scale, cols.clone()) else {
            continue;
        };
        for i in w.maybe {
            let p = DVec2::new(i as f64 + 0.5, pv);
            if !w.sure.contains(&i) && !covers(p) {
                continue;
            }
            let iz = za + gu * (p.x - a.x) + gv * (p.y - a.y);
            if !(iz > 0.0) {
                continue;
            }
            let z = if ortho { iz } else { 1.0 / iz };
            let mut zs = z as f32;
            if bias.constant != 0.0 || bias.slope != 0.0 {
                // dz/du = -z^2 d(1/z)/du (orthographic: the plane's own gradient).
                let g = gu.abs().max(gv.abs());
                let slope = (if ortho { g } else { z * z * g }) as f32;
                zs += bias.constant + bias.slope * slope;
            }
            let idx = (j - row0) * r + i;
            if let Some(prev) = behind {
                let pz = prev.depth[j * r + i];
                if !(zs > pz * (1.0 + PEEL_EPS_REL)) {
                    continue;
                }
            }
            if zs < rows[idx] {
                rows[idx] = zs;
                if let Some(ar) = alpha_rows.as_deref_mut() {
                    ar[idx] = t.alpha;
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The fill rule's own per-texel test (the rasteriser before row windows).
    fn covered(edges: &[(DVec2, DVec2); 3], own: &[bool; 3], p: DVec2) -> bool {
        edges.iter().zip(own).all(|((s, e), own)| {
            let ef = edge_function(*s, *e, p);
            !(ef < 0.0 || (ef == 0.0 && !own))
        })
    }

    /// A row window skips only texels the per-texel test leaves uncovered, and marks sure only
    /// texels it covers: on random triangles with ties (centres on edges, horizontal and vertical
    /// edges), nearly horizontal edges, slivers and coordinates far outside the map.
    #[test]
    fn row_windows_change_no_texel() {
        use proptest::{
            prelude::Rng,
            test_runner::{RngAlgorithm, TestRng},
        };
        let mut rng = TestRng::deterministic_rng(RngAlgorithm::ChaCha);
        let mut next = move || (rng.next_u64() >> 11) as f64 / (1u64 << 53) as f64;
        let r = 64usize;
        let (mut rows, mut sure_texels, mut covered_texels) = (0, 0usize, 0usize);
        for t in 0..4000 {
            let mut coord = |k: usize| -> f64 {
                let x = next();
                match (t + k) % 5 {
                    0 => (x * 80.0 - 8.0).round() * 0.5,
                    1 => x * 80.0 - 8.0,
                    2 => x * 2.0e6 - 1.0e6,
                    _ => x * 70.0 - 3.0,
                }
            };
            let mut v = [0usize, 1, 2].map(|k| DVec2::new(coord(2 * k), coord(2 * k + 1)));
            match t % 7 {
                // A horizontal edge, and a nearly horizontal one.
                0 => v[1].y = v[0].y,
                1 => v[1].y = v[0].y + 1e-9 * (next() - 0.5),
                // A sliver.
                2 => v[2] = v[0] + (v[1] - v[0]) * next() + DVec2::splat(1e-7),
                _ => {}
            }
            let [mut a, mut b, c] = v;
            let area = (b - a).perp_dot(c - a);
            if area == 0.0 || !area.is_finite() {
                continue;
            }
            if area < 0.0 {
                std::mem::swap(&mut a, &mut b);
            }
            let edges = [(a, b), (b, c), (c, a)];
            let own = edges.map(|(p, q)| owns_ties(q.x - p.x, q.y - p.y));
            let scale = [a, b, c]
                .iter()
                .fold(r as f64, |m, v| m.max(v.x.abs()).max(v.y.abs()));
            let (cols, rows_hit) = texel_span([a, b, c], r, 0..r);
            for j in rows_hit {
                rows += 1;
                let pv = j as f64 + 0.5;
                let w = row_window(&edges, &own, pv, scale, cols.clone());
                for i in cols.clone() {
                    let inside = covered(&edges, &own, DVec2::new(i as f64 + 0.5, pv));
                    covered_texels += usize::from(inside);
                    let (maybe, sure) = w.as_ref().map_or((false, false), |w| {
                        (w.maybe.contains(&i), w.sure.contains(&i))
                    });
                    assert!(
                        !inside || maybe,
                        "triangle {t} {v:?}: texel ({i}, {j}) skipped"
                    );
                    assert!(
                        !sure || inside,
                        "triangle {t} {v:?}: texel ({i}, {j}) not covered"
                    );
                    sure_texels += usize::from(sure);
                }
            }
        }
        // The windows do their work: most covered texels need no edge test.
        assert!(rows > 10_000, "{rows} rows");
        assert!(
            sure_texels * 10 > covered_texels * 7,
            "{sure_texels} sure of {covered_texels} covered"
        );
    }
}
