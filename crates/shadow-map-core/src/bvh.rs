//! Ray queries against the scene through a BVH from the `obvhs` crate (PLOC-built BVH2).
//!
//! Shared by the camera G-buffer and the ray-traced `reference` crate, so both see exactly the
//! same geometry.
use crate::scene::Scene;
use glam::{Vec3, Vec3A};
use obvhs::{
    bvh2::{builder::build_bvh2_from_tris, Bvh2},
    ray::{Ray, RayHit},
    triangle::Triangle,
    BvhBuildParams,
};

/// A BVH over the scene's triangles, with their opacities.
pub struct SceneBvh {
    bvh: Bvh2,
    tris: Vec<Triangle>,
    opacity: Vec<f32>,
    /// Scene bounds diagonal, the scale for ray offsets.
    pub scale: f32,
}

/// A closest hit.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Hit {
    /// Distance along the (unit) ray.
    pub t: f32,
    /// Triangle index in [`Scene::triangles`].
    pub triangle: usize,
}

impl SceneBvh {
    /// Builds the BVH (medium-quality PLOC preset).
    pub fn new(scene: &Scene) -> Self {
        let tris: Vec<Triangle> = scene
            .triangles()
            .iter()
            .map(|t| Triangle {
                v0: t[0].into(),
                v1: t[1].into(),
                v2: t[2].into(),
            })
            .collect();
        let bvh = build_bvh2_from_tris(
            &tris,
            BvhBuildParams::medium_build(),
            &mut Default::default(),
        );
        let opacity = (0..scene.triangles().len())
            .map(|i| scene.triangle_opacity(i))
            .collect();
        SceneBvh {
            bvh,
            tris,
            opacity,
            scale: scene.bounds().diagonal().max(1e-6),
        }
    }

    /// Closest hit of the ray `origin + t dir`, `t in (t_min, t_max)`.
    pub fn closest_hit(&self, origin: Vec3, dir: Vec3, t_min: f32, t_max: f32) -> Option<Hit> {
        let ray = Ray::new(Vec3A::from(origin), Vec3A::from(dir), t_min, t_max);
        let mut hit = RayHit::none();
        let found = self.bvh.ray_traverse(ray, &mut hit, |r, id| {
            let tri = self.bvh.primitive_indices[id] as usize;
            self.tris[tri].intersect(r)
        });
        if found && hit.t.is_finite() {
            Some(Hit {
                t: hit.t,
                triangle: self.bvh.primitive_indices[hit.primitive_id as usize] as usize,
            })
        } else {
            None
        }
    }

    /// Transmittance along the segment `origin + t dir`, `t in (t_min, t_max)`: the product of
    /// `(1 - opacity)` over every distinct surface crossed (0 as soon as an opaque one is hit).
    pub fn transmittance(&self, origin: Vec3, dir: Vec3, t_min: f32, t_max: f32) -> f32 {
        let ray = Ray::new(Vec3A::from(origin), Vec3A::from(dir), t_min, t_max);
        let mut hit = RayHit::none();
        let mut opaque = false;
        let mut crossed: Vec<u32> = Vec::new();
        self.bvh.ray_traverse(ray, &mut hit, |r, id| {
            if opaque {
                return f32::INFINITY;
            }
            let tri = self.bvh.primitive_indices[id];
            let t = self.tris[tri as usize].intersect(r);
            if t.is_finite() && t > t_min && t < t_max {
                let o = self.opacity[tri as usize];
                if o >= 1.0 {
                    opaque = true;
                    return t;
                }
                if !crossed.contains(&tri) {
                    crossed.push(tri);
                }
            }
            f32::INFINITY
        });
        if opaque {
            return 0.0;
        }
        crossed
            .iter()
            .map(|&t| 1.0 - self.opacity[t as usize])
            .product()
    }

    /// Whether `test` holds for some triangle whose bounding box meets the box `[lo, hi]` and
    /// is not wholly outside one of the convex region's `planes` (each `[a, b, c, d]`, inside
    /// where `a x + b y + c z + d >= 0`). Nodes are culled by the box and by the planes (a node
    /// is outside a plane when its box corner furthest along the plane's normal is), so a
    /// narrow region visits few nodes; stops at the first triangle that passes.
    pub fn any_in_convex(
        &self,
        lo: Vec3,
        hi: Vec3,
        planes: &[[f64; 4]],
        mut test: impl FnMut(&[Vec3; 3]) -> bool,
    ) -> bool {
        let nodes = &self.bvh.nodes;
        if nodes.is_empty() {
            return false;
        }
        let visible = |k: u32| -> bool {
            let a = nodes[k as usize].aabb();
            let (nlo, nhi) = (Vec3::from(a.min), Vec3::from(a.max));
            if nlo.cmpgt(hi).any() || nhi.cmplt(lo).any() {
                return false;
            }
            planes.iter().all(|pl| {
                let x = if pl[0] >= 0.0 { nhi.x } else { nlo.x } as f64;
                let y = if pl[1] >= 0.0 { nhi.y } else { nlo.y } as f64;
                let z = if pl[2] >= 0.0 { nhi.z } else { nlo.z } as f64;
                pl[0] * x + pl[1] * y + pl[2] * z + pl[3] >= 0.0
            })
        };
        let mut stack: Vec<u32> = Vec::with_capacity(64);
        if visible(0) {
            stack.push(0);
        }
        while let Some(k) = stack.pop() {
            let node = &nodes[k as usize];
            if node.is_leaf() {
                let first = node.first_index as usize;
                for i in first..first + node.prim_count as usize {
                    let t = &self.tris[self.bvh.primitive_indices[i] as usize];
                    if test(&[t.v0.into(), t.v1.into(), t.v2.into()]) {
                        return true;
                    }
                }
            } else {
                for c in [node.first_index, node.first_index + 1] {
                    if visible(c) {
                        stack.push(c);
                    }
                }
            }
        }
        false
    }

    /// Geometric unit normal of a triangle (from its winding).
    pub fn normal(&self, triangle: usize) -> Vec3 {
        let t = &self.tris[triangle];
        Vec3::from((t.v1 - t.v0).cross(t.v2 - t.v0)).normalize_or_zero()
    }
}
