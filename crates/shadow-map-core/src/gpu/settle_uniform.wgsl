// Mirrors gpu::settle::SettleUniform (tests/layouts.rs checks it with naga): read by
// settle.wgsl and settle_args.wgsl.
struct SettleUniform {
    // Caster triangles (three vec4 each in `casters`).
    triangles: u32,
    // Workgroup rows of `settle_test` (its y dispatch): span of triangles = y + z * rows.
    rows: u32,
    // The word of `counters` that counts receivers left NaN (something may shadow them).
    unsettled_word: u32,
    _pad: u32,
}
