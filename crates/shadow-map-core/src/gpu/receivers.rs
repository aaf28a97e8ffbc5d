//! Receivers on the GPU: a storage buffer of [`ReceiverGpu`] (32 bytes each), uploaded from
//! [`Receivers`] or wrapped around a user's buffer (e.g. built from their own G-buffer).
use super::{
    kernel::buffer_init,
    shared::{pack_receivers, ReceiverGpu},
    GpuContext,
};
use crate::{receivers::Receivers, Error, Result};
use std::num::NonZeroU64;

/// The per-receiver estimate entry point (`estimate`) every per-receiver kernel shares, with its
/// head `active_receiver(k)` (inactive receivers get V = NaN) and tail `store_v(k, x)` (V clamped
/// to [0, 1], non-finite results written as 0 and counted), and the loop-budget probe (a cut
/// receiver flagged and counted): for kernels that declare `receivers`, `v_out`, `counters`,
/// `estimate_receiver` and `receiver_probe` (see the file).
pub const RECEIVERS_WGSL: &str = include_str!("receivers.wgsl");

/// [`RECEIVERS_WGSL`] after the estimate head and the bindings it expects, as [`super::SHADERS`]
/// validates it.
pub const RECEIVERS_CHECK_WGSL: &str = concat!(
    include_str!("shared.wgsl"),
    include_str!("estimate.wgsl"),
    include_str!("math.wgsl"),
    "@group(0) @binding(0) var<storage, read> receivers: array<ReceiverGpu>;\n",
    "@group(0) @binding(1) var<storage, read_write> v_out: array<u32>;\n",
    "@group(0) @binding(2) var<storage, read_write> counters: array<atomic<u32>, 3>;\n",
    "fn estimate_receiver(p: vec3<f32>, n: vec3<f32>) -> f32 { return dot(p, n); }\n",
    "fn receiver_probe() -> u32 { return 0u; }\n",
    include_str!("receivers.wgsl")
);

/// Bytes of one receiver on the GPU.
pub const RECEIVER_BYTES: u64 = std::mem::size_of::<ReceiverGpu>() as u64;

/// `count` receivers in `buffer`, starting at offset 0.
#[derive(Debug, Clone)]
pub struct GpuReceivers {
    /// The buffer (usage includes `STORAGE`).
    pub buffer: wgpu::Buffer,
    /// Number of receivers.
    pub count: u32,
}

impl GpuReceivers {
    /// Uploads receivers (packed with [`pack_receivers`]) into a new buffer labelled
    /// `receivers` (usages `STORAGE | COPY_SRC | COPY_DST`). Fails with [`Error::Limit`] beyond
    /// `u32::MAX` receivers or the device's `max_buffer_size`.
    pub fn upload(ctx: &GpuContext, receivers: &Receivers) -> Result<Self> {
        let n = receivers.len() as u64;
        let max = (ctx.limits().max_buffer_size / RECEIVER_BYTES).min(u32::MAX as u64);
        if n > max {
            return Err(Error::Limit {
                what: "receivers in one GPU buffer (max_buffer_size / 32 bytes)",
                requested: n,
                max,
            });
        }
        let mut packed = pack_receivers(receivers);
        if packed.is_empty() {
            // A zero-sized binding is invalid; keep one inactive slot that `count` excludes.
            packed.push(bytemuck::Zeroable::zeroed());
        }
        ctx.scoped("receivers", || GpuReceivers {
            buffer: buffer_init(
                &ctx.device,
                "receivers",
                bytemuck::cast_slice(&packed),
                wgpu::BufferUsages::STORAGE
                    | wgpu::BufferUsages::COPY_SRC
                    | wgpu::BufferUsages::COPY_DST,
            ),
            count: n as u32,
        })
    }

    /// Wraps a user's buffer holding `count` [`ReceiverGpu`]s from offset 0. Fails with
    /// [`Error::Receivers`] when the buffer lacks the `STORAGE` usage or is smaller than
    /// `max(count, 1)` receivers.
    pub fn from_buffer(buffer: wgpu::Buffer, count: u32) -> Result<Self> {
        if !buffer.usage().contains(wgpu::BufferUsages::STORAGE) {
            return Err(Error::Receivers(
                "the receiver buffer needs the STORAGE usage".into(),
            ));
        }
        // At least one slot, so that a binding of an empty range is valid.
        let need = (count as u64).max(1) * RECEIVER_BYTES;
        if buffer.size() < need {
            return Err(Error::Receivers(format!(
                "buffer of {} bytes is too small for {count} receivers ({need} bytes)",
                buffer.size()
            )));
        }
        Ok(GpuReceivers { buffer, count })
    }

    /// Bytes the receivers occupy.
    pub fn bytes(&self) -> u64 {
        self.count as u64 * RECEIVER_BYTES
    }

    /// Splits `0..count` into ranges whose bindings fit `max_binding_bytes` and start at offsets
    /// that are multiples of `offset_alignment` (pass the device's
    /// `max_storage_buffer_binding_size` and `min_storage_buffer_offset_alignment`): receivers
    /// beyond one binding are processed chunk by chunk, not refused. One range for `count == 0`.
    pub fn chunks(
        &self,
        max_binding_bytes: u64,
        offset_alignment: u32,
    ) -> Vec<std::ops::Range<u32>> {
        // Receivers per alignment unit (alignments are powers of two >= 32 in practice).
        let unit = (offset_alignment as u64)
            .max(RECEIVER_BYTES)
            .div_ceil(RECEIVER_BYTES);
        let per = ((max_binding_bytes / RECEIVER_BYTES) / unit * unit).max(unit);
        let mut out = Vec::new();
        let mut first = 0u64;
        loop {
            let end = (first + per).min(self.count as u64);
            out.push(first as u32..end as u32);
            if end >= self.count as u64 {
                break;
            }
            first = end;
        }
        out
    }

    /// A binding of the receivers `range` (see [`GpuReceivers::chunks`]); at least one receiver
    /// slot is bound even for an empty range.
    pub fn binding(&self, range: std::ops::Range<u32>) -> wgpu::BindingResource<'_> {
        let n = (range.end.saturating_sub(range.start) as u64).max(1);
        wgpu::BindingResource::Buffer(wgpu::BufferBinding {
            buffer: &self.buffer,
            offset: range.start as u64 * RECEIVER_BYTES,
            size: NonZeroU64::new(n * RECEIVER_BYTES),
        })
    }

    /// Reads the receivers back. Fails with [`Error::Receivers`] when the buffer lacks the
    /// `COPY_SRC` usage (a user's buffer may).
    pub fn read(&self, ctx: &GpuContext) -> Result<Vec<ReceiverGpu>> {
        if self.count == 0 {
            return Ok(Vec::new());
        }
        if !self.buffer.usage().contains(wgpu::BufferUsages::COPY_SRC) {
            return Err(Error::Receivers(
                "the receiver buffer needs the COPY_SRC usage to be read back".into(),
            ));
        }
        ctx.read_buffer(&self.buffer, self.bytes())
    }
}
