// The active receivers of one receiver range, listed (receivers::ActiveLists), so that a
// per-receiver kernel runs one invocation per receiver it estimates and none for the sky or for
// other inactive slots: a lane-predicated device (lavapipe) pays a whole kernel for an inactive
// lane as for an active one, and a GPU leaves it idle. Prepended by shared.wgsl.
//
// The list: words 0..3 the indirect dispatch of the kernel that reads it (x, 1, 1), word 3 the
// count, then the indices (within the range) of the active receivers, in no particular order.

override WG: u32;

struct ActiveList {
    x: u32,
    y: u32,
    z: u32,
    count: atomic<u32>,
    indices: array<u32>,
}

@group(0) @binding(0) var<storage, read> receivers: array<ReceiverGpu>;
@group(0) @binding(1) var<storage, read_write> v_out: array<u32>;
@group(0) @binding(2) var<storage, read_write> list: ActiveList;

var<workgroup> group_count: atomic<u32>;
var<workgroup> group_base: u32;

// Receivers one invocation compacts, a run of consecutive slots (receivers::COMPACT_RUN): the
// list keeps the slots' order within a run, and the barriers are paid once per run.
override RUN: u32;

// One invocation per run of slots: an inactive receiver's V is NaN (as the CPU's); the run's
// active ones take consecutive places in its workgroup's part of the list, which one atomic per
// workgroup places.
@compute @workgroup_size(WG)
fn compact(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(local_invocation_index) lane: u32) {
    let first = gid.x * RUN;
    let slots = arrayLength(&receivers);
    var bits = 0u;
    var count = 0u;
    for (var i = 0u; i < RUN; i++) {
        let k = first + i;
        if k < slots {
            if receivers[k].is_active != 0u {
                bits |= 1u << i;
                count += 1u;
            } else {
                v_out[k] = NAN_BITS;
            }
        }
    }
    var place = 0u;
    if count > 0u {
        place = atomicAdd(&group_count, count);
    }
    workgroupBarrier();
    if lane == 0u {
        group_base = atomicAdd(&list.count, atomicLoad(&group_count));
    }
    var at = workgroupUniformLoad(&group_base) + place;
    for (var i = 0u; i < RUN; i++) {
        if (bits & (1u << i)) != 0u {
            list.indices[at] = first + i;
            at += 1u;
        }
    }
}

// The dispatch of one invocation per listed receiver.
@compute @workgroup_size(1)
fn dispatch_args() {
    list.x = (atomicLoad(&list.count) + WG - 1u) / WG;
    list.y = 1u;
    list.z = 1u;
}
