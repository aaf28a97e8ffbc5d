//! Receivers settled without a map, on the device: the GPU twin of
//! [`Settler::unshadowed`](crate::settle::Settler::unshadowed) (docs/methods.md §1 "Receivers
//! outside every view"), for the lit receivers a frame's kernel leaves open because no map it
//! has holds them (accumulation's one frustum, a deep-shadow sub-light view).
//!
//! The kernel appends each open receiver of a range to that range's open list
//! ([`GpuSettler::open_list`]: word 0 the count, then the indices, room for the whole range so
//! nothing is dropped) and leaves its V NaN; [`GpuSettler::encode`] then records three passes
//! over the list (`settle_args.wgsl`, `settle.wgsl`): the indirect dispatches; the casters'
//! boxes in blocks of 64 triangles and runs of 8; the test of every open receiver's light
//! pyramid against them (one invocation per receiver and 256 triangles: a block's box, then its
//! runs' boxes, then their triangles, as the CPU twin's BVH walk tests nodes before triangles);
//! and the result: the facing fraction where no triangle meets the pyramid, NaN (counted) where
//! one may shadow the receiver. The work is at most open receivers x blocks box tests plus the
//! triangles of the blocks and runs a pyramid reaches, with no work at all when none is open.
//! The test runs in f32 relative to the receiver; the CPU's in f64: they can disagree only on a
//! triangle that touches a pyramid's boundary to within f32 rounding.
use super::{
    frame::{compute_pass, compute_pass_indirect, compute_pass_indirect_at, ReceiverRange},
    kernel::{BindGroupCache, Kernel, SpecializedKernel},
    raster::GpuScene,
    EstimateUniform, GpuContext,
};
use crate::Result;
use bytemuck::{Pod, Zeroable};
use std::sync::Mutex;

/// `SettleUniform` in WGSL, the head of [`SETTLE_WGSL`] and [`SETTLE_ARGS_WGSL`].
pub const SETTLE_UNIFORM_WGSL: &str = include_str!("settle_uniform.wgsl");

/// `settle.wgsl`: the test and the result (after the core's light head, `shared.wgsl`,
/// `estimate.wgsl`, `math.wgsl`, and [`SETTLE_UNIFORM_WGSL`]).
pub const SETTLE_WGSL: &str = include_str!("settle.wgsl");

/// `settle_args.wgsl`: the passes' indirect dispatches (after [`SETTLE_UNIFORM_WGSL`]).
pub const SETTLE_ARGS_WGSL: &str = include_str!("settle_args.wgsl");

/// [`SETTLE_WGSL`] and [`SETTLE_ARGS_WGSL`] after what they expect, as [`super::SHADERS`]
/// validates them.
pub const SETTLE_CHECK_WGSL: &str = concat!(
    include_str!("shared.wgsl"),
    include_str!("estimate.wgsl"),
    include_str!("math.wgsl"),
    include_str!("settle_uniform.wgsl"),
    include_str!("settle.wgsl")
);
/// See [`SETTLE_CHECK_WGSL`].
pub const SETTLE_ARGS_CHECK_WGSL: &str = concat!(
    include_str!("settle_uniform.wgsl"),
    include_str!("settle_args.wgsl")
);

/// WGSL a kernel includes to append receiver `k` to its range's open list, bound as
/// `open_list: array<atomic<u32>>` ([`GpuSettler::open_list`]): `fn leave_open(k: u32)`, and
/// `OPEN_BITS`, a NaN payload a kernel that sums over views may keep for a receiver it opened.
pub const OPEN_WGSL: &str = "
// A receiver already in the open list, for a kernel that sums over views (not read here).
const OPEN_BITS: u32 = 0x7fc00be4u;

// Appends receiver k to the range's open list (gpu::settle): its V stays NaN for the settle
// passes. The list holds the whole range, so no receiver is ever dropped.
fn leave_open(k: u32) {
    let i = atomicAdd(&open_list[0], 1u);
    if i + 1u < arrayLength(&open_list) {
        atomicStore(&open_list[i + 1u], k);
    }
}
";

/// Mirrors `SettleUniform` in `settle.wgsl`.
#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable, PartialEq, Eq)]
pub struct SettleUniform {
    /// Caster triangles.
    pub triangles: u32,
    /// Workgroup rows of the test's dispatch (a span of [`SPAN_TRIANGLES`] per row, then
    /// layers of rows).
    pub rows: u32,
    /// The word of the caller's counters that counts receivers left NaN.
    pub unsettled_word: u32,
    /// Padding to 16 bytes.
    pub _pad: u32,
}

const LABEL: &str = "settle";

/// Caster triangles per block of the test's two-level hierarchy (`settle.wgsl`'s RUN * RUNS).
pub const BLOCK_TRIANGLES: u32 = 64;

/// Caster triangles one invocation of the test covers (`settle.wgsl`'s RUN * RUNS * BLOCKS).
pub const SPAN_TRIANGLES: u32 = 256;

/// Bytes of the boxes of `triangles` casters: per block and per run of 8, two `vec4`.
fn box_bytes(triangles: u32) -> u64 {
    let blocks = triangles.div_ceil(BLOCK_TRIANGLES).max(1) as u64;
    blocks * (1 + BLOCK_TRIANGLES as u64 / 8) * 32
}

/// The settle passes of one frame estimator (see the module).
#[derive(Debug)]
pub struct GpuSettler {
    kernel: SpecializedKernel,
    /// `settle_args`, and its layout.
    args_kernel: Kernel,
    uniform: wgpu::Buffer,
    args: wgpu::Buffer,
    /// The casters' block and run boxes, grown to the casters.
    boxes: Mutex<wgpu::Buffer>,
    /// One open list per range index, grown to the range.
    lists: Mutex<Vec<wgpu::Buffer>>,
    groups: BindGroupCache,
}

impl GpuSettler {
    /// Compiles the passes.
    pub fn new(ctx: &GpuContext) -> Result<Self> {
        let parts = [
            super::estimate::LIGHT_HEAD_WGSL,
            SETTLE_UNIFORM_WGSL,
            SETTLE_WGSL,
        ];
        let args_kernel = SpecializedKernel::new(
            ctx,
            "settle dispatch",
            &[SETTLE_UNIFORM_WGSL, SETTLE_ARGS_WGSL],
            "settle_args",
            &[("WG", super::estimate::WORKGROUP_SIZE as f64)],
        )?
        .fixed(ctx)?;
        let kernel = SpecializedKernel::new(
            ctx,
            LABEL,
            &parts,
            "settle_test",
            super::estimate::OVERRIDES,
        )?;
        let args = ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("settle dispatch"),
            size: 36,
            usage: wgpu::BufferUsages::STORAGE
                | wgpu::BufferUsages::INDIRECT
                | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        Ok(GpuSettler {
            kernel,
            args_kernel,
            uniform: super::kernel::uniform_buffer(
                ctx,
                "settle uniform",
                std::mem::size_of::<SettleUniform>() as u64,
            ),
            args,
            boxes: Mutex::new(super::kernel::storage_buffer(
                ctx,
                "settle boxes",
                box_bytes(0),
            )),
            lists: Mutex::new(Vec::new()),
            groups: BindGroupCache::default(),
        })
    }

    /// The open list of the `index`-th range of a frame, `range`, emptied in `enc`: what the
    /// kernel over that range binds as `open_list` ([`OPEN_WGSL`]) before [`encode`](Self::encode)
    /// settles it. Room for every receiver of the range (grown, never truncated).
    pub fn open_list(
        &self,
        ctx: &GpuContext,
        enc: &mut wgpu::CommandEncoder,
        index: usize,
        range: ReceiverRange,
    ) -> wgpu::Buffer {
        if index == 0 {
            self.groups.next_encode();
        }
        let words = 1 + range.count as u64;
        let list = {
            let mut lists = self.lists.lock().unwrap_or_else(|e| e.into_inner());
            while lists.len() <= index {
                lists.push(super::kernel::storage_buffer(ctx, "open receivers", 8));
            }
            if lists[index].size() < 4 * words {
                lists[index] = super::kernel::storage_buffer(ctx, "open receivers", 4 * words);
            }
            lists[index].clone()
        };
        enc.clear_buffer(&list, 0, Some(4));
        list
    }

    /// Records the settle passes over `list` ([`open_list`](Self::open_list) of `range`, after
    /// the kernel that filled it): V of `receivers` into `v` for the light of `est` (its buffer
    /// `est_buffer`), against the caster triangles of `casters`; receivers left NaN counted in
    /// word `unsettled_word` of `counters`.
    #[allow(clippy::too_many_arguments)]
    pub fn encode(
        &self,
        ctx: &GpuContext,
        enc: &mut wgpu::CommandEncoder,
        (est, est_buffer): (&EstimateUniform, &wgpu::Buffer),
        casters: &GpuScene,
        range: ReceiverRange,
        list: &wgpu::Buffer,
        (receivers, v): (&wgpu::Buffer, &wgpu::Buffer),
        (counters, unsettled_word): (&wgpu::Buffer, u32),
    ) -> Result<()> {
        let max = ctx.limits().max_compute_workgroups_per_dimension.max(1);
        let spans = casters.triangles.div_ceil(SPAN_TRIANGLES);
        let u = SettleUniform {
            triangles: casters.triangles,
            rows: spans.clamp(1, max),
            unsettled_word,
            _pad: 0,
        };
        ctx.write_in(enc, &self.uniform, 0, bytemuck::bytes_of(&u));
        let shape = [est.shape_switch()];
        let boxes = {
            let mut b = self.boxes.lock().unwrap_or_else(|e| e.into_inner());
            let need = box_bytes(casters.triangles);
            if b.size() < need {
                *b = super::kernel::storage_buffer(ctx, "settle boxes", need);
            }
            b.clone()
        };
        let group = self.groups.get_dense(
            ctx,
            LABEL,
            &self.kernel.layout,
            &[
                est_buffer.as_entire_binding(),
                self.uniform.as_entire_binding(),
                casters.vertices.as_entire_binding(),
                range.receivers(receivers),
                range.words(v),
                list.as_entire_binding(),
                counters.as_entire_binding(),
                boxes.as_entire_binding(),
            ],
        );
        let args_group = self.groups.get_dense(
            ctx,
            "settle dispatch",
            &self.args_kernel.layout,
            &[
                self.uniform.as_entire_binding(),
                list.as_entire_binding(),
                self.args.as_entire_binding(),
            ],
        );
        compute_pass(
            enc,
            "settle dispatch",
            &self.args_kernel.pipeline,
            &args_group,
            [1, 1, 1],
        );
        let bound = self.kernel.entry_pipeline(ctx, "settle_boxes", &shape)?;
        compute_pass_indirect_at(enc, "settle boxes", &bound, &group, &self.args, 24);
        let test = self.kernel.entry_pipeline(ctx, "settle_test", &shape)?;
        compute_pass_indirect(enc, "settle test", &test, &group, &self.args);
        let finish = self.kernel.entry_pipeline(ctx, "settle_finish", &shape)?;
        compute_pass_indirect_at(enc, "settle finish", &finish, &group, &self.args, 12);
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::{BLOCK_TRIANGLES, SETTLE_ARGS_CHECK_WGSL, SETTLE_CHECK_WGSL, SPAN_TRIANGLES};
    use test_support::wgsl::u32_constant;

    /// The hierarchy's sizes agree on all three sides: settle.wgsl's runs, blocks and span,
    /// settle_args.wgsl's dispatch and this module's buffer sizes.
    #[test]
    fn hierarchy_sizes_agree_with_the_wgsl() {
        let c = |src, name| u32_constant(src, name).unwrap_or_else(|e| panic!("{e}"));
        let (run, runs, blocks) = (
            c(SETTLE_CHECK_WGSL, "RUN"),
            c(SETTLE_CHECK_WGSL, "RUNS"),
            c(SETTLE_CHECK_WGSL, "BLOCKS"),
        );
        assert_eq!(run * runs, BLOCK_TRIANGLES, "settle.wgsl RUN * RUNS");
        assert_eq!(run * runs * blocks, SPAN_TRIANGLES, "settle.wgsl's span");
        assert_eq!(run, 8, "box_bytes counts a box per run of 8");
        for (name, rust) in [
            ("BLOCK_TRIANGLES", BLOCK_TRIANGLES),
            ("SPAN_TRIANGLES", SPAN_TRIANGLES),
        ] {
            assert_eq!(
                c(SETTLE_ARGS_CHECK_WGSL, name),
                rust,
                "settle_args.wgsl {name}"
            );
        }
    }
}
