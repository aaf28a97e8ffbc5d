//! Active lists (`gpu::receivers::ActiveLists`), the compaction every per-receiver frame kernel
//! runs over: each range's list holds each of its active receivers once, in slot order (indices
//! within the range; the same order every frame, so a SIMD batch meets the same receivers), its
//! head is the indirect dispatch of one invocation per listed receiver, inactive
//! slots get V = NaN and active ones are left for the kernel. Two ranges of one frame keep two
//! lists alive at once, and a list grows with its range from frame to frame. The deferred list
//! of a range holds the receivers a first pass left `DEFER_BITS` in V, and leaves V as it is;
//! listed for a wide pass, it holds the same receivers and dispatches a workgroup for each.
#![cfg(feature = "gpu")]

use crate::common;

use shadow_map_core::{
    gpu::{
        estimate::WORKGROUP_SIZE,
        frame::ReceiverRange,
        kernel::buffer_init,
        receivers::{
            ActiveLists,
            ListKind::{Active, Deferred, DeferredWide},
            ACTIVE_HEAD_WORDS,
        },
        shared::ReceiverGpu,
    },
    Error,
};

/// V's value before the frame: what an active slot keeps (the kernel writes it).
const UNWRITTEN: u32 = 0x1234_5678;

/// `shared.wgsl`'s `DEFER_BITS`: what a first pass leaves for the second.
const DEFER_BITS: u32 = 0x7fc0_defe;

/// Receivers whose two ranges each defer more than 65,535 (`first_pass`, `receivers`).
const TWO_ROWS: u32 = 700_000;

/// V as a first pass left it: every third active receiver deferred.
fn first_pass(recs: &[ReceiverGpu]) -> Vec<u32> {
    (0..recs.len())
        .map(|k| match recs[k].active != 0 && k % 3 == 0 {
            true => DEFER_BITS,
            false => UNWRITTEN,
        })
        .collect()
}

/// `n` receivers, active in an irregular pattern with a long inactive run (the sky), or none.
fn receivers(n: u32, none_active: bool) -> Vec<ReceiverGpu> {
    (0..n)
        .map(|k| ReceiverGpu {
            position: [k as f32, 0.0, 1.0],
            active: u32::from(
                !none_active && !(1000..1600).contains(&k) && (k.wrapping_mul(7919) % 13 > 3),
            ),
            normal: [0.0, 1.0, 0.0],
            _pad0: 0.0,
        })
        .collect()
}

#[test]
fn active_lists_hold_each_active_receiver_once() -> Result<(), Error> {
    let Some(ctx) = common::context_for_tests("active_lists_hold_each_active_receiver_once")?
    else {
        return Ok(());
    };
    let lists = ActiveLists::new(&ctx)?;
    for (n, none_active) in [
        (1, false),
        (7, false),
        (64, true),
        (517, false),
        (10_000, false),
        // More than 65,535 deferred in each range: a wide dispatch of two rows.
        (TWO_ROWS, false),
    ] {
        let recs = receivers(n, none_active);
        let storage = wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC;
        let rb = buffer_init(
            &ctx.device,
            "receivers",
            bytemuck::cast_slice(&recs),
            storage,
        );
        let v0 = first_pass(&recs);
        let v = buffer_init(&ctx.device, "V", bytemuck::cast_slice(&v0), storage);
        // Two ranges where the receivers hold more than one whole run of workgroups.
        let split = n / 2 / WORKGROUP_SIZE * WORKGROUP_SIZE;
        let ranges: Vec<ReceiverRange> = if split == 0 {
            vec![ReceiverRange { first: 0, count: n }]
        } else {
            vec![
                ReceiverRange {
                    first: 0,
                    count: split,
                },
                ReceiverRange {
                    first: split,
                    count: n - split,
                },
            ]
        };
        let mut enc = ctx.device.create_command_encoder(&Default::default());
        let listed = ranges
            .iter()
            .enumerate()
            .map(|(index, &range)| {
                let active = lists.encode(&ctx, &mut enc, Active, index, range, &rb, &v)?;
                // The deferred list with a workgroup per receiver, copied before the deferred
                // list, which shares its buffer, is made again.
                let wide = lists.encode(&ctx, &mut enc, DeferredWide, index, range, &rb, &v)?;
                let wide_copy = ctx.device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some("wide list copy"),
                    size: wide.size(),
                    usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::COPY_SRC,
                    mapped_at_creation: false,
                });
                enc.copy_buffer_to_buffer(&wide, 0, &wide_copy, 0, wide.size());
                let deferred = lists.encode(&ctx, &mut enc, Deferred, index, range, &rb, &v)?;
                Ok((active, deferred, wide_copy))
            })
            .collect::<Result<Vec<_>, Error>>()?;
        ctx.queue.submit([enc.finish()]);
        let bits: Vec<u32> = ctx.read_buffer(&v, 4 * n as u64)?;
        for (range, (active, deferred, wide)) in ranges.iter().zip(&listed) {
            // The wide list: the deferred receivers, a workgroup each.
            let words: Vec<u32> = ctx.read_buffer(wide, wide.size())?;
            let deferred_words: Vec<u32> = ctx.read_buffer(deferred, deferred.size())?;
            let count = words[3];
            assert_eq!(
                count, deferred_words[3],
                "{n} receivers: the wide list's count"
            );
            assert!(
                n != TWO_ROWS || count > 65_535,
                "{n} receivers: {count} deferred"
            );
            assert_eq!(
                &words[ACTIVE_HEAD_WORDS as usize..][..count as usize],
                &deferred_words[ACTIVE_HEAD_WORDS as usize..][..count as usize],
                "{n} receivers: the wide list"
            );
            assert_eq!(
                &words[..3],
                &[count.min(65_535), count.div_ceil(65_535), 1],
                "{n} receivers: the wide list's dispatch"
            );
            let slots = range.first..range.first + range.count;
            for (list, what, want) in [
                (
                    active,
                    "active",
                    slots
                        .clone()
                        .filter(|&k| recs[k as usize].active != 0)
                        .collect::<Vec<u32>>(),
                ),
                (
                    deferred,
                    "deferred",
                    slots
                        .clone()
                        .filter(|&k| v0[k as usize] == DEFER_BITS)
                        .collect(),
                ),
            ] {
                let words: Vec<u32> = ctx.read_buffer(list, list.size())?;
                let count = words[3];
                let got: Vec<u32> = words[ACTIVE_HEAD_WORDS as usize..][..count as usize]
                    .iter()
                    .map(|i| range.first + i)
                    .collect();
                assert_eq!(got, want, "{n} receivers, range {range:?}: the {what} list");
                assert_eq!(
                    &words[..3],
                    &[count.div_ceil(WORKGROUP_SIZE), 1, 1],
                    "{n} receivers: the {what} list's dispatch"
                );
            }
        }
        for (k, (r, b)) in recs.iter().zip(&bits).enumerate() {
            if r.active != 0 {
                assert_eq!(*b, v0[k], "{n} receivers: active slot {k} written");
            } else {
                assert!(
                    f32::from_bits(*b).is_nan(),
                    "{n} receivers: inactive slot {k} not NaN"
                );
            }
        }
    }
    Ok(())
}
