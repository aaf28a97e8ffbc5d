//! Receivers on the GPU: a storage buffer of [`ReceiverGpu`] (32 bytes each), uploaded from
//! [`Receivers`] or wrapped around a user's buffer (e.g. built from their own G-buffer).
use super::{
    frame::{compute_pass, ReceiverRange},
    kernel::{buffer_init, BindGroupCache, SpecializedKernel},
    shared::{pack_receivers, ReceiverGpu, SHARED_WGSL},
    GpuContext,
};
use crate::{receivers::Receivers, Error, Result};
use std::num::NonZeroU64;
use std::sync::Mutex;

/// The per-receiver estimate entry point (`estimate`) every per-receiver kernel shares, one
/// invocation per receiver of an [`ActiveLists`] list, with its tail `store_v(k, x)` (V clamped
/// to [0, 1], non-finite results written as 0 and counted), and the loop-budget probe (a cut
/// receiver flagged and counted): for kernels that declare `receivers`, `v_out`, `counters`,
/// `active_list`, `estimate_receiver` and `receiver_probe` (see the file).
pub const RECEIVERS_WGSL: &str =
    concat!(include_str!("active.wgsl"), include_str!("receivers.wgsl"));

/// WGSL reading an active list ([`ActiveLists`]): `listed_receiver(i)`, for kernels that
/// declare `active_list` and do not use [`RECEIVERS_WGSL`], which holds it.
pub const ACTIVE_WGSL: &str = include_str!("active.wgsl");

/// WGSL of the compaction [`ActiveLists`] records (after the core's `SHARED_WGSL`).
pub const COMPACT_WGSL: &str = include_str!("compact.wgsl");

/// [`COMPACT_WGSL`] after what it expects, as [`super::SHADERS`] validates it.
pub const COMPACT_CHECK_WGSL: &str =
    concat!(include_str!("shared.wgsl"), include_str!("compact.wgsl"));

/// Consecutive receiver slots one invocation of the compaction lists (at most 32, a bit each;
/// a range's workgroups of them, at most 65,535 x 64 / 512 rounded up = 8,192, are scanned by
/// one workgroup).
pub const COMPACT_RUN: u32 = 8;

/// Words before the indices of an active list: the indirect dispatch (x, y, z) of the kernel
/// that reads it, then the count (`compact.wgsl`).
pub const ACTIVE_HEAD_WORDS: u64 = 4;

/// Which of a range's lists [`ActiveLists::encode`] records.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ListKind {
    /// The range's active receivers.
    Active,
    /// The receivers a first pass over the active list deferred to a second (V = `DEFER_BITS`).
    Deferred,
    /// The same receivers for a second pass that takes a whole workgroup per receiver (a long
    /// tail whose work its lanes share): dispatched as `(min(count, 65535), ⌈count / 65535⌉, 1)`
    /// workgroups, workgroup `(x, y)` taking item `x + 65535 y` (`listed_receiver_of_group`).
    DeferredWide,
}

/// Per receiver range of a frame, the list of its active receivers, made on the device each
/// frame (`compact.wgsl`, three passes, so the list is in slot order on every device):
/// inactive slots get V = NaN there, and the per-receiver kernels run one
/// invocation per listed receiver, dispatched indirectly from the list's head
/// ([`compute_pass_indirect`](super::frame::compute_pass_indirect)). A kernel reading a list
/// declares it as `active_list: array<u32>` and takes receiver `active_list[4 + i]` for invocation
/// `i < active_list[3]`. One list per range index, grown to the range (never truncated), so a frame
/// whose ranges are dispatched in turn keeps every range's list alive at once.
#[derive(Debug)]
pub struct ActiveLists {
    kernel: SpecializedKernel,
    /// `count_runs` of the active receivers and of the deferred ones, `scan_groups` for a
    /// workgroup per `WG` receivers and per receiver, `place_runs`.
    count: [wgpu::ComputePipeline; 2],
    scan: [wgpu::ComputePipeline; 2],
    place: wgpu::ComputePipeline,
    lists: Mutex<Vec<wgpu::Buffer>>,
    deferred: Mutex<Vec<wgpu::Buffer>>,
    groups: BindGroupCache,
}

impl ActiveLists {
    /// Compiles the compaction.
    pub fn new(ctx: &GpuContext) -> Result<Self> {
        let wg = [
            ("WG", super::estimate::WORKGROUP_SIZE as f64),
            ("RUN", COMPACT_RUN as f64),
        ];
        let kernel = SpecializedKernel::new(
            ctx,
            "active receivers",
            &[SHARED_WGSL, COMPACT_WGSL],
            "count_runs",
            &wg,
        )?;
        let count = [
            kernel.pipeline(ctx, &[])?,
            kernel.pipeline(ctx, &[("DEFERRED", 1.0)])?,
        ];
        let scan = [
            kernel.entry_pipeline(ctx, "scan_groups", &[])?,
            kernel.entry_pipeline(ctx, "scan_groups", &[("PER_RECEIVER_GROUP", 1.0)])?,
        ];
        let place = kernel.entry_pipeline(ctx, "place_runs", &[])?;
        Ok(ActiveLists {
            kernel,
            count,
            scan,
            place,
            lists: Mutex::new(Vec::new()),
            deferred: Mutex::new(Vec::new()),
            groups: BindGroupCache::default(),
        })
    }

    /// Records the list `kind` of `range`, the `index`-th range of a frame, of `receivers`
    /// with V into `v`, and returns it to be bound and dispatched from: the range's active
    /// receivers ([`ListKind::Active`], which also writes NaN into its inactive slots; index 0
    /// starts a frame's encode), or, after a first pass over that list, the receivers the pass
    /// deferred ([`ListKind::Deferred`], V = `DEFER_BITS`, `shared.wgsl`) to a second: a kernel's
    /// long tail, run densely ([`ListKind::DeferredWide`]: a workgroup per receiver). One list
    /// per range index for the active receivers, one for the deferred.
    #[allow(clippy::too_many_arguments)]
    pub fn encode(
        &self,
        ctx: &GpuContext,
        enc: &mut wgpu::CommandEncoder,
        kind: ListKind,
        index: usize,
        range: ReceiverRange,
        receivers: &wgpu::Buffer,
        v: &wgpu::Buffer,
    ) -> Result<wgpu::Buffer> {
        let pipes = match kind {
            ListKind::Active => {
                if index == 0 {
                    self.groups.next_encode();
                }
                (&self.lists, &self.count[0], &self.scan[0])
            }
            ListKind::Deferred => (&self.deferred, &self.count[1], &self.scan[0]),
            ListKind::DeferredWide => (&self.deferred, &self.count[1], &self.scan[1]),
        };
        self.record(ctx, enc, pipes, index, range, (receivers, v))
    }

    /// The active list ([`encode`](Self::encode)) of each of the
    /// [`receiver_ranges`](super::frame::receiver_ranges) of `count` receivers, in order: every
    /// range with its list, for a frame whose passes each run over all of them.
    pub fn encode_ranges(
        &self,
        ctx: &GpuContext,
        enc: &mut wgpu::CommandEncoder,
        count: u32,
        receivers: &wgpu::Buffer,
        v: &wgpu::Buffer,
    ) -> Result<Vec<(ReceiverRange, wgpu::Buffer)>> {
        super::frame::receiver_ranges(ctx, count)
            .into_iter()
            .enumerate()
            .map(|(index, range)| {
                let list = self.encode(ctx, enc, ListKind::Active, index, range, receivers, v)?;
                Ok((range, list))
            })
            .collect()
    }

    /// Records a kernel's passes over each of the [`receiver_ranges`](super::frame::receiver_ranges)
    /// of `count` receivers, dispatched indirectly from the range's lists: `over_active` over its
    /// active receivers, then, when given, `over_deferred` over those the first deferred, listed
    /// as its kind says (a first pass that finishes the receivers its cheap test settles and
    /// leaves `DEFER_BITS` for the rest, and the whole kernel over the long tail alone). `group(index, range, list)` makes
    /// the bind group of a pass over `list`, the list of the `index`-th range.
    #[allow(clippy::too_many_arguments)]
    pub fn dispatch_passes(
        &self,
        ctx: &GpuContext,
        enc: &mut wgpu::CommandEncoder,
        label: &str,
        (over_active, over_deferred): (
            &wgpu::ComputePipeline,
            Option<(ListKind, &wgpu::ComputePipeline)>,
        ),
        count: u32,
        (receivers, v): (&wgpu::Buffer, &wgpu::Buffer),
        mut group: impl FnMut(usize, ReceiverRange, &wgpu::Buffer) -> wgpu::BindGroup,
    ) -> Result<()> {
        for (index, range) in super::frame::receiver_ranges(ctx, count)
            .into_iter()
            .enumerate()
        {
            let passes = [Some((ListKind::Active, over_active)), over_deferred];
            for (kind, pipeline) in passes.into_iter().flatten() {
                let list = self.encode(ctx, enc, kind, index, range, receivers, v)?;
                let bind = group(index, range, &list);
                super::frame::compute_pass_indirect(enc, label, pipeline, &bind, &list);
            }
        }
        Ok(())
    }

    fn record(
        &self,
        ctx: &GpuContext,
        enc: &mut wgpu::CommandEncoder,
        (lists, count, scan): (
            &Mutex<Vec<wgpu::Buffer>>,
            &wgpu::ComputePipeline,
            &wgpu::ComputePipeline,
        ),
        index: usize,
        range: ReceiverRange,
        (receivers, v): (&wgpu::Buffer, &wgpu::Buffer),
    ) -> Result<wgpu::Buffer> {
        // The head, the indices, then per workgroup of the slot passes its place and per
        // invocation its run's bits (`compact.wgsl`).
        let groups = range
            .count
            .div_ceil(super::estimate::WORKGROUP_SIZE * COMPACT_RUN);
        let words = ACTIVE_HEAD_WORDS
            + range.count as u64
            + groups as u64 * (1 + super::estimate::WORKGROUP_SIZE as u64);
        let list = {
            let mut lists = lists.lock().unwrap_or_else(|e| e.into_inner());
            while lists.len() <= index {
                lists.push(list_buffer(ctx, ACTIVE_HEAD_WORDS + 1));
            }
            if lists[index].size() < 4 * words {
                // Grown to the range with room for a view a little larger next frame.
                lists[index] = list_buffer(ctx, words + words / 4);
            }
            lists[index].clone()
        };
        let group = self.groups.get_dense(
            ctx,
            "active receivers",
            &self.kernel.layout,
            &[
                range.receivers(receivers),
                range.words(v),
                list.as_entire_binding(),
            ],
        );
        compute_pass(enc, "active receivers count", count, &group, [groups, 1, 1]);
        compute_pass(enc, "active receivers scan", scan, &group, [1, 1, 1]);
        compute_pass(
            enc,
            "active receivers place",
            &self.place,
            &group,
            [groups, 1, 1],
        );
        Ok(list)
    }
}

/// An active list of `words` u32 (`STORAGE | INDIRECT | COPY_DST | COPY_SRC`, read back by
/// tests).
fn list_buffer(ctx: &GpuContext, words: u64) -> wgpu::Buffer {
    ctx.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("active receivers"),
        size: 4 * words,
        usage: wgpu::BufferUsages::STORAGE
            | wgpu::BufferUsages::INDIRECT
            | wgpu::BufferUsages::COPY_DST
            | wgpu::BufferUsages::COPY_SRC,
        mapped_at_creation: false,
    })
}

/// [`RECEIVERS_WGSL`] after the estimate head and the bindings it expects, as [`super::SHADERS`]
/// validates it.
pub const RECEIVERS_CHECK_WGSL: &str = concat!(
    include_str!("shared.wgsl"),
    include_str!("estimate.wgsl"),
    include_str!("math.wgsl"),
    "@group(0) @binding(0) var<storage, read> receivers: array<ReceiverGpu>;\n",
    "@group(0) @binding(1) var<storage, read_write> v_out: array<u32>;\n",
    "@group(0) @binding(2) var<storage, read_write> counters: array<atomic<u32>, 3>;\n",
    "@group(0) @binding(3) var<storage, read> active_list: array<u32>;\n",
    "fn estimate_receiver(p: vec3<f32>, n: vec3<f32>) -> f32 { return dot(p, n); }\n",
    "fn receiver_probe() -> u32 { return 0u; }\n",
    include_str!("active.wgsl"),
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
