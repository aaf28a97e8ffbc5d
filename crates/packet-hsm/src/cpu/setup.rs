//! Step 5 for one receiver and one sub-light: the map-free set-up (facing fraction, projection,
//! threshold), the tight kernel from the MSSM and the trivial lit / umbra classification.
use super::SubView;
use crate::math::contour::{
    plane_threshold_range, true_min, CellRect, OccluderTest, Receiver, SampleGrid,
};
use crate::math::{kernel_cells, radial::Emitter};
use crate::settings::Config;
use glam::{Vec2, Vec3};
use shadow_map_core::{light::front_fraction, silhouette::Silhouette, ReceiverPlane, Receivers};

/// The outcome of step 5 for one receiver and one sub-light.
#[derive(Debug, Clone, Copy)]
pub enum Prep {
    /// V (with the facing factor) is known: behind, outside, fully lit or fully occluded.
    Done(f32),
    /// A penumbra receiver.
    Penumbra {
        /// The receiver as the contour sees it.
        rec: Receiver,
        /// Its kernel in dual cells.
        cr: CellRect,
        /// The facing fraction of the sub-light.
        facing: f32,
    },
}

/// The per-receiver setup that needs no map (the CPU twin's; `packet_hsm_frame.wgsl`'s `frame_setup` is
/// its twin on the GPU).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ReceiverSetup {
    /// V (with the facing factor) is known: behind the light, facing away, nearer than n.
    Settled(f32),
    /// Projects outside the map (counted): V = facing.
    Outside(f32),
    /// Needs the map: texel coordinates, depth, classification threshold, facing fraction.
    Map {
        /// `(u_p, v_p)`.
        uv: Vec2,
        /// `z_p`.
        zp: f32,
        /// `t_p` (`z_p` with midpoints or the receiver plane, `z_p - eps` with the bias).
        t: f32,
        /// Fraction of the sub-light in front of the receiver's tangent plane.
        facing: f32,
        /// The receiver plane (`receiver_plane=true`): a sample occludes only if it also passes
        /// [`ReceiverPlane::caster`] on its true depth (with the bias, instead of the bias test).
        plane: Option<ReceiverPlane>,
        /// A sphere light's silhouette disk seen from the receiver.
        sil: Option<Silhouette>,
    },
}

/// Step 5, the part without maps: light-space transform, facing fraction of the sub-light (the
/// contract's tangent-plane term), projection, classification threshold.
pub fn setup_receiver(sv: &SubView, cfg: &Config, pw: Vec3, nw: Vec3) -> ReceiverSetup {
    let view = &sv.ls.view;
    let p = view.frame.to_light(pw);
    let n = view.frame.dir_to_light(nw);
    let (facing, sil) = match sv.emitter {
        Emitter::Sphere(r) => {
            // Two-sided: the contract's silhouette disk in world space; a receiver behind the
            // map's plane or whose silhouette reaches its depth is outside every view (V = facing,
            // as backprojection does).
            let facing = sv.light.front_fraction_world(pw, nw);
            if !(facing > 0.0) {
                return ReceiverSetup::Settled(0.0);
            }
            match Silhouette::new(p, r as f32).filter(|_| p.z > 0.0) {
                Some(s) => (facing, Some(s)),
                None => return ReceiverSetup::Outside(facing),
            }
        }
        // The sun: its disk of directions one unit from p (Light::front_fraction_world).
        _ if view.is_ortho() => (front_fraction(&sv.shape, Vec3::Z, n), None),
        _ => {
            if !(p.z > 0.0) {
                return ReceiverSetup::Settled(0.0);
            }
            (front_fraction(&sv.shape, p, n), None)
        }
    };
    if !(facing > 0.0) {
        return ReceiverSetup::Settled(0.0);
    }
    if p.z <= view.n {
        return ReceiverSetup::Settled(facing);
    }
    let uv = view.project(p);
    if !view.contains(uv) {
        return ReceiverSetup::Outside(facing);
    }
    let t = if cfg.shadow.midpoint() || cfg.shadow.receiver_plane {
        p.z
    } else {
        p.z - view.receiver_bias(p, n, cfg.shadow.bias, cfg.shadow.slope_bias)
    };
    let plane = cfg
        .shadow
        .receiver_plane
        .then(|| ReceiverPlane::plane(view, p, n, cfg.shadow.bias, 0.0));
    ReceiverSetup::Map {
        uv,
        zp: p.z,
        t,
        facing,
        plane,
        sil,
    }
}

/// Step 5 for one receiver: [`setup_receiver`], then the tight kernel from the MSSM and the
/// trivial classification. `outside` is set when the receiver projects outside the map.
pub fn prepare(
    sv: &SubView,
    grid: &SampleGrid,
    cfg: &Config,
    pw: Vec3,
    nw: Vec3,
    outside: &mut bool,
) -> Prep {
    let (uv, zp, t, facing, plane, sil) = match setup_receiver(sv, cfg, pw, nw) {
        ReceiverSetup::Settled(x) => return Prep::Done(x),
        ReceiverSetup::Outside(x) => {
            *outside = true;
            return Prep::Done(x);
        }
        ReceiverSetup::Map {
            uv,
            zp,
            t,
            facing,
            plane,
            sil,
        } => (uv, zp, t, facing, plane, sil),
    };
    let Some(cr) = kernel_cells(
        &sv.ls.view,
        &sv.mssm,
        uv,
        zp,
        kernel_light(sv, sil.as_ref()),
    ) else {
        return Prep::Done(facing);
    };
    let mm = sv.dual.query(&cr);
    let test = OccluderTest { t, plane };
    let (lit, umbra) = trivial(mm.min, mm.max, &test, &cr, || {
        true_min(
            grid.class_is_depth(),
            Some(&sv.mssm),
            mm.min,
            [cr[0], cr[1], cr[2], cr[3]],
        )
    });
    if lit {
        return Prep::Done(facing); // fully lit
    }
    if umbra {
        return Prep::Done(0.0); // fully occluded (umbra)
    }
    let mut rec = Receiver::with_test(grid, uv.as_dvec2(), zp as f64, test);
    rec.sil = sil;
    Prep::Penumbra { rec, cr, facing }
}

/// [`prepare`] for receiver `k` of `receivers`: its outcome, and whether it projects outside
/// the map.
pub fn prepare_receiver(
    sv: &SubView,
    grid: &SampleGrid,
    cfg: &Config,
    receivers: &Receivers,
    k: usize,
) -> (Prep, bool) {
    let mut outside = false;
    let (pw, nw) = (receivers.position()[k], receivers.normal()[k]);
    let prep = prepare(sv, grid, cfg, pw, nw, &mut outside);
    (prep, outside)
}

/// The light size `l` of a receiver's kernel ([`kernel_cells`]): the (sub-)light's bounding
/// rectangle (a disk's bounding square is conservative, docs/methods.md §3 "Disk lights"), or for
/// a sphere the smallest rectangle centred on the light's centre holding [`Silhouette::clip`]
/// (the image on z = 0 of the silhouette disk seen from the receiver: every sample whose
/// backprojection meets the disk's image lies in that kernel; §3 "Sphere lights").
pub fn kernel_light(sv: &SubView, sil: Option<&Silhouette>) -> Vec2 {
    match sil {
        Some(s) => {
            2.0 * Vec2::new(
                s.clip[0].abs().max(s.clip[2].abs()),
                s.clip[1].abs().max(s.clip[3].abs()),
            )
        }
        None => 2.0 * sv.half,
    }
}

/// Step 5's trivial classification of a kernel `cr` whose classification depths span
/// `[min, max]`: `(fully lit, fully occluded)`. Classic test: `min >= t` / `max < t`. With a
/// receiver plane, fully occluded also needs `max` below the plane's smallest threshold over the
/// kernel's samples, and fully lit also holds when the kernel's smallest true depth
/// (`true_min()`, see [`true_min`]) reaches its largest threshold ([`plane_threshold_range`],
/// conservative).
pub fn trivial(
    min: f32,
    max: f32,
    test: &OccluderTest,
    cr: &CellRect,
    true_min: impl FnOnce() -> f32,
) -> (bool, bool) {
    if test.plane.is_none() {
        return (!(min < test.t), max < test.t);
    }
    if !(min < test.t) {
        return (true, false);
    }
    // Cells [x0, x1) touch samples [x0, x1] (inclusive).
    let (lo, hi) = plane_threshold_range(std::slice::from_ref(test), [cr[0], cr[1], cr[2], cr[3]]);
    if true_min() >= hi {
        return (true, false);
    }
    (false, max < test.t && max < lo)
}
