//! The engine path's kernel against the CPU twin on the very maps the frame rendered: one frame
//! of [`AccumulationFrame`] recorded from uploaded casters and receivers, V, the status and the
//! maps read back, then [`CpuAccumulation::estimate_with`] on those maps, so only the kernel
//! differs. Every receiver beyond [`Tolerance::TWIN`] must be a tie: nudging the depth
//! threshold by [`TIE_NUDGE_REL`] of the depth (through `bias`) or moving the receiver by
//! [`SAMPLING_NUDGE_REL`] of its distance from the origin changes the CPU's V or reproduces the
//! GPU's (a caster centre on the footprint's edge, a bit on a caster square's edge, a kernel
//! bound on a texel edge).
//!
//! One known difference is checked by its own rule instead: the exact variant on a receiver
//! whose every occlusion bit lies behind its tangent plane (a grazing receiver with few bits),
//! where no bit samples the part of the light that reaches it. The kernel sets those bits from
//! the start and so finds the light fully occluded (V = 0); the CPU twin sets them only once a
//! caster is found, so it gives V = 0 too when one is, and the facing fraction when none is.
#![cfg(feature = "gpu")]

use accumulation::{
    cpu::MAX_BITS,
    math::{Footprint, FrontEdge},
    settings::{Settings, Variant},
    AccumulationFrame, CpuAccumulation,
};
use glam::Vec3;
use shadow_map_core::{
    gpu::{frame::FrameEstimator, shared::CUT_BITS, GpuContext},
    light_space::LightSpace,
    LightView, Params, Receivers, Result, Scene, SoftShadowEstimator,
};
use test_support::{fixtures::points, CaseStats, Tolerance, Verdict};

const TWIN: Tolerance = Tolerance::TWIN;
/// The depth nudge of a depth tie, relative to the depth.
pub const TIE_NUDGE_REL: f32 = 1e-5;
/// The receiver nudge of a sampling tie, relative to its distance from the origin.
pub const SAMPLING_NUDGE_REL: f32 = 1e-6;

/// One frame's output, read back: what [`test_support::frame_run`] reads, with the raw status
/// words and the maps the frame rendered.
pub struct FrameRun {
    /// The view the frame fitted.
    pub view: LightView,
    /// V as the frame wrote it (NaN for inactive receivers, outside ones and cut ones).
    pub v: Vec<f32>,
    /// The status words: lit receivers outside the frustum, non-finite results, cut receivers,
    /// outside receivers left NaN.
    pub status: Vec<u32>,
    /// The maps the frame rendered (layers, and the MSSM rebuilt from layer 0).
    pub maps: LightSpace,
}

/// One frame of `frame` over `scene` and `rec` ([`test_support::frame_run::run_frame`]), then its
/// status words and its maps read back. Errors: the frame's own (a view it cannot fit, device
/// limits).
pub fn run_frame(
    ctx: &GpuContext,
    frame: &AccumulationFrame,
    scene: &Scene,
    rec: &Receivers,
) -> Result<FrameRun> {
    let (rig, out) = test_support::frame_run::run_frame(ctx, frame, scene, rec)?;
    let view = rig.views[0].expect("accumulation fits one view");
    let status_buf = frame.status().expect("the frame keeps a status");
    let status: Vec<u32> = ctx.read_buffer(status_buf, status_buf.size())?;
    let maps = frame.maps().layers.light_space(&view).to_cpu(ctx)?;
    Ok(FrameRun {
        view,
        v: out.v,
        status,
        maps,
    })
}

/// The CPU twin's V on `maps` with the parameters `params` and the depth bias `bias` (lit
/// receivers outside the frustum left NaN).
pub fn cpu_on(
    maps: &LightSpace,
    scene: &Scene,
    rec: &Receivers,
    params: &Params,
    bias: f32,
) -> std::result::Result<Vec<f32>, String> {
    let mut e = CpuAccumulation::new().map_err(|e| e.to_string())?;
    shadow_map_core::estimator::configure(&mut e, params).map_err(|e| e.to_string())?;
    e.set_param("bias", &bias.to_string())
        .map_err(|e| e.to_string())?;
    let mut v = vec![0.5; rec.len()];
    e.estimate_with(maps, scene, rec, &mut v)
        .map_err(|e| format!("cpu estimate: {e}"))?;
    Ok(v)
}

/// What [`judge_on_maps`] counted besides the comparison.
#[derive(Debug, Clone, Copy, Default)]
pub struct Left {
    /// Active receivers outside the one frustum (left NaN by the CPU twin's estimate on the
    /// maps, for its `settle_outside`; the frame's settle passes settle them or leave NaN).
    pub outside: usize,
    /// Among them, those the frame left NaN (something may shadow them).
    pub unsettled: usize,
    /// Among those, the ones the CPU's settle test settles (a triangle touching the pyramid to
    /// within f32 rounding: the frame's test is the stricter).
    pub unsettled_gpu_only: usize,
    /// Active receivers the frame cut at the device's loop budget (`CUT_BITS`: the caller
    /// redoes them on the CPU).
    pub cut: usize,
    /// Active receivers of the exact variant with no bit in front of their tangent plane
    /// ([`no_front_bit`]), checked by that rule.
    pub no_front_bit: usize,
    /// Those among them where the two differ (the CPU twin found no caster).
    pub no_front_bit_differ: usize,
}

/// Whether, for the exact variant, every occlusion bit of receiver k's light patch lies behind
/// its tangent plane while part of the light is in front of it (as [`CpuAccumulation`]'s
/// shadowing computes the patch and the plane in `view`).
pub fn no_front_bit(
    view: &LightView,
    scene: &Scene,
    rec: &Receivers,
    s: &Settings,
    k: usize,
) -> bool {
    if s.variant != Variant::Exact {
        return false;
    }
    let p = view.frame.to_light(rec.position()[k]);
    let fp = Footprint::for_light(&scene.light().shape, s.sphere, p, (view.n, view.far));
    let front = FrontEdge::new(&fp.patch, fp.r, view.frame.dir_to_light(rec.normal()[k]));
    let b = s.bits.min(MAX_BITS);
    front.fraction > 0.0
        && !front.whole
        && (0..b * b).all(|i| !front.front(fp.patch.bit_local(i % b, i / b, b)))
}

/// The frame's V against the CPU twin on the frame's own maps (`run.maps`), judged by
/// [`Tolerance::judge`] with the depth and sampling tie explainers on the same maps. Receivers
/// outside the frustum (NaN in the CPU twin's estimate) are counted in status word 0 and hold
/// what the CPU's settle test gives them (the facing fraction, or NaN counted in word 3, where
/// the GPU may also leave NaN for one of them, or 1 in 500, that the CPU settles), cut receivers
/// (`CUT_BITS`) counted in word 2, no non-finite result (word 1); both kinds are left out of the
/// comparison, and receivers with [`no_front_bit`] are checked by their rule (GPU V = 0, CPU V
/// = 0 or the facing fraction). Returns the CPU's V, the case's counts and what was left out.
pub fn judge_on_maps(
    label: &str,
    run: &FrameRun,
    scene: &Scene,
    rec: &Receivers,
    params: &Params,
) -> std::result::Result<(Vec<f32>, CaseStats, Left), String> {
    let bias = params.float("bias").map_err(|e| e.to_string())? as f32;
    let maps = &run.maps;
    let v_cpu = cpu_on(maps, scene, rec, params, bias)?;
    let mut twin = CpuAccumulation::new().map_err(|e| e.to_string())?;
    shadow_map_core::estimator::configure(&mut twin, params).map_err(|e| e.to_string())?;
    let s = twin.settings();
    let mut left = Left::default();
    let mut compared = rec.active().to_vec();
    let mut settler = None;
    for k in 0..rec.len() {
        let (c, g) = (v_cpu[k], run.v[k]);
        if !rec.active()[k] {
            continue;
        }
        if g.to_bits() == CUT_BITS {
            left.cut += 1;
            compared[k] = false;
        } else if c.is_nan() {
            let settler =
                settler.get_or_insert_with(|| shadow_map_core::settle::Settler::new(scene));
            let (pw, nw) = (rec.position()[k], rec.normal()[k]);
            let settled = settler.unshadowed(pw, nw);
            let facing = scene.light().front_fraction_world(pw, nw).clamp(0.0, 1.0);
            left.outside += 1;
            compared[k] = false;
            if g.is_nan() {
                left.unsettled += 1;
                left.unsettled_gpu_only += usize::from(settled);
            } else if !settled || (g - facing).abs() > 1e-5 {
                return Err(format!(
                    "{label}: receiver {k} outside the frustum: gpu {g}, cpu settle test {}",
                    if settled {
                        format!("settles it, V {facing}")
                    } else {
                        "does not settle it".to_string()
                    }
                ));
            }
        } else if g.is_nan() {
            return Err(format!(
                "{label}: receiver {k} left NaN by the frame only (cpu {c})"
            ));
        } else if no_front_bit(&maps.view, scene, rec, &s, k) {
            let (pw, nw) = (rec.position()[k], rec.normal()[k]);
            let facing = scene.light().front_fraction_world(pw, nw).clamp(0.0, 1.0);
            if g != 0.0 || (c != 0.0 && c != facing) {
                return Err(format!(
                    "{label}: receiver {k} with no bit in front of its plane: cpu {c} (facing \
                     {facing}), gpu {g}"
                ));
            }
            left.no_front_bit += 1;
            left.no_front_bit_differ += usize::from(c != g);
            compared[k] = false;
        }
    }
    let w = |k: usize| run.status.get(k).copied().unwrap_or(0) as usize;
    if (w(0), w(1), w(2), w(3)) != (left.outside, 0, left.cut, left.unsettled) {
        return Err(format!(
            "{label}: status {:?}, but {} outside ({} left NaN) and {} cut receivers",
            run.status, left.outside, left.unsettled, left.cut
        ));
    }
    if left.unsettled_gpu_only > (left.outside / 500).max(1) {
        return Err(format!(
            "{label}: {} of {} outside receivers settled by the CPU's test only",
            left.unsettled_gpu_only, left.outside
        ));
    }
    let masked = |v: &[f32]| -> Vec<f32> {
        v.iter()
            .zip(&compared)
            .map(|(&x, &c)| if c { x } else { f32::NAN })
            .collect()
    };
    let (c_cmp, g_cmp) = (masked(&v_cpu), masked(&run.v));
    let cmp = TWIN.compare(label, &compared, &c_cmp, &g_cmp)?;
    let st = TWIN.judge(label, &cmp, rec, &c_cmp, &g_cmp, |beyond| {
        let nudge = test_support::tolerance::bias_nudge(&maps.view, TIE_NUDGE_REL);
        let nudged = [bias + nudge, (bias - nudge).max(0.0)]
            .iter()
            .map(|&b| cpu_on(maps, scene, rec, params, b))
            .collect::<std::result::Result<Vec<_>, _>>()?;
        beyond
            .iter()
            .map(|&k| {
                let (c, g) = (c_cmp[k], g_cmp[k]);
                let depth = nudged.iter().any(|v| TWIN.nudge_explains(v[k], c, g));
                let sampling = !depth && sampling_tie(maps, scene, rec, params, bias, k, c, g)?;
                Ok(Verdict::of(depth, sampling))
            })
            .collect()
    })?;
    Ok((v_cpu, st, left))
}

/// True when moving receiver k by a few f32 ulps (six directions) changes the CPU's V by more
/// than the tolerance or brings it within the tolerance of the GPU's.
#[allow(clippy::too_many_arguments)]
fn sampling_tie(
    maps: &LightSpace,
    scene: &Scene,
    rec: &Receivers,
    params: &Params,
    bias: f32,
    k: usize,
    c: f32,
    g: f32,
) -> std::result::Result<bool, String> {
    let p = rec.position()[k];
    let d = SAMPLING_NUDGE_REL * p.length().max(1.0);
    let pos: Vec<Vec3> = [Vec3::X, -Vec3::X, Vec3::Z, -Vec3::Z, Vec3::Y, -Vec3::Y]
        .iter()
        .map(|e| p + *e * d)
        .collect();
    Ok(
        cpu_on(maps, scene, &points(pos, rec.normal()[k]), params, bias)?
            .iter()
            .any(|&v| TWIN.nudge_explains(v, c, g)),
    )
}
