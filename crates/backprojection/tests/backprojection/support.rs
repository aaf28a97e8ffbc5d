//! What the frame tests share: one frame of [`BackprojectionFrame`] as a renderer records it
//! (test-support's `frame_run`) with the maps it rendered read back, and the CPU twin evaluated
//! on those very maps, which isolates the kernel from the rasteriser.
#![cfg(feature = "gpu")]

use backprojection::{BackprojectionFrame, CpuBackprojection};
use shadow_map_core::{
    gpu::{
        frame::{FrameStatus, Views},
        GpuContext,
    },
    light_space::LightSpace,
    LightView, Receivers, Scene, SoftShadowEstimator,
};
use std::sync::Arc;
use test_support::{
    conformance::{table, Params},
    fixtures::configure,
    frame_run::run_frame,
};

/// One frame: V read back, the decoded status, the views and the maps the frame rendered (read
/// back, opacity planes included for semi-transparent casters).
pub struct FrameRun {
    pub v: Vec<f32>,
    pub status: FrameStatus,
    pub views: Vec<Option<LightView>>,
    pub maps: LightSpace,
}

impl FrameRun {
    /// Active receivers the frame left NaN (cut short by the loop budget).
    pub fn cut(&self, rec: &Receivers) -> Vec<usize> {
        (0..rec.len())
            .filter(|&k| rec.active()[k] && self.v[k].is_nan())
            .collect()
    }
}

/// A frame prepared for `params` (a table of backprojection's specs).
pub fn prepare(ctx: &Arc<GpuContext>, params: &Params) -> Result<BackprojectionFrame, String> {
    BackprojectionFrame::prepare(ctx.clone(), &table(backprojection::settings::SPECS, params))
        .map_err(|e| format!("prepare: {e}"))
}

/// The maps `frame` rendered in its last submitted frame, in the single view of `views`, read
/// back.
pub fn frame_maps(
    ctx: &GpuContext,
    frame: &BackprojectionFrame,
    views: &Views,
) -> Result<LightSpace, String> {
    let view = views.first().copied().flatten().ok_or("frame: no view")?;
    frame
        .maps()
        .layers
        .light_space(&view)
        .to_cpu(ctx)
        .map_err(|e| format!("maps: {e}"))
}

/// `frame` on `scene` and `rec` in the views it fits for them (one encoder, one submit), then V,
/// the status and the maps read back.
pub fn frame_once(
    ctx: &GpuContext,
    frame: &BackprojectionFrame,
    scene: &Scene,
    rec: &Receivers,
) -> Result<FrameRun, String> {
    let (rig, out) = run_frame(ctx, frame, scene, rec).map_err(|e| format!("frame: {e}"))?;
    let maps = frame_maps(ctx, frame, &rig.views)?;
    Ok(FrameRun {
        v: out.v,
        status: out.status.unwrap_or_default(),
        views: rig.views,
        maps,
    })
}

/// [`frame_once`] with a frame prepared for `params`.
pub fn prepare_and_run(
    ctx: &Arc<GpuContext>,
    scene: &Scene,
    rec: &Receivers,
    params: &Params,
) -> Result<FrameRun, String> {
    frame_once(ctx, &prepare(ctx, params)?, scene, rec)
}

/// The CPU twin's V with `params` on the light-space data `maps` (a frame's, read back).
pub fn cpu_on_maps(maps: &LightSpace, scene: &Scene, rec: &Receivers, params: &Params) -> Vec<f32> {
    let mut e = CpuBackprojection::new().expect("cpu twin");
    configure(&mut e, params);
    e.set_light_space(maps.clone());
    let mut v = vec![0.5f32; rec.len()];
    e.estimate(scene, rec, &mut v).expect("cpu estimate");
    v
}
