// The head and tail every per-receiver estimate entry point shares (the CPU's
// `for_each_receiver`). The including shader declares `receivers: array<ReceiverGpu>`,
// `v_out: array<u32>` (V as f32 bits) and `counters: array<atomic<u32>, N>` with N >= 2
// (`counters[1]`: non-finite results).

// Whether slot k holds an active receiver; an inactive one is given V = NaN.
fn active_receiver(k: u32) -> bool {
    if k >= arrayLength(&receivers) {
        return false;
    }
    if receivers[k].is_active == 0u {
        v_out[k] = NAN_BITS;
        return false;
    }
    return true;
}

// V = x clamped to [0, 1] into slot k; a non-finite x is written as 0 and counted in counters[1].
fn store_v(k: u32, x: f32) {
    if is_finite(x) {
        v_out[k] = bitcast<u32>(clamp(x, 0.0, 1.0));
    } else {
        v_out[k] = 0u;
        atomicAdd(&counters[1], 1u);
    }
}
