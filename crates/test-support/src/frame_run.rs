//! One frame of a [`FrameEstimator`] in a test, as a renderer records it: the casters, the
//! receivers and a V buffer uploaded, the views the frame fits, one encoder, one submit, V and
//! the status read back. Every crate's frame tests and the conformance suite run frames this way.
use shadow_map_core::{
    gpu::{
        frame::{FrameEstimator, FrameInputs, FrameStatus},
        receivers::GpuReceivers,
        GpuContext, GpuScene,
    },
    Light, LightView, Receivers, Result, Scene,
};

/// A frame's inputs on the device: what [`FrameInputs`] borrows.
pub struct FrameRig {
    /// The views the frame fitted ([`FrameEstimator::fit_views`]).
    pub views: Vec<Option<LightView>>,
    /// The scene's casters.
    pub casters: GpuScene,
    /// The receivers.
    pub receivers: GpuReceivers,
    /// The caller's V buffer (4 bytes a receiver, at least 4).
    pub v: wgpu::Buffer,
    light: Light,
}

/// What one frame left: V (NaN for inactive receivers and the ones the frame leaves to its
/// caller) and its decoded status (`None` for a frame without one).
#[derive(Debug, Clone)]
pub struct FrameOutput {
    /// V per receiver, as the frame wrote it.
    pub v: Vec<f32>,
    /// The frame's counts.
    pub status: Option<FrameStatus>,
}

impl FrameRig {
    /// `frame`'s views fitted to `rec`, and `scene`'s casters, `rec` and a V buffer uploaded.
    /// Errors: the frame's (a view it cannot fit) and the device's (limits, allocation).
    pub fn new(
        ctx: &GpuContext,
        frame: &dyn FrameEstimator,
        scene: &Scene,
        rec: &Receivers,
    ) -> Result<Self> {
        let views = frame.fit_views(scene, rec)?;
        let casters = GpuScene::upload(ctx, scene)?;
        let receivers = GpuReceivers::upload(ctx, rec)?;
        let v = ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("test V"),
            size: 4 * (rec.len() as u64).max(1),
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        Ok(Self {
            views,
            casters,
            receivers,
            v,
            light: *scene.light(),
        })
    }

    /// The inputs of one frame over this rig, in its fitted views.
    pub fn inputs(&self) -> FrameInputs<'_> {
        FrameInputs {
            casters: &self.casters,
            views: &self.views,
            light: &self.light,
            receivers: &self.receivers.buffer,
            count: self.receivers.count,
            v: &self.v,
            timestamps: None,
        }
    }

    /// One frame of `frame` recorded into an encoder of its own and submitted, then V and the
    /// status read back.
    pub fn run(&self, ctx: &GpuContext, frame: &dyn FrameEstimator) -> Result<FrameOutput> {
        self.submit(ctx, frame)?;
        self.read(ctx, frame)
    }

    /// One frame of `frame` recorded into an encoder of its own and submitted; nothing waited
    /// for or read back (a bench's timed frame, or one of several frames in a row).
    pub fn submit(&self, ctx: &GpuContext, frame: &dyn FrameEstimator) -> Result<()> {
        let mut enc = ctx.device.create_command_encoder(&Default::default());
        frame.encode(&mut enc, &self.inputs())?;
        ctx.queue.submit([enc.finish()]);
        Ok(())
    }

    /// V and `frame`'s status as the last submitted frame left them.
    pub fn read(&self, ctx: &GpuContext, frame: &dyn FrameEstimator) -> Result<FrameOutput> {
        let n = self.receivers.count as u64;
        let v = if n == 0 {
            Vec::new()
        } else {
            ctx.read_buffer(&self.v, 4 * n)?
        };
        Ok(FrameOutput {
            v,
            status: frame.read_status(ctx)?,
        })
    }
}

/// One frame of `frame` over `scene` and `rec` ([`FrameRig::new`], then [`FrameRig::run`]); the
/// rig is returned for what the test reads next (the views, the maps, a second frame).
pub fn run_frame(
    ctx: &GpuContext,
    frame: &dyn FrameEstimator,
    scene: &Scene,
    rec: &Receivers,
) -> Result<(FrameRig, FrameOutput)> {
    let rig = FrameRig::new(ctx, frame, scene, rec)?;
    let out = rig.run(ctx, frame)?;
    Ok((rig, out))
}
