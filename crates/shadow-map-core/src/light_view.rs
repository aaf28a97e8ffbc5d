//! The light view: a perspective projection through the light centre onto the shadow-map plane
//! z = n (the papers' convention, docs/methods.md §1), fitted tightly to what the receivers need
//! (common-techniques-shadow-depth-maps.md, "tight light frusta" and "near and far planes").
use crate::{
    light::LightFrame,
    params::{ParamKind, ParamSpec},
    receivers::Receivers,
    scene::Scene,
    Error, Result,
};
use glam::{DVec2, DVec3, Vec2, Vec3};

mod ortho;

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
pub const RESOLUTION: ParamSpec = ParamSpec {
    key: "resolution",
    kind: ParamKind::Int {
        min: 1,
        max: MAX_RESOLUTION as i64,
    },
    default: "1024",
    help: "shadow-map resolution r (texels per side)",
};
/// `bias`: constant receiver bias `b0` in texel footprints ([`LightView::receiver_bias`]).
pub const BIAS: ParamSpec = ParamSpec {
    key: "bias",
    kind: ParamKind::Float {
        min: 0.0,
        max: 1000.0,
    },
    default: "1.0",
    help: "constant bias in world-space texel footprints at the receiver (w z / (n r)): along the normal under receiver_plane=true (tolerance of the tangent-plane test), along z under receiver_plane=false",
};
/// `slope_bias`: slope-scaled receiver bias `b1` in texel footprints
/// ([`LightView::receiver_bias`]).
pub const SLOPE_BIAS: ParamSpec = ParamSpec {
    key: "slope_bias",
    kind: ParamKind::Float {
        min: 0.0,
        max: 1000.0,
    },
    default: "1.0",
    help: "slope-scaled bias (receiver_plane=false only): texel footprints times min(tan(theta), 10), theta = angle(normal, light)",
};

/// `fit`: the window choice ([`FitMode`]).
pub const FIT: ParamSpec = ParamSpec {
    key: "fit",
    kind: ParamKind::Choice(FitMode::WORDS),
    default: "receivers",
    help: "light-view window: tightest over the receivers, the whole scene, or stable (power-of-two size, texel-snapped: no shimmer when the camera moves)",
};

/// `nearfar`: the near/far choice ([`NearFar`]).
pub const NEARFAR: ParamSpec = ParamSpec {
    key: "nearfar",
    kind: ParamKind::Choice(NearFar::WORDS),
    default: "clipped",
    help: "near/far planes: light frustum clipped to the scene, scene AABB, or the view frustum (receivers; clips casters nearer than them)",
};

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
    if r == 0 || r > MAX_RESOLUTION {
        return Err(Error::Limit {
            what: "shadow-map resolution",
            requested: r as u64,
            max: MAX_RESOLUTION as u64,
        });
    }
    Ok(())
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

// Fitting to receiver bounds: for receivers that stay on the GPU (a user's G-buffer), where the
// CPU knows only a world-space box that holds them.

use crate::scene::Aabb;

/// The world-space box of the active receivers ([`Aabb::EMPTY`] when none is active): the bounds
/// [`LightView::fit_bounds`] takes when the receivers themselves stay on the GPU.
pub fn receiver_bounds(receivers: &Receivers) -> Aabb {
    let mut b = Aabb::EMPTY;
    for (p, &a) in receivers.position().iter().zip(receivers.active()) {
        if a {
            b.grow(*p);
        }
    }
    b
}

/// The 8 corners of `bounds` as receivers (normals `+z`, unused by the fit), checked for a light
/// view at `frame` in `scene`: what [`LightView::fit_bounds`] fits.
///
/// Errors, never a panic: [`Error::Receivers`] for an inverted or empty box (`min > max` on an
/// axis, as [`Aabb::EMPTY`]) or a non-finite one; [`Error::LightView`] for a box with a corner at
/// or behind the light plane (light-space `z <= 1e-6` of the scene diagonal, where
/// [`LightView::fit_with`] counts a receiver as behind the light) or beyond the frustum
/// (`|x/z| > MAX_TAN`), whose receivers no window could cover.
pub fn bounds_receivers(scene: &Scene, bounds: &Aabb, frame: LightFrame) -> Result<Receivers> {
    let (min, max) = checked_bounds(bounds)?;
    let z_eps = 1e-6 * scene.bounds().diagonal().max(1e-6);
    let mut corners = Vec::with_capacity(8);
    for c in box_corners(min, max) {
        let q = frame.to_light(c);
        if !q.is_finite() {
            return Err(Error::Receivers(format!(
                "receiver bounds corner {c} overflows in light space ({q})"
            )));
        }
        if q.z <= z_eps {
            return Err(Error::LightView(format!(
                "receiver bounds cross the light plane: corner {c} is at light-space z = {z} \
                 (must be > {z_eps}); pass tighter bounds holding only the receivers in front of \
                 the light (those behind it are unlit), or use fit=scene with the receivers on \
                 the CPU",
                z = q.z
            )));
        }
        let t = DVec2::new(q.x as f64, q.y as f64) / q.z as f64;
        if t.abs().max_element() > MAX_TAN as f64 {
            return Err(Error::LightView(format!(
                "receiver bounds leave the light frustum: corner {c} is at |x/z| = {} > {MAX_TAN} \
                 in light space; pass tighter bounds",
                t.abs().max_element()
            )));
        }
        corners.push(c);
    }
    Receivers::from_points(corners, vec![Vec3::Z; 8])
}

/// `bounds` checked: not inverted or empty, finite.
fn checked_bounds(bounds: &Aabb) -> Result<(Vec3, Vec3)> {
    let (min, max) = (bounds.min, bounds.max);
    if min.cmpgt(max).any() {
        return Err(Error::Receivers(format!(
            "receiver bounds are inverted or empty (min {min} > max {max} on some axis; no active \
             receiver?)"
        )));
    }
    if !(min.is_finite() && max.is_finite()) {
        return Err(Error::Receivers(format!(
            "receiver bounds are not finite (min {min}, max {max})"
        )));
    }
    Ok((min, max))
}

/// The 8 corners of the box `[min, max]`.
fn box_corners(min: Vec3, max: Vec3) -> impl Iterator<Item = Vec3> {
    (0..8).map(move |k| {
        Vec3::new(
            if k & 1 == 0 { min.x } else { max.x },
            if k & 2 == 0 { min.y } else { max.y },
            if k & 4 == 0 { min.z } else { max.z },
        )
    })
}

/// The 8 corners of `bounds` as the receivers a view fit at `frame` in `scene` takes:
/// [`bounds_receivers`], or under the sun [`sun_bounds_receivers`] (an orthographic view has no
/// light plane to cross and no frustum to leave).
fn corner_receivers(scene: &Scene, bounds: &Aabb, frame: LightFrame) -> Result<Receivers> {
    if scene.light().is_directional() {
        sun_bounds_receivers(bounds)
    } else {
        bounds_receivers(scene, bounds, frame)
    }
}

/// [`bounds_receivers`] under the sun: the corners of a checked box (an orthographic view has
/// no light plane to cross and no frustum to leave).
fn sun_bounds_receivers(bounds: &Aabb) -> Result<Receivers> {
    let (min, max) = checked_bounds(bounds)?;
    Receivers::from_points(box_corners(min, max).collect(), vec![Vec3::Z; 8])
}

impl LightView {
    /// [`fit_with`](Self::fit_with) for receivers known only by a world-space box that holds
    /// every one of them (`bounds`, e.g. [`receiver_bounds`] or the bounds of a user's G-buffer):
    /// the fit runs over the box's 8 corners ([`bounds_receivers`], which also lists the errors).
    ///
    /// Conservative: for a receiver p in the box, the window edges its footprint reaches,
    /// `(x_p -+ h_x) / z_p + h_x / n` (and likewise in y), are linear-fractional in p with `z_p >
    /// 0`, so over the box they are extreme at corners; n is at most the nearest corner depth
    /// (the nearest depth in the box) and far at least the farthest. So the window holds every
    /// footprint of a receiver inside the box, and in `x/z` units it holds the window
    /// [`fit_with`](Self::fit_with) fits to such receivers when n is not raised above theirs (the
    /// unit tests check both). The price is texel density: the box's footprint is usually larger
    /// than the receivers'.
    pub fn fit_bounds(
        scene: &Scene,
        bounds: &Aabb,
        frame: LightFrame,
        light_half: Vec2,
        r: u32,
        opts: &ViewOptions,
    ) -> Result<(LightView, FitReport)> {
        let corners = corner_receivers(scene, bounds, frame)?;
        Self::fit_with(scene, &corners, frame, light_half, r, opts)
    }
}

/// A stand-in, made from two world-space boxes alone, for the CPU scene and receivers an
/// estimator's view fit reads (`FrameEstimator::fit_views`, [`LightView::fit_with`]): a scene
/// whose casters are the 12 triangles of `casters` (the box holding every caster; the fit's near
/// plane lands at or in front of the real casters, so nothing is clipped, only some depth
/// precision is spent) under `light`, seen by `camera` (unused by the fit), and the 8 corners of
/// `receivers` ([`bounds_receivers`], or the plain corners under the sun). For a renderer whose
/// geometry and receivers stay on the GPU: fitting views to the stand-in costs the same for any
/// number of triangles and receivers, and the views hold every receiver in the box, as
/// [`LightView::fit_bounds`] explains; the price is texel density. A box flat on one axis (a
/// ground) is thickened by 1e-6 of its diagonal. Errors: the boxes' ([`bounds_receivers`]'s).
pub fn bounds_stand_in(
    light: &crate::Light,
    camera: &crate::Camera,
    casters: &Aabb,
    receivers: &Aabb,
) -> Result<(Scene, Receivers)> {
    let (min, max) = checked_bounds(casters)?;
    let pad = Vec3::splat(1e-6 * (max - min).length().max(1e-6));
    let (min, max) = (min - pad, max + pad);
    let c: Vec<Vec3> = box_corners(min, max).collect();
    // Corner k has bit 0 for x, 1 for y, 2 for z; two triangles per face.
    let faces = [
        [0, 2, 6, 4],
        [1, 5, 7, 3],
        [0, 4, 5, 1],
        [2, 3, 7, 6],
        [0, 1, 3, 2],
        [4, 6, 7, 5],
    ];
    let tris: Vec<[Vec3; 3]> = faces
        .iter()
        .flat_map(|f| [[c[f[0]], c[f[1]], c[f[2]]], [c[f[0]], c[f[2]], c[f[3]]]])
        .collect();
    let scene = Scene::from_meshes("casters' bounds", *camera, *light, vec![(tris, 1.0)])?;
    let corners = corner_receivers(&scene, receivers, light.frame())?;
    Ok((scene, corners))
}

#[cfg(test)]
mod bounds_tests {
    use super::*;
    use crate::bvh::SceneBvh;

    fn fixture(name: &str) -> Scene {
        let path = format!(
            "{}/../../fixtures/{name}/{name}.toml",
            env!("CARGO_MANIFEST_DIR")
        );
        Scene::load(&path).unwrap_or_else(|e| panic!("{path}: {e}"))
    }

    /// Window in x/z units: (lo, hi).
    fn tan_window(v: &LightView) -> (Vec2, Vec2) {
        (v.window_min / v.n, (v.window_min + Vec2::splat(v.w)) / v.n)
    }

    /// Asserts the window of `vb` (from bounds) holds the window of `vr` (from receivers) in x/z
    /// units and every active receiver's footprint at `vb`'s own n.
    fn assert_covers(vb: &LightView, vr: &LightView, rec: &Receivers, half: Vec2, what: &str) {
        let (lb, hb) = tan_window(vb);
        let (lr, hr) = tan_window(vr);
        let slack = 1e-5 * (hb - lb).max_element();
        assert!(vb.n <= vr.n * (1.0 + 1e-6), "{what}: n {} > {}", vb.n, vr.n);
        assert!(
            vb.far >= vr.far * (1.0 - 1e-6),
            "{what}: far {} < {}",
            vb.far,
            vr.far
        );
        assert!(
            lb.cmple(lr + slack).all() && hb.cmpge(hr - slack).all(),
            "{what}: bounds window {lb}..{hb} misses receivers window {lr}..{hr}"
        );
        let mut checked = 0;
        for (p, &a) in rec.position().iter().zip(rec.active()) {
            if !a {
                continue;
            }
            let q = vb.frame.to_light(*p);
            let t = Vec2::new(q.x, q.y) / q.z;
            let f = half * (1.0 / vb.n - 1.0 / q.z).max(0.0);
            assert!(
                (t - f).cmpge(lb - slack).all() && (t + f).cmple(hb + slack).all(),
                "{what}: footprint of {p} ({}..{}) outside {lb}..{hb}",
                t - f,
                t + f
            );
            checked += 1;
        }
        assert!(checked > 0, "{what}: no receiver checked");
    }

    /// The receivers' fit a bounds fit with `opts` must hold: the same options, except that
    /// `stable` is compared with `receivers` (each snaps its own square to the power-of-two
    /// lattice, so two stable windows of the same side need not nest; the bounds' stable window
    /// holds the bounds' square, which holds the receivers').
    fn reference(opts: ViewOptions) -> ViewOptions {
        ViewOptions {
            fit: match opts.fit {
                FitMode::Stable => FitMode::Receivers,
                f => f,
            },
            ..opts
        }
    }

    #[test]
    fn bounds_window_holds_the_receivers_window_on_fixtures() {
        for name in ["parallel-squares", "stacked", "overlapping"] {
            let scene = fixture(name);
            let rec = Receivers::from_camera(&scene, &SceneBvh::new(&scene));
            let b = receiver_bounds(&rec);
            let light = scene.light();
            for fit in [FitMode::Receivers, FitMode::Scene, FitMode::Stable] {
                for nearfar in [NearFar::Clipped, NearFar::Aabb, NearFar::Frustum] {
                    let opts = ViewOptions { fit, nearfar };
                    let what = format!("{name} {fit:?} {nearfar:?}");
                    let half = light.half_extent();
                    let (vr, _) = LightView::fit_with(
                        &scene,
                        &rec,
                        light.frame(),
                        half,
                        256,
                        &reference(opts),
                    )
                    .expect("receivers fit");
                    let (vb, rep) =
                        LightView::fit_bounds(&scene, &b, light.frame(), half, 256, &opts)
                            .expect("bounds fit");
                    assert_eq!(rep.behind + rep.out_of_frustum, 0, "{what}");
                    assert_covers(&vb, &vr, &rec, half, &what);
                }
            }
        }
    }

    /// Points scattered inside a box under a tilted light (a fixed pseudo-random sequence, the
    /// box's corners among them): the bounds window holds their window and footprints.
    #[test]
    fn bounds_window_holds_scattered_points() {
        let mut scene = fixture("parallel-squares");
        let mut light = *scene.light();
        light.normal = Vec3::new(0.3, -1.0, 0.2).normalize();
        light.shape = crate::LightShape::Rect { size: [0.8, 0.5] };
        scene.set_light(light).unwrap();
        let b = Aabb {
            min: Vec3::new(-1.5, 0.0, -1.2),
            max: Vec3::new(1.3, 1.2, 1.6),
        };
        let mut seed = 0x2545_f491_u32;
        let mut unit = move || {
            seed = seed.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            (seed >> 8) as f32 / (1u32 << 24) as f32
        };
        let mut pts: Vec<Vec3> = (0..8)
            .map(|k| {
                Vec3::new(
                    if k & 1 == 0 { b.min.x } else { b.max.x },
                    if k & 2 == 0 { b.min.y } else { b.max.y },
                    if k & 4 == 0 { b.min.z } else { b.max.z },
                )
            })
            .collect();
        pts.extend((0..500).map(|_| b.min + (b.max - b.min) * Vec3::new(unit(), unit(), unit())));
        // Half of them only, so the receivers' window is strictly smaller than the box's.
        let inner: Vec<Vec3> = pts[8..258].to_vec();
        let light = scene.light();
        let half = light.half_extent();
        for (set, label) in [(pts, "with corners"), (inner, "inside")] {
            let n = set.len();
            let rec = Receivers::from_points(set, vec![Vec3::Y; n]).expect("points");
            for fit in [FitMode::Receivers, FitMode::Scene, FitMode::Stable] {
                let opts = ViewOptions {
                    fit,
                    nearfar: NearFar::Clipped,
                };
                let (vr, _) =
                    LightView::fit_with(&scene, &rec, light.frame(), half, 128, &reference(opts))
                        .expect("receivers fit");
                let (vb, _) = LightView::fit_bounds(&scene, &b, light.frame(), half, 128, &opts)
                    .expect("bounds fit");
                assert_covers(&vb, &vr, &rec, half, &format!("{label} {fit:?}"));
            }
        }
    }

    #[test]
    fn bad_bounds_are_typed_errors() {
        let scene = fixture("parallel-squares");
        let light = scene.light();
        let fit = |min: Vec3, max: Vec3| {
            LightView::fit_bounds(
                &scene,
                &Aabb { min, max },
                light.frame(),
                light.half_extent(),
                64,
                &ViewOptions::default(),
            )
        };
        let receivers_err = |r: Result<(LightView, FitReport)>, needle: &str| match r {
            Err(Error::Receivers(m)) => assert!(m.contains(needle), "{m}"),
            other => panic!("expected Error::Receivers({needle}), got {other:?}"),
        };
        let view_err = |r: Result<(LightView, FitReport)>, needle: &str| match r {
            Err(Error::LightView(m)) => {
                assert!(m.contains(needle), "{m}");
                assert!(m.contains("tighter bounds"), "{m}");
            }
            other => panic!("expected Error::LightView({needle}), got {other:?}"),
        };
        receivers_err(
            LightView::fit_bounds(
                &scene,
                &Aabb::EMPTY,
                light.frame(),
                light.half_extent(),
                64,
                &ViewOptions::default(),
            ),
            "inverted or empty",
        );
        receivers_err(fit(Vec3::ONE, Vec3::ZERO), "inverted or empty");
        receivers_err(fit(Vec3::new(f32::NAN, 0.0, 0.0), Vec3::ONE), "not finite");
        receivers_err(
            fit(Vec3::ZERO, Vec3::new(1.0, f32::INFINITY, 1.0)),
            "not finite",
        );
        // Finite in the world, past f32 in a tilted light's frame.
        let mut tilted = fixture("parallel-squares");
        let mut light = *tilted.light();
        light.normal = Vec3::new(0.6, -0.8, 0.0);
        tilted.set_light(light).unwrap();
        receivers_err(
            LightView::fit_bounds(
                &tilted,
                &Aabb {
                    min: Vec3::new(3e38, -3e38, 0.0),
                    max: Vec3::new(3.1e38, -2.9e38, 1.0),
                },
                tilted.light().frame(),
                tilted.light().half_extent(),
                64,
                &ViewOptions::default(),
            ),
            "overflows in light space",
        );
        // The light sits at y = 3 facing down: a box reaching above y = 3 crosses its plane.
        view_err(
            fit(Vec3::new(-1.0, 0.0, -1.0), Vec3::new(1.0, 3.5, 1.0)),
            "cross the light plane",
        );
        view_err(
            fit(Vec3::new(-1.0, 3.0, -1.0), Vec3::new(1.0, 3.0, 1.0)),
            "cross the light plane",
        );
        // Just below the light plane and far to the side: beyond MAX_TAN.
        view_err(
            fit(Vec3::new(-1.0, 2.9, -1.0), Vec3::new(100.0, 2.99, 1.0)),
            "leave the light frustum",
        );
        // A box holding a single point in front of the light is fine.
        let p = Vec3::new(0.2, 0.5, -0.3);
        let (v, rep) = fit(p, p).expect("point box");
        assert_eq!(rep.behind + rep.out_of_frustum, 0);
        assert!(v.contains(v.project(v.frame.to_light(p))));
    }
}

#[cfg(test)]
mod param_tests {
    use super::*;
    use crate::{precision::DEPTH, Cull, DepthPrecision, FromParam, ParamValue};

    /// Every word of a choice converts, nothing else does.
    fn words_convert<T: FromParam>(spec: &ParamSpec) {
        let ParamKind::Choice(words) = spec.kind else {
            panic!("{} is not a choice", spec.key);
        };
        for w in words {
            assert!(
                T::from_param(ParamValue::Choice(w)).is_some(),
                "{}={w}",
                spec.key
            );
        }
        assert!(T::from_param(ParamValue::Choice("nonsense")).is_none());
        assert!(T::from_param(ParamValue::Int(0)).is_none());
    }

    #[test]
    fn choice_enums_cover_their_words() {
        words_convert::<FitMode>(&FIT);
        words_convert::<NearFar>(&NEARFAR);
        words_convert::<DepthPrecision>(&DEPTH);
        let cull = ParamSpec {
            key: "cull",
            kind: ParamKind::Choice(Cull::WORDS),
            default: "none",
            help: "",
        };
        words_convert::<Cull>(&cull);
        words_convert::<crate::peeling::SelfShadow>(&crate::peeling::SELF_SHADOW);
        for w in ["midpoint", "bias"] {
            let s = crate::peeling::SelfShadow::from_param(ParamValue::Choice(w)).unwrap();
            assert_eq!(s.word(), w);
        }
        assert_eq!(
            FitMode::from_param(ParamValue::Choice("receivers")),
            Some(FitMode::default())
        );
        assert_eq!(
            NearFar::from_param(ParamValue::Choice("clipped")),
            Some(NearFar::default())
        );
    }
}

#[cfg(test)]
mod near_tests {
    use super::*;

    /// Clipping a triangle to a tan-space window: a ground triangle that reaches the light's
    /// plane far outside the window gives the depth where it enters the window, not its nearest
    /// vertex; one wholly outside gives nothing; one wholly inside gives its vertices' range.
    #[test]
    fn clipped_depth_range_is_the_depth_inside_the_window() {
        let window = |lo: f64, hi: f64| -> [Plane; 4] {
            [
                [1.0, 0.0, -lo, 0.0],
                [-1.0, 0.0, hi, 0.0],
                [0.0, 1.0, -lo, 0.0],
                [0.0, -1.0, hi, 0.0],
            ]
        };
        // A plane x = 1 (light space) from z = 0.01 to z = 10: inside |x/z| <= 0.5 only for
        // z >= 2.
        let t = [
            Vec3::new(1.0, -0.1, 0.01),
            Vec3::new(1.0, 0.1, 0.01),
            Vec3::new(1.0, 0.0, 10.0),
        ];
        let (a, b) = clipped_depth_range(&t, &window(-0.5, 0.5)).unwrap();
        assert!((a - 2.0).abs() < 1e-3, "near {a}");
        assert!((b - 10.0).abs() < 1e-3, "far {b}");
        assert!(clipped_depth_range(&t, &window(-0.05, 0.05)).is_none());
        let inside = [
            Vec3::new(0.0, 0.0, 1.0),
            Vec3::new(0.1, 0.0, 2.0),
            Vec3::new(0.0, 0.1, 3.0),
        ];
        let (a, b) = clipped_depth_range(&inside, &window(-1.0, 1.0)).unwrap();
        assert!(
            (0.9999..=1.0).contains(&a) && (3.0..3.0001).contains(&b),
            "{a} {b}"
        );
    }

    /// The occluder hull holds every segment from the light to a receiver (sampled), and a point
    /// beside the light, off every such segment, lies outside it.
    #[test]
    fn occluder_hull_holds_every_light_to_receiver_segment() {
        let half = DVec2::new(0.5, 0.3);
        let rec: Vec<(DVec2, f64)> = [(0.2, -0.1, 2.0), (-1.5, 0.4, 5.0), (3.0, 2.0, 0.7)]
            .iter()
            .map(|&(x, y, z)| (DVec2::new(x, y) / z, z))
            .collect();
        let hull = occluder_hull(&rec, half);
        let inside = |p: DVec3| {
            hull.iter()
                .all(|pl| pl[0] * p.x + pl[1] * p.y + pl[2] * p.z + pl[3] >= -1e-9)
        };
        for &(t, z) in &rec {
            let p = (t * z).extend(z);
            for cx in [-1.0, 0.0, 1.0] {
                for cy in [-1.0, 0.0, 1.0] {
                    let c = DVec3::new(cx * half.x, cy * half.y, 0.0);
                    for k in 0..=10 {
                        let s = k as f64 / 10.0;
                        assert!(inside(c + (p - c) * s), "segment point {s} to {p}");
                    }
                }
            }
        }
        // Beside the light at a small depth: between no receiver and the light.
        assert!(!inside(DVec3::new(3.0, 0.0, 0.01)));
    }

    /// A ground running past the light's plane (the backlit-stone kind) no longer pulls the near
    /// plane down to where it crosses: the near plane is the nearest geometry that can shadow a
    /// receiver.
    #[test]
    fn a_ground_past_the_light_plane_does_not_set_the_near_plane() {
        let path = format!(
            "{}/../../fixtures/backlit-stone/backlit-stone.toml",
            env!("CARGO_MANIFEST_DIR")
        );
        let scene = Scene::load(&path).unwrap();
        let bvh = crate::bvh::SceneBvh::new(&scene);
        let rec = Receivers::from_camera(&scene, &bvh);
        let light = scene.light();
        let (view, _) =
            LightView::fit(&scene, &rec, light.frame(), light.half_extent(), 256).unwrap();
        // The ground crosses the light's plane: its nearest vertex in front of the light is a
        // few 1e-4 deep; the nearest geometry that matters is far deeper.
        assert!(view.n > 0.01, "near {}", view.n);
    }
}
