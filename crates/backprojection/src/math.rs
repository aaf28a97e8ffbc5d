//! Pure geometry of micropatch backprojection (docs/methods.md §2; Bavoil 2008 eq. 1, §3).
//!
//! Conventions: light space with the light centre at the origin, light plane z = 0, shadow-map
//! plane z = n, texel coordinates `u = (n x / z - x0) / delta` (see
//! [`shadow_map_core::LightView`]). Lengths returned on the light plane are world units relative
//! to the light centre.

/// Largest magnitude a backprojected bound may take. Bounds that would overflow (a sample almost
/// at the receiver's depth) are clamped to +-`FAR_BOUND`, which keeps them finite and keeps their
/// limit meaning: a micropatch containing the receiver's projection covers the whole light, the
/// others leave it.
pub const FAR_BOUND: f32 = 1e30;

pub use shadow_map_core::mssm::kernel_width;
pub use shadow_map_core::silhouette::{
    hull_point, Silhouette, HULL_DIRS, HULL_SCALE, SILHOUETTE_HULL,
};

/// `(k, ortho)` of a view for [`micropatch_scale`] and [`backprojected_micropatch`]: the texel
/// pitch over n in perspective, the texel pitch itself for an orthographic view (the sun;
/// docs/methods.md §2 "Backprojected micropatch", §14 "Backprojection").
#[inline]
pub fn micropatch_k(view: &shadow_map_core::LightView) -> (f32, bool) {
    if view.is_ortho() {
        (view.delta(), true)
    } else {
        (view.delta() / view.n, false)
    }
}

/// Scale of a backprojected texel on the light plane (docs/methods.md §2 "Backprojected
/// micropatch"; Bavoil eq. 1 before his division by l):
///
/// `S = k z_s z_p / (z_p - z_s)`, `k = w / (n r)` (the texel pitch over n).
///
/// Guarded: `z_p - z_s` is floored at `1e-7 z_p` (the f32 resolution of depths near `z_p`) so S
/// stays finite (its limit is +inf); samples at or behind the receiver (`z_s >= z_p`) or at or
/// behind the light (`z_s <= 0`) return 0 (they block nothing). Never NaN for finite inputs.
///
/// The sun (`ortho`, docs/methods.md §14 "Backprojection"): texel offsets are world offsets
/// (`k = delta`) and the micropatch is carried onto the disk of directions at unit distance, the
/// direction from p through a point `z_p - z_s` nearer the sun and `x` across being `x / (z_p - z_s)`:
/// `S = delta / (z_p - z_s)`, with the same guards.
#[inline]
pub fn micropatch_scale(k: f32, z_s: f32, z_p: f32, ortho: bool) -> f32 {
    if !(z_s > 0.0) || !(z_s < z_p) || !(k > 0.0) {
        return 0.0;
    }
    let gap = (z_p - z_s).max(1e-7 * z_p).max(f32::MIN_POSITIVE);
    let s = if ortho {
        k / gap
    } else {
        k * z_s * (z_p / gap)
    };
    if s.is_finite() {
        s
    } else {
        f32::MAX
    }
}

/// An axis-aligned rectangle `[x0, x1] x [y0, y1]` on the light plane.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Rect {
    /// Smallest x.
    pub x0: f32,
    /// Smallest y.
    pub y0: f32,
    /// Largest x.
    pub x1: f32,
    /// Largest y.
    pub y1: f32,
}

/// Backprojects the micropatch covering the texel span `[i0, i1] x [j0, j1]` (texel coordinates;
/// `[i, i+1] x [j, j+1]` for one texel, wider for the adaptive step of Bavoil §5) at depth `z_s`
/// from the receiver at texel coordinates `(u_p, v_p)` and depth `z_p` onto the light plane
/// (docs/methods.md §2, exact closed form; Bavoil eq. 1):
///
/// `B_s = [(i0 - u_p) S, (i1 - u_p) S] x [(j0 - v_p) S, (j1 - v_p) S]`, S from
/// [`micropatch_scale`].
///
/// Bounds are clamped to +-[`FAR_BOUND`]: when `z_p - z_s` is tiny, a micropatch whose span
/// contains `(u_p, v_p)` becomes a rectangle containing the whole light (the limit), and one that
/// does not moves off to infinity. Never NaN or inf for finite inputs.
#[inline]
pub fn backprojected_micropatch(
    span: [f32; 4],
    uv_p: [f32; 2],
    (k, ortho): (f32, bool),
    z_s: f32,
    z_p: f32,
) -> Rect {
    let s = micropatch_scale(k, z_s, z_p, ortho);
    let b = |t: f32, c: f32| {
        let d = t - c;
        if d == 0.0 || s == 0.0 {
            0.0
        } else {
            (d * s).clamp(-FAR_BOUND, FAR_BOUND)
        }
    };
    Rect {
        x0: b(span[0], uv_p[0]),
        x1: b(span[1], uv_p[0]),
        y0: b(span[2], uv_p[1]),
        y1: b(span[3], uv_p[1]),
    }
}

/// Area of `rect ∩ L` for the rectangle light `L = [-l_x/2, l_x/2] x [-l_y/2, l_y/2]`
/// (docs/methods.md §2 "Estimator": `area(B_s(p) ∩ L)`). 0 for empty or inverted rectangles.
#[inline]
pub fn light_overlap_area(rect: &Rect, half: [f32; 2]) -> f64 {
    let dx = (rect.x1.min(half[0]) as f64 - rect.x0.max(-half[0]) as f64).max(0.0);
    let dy = (rect.y1.min(half[1]) as f64 - rect.y0.max(-half[1]) as f64).max(0.0);
    dx * dy
}

/// Smallest carried overlap, relative to the silhouette disk's area, that counts as a contribution
/// ([`Emitter::contributes`]).
pub const CONTRIBUTION_REL: f32 = 1e-6;

/// The emitting surface as backprojection measures it (docs/methods.md §2 "Disk and sphere
/// lights"): occlusion is the area of each backprojected micropatch `B_s` (a rectangle on the
/// light plane z = 0) inside the light, over the light's area.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Emitter {
    /// `[-hx, hx] x [-hy, hy]` in the light plane.
    Rect {
        /// Half extents.
        half: [f32; 2],
    },
    /// The disk of this radius at the origin of the light plane.
    Disk {
        /// Radius.
        radius: f32,
    },
    /// The contract's sphere: per receiver p, the disk of this radius through the centre,
    /// perpendicular to p ([`Silhouette`]).
    Sphere {
        /// Radius.
        radius: f32,
    },
}

/// Area of `rect` (on z = 0) carried onto the silhouette disk `s`, inside the disk
/// ([`Silhouette::overlap_rect`]).
#[inline]
pub fn overlap_on(s: &Silhouette, rect: &Rect) -> f32 {
    s.overlap_rect(rect.x0, rect.y0, rect.x1, rect.y1)
}

impl Emitter {
    /// The emitter of a light.
    pub fn of(shape: &shadow_map_core::LightShape) -> Emitter {
        match *shape {
            shadow_map_core::LightShape::Rect { size } => Emitter::Rect {
                half: [0.5 * size[0], 0.5 * size[1]],
            },
            shadow_map_core::LightShape::Disk { radius } => Emitter::Disk { radius },
            shadow_map_core::LightShape::Sphere { radius } => Emitter::Sphere { radius },
            // The sun: its disk of directions at unit distance, onto which an orthographic
            // view's micropatches are carried ([`micropatch_scale`]).
            shadow_map_core::LightShape::Directional { .. } => Emitter::Disk {
                radius: shape.tan_half(),
            },
        }
    }

    /// Area `A_L` (f64; a sphere's silhouette disk).
    pub fn area(&self) -> f64 {
        match *self {
            Emitter::Rect { half } => 4.0 * half[0] as f64 * half[1] as f64,
            Emitter::Disk { radius } | Emitter::Sphere { radius } => {
                std::f64::consts::PI * radius as f64 * radius as f64
            }
        }
    }

    /// Whether `B_s` covers part of the light (Bavoil §4.2's "non-zero contribution",
    /// `layer_rule=first_nonzero`), decided without the cancellation of a small overlap area:
    /// a rect's overlap is exact; a disk is met when the rectangle's point nearest the centre
    /// lies strictly inside it; on a sphere's silhouette the carried overlap must exceed
    /// [`CONTRIBUTION_REL`] of the disk's area (rounding in the edge sum is about 1e-7 of it).
    #[inline]
    pub fn contributes(&self, rect: &Rect, sil: Option<&Silhouette>) -> bool {
        match *self {
            Emitter::Rect { half } => light_overlap_area(rect, half) > 0.0,
            Emitter::Disk { radius } => {
                if !(rect.x1 > rect.x0 && rect.y1 > rect.y0) {
                    return false;
                }
                let cx = 0.0f32.clamp(rect.x0, rect.x1);
                let cy = 0.0f32.clamp(rect.y0, rect.y1);
                cx * cx + cy * cy < radius * radius
            }
            Emitter::Sphere { radius } => {
                let a = std::f32::consts::PI * radius * radius;
                sil.is_some_and(|s| overlap_on(s, rect) > CONTRIBUTION_REL * a)
            }
        }
    }

    /// `area(B_s ∩ L)` for a light in the plane z = 0 (rect, disk), or on the silhouette `sil`
    /// (sphere; 0 without one).
    #[inline]
    pub fn overlap(&self, rect: &Rect, sil: Option<&Silhouette>) -> f64 {
        match *self {
            Emitter::Rect { half } => light_overlap_area(rect, half),
            Emitter::Disk { radius } => {
                // Clipped to the disk's bounding square first, which keeps the corners finite.
                shadow_map_core::overlap::rect_disk_area(
                    rect.x0.max(-radius),
                    rect.y0.max(-radius),
                    rect.x1.min(radius),
                    rect.y1.min(radius),
                    radius,
                ) as f64
            }
            Emitter::Sphere { .. } => sil.map_or(0.0, |s| overlap_on(s, rect) as f64),
        }
    }
}

/// Gap filling (docs/methods.md §2 "Gap filling", reconstructed): `bound`, a micropatch's far
/// edge on the light plane (`x1` or `y1`), extended to the near edge of its +u or +v
/// neighbour's micropatch, the occluder at true depth `z_t` whose near texel edge lies `d`
/// texels past the receiver's projection: `max(bound, d S_t)`, `d S_t` clamped to
/// +-[`FAR_BOUND`]. `bound` unchanged where the neighbour occludes nothing (`z_t` +inf), blocks
/// nothing (`S_t = 0`) or its edge passes through the receiver's projection (`d = 0`).
#[inline]
pub fn gap_filled(bound: f32, k: (f32, bool), z_t: f32, z_p: f32, d: f32) -> f32 {
    if !z_t.is_finite() {
        return bound;
    }
    let s_t = micropatch_scale(k.0, z_t, z_p, k.1);
    if d != 0.0 && s_t > 0.0 {
        bound.max((d * s_t).clamp(-FAR_BOUND, FAR_BOUND))
    } else {
        bound
    }
}

/// The bit points of `occlusion=bitmask` for `emitter` (B = `bits`): a grid on a rect light,
/// concentric on a disk, on the unit-free silhouette disk of radius `radius` for a sphere
/// (docs/methods.md §2 "Bitmask occlusion"; Schwarz & Stamminger 2007).
pub fn emitter_bits(emitter: &Emitter, bits: u32) -> Vec<glam::Vec2> {
    match *emitter {
        Emitter::Rect { half } => {
            shadow_map_core::bitmask::bit_points(glam::Vec2::from(half), None, bits)
        }
        Emitter::Disk { radius } | Emitter::Sphere { radius } => {
            shadow_map_core::bitmask::bit_points(glam::Vec2::ZERO, Some(radius), bits)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The closed form agrees with projecting the micropatch corners from p onto z = 0.
    #[test]
    fn closed_form_matches_direct_projection() {
        // View: n = 1, window [-1, 1], r = 64.
        let (n, x0, w, r) = (1.0f64, -1.0f64, 2.0f64, 64.0f64);
        let delta = w / r;
        let p = [0.13f64, -0.2, 3.0];
        let u_p = (n * p[0] / p[2] - x0) / delta;
        let v_p = (n * p[1] / p[2] - x0) / delta;
        let (i, j, zs) = (30.0f64, 27.0f64, 1.7f64);
        let world = |u: f64| (u * delta + x0) * zs / n; // x of the sample at texel coord u
        let proj = |xs: f64, xp: f64| (p[2] * xs - zs * xp) / (p[2] - zs);
        let b = backprojected_micropatch(
            [i as f32, i as f32 + 1.0, j as f32, j as f32 + 1.0],
            [u_p as f32, v_p as f32],
            ((w / (n * r)) as f32, false),
            zs as f32,
            p[2] as f32,
        );
        let ex0 = proj(world(i), p[0]);
        let ey1 = proj(world(j + 1.0), p[1]);
        assert!((b.x0 as f64 - ex0).abs() < 1e-5, "{} vs {ex0}", b.x0);
        assert!((b.y1 as f64 - ey1).abs() < 1e-5, "{} vs {ey1}", b.y1);
    }

    #[test]
    fn degenerate_depths_stay_finite() {
        let b = backprojected_micropatch([3.0, 4.0, 3.0, 4.0], [3.5, 3.5], (0.01, false), 2.0, 2.0);
        assert_eq!(light_overlap_area(&b, [0.5, 0.5]), 0.0);
        let b = backprojected_micropatch(
            [3.0, 4.0, 3.0, 4.0],
            [3.5, 3.5],
            (0.01, false),
            1.999_999_9,
            2.0,
        );
        assert!(b.x0.is_finite() && b.x1.is_finite());
        assert!((light_overlap_area(&b, [0.5, 0.5]) - 1.0).abs() < 1e-6);
        assert_eq!(kernel_width(100.0, 1.0, 0.0, 1.0), f32::MAX);
        assert_eq!(kernel_width(100.0, 1.0, 2.0, 1.0), 0.0);
        assert_eq!(micropatch_scale(0.01, 0.0, 1.0, false), 0.0);
        assert_eq!(micropatch_scale(0.01, 1.0, 1.0, true), 0.0);
        assert!(micropatch_scale(0.01, 1.0 - 1e-9, 1.0, true).is_finite());
    }
}
