// The per-receiver estimate entry point every such kernel shares (the CPU's
// `Receivers::estimate_each`), with its tail. The including shader declares
// `receivers: array<ReceiverGpu>`, `v_out: array<u32>` (V as f32 bits),
// `counters: array<atomic<u32>, N>` with N >= 3 (`counters[1]`: non-finite results,
// `counters[2]`: receivers cut by the loop budget), `active_list: array<u32>` (the range's active
// list, compact.wgsl: inactive receivers already hold V = NaN; active.wgsl reads it, prepended),
// `fn estimate_receiver(p: vec3<f32>,
// n: vec3<f32>) -> f32` (V of one receiver; -1: a lit receiver left NaN for the host, counted by the
// method; -2: deferred to the kernel's second pass over ActiveLists::encode_deferred's list) and `fn receiver_probe() -> u32` (its uniform's loop-budget probe).

// The receiver estimate_receiver is estimating, for a method that lists it (gpu::settle's
// leave_open).
var<private> current_receiver: u32;

// V = x clamped to [0, 1] into slot k; a non-finite x is written as 0 and counted in counters[1].
fn store_v(k: u32, x: f32) {
    if is_finite(x) {
        v_out[k] = bitcast<u32>(clamp(x, 0.0, 1.0));
    } else {
        v_out[k] = 0u;
        atomicAdd(&counters[1], 1u);
    }
}

// One invocation per slot of the range instead, for a kernel whose work per receiver is about
// what listing it costs (a frame that makes no active list; `active_list` bound but unread):
// inactive receivers NaN, the others as `estimate`.
@compute @workgroup_size(WG)
fn estimate_slots(@builtin(global_invocation_id) gid: vec3<u32>) {
    let k = gid.x;
    if k >= arrayLength(&receivers) {
        return;
    }
    if receivers[k].is_active == 0u {
        v_out[k] = NAN_BITS;
        return;
    }
    estimate_one(k);
}

// One invocation per listed receiver of the range's active list.
@compute @workgroup_size(WG)
fn estimate(@builtin(global_invocation_id) gid: vec3<u32>) {
    let k = listed_receiver(gid.x);
    if k != NONE_LISTED {
        estimate_one(k);
    }
}

// Receiver k's V into its slot (the tail of both entry points): V stored (clamped, non-finite as
// 0), V of -2 or less DEFER_BITS (left for the second pass), of -1 or less (a lit receiver the
// method leaves to the host) NaN, and a receiver whose work ran out of the device's loop budget
// (shared.wgsl's two-trip probe) flagged CUT_BITS and counted in counters[2], for the host to
// redo.
fn estimate_one(k: u32) {
    current_receiver = k;
    let x = estimate_receiver(receivers[k].position, receivers[k].normal);
    if loop_limit_hit(receiver_probe()) {
        v_out[k] = CUT_BITS;
        atomicAdd(&counters[2], 1u);
        return;
    }
    // A NaN test here could be folded away by a finite-math compiler: hence the sentinels.
    if x <= -2.0 {
        v_out[k] = DEFER_BITS;
    } else if x <= -1.0 {
        v_out[k] = NAN_BITS;
    } else {
        store_v(k, x);
    }
}
