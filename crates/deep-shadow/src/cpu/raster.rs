//! Fragment rasteriser for the deep shadow map: like the core's
//! [`shadow_map_core::raster`] (texel centres, top-left rule, perspective-correct linear z,
//! near-plane clipping), but it keeps *every* fragment with its opacity instead of the nearest
//! depth. The engine path (`crate::gpu`, feature `gpu`) inserts its fragments from the
//! hardware rasteriser instead, whose sub-pixel vertex snapping can decide a texel centre close
//! to an edge differently.
use glam::{DVec2, Vec3};
use rayon::prelude::*;
use shadow_map_core::{
    raster::{texel_span, TexelProjection},
    LightView, Scene,
};

/// A triangle after clipping to z >= n and projection to continuous texel coordinates, with the
/// opacity of its mesh. Triangles of fully transparent meshes (opacity 0) are dropped: they
/// change no transmittance.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PreparedTri {
    /// Texel coordinates (u, v) of the vertices, ordered so the signed area is positive.
    pub uv: [DVec2; 3],
    /// The depth term at the vertices, affine in (u, v): 1/z, or z itself in an orthographic
    /// view (the sun; [`TexelProjection::clip_project`]).
    pub inv_z: [f64; 3],
    /// The view is orthographic: [`inv_z`](Self::inv_z) holds z.
    pub ortho: bool,
    /// Opacity alpha of the mesh.
    pub alpha: f32,
}

/// One rasterised fragment: texel index `j * r + i`, linear depth, opacity.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Fragment {
    /// Texel index `j * r + i`.
    pub texel: u32,
    /// Linear light-space depth z.
    pub depth: f32,
    /// Opacity.
    pub alpha: f32,
}

/// Transforms, clips (z >= n) and projects every triangle of the scene for `view` (no culling:
/// hair is two-sided). Same arithmetic as the core's `PreparedScene::new`: both clip and
/// project with [`TexelProjection::clip_project`].
pub fn prepare(scene: &Scene, view: &LightView) -> Vec<PreparedTri> {
    let proj = TexelProjection::new(view);
    let mut out = Vec::with_capacity(scene.triangles().len());
    for (t, tri) in scene.triangles().iter().enumerate() {
        let alpha = scene.triangle_opacity(t);
        if !(alpha > 0.0) {
            continue;
        }
        let l: [Vec3; 3] = tri.map(|v| view.frame.to_light(v));
        let l = l.map(|v| v.as_dvec3());
        for mut tri in proj.clip_project(l) {
            let area = (tri[1].0 - tri[0].0).perp_dot(tri[2].0 - tri[0].0);
            if area == 0.0 || !area.is_finite() {
                continue;
            }
            if area < 0.0 {
                tri.swap(0, 1);
            }
            out.push(PreparedTri {
                uv: tri.map(|p| p.0),
                inv_z: tri.map(|p| p.1),
                alpha,
                ortho: proj.is_ortho(),
            });
        }
    }
    out
}

/// The core raster's fill rule (one definition): the top-left rule and the watertight edge
/// function.
pub use shadow_map_core::raster::{edge_function, owns_ties};

/// Calls `emit(i, j, z)` for every texel centre of the `r x r` map in rows `rows.0..rows.1` inside
/// `t` (top-left rule), with the perspective-correct linear depth z there.
pub fn raster_tri(t: &PreparedTri, r: u32, rows: (u32, u32), mut emit: impl FnMut(u32, u32, f32)) {
    let [a, b, c] = t.uv;
    let [za, zb, zc] = t.inv_z;
    let area = (b - a).perp_dot(c - a);
    if !(area > 0.0) {
        return;
    }
    let e1 = b - a;
    let e2 = c - a;
    let gu = ((zb - za) * e2.y - (zc - za) * e1.y) / area;
    let gv = ((zc - za) * e1.x - (zb - za) * e2.x) / area;
    let (cols, rows_hit) = texel_span(t.uv, r as usize, rows.0 as usize..rows.1.min(r) as usize);
    let edges = [(a, b), (b, c), (c, a)];
    let own = edges.map(|(p, q)| owns_ties(q.x - p.x, q.y - p.y));
    for j in rows_hit.map(|j| j as u32) {
        let pv = j as f64 + 0.5;
        for i in cols.clone().map(|i| i as u32) {
            let p = DVec2::new(i as f64 + 0.5, pv);
            let inside = edges.iter().enumerate().all(|(k, (s, e))| {
                let ef = edge_function(*s, *e, p);
                ef > 0.0 || (ef == 0.0 && own[k])
            });
            if !inside {
                continue;
            }
            let iz = za + gu * (p.x - a.x) + gv * (p.y - a.y);
            if !(iz > 0.0) {
                continue;
            }
            let z = if t.ortho { iz } else { 1.0 / iz } as f32;
            if z.is_finite() {
                emit(i, j, z);
            }
        }
    }
}

/// Every fragment of the prepared triangles, rasterised in parallel over 16-row bands and returned
/// in a deterministic order (band, then triangle, then row-major texel).
pub fn fragments(tris: &[PreparedTri], r: u32) -> Vec<Fragment> {
    let band = 16u32;
    let nb = r.div_ceil(band) as usize;
    let mut bins: Vec<Vec<u32>> = vec![Vec::new(); nb];
    for (k, t) in tris.iter().enumerate() {
        let (_, rows) = texel_span(t.uv, r as usize, 0..r as usize);
        if rows.is_empty() {
            continue;
        }
        for bin in &mut bins[rows.start / band as usize..=(rows.end - 1) / band as usize] {
            bin.push(k as u32);
        }
    }
    let per_band: Vec<Vec<Fragment>> = bins
        .par_iter()
        .enumerate()
        .map(|(b, bin)| {
            let (row0, row1) = (b as u32 * band, ((b as u32 + 1) * band).min(r));
            let mut out = Vec::new();
            for &k in bin {
                let t = &tris[k as usize];
                raster_tri(t, r, (row0, row1), |i, j, z| {
                    out.push(Fragment {
                        texel: j * r + i,
                        depth: z,
                        alpha: t.alpha,
                    });
                });
            }
            out
        })
        .collect();
    per_band.concat()
}
