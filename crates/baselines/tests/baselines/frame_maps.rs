//! The frames on a scene with the maps they rendered read back, and the CPU twins on those very
//! maps: what isolates the per-receiver kernels from the raster in the twin checks
//! (`gpu_twins.rs`) and the frame checks (`frame.rs`).
#![cfg(feature = "gpu")]

use baselines::{
    cpu::{Filter, MapEstimator},
    gpu::{GpuFilter, MapFrame, MultiSampleFrame},
    MultiSample,
};
use shadow_map_core::{
    gpu::GpuContext, light_space::LightSpace, Error, LightView, Receivers, Result, Scene,
    SoftShadowEstimator,
};
use test_support::frame_run::run_frame;

/// One frame on a scene: V, the views it was recorded in, and per view the map the frame
/// rendered in it, read back (`None` where the view is absent).
pub struct FrameRun {
    /// V, read back after the frame.
    pub v: Vec<f32>,
    /// The views ([`FrameEstimator::fit_views`](baselines::gpu::FrameEstimator::fit_views)).
    pub views: Vec<Option<LightView>>,
    /// The frame's maps, one per view.
    pub maps: Vec<Option<LightSpace>>,
}

/// Hard, PCF or PCSS: one frame in the views the frame fits, and its one map read back
/// ([`MapFrame::light_space`]).
pub fn run_map_frame<F: GpuFilter>(
    ctx: &GpuContext,
    frame: &MapFrame<F>,
    scene: &Scene,
    rec: &Receivers,
) -> Result<FrameRun> {
    let (rig, out) = run_frame(ctx, frame, scene, rec)?;
    let maps = rig
        .views
        .iter()
        .map(|view| {
            view.map(|view| frame.light_space(&view)?.to_cpu(ctx))
                .transpose()
        })
        .collect::<Result<_>>()?;
    Ok(FrameRun {
        v: out.v,
        views: rig.views,
        maps,
    })
}

/// Multi-sample: one frame in the views the frame fits, then, per sub-light, one more frame with
/// only that sub-light's view present, whose map is read back
/// ([`MultiSampleFrame::light_space`]): the frame renders its sub-lights in turn into one layer,
/// so a sub-light's map is only whole after a frame that renders it last.
pub fn run_multi_sample_frame(
    ctx: &GpuContext,
    frame: &MultiSampleFrame,
    scene: &Scene,
    rec: &Receivers,
) -> Result<FrameRun> {
    let (mut rig, out) = run_frame(ctx, frame, scene, rec)?;
    let views = std::mem::take(&mut rig.views);
    let mut maps = Vec::with_capacity(views.len());
    for (k, view) in views.iter().enumerate() {
        if view.is_none() {
            maps.push(None);
            continue;
        }
        rig.views = (0..views.len())
            .map(|i| if i == k { *view } else { None })
            .collect();
        rig.run(ctx, frame)?;
        let ls = frame
            .light_space(&rig.views)?
            .ok_or_else(|| Error::LightView(format!("no map for sub-light {k}")))?;
        maps.push(Some(ls.to_cpu(ctx)?));
    }
    Ok(FrameRun {
        v: out.v,
        views,
        maps,
    })
}

/// The CPU filter `F` with `params` on `maps` (the one map of a map frame, as rendered):
/// [`MapEstimator::set_light_space`], then `estimate`.
pub fn cpu_on_map<F: Filter>(
    params: &[(&str, String)],
    scene: &Scene,
    rec: &Receivers,
    maps: &[Option<LightSpace>],
) -> Result<Vec<f32>> {
    let [Some(ls)] = maps else {
        return Err(Error::LightView(format!(
            "{} maps for a single-map estimator",
            maps.len()
        )));
    };
    let mut e = MapEstimator::<F>::new()?;
    test_support::fixtures::set_params(&mut e, params)?;
    e.set_light_space(ls.clone())?;
    let mut v = vec![0.0; rec.len()];
    e.estimate(scene, rec, &mut v)?;
    Ok(v)
}

/// The CPU multi-sample estimator with `params` on `maps` (one per sub-light, as rendered):
/// [`MultiSample::estimate_in_light_spaces`].
pub fn cpu_on_sub_light_maps(
    params: &[(&str, String)],
    scene: &Scene,
    rec: &Receivers,
    maps: &[Option<LightSpace>],
) -> Result<Vec<f32>> {
    let mut e = MultiSample::new()?;
    test_support::fixtures::set_params(&mut e, params)?;
    let mut v = vec![0.0; rec.len()];
    e.estimate_in_light_spaces(scene, rec, maps.to_vec(), &mut v)?;
    Ok(v)
}
