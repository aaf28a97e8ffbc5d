// The active receivers of one receiver range, listed (receivers::ActiveLists), so that a
// per-receiver kernel runs one invocation per receiver it estimates and none for the sky or for
// other inactive slots: a lane-predicated device (lavapipe) pays a whole kernel for an inactive
// lane as for an active one, and a GPU leaves it idle. Prepended by shared.wgsl.
//
// The list, in words: 0..3 the indirect dispatch of the kernel that reads it (x, y, 1), 3 the
// count, then from word 4 the indices (within the range) of the listed receivers in slot order,
// then per workgroup of `count_runs` its first place in the list, then per invocation its run's
// bits. Three passes make the order the slots' own on every device, so a kernel's lanes (and a
// loop budget shared by a SIMD batch of them) see the same receivers every frame.

override WG: u32;

// Receivers one invocation compacts, a run of consecutive slots (receivers::COMPACT_RUN, at most
// 32: one bit each).
override RUN: u32;

// Whether the list is of the receivers a first pass deferred (V = DEFER_BITS) rather than of the
// active ones; it leaves V as it is.
override DEFERRED: bool = false;

// Whether the kernel reading the list takes a whole workgroup per listed receiver (a wide pass
// over a long tail): the dispatch is then (min(count, MAX_GROUPS), ceil(count / MAX_GROUPS), 1)
// workgroups instead of (ceil(count / WG), 1, 1), and workgroup (x, y) takes item x + y MAX_GROUPS.
override PER_RECEIVER_GROUP: bool = false;
// Workgroups per dimension of a dispatch (wgpu's default maxComputeWorkgroupsPerDimension).
const MAX_GROUPS: u32 = 65535u;

struct ActiveList {
    x: u32,
    y: u32,
    z: u32,
    count: u32,
    words: array<u32>,
}

@group(0) @binding(0) var<storage, read> receivers: array<ReceiverGpu>;
@group(0) @binding(1) var<storage, read_write> v_out: array<u32>;
@group(0) @binding(2) var<storage, read_write> list: ActiveList;

var<workgroup> group_count: atomic<u32>;
var<workgroup> lane_counts: array<u32, WG>;
var<workgroup> chunk_bases: array<u32, WG>;

// Workgroups of the passes over the slots.
fn slot_groups() -> u32 {
    return (arrayLength(&receivers) + WG * RUN - 1u) / (WG * RUN);
}

// Word of workgroup g's place (after the indices), and of invocation t's run bits.
fn group_word(g: u32) -> u32 {
    return arrayLength(&receivers) + g;
}

fn bits_word(t: u32) -> u32 {
    return arrayLength(&receivers) + slot_groups() + t;
}

// Pass 1, one invocation per run of slots: an inactive receiver's V is NaN (as the CPU's); the
// run's listed slots as bits, and the workgroup's count.
@compute @workgroup_size(WG)
fn count_runs(@builtin(global_invocation_id) gid: vec3<u32>,
              @builtin(workgroup_id) wid: vec3<u32>,
              @builtin(local_invocation_index) lane: u32) {
    let first = gid.x * RUN;
    let slots = arrayLength(&receivers);
    var bits = 0u;
    for (var i = 0u; i < RUN; i++) {
        let k = first + i;
        if k < slots {
            if DEFERRED {
                if v_out[k] == DEFER_BITS {
                    bits |= 1u << i;
                }
            } else if receivers[k].is_active != 0u {
                bits |= 1u << i;
            } else {
                v_out[k] = NAN_BITS;
            }
        }
    }
    list.words[bits_word(gid.x)] = bits;
    atomicAdd(&group_count, countOneBits(bits));
    workgroupBarrier();
    if lane == 0u {
        list.words[group_word(wid.x)] = atomicLoad(&group_count);
    }
}

// Pass 2, one workgroup: each workgroup's count replaced by its first place (an exclusive
// scan, WG chunks in parallel), the total and the dispatch.
@compute @workgroup_size(WG)
fn scan_groups(@builtin(local_invocation_index) lane: u32) {
    let groups = slot_groups();
    let per = (groups + WG - 1u) / WG;
    let g0 = min(lane * per, groups);
    let g1 = min(g0 + per, groups);
    var sum = 0u;
    for (var g = g0; g < g1; g++) {
        sum += list.words[group_word(g)];
    }
    lane_counts[lane] = sum;
    workgroupBarrier();
    if lane == 0u {
        var run = 0u;
        for (var l = 0u; l < WG; l++) {
            chunk_bases[l] = run;
            run += lane_counts[l];
        }
        list.count = run;
        if PER_RECEIVER_GROUP {
            list.x = min(run, MAX_GROUPS);
            list.y = (run + MAX_GROUPS - 1u) / MAX_GROUPS;
        } else {
            list.x = (run + WG - 1u) / WG;
            list.y = 1u;
        }
        list.z = 1u;
    }
    workgroupBarrier();
    var at = chunk_bases[lane];
    for (var g = g0; g < g1; g++) {
        let c = list.words[group_word(g)];
        list.words[group_word(g)] = at;
        at += c;
    }
}

// Pass 3, one invocation per run of slots: the run's listed slots at their places, in order.
@compute @workgroup_size(WG)
fn place_runs(@builtin(global_invocation_id) gid: vec3<u32>,
              @builtin(workgroup_id) wid: vec3<u32>,
              @builtin(local_invocation_index) lane: u32) {
    let bits = list.words[bits_word(gid.x)];
    lane_counts[lane] = countOneBits(bits);
    workgroupBarrier();
    var at = list.words[group_word(wid.x)];
    for (var l = 0u; l < lane; l++) {
        at += lane_counts[l];
    }
    let first = gid.x * RUN;
    for (var i = 0u; i < RUN; i++) {
        if (bits & (1u << i)) != 0u {
            list.words[at] = first + i;
            at += 1u;
        }
    }
}
