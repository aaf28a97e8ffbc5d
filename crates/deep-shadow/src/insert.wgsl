// Deep shadow maps on the engine path, §1.3.1 as the paper does it: the hardware rasteriser
// draws the casters (the core's `vs_main`, raster.wgsl, prepended with shared.wgsl) and each
// fragment of a caster with opacity > 0 inserts (linear z, opacity) into its texel's list
// (Listing 1.2: `atomicAdd` on the counter, `atomicExchange` on the head; past the element
// buffer only the counter moves, and frame.wgsl then marks the frame's receivers cut for the
// caller to redo). Helper invocations write nothing (their stores and atomics have no effect).
// The colour target is the frame's map layer with an empty write mask (a render pass needs one).
// Node and NIL come from node.wgsl, the part before this one.

// The first three words of deep_shadow.wgsl's Counters: elements asked for, lookup steps,
// wraps of the element counter past u32::MAX.
struct InsertCounters {
    count: atomic<u32>,
    steps: atomic<u32>,
    wraps: atomic<u32>,
}

@group(1) @binding(0) var<storage, read_write> ins_head: array<atomic<u32>>;
@group(1) @binding(1) var<storage, read_write> ins_nodes: array<Node>;
@group(1) @binding(2) var<storage, read_write> ins_counters: InsertCounters;

@fragment
fn fs_insert(in: VsOut) -> @location(0) f32 {
    // raster.rs prepare drops fully transparent casters: they change no transmittance.
    if (in.opacity > 0.0 && abs(in.z) <= 3.40282347e38) {
        let texel = u32(in.clip.y) * view.r + u32(in.clip.x);
        let e = atomicAdd(&ins_counters.count, 1u);
        if (e == 0xffffffffu) { atomicAdd(&ins_counters.wraps, 1u); }
        if (e < arrayLength(&ins_nodes)) {
            ins_nodes[e] = Node(in.z, in.opacity, 1.0, atomicExchange(&ins_head[texel], e),
                                NIL, NIL, NIL, 0u);
        }
    }
    return in.z;
}
