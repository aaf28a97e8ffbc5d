//! The CPU backprojection estimator (docs/methods.md §2; Bavoil 2008 §4.1, §4.2, §5), over
//! the geometry of [`crate::math`] with the settings of [`crate::settings`], and the light view
//! and light-space request it plans ([`plan`], [`request`]), which the frame renders too.
use crate::math::{
    backprojected_micropatch, emitter_bits, gap_filled, micropatch_k, Emitter, Rect, Silhouette,
};
use crate::settings::{LayerRule, Occlusion, Resolved, Settings};
use glam::Vec3;
use shadow_map_core::{
    light_space::{LightSpace, LightSpaceRequest},
    light_view::{FitReport, LightView},
    mssm::refine_kernel,
    Cancel, Configured, RasterOptions, ReceiverPlane, Receivers, Report, Result, Scene,
    SoftShadowEstimator, Warning,
};
use std::sync::atomic::{AtomicU32, AtomicUsize, Ordering};

/// The report notes of the resolved choices (`occlusion`, `layer_rule`, `gap_filling`, and
/// `bits` under bitmask).
fn note_resolved(report: &mut Report, s: &Settings, res: Resolved) {
    let rule = if res.first_nonzero {
        LayerRule::FirstNonzero
    } else {
        LayerRule::Deepest
    };
    report.note("occlusion", res.occlusion);
    report.note("layer_rule", rule);
    report.note("gap_filling", res.gap_filling);
    if res.occlusion == Occlusion::Bitmask {
        report.note("bits", s.bits);
    }
}

/// Warns that `scene`'s semi-transparent meshes were cast opaque when `occlusion=bitmask` was
/// asked for (the bits carry no opacity; `auto` takes additive occlusion there): the CPU
/// estimator's report and the engine path's scene warnings.
pub fn warn_bitmask_opacity(report: &mut Report, s: &Settings, scene: &Scene) {
    if s.occlusion == Occlusion::Bitmask {
        report.warn_all(Warning::opaque_casters(scene));
    }
}

/// Soft shadows by micropatch backprojection onto an area light (Guennebaud et al. 2006),
/// with Bavoil's (2008) depth-peeled layers (§4.1: per texel, only the furthest occluding layer
/// is backprojected, with its true depth), midpoint layers against self-shadowing (§4.2), and the
/// adaptive uniform step (§5).
///
/// Per receiver p (light-space depth `z_p`, texel coordinates `(u_p, v_p)`):
/// 1. facing = the fraction of the light in front of p's tangent plane; behind the light: 0;
///    `z_p <= n`: facing (nothing recorded is nearer).
/// 2. Kernel: [`LightView::kernel_texels`](shadow_map_core::LightView::kernel_texels) at `z_m = n`, then refined with the MSSM minimum over the kernel
///    (`z_m = min depth`) until it stops shrinking; if that minimum is `>= z_p` (bias mode:
///    `>= z_p - eps`; `receiver_plane=true`: `>=` the largest depth a caster of the receiver
///    plane can have over the kernel, [`ReceiverPlane::max_threshold`]), V = facing.
/// 3. Per sample (block centre of the adaptive step), the layers from the deepest: a layer
///    occludes when its midpoint is `< z_p` (bias mode: `z + eps < z_p`) and, with
///    `receiver_plane=true`, its true depth passes [`ReceiverPlane::caster`] (in bias mode the
///    plane test replaces the bias test). `layer_rule=deepest` takes the first
///    occluding layer; `layer_rule=first_nonzero` (Bavoil §4.2's wording) the first occluding
///    layer whose micropatch `B_s` overlaps the light ([`LayerRule`] has the measurements).
///    The defaults (`auto`, [`Settings::resolve`]): bitmask, first non-zero, gap filling on an
///    opaque scene; additive, deepest, no gap filling when a mesh is semi-transparent.
/// 4. `occlusion=additive`: sum `area(B_s ∩ L)` (times the opacity weight) over the kernel's samples, and
///    `V = facing (1 - clamp01(A_occ / A_L))`. `occlusion=bitmask`: set the bits (light samples,
///    [`emitter_bits`]) each `B_s` contains, in the same order, stopping when all are set, and
///    `V = facing (1 - set / B^2)` ([`Occlusion`]).
///
/// Rect, disk and sphere lights (docs/methods.md §2 "Disk and sphere lights"): `area(B_s ∩ L)` is
/// a rectangle's overlap with the rect or the disk in the light plane, or, for a sphere, the
/// overlap of `B_s` carried onto the receiver's silhouette disk ([`Silhouette`]), whose hull also
/// bounds the kernel.
pub struct CpuBackprojection {
    /// The parameters and their typed settings.
    config: Configured<Settings>,
    ls: Option<LightSpace>,
    report: Report,
    cancel: Cancel,
}

impl CpuBackprojection {
    /// With default parameters.
    pub fn new() -> Result<Self> {
        Ok(CpuBackprojection {
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
    /// The current parameters, typed.
    pub fn settings(&self) -> &Settings {
        self.config.settings()
    }
    /// Takes given light-space data as the last build's: the CPU estimate on maps made elsewhere
    /// (say the engine path's, read back with
    /// `BackprojectionFrame::light_space(view).to_cpu(ctx)`).
    pub fn set_light_space(&mut self, ls: LightSpace) {
        self.ls = Some(ls);
    }
    /// [`SoftShadowEstimator::estimate`] with only the light taken from a scene: V of
    /// `receivers` from the light-space data of the last build or [`Self::set_light_space`].
    pub fn estimate_light(
        &mut self,
        light: &shadow_map_core::Light,
        receivers: &Receivers,
        v: &mut [f32],
    ) -> Result<()> {
        receivers.check_output(v)?;
        let ls = shadow_map_core::estimator::built(self.ls.as_ref())?;
        let s = self.config.settings();
        let h = light.half_extent();
        let emitter = Emitter::of(&light.shape);
        let res = s.resolve(!ls.opacity.is_empty());
        let setup = Setup {
            ls,
            emitter,
            half: [h.x, h.y],
            area: emitter.area(),
            midpoint: s.shadow.midpoint(),
            gap_filling: res.gap_filling,
            max_nspp: s.max_nspp,
            b0: s.shadow.bias,
            b1: s.shadow.slope_bias,
            receiver_plane: s.shadow.receiver_plane,
            first_nonzero: res.first_nonzero,
            max_step: AtomicU32::new(1),
            bit_pts: match res.occlusion {
                Occlusion::Bitmask => emitter_bits(&emitter, s.bits),
                _ => Vec::new(),
            },
            bit_side: s.bits,
        };
        let view = &ls.view;
        let outside = AtomicUsize::new(0);
        let t = std::time::Instant::now();
        let nonfinite = receivers.estimate_each(&self.cancel, v, |pw, nw| {
            let facing = light.front_fraction_world(pw, nw);
            let p = view.frame.to_light(pw);
            // A sphere's silhouette disk seen from p (None: it reaches p's depth).
            let sil = match emitter {
                Emitter::Sphere { radius } if p.z > 0.0 => Silhouette::new(p, radius),
                _ => None,
            };
            let sphere_unserved = matches!(emitter, Emitter::Sphere { .. }) && sil.is_none();
            let x = if !(facing > 0.0) {
                0.0
            } else if p.z <= 0.0 || sphere_unserved {
                // Behind a sphere light's frustum, or beside its silhouette.
                outside.fetch_add(1, Ordering::Relaxed);
                facing
            } else if p.z <= view.n {
                facing
            } else {
                let uv = view.project(p);
                if !view.contains(uv) {
                    outside.fetch_add(1, Ordering::Relaxed);
                    facing
                } else {
                    let n = view.frame.dir_to_light(nw);
                    facing * setup.visibility(p, n, uv, sil.as_ref())
                }
            };
            Some(x)
        })?;
        self.report
            .stages
            .push(("estimate".into(), t.elapsed().as_secs_f64() * 1e3));
        self.report.note("resolution", view.r);
        self.report.note("layers", ls.layers.len());
        self.report.note("self_shadow", s.shadow.self_shadow);
        note_resolved(&mut self.report, s, res);
        self.report.note("receiver_plane", s.shadow.receiver_plane);
        self.report
            .note("max_step", setup.max_step.load(Ordering::Relaxed));
        self.report.note("near", view.n);
        self.report.note("far", view.far);
        let outside = outside.into_inner();
        self.report
            .note("out_of_frustum", outside + ls.fit.out_of_frustum);
        self.report.note("window_scale", ls.fit.window_scale);
        self.report.warn(Warning::NonFiniteV {
            receivers: nonfinite,
        });
        self.report
            .warn(Warning::OutsideViews { receivers: outside });
        self.report.warn(Warning::KernelClipped {
            receivers: shadow_map_core::light_view::beyond_sphere_window(view, light, receivers),
        });
        Ok(())
    }
    /// Builds the light-space data in a given `view` (the engine path's CPU twin: a view the
    /// caller fitted, e.g. an engine path's `FrameEstimator::fit_views`), with the request
    /// [`request`] makes for `receivers`. Errors: `view` of another resolution than the
    /// parameters' ([`shadow_map_core::Error::LightView`]).
    pub fn build_in_view(
        &mut self,
        scene: &Scene,
        receivers: &Receivers,
        view: LightView,
    ) -> Result<()> {
        let r = self.config.settings().resolution;
        if view.r != r {
            return Err(shadow_map_core::Error::LightView(format!(
                "a view of resolution {} for resolution={r}",
                view.r
            )));
        }
        let half = shadow_map_core::light_view::fit_half_extent(scene.light(), receivers);
        self.timed_build(|s| {
            LightSpace::try_build_in_view(
                scene,
                view,
                FitReport::default(),
                &request(s, &view, half),
            )
        })
    }

    /// A fresh report whose `build` stage times `make` (given the settings), then the
    /// light-space data it made kept as the last build's.
    fn timed_build(&mut self, make: impl FnOnce(&Settings) -> Result<LightSpace>) -> Result<()> {
        self.report = Report::default();
        let settings = self.config.settings();
        let ls = self.report.time("build", || make(settings))?;
        self.report.light_space_bytes = ls.bytes();
        self.ls = Some(ls);
        Ok(())
    }
}

/// Settings read once per estimate.
struct Setup<'a> {
    ls: &'a LightSpace,
    /// The light's shape (rect, disk, sphere).
    emitter: Emitter,
    /// Half extents of its bounding rectangle in the light plane (the kernel's light size).
    half: [f32; 2],
    area: f64,
    midpoint: bool,
    gap_filling: bool,
    max_nspp: u32,
    b0: f32,
    b1: f32,
    /// Receiver-plane rejection on.
    receiver_plane: bool,
    /// Bavoil §4.2's first non-zero contribution (else the deepest occluding layer).
    first_nonzero: bool,
    /// Largest adaptive step used (reported).
    max_step: AtomicU32,
    /// `occlusion=bitmask`: the bit points ([`shadow_map_core::bitmask::bit_points`]) on the
    /// light plane (rect, disk) or in a sphere's silhouette-disk coordinates; empty: additive.
    bit_pts: Vec<glam::Vec2>,
    /// Bit-grid side B (rect lights test bits by [`BitMask::set_in_lattice`]).
    ///
    /// [`BitMask::set_in_lattice`]: shadow_map_core::bitmask::BitMask::set_in_lattice
    bit_side: u32,
}

/// A half-open texel rectangle `[x0, x1) x [y0, y1)` of the kernel around `uv`, clamped to the map.
fn kernel_rect(view: &LightView, uv: glam::Vec2, wx: f32, wy: f32) -> [i32; 4] {
    let r = view.r as f32;
    let lo = |c: f32, w: f32| (c - 0.5 * w).floor().clamp(0.0, r) as i32;
    let hi = |c: f32, w: f32| (c + 0.5 * w).ceil().clamp(0.0, r) as i32;
    [lo(uv.x, wx), lo(uv.y, wy), hi(uv.x, wx), hi(uv.y, wy)]
}

/// A half-open texel rectangle covering continuous bounds `[u0, v0, u1, v1]`, clamped to the map.
fn bounds_rect(view: &LightView, b: [f32; 4]) -> [i32; 4] {
    let r = view.r as f32;
    [
        b[0].floor().clamp(0.0, r) as i32,
        b[1].floor().clamp(0.0, r) as i32,
        b[2].ceil().clamp(0.0, r) as i32,
        b[3].ceil().clamp(0.0, r) as i32,
    ]
}

impl Setup<'_> {
    /// `area(B_s ∩ L)` ([`Emitter::overlap`]).
    #[inline]
    fn overlap(&self, b: &Rect, sil: Option<&Silhouette>) -> f64 {
        self.emitter.overlap(b, sil)
    }

    /// Visibility before the facing factor, in [0, 1]. `sil`: a sphere light's silhouette disk
    /// seen from p.
    fn visibility(&self, p: Vec3, n: Vec3, uv: glam::Vec2, sil: Option<&Silhouette>) -> f32 {
        let ls = self.ls;
        let view = &ls.view;
        let zp = p.z;
        let eps = if self.midpoint {
            0.0
        } else {
            view.receiver_bias(p, n, self.b0, self.b1)
        };
        // Receiver-plane rejection: a sample occludes only if it also lies in front of p's
        // tangent plane (midpoints), or instead of the bias test (bias mode).
        let plane = self
            .receiver_plane
            .then(|| ReceiverPlane::plane(view, p, n, self.b0, 0.0));
        let (lx, ly) = (2.0 * self.half[0], 2.0 * self.half[1]);
        // Kernel at z_m = n, refined by the exact min over it (docs/methods.md §2); a sphere's
        // from its silhouette disk's hull.
        let kernel = |zm: f32| match sil {
            Some(s) => s
                .kernel_bounds(view, p, zm)
                .map_or([0, 0, view.r as i32, view.r as i32], |b| {
                    bounds_rect(view, b)
                }),
            None => kernel_rect(
                view,
                uv,
                view.kernel_texels(lx, zm, zp),
                view.kernel_texels(ly, zm, zp),
            ),
        };
        // No sample of the kernel can occlude: the plane's largest caster depth bound over the
        // kernel's texels (ReceiverPlane::max_threshold, conservative).
        let bound = |r: &[i32; 4]| match &plane {
            Some(pl) => pl.max_threshold(r[0] as f32, r[2] as f32, r[1] as f32, r[3] as f32),
            None => zp - eps,
        };
        let Some(rect) = refine_kernel(ls.mssm.as_ref(), view.n, kernel, bound) else {
            return 1.0;
        };
        let (nx, ny) = ((rect[2] - rect[0]) as u32, (rect[3] - rect[1]) as u32);
        if nx == 0 || ny == 0 {
            return 1.0;
        }
        // Adaptive uniform step (Bavoil §5).
        let step = if (nx as u64) * (ny as u64) > self.max_nspp as u64 {
            (nx.max(ny) as f32 / (self.max_nspp as f32).sqrt())
                .ceil()
                .max(1.0) as u32
        } else {
            1
        };
        self.max_step.fetch_max(step, Ordering::Relaxed);
        let bx = nx.div_ceil(step) as usize;
        let by = ny.div_ceil(step) as usize;
        let k = micropatch_k(view);
        let uvp = [uv.x, uv.y];
        // Bavoil §4.2's rule needs a light of positive area to tell a contribution from none.
        let first_nonzero = self.first_nonzero && self.area > 0.0;
        // Per block: true depth of the occluding layer backprojected (`layer_rule`), or +inf.
        let mut occ = vec![f32::INFINITY; bx * by];
        // Per block: the backprojected layer's opacity (semi-transparent scenes only).
        let mut occ_alpha = vec![1.0f32; if ls.opacity.is_empty() { 0 } else { bx * by }];
        for b in 0..by {
            let j0 = rect[1] + (b as u32 * step) as i32;
            let j1 = (j0 + step as i32).min(rect[3]);
            let jc = j0 + (j1 - j0 - 1) / 2;
            for a in 0..bx {
                let i0 = rect[0] + (a as u32 * step) as i32;
                let i1 = (i0 + step as i32).min(rect[2]);
                let ic = i0 + (i1 - i0 - 1) / 2;
                for m in (0..ls.layers.len()).rev() {
                    let z = ls.layers[m].at(ic, jc);
                    let occludes = if self.midpoint {
                        let cls = ls.midpoints.get(m).map_or(z, |d| d.at(ic, jc));
                        match &plane {
                            Some(pl) => cls < zp && pl.caster(ic, jc, z),
                            None => cls < zp && z < zp,
                        }
                    } else {
                        match &plane {
                            Some(pl) => pl.caster(ic, jc, z),
                            None => z + eps < zp && z < zp,
                        }
                    };
                    if !occludes {
                        continue;
                    }
                    if first_nonzero {
                        let own = backprojected_micropatch(
                            [i0 as f32, i1 as f32, j0 as f32, j1 as f32],
                            uvp,
                            k,
                            z,
                            zp,
                        );
                        if !self.emitter.contributes(&own, sil) {
                            continue; // a zero contribution: try the next shallower layer
                        }
                    }
                    occ[b * bx + a] = z;
                    if !occ_alpha.is_empty() {
                        // This layer and those nearer the light, in front of the receiver.
                        let t = jc as usize * view.r as usize + ic as usize;
                        occ_alpha[b * bx + a] = ls.opacity_in_front(t, m, zp);
                    }
                    break;
                }
            }
        }
        let bitmask = !self.bit_pts.is_empty();
        let nbits = self.bit_pts.len() as u32;
        let mut mask = shadow_map_core::bitmask::BitMask::new();
        let mut a_occ = 0.0f64;
        'blocks: for b in 0..by {
            let j0 = rect[1] + (b as u32 * step) as i32;
            let j1 = (j0 + step as i32).min(rect[3]);
            for a in 0..bx {
                let z = occ[b * bx + a];
                if !z.is_finite() {
                    continue;
                }
                let i0 = rect[0] + (a as u32 * step) as i32;
                let i1 = (i0 + step as i32).min(rect[2]);
                let mut br = backprojected_micropatch(
                    [i0 as f32, i1 as f32, j0 as f32, j1 as f32],
                    uvp,
                    k,
                    z,
                    zp,
                );
                if self.gap_filling {
                    // The +u and +v neighbours' near edges: (i1 - u_p) S_t and (j1 - v_p) S_t.
                    if a + 1 < bx {
                        br.x1 = gap_filled(br.x1, k, occ[b * bx + a + 1], zp, i1 as f32 - uv.x);
                    }
                    if b + 1 < by {
                        br.y1 = gap_filled(br.y1, k, occ[(b + 1) * bx + a], zp, j1 as f32 - uv.y);
                    }
                }
                if bitmask {
                    // The bits B_s contains: on the light plane, or carried onto a sphere's
                    // silhouette disk.
                    let set = match (&self.emitter, sil) {
                        (Emitter::Sphere { .. }, Some(s)) => {
                            match s.carry_rect(br.x0, br.y0, br.x1, br.y1) {
                                Some(q) => mask.set_in_quad(&self.bit_pts, &q, false),
                                None => mask.count(),
                            }
                        }
                        (Emitter::Sphere { .. }, None) => mask.count(),
                        (Emitter::Rect { .. }, _) => mask.set_in_lattice(
                            &self.bit_pts,
                            self.bit_side,
                            glam::Vec2::new(br.x0, br.y0),
                            glam::Vec2::new(br.x1, br.y1),
                        ),
                        _ => mask.set_in_rect(
                            &self.bit_pts,
                            glam::Vec2::new(br.x0, br.y0),
                            glam::Vec2::new(br.x1, br.y1),
                        ),
                    };
                    if set == nbits {
                        break 'blocks;
                    }
                    continue;
                }
                let w = occ_alpha.get(b * bx + a).copied().unwrap_or(1.0) as f64;
                a_occ += w * self.overlap(&br, sil);
            }
        }
        if bitmask {
            return 1.0 - mask.count() as f32 / nbits as f32;
        }
        if !(self.area > 0.0) {
            return if a_occ > 0.0 { 0.0 } else { 1.0 };
        }
        // Snap a covered fraction within 1e-6 of 1 to full cover: summing abutting micropatches
        // in f32 bounds can miss the whole light by a rounding error (tiny lights).
        let f = a_occ / self.area;
        if f >= 1.0 - 1e-6 {
            return 0.0;
        }
        (1.0 - f.clamp(0.0, 1.0)) as f32
    }
}

/// The light view and the light-space request the CPU estimator builds for `params` (the engine
/// path fits the same view, `BackprojectionFrame`'s `fit_views`, and
/// renders the same request but for the MSSM's level count): the view fitted to
/// the receivers at the light centre; `layers` peeled layers; midpoints clamped at `max_bias`
/// texel footprints at the far plane (the largest footprint any receiver has, so the clamp never
/// binds tighter than `max_bias` footprints at the receiver); an anchored MSSM with enough levels
/// for the largest kernel (at `z_m = n`, `z_p = far`).
pub fn plan(
    settings: &Settings,
    scene: &Scene,
    receivers: &Receivers,
) -> Result<(LightView, FitReport, LightSpaceRequest)> {
    let light = scene.light();
    let r = settings.resolution;
    let opts = settings.view;
    let half = shadow_map_core::light_view::fit_half_extent(light, receivers);
    let (view, fit) = LightView::fit_with(scene, receivers, light.frame(), half, r, &opts)?;
    Ok((view, fit, request(settings, &view, half)))
}

/// The light-space request of [`plan`] in `view` for a light of half extent `half`
/// ([`fit_half_extent`](shadow_map_core::light_view::fit_half_extent)). The MSSM's levels only
/// speed the kernel's minimum query up; its result is the exact minimum over the query's
/// rectangle whatever their number.
pub fn request(settings: &Settings, view: &LightView, half: glam::Vec2) -> LightSpaceRequest {
    let r = settings.resolution;
    let l = 2.0 * half.max_element();
    let wmax = view.kernel_texels(l, view.n, view.far).clamp(1.0, r as f32);
    let levels = (wmax.log2().ceil() as u32).clamp(1, 10);
    LightSpaceRequest {
        resolution: r,
        layers: settings.layers,
        midpoints: settings.shadow.midpoint_clamp(view),
        mssm_levels: Some(levels),
        dual_mssm_levels: None,
        pyramid: false,
        raster: RasterOptions::default(),
        // Semi-transparent occluders weight their micropatches by opacity.
        opacity: true,
    }
}

impl SoftShadowEstimator for CpuBackprojection {
    shadow_map_core::estimator_identity!("backprojection", "micropatch backprojection onto rect, disk and sphere lights with depth-peeled layers and midpoints, additive or occlusion bits (Guennebaud 2006, Bavoil 2008, Schwarz & Stamminger 2007)", Cpu, config: config, cancel: cancel);
    fn build(&mut self, scene: &Scene, receivers: &Receivers) -> Result<()> {
        self.ls = None;
        self.timed_build(|s| {
            let (view, fit, req) = plan(s, scene, receivers)?;
            LightSpace::try_build_in_view(scene, view, fit, &req)
        })
    }
    fn estimate(&mut self, scene: &Scene, receivers: &Receivers, v: &mut [f32]) -> Result<()> {
        self.estimate_light(scene.light(), receivers, v)?;
        warn_bitmask_opacity(&mut self.report, self.config.settings(), scene);
        Ok(())
    }
    fn report(&self) -> Report {
        self.report.clone()
    }
}
