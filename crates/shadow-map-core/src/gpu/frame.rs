//! What every estimator's engine path shares: the trait each estimator's frame type
//! implements ([`FrameEstimator`]), the inputs of one frame, all the caller's
//! ([`FrameInputs`]), the checks made before anything is recorded ([`check_buffers`]), and the
//! status buffer that replaces a readback ([`status_buffer`]).
//!
//! ```text
//! let frame = SomeFrame::prepare(ctx, &params)?;              // once: pipelines, maps, uniforms
//! let views = frame.fit_views(&scene, &bounds_receivers)?;    // when the light or scene moves
//! loop {
//!     let mut enc = device.create_command_encoder(&Default::default());
//!     frame.encode(&mut enc, &FrameInputs { casters, views: &views, light, receivers, count, v })?;
//!     queue.submit([enc.finish()]);                           // the caller's submit
//! }
//! ```
use super::{estimate::WORKGROUP_SIZE, receivers::RECEIVER_BYTES, GpuContext, GpuScene};
use crate::{light_view::LightView, Error, Light, Receivers, Report, Result, Scene, Warning};
use std::num::NonZeroU64;

/// An estimator's engine path: prepared once, then [`encode`](Self::encode) records each frame
/// into the caller's command encoder (render and compute passes only: no submit, no wait, no
/// readback), reading the caller's casters and receiver buffer and writing V into the caller's
/// buffer. `Send + Sync`, so an engine can keep one in its render world (a Bevy resource).
pub trait FrameEstimator: Send + Sync {
    /// The estimator's name (its `SoftShadowEstimator::name`).
    fn name(&self) -> &'static str;

    /// The light views the estimator's own `build` fits for `receivers`, one per view slot
    /// (one for most methods, one per sub-light for multi-sample; `None`: a slot no receiver is
    /// in front of). CPU work over the scene's triangles, for when the light or the scene moves,
    /// not per frame. [`Error::DeviceLost`] once the estimator's device is lost (the views are
    /// of no use to it any more).
    fn fit_views(&self, scene: &Scene, receivers: &Receivers) -> Result<Vec<Option<LightView>>>;

    /// Records one frame into `enc`. Its uniforms are written in the encoder's order
    /// ([`GpuContext::write_in`]), so one estimator may record several frames (lights, views,
    /// receiver sets) into one encoder or into several encoders of one submit, each reading its
    /// own; the status buffer holds the last one's. Errors, before anything is recorded: views of another resolution
    /// or number ([`Error::LightView`]); buffers smaller than the count needs ([`Error::Limit`],
    /// [`check_buffers`]); a lost device ([`Error::DeviceLost`]: checked
    /// first, never blocking; see below).
    ///
    /// **Device loss.** Once the device is lost (as [`GpuContext::check_lost`] sees it: a real
    /// loss at once, an explicit `destroy` at the device's next poll) every call gives
    /// [`Error::DeviceLost`], never a panic; a frame recorded before wgpu reports a `destroy`
    /// is recorded into objects wgpu has invalidated, which is harmless. The estimator is not
    /// revived: the caller makes a new context on its new device and prepares the estimator
    /// again (`softshadow::frame_estimator` with the same parameters), which then gives what
    /// an estimator on a device that never saw a loss gives.
    fn encode(&self, enc: &mut wgpu::CommandEncoder, inputs: &FrameInputs<'_>) -> Result<()>;

    /// Device bytes of the light-space data the frame allocated (maps, peeled layers,
    /// midpoints, opacity planes, MSSMs, lists; not per-receiver buffers, uniforms or a
    /// kernel's copies of the maps), counted as the CPU twin counts its own: the report's
    /// `light_space_bytes` for the GPU backend.
    fn light_space_bytes(&self) -> usize;

    /// The counters of the last submitted frame (u32s, each estimator's own: receivers outside
    /// the frustum, non-finite results replaced, ...), for the caller to copy out when it likes;
    /// `None` when the estimator keeps none. [`decode_status`](Self::decode_status) names them.
    fn status(&self) -> Option<&wgpu::Buffer>;

    /// The words of [`status`](Self::status) as named counts. The default reads the layout most
    /// estimators write: `[outside, nonfinite, cut, unsettled]`, where `unsettled` counts the
    /// outside receivers the settle passes ([`super::settle`]) left NaN (missing words count 0).
    fn decode_status(&self, words: &[u32]) -> FrameStatus {
        let w = |k: usize| words.get(k).copied().unwrap_or(0);
        FrameStatus {
            outside: w(0).saturating_sub(w(3)),
            nonfinite: w(1),
            left_nan: w(2) + w(3),
        }
    }

    /// Reads the status buffer back (a blocking readback, for tools and tests, not per frame)
    /// and decodes it; `None` when the estimator keeps none.
    fn read_status(&self, ctx: &GpuContext) -> Result<Option<FrameStatus>> {
        let Some(b) = self.status() else {
            return Ok(None);
        };
        let words: Vec<u32> = ctx.read_buffer(b, b.size())?;
        Ok(Some(self.decode_status(&words)))
    }

    /// Render passes over the casters one frame records in `views` (peeled layers, sub-lights):
    /// what a frame's raster work is, in units of the casters' triangles. The default: one per
    /// view present.
    fn caster_passes(&self, views: &Views) -> u32 {
        views.iter().flatten().count() as u32
    }

    /// Why this engine path does not take `scene` (a light or a setting it does not model), for
    /// the caller to use the estimator's twin instead; `None` (the default) when it does.
    /// [`encode`](Self::encode) fails with the same reason.
    fn refuses(&self, _scene: &Scene) -> Option<String> {
        None
    }

    /// Whether the frame models semi-transparent casters (each caster's opacity, the caster
    /// buffer's w): `false` (the default) when it casts every caster opaque.
    fn models_opacity(&self) -> bool {
        false
    }

    /// The warnings a frame of `scene` owes its caller before it runs (what it models less
    /// than the scene asks): by default [`Warning::OpaqueCasters`] for a semi-transparent scene
    /// when the frame casts every caster opaque ([`models_opacity`](Self::models_opacity)).
    fn scene_warnings(&self, scene: &Scene) -> Vec<Warning> {
        if self.models_opacity() {
            return Vec::new();
        }
        Warning::opaque_casters(scene).into_iter().collect()
    }

    /// The CPU twin's V for `receivers` in the same `views` (what the conformance check and
    /// `examples/frame_loop.rs` compare a frame with).
    fn cpu_twin(&self, scene: &Scene, receivers: &Receivers, views: &Views) -> Result<Vec<f32>>;
}

/// What the last submitted frame counted ([`FrameEstimator::decode_status`]).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct FrameStatus {
    /// Receivers outside the light view, given their facing fraction (summed over views).
    pub outside: u32,
    /// Receivers whose V came out non-finite, written as 0.
    pub nonfinite: u32,
    /// Active receivers left NaN for the caller to redo (cut by the device's loop budget, or
    /// outside the one view accumulation uses with something that may shadow them): a
    /// composite that does not redo them draws them fully lit.
    pub left_nan: u32,
}

impl FrameStatus {
    /// The counts as [`Warning`]s (none for zero counts).
    pub fn warnings(&self) -> Vec<Warning> {
        [
            Warning::OutsideViews {
                receivers: self.outside as usize,
            },
            Warning::NonFiniteV {
                receivers: self.nonfinite as usize,
            },
            Warning::FrameLeftNan {
                receivers: self.left_nan as usize,
            },
        ]
        .into_iter()
        .filter(|w| w.count() > 0)
        .collect()
    }
}

/// The refusal of an engine path whose frame casts every caster opaque while its estimator
/// models opacity on its twin path ([`FrameEstimator::refuses`]): semi-transparent meshes would
/// cast opaque shadows there; `None` for an opaque scene.
pub fn refuse_semi_transparent(scene: &Scene) -> Option<String> {
    let n = scene.semi_transparent_meshes();
    (n > 0).then(|| {
        format!(
            "{n} semi-transparent meshes: the engine path's casters are opaque; the estimator's twin path models opacity"
        )
    })
}

/// What a caller that reads a frame's V back does with it, as `softshadow render` and
/// [`FrameTwin`](super::frame_twin::FrameTwin) do: V of the inactive receivers set to NaN; the
/// frame's status (a readback) noted as `frame_status` and its warnings added to `report`, but
/// for [`Warning::FrameLeftNan`]: the active receivers left non-finite (a loop-budget cut, a
/// rasterised miss) are redone here by the frame's CPU twin in the same `views` (the stage
/// `frame: CPU redo`, the note `frame_cpu_redo`), so none is lost.
pub fn finish_on_cpu(
    frame: &dyn FrameEstimator,
    ctx: &GpuContext,
    scene: &Scene,
    receivers: &Receivers,
    views: &Views,
    v: &mut [f32],
    report: &mut Report,
) -> Result<()> {
    for (x, &a) in v.iter_mut().zip(receivers.active()) {
        if !a {
            *x = f32::NAN;
        }
    }
    if let Some(status) = frame.read_status(ctx)? {
        report.note("frame_status", format!("{status:?}"));
        report.warn_all(
            status
                .warnings()
                .into_iter()
                .filter(|w| !matches!(w, Warning::FrameLeftNan { .. })),
        );
    }
    let redo: Vec<usize> = (0..v.len().min(receivers.len()))
        .filter(|&k| receivers.active()[k] && !v[k].is_finite())
        .collect();
    if !redo.is_empty() {
        let t = std::time::Instant::now();
        let sub = Receivers::from_points(
            redo.iter().map(|&k| receivers.position()[k]).collect(),
            redo.iter().map(|&k| receivers.normal()[k]).collect(),
        )?;
        let vs = frame.cpu_twin(scene, &sub, views)?;
        for (&k, x) in redo.iter().zip(vs) {
            v[k] = x;
        }
        report
            .stages
            .push(("frame: CPU redo".into(), t.elapsed().as_secs_f64() * 1e3));
        report.note("frame_cpu_redo", redo.len());
    }
    Ok(())
}

/// The one view of a single-view method's frame: `views` must hold exactly one, present
/// ([`Error::LightView`] otherwise).
pub fn single_view(views: &Views) -> Result<&LightView> {
    match views {
        [Some(v)] => Ok(v),
        _ => Err(Error::LightView(format!(
            "this estimator renders one light view per frame, {} given ({} present)",
            views.len(),
            views.iter().flatten().count()
        ))),
    }
}

/// A frame's light views, one per slot (cascades, direction tiles, sub-lights); `None` for a
/// slot no receiver needs this frame ([`FrameEstimator::fit_views`]).
pub type Views = [Option<LightView>];

/// What one frame reads and writes, all the caller's.
#[derive(Debug, Clone, Copy)]
pub struct FrameInputs<'a> {
    /// The casters' triangles (a [`GpuScene`]: three `vec4` per triangle, the position and the
    /// caster's opacity).
    pub casters: &'a GpuScene,
    /// The frame's light views ([`FrameEstimator::fit_views`]), at the resolution the frame
    /// was prepared with.
    pub views: &'a Views,
    /// The light.
    pub light: &'a Light,
    /// The receivers: an array of the core's `ReceiverGpu` (32 bytes each), `STORAGE` usage.
    pub receivers: &'a wgpu::Buffer,
    /// How many receivers the buffer holds (from its start).
    pub count: u32,
    /// V per receiver as f32 bits (NaN for inactive receivers), `STORAGE` usage, at least
    /// `4 count` bytes.
    pub v: &'a wgpu::Buffer,
    /// Optional GPU timestamps per stage ([`FrameTimestamps`]); `None`: none written.
    pub timestamps: Option<&'a FrameTimestamps>,
}

impl FrameInputs<'_> {
    /// Writes a timestamp closing the stage `stage` (the stage ends here; the frame's first
    /// mark, `"start"`, opens it) when the caller passed [`FrameTimestamps`]; nothing otherwise.
    /// Called by every estimator's `encode` between its passes.
    pub fn mark(&self, enc: &mut wgpu::CommandEncoder, stage: &'static str) {
        if let Some(t) = self.timestamps {
            t.mark(enc, stage);
        }
    }
}

/// GPU time per stage of a frame, from a timestamp query set the caller owns: each
/// estimator's `encode` writes a timestamp when it starts and after each of its stages
/// ([`FrameInputs::mark`], `CommandEncoder::write_timestamp` between passes), the caller
/// resolves them into the same encoder after the frame ([`resolve`](Self::resolve)) and, when it
/// likes, after the submit, reads them as milliseconds per stage ([`read`](Self::read): a
/// readback, so once at the end of a run, not per frame). Needs
/// `Features::TIMESTAMP_QUERY | TIMESTAMP_QUERY_INSIDE_ENCODERS`, which [`GpuContext::new`]
/// requests where the adapter has them: [`new`](Self::new) is `None` elsewhere.
///
/// ```text
/// let ts = FrameTimestamps::new(&ctx, 64)?;          // Option: None without the features
/// ts.as_ref().map(|t| t.reset());
/// frame.encode(&mut enc, &FrameInputs { timestamps: ts.as_ref(), .. })?;
/// ts.as_ref().map(|t| t.resolve(&mut enc));
/// queue.submit([enc.finish()]);
/// let stages = ts.unwrap().read(&ctx)?;               // [("raster", 0.4), ("estimate", 1.2)]
/// ```
#[derive(Debug)]
pub struct FrameTimestamps {
    set: wgpu::QuerySet,
    resolved: wgpu::Buffer,
    capacity: u32,
    /// The stage each mark closes, in order (mark 0 opens the frame), and marks dropped for
    /// want of room.
    marks: std::sync::Mutex<(Vec<&'static str>, u32)>,
    period_ns: f32,
}

impl FrameTimestamps {
    /// The features timestamps between passes need.
    pub const FEATURES: wgpu::Features =
        wgpu::Features::TIMESTAMP_QUERY.union(wgpu::Features::TIMESTAMP_QUERY_INSIDE_ENCODERS);

    /// Room for every mark of the largest frame any estimator here records: packet-hsm's 16 x 16
    /// views (sub-lights x opacity levels) at five marks a view, and the start (1,281), rounded
    /// up to a power of two.
    pub const FRAME_CAPACITY: u32 = 2048;

    /// A query set of `capacity` timestamps (2 to `wgpu::QUERY_SET_MAX_QUERIES`, else
    /// [`Error::Limit`]); `None` when the device lacks [`Self::FEATURES`].
    pub fn new(ctx: &GpuContext, capacity: u32) -> Result<Option<Self>> {
        ctx.check_lost()?;
        if !ctx.device.features().contains(Self::FEATURES) {
            return Ok(None);
        }
        if !(2..=wgpu::QUERY_SET_MAX_QUERIES).contains(&capacity) {
            return Err(Error::Limit {
                what: "timestamps per frame (wgpu::QUERY_SET_MAX_QUERIES)",
                requested: capacity as u64,
                max: wgpu::QUERY_SET_MAX_QUERIES as u64,
            });
        }
        let set = ctx.device.create_query_set(&wgpu::QuerySetDescriptor {
            label: Some("frame timestamps"),
            ty: wgpu::QueryType::Timestamp,
            count: capacity,
        });
        let resolved = ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("frame timestamps resolved"),
            size: 8 * capacity as u64,
            usage: wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        Ok(Some(FrameTimestamps {
            set,
            resolved,
            capacity,
            marks: std::sync::Mutex::new((Vec::new(), 0)),
            period_ns: ctx.queue.get_timestamp_period(),
        }))
    }

    /// Forgets the marks of the last frame (call before each frame's `encode`).
    pub fn reset(&self) {
        if let Ok(mut m) = self.marks.lock() {
            m.0.clear();
            m.1 = 0;
        }
    }

    /// Writes the next timestamp, closing `stage` (see [`FrameInputs::mark`]); past the
    /// capacity the mark is dropped and counted ([`dropped`](Self::dropped)).
    pub fn mark(&self, enc: &mut wgpu::CommandEncoder, stage: &'static str) {
        let Ok(mut m) = self.marks.lock() else { return };
        let k = m.0.len() as u32;
        if k < self.capacity {
            enc.write_timestamp(&self.set, k);
            m.0.push(stage);
        } else {
            m.1 += 1;
        }
    }

    /// Marks dropped since [`reset`](Self::reset) for want of room.
    pub fn dropped(&self) -> u32 {
        self.marks.lock().map(|m| m.1).unwrap_or(0)
    }

    /// Resolves the frame's timestamps into the buffer [`read`](Self::read) copies out (record
    /// after the frame, in the same or a later encoder, before the submit).
    pub fn resolve(&self, enc: &mut wgpu::CommandEncoder) {
        let n = self.marks.lock().map(|m| m.0.len() as u32).unwrap_or(0);
        if n > 0 {
            enc.resolve_query_set(&self.set, 0..n, &self.resolved, 0);
        }
    }

    /// The frame's stages in order with their GPU milliseconds (the time from the previous mark
    /// to the stage's own; a stage marked several times, e.g. once per sub-light, is summed
    /// under its first place). A readback: call after the submit, outside the frame loop.
    pub fn read(&self, ctx: &GpuContext) -> Result<Vec<(&'static str, f64)>> {
        let labels = self.marks.lock().map(|m| m.0.clone()).unwrap_or_default();
        if labels.len() < 2 {
            return Ok(Vec::new());
        }
        let ticks: Vec<u64> = ctx.read_buffer(&self.resolved, 8 * labels.len() as u64)?;
        let mut out: Vec<(&'static str, f64)> = Vec::new();
        for k in 1..labels.len() {
            let ns = ticks[k].saturating_sub(ticks[k - 1]) as f64 * self.period_ns as f64;
            match out.iter_mut().find(|(s, _)| *s == labels[k]) {
                Some(e) => e.1 += ns * 1e-6,
                None => out.push((labels[k], ns * 1e-6)),
            }
        }
        Ok(out)
    }
}

/// The checks every [`FrameEstimator::encode`] makes first, before anything is recorded: the
/// device not lost ([`GpuContext::check_lost`], a flag: no poll, no wait), then the caller's
/// buffers against the count ([`Error::Limit`], `what` naming the buffer). Frames bind their
/// receivers a [`ReceiverRange`] at a time, so they take any count these buffers hold.
pub fn check_buffers(
    ctx: &GpuContext,
    receivers: &wgpu::Buffer,
    v: &wgpu::Buffer,
    n: u64,
) -> Result<()> {
    ctx.check_lost()?;
    for (what, have, need) in [
        (
            "receiver buffer bytes",
            receivers.size(),
            n * RECEIVER_BYTES,
        ),
        ("V buffer bytes", v.size(), n * 4),
    ] {
        if have < need {
            return Err(Error::Limit {
                what,
                requested: need,
                max: have,
            });
        }
    }
    Ok(())
}

/// A run of a frame's receivers that one dispatch covers: receivers `first..first + count`,
/// bound as a range of the caller's receiver buffer, of V and of any per-receiver buffer of the
/// frame's own, so the kernel indexes them from 0 and `arrayLength` is the range's count.
/// [`receiver_ranges`] cuts a frame into them.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ReceiverRange {
    /// The range's first receiver.
    pub first: u32,
    /// How many receivers it holds (at least 1).
    pub count: u32,
}

impl ReceiverRange {
    /// The range's elements of `stride` bytes each in `b` (receivers: [`RECEIVER_BYTES`]; V
    /// and other per-receiver words: 4) as a binding.
    pub fn bind(self, b: &wgpu::Buffer, stride: u64) -> wgpu::BindingResource<'_> {
        wgpu::BindingResource::Buffer(wgpu::BufferBinding {
            buffer: b,
            offset: self.first as u64 * stride,
            size: NonZeroU64::new(self.count as u64 * stride),
        })
    }

    /// The range's receivers in the caller's receiver buffer.
    pub fn receivers(self, b: &wgpu::Buffer) -> wgpu::BindingResource<'_> {
        self.bind(b, RECEIVER_BYTES)
    }

    /// The range's words (V, per-receiver sums) in `b`.
    pub fn words(self, b: &wgpu::Buffer) -> wgpu::BindingResource<'_> {
        self.bind(b, 4)
    }

    /// The workgroups of one invocation per receiver of the range.
    pub fn workgroups(self) -> [u32; 3] {
        [self.count.div_ceil(WORKGROUP_SIZE), 1, 1]
    }
}

/// The most receivers one [`ReceiverRange`] holds on a device of `limits` when the widest
/// per-receiver element it binds is `widest` bytes: that binding within
/// `max_storage_buffer_binding_size`, its dispatch within
/// `max_compute_workgroups_per_dimension`, a multiple of the offset unit (see
/// [`receiver_ranges`]) and of [`WORKGROUP_SIZE`]; 0 where the binding holds less than one such
/// multiple.
fn max_range(limits: &wgpu::Limits, widest: u64) -> u64 {
    let unit = range_unit(limits);
    let by_binding = limits.max_storage_buffer_binding_size / widest.max(RECEIVER_BYTES);
    let by_dispatch = limits.max_compute_workgroups_per_dimension as u64 * WORKGROUP_SIZE as u64;
    by_binding.min(by_dispatch) / unit * unit
}

/// The step range starts are multiples of: their byte offsets in 4-byte and 32-byte buffers are
/// multiples of `min_storage_buffer_offset_alignment`, and ranges hold whole workgroups.
fn range_unit(limits: &wgpu::Limits) -> u64 {
    let words = (limits.min_storage_buffer_offset_alignment.max(1) as u64).div_ceil(4);
    let wg = WORKGROUP_SIZE as u64;
    words / gcd(words, wg) * wg
}

fn gcd(a: u64, b: u64) -> u64 {
    if b == 0 {
        a
    } else {
        gcd(b, a % b)
    }
}

/// The [`ReceiverRange`]s covering `count` receivers on `ctx`'s device, in order (none for 0):
/// a 3840 x 2160 view (8.3 M receivers, 265 MB) is 2 ranges under the default limits.
pub fn receiver_ranges(ctx: &GpuContext, count: u32) -> Vec<ReceiverRange> {
    receiver_ranges_binding(ctx, count, RECEIVER_BYTES)
}

/// [`receiver_ranges`] for a frame that also binds per-receiver elements of its own of up to
/// `widest` bytes a range at a time (each range's binding of them within the device's). A frame
/// calls [`range_capacity`] at `prepare` first, which refuses a device with no such range.
pub fn receiver_ranges_binding(ctx: &GpuContext, count: u32, widest: u64) -> Vec<ReceiverRange> {
    ranges_of(max_range(&ctx.limits(), widest).max(1), count)
}

/// The most receivers one range of [`receiver_ranges_binding`] holds on `ctx`'s device: what a
/// frame sizes the scratch buffers it binds a range at a time for. [`Error::Limit`] (`what`
/// naming the elements) where `max_storage_buffer_binding_size` holds fewer `widest`-byte
/// elements than one aligned run of whole workgroups.
pub fn range_capacity(ctx: &GpuContext, what: &'static str, widest: u64) -> Result<u64> {
    let limits = ctx.limits();
    match max_range(&limits, widest) {
        0 => Err(Error::Limit {
            what,
            requested: range_unit(&limits) * widest,
            max: limits.max_storage_buffer_binding_size,
        }),
        n => Ok(n),
    }
}

fn ranges_of(per: u64, count: u32) -> Vec<ReceiverRange> {
    (0..count as u64)
        .step_by(per as usize)
        .map(|first| ReceiverRange {
            first: first as u32,
            count: (count as u64 - first).min(per) as u32,
        })
        .collect()
}

/// The per-receiver storage buffer of `4 max_receivers` bytes an engine path allocates at
/// `prepare` ([`Error::Limit`] naming `max_storage_buffer_binding_size` beyond the device's
/// binding or buffer size; `what` names the buffer).
pub fn check_per_receiver(ctx: &GpuContext, what: &'static str, max_receivers: u32) -> Result<()> {
    ctx.check_storage_bytes(what, 4 * max_receivers as u64)
}

/// [`check_buffers`] for `inputs`, then its receiver count against the `max_receivers` the frame
/// was prepared for ([`Error::Limit`] with `what`): the checks a frame with per-receiver buffers
/// of its own makes first in `encode`. Returns the count.
pub fn check_prepared_inputs(
    ctx: &GpuContext,
    inputs: &FrameInputs<'_>,
    max_receivers: u32,
    what: &'static str,
) -> Result<u64> {
    let n = inputs.count as u64;
    check_buffers(ctx, inputs.receivers, inputs.v, n)?;
    if inputs.count > max_receivers {
        return Err(Error::Limit {
            what,
            requested: n,
            max: max_receivers as u64,
        });
    }
    Ok(n)
}

/// V of a frame's CPU twin `est` configured with the frame's `params`
/// ([`FrameEstimator::cpu_twin`]): `estimate` builds it in the frame's views and writes one
/// value per receiver of `receivers`.
pub fn cpu_twin_v<E: crate::SoftShadowEstimator>(
    mut est: E,
    params: &crate::Params,
    receivers: &Receivers,
    estimate: impl FnOnce(&mut E, &mut [f32]) -> Result<()>,
) -> Result<Vec<f32>> {
    crate::estimator::configure(&mut est, params)?;
    let mut v = vec![0.0; receivers.len()];
    estimate(&mut est, &mut v)?;
    Ok(v)
}

/// Records one compute pass `label`: `pipe` with `group` at index 0, `workgroups` dispatched.
pub fn compute_pass(
    enc: &mut wgpu::CommandEncoder,
    label: &str,
    pipe: &wgpu::ComputePipeline,
    group: &wgpu::BindGroup,
    workgroups: [u32; 3],
) {
    let [x, y, z] = workgroups;
    begin(enc, label, pipe, group).dispatch_workgroups(x, y, z);
}

/// A compute pass labelled `label` with `pipe` and `group` (at group 0) set.
fn begin<'e>(
    enc: &'e mut wgpu::CommandEncoder,
    label: &str,
    pipe: &wgpu::ComputePipeline,
    group: &wgpu::BindGroup,
) -> wgpu::ComputePass<'e> {
    let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
        label: Some(label),
        timestamp_writes: None,
    });
    pass.set_pipeline(pipe);
    pass.set_bind_group(0, group, &[]);
    pass
}

/// [`compute_pass`] with its workgroup counts read from `args` (three u32 at byte 0, written on
/// the device: a pass over a queue an earlier pass filled).
pub fn compute_pass_indirect(
    enc: &mut wgpu::CommandEncoder,
    label: &str,
    pipe: &wgpu::ComputePipeline,
    group: &wgpu::BindGroup,
    args: &wgpu::Buffer,
) {
    compute_pass_indirect_at(enc, label, pipe, group, args, 0);
}

/// [`compute_pass_indirect`] with the three u32 at byte `offset` of `args`.
pub fn compute_pass_indirect_at(
    enc: &mut wgpu::CommandEncoder,
    label: &str,
    pipe: &wgpu::ComputePipeline,
    group: &wgpu::BindGroup,
    args: &wgpu::Buffer,
    offset: u64,
) {
    begin(enc, label, pipe, group).dispatch_workgroups_indirect(args, offset);
}

/// A zeroed status buffer of `words` u32 (`STORAGE | COPY_SRC | COPY_DST`): the counters a frame
/// writes for the caller to read when it likes (cleared by each `encode`).
pub fn status_buffer(ctx: &GpuContext, label: &str, words: u64) -> wgpu::Buffer {
    super::kernel::storage_buffer(ctx, label, 4 * words.max(1))
}

/// A frame's status read back without waiting, for an engine's render loop: each frame,
/// [`copy`](Self::copy) records a copy of the status buffer after the frame's passes (when no
/// earlier copy is still on its way), [`submitted`](Self::submitted) starts mapping it once the
/// caller has submitted, and [`take`](Self::take) returns the words once the device has
/// finished (the engine polls the device as it always does). Each map counts as a readback of
/// its [`GpuContext`] ([`GpuContext::readbacks`]).
pub struct StatusReadback {
    staging: wgpu::Buffer,
    state: std::sync::Arc<std::sync::atomic::AtomicU8>,
}

impl StatusReadback {
    const IDLE: u8 = 0;
    const COPIED: u8 = 1;
    const MAPPING: u8 = 2;
    const MAPPED: u8 = 3;

    /// A readback for status buffers of `bytes` bytes (a [`FrameEstimator::status`]'s size).
    pub fn new(ctx: &GpuContext, bytes: u64) -> StatusReadback {
        StatusReadback {
            staging: ctx.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("frame status readback"),
                size: bytes.max(4),
                usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
                mapped_at_creation: false,
            }),
            state: Default::default(),
        }
    }

    /// Records a copy of `status` into the readback when the last one has been taken; whether
    /// it recorded one. Record it after the frame's passes, into the same encoder.
    pub fn copy(&self, enc: &mut wgpu::CommandEncoder, status: &wgpu::Buffer) -> bool {
        use std::sync::atomic::Ordering;
        if self.state.load(Ordering::Acquire) != Self::IDLE {
            return false;
        }
        let bytes = status.size().min(self.staging.size());
        enc.copy_buffer_to_buffer(status, 0, &self.staging, 0, bytes);
        self.state.store(Self::COPIED, Ordering::Release);
        true
    }

    /// Starts mapping a copy recorded since the last call, once the encoder holding it has been
    /// submitted (before that, mapping would make the submit invalid). Does not wait.
    pub fn submitted(&self, ctx: &GpuContext) {
        use std::sync::atomic::Ordering;
        if self
            .state
            .compare_exchange(
                Self::COPIED,
                Self::MAPPING,
                Ordering::AcqRel,
                Ordering::Acquire,
            )
            .is_err()
        {
            return;
        }
        ctx.count_readback();
        let state = self.state.clone();
        self.staging
            .slice(..)
            .map_async(wgpu::MapMode::Read, move |r| {
                // A failed map (a lost device) leaves it mapping: nothing more is copied.
                if r.is_ok() {
                    state.store(Self::MAPPED, Ordering::Release);
                }
            });
    }

    /// The words of the last copy once the device has mapped them (the readback is then free
    /// for the next [`copy`](Self::copy)); `None` while none is ready.
    pub fn take(&self) -> Option<Vec<u32>> {
        use std::sync::atomic::Ordering;
        if self.state.load(Ordering::Acquire) != Self::MAPPED {
            return None;
        }
        let words = self
            .staging
            .slice(..)
            .get_mapped_range()
            .ok()
            .map(|data| bytemuck::pod_collect_to_vec::<u8, u32>(&data));
        self.staging.unmap();
        self.state.store(Self::IDLE, Ordering::Release);
        words
    }
}

/// The first `bytes` of `b` as a binding.
pub fn buffer_range(b: &wgpu::Buffer, bytes: u64) -> wgpu::BindingResource<'_> {
    wgpu::BindingResource::Buffer(wgpu::BufferBinding {
        buffer: b,
        offset: 0,
        size: NonZeroU64::new(bytes),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn receiver_ranges_cover_every_receiver_once_within_the_limits() {
        let mut limits = wgpu::Limits::default();
        // The default limits: one dispatch (65,535 workgroups) holds fewer receivers than a
        // 128 MiB binding (4 Mi); a 4K view takes 2 ranges.
        assert_eq!(max_range(&limits, RECEIVER_BYTES), 65_535 * 64);
        assert_eq!(
            ranges_of(max_range(&limits, RECEIVER_BYTES), 3840 * 2160).len(),
            2
        );
        // 96-byte elements: 128 MiB / 96, down to whole workgroups.
        assert_eq!(max_range(&limits, 96), (128 << 20) / 96 / 64 * 64);
        // A binding short of one aligned run of whole workgroups: none.
        limits.max_storage_buffer_binding_size = 4096;
        assert_eq!(max_range(&limits, 96), 0);
        for (binding, groups, align) in [(64 << 10, 65_535, 256), (1 << 20, 3, 256), (4096, 8, 1)] {
            limits.max_storage_buffer_binding_size = binding;
            limits.max_compute_workgroups_per_dimension = groups;
            limits.min_storage_buffer_offset_alignment = align;
            let per = max_range(&limits, RECEIVER_BYTES);
            assert!(per > 0 && per * RECEIVER_BYTES <= binding && per <= groups as u64 * 64);
            for count in [0, 1, 63, 64, 65, 2047, 2048, 2049, 10_000] {
                let ranges = ranges_of(per, count);
                let mut next = 0;
                for r in &ranges {
                    assert_eq!(r.first, next, "{count}: ranges in order, no gap");
                    assert!(r.count >= 1 && r.count as u64 <= per);
                    assert_eq!(r.first as u64 * 4 % align as u64, 0, "aligned V offset");
                    assert_eq!(r.first % WORKGROUP_SIZE, 0, "whole workgroups");
                    let [x, y, z] = r.workgroups();
                    assert!(x <= groups && y == 1 && z == 1);
                    next = r.first + r.count;
                }
                assert_eq!(next, count);
            }
        }
    }
}
