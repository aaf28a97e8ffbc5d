//! Receiver-plane rejection: which shadow-map samples may shadow a receiver
//! (docs/methods.md §2, "Receiver plane"). Every estimator that compares kernel texels with a
//! receiver asks a [`ReceiverPlane`]; the WGSL twin is `plane_*` in `gpu/math.wgsl`.
//!
//! **The test.** In light space the view's centre of projection is the origin and the sample
//! stored in texel (i, j) at depth `z` is the point `s = z d(u)`, `d(u) = unproject_dir(u)` at the
//! texel centre `u = (i + 1/2, j + 1/2)` (the rasteriser samples texel centres, see
//! [`crate::raster`]). With the receiver at `p` and its unit normal `n` (the lit side), the sample
//! lies in front of the receiver's tangent plane by `h = n.(s - p) = c - z g(u)` with
//! `c = -n.p` (the height of the centre of projection over the plane) and `g(u) = -n.d(u)`,
//! affine in u. The sample is a caster only when `h > tau`:
//!
//! ```text
//! caster  <=>  z finite  and  z < z_p  and  z (g(u) + kappa) < c - tau_p
//! ```
//!
//! a drop-in for the classic `z < z_p - eps` with no division, whatever the kernel's size and the
//! angle of incidence. `z < z_p` keeps what the classic test knew: light reaches p along segments
//! from the light (at z of about 0) to p, so a sample deeper than p cannot lie on one, even when it
//! is in front of the tangent plane (for `g <= 0` the texel's ray never meets the plane on the lit
//! side, and everything on it, however deep, is in front).
//!
//! **Tolerance** (in world units along `n`, so it does not grow at grazing incidence the way a
//! depth bias along z must): `tau = tau_p + kappa z`,
//! - `kappa z` with `kappa = 2^-16 |d|_max`: rounding of the f32 sample position and of `g`
//!   (a few ulps of `|s|`, kept 256 ulps away);
//! - `2^-16 |p|`: rounding of the receiver position (G-buffer hit, frame change);
//! - `2^-9 t(z_p)`, `t(z) = w z / (n r)` the world size of a texel at depth z: a GPU rasteriser
//!   snaps vertices to 1/256 texel (Vulkan's 8 sub-pixel bits), which slides a planar receiver
//!   by at most 1/512 texel across its texel centre, moving its sample off the plane by at most
//!   that much of the footprint;
//! - `b0 t(z_p)`: the user's `bias` (texel footprints, default 0), for meshes whose facets bend
//!   towards the light within a kernel (concave tessellation) when that must not count;
//! - 16-bit maps: the decoded depth is `z + half step` (the nearest code can be half a step
//!   nearer than the surface), and `z_p` is lowered by half a step for the same reason, so the
//!   receiver's own surface just behind it never reads as in front (`tests/workspace/stability.rs`,
//!   grazing receivers under `depth=unorm16`).
//!
//! **Bound.** A receiver on a planar surface is never shadowed by that surface's own samples, for
//! any kernel size, any resolution and any angle of incidence below 90 degrees; a true caster is
//! missed only when it lies within `tau` of the tangent plane (about 1e-5 of its distance from
//! the light, plus `b0 + 1/512` texel footprints), where it can hide at most the light seen
//! within `tau / distance` radians of the plane.
//!
//! With `receiver_plane=false` the same struct performs the classic test `z < z_p - eps`, eps
//! from [`LightView::receiver_bias`] (constant plus slope-scaled bias).
use crate::light_view::LightView;
use crate::params::ParamSpec;
use glam::{Vec2, Vec3};

/// `receiver_plane`: receiver-plane rejection on or off (every estimator with a kernel).
pub const RECEIVER_PLANE: ParamSpec = ParamSpec::flag(true).named("receiver_plane", "a sample shadows the receiver only if it lies in front of the receiver's tangent plane (no bias tuning at any angle); false: the classic depth test against z - bias");

/// Relative rounding allowance of the test (see the module documentation).
pub const ROUNDING: f32 = 1.0 / 65536.0;
/// Raster snapping allowance in texel footprints (half of Vulkan's 1/256 sub-pixel step).
pub const SNAP: f32 = 1.0 / 512.0;

/// The caster test of one receiver: `z finite && z < zp && (z + hs) (g0 + gu u + gv v) < c + cu u + cv v`,
/// u, v the texel centre's coordinates (`cu = cv = 0` in a perspective view; an orthographic
/// view's texel rays are parallel, so the plane's height over them varies with u, v instead). `#[repr(C)]`-free on purpose: the GPU twin rebuilds it from the same
/// inputs in `gpu/math.wgsl` (`plane_new`, `plane_caster`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ReceiverPlane {
    /// `g` at u = v = 0, plus `kappa`.
    pub g0: f32,
    /// `dg/du`.
    pub gu: f32,
    /// `dg/dv`.
    pub gv: f32,
    /// `c - tau_p` (plane) or `z_p - eps` (classic), at u = v = 0.
    pub c: f32,
    /// `dc/du` (orthographic views, else 0).
    pub cu: f32,
    /// `dc/dv` (orthographic views, else 0).
    pub cv: f32,
    /// `z_p - hs`: samples whose stored depth reaches it are never casters (a 16-bit code can
    /// read up to half a step nearer than the surface, so a surface just behind the receiver
    /// must not read as in front of it).
    pub zp: f32,
    /// Half a code step under `depth=unorm16`, else 0.
    pub hs: f32,
}

impl ReceiverPlane {
    /// The receiver-plane test of the receiver at light-space `p` with light-space unit normal `n`
    /// in `view`; `b0` is the user tolerance in texel footprints, `hs` half a code step (16-bit
    /// maps) or 0.
    pub fn plane(view: &LightView, p: Vec3, n: Vec3, b0: f32, hs: f32) -> Self {
        let texel = view.texel_at(p.z);
        if view.is_ortho() {
            // The sample s = (u delta + x0, v delta + y0, z): n.(s - p) > tau  <=>
            // z (-n_z) < -n.p - tau + n_x (u delta + x0) + n_y (v delta + y0). The window
            // corner's size joins the position's rounding.
            let corner = view.window_min.abs().max_element() + view.w;
            let tau = ROUNDING * (p.length() + corner) + (SNAP + b0) * texel;
            let d = view.delta();
            return ReceiverPlane {
                g0: -n.z + ROUNDING,
                gu: 0.0,
                gv: 0.0,
                c: -n.dot(p) - tau + n.x * view.window_min.x + n.y * view.window_min.y,
                cu: n.x * d,
                cv: n.y * d,
                zp: p.z - hs,
                hs,
            };
        }
        let kappa = ROUNDING * view.max_dir_len();
        let tau = ROUNDING * p.length() + (SNAP + b0) * texel;
        // d(u) = ((u delta + window_min) / n_near, 1), g = -n.d.
        let s = view.delta() / view.n;
        let o = view.window_min / view.n;
        ReceiverPlane {
            g0: -(n.x * o.x + n.y * o.y + n.z) + kappa,
            gu: -n.x * s,
            gv: -n.y * s,
            c: -n.dot(p) - tau,
            cu: 0.0,
            cv: 0.0,
            zp: p.z - hs,
            hs,
        }
    }
    /// The classic depth test `z < z_p - eps` (eps from [`LightView::receiver_bias`] with
    /// `b0`, `b1`), in the same form.
    pub fn classic(view: &LightView, p: Vec3, n: Vec3, b0: f32, b1: f32, hs: f32) -> Self {
        ReceiverPlane {
            g0: 1.0,
            gu: 0.0,
            gv: 0.0,
            c: p.z - view.receiver_bias(p, n, b0, b1),
            cu: 0.0,
            cv: 0.0,
            zp: p.z - hs,
            hs,
        }
    }
    /// [`plane`](Self::plane) or [`classic`](Self::classic) as `on` says (the
    /// [`RECEIVER_PLANE`] parameter).
    pub fn new(
        on: bool,
        view: &LightView,
        p: Vec3,
        n: Vec3,
        (b0, b1): (f32, f32),
        hs: f32,
    ) -> Self {
        if on {
            Self::plane(view, p, n, b0, hs)
        } else {
            Self::classic(view, p, n, b0, b1, hs)
        }
    }
    /// `g + kappa` at continuous texel coordinates `uv`.
    #[inline]
    pub fn slope_at(&self, uv: Vec2) -> f32 {
        self.g0 + self.gu * uv.x + self.gv * uv.y
    }
    /// `c + cu u + cv v` at continuous texel coordinates `uv`.
    #[inline]
    pub fn height_at(&self, uv: Vec2) -> f32 {
        self.c + self.cu * uv.x + self.cv * uv.y
    }
    /// True when a sample at depth `z` on the ray through continuous texel coordinates `uv`
    /// shadows the receiver.
    #[inline]
    pub fn caster_at(&self, uv: Vec2, z: f32) -> bool {
        z.is_finite() && z < self.zp && (z + self.hs) * self.slope_at(uv) < self.height_at(uv)
    }
    /// True when the sample at depth `z` stored in texel (i, j) shadows the receiver.
    #[inline]
    pub fn caster(&self, i: i32, j: i32, z: f32) -> bool {
        self.caster_at(Vec2::new(i as f32 + 0.5, j as f32 + 0.5), z)
    }
    /// An upper bound on the depth of any caster on the ray through `uv`, the per-texel form of
    /// `z_p - eps` for estimators that need a depth (a min-depth hierarchy's bound, a blocker's
    /// distance). Where the ray descends towards the plane (`g > 0`) it is exact: a sample is a
    /// caster iff its depth is below `min(z_p, c / g - hs)`. Where it does not (`g <= 0`) the
    /// casters are the samples deeper than `c / g` (every one when `c > 0`) and nearer than
    /// `z_p`, so the bound is `z_p`.
    #[inline]
    pub fn threshold_at(&self, uv: Vec2) -> f32 {
        let g = self.slope_at(uv);
        if g > 0.0 {
            (self.height_at(uv) / g - self.hs).min(self.zp)
        } else {
            self.zp
        }
    }
    /// The largest [`threshold_at`](Self::threshold_at) over the texel rectangle
    /// `[u0, u1] x [v0, v1]` (continuous coordinates): `g` is affine (and `c + cu u + cv v`
    /// only varies where `g` is constant), so the extreme is at a corner. A block of samples whose minimum depth reaches this holds no caster.
    pub fn max_threshold(&self, u0: f32, u1: f32, v0: f32, v1: f32) -> f32 {
        [
            Vec2::new(u0, v0),
            Vec2::new(u1, v0),
            Vec2::new(u0, v1),
            Vec2::new(u1, v1),
        ]
        .into_iter()
        .map(|uv| self.threshold_at(uv))
        .fold(f32::NEG_INFINITY, f32::max)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A view down the world's z axis (window [-1, 1]^2, near 0.5, far 20).
    fn view(r: u32) -> LightView {
        LightView {
            n: 0.5,
            far: 20.0,
            ..LightView::placeholder(r)
        }
    }

    /// A plane through `p` with normal `n` sampled exactly at every texel centre of the map is
    /// never its own caster, at any tilt up to 89.9 degrees and any resolution, while a point
    /// lifted off the plane by 1e-3 of its distance is one.
    #[test]
    fn a_planar_receiver_never_shadows_itself() {
        let p = Vec3::new(0.1, -0.2, 5.0);
        sweep_tilted_planes(view, p, |v, rp, n, (r, deg), i, j| {
            let d = v.unproject_dir(Vec2::new(i as f32 + 0.5, j as f32 + 0.5));
            let g = -n.dot(d);
            if g <= 1e-3 {
                return;
            }
            let z = -n.dot(p) / g;
            if !(z > v.n && z < v.far) {
                return; // the plane meets this ray outside the view
            }
            assert!(!rp.caster(i, j, z), "r {r} {deg} deg texel ({i},{j}) z {z}");
            // The same point lifted off the plane by 1e-3 of its distance: a caster when it is
            // nearer the light than the receiver.
            let s = z * d + n * (1e-3 * (z * d).length());
            assert!(
                s.z >= p.z || rp.caster_at(v.project(s), s.z),
                "lifted sample not a caster: r {r} {deg} deg"
            );
        });
    }

    /// Calls `check(v, rp, n, (r, deg), i, j)` at about 64 x 64 texels `(i, j)` of `v =
    /// view_at(r)` for r of 256, 1024 and 4096, with `rp` the plane through `p` whose normal `n`
    /// is tilted from -z towards +x by `deg` from 0 to 89.9 degrees.
    fn sweep_tilted_planes(
        view_at: impl Fn(u32) -> LightView,
        p: Vec3,
        mut check: impl FnMut(&LightView, &ReceiverPlane, Vec3, (u32, f32), i32, i32),
    ) {
        for r in [256u32, 1024, 4096] {
            let v = view_at(r);
            for deg in [0.0f32, 60.0, 75.0, 85.0, 89.0, 89.9] {
                let t = deg.to_radians();
                let n = Vec3::new(t.sin(), 0.0, -t.cos());
                let rp = ReceiverPlane::plane(&v, p, n, 0.0, 0.0);
                let step = (r / 64).max(1) as usize;
                for j in (0..r as i32).step_by(step) {
                    for i in (0..r as i32).step_by(step) {
                        check(&v, &rp, n, (r, deg), i, j);
                    }
                }
            }
        }
    }

    /// [`a_planar_receiver_never_shadows_itself`] in an orthographic view (the sun), placed as
    /// the sun's fit places it (every depth in `[R, 3R]`, the window far from the origin across):
    /// a plane sampled at every texel centre is never its own caster up to 89.9 degrees of tilt,
    /// its texels' threshold depths lie just in front of it (on it, to 1e-3, up to 60 degrees),
    /// and a point lifted off it by 1e-3 of the window's size is a caster.
    #[test]
    fn a_planar_receiver_never_shadows_itself_under_the_sun() {
        let sun = |r| LightView {
            projection: crate::light_view::Projection::Orthographic,
            n: 40.0,
            far: 120.0,
            window_min: Vec2::new(35.0, -60.0),
            w: 20.0,
            ..view(r)
        };
        let p = Vec3::new(44.3, -51.7, 80.0);
        sweep_tilted_planes(sun, p, |v, rp, n, (r, deg), i, j| {
            let uv = Vec2::new(i as f32 + 0.5, j as f32 + 0.5);
            let xy = v.texel_point(uv, 0.0);
            // The plane's depth over this texel: n.(s - p) = 0.
            let z = p.z - (n.x * (xy.x - p.x) + n.y * (xy.y - p.y)) / n.z;
            if !(z > v.n && z < v.far) {
                return;
            }
            assert!(!rp.caster(i, j, z), "r {r} {deg} deg texel ({i},{j}) z {z}");
            // The threshold depth never reaches the plane (tau and kappa keep it in front), and
            // at moderate tilts it is the plane's depth.
            let th = rp.threshold_at(uv);
            assert!(th <= z.min(p.z), "{deg} deg: {th} above {z}");
            assert!(deg > 60.0 || z.min(p.z) - th <= 1e-3 * z, "{th} vs {z}");
            let s = v.texel_point(uv, z) + n * (1e-3 * v.w);
            assert!(
                s.z >= p.z || rp.caster_at(v.project(s), s.z),
                "lifted sample not a caster: r {r} {deg} deg"
            );
        });
    }

    #[test]
    fn classic_mode_is_the_depth_test() {
        let v = view(512);
        let p = Vec3::new(0.0, 0.0, 4.0);
        let n = Vec3::new(0.0, 0.0, -1.0);
        let rp = ReceiverPlane::classic(&v, p, n, 1.0, 1.0, 0.0);
        let eps = v.receiver_bias(p, n, 1.0, 1.0);
        assert!(rp.caster(3, 9, 4.0 - eps * 1.01));
        assert!(!rp.caster(3, 9, 4.0 - eps * 0.99));
        assert!(!rp.caster(3, 9, f32::INFINITY));
    }

    #[test]
    fn max_threshold_bounds_every_texel_of_the_block() {
        let v = view(1024);
        let t = 80f32.to_radians();
        let rp = ReceiverPlane::plane(
            &v,
            Vec3::new(0.3, 0.1, 6.0),
            Vec3::new(t.sin(), 0.0, -t.cos()),
            0.0,
            0.0,
        );
        let m = rp.max_threshold(600.0, 640.0, 500.0, 520.0);
        for j in 500..520 {
            for i in 600..640 {
                let th = rp.threshold_at(Vec2::new(i as f32 + 0.5, j as f32 + 0.5));
                assert!(th <= m, "{th} > {m}");
            }
        }
    }
}
