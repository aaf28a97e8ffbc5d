//! The wgpu backend of the shadow-map core (cargo feature `gpu`).
//!
//! A [`GpuContext`] either creates its own headless device (Vulkan requested explicitly: wgpu never
//! falls back to GL silently, docs/methods.md §12) or wraps a user's `wgpu::Device` and
//! `wgpu::Queue`, so the estimators can run inside someone else's renderer.
//!
//! Stages, each a module with its WGSL beside it (listed in [`SHADERS`]) and a CPU twin:
//!
//! | module | GPU | CPU twin |
//! |---|---|---|
//! | [`raster`] (`raster.wgsl`) | [`GpuShadowMapper`], [`GpuScene`]: peeled layers | [`crate::raster`], [`crate::peeling::peel`] |
//! | [`midpoint`] (`midpoint.wgsl`) | midpoint layers (compute) | [`crate::peeling::midpoints`] |
//! | [`mssm`] (`mssm.wgsl`) | [`GpuMssmBuilder`]: MSSM, dual MSSM, pyramid | [`crate::mssm`] |
//! | [`depth_map`] | [`GpuDepthMap`], upload / readback | [`crate::DepthMap`] |
//! | [`precision`] (`precision.wgsl`) | [`GpuUnorm16Encoder`], [`GpuUnorm16Map`]: 16-bit maps | [`crate::precision`] |
//! | [`light_space`] | [`GpuLightSpace`] | [`crate::LightSpace`] |
//! | [`receivers`] | [`GpuReceivers`] | [`crate::Receivers`] |
//! | [`settle`] (`settle.wgsl`) | [`settle::GpuSettler`]: receivers settled without a map | [`crate::settle::Settler`] |
//! | [`gbuffer`] (`gbuffer.wgsl`) | [`GpuGBuffer`]: camera G-buffer | [`crate::Receivers::from_camera`] |
//! | [`shared`] (`shared.wgsl`) | structs both sides read | |
//! | [`estimate`] (`estimate.wgsl`, `math.wgsl`) | [`EstimateUniform`]: the light and bias every estimate kernel reads, f32 light math | [`crate::light`], [`crate::LightView::receiver_bias`] |
//! | [`kernel`] | [`Kernel`]: layouts from a binding list, pipelines, chunked receivers, readback | |
use crate::{Error, Result};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};

pub mod casters;
pub mod depth_map;
pub mod depth_receivers;
pub mod estimate;
pub mod frame;
pub mod frame_twin;
pub mod gbuffer;
pub mod kernel;
pub mod layout;
pub mod light_space;
pub mod midpoint;
pub mod mssm;
pub mod precision;
pub mod raster;
pub mod receivers;
pub mod settle;
pub mod shared;

pub use depth_map::{read_depth_map, upload_depth_map, GpuDepthMap};
pub use estimate::EstimateUniform;
pub use gbuffer::{GpuGBuffer, GpuGBufferImage};
pub use kernel::{Binding, Kernel};
pub use light_space::GpuLightSpace;
pub use midpoint::GpuMidpointPass;
pub use mssm::{
    GpuDualMssm, GpuMinMaxLevel, GpuMinMaxPass, GpuMinMaxPyramid, GpuMssm, GpuMssmBuilder,
};
pub use precision::{GpuUnorm16Encoder, GpuUnorm16Frame, GpuUnorm16Map};
pub use raster::{GpuLayersFrame, GpuMapFrame, GpuScene, GpuShadowMapper, LayersSlot};
pub use receivers::GpuReceivers;

/// Every WGSL shader of the crate as `(name, complete source)`, shared structs prepended where a
/// stage uses them. A unit test validates each with naga, so a WGSL error fails CPU-only CI.
pub const SHADERS: &[(&str, &str)] = &[
    ("shared", shared::SHARED_WGSL),
    ("raster", raster::RASTER_WGSL),
    ("midpoint", midpoint::MIDPOINT_WGSL),
    ("mssm", mssm::MSSM_WGSL),
    ("gbuffer", gbuffer::GBUFFER_WGSL),
    ("precision", precision::PRECISION_WGSL),
    ("estimate", estimate::ESTIMATE_HEAD_WGSL),
    ("bitmask", estimate::BITMASK_WGSL),
    ("cells", estimate::CELLS_WGSL),
    ("silhouette_setup", estimate::SILHOUETTE_SETUP_CHECK_WGSL),
    ("depth_receivers", depth_receivers::DEPTH_RECEIVERS_SOURCE),
    ("casters", casters::CASTERS_WGSL),
    ("receivers", receivers::RECEIVERS_CHECK_WGSL),
    ("compact", receivers::COMPACT_CHECK_WGSL),
    ("settle", settle::SETTLE_CHECK_WGSL),
    ("settle_args", settle::SETTLE_ARGS_CHECK_WGSL),
    ("plane_to_layer", layout::PLANE_TO_LAYER_WGSL),
    ("linear_layer", raster::LINEAR_LAYER_CHECK_WGSL),
];

/// Redoes the receivers a kernel flagged with [`shared::CUT_BITS`] (cut short by the device's
/// loop budget): checks that the kernel's own count `expected` matches the flags (else
/// [`Error::Gpu`] in `stage`), runs `cpu` on just those receivers (same order) and writes its V
/// over the flags. Returns how many were redone.
pub fn redo_cut_receivers(
    v: &mut [f32],
    receivers: &crate::Receivers,
    expected: usize,
    stage: &str,
    cpu: impl FnOnce(&crate::Receivers, &mut [f32]) -> Result<()>,
) -> Result<usize> {
    let cut: Vec<usize> = (0..v.len())
        .filter(|&k| v[k].to_bits() == shared::CUT_BITS)
        .collect();
    if cut.len() != expected {
        return Err(Error::Gpu {
            stage: stage.into(),
            reason: format!(
                "{expected} receivers counted as cut short by the loop limit, {} flagged",
                cut.len()
            ),
        });
    }
    if cut.is_empty() {
        return Ok(0);
    }
    let sub = crate::Receivers::from_points(
        cut.iter().map(|&k| receivers.position()[k]).collect(),
        cut.iter().map(|&k| receivers.normal()[k]).collect(),
    )?;
    let mut vs = vec![0.0f32; cut.len()];
    cpu(&sub, &mut vs)?;
    for (&k, x) in cut.iter().zip(vs) {
        v[k] = x;
    }
    Ok(cut.len())
}

/// Bytes per chunk of [`GpuContext::write_in`]'s staging belt: each write takes a chunk of its
/// own (larger writes a larger one), the uniforms of a frame one each.
const BELT_CHUNK_BYTES: u64 = 256;

/// A device and queue, owned or borrowed, with what the backend needs to know about them.
#[derive(Debug, Clone)]
pub struct GpuContext {
    /// The device.
    pub device: wgpu::Device,
    /// Its queue.
    pub queue: wgpu::Queue,
    /// Adapter description (None for a user's device, where wgpu does not expose it).
    pub adapter: Option<wgpu::AdapterInfo>,
    /// Set by the device-lost callback; checked by [`GpuContext::check_lost`].
    lost: Arc<Mutex<Option<String>>>,
    /// Buffers mapped for reading through [`GpuContext::read_buffer`] (every readback the
    /// library makes goes through it).
    readbacks: Arc<AtomicU64>,
    /// The staging memory of [`GpuContext::write_in`].
    belt: Arc<Mutex<wgpu::util::StagingBelt>>,
    /// Bind groups made through [`GpuContext::create_bind_group`].
    bind_groups: Arc<AtomicU64>,
}

impl GpuContext {
    /// Creates a headless device on the first Vulkan adapter, with the adapter's own limits (so the
    /// largest textures and storage bindings it supports are usable) and the features the backend
    /// uses when available (timestamp queries).
    pub fn new() -> Result<Self> {
        let mut desc = wgpu::InstanceDescriptor::new_without_display_handle_from_env();
        desc.backends = wgpu::Backends::VULKAN;
        let instance = wgpu::Instance::new(desc);
        let adapter = pollster::block_on(instance.request_adapter(&wgpu::RequestAdapterOptions {
            power_preference: wgpu::PowerPreference::HighPerformance,
            force_fallback_adapter: false,
            compatible_surface: None,
            ..Default::default()
        }))
        .map_err(|e| Error::NoAdapter(e.to_string()))?;
        let wanted =
            wgpu::Features::TIMESTAMP_QUERY | wgpu::Features::TIMESTAMP_QUERY_INSIDE_ENCODERS;
        let features = adapter.features() & wanted;
        let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
            label: Some("softshadow"),
            required_features: features,
            required_limits: adapter.limits(),
            ..Default::default()
        }))
        .map_err(|e| Error::NoAdapter(format!("request_device: {e}")))?;
        let mut ctx = Self::from_device(device, queue);
        ctx.adapter = Some(adapter.get_info());
        // The device is ours: its losses come back as Error::DeviceLost (the callback holds the
        // flag only, not the device, so no reference cycle keeps the device alive).
        let lost = ctx.lost.clone();
        ctx.device.set_device_lost_callback(move |reason, msg| {
            if let Ok(mut g) = lost.lock() {
                *g = Some(format!("{reason:?}: {msg}"));
            }
        });
        Ok(ctx)
    }

    /// Wraps a user's device and queue. Nothing is created or changed on them: the device-lost
    /// callback stays the host renderer's (wgpu keeps one per device). To have losses come back
    /// from this crate as [`Error::DeviceLost`], call
    /// [`report_device_lost`](Self::report_device_lost) from that callback.
    pub fn from_device(device: wgpu::Device, queue: wgpu::Queue) -> Self {
        let belt = wgpu::util::StagingBelt::new(device.clone(), BELT_CHUNK_BYTES);
        GpuContext {
            device,
            queue,
            adapter: None,
            lost: Arc::new(Mutex::new(None)),
            readbacks: Arc::new(AtomicU64::new(0)),
            belt: Arc::new(Mutex::new(belt)),
            bind_groups: Arc::new(AtomicU64::new(0)),
        }
    }

    /// `device.create_bind_group`, counted ([`bind_groups`](Self::bind_groups)): the bind
    /// groups of every frame estimator's `encode` and of the compute kernels go through it.
    pub fn create_bind_group(&self, desc: &wgpu::BindGroupDescriptor<'_>) -> wgpu::BindGroup {
        self.bind_groups.fetch_add(1, Ordering::Relaxed);
        self.device.create_bind_group(desc)
    }

    /// How many bind groups this context has made so far: a frame recorded again from the same
    /// buffers makes none ([`kernel::BindGroupCache`]).
    pub fn bind_groups(&self) -> u64 {
        self.bind_groups.load(Ordering::Relaxed)
    }

    /// Writes `bytes` (a multiple of 4 long) into `dst` at `offset` as a copy recorded into
    /// `enc` (`dst` needs `COPY_DST`): passes recorded after it read the new value and passes
    /// before it the old one, so one encoder, or several submitted together, may record a frame
    /// many times with different uniforms. `queue.write_buffer` instead lands before the whole
    /// submit, leaving every pass the last value written. The bytes go through mapped chunks
    /// of wgpu's `StagingBelt`, handed back for reuse once `enc` is submitted and done (an
    /// encoder dropped unsubmitted drops its chunks).
    pub fn write_in(
        &self,
        enc: &mut wgpu::CommandEncoder,
        dst: &wgpu::Buffer,
        offset: u64,
        bytes: &[u8],
    ) {
        let Some(size) = wgpu::BufferSize::new(bytes.len() as u64) else {
            return;
        };
        if self.check_lost().is_err() {
            return;
        }
        let mut belt = self.belt.lock().unwrap_or_else(|e| e.into_inner());
        let align = wgpu::BufferSize::new(wgpu::COPY_BUFFER_ALIGNMENT).expect("non-zero");
        let slice = belt.allocate(size, align);
        // A device lost or destroyed gives no mapping: nothing is written (nothing recorded on
        // it will run). The loss is recorded at once, so that no later write touches the belt,
        // whose chunk made on the lost device cannot even be unmapped; `check_lost` reports it.
        let Ok(mut view) = slice.get_mapped_range_mut() else {
            drop(belt);
            self.report_device_lost("a staging buffer could not be mapped: the device is lost");
            return;
        };
        view.copy_from_slice(bytes);
        drop(view);
        enc.copy_buffer_to_buffer(slice.buffer(), slice.offset(), dst, offset, size.get());
        // Closed at once: the chunk is unmapped before `enc` can be submitted, and re-mapped
        // for the belt when that submission completes.
        belt.finish_and_recall_on_submit(enc);
    }

    /// Marks the device lost (`reason` is kept for the error): every later call through this
    /// context (and its clones) fails with [`Error::DeviceLost`]. For a host that owns the
    /// device-lost callback ([`from_device`](Self::from_device)).
    pub fn report_device_lost(&self, reason: impl Into<String>) {
        if let Ok(mut g) = self.lost.lock() {
            *g = Some(reason.into());
        }
    }

    /// One context per process, created on first use (tests, the registry's GPU twins and the
    /// CLI share it). Once its device is lost ([`check_lost`](Self::check_lost), after a
    /// non-blocking poll so that wgpu can report an explicit `destroy`), the next call creates
    /// a fresh context and hands that out from then on: a loss is never cached for the rest of
    /// the process. Holders of the lost context keep it (every call through it gives
    /// [`Error::DeviceLost`]) and make their estimators again from a new `shared()`. A missing
    /// adapter is cached ([`Error::NoAdapter`] every time).
    pub fn shared() -> Result<Arc<GpuContext>> {
        static CTX: Mutex<Option<std::result::Result<Arc<GpuContext>, String>>> = Mutex::new(None);
        let mut slot = CTX.lock().unwrap_or_else(|e| e.into_inner());
        if let Some(Ok(c)) = slot.as_ref() {
            if c.poll_lost().is_err() {
                *slot = None;
            }
        }
        slot.get_or_insert_with(|| {
            GpuContext::new().map(Arc::new).map_err(|e| match e {
                Error::NoAdapter(m) => m,
                other => other.to_string(),
            })
        })
        .clone()
        .map_err(Error::NoAdapter)
    }

    /// [`check_lost`](Self::check_lost) after a non-blocking poll of the device, which is when
    /// wgpu reports an explicit `Device::destroy` (a real loss is reported as it happens). A
    /// blocking call's check, not `encode`'s (a poll runs the device's pending callbacks).
    pub fn poll_lost(&self) -> Result<()> {
        self.check_lost()?;
        self.poll(wgpu::PollType::Poll)?;
        self.check_lost()
    }

    /// `device.poll`, with a loss as [`Error::DeviceLost`]: wgpu panics when polling a device
    /// the driver lost (its fatal-error path), so that panic is caught here and reported as the
    /// loss its device-lost callback has recorded by then.
    fn poll(&self, poll: wgpu::PollType) -> Result<wgpu::PollStatus> {
        let polled =
            std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| self.device.poll(poll)));
        match polled {
            Ok(Ok(status)) => Ok(status),
            Ok(Err(e)) => Err(self.lost_or(Error::Gpu {
                stage: "poll".into(),
                reason: e.to_string(),
            })),
            Err(panic) => {
                let reason = panic
                    .downcast_ref::<String>()
                    .cloned()
                    .or_else(|| panic.downcast_ref::<&str>().map(|s| s.to_string()))
                    .unwrap_or_else(|| "wgpu panicked in Device::poll".into());
                Err(self.lost_or(Error::Gpu {
                    stage: "poll".into(),
                    reason: reason.replace('\n', " "),
                }))
            }
        }
    }

    /// `e`, or [`Error::DeviceLost`] when the device has been lost: the errors wgpu gives for
    /// objects of a lost device (an invalid buffer, a failed mapping) are the loss. Polls once
    /// (non-blocking) when no loss is recorded yet, so a `destroy` wgpu has not reported counts.
    fn lost_or(&self, e: Error) -> Error {
        if self.check_lost().is_ok() {
            let poll = || self.device.poll(wgpu::PollType::Poll);
            let _ = std::panic::catch_unwind(std::panic::AssertUnwindSafe(poll));
        }
        match self.check_lost() {
            Err(lost) => lost,
            Ok(()) => e,
        }
    }

    /// Fails with [`Error::Limit`] (naming `max_texture_dimension_2d`) when a square texture
    /// of side `size` (a shadow-map resolution) cannot be created on this device: what every
    /// estimator checks before allocating anything of that size, CPU-side twins included.
    pub fn check_resolution(&self, size: u32) -> Result<()> {
        depth_map::check_size(self, size)
    }

    /// Fails with [`Error::Limit`] when a storage buffer of `bytes`, bound whole, exceeds
    /// `max_storage_buffer_binding_size` or `max_buffer_size` (the maximum reported is the
    /// smaller). `what` names the buffer and the limit, e.g.
    /// `"multi-sample frame counts bytes (max_storage_buffer_binding_size)"`.
    pub fn check_storage_bytes(&self, what: &'static str, bytes: u64) -> Result<()> {
        let l = self.limits();
        let max = l.max_storage_buffer_binding_size.min(l.max_buffer_size);
        if bytes > max {
            return Err(Error::Limit {
                what,
                requested: bytes,
                max,
            });
        }
        Ok(())
    }

    /// The device's limits.
    pub fn limits(&self) -> wgpu::Limits {
        self.device.limits()
    }

    /// A one-line description of the adapter ("lavapipe (Vulkan, Cpu)").
    pub fn describe(&self) -> String {
        match &self.adapter {
            Some(a) => format!("{} ({:?}, {:?})", a.name, a.backend, a.device_type),
            None => "user-provided device".into(),
        }
    }

    /// Fails with [`Error::DeviceLost`] once the device has been lost: a real loss as wgpu
    /// meets it, an explicit `Device::destroy` once wgpu reports it (at the device's next poll,
    /// WebGPU's "lost after the queued work"). Reads a flag only: never blocks, never polls, so
    /// every [`FrameEstimator::encode`](frame::FrameEstimator::encode) calls it first.
    ///
    /// **After a loss** nothing made on the device works again (a wgpu device is not revived):
    /// the caller makes a new context ([`new`](Self::new), [`from_device`](Self::from_device)
    /// with its new device, or [`shared`](Self::shared), which replaces a lost one) and prepares
    /// its estimators again on it; the library keeps no other state bound to a device.
    pub fn check_lost(&self) -> Result<()> {
        match self.lost.lock().ok().and_then(|g| g.clone()) {
            Some(m) => Err(Error::DeviceLost(m)),
            None => Ok(()),
        }
    }

    /// Runs `f` inside validation and out-of-memory error scopes, turning wgpu's asynchronous
    /// errors into typed ones named after `stage`.
    pub fn scoped<T>(&self, stage: &str, f: impl FnOnce() -> T) -> Result<T> {
        self.check_lost()?;
        let oom = self.device.push_error_scope(wgpu::ErrorFilter::OutOfMemory);
        let val = self.device.push_error_scope(wgpu::ErrorFilter::Validation);
        let out = f();
        let v = pollster::block_on(val.pop());
        let o = pollster::block_on(oom.pop());
        if let Some(e) = o {
            return Err(self.lost_or(Error::OutOfMemory(format!("{stage}: {e}"))));
        }
        if let Some(e) = v {
            return Err(self.lost_or(Error::Gpu {
                stage: stage.to_string(),
                reason: e.to_string().replace('\n', " "),
            }));
        }
        self.check_lost()?;
        Ok(out)
    }

    /// Blocks until all submitted work is done. [`Error::DeviceLost`] once the device is lost
    /// (the wait is when wgpu reports an explicit `destroy`).
    pub fn wait(&self) -> Result<()> {
        self.check_lost()?;
        self.poll(wgpu::PollType::wait_indefinitely())?;
        self.check_lost()
    }

    /// How many buffers this context has mapped back to the CPU so far ([`read_buffer`](Self::read_buffer),
    /// and [`frame::StatusReadback`]'s maps): a frame loop that reads nothing back leaves it unchanged.
    pub fn readbacks(&self) -> u64 {
        self.readbacks.load(Ordering::Relaxed)
    }

    /// Counts a readback made outside [`read_buffer`](Self::read_buffer) (a non-blocking one).
    pub(crate) fn count_readback(&self) {
        self.readbacks.fetch_add(1, Ordering::Relaxed);
    }

    /// Copies a buffer back to the CPU as `T`s (a staging buffer, one submit, one wait).
    pub fn read_buffer<T: bytemuck::Pod>(&self, src: &wgpu::Buffer, bytes: u64) -> Result<Vec<T>> {
        let gpu = |reason: String| Error::Gpu {
            stage: "readback".into(),
            reason,
        };
        self.readbacks.fetch_add(1, Ordering::Relaxed);
        // Scoped: on a lost device the staging buffer is invalid and mapping it is a validation
        // error, which would otherwise reach wgpu's default handler (a panic).
        let (staging, rx) = self.scoped("readback", || {
            let staging = self.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("readback"),
                size: bytes,
                usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
                mapped_at_creation: false,
            });
            let mut enc = self.device.create_command_encoder(&Default::default());
            enc.copy_buffer_to_buffer(src, 0, &staging, 0, bytes);
            self.queue.submit([enc.finish()]);
            let (tx, rx) = std::sync::mpsc::channel();
            staging.slice(..).map_async(wgpu::MapMode::Read, move |r| {
                let _ = tx.send(r);
            });
            (staging, rx)
        })?;
        self.wait()?;
        rx.recv()
            .map_err(|e| self.lost_or(gpu(e.to_string())))?
            .map_err(|e| self.lost_or(gpu(e.to_string())))?;
        let slice = staging.slice(..);
        let data = slice
            .get_mapped_range()
            .map_err(|e| self.lost_or(gpu(format!("{e:?}"))))?;
        // Copy into a `Vec<T>` rather than casting the mapping, which need not be aligned for `T`.
        let n = data.len() / std::mem::size_of::<T>().max(1);
        let mut out = vec![T::zeroed(); n];
        bytemuck::cast_slice_mut::<T, u8>(&mut out)
            .copy_from_slice(&data[..n * std::mem::size_of::<T>()]);
        drop(data);
        staging.unmap();
        Ok(out)
    }
}

#[cfg(test)]
mod tests {
    use super::SHADERS;

    /// Every shader of the crate parses and validates with naga (no device needed, so a WGSL
    /// error fails CPU-only CI), and every `.wgsl` file beside this module is part of one.
    #[test]
    fn every_shader_validates_with_naga() {
        for (name, src) in SHADERS {
            let module = naga::front::wgsl::parse_str(src)
                .unwrap_or_else(|e| panic!("{name}.wgsl: {}", e.emit_to_string(src)));
            naga::valid::Validator::new(
                naga::valid::ValidationFlags::all(),
                naga::valid::Capabilities::all(),
            )
            .validate(&module)
            .unwrap_or_else(|e| panic!("{name}.wgsl: {}", e.emit_to_string(src)));
        }
        let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("src/gpu");
        let mut files = 0;
        for entry in std::fs::read_dir(&dir)
            .expect("src/gpu is readable")
            .flatten()
        {
            let path = entry.path();
            if path.extension().is_some_and(|e| e == "wgsl") {
                files += 1;
                let text = std::fs::read_to_string(&path).expect("wgsl is readable");
                assert!(
                    SHADERS.iter().any(|(_, src)| src.contains(text.as_str())),
                    "{} is not part of gpu::SHADERS",
                    path.display()
                );
            }
        }
        assert!(files >= SHADERS.len());
    }
}
