//! A method's engine path as its GPU [`SoftShadowEstimator`]: [`FrameTwin`] runs any
//! [`FrameEstimator`] on the receivers it is given (uploaded once per estimate), in the views
//! the frame fits for them at `build`, and reads V back once, so the path a renderer embeds is
//! the path `render --backend gpu`, the report and the conformance suite measure. Cascades,
//! direction tiles and settled receivers come from the registry's [`crate::cascades::Cascaded`]
//! around it, which builds and estimates once per view set on the receivers that set serves.
use super::{
    frame::{finish_on_cpu, FrameEstimator, FrameInputs},
    raster::GpuScene,
    receivers::GpuReceivers,
    GpuContext,
};
use crate::{
    method::FrameConstructor, Backend, Cancel, LightView, Params, Receivers, Report, Result, Scene,
    SoftShadowEstimator,
};
use std::{sync::Arc, time::Instant};

/// The engine path of one method as a GPU estimator (see the module's documentation). Its name,
/// description and parameter table are its CPU twin's; receivers the frame leaves NaN (cut by the
/// device's loop budget) are redone by the frame's CPU twin in the same views and counted
/// (`frame_cpu_redo`). The frame is prepared (pipelines compiled, maps allocated) at the first
/// `build` and again only when the parameters change or more receivers come: the `prepare`
/// stage of the report, which `softshadow report` does not count as frame time (a twin that
/// compiles at construction is timed the same way).
pub struct FrameTwin {
    ctx: Arc<GpuContext>,
    cpu: Box<dyn SoftShadowEstimator>,
    make: FrameConstructor,
    /// The prepared frame, the parameters and receiver capacity it was prepared for.
    frame: Option<(Box<dyn FrameEstimator>, Params, u32)>,
    /// The scene's casters on the device, keyed by a hash of the triangles.
    casters: Option<(u64, GpuScene)>,
    views: Option<Vec<Option<LightView>>>,
    report: Report,
    cancel: Cancel,
}

impl FrameTwin {
    /// The engine path `make` of the method whose CPU twin is `cpu`, on `ctx`.
    pub fn new(
        ctx: Arc<GpuContext>,
        cpu: Box<dyn SoftShadowEstimator>,
        make: FrameConstructor,
    ) -> FrameTwin {
        FrameTwin {
            ctx,
            cpu,
            make,
            frame: None,
            casters: None,
            views: None,
            report: Report::default(),
            cancel: Cancel::default(),
        }
    }

    /// Prepares the frame again when the parameters changed or `n` receivers exceed what it was
    /// prepared for, and uploads the casters when the scene's triangles changed.
    fn prepare(&mut self, scene: &Scene, n: u32) -> Result<()> {
        let params = self.cpu.params();
        let fresh = matches!(&self.frame, Some((_, p, cap)) if p == params && *cap >= n);
        if !fresh {
            let t = Instant::now();
            let cap = n.max(1).next_power_of_two();
            let f = (self.make)(self.ctx.clone(), params, cap)?;
            self.frame = Some((f, params.clone(), cap));
            // One-time work (pipelines, maps): a stage of its own, not the frame's.
            self.report.stages.push(("prepare".into(), ms(t)));
        }
        use std::hash::{Hash, Hasher};
        let mut h = std::collections::hash_map::DefaultHasher::new();
        bytemuck::cast_slice::<[glam::Vec3; 3], u32>(scene.triangles()).hash(&mut h);
        let key = h.finish();
        if self.casters.as_ref().is_none_or(|(k, _)| *k != key) {
            self.casters = Some((key, GpuScene::upload(&self.ctx, scene)?));
        }
        Ok(())
    }

    /// The prepared frame and casters ([`prepare`](Self::prepare) first).
    fn parts(&self) -> Result<(&dyn FrameEstimator, &GpuScene)> {
        match (&self.frame, &self.casters) {
            (Some((f, _, _)), Some((_, c))) => Ok((f.as_ref(), c)),
            _ => Err(crate::Error::Gpu {
                stage: "frame twin".into(),
                reason: "estimate before build".into(),
            }),
        }
    }
}

impl SoftShadowEstimator for FrameTwin {
    fn name(&self) -> &'static str {
        self.cpu.name()
    }
    fn description(&self) -> &'static str {
        self.cpu.description()
    }
    fn backend(&self) -> Backend {
        Backend::Gpu
    }
    fn params(&self) -> &Params {
        self.cpu.params()
    }
    fn set_param(&mut self, key: &str, value: &str) -> Result<()> {
        self.cpu.set_param(key, value)
    }
    fn set_cancel(&mut self, cancel: Cancel) {
        self.cpu.set_cancel(cancel.clone());
        self.cancel = cancel;
    }

    /// Fits the frame's views to `receivers` (as its CPU twin's `build` fits them) and uploads
    /// the casters when they changed. A scene the frame does not take is an error naming why.
    fn build(&mut self, scene: &Scene, receivers: &Receivers) -> Result<()> {
        self.ctx.check_lost()?;
        self.report = Report::default();
        self.views = None;
        let n = u32::try_from(receivers.len()).unwrap_or(u32::MAX);
        let t = Instant::now();
        self.prepare(scene, n)?;
        let prepare_ms = self.report.total_ms("prepare");
        self.report
            .stages
            .push(("upload".into(), ms(t) - prepare_ms));
        let t = Instant::now();
        let (frame, _) = self.parts()?;
        if let Some(why) = frame.refuses(scene) {
            return Err(crate::Error::param("scene", why));
        }
        let views = frame.fit_views(scene, receivers)?;
        self.report.stages.push(("fit".into(), ms(t)));
        self.views = Some(views);
        Ok(())
    }

    /// Uploads the receivers, records the frame into one command encoder, submits it and reads
    /// V and the frame's status back.
    fn estimate(&mut self, scene: &Scene, receivers: &Receivers, v: &mut [f32]) -> Result<()> {
        receivers.check_output(v)?;
        self.cancel.check()?;
        let views = crate::estimator::built(self.views.clone())?;
        let n = receivers.len();
        let count = u32::try_from(n).map_err(|_| crate::Error::Limit {
            what: "receivers per frame",
            requested: n as u64,
            max: u32::MAX as u64,
        })?;
        let mut report = std::mem::take(&mut self.report);
        let t = Instant::now();
        let gpu_receivers = GpuReceivers::upload(&self.ctx, receivers)?;
        let v_buf = self.ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("frame twin V"),
            size: 4 * n.max(1) as u64,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        self.prepare(scene, count)?;
        let ctx = self.ctx.clone();
        let (frame, casters) = self.parts()?;
        let mut enc = ctx.device.create_command_encoder(&Default::default());
        frame.encode(
            &mut enc,
            &FrameInputs {
                casters,
                views: &views,
                light: scene.light(),
                receivers: &gpu_receivers.buffer,
                count,
                v: &v_buf,
                timestamps: None,
            },
        )?;
        ctx.queue.submit([enc.finish()]);
        let out: Vec<f32> = ctx.read_buffer(&v_buf, 4 * n as u64)?;
        report.stages.push(("estimate".into(), ms(t)));
        v.copy_from_slice(&out[..n]);
        // What the frame models less than the scene asks (a frame that casts every caster
        // opaque, on a semi-transparent scene).
        report.warn_all(frame.scene_warnings(scene));
        finish_on_cpu(frame, &ctx, scene, receivers, &views, v, &mut report)?;
        report.light_space_bytes = frame.light_space_bytes();
        report.note("engine_path", "frame twin");
        report.note("views", views.iter().flatten().count());
        self.report = report;
        Ok(())
    }

    fn report(&self) -> Report {
        self.report.clone()
    }
}

fn ms(t: Instant) -> f64 {
    t.elapsed().as_secs_f64() * 1e3
}
