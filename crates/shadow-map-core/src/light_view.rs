//! The light view: a perspective projection through the light centre onto the shadow-map plane
//! z = n (the papers' convention, docs/methods.md §1), fitted tightly to what the receivers need
//! (common-techniques-shadow-depth-maps.md, "tight light frusta" and "near and far planes").
use crate::{
    light::LightFrame, params::ParamSpec, receivers::Receivers, scene::Scene, Error, Result,
};
use glam::{DVec2, DVec3, Vec2, Vec3};

mod bounds;
mod ortho;
#[cfg(test)]
mod tests;

pub use bounds::{bounds_receivers, bounds_stand_in, receiver_bounds};

/// Largest shadow-map resolution the CPU core accepts (texels per side).
pub const MAX_RESOLUTION: u32 = 16384;

/// Largest |x/z| (tangent of the half angle from the light axis) the light frustum may reach:
/// tan(87.1 deg). Receivers beyond it are out of the frustum and reported, not silently lit.
pub const MAX_TAN: f32 = 20.0;

/// A fitted light view. Light-space coordinates are those of [`LightFrame`]; the shadow-map
/// plane is z = n and the map's window on it is the square `[x0, x0 + w] x [y0, y0 + w]`, split in
/// `r x r` texels of pitch `delta = w / r`. Continuous texel coordinates of a light-space point:
///
/// `u = (n x / z - x0) / delta`, `v = (n y / z - y0) / delta`
///
/// (texel (i, j) = (floor u, floor v), centre (i + 1/2, j + 1/2); docs/methods.md §1, with an
/// off-centre window so the frustum covers what the receivers need and no more).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LightView {
    /// Light-space frame (origin at the centre of projection).
    pub frame: LightFrame,
    /// Near plane and shadow-map plane distance n > 0.
    pub n: f32,
    /// Far plane: the largest light-space depth the map needs.
    pub far: f32,
    /// Window corner (x0, y0) on the plane z = n.
    pub window_min: Vec2,
    /// Window side w on the plane z = n.
    pub w: f32,
    /// Resolution r (texels per side).
    pub r: u32,
    /// Perspective from the frame's origin (area lights) or orthographic along `e_z` (the sun).
    pub projection: Projection,
}

/// How a [`LightView`] maps light space to its map (docs/methods.md §1 and §14).
///
/// - `Perspective`: through the frame's origin onto the plane z = n,
///   `(u, v) = ((n x / z, n y / z) - window_min) / delta`: every area light, from its centre or
///   from a point on it.
/// - `Orthographic`: along `e_z`, `(u, v) = ((x, y) - window_min) / delta`: the sun, whose rays
///   are parallel. The window and the near plane are then in world units (the frame's x, y and
///   z), the origin is a point behind the scene (so every depth is positive), and `n` is only the
///   near plane: the map plane has no distance to the light.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub enum Projection {
    /// Perspective from the origin (area lights).
    #[default]
    Perspective,
    /// Orthographic along `e_z` (directional lights).
    Orthographic,
}

/// Statistics of a fit, reported by `--stats`.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct FitReport {
    /// Active receivers behind or in the light plane (z <= 0 in light space).
    pub behind: usize,
    /// Active receivers in front of the light but outside the frustum (beyond [`MAX_TAN`]).
    pub out_of_frustum: usize,
    /// Side of the final window over the side of the tightest window over the receivers'
    /// footprints at the same n (1 for `fit=receivers`; up to 2 for `fit=stable`; the texel
    /// density given up is its square). 0 when no receiver needed the map.
    pub window_scale: f32,
}

/// How the window on the shadow-map plane is chosen (`--param fit=...`; common techniques,
/// "Calculating a tight projection" and "Moving the light in texel-sized increments").
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub enum FitMode {
    /// The bounding square of every scene vertex in front of the light (and of the receivers'
    /// footprints): constant while the camera moves, wasteful when the camera sees a small part.
    Scene,
    /// The tightest square over this frame's receivers' footprints (the default).
    #[default]
    Receivers,
    /// Shimmer-free: the receivers' square, its side rounded up to a power of two (in `x/z`
    /// units, after one texel of slack) and its corner snapped to whole texels of that size, with
    /// n and far taken from the scene, not the receivers. The texel lattice in `x/z` is then a
    /// fixed grid (`k s / r` for integers k, s the power of two) while the camera moves and the
    /// side stays on the same power of two, so a world point keeps the same texels and the same V
    /// up to float rounding. Costs up to 2x in window side (4x in texel density).
    Stable,
}

crate::param_words!(FitMode { Receivers = "receivers", Scene = "scene", Stable = "stable" });

/// How the near and far planes are chosen (`--param nearfar=...`; common techniques,
/// "Calculating the near plane and far plane").
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub enum NearFar {
    /// The scene's bounding box corners in light space: min and max z (n at least the floor of
    /// 1e-4 of the far receiver; a light inside the box gets that floor).
    Aabb,
    /// The view frustum in light space: the nearest and farthest receiver (what the camera sees).
    /// Casters nearer than the nearest receiver are clipped, the paper's warning; reported in
    /// `--stats` and measured, not hidden.
    Frustum,
    /// The light frustum intersected with the scene: the paper's recommendation and the default
    /// (see [`LightView::fit`]).
    #[default]
    Clipped,
}

crate::param_words!(NearFar { Clipped = "clipped", Aabb = "aabb", Frustum = "frustum" });

crate::typed_params! {
    /// Light-view options shared by every estimator with a map ([`FitMode`], [`NearFar`]): the
    /// `view` group of each estimator's parameters, declared once here.
    #[derive(Default, Eq)]
    pub struct ViewOptions {
        /// Window choice.
        fit: FitMode = FIT,
        /// Near/far choice.
        nearfar: NearFar = NEARFAR,
    }
}

/// `resolution`: shadow-map side in texels (every estimator with a map).
pub const RESOLUTION: ParamSpec = ParamSpec::int(1, MAX_RESOLUTION as i64, "1024")
    .named("resolution", "shadow-map resolution r (texels per side)");
/// `bias`: constant receiver bias `b0` in texel footprints ([`LightView::receiver_bias`]).
pub const BIAS: ParamSpec = ParamSpec::float(0.0, 1000.0, "1.0").named("bias", "constant bias in world-space texel footprints at the receiver (w z / (n r)): along the normal under receiver_plane=true (tolerance of the tangent-plane test), along z under receiver_plane=false");
/// `slope_bias`: slope-scaled receiver bias `b1` in texel footprints
/// ([`LightView::receiver_bias`]).
pub const SLOPE_BIAS: ParamSpec = ParamSpec::float(0.0, 1000.0, "1.0").named("slope_bias", "slope-scaled bias (receiver_plane=false only): texel footprints times min(tan(theta), 10), theta = angle(normal, light)");

/// `fit`: the window choice ([`FitMode`]).
pub const FIT: ParamSpec = ParamSpec::choice(FitMode::WORDS, "receivers").named("fit", "light-view window: tightest over the receivers, the whole scene, or stable (power-of-two size, texel-snapped: no shimmer when the camera moves)");

/// `nearfar`: the near/far choice ([`NearFar`]).
pub const NEARFAR: ParamSpec = ParamSpec::choice(NearFar::WORDS, "clipped").named("nearfar", "near/far planes: light frustum clipped to the scene, scene AABB, or the view frustum (receivers; clips casters nearer than them)");

impl LightView {
    /// A view of side `r` on the world axes (near 1, far 2, window [-1, 1]^2) that stands in for
    /// a frame's view in buffers allocated before any view is known (the engine path).
    pub fn placeholder(r: u32) -> LightView {
        LightView {
            frame: crate::light::LightFrame {
                origin: glam::Vec3::ZERO,
                ex: glam::Vec3::X,
                ey: glam::Vec3::Y,
                ez: glam::Vec3::Z,
            },
            n: 1.0,
            far: 2.0,
            window_min: glam::Vec2::splat(-1.0),
            w: 2.0,
            r,
            projection: Default::default(),
        }
    }

    /// Receiver-side depth bias in world units (docs/methods.md §2, "Self-shadowing"):
    /// `eps = (w z_p / (n r)) (b0 + b1 min(tan theta, 10))`, where `w z_p / (n r)` is the world
    /// size of one texel at the receiver's depth and theta the angle between the receiver normal
    /// `n_light` and the direction from the light-space point `p_light` to the view's centre of
    /// projection. Scale-invariant: the same numbers work for any scene size. The WGSL twin is
    /// `receiver_bias` in `gpu/math.wgsl`.
    #[inline]
    pub fn receiver_bias(&self, p_light: Vec3, n_light: Vec3, b0: f32, b1: f32) -> f32 {
        let texel = self.texel_at(p_light.z);
        let to_light = if self.is_ortho() {
            Vec3::NEG_Z
        } else {
            (-p_light).normalize_or_zero()
        };
        let cos = n_light.dot(to_light).abs().max(1e-6);
        let tan = ((1.0 - cos * cos).max(0.0)).sqrt() / cos;
        texel * (b0 + b1 * tan.min(10.0))
    }

    /// The longest texel ray direction `|unproject_dir(u)|` over the window (at a corner): the
    /// scale of [`crate::receiver_plane`]'s rounding allowance.
    pub fn max_dir_len(&self) -> f32 {
        if self.is_ortho() {
            return 1.0;
        }
        let a = self
            .window_min
            .abs()
            .max((self.window_min + Vec2::splat(self.w)).abs())
            / self.n;
        (a.length_squared() + 1.0).sqrt()
    }

    /// Texel pitch on the plane z = n: `delta = w / r`.
    #[inline]
    pub fn delta(&self) -> f32 {
        self.w / self.r as f32
    }
    /// Yang's scale from light space to texels, `alpha = n r / w`: `u - u_p = alpha (x/z - x_p/z_p)`.
    #[inline]
    pub fn alpha(&self) -> f32 {
        self.n * self.r as f32 / self.w
    }
    /// The blocker-search kernel width in texels for a light of extent `l` (per axis) and
    /// occluders no nearer than `z_m`, over a receiver at depth `z_p` (Guennebaud's search area,
    /// Yang eq. 1): [`crate::mssm::kernel_width`] with `alpha = n r / w` in perspective; for the
    /// sun (`l` = the diameter `2 tan(angle / 2)` of its disk of directions) the occluder prism's
    /// width at `z_m`, `l (z_p - z_m) / delta` (docs/methods.md §14 "Backprojection"). 0 when
    /// `z_m >= z_p`, `f32::MAX` when not finite.
    #[inline]
    pub fn kernel_texels(&self, l: f32, z_m: f32, z_p: f32) -> f32 {
        if !self.is_ortho() {
            return crate::mssm::kernel_width(self.alpha(), l, z_m, z_p);
        }
        if !(z_m < z_p) {
            return 0.0;
        }
        let w = l * (z_p - z_m) / self.delta();
        if w.is_finite() {
            w.max(0.0)
        } else {
            f32::MAX
        }
    }
    /// True for an orthographic view (the sun, [`Projection::Orthographic`]).
    #[inline]
    pub fn is_ortho(&self) -> bool {
        self.projection == Projection::Orthographic
    }
    /// World size of one texel at light-space depth `z`: `w z / (n r)` in perspective, `w / r`
    /// orthographic.
    #[inline]
    pub fn texel_at(&self, z: f32) -> f32 {
        if self.is_ortho() {
            self.delta()
        } else {
            self.w * z / (self.n * self.r as f32)
        }
    }
    /// The point of the window plane a light-space point maps to: `n (x, y) / z` in perspective,
    /// `(x, y)` orthographic.
    #[inline]
    pub fn to_plane(&self, p: Vec3) -> Vec2 {
        if self.is_ortho() {
            Vec2::new(p.x, p.y)
        } else {
            Vec2::new(p.x, p.y) * (self.n / p.z)
        }
    }
    /// Continuous texel coordinates (u, v) of a light-space point with z > 0.
    #[inline]
    pub fn project(&self, p: Vec3) -> Vec2 {
        (self.to_plane(p) - self.window_min) / self.delta()
    }
    /// Light-space direction through continuous texel coordinates (u, v), scaled so that z = 1
    /// (perspective views only: an orthographic view's texels share the direction `e_z`, see
    /// [`texel_point`](Self::texel_point)).
    #[inline]
    pub fn unproject_dir(&self, uv: Vec2) -> Vec3 {
        let xy = (uv * self.delta() + self.window_min) / self.n;
        Vec3::new(xy.x, xy.y, 1.0)
    }
    /// The light-space point at depth `z` on the texel ray through (u, v), in either projection.
    #[inline]
    pub fn texel_point(&self, uv: Vec2, z: f32) -> Vec3 {
        let xy = uv * self.delta() + self.window_min;
        if self.is_ortho() {
            xy.extend(z)
        } else {
            (xy * (z / self.n)).extend(z)
        }
    }
    /// True when the continuous texel coordinates fall inside the map.
    #[inline]
    pub fn contains(&self, uv: Vec2) -> bool {
        uv.x >= 0.0 && uv.y >= 0.0 && uv.x < self.r as f32 && uv.y < self.r as f32
    }

    /// Fits a view at `frame` (the light centre for area-light estimators, a point on the light for
    /// multi-view ones) to the active receivers.
    ///
    /// Window: an occluder that can shadow receiver p lies in the pyramid between p and the light.
    /// Projected from the centre onto z = n (the near plane: nothing nearer is recorded), that
    /// pyramid covers `q +- (1 - n/z_p) h` where `q = n p_xy / z_p` and h is the light's half
    /// extent in the frame's x and y (docs/methods.md §1 "Coverage", §2 "Search area"). The
    /// window is the bounding square of these footprints over all receivers (in `x/z` space,
    /// clamped to [`MAX_TAN`]), so the frustum covers what the receivers need and no more.
    ///
    /// Near and far: the papers' recommendation (common-techniques, "near and far planes"): the
    /// light frustum intersected with the scene bounds. n0 is the nearest scene vertex in front of
    /// the light; the square window is fitted at n0, n is raised to the nearest vertex of the
    /// triangles overlapping it, and the raise is kept only if the window refitted at the new n
    /// overlaps nothing nearer, so every triangle in the final frustum lies at z >= n. n never
    /// exceeds the nearest receiver, and is at least `1e-4` times the farthest receiver depth
    /// (geometry nearer than that is clipped). far is the farthest vertex in the window.
    pub fn fit(
        scene: &Scene,
        receivers: &Receivers,
        frame: LightFrame,
        light_half: Vec2,
        r: u32,
    ) -> Result<(LightView, FitReport)> {
        Self::fit_with(
            scene,
            receivers,
            frame,
            light_half,
            r,
            &ViewOptions::default(),
        )
    }

    /// [`fit`](Self::fit) with a window and near/far choice ([`ViewOptions`]); the defaults
    /// (`receivers`, `clipped`) are `fit`.
    pub fn fit_with(
        scene: &Scene,
        receivers: &Receivers,
        frame: LightFrame,
        light_half: Vec2,
        r: u32,
        opts: &ViewOptions,
    ) -> Result<(LightView, FitReport)> {
        if scene.light().is_directional() {
            // The sun: an orthographic view along the frame's e_z (light_half is the disk of
            // directions' half extent at unit distance).
            return ortho::fit(scene, receivers, frame, light_half, r, opts);
        }
        check_resolution(r)?;
        let mut rep = FitReport::default();
        let scale = scene.bounds().diagonal().max(1e-6);
        let z_eps = 1e-6 * scale;
        let rec = receivers_in_tan_space(receivers, frame, z_eps, &mut rep);
        if rec.is_empty() {
            // No receiver needs the map (none at all, or all behind the light, where V = 0 for a
            // one-sided light): any view is correct, so give a small one on the light axis rather
            // than an error.
            return Ok((axis_view(frame, scale, r), rep));
        }
        let fit = FitGeometry::new(scene, frame, light_half, rec, z_eps, opts.fit);
        let (n, far) = fit.near_far(scene, frame, opts.nearfar);
        let (mut lo, mut hi) = fit.square(n);
        let tight = {
            let (lo, hi) = fit.footprints(n);
            (hi - lo).max_element().max(1e-9)
        };
        if fit.fit_mode == FitMode::Stable && r >= 2 {
            (lo, hi) = snap_stable(lo, hi, r);
        }
        let side = hi.x - lo.x;
        rep.window_scale = (side / tight) as f32;
        let nd = n as f64;
        let view = LightView {
            frame,
            n,
            far,
            window_min: (lo * nd).as_vec2(),
            w: (side * nd) as f32,
            r,
            projection: Projection::Perspective,
        };
        Ok((view, rep))
    }
}

/// The half extent to fit a light view to (`light_half` of [`LightView::fit_with`]) so that the
/// window holds every receiver's kernel: the light's bounding half extent for rect and disk
/// lights. The contract's sphere is a silhouette disk that leaves the light plane by up to
/// `z_max = R |r_xy| / |r|` (light space); it is fitted to the half extent of its equivalent disk
/// in the light plane (where the lines from r through the disk meet z = 0),
/// `h = (|r_xy| z_max + R r_z) / (r_z - z_max)`, the largest over the receivers, capped at
/// [`SPHERE_WINDOW_CAP`] R (a receiver needing more would lose casters beyond the window edge: an
/// estimator finds them with its footprint and redoes them in a wider window,
/// [`fit_half_extent_capped`], as accumulation does).
pub fn fit_half_extent(light: &crate::Light, receivers: &Receivers) -> Vec2 {
    fit_half_extent_capped(light, receivers, SPHERE_WINDOW_CAP)
}

/// Active receivers of `receivers` whose sphere-light kernel in `view` needs a window wider
/// than [`SPHERE_WINDOW_CAP`] radii (their kernel is clipped at the window's edge); 0 for other
/// lights.
pub fn beyond_sphere_window(
    view: &LightView,
    light: &crate::Light,
    receivers: &Receivers,
) -> usize {
    let crate::LightShape::Sphere { radius } = light.shape else {
        return 0;
    };
    (0..receivers.len())
        .filter(|&k| {
            receivers.active()[k]
                && sphere_window_factor(radius, view.frame.to_light(receivers.position()[k]))
                    > SPHERE_WINDOW_CAP
        })
        .count()
}

/// The cap of [`fit_half_extent`]: a sphere light's window half extent is at most this many
/// radii, so one grazing receiver does not spread every other receiver's texels over a window
/// many times wider.
pub const SPHERE_WINDOW_CAP: f32 = 4.0;

/// [`fit_half_extent`] with another cap (in radii).
pub fn fit_half_extent_capped(light: &crate::Light, receivers: &Receivers, cap: f32) -> Vec2 {
    let half = light.half_extent();
    let crate::LightShape::Sphere { radius } = light.shape else {
        return half;
    };
    let frame = light.frame();
    let mut f = 1.0f32;
    for (k, pw) in receivers.position().iter().enumerate() {
        if receivers.active()[k] {
            f = f.max(sphere_window_factor(radius, frame.to_light(*pw)));
        }
    }
    half * f.min(cap)
}

/// The window half extent, in radii, that the receiver at light-space `p` needs under a sphere
/// light of `radius` ([`fit_half_extent`]'s `h / R`); 1 for receivers at or behind the light's
/// plane, or whose silhouette disk reaches it.
pub fn sphere_window_factor(radius: f32, p: Vec3) -> f32 {
    if !(p.z > 0.0) || !(radius > 0.0) {
        return 1.0;
    }
    let rxy = Vec2::new(p.x, p.y).length();
    let zmax = radius * rxy / p.length();
    if zmax < p.z {
        ((rxy * zmax + radius * p.z) / (radius * (p.z - zmax))).max(1.0)
    } else {
        1.0
    }
}

fn check_resolution(r: u32) -> Result<()> {
    Error::check_in_range("shadow-map resolution", r, MAX_RESOLUTION)
}

/// The active receivers in tan space, `(x/z, y/z)` and z, counting those behind the light or
/// beyond [`MAX_TAN`] in `rep` instead.
fn receivers_in_tan_space(
    receivers: &Receivers,
    frame: LightFrame,
    z_eps: f32,
    rep: &mut FitReport,
) -> Vec<(DVec2, f64)> {
    let mut rec: Vec<(DVec2, f64)> = Vec::new();
    for (k, p) in receivers.position().iter().enumerate() {
        if !receivers.active()[k] {
            continue;
        }
        let q = frame.to_light(*p);
        if q.z <= z_eps {
            rep.behind += 1;
            continue;
        }
        let t = DVec2::new(q.x as f64, q.y as f64) / q.z as f64;
        if t.abs().max_element() > MAX_TAN as f64 {
            rep.out_of_frustum += 1;
            continue;
        }
        rec.push((t, q.z as f64));
    }
    rec
}

/// The small view on the light axis given when no receiver needs the map.
fn axis_view(frame: LightFrame, scale: f32, r: u32) -> LightView {
    let n = (1e-3 * scale).max(f32::MIN_POSITIVE);
    LightView {
        frame,
        n,
        far: scale,
        window_min: Vec2::splat(-n),
        w: 2.0 * n,
        r,
        projection: Projection::Perspective,
    }
}

/// A half-space `a x + b y + c z + d >= 0` of light space.
pub(crate) type Plane = [f64; 4];

/// The bounding frustum of every receiver's occluder pyramid (the convex hull of the light and
/// the receiver): at depth z the pyramid of a receiver at tan-space `t`, depth `z_p`, covers
/// `(1 - z/z_p) [-h, h] + (z/z_p) p_xy`, whose lower end `-h + z (t + h/z_p)` is at least
/// `-h + z min(t + h/z_p)` over receivers and whose upper end is at most `h + z max(t - h/z_p)`.
/// Geometry outside these four planes lies between no receiver and no point of the light, so it
/// cannot shadow anything and does not decide the near plane.
fn occluder_hull(rec: &[(DVec2, f64)], half: DVec2) -> [Plane; 4] {
    let (mut a_lo, mut a_hi) = (DVec2::splat(f64::INFINITY), DVec2::splat(f64::NEG_INFINITY));
    for &(t, z) in rec {
        a_lo = a_lo.min(t + half / z);
        a_hi = a_hi.max(t - half / z);
    }
    [
        [1.0, 0.0, -a_lo.x, half.x],
        [-1.0, 0.0, a_hi.x, half.x],
        [0.0, 1.0, -a_lo.y, half.y],
        [0.0, -1.0, a_hi.y, half.y],
    ]
}

/// Nearest and farthest geometry (light-space triangles `tris`) inside the frustum of a tan-space
/// window beyond `n_floor`, each triangle clipped to it ([`clipped_depth_range`]), so a large
/// triangle that reaches near the light outside the window (a ground running past the light's
/// plane) does not pull the near plane down (the common-techniques paper's intersection of the
/// scene with the light frustum). The nearest is taken inside `hull` too (the receivers'
/// [`occluder_hull`]): geometry that can shadow no receiver does not decide it.
fn geometry_range(
    tris: &[[Vec3; 3]],
    n_floor: f32,
    (lo, hi): (DVec2, DVec2),
    hull: Option<&[Plane; 4]>,
) -> (f32, f32) {
    let window: [Plane; 5] = [
        [1.0, 0.0, -lo.x, 0.0],
        [-1.0, 0.0, hi.x, 0.0],
        [0.0, 1.0, -lo.y, 0.0],
        [0.0, -1.0, hi.y, 0.0],
        [0.0, 0.0, 1.0, -(n_floor as f64)],
    ];
    let (mut zmin, mut zmax) = (f32::INFINITY, 0.0f32);
    for t in tris {
        // Clipped to the window, then on to the hull: one polygon for both ends.
        let mut p = Polygon::triangle(t);
        if !p.clip(&window) {
            continue;
        }
        zmax = zmax.max(p.depth_range().1);
        if hull.is_none_or(|h| p.clip(h)) {
            zmin = zmin.min(p.depth_range().0.max(n_floor));
        }
    }
    (zmin, zmax)
}

/// The depth range of triangle `t` (light space) clipped to the half-spaces `planes`
/// ([`Polygon`]), or `None` when nothing of it is inside.
#[cfg(test)]
fn clipped_depth_range(t: &[Vec3; 3], planes: &[Plane]) -> Option<(f32, f32)> {
    let mut p = Polygon::triangle(t);
    p.clip(planes).then(|| p.depth_range())
}

/// A convex polygon of light space clipped plane by plane (Sutherland-Hodgman, in f64): a
/// triangle and at most one more vertex per plane.
pub(crate) struct Polygon {
    v: [DVec3; Polygon::MAX],
    n: usize,
}

impl Polygon {
    /// A triangle clipped by up to 10 planes (the fit's 9, [`crate::settle`]'s 10).
    const MAX: usize = 3 + 10;

    pub(crate) fn triangle(t: &[Vec3; 3]) -> Self {
        let mut v = [DVec3::ZERO; Self::MAX];
        for (k, p) in t.iter().enumerate() {
            v[k] = p.as_dvec3();
        }
        Polygon { v, n: 3 }
    }

    /// Keeps the part inside every plane of `planes`; false when nothing is left. A plane with
    /// every vertex inside leaves the polygon as it is (most triangles lie wholly inside or
    /// wholly outside a plane).
    pub(crate) fn clip(&mut self, planes: &[Plane]) -> bool {
        for pl in planes {
            let side = |p: DVec3| pl[0] * p.x + pl[1] * p.y + pl[2] * p.z + pl[3];
            let poly = &self.v[..self.n];
            if poly.iter().all(|&p| side(p) >= 0.0) {
                continue;
            }
            let mut next = [DVec3::ZERO; Self::MAX];
            let mut m = 0;
            for k in 0..self.n {
                let (a, b) = (poly[k], poly[(k + 1) % self.n]);
                let (da, db) = (side(a), side(b));
                if da >= 0.0 && m < Self::MAX {
                    next[m] = a;
                    m += 1;
                }
                if (da >= 0.0) != (db >= 0.0) && m < Self::MAX {
                    next[m] = a + (b - a) * (da / (da - db));
                    m += 1;
                }
            }
            if m == 0 {
                self.n = 0;
                return false;
            }
            self.v = next;
            self.n = m;
        }
        self.n > 0
    }

    /// The polygon's depth range, the near end lowered by `2^-20` of itself and the far end
    /// raised as much, so rounding never clips recorded geometry.
    fn depth_range(&self) -> (f32, f32) {
        let (mut zmin, mut zmax) = (f64::INFINITY, f64::NEG_INFINITY);
        for p in &self.v[..self.n] {
            zmin = zmin.min(p.z);
            zmax = zmax.max(p.z);
        }
        let slack = 1.0 / 1_048_576.0;
        ((zmin * (1.0 - slack)) as f32, (zmax * (1.0 + slack)) as f32)
    }
}

/// Tan-space bounds of every scene vertex in front of the light (beyond `n_floor`), clamped to
/// `all` (for `fit=scene`).
fn scene_tan_bounds(tris: &[[Vec3; 3]], n_floor: f32, all: (DVec2, DVec2)) -> (DVec2, DVec2) {
    let mut lo = DVec2::splat(f64::INFINITY);
    let mut hi = DVec2::splat(f64::NEG_INFINITY);
    for v in tris.iter().flatten() {
        if v.z > n_floor {
            let t = DVec2::new(v.x as f64, v.y as f64) / v.z as f64;
            lo = lo.min(t);
            hi = hi.max(t);
        }
    }
    (lo.max(all.0), hi.min(all.1))
}

/// `fit=stable` window snapping: a margin of 3 texels, the side rounded up to a power of two and
/// the corner snapped to whole texels.
fn snap_stable(mut lo: DVec2, mut hi: DVec2, r: u32) -> (DVec2, DVec2) {
    // A margin of 3 texels so no search kernel (its ceil adds up to one texel) reaches the
    // map border, where clamping would shift it differently in each frame; then the side
    // rounded up to a power of two with room for one texel of snapping, and the corner
    // snapped to whole texels.
    let m = 3.0 * (hi.x - lo.x) / r as f64;
    lo -= DVec2::splat(m);
    hi += DVec2::splat(m);
    let side = hi.x - lo.x;
    let need = side * r as f64 / (r - 1) as f64;
    let s2 = 2f64.powi(need.log2().ceil() as i32);
    let d = s2 / r as f64;
    let lo2 = (lo / d).floor() * d;
    lo = lo2;
    hi = lo2 + DVec2::splat(s2);
    (lo, hi)
}

/// The receivers and scene as [`LightView::fit_with`] sees them in light space, with the depths
/// derived from them.
struct FitGeometry {
    /// Active receivers in the frustum: tan-space position and depth.
    rec: Vec<(DVec2, f64)>,
    /// Scene triangles in light space.
    tris: Vec<[Vec3; 3]>,
    /// The light's half extent in the frame's x and y.
    half: DVec2,
    /// Nearest and farthest receiver depth.
    zr_min: f32,
    zr_max: f32,
    /// Depth below which geometry is clipped.
    n_floor: f32,
    /// Near plane below every triangle in front of the light (and every receiver).
    n0: f32,
    /// Farthest geometry in the whole frustum.
    far_scene: f32,
    /// Tan-space bounds of the scene in front of the light.
    scene_window: (DVec2, DVec2),
    /// The window choice.
    fit_mode: FitMode,
    /// The receivers' [`occluder_hull`].
    hull: [Plane; 4],
}

impl FitGeometry {
    /// Moves the scene into light space and derives the receiver depth range, the clipping floor,
    /// the nearest and farthest geometry and the scene's tan-space bounds.
    fn new(
        scene: &Scene,
        frame: LightFrame,
        light_half: Vec2,
        rec: Vec<(DVec2, f64)>,
        z_eps: f32,
        fit_mode: FitMode,
    ) -> Self {
        let zr_min = rec.iter().map(|r| r.1).fold(f64::INFINITY, f64::min) as f32;
        let zr_max = rec.iter().map(|r| r.1).fold(0.0f64, f64::max) as f32;
        let n_floor = (1e-4 * zr_max).max(z_eps);

        let tris: Vec<[Vec3; 3]> = scene
            .triangles()
            .iter()
            .map(|t| t.map(|v| frame.to_light(v)))
            .collect();
        let half = light_half.as_dvec2();
        let all = (DVec2::splat(-MAX_TAN as f64), DVec2::splat(MAX_TAN as f64));
        let hull = occluder_hull(&rec, half);
        // `fit=stable` keeps its near plane independent of the receivers (the camera).
        let n_hull = (fit_mode != FitMode::Stable).then_some(&hull);
        let (n_scene, far_scene) = geometry_range(&tris, n_floor, all, n_hull);
        let n0 = n_scene.min(zr_min * 0.999).max(n_floor);
        let scene_window = scene_tan_bounds(&tris, n_floor, all);
        FitGeometry {
            rec,
            tris,
            half,
            zr_min,
            zr_max,
            n_floor,
            n0,
            far_scene,
            scene_window,
            fit_mode,
            hull,
        }
    }

    /// The bounding box of the receivers' occluder footprints projected onto z = n, in x/z space,
    /// clamped to [`MAX_TAN`].
    fn footprints(&self, n: f32) -> (DVec2, DVec2) {
        let mut lo = DVec2::splat(f64::INFINITY);
        let mut hi = DVec2::splat(f64::NEG_INFINITY);
        for &(t, z) in &self.rec {
            let f = self.half * (1.0 / n as f64 - 1.0 / z).max(0.0);
            lo = lo.min(t - f);
            hi = hi.max(t + f);
        }
        let m = MAX_TAN as f64;
        (lo.max(DVec2::splat(-m)), hi.min(DVec2::splat(m)))
    }

    /// Nearest and farthest geometry overlapping a tan-space window.
    fn geometry_range(&self, lo: DVec2, hi: DVec2) -> (f32, f32) {
        geometry_range(&self.tris, self.n_floor, (lo, hi), Some(&self.hull))
    }

    /// The square window (texels are square) fitted at a given n, in x/z space.
    fn square(&self, n: f32) -> (DVec2, DVec2) {
        let (mut lo, mut hi) = self.footprints(n);
        if self.fit_mode == FitMode::Scene && self.scene_window.0.x <= self.scene_window.1.x {
            lo = lo.min(self.scene_window.0);
            hi = hi.max(self.scene_window.1);
        }
        // A hair of slack (1e-6 relative) so f32 rounding never drops a footprint corner.
        let side = (hi - lo).max_element().max(1e-9) * (1.0 + 1e-6);
        let c = (lo + hi) * 0.5;
        (c - DVec2::splat(side * 0.5), c + DVec2::splat(side * 0.5))
    }

    /// The near and far planes for a [`NearFar`] choice.
    fn near_far(&self, scene: &Scene, frame: LightFrame, nearfar: NearFar) -> (f32, f32) {
        let (zr_min, zr_max, n_floor) = (self.zr_min, self.zr_max, self.n_floor);
        match (nearfar, self.fit_mode) {
            (NearFar::Aabb, _) => self.aabb_near_far(scene, frame),
            (NearFar::Frustum, _) => ((zr_min * 0.999).max(n_floor), zr_max),
            // Receiver-independent planes, so the lattice and kernels do not move with the camera.
            (NearFar::Clipped, FitMode::Stable) => (self.n0, self.far_scene.max(zr_max)),
            (NearFar::Clipped, _) => self.clipped_near_far(),
        }
    }

    /// `nearfar=aabb`: the light-space depth range of the scene's bounding-box corners.
    fn aabb_near_far(&self, scene: &Scene, frame: LightFrame) -> (f32, f32) {
        let b = scene.bounds();
        let (mut zmin, mut zmax) = (f32::INFINITY, f32::NEG_INFINITY);
        for k in 0..8 {
            let c = Vec3::new(
                if k & 1 == 0 { b.min.x } else { b.max.x },
                if k & 2 == 0 { b.min.y } else { b.max.y },
                if k & 4 == 0 { b.min.z } else { b.max.z },
            );
            let z = frame.to_light(c).z;
            zmin = zmin.min(z);
            zmax = zmax.max(z);
        }
        (
            zmin.min(self.zr_min * 0.999).max(self.n_floor),
            zmax.max(self.zr_max),
        )
    }

    /// `nearfar=clipped`: n raised from n0 to the nearest geometry in the window, far the farthest.
    fn clipped_near_far(&self) -> (f32, f32) {
        let (n0, zr_min, zr_max) = (self.n0, self.zr_min, self.zr_max);
        // Raise n from n0 (below every triangle in front of the light) to the nearest
        // geometry inside the square window fitted at n0, and keep it only if the window
        // refitted at the raised n (which can shift when it is squared) holds nothing
        // nearer.
        let mut n = n0;
        let (z1, _) = {
            let (lo, hi) = self.square(n0);
            self.geometry_range(lo, hi)
        };
        if z1.is_finite() {
            let raised = z1.min(zr_min * 0.999).max(n0);
            let (lo, hi) = self.square(raised);
            let (z2, _) = self.geometry_range(lo, hi);
            if !(z2 < raised) {
                n = raised;
            }
        }
        let (lo, hi) = self.square(n);
        let (_, far) = self.geometry_range(lo, hi);
        (n, far.max(zr_max))
    }
}
