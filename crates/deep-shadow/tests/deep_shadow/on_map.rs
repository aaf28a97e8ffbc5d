//! The frame's V taken apart on the map it rendered: the CPU twin's queries and lookups read on
//! that map (read back), the explainer of the receivers beyond a tolerance, and the bounds of the
//! GPU estimator against the CPU twin's own build on the fixtures.
#![cfg(feature = "gpu")]
use deep_shadow::{
    cpu::finish,
    gpu::FrameMap,
    math::{
        transmittance_opaque_plane,
        view::{lookup_settings, query, Query},
        LookupSettings,
    },
    settings::Settings,
    DeepShadowFrame,
};
use glam::Vec2;
use shadow_map_core::{
    gpu::{frame::FrameEstimator, GpuContext},
    LightView, Params, ReceiverPlane, Receivers, Scene,
};
use std::sync::Arc;
use test_support::{
    frame_run::run_frame,
    tolerance::{CaseStats, Tolerance, Verdict},
};

/// The transmittance the CPU twin's lookup reads in `map` at `uv` with the caster test `plane`.
fn lookup(map: &FrameMap, uv: Vec2, plane: &ReceiverPlane, ls: &LookupSettings) -> f32 {
    match map {
        FrameMap::Lists(d) => d.transmittance_plane(uv, plane, ls).0,
        FrameMap::Depths(m) => transmittance_opaque_plane(m, uv, plane, ls),
    }
}

/// The CPU twin's V in `view` read from `map` (the frame's, read back): the twin's queries, its
/// lookup, its `finish`.
pub fn cpu_on_map(
    map: &FrameMap,
    scene: &Scene,
    rec: &Receivers,
    view: &LightView,
    s: &Settings,
) -> Vec<f32> {
    let ls = lookup_settings(view, scene.light(), s);
    let acc: Vec<f32> = (0..rec.len())
        .map(|k| {
            if !rec.active()[k] {
                return 0.0;
            }
            match query(view, scene.light(), rec.position()[k], rec.normal()[k], s) {
                Query::Fixed(x) => x,
                Query::Look { uv, plane, facing } => facing * lookup(map, uv, &plane, &ls),
            }
        })
        .collect();
    let mut v = vec![0.0; rec.len()];
    finish(scene, rec, &acc, 1, &mut v);
    v
}

/// Why receiver `k` is beyond the tolerance: the CPU twin's lookup on the same map with the
/// query's texel coordinates moved by a few ulps (a texel or cell edge the GPU's own projection
/// falls on the other side of) or its depth by 1e-6 relative (a depth the GPU computes an ulp
/// away), against the CPU's V `cpu` and the frame's `gpu`.
#[allow(clippy::too_many_arguments)]
pub fn explain(
    tol: &Tolerance,
    map: &FrameMap,
    scene: &Scene,
    rec: &Receivers,
    view: &LightView,
    s: &Settings,
    k: usize,
    (cpu, gpu): (f32, f32),
) -> Verdict {
    let Query::Look { uv, plane, facing } =
        query(view, scene.light(), rec.position()[k], rec.normal()[k], s)
    else {
        return Verdict::of(false, false).note("no lookup");
    };
    let ls = lookup_settings(view, scene.light(), s);
    let at =
        |uv: Vec2, plane: &ReceiverPlane| (facing * lookup(map, uv, plane, &ls)).clamp(0.0, 1.0);
    let d = 8.0 * f32::EPSILON * view.r as f32;
    let sampling = [Vec2::X, -Vec2::X, Vec2::Y, -Vec2::Y]
        .iter()
        .any(|&e| tol.nudge_explains(at(uv + d * e, &plane), cpu, gpu));
    let depth = [1.0 + 1e-6f32, 1.0 - 1e-6].iter().any(|&f| {
        let p = ReceiverPlane {
            zp: plane.zp * f,
            c: plane.c * f,
            ..plane
        };
        tol.nudge_explains(at(uv, &p), cpu, gpu)
    });
    Verdict::of(depth, sampling)
}

/// How far the GPU estimator's V may lie from the CPU twin's own build on a fixture, as
/// `(fraction of the active receivers beyond 1e-4, largest |dV|, RMSE)`. The frame's maps come
/// from the hardware rasteriser, whose sub-pixel vertex snapping (8 bits on lavapipe) covers a
/// texel centre within 1/256 texel of a caster's edge that the CPU's exact fill rule does not,
/// or the reverse: on an opaque fixture (bunny) that moved nothing here, and the bound is the
/// twins' own; on thin semi-transparent strands (hair, strands at 40 x 30, resolution 256) a
/// one-tap filter (`none`, `first`) moves a receiver by a fragment's whole opacity (measured: at
/// most 0.9% of the receivers, RMSE 0.029), a filter over many taps by a tap's share, or under
/// PCSS a blocker depth in or out of the average (measured: up to 13.7% of the receivers beyond
/// 1e-4, max 0.087, RMSE 2.6e-3 on hair under PCSS). [`frame_on_its_map`] shows that the maps
/// are the whole difference.
pub fn raster_bound(scene: &Scene, kv: &[(&str, &str)]) -> (f64, f32, f64) {
    let one_tap = kv
        .iter()
        .any(|&(k, v)| k == "filter" && (v == "none" || v == "first"));
    if scene.is_opaque() {
        (0.001, 1e-3, 1e-4)
    } else if one_tap {
        (0.015, 1.0, 0.04)
    } else {
        (0.15, 0.1, 3e-3)
    }
}

/// The estimators on a fixture, `what`: V of the GPU estimator against the CPU twin's over the
/// active receivers of `rec`, finite, within `(beyond, max, rmse)` ([`raster_bound`]).
pub fn assert_fixture_within(
    what: &str,
    vc: &[f32],
    vg: &[f32],
    rec: &Receivers,
    (beyond, max, rmse): (f64, f32, f64),
) {
    let n = rec.active_count();
    let (mut far, mut worst) = (0usize, 0.0f32);
    for k in 0..rec.len() {
        if rec.active()[k] {
            let d = (vc[k] - vg[k]).abs();
            assert!(
                d.is_finite(),
                "{what}: receiver {k}: {} vs {}",
                vc[k],
                vg[k]
            );
            far += usize::from(d > 1e-4);
            worst = worst.max(d);
        }
    }
    let e = test_support::fixtures::rmse(vc, vg, rec.active());
    println!(
        "{what}: {far} of {n} beyond 1e-4 of the CPU twin, max |dV| {worst:.2e}, rmse {e:.2e}"
    );
    assert!(
        far as f64 <= beyond * n as f64 && worst <= max && e <= rmse,
        "{what}: {far} of {n} beyond 1e-4, max |dV| {worst}, rmse {e}"
    );
}

/// The GPU estimator's V `vg` on a fixture, `what`, taken apart when the settings `params` it
/// ran with render one view: `frame`, prepared with `params`, in the views it fits, gives `vg`
/// bit for bit (but for receivers it left to the redo), and the CPU twin's lookup on the frame's
/// own map (read back) gives it within the twins' tolerance ([`Tolerance::TWIN`], each receiver
/// beyond a tie [`explain`] shows). Returns the comparison's counts, `None` for several views.
pub fn frame_on_its_map(
    what: &str,
    ctx: &Arc<GpuContext>,
    (frame, params): (&DeepShadowFrame, &Params),
    scene: &Scene,
    rec: &Receivers,
    vg: &[f32],
) -> Option<CaseStats> {
    let s = Settings::from_params(params).unwrap();
    let [Some(view)] = frame.fit_views(scene, rec).unwrap()[..] else {
        return None;
    };
    let (_, out) = run_frame(ctx, frame, scene, rec).unwrap();
    let st = out.status.expect("deep-shadow's frame has a status");
    let mut vf = out.v;
    assert_eq!((st.outside, st.nonfinite), (0, 0), "{what}: {st:?}");
    let map = frame.read_map().unwrap();
    let vc = cpu_on_map(&map, scene, rec, &view, &s);
    let mut cut = 0;
    for k in 0..rec.len() {
        if rec.active()[k] && vf[k].is_nan() {
            // Left to the redo (the loop budget): the CPU twin's, out of the comparison.
            cut += 1;
            vf[k] = vc[k];
        } else {
            assert_eq!(vf[k].to_bits(), vg[k].to_bits(), "{what}: receiver {k}");
        }
    }
    assert_eq!(cut, st.left_nan as usize, "{what}: {st:?}");
    let tol = Tolerance::TWIN;
    let cmp = tol.compare(what, rec.active(), &vc, &vf).unwrap();
    let judged = tol.judge(what, &cmp, rec, &vc, &vf, |beyond| {
        Ok(beyond
            .iter()
            .map(|&k| explain(&tol, &map, scene, rec, &view, &s, k, (vc[k], vf[k])))
            .collect())
    });
    let st = judged.unwrap_or_else(|e| panic!("{e}"));
    let lists = match &map {
        FrameMap::Lists(d) => format!("{} fragments", d.stats().fragments),
        FrameMap::Depths(_) => "depths".into(),
    };
    println!(
        "{what}: frame vs the CPU twin on the frame's map ({lists}): max |dV| {:.2e}, {} of {} \
         beyond 1e-4 ({} ties), {cut} left to the redo",
        st.max_dv, st.beyond, st.receivers, st.ties
    );
    Some(st)
}
