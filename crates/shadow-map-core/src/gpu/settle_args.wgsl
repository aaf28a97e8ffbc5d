// The indirect dispatches of settle.wgsl's two passes over a range's open list, from its count
// (a module of its own: the dispatch buffer is written here and read as INDIRECT there, which
// one usage scope cannot hold). Prepended: settle_uniform.wgsl.

override WG: u32;

@group(0) @binding(0) var<uniform> settle: SettleUniform;
@group(0) @binding(1) var<storage, read> open_list: array<u32>;
// (x, y, z) of settle_test, of settle_finish, of settle_boxes.
@group(0) @binding(2) var<storage, read_write> dispatch: array<u32, 9>;

// settle.wgsl's RUN * RUNS and RUN * RUNS * BLOCKS.
const BLOCK_TRIANGLES: u32 = 64u;
const SPAN_TRIANGLES: u32 = 256u;

@compute @workgroup_size(1)
fn settle_args() {
    let n = open_list[0];
    let groups = (n + WG - 1u) / WG;
    let spans = (settle.triangles + SPAN_TRIANGLES - 1u) / SPAN_TRIANGLES;
    let blocks = (settle.triangles + BLOCK_TRIANGLES - 1u) / BLOCK_TRIANGLES;
    let rows = max(settle.rows, 1u);
    // No casters: nothing to test, every open receiver settles (settle_finish).
    let testing = select(0u, 1u, n > 0u && spans > 0u);
    dispatch[0] = groups * testing;
    dispatch[1] = rows;
    dispatch[2] = max((spans + rows - 1u) / rows, 1u);
    dispatch[3] = groups;
    dispatch[4] = 1u;
    dispatch[5] = 1u;
    dispatch[6] = ((blocks + WG - 1u) / WG) * testing;
    dispatch[7] = 1u;
    dispatch[8] = 1u;
}
