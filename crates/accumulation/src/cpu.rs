//! The CPU shadow-accumulation estimator (Aszódi & Szirmay-Kalos 2006, §1.1; geometry in
//! [`crate::math`]).
use crate::math::{fixed_kernel_start, paper_plane_distance, Footprint, FrontEdge};
use crate::settings::{KernelMode, Settings, SphereModel, Variant};
use glam::{Vec2, Vec3};
use rayon::prelude::*;
use shadow_map_core::{
    light_space::{LightSpace, LightSpaceRequest},
    light_view::{FitReport, LightView},
    mssm::refine_kernel,
    Cancel, Configured, Error, LightShape, RasterOptions, ReceiverPlane, Receivers, Report, Result,
    Scene, SoftShadowEstimator,
};
use std::sync::atomic::{AtomicU64, AtomicUsize, Ordering};

mod rings;
pub use rings::{for_each_ring_cell, ring_phase, ring_width, Kernel};

/// Largest bit-grid side of the exact variant (16 x 16 = 256 bits, 8 u32 words on the GPU), and
/// the words of the occlusion-bit mask: the core's [`shadow_map_core::bitmask`].
pub use shadow_map_core::bitmask::{MASK_WORDS, MAX_BITS};
/// Highest MSSM level built for the adaptive kernel (windows up to 32 texels; wider kernels take
/// more fetches, never a wrong minimum).
pub const MAX_MSSM_LEVEL: u32 = 5;
/// Most refinement rounds of the adaptive kernel (the WGSL's `REFINE_ROUNDS`).
pub use shadow_map_core::mssm::REFINE_ROUNDS;

/// The light view and the request the CPU twin and the engine path build (one shadow map at the
/// light centre, fitted to the receivers with the `fit` and `nearfar` choices of `s.view`
/// ([`LightView::fit_with`]); peeled layers for the exact variant; the anchored MSSM for the
/// adaptive kernel).
///
/// The window is fitted to [`shadow_map_core::light_view::fit_half_extent`] (for the paper's
/// sphere model, to the light's bounding half extent).
pub fn plan(
    scene: &Scene,
    receivers: &Receivers,
    s: &Settings,
    resolution: u32,
) -> Result<(LightView, FitReport, LightSpaceRequest)> {
    let frame = scene.light().frame();
    let half = plan_half_extent(scene, receivers, s);
    let (view, fit) = LightView::fit_with(scene, receivers, frame, half, resolution, &s.view)?;
    Ok((view, fit, request(s, &view, half)))
}

/// The half extent [`plan`] fits the window to: the contract's sphere model needs
/// [`fit_half_extent`](shadow_map_core::light_view::fit_half_extent) over the receivers, the
/// paper's the light's bounding half extent.
pub fn plan_half_extent(scene: &Scene, receivers: &Receivers, s: &Settings) -> Vec2 {
    match s.sphere {
        SphereModel::Contract => {
            shadow_map_core::light_view::fit_half_extent(scene.light(), receivers)
        }
        SphereModel::Paper => scene.light().half_extent(),
    }
}

/// The light-space request of [`plan`] in `view` for a window half extent `half`
/// ([`plan_half_extent`]): peeled layers for the exact variant, the anchored MSSM for the
/// adaptive kernel with enough levels for its widest kernel (the levels only speed the minimum
/// query up: it is exact whatever their number).
pub fn request(s: &Settings, view: &LightView, half: Vec2) -> LightSpaceRequest {
    let resolution = view.r;
    let mssm_levels = (s.kernel == KernelMode::Adaptive).then(|| {
        let l = 2.0 * half.max_element();
        let wmax = view
            .kernel_texels(l, view.n, view.far)
            .clamp(1.0, resolution as f32);
        (wmax.log2().ceil() as u32).clamp(1, MAX_MSSM_LEVEL)
    });
    LightSpaceRequest {
        resolution,
        layers: s.peeled_layers().max(1),
        midpoints: None,
        mssm_levels,
        dual_mssm_levels: None,
        pyramid: false,
        raster: RasterOptions::default(),
        opacity: false,
    }
}

/// Half-open texel rectangle `[x0, x1) x [y0, y1)` covering continuous bounds, clamped to the map.
fn bounds_rect(b: [f32; 4], r: u32) -> [i32; 4] {
    let r = r as f32;
    let lo = |x: f32| {
        if x.is_nan() {
            0.0
        } else {
            x.floor().clamp(0.0, r)
        }
    };
    let hi = |x: f32| {
        if x.is_nan() {
            r
        } else {
            x.ceil().clamp(0.0, r)
        }
    };
    [
        lo(b[0]) as i32,
        lo(b[1]) as i32,
        hi(b[2]) as i32,
        hi(b[3]) as i32,
    ]
}

/// What one receiver's estimate cost (summed into the report).
#[derive(Debug, Default, Clone, Copy)]
pub struct TapStats {
    /// Lexel fetches in the kernel (all layers).
    pub taps: u64,
}

/// The per-receiver algorithm over given light-space data: the shadowing factor s in [0, 1], the
/// occluded fraction of the part of the light in front of the receiver's tangent plane
/// (V = facing (1 - s), i.e. `facing - s_front`, see [`CpuAccumulation`]).
pub struct Accumulator<'a> {
    /// The maps.
    pub ls: &'a LightSpace,
    /// The settings.
    pub s: Settings,
}

impl Accumulator<'_> {
    /// The kernel of one receiver: `None` when the adaptive kernel proves that no lexel is a
    /// caster for `plane` (the MSSM minimum over the kernel at or beyond the largest caster
    /// threshold of its texels, [`ReceiverPlane::max_threshold`]).
    pub fn kernel(&self, fp: &Footprint, uv: Vec2, plane: &ReceiverPlane) -> Option<Kernel> {
        let view = &self.ls.view;
        let bounds =
            |z: f32| bounds_rect(fp.texel_bounds(z, view.window_min, view.delta()), view.r);
        let rect = match self.s.kernel {
            KernelMode::Lexels => {
                let k = self.s.k as i32;
                let (i0, j0) = (
                    fixed_kernel_start(uv.x, self.s.k),
                    fixed_kernel_start(uv.y, self.s.k),
                );
                return Some(Kernel::Uniform {
                    rect: [i0, j0, i0 + k, j0 + k],
                    step: 1,
                });
            }
            KernelMode::Fixed => bounds(view.n),
            KernelMode::Adaptive => refine_kernel(self.ls.mssm.as_ref(), view.n, bounds, |r| {
                plane.max_threshold(r[0] as f32, r[2] as f32, r[1] as f32, r[3] as f32)
            })?,
        };
        let (nx, ny) = (
            (rect[2] - rect[0]).max(0) as u32,
            (rect[3] - rect[1]).max(0) as u32,
        );
        if nx == 0 || ny == 0 {
            return None;
        }
        if self.s.kernel == KernelMode::Adaptive {
            return Some(Kernel::Rings {
                bound: rect,
                centre: [(uv.x + 0.5).floor() as i32, (uv.y + 0.5).floor() as i32],
                m: ring_width(self.s.k),
                phase: ring_phase(view, self.s.view.fit),
            });
        }
        Some(Kernel::Uniform {
            rect,
            step: nx.max(ny).div_ceil(self.s.k).max(1),
        })
    }

    /// The shadowing factor of the receiver at light-space `p` (normal `nrm`, texel coordinates
    /// `uv`) with footprint `fp`: the occluded fraction of the light in front of its tangent
    /// plane.
    pub fn shadowing(&self, fp: &Footprint, nrm: Vec3, uv: Vec2, stats: &mut TapStats) -> f32 {
        let ls = self.ls;
        let view = &ls.view;
        let p = fp.receiver();
        let plane = self.s.plane(view, p, nrm);
        let front = FrontEdge::new(&fp.patch, fp.r, nrm);
        if !(front.fraction > 0.0) {
            return 0.0;
        }
        let Some(kernel) = self.kernel(fp, uv, &plane) else {
            return 0.0;
        };
        let delta = view.delta();
        let layers = (self.s.peeled_layers() as usize)
            .min(ls.layers.len())
            .max(1);
        let exact = self.s.variant == Variant::Exact;
        let nbits = (self.s.bits * self.s.bits) as usize;
        // Parallel lights: the backprojected caster is an axis-aligned rectangle.
        let flat = fp.patch.a == Vec3::Z;
        let mut bit_pts: Vec<Vec2> = Vec::new();
        let mut mask = shadow_map_core::bitmask::BitMask::new();
        let mut set = 0usize;
        // Bits behind the tangent plane: set from the start, never counted as occluded.
        let mut behind = 0usize;
        let mut s_add = 0.0f32;
        // Additive: the front part of the light is fully occluded at this sum.
        let s_full = front.fraction * (1.0 - 1e-6);
        // One cell [i0, i1) x [j0, j1): its centre texel's depth stands for the whole cell (a lexel
        // of a coarser map). Returns true when every bit is set.
        let mut visit = |i0: i32, i1: i32, j0: i32, j1: i32| -> bool {
            let ic = i0 + (i1 - i0 - 1) / 2;
            let jc = j0 + (j1 - j0 - 1) / 2;
            // The cell's centre on the plane: eq. 4's l.
            let l = view.window_min + Vec2::new((i0 + i1) as f32, (j0 + j1) as f32) * (0.5 * delta);
            for layer in &ls.layers[..layers] {
                stats.taps += 1;
                let cz = layer.at(ic, jc);
                // The receiver-plane test of the sample itself (texel (ic, jc)): only samples in
                // front of the receiver's tangent plane can block light that reaches it, and
                // the receiver's own surface never does. A sample that fails is no nearer than
                // the texel's threshold depth, and deeper layers are further still.
                if !plane.caster(ic, jc, cz) {
                    break;
                }
                let Some((lr, size)) = fp.caster(l, cz) else {
                    continue;
                };
                let hx = 0.5 * (i1 - i0) as f32 * delta * size;
                let hy = 0.5 * (j1 - j0) as f32 * delta * size;
                if !exact {
                    s_add += if self.s.overlap() {
                        fp.overlap_term_front(lr, hx, hy, &front)
                    } else {
                        fp.additive_term_front(lr, 4.0 * hx * hy, &front)
                    };
                    continue;
                }
                // The caster backprojected onto the light, and the bits (in-plane coordinates)
                // inside it.
                let Some(quad) = fp.caster_quad(lr, hx, hy) else {
                    continue;
                };
                if bit_pts.is_empty() {
                    let bits = self.s.bits;
                    bit_pts = (0..nbits as u32)
                        .map(|k| fp.patch.bit_local(k % bits, k / bits, bits))
                        .collect();
                    if !front.whole {
                        for (k, b) in bit_pts.iter().enumerate() {
                            if !front.front(*b) {
                                mask.set(k);
                            }
                        }
                        behind = mask.count() as usize;
                        set = behind;
                    }
                }
                set = mask.set_in_quad(&bit_pts, &quad, flat) as usize;
                if set == nbits {
                    return true;
                }
            }
            false
        };
        match kernel {
            Kernel::Uniform { rect, step } => {
                let bx = ((rect[2] - rect[0]) as u32).div_ceil(step);
                let by = ((rect[3] - rect[1]) as u32).div_ceil(step);
                'grid: for b in 0..by {
                    let j0 = rect[1] + (b * step) as i32;
                    let j1 = (j0 + step as i32).min(rect[3]);
                    for a in 0..bx {
                        let i0 = rect[0] + (a * step) as i32;
                        let i1 = (i0 + step as i32).min(rect[2]);
                        if visit(i0, i1, j0, j1) {
                            break 'grid;
                        }
                    }
                }
            }
            Kernel::Rings {
                bound,
                centre,
                m,
                phase,
            } => for_each_ring_cell(bound, centre, m, phase, visit),
        }
        if exact {
            if set == nbits {
                return 1.0;
            }
            (set - behind) as f32 / (nbits - behind) as f32
        } else if s_add >= s_full {
            1.0
        } else {
            (s_add / front.fraction).clamp(0.0, 1.0)
        }
    }
}

/// Shadow accumulation (Aszódi & Szirmay-Kalos 2006): see the crate documentation and
/// [`crate::math`] for the geometry.
///
/// Per active receiver p (light space):
/// 1. facing = the fraction of the light in front of p's tangent plane (contract); 0: V = 0.
/// 2. The footprint of the light seen from p on the plane z = n ([`Footprint`]); a receiver
///    outside the one frustum the map covers (the light not entirely nearer the light plane than
///    p, `z_p <= n`, or p's projection outside the map, which for a sphere light means behind its
///    centre's plane or beyond 87 degrees off its axis) makes `estimate` fail with
///    [`Error::Receivers`] naming the count: V is never silently set to full light there.
/// 3. The kernel ([`Accumulator::kernel`]); per lexel (and per peeled layer for the exact
///    variant) whose sample is a caster for p ([`ReceiverPlane`], `receiver_plane`: in front of
///    p's tangent plane and nearer the light than p; the classic `c_z < z_p - eps` with
///    `receiver_plane=false`), the elementary caster ([`Footprint::caster`]). This is the one caster test:
///    the receiver's own surface never shadows it, at any kernel size or angle, and no caster
///    behind the tangent plane is taken (it could block only light the receiver does not see).
/// 4. Occlusion is measured on the part of the light in front of p's tangent plane
///    ([`FrontEdge`]: each caster's image on the light clipped by the plane's trace), the only
///    light that reaches p: additive, `s_front = sum |Q_c ∩ F ∩ front| J / A_L`
///    ([`Footprint::overlap_term_front`]) or, with `coverage = centre`, the paper's
///    `sum (size delta)^2 J(l_r) / A_L [l_r in F, in front]`; exact, the bits behind the plane are
///    set from the start and never counted, `s_front = popcount(front bits set) / B^2`.
///    `V = facing - s_front`, computed as `facing (1 - min(1, s_front / f))` with `f` the patch's
///    own front fraction (equal to `facing` when the patch is the light: rect, disk, the contract's
///    sphere; the ratio keeps a fully covered front part at V = 0 for the paper's sphere model and
///    for the bit grid). The former `V = facing (1 - s)`, s normalised over the whole light,
///    was too bright by `s_front (1 - facing) / facing` on receivers lit at grazing angles.
///
/// All surfaces are treated as opaque (the shadow map stores no opacity).
pub struct CpuAccumulation {
    /// The parameters and their typed settings.
    config: Configured<Settings>,
    ls: Option<LightSpace>,
    report: Report,
    cancel: Cancel,
}

impl CpuAccumulation {
    /// With default parameters.
    pub fn new() -> Result<Self> {
        Ok(CpuAccumulation {
            config: Configured::new()?,
            ls: None,
            report: Report::default(),
            cancel: Cancel::new(),
        })
    }
    /// The light-space data of the last build.
    pub fn light_space(&self) -> Option<&LightSpace> {
        self.ls.as_ref()
    }
    /// The typed settings.
    pub fn settings(&self) -> Settings {
        *self.config.settings()
    }

    /// Builds the light-space data in a given `view` (the engine path's CPU twin: a view the
    /// caller fitted, e.g. with an engine path's `FrameEstimator::fit_views`), with the request
    /// [`request`] makes for `receivers`. Errors: a view of another resolution than the
    /// parameters' ([`Error::LightView`]).
    pub fn build_in_view(
        &mut self,
        scene: &Scene,
        receivers: &Receivers,
        view: LightView,
    ) -> Result<()> {
        let s = self.settings();
        if view.r != s.resolution {
            return Err(Error::LightView(format!(
                "a view of resolution {} for resolution={}",
                view.r, s.resolution
            )));
        }
        self.report = Report::default();
        let req = request(&s, &view, plan_half_extent(scene, receivers, &s));
        let ls = self.report.time("build", || {
            LightSpace::try_build_in_view(scene, view, FitReport::default(), &req)
        })?;
        self.report.light_space_bytes = ls.bytes();
        self.ls = Some(ls);
        Ok(())
    }

    /// Estimates V from given light-space data (as `build` makes them). Returns the lexel taps
    /// made. Lit receivers outside the one frustum are left NaN for [`settle_outside`].
    pub fn estimate_with(
        &self,
        ls: &LightSpace,
        scene: &Scene,
        receivers: &Receivers,
        v: &mut [f32],
    ) -> Result<u64> {
        receivers.check_output(v)?;
        let s = self.settings();
        let acc = Accumulator { ls, s };
        let light = scene.light();
        let view = &ls.view;
        let outside = AtomicUsize::new(0);
        let taps = AtomicU64::new(0);
        let nonfinite = receivers.estimate_each(&self.cancel, v, |pw, nw| {
            let facing = light.front_fraction_world(pw, nw);
            if !(facing > 0.0) {
                return Some(0.0);
            }
            let p = view.frame.to_light(pw);
            let fp = Footprint::for_light(&light.shape, s.sphere, p, (view.n, view.far));
            let uv = view.project(p);
            if !fp.covered() || !view.contains(uv) {
                outside.fetch_add(1, Ordering::Relaxed);
                return None;
            }
            let mut st = TapStats::default();
            let sh = acc.shadowing(&fp, view.frame.dir_to_light(nw), uv, &mut st);
            taps.fetch_add(st.taps, Ordering::Relaxed);
            Some(facing * (1.0 - sh))
        })?;
        let _ = outside.into_inner();
        if nonfinite > 0 {
            return Err(Error::Receivers(format!(
                "{nonfinite} receivers got a non-finite V (a bug; replaced by 0)"
            )));
        }
        Ok(taps.into_inner())
    }
}

/// How many active receivers need a window wider than a sphere light's is allowed to be: under
/// the contract's sphere model the window half extent is capped at
/// [`SPHERE_WINDOW_CAP`](shadow_map_core::light_view::SPHERE_WINDOW_CAP) radii
/// ([`shadow_map_core::light_view::fit_half_extent`]); a receiver whose
/// [`sphere_window_factor`](shadow_map_core::light_view::sphere_window_factor) is larger (far
/// off the light's axis, about 65 degrees at 8 radii from the light) has its kernel clipped at
/// the map's edge. The part clipped holds casters within a few radii of the light's own plane,
/// which a perspective view from the light's centre cannot hold at any window size (their
/// projection runs to infinity as their depth goes to 0): a wider window does not bring them
/// back (a second view at 64 radii was tried and measured no better, see
/// `tests/accuracy.rs::sphere_receivers_beyond_the_window_are_counted`). Reported as the note
/// `beyond_sphere_window`, so no loss is silent. 0 for other lights, the paper's model and the
/// fixed lexel kernel.
pub fn beyond_window(
    view: &LightView,
    light: &shadow_map_core::Light,
    receivers: &Receivers,
    s: &Settings,
) -> usize {
    let LightShape::Sphere { radius } = light.shape else {
        return 0;
    };
    if s.kernel == KernelMode::Lexels || s.sphere != SphereModel::Contract {
        return 0;
    }
    let cap = shadow_map_core::light_view::SPHERE_WINDOW_CAP;
    (0..receivers.len())
        .into_par_iter()
        .filter(|&k| {
            receivers.active()[k]
                && shadow_map_core::light_view::sphere_window_factor(
                    radius,
                    view.frame.to_light(receivers.position()[k]),
                ) > cap
        })
        .count()
}

/// The error for lit receivers outside the one light frustum that [`settle_outside`] could not
/// prove unshadowed.
pub fn outside_error(count: usize, light: &shadow_map_core::Light) -> Error {
    let what = if matches!(light.shape, LightShape::Sphere { .. }) {
        "sphere light: behind the plane through its centre perpendicular to its normal, or beyond 87 degrees off that normal"
    } else {
        "beyond 87 degrees off the light normal, or no farther from the light plane than the light itself"
    };
    Error::Receivers(format!(
        "{count} lit receivers lie outside the one shadow-map frustum accumulation uses ({what}) \
         and scene geometry lies between them and the light, so no map defines their V: aim the light's normal at them or use another estimator"
    ))
}

/// Settles the lit receivers [`CpuAccumulation::estimate_with`] left NaN (outside the one
/// frustum: almost in the light's plane, seen from the light) without a map: where no scene
/// triangle lies in a receiver's light pyramid ([`shadow_map_core::settle`]), nothing can shadow
/// it and V is its facing fraction exactly. Returns how many were settled; fails with
/// [`outside_error`] when any could not be (geometry between it and the light). Builds the scene's
/// BVH only when some receiver needs it.
pub fn settle_outside(scene: &Scene, receivers: &Receivers, v: &mut [f32]) -> Result<usize> {
    let open: Vec<usize> = (0..v.len())
        .filter(|&k| receivers.active()[k] && v[k].is_nan())
        .collect();
    if open.is_empty() {
        return Ok(0);
    }
    let settler = shadow_map_core::settle::Settler::new(scene);
    let light = scene.light();
    let settled: Vec<Option<f32>> = open
        .par_iter()
        .map(|&k| {
            let (p, n) = (receivers.position()[k], receivers.normal()[k]);
            settler
                .unshadowed(p, n)
                .then(|| light.front_fraction_world(p, n).clamp(0.0, 1.0))
        })
        .collect();
    let mut unsettled = 0;
    for (&k, x) in open.iter().zip(&settled) {
        match x {
            Some(x) => v[k] = *x,
            None => {
                v[k] = 0.0;
                unsettled += 1;
            }
        }
    }
    if unsettled > 0 {
        return Err(outside_error(unsettled, light));
    }
    Ok(open.len())
}

impl SoftShadowEstimator for CpuAccumulation {
    shadow_map_core::estimator_identity!("accumulation", "shadow accumulation over a kernel of elementary casters, additive or exact occlusion bits (Aszodi & Szirmay-Kalos 2006)", Cpu, config: config, cancel: cancel);
    fn build(&mut self, scene: &Scene, receivers: &Receivers) -> Result<()> {
        self.report = Report::default();
        self.ls = None;
        let s = self.settings();
        let r = s.resolution;
        let ls = self.report.time("build", || -> Result<LightSpace> {
            let (view, fit, req) = plan(scene, receivers, &s, r)?;
            LightSpace::try_build_in_view(scene, view, fit, &req)
        })?;
        self.report.light_space_bytes = ls.bytes();
        self.ls = Some(ls);
        Ok(())
    }
    fn estimate(&mut self, scene: &Scene, receivers: &Receivers, v: &mut [f32]) -> Result<()> {
        let ls = shadow_map_core::estimator::built(self.ls.take())?;
        let t = std::time::Instant::now();
        let out = self.estimate_with(&ls, scene, receivers, v);
        self.report
            .stages
            .push(("estimate".into(), t.elapsed().as_secs_f64() * 1e3));
        let taps = out.as_ref().copied().unwrap_or(0);
        let t = std::time::Instant::now();
        let settled = match &out {
            Ok(_) => settle_outside(scene, receivers, v),
            Err(_) => Ok(0),
        };
        if let Ok(n @ 1..) = settled {
            self.report
                .stages
                .push(("settle".into(), t.elapsed().as_secs_f64() * 1e3));
            self.report.note("settled_without_map", n);
        }
        let settings = self.settings();
        note_settings(
            &mut self.report,
            &settings,
            &ls,
            scene.light(),
            receivers,
            taps,
        );
        // Every caster is opaque to the occlusion this method accumulates.
        self.report
            .warn_all(shadow_map_core::Warning::opaque_casters(scene));
        self.ls = Some(ls);
        out.and(settled).map(|_| ())
    }
    fn report(&self) -> Report {
        self.report.clone()
    }
}

/// The notes the estimator adds to its report.
pub fn note_settings(
    report: &mut Report,
    s: &Settings,
    ls: &LightSpace,
    light: &shadow_map_core::Light,
    receivers: &Receivers,
    taps: u64,
) {
    let view = &ls.view;
    report.note("resolution", view.r);
    report.note("variant", format!("{:?}", s.variant).to_lowercase());
    report.note("kernel", format!("{:?}", s.kernel).to_lowercase());
    report.note("layers", s.peeled_layers());
    report.note("near", view.n);
    report.note("far", view.far);
    if s.kernel == KernelMode::Lexels {
        let radius = 0.5 * light.diameter();
        report.note(
            "paper_n",
            paper_plane_distance(radius, view.r, s.k, view.w / view.n),
        );
    }
    if taps > 0 {
        let n = receivers.active_count().max(1);
        report.note(
            "taps_per_receiver",
            format!("{:.1}", taps as f64 / n as f64),
        );
    }
    report.note("out_of_frustum_fit", ls.fit.out_of_frustum);
    report.note("window_scale", ls.fit.window_scale);
    let beyond = beyond_window(view, light, receivers, s);
    if beyond > 0 {
        report.note("beyond_sphere_window", beyond);
    }
    report.warn(shadow_map_core::Warning::KernelClipped { receivers: beyond });
}

#[cfg(test)]
mod tests;
