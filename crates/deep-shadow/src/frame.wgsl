// Deep shadow maps on the engine path (gpu.rs, DeepShadowFrame). Opaque casters: the caster
// map of each sub-light view comes from the core's raster pass (an R32Float layer, +inf where
// empty); its depths go into head[] as the opaque path's bits (`frame_head`). Semi-transparent
// casters (F.lists): insert.wgsl builds the lists, deep_shadow.wgsl's `clear`, `process` and
// `link` finish them, and the lookup walks them (`list_transmittance`). Each receiver's query is
// made here from the caller's receiver buffer, the twin of cpu.rs `query` (`frame_lookup`, which
// adds the view's transmittance into acc); `frame_finish` writes V, the twin of cpu.rs `finish`.
// Appended after the core's shared.wgsl, estimate.wgsl, math.wgsl and cells.wgsl, node.wgsl and
// deep_shadow.wgsl (bindings 0, 3, 4 and 5).

// Mirrors gpu.rs DsFrameUniform field for field.
struct DsFrameUniform {
    bias: f32,
    slope_bias: f32,
    receiver_plane: u32,
    pcss: u32,
    inv_views: f32,
    lists: u32,
    _pad0: u32,
    _pad1: u32,
}

@group(0) @binding(8) var<uniform> fview: LightViewUniform;
// The view's light (cpu.rs view_light) in frame_lookup, the scene's light in frame_finish.
@group(0) @binding(9) var<uniform> flight: EstimateUniform;
@group(0) @binding(10) var depth_map: texture_2d<f32>;
// Bindings 11 to 13 hold one range of the frame's receivers (gpu.rs ReceiverRange).
@group(0) @binding(11) var<storage, read> receivers: array<ReceiverGpu>;
@group(0) @binding(12) var<storage, read_write> acc: array<f32>;
@group(0) @binding(13) var<storage, read_write> v_out: array<u32>;
// [0]: receivers looked up outside some view's map (each once); [1]: non-finite V; [2]: cut
// receivers; [3]: of [0], those the settle passes left NaN (gpu::settle).
@group(0) @binding(14) var<storage, read_write> status: array<atomic<u32>, 4>;
@group(0) @binding(15) var<uniform> F: DsFrameUniform;
// The range's active list (the core's receivers::ActiveLists, active.wgsl): frame_lookup and
// frame_finish run one invocation per listed receiver; inactive ones already hold V = NaN.
@group(0) @binding(16) var<storage, read> active_list: array<u32>;
// The range's open list (the core's gpu::settle): receivers no view's map holds, settled after
// frame_finish as the CPU's settle_outside settles them.
@group(0) @binding(17) var<storage, read_write> open_list: array<atomic<u32>>;

// The map's depth at texel t as the opaque path's head: its bits, NIL where empty.
@compute @workgroup_size(WG)
fn frame_head(@builtin(workgroup_id) wid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>,
              @builtin(local_invocation_id) lid: vec3<u32>) {
    let t = linear_id(wid, nwg, lid);
    if (t >= P.r * P.r) { return; }
    let z = textureLoad(depth_map, vec2<i32>(i32(t % P.r), i32(t / P.r)), 0).x;
    atomicStore(&head[t], select(NIL, bitcast<u32>(z), is_finite(z)));
}

// cpu.rs facing: 1 or 0 by the side of the tangent plane the view's point (the sun: -e_z) lies
// on; under filter=pcss the fraction of the view's light in front of it.
fn frame_facing(pw: vec3<f32>, nw: vec3<f32>) -> f32 {
    if (F.pcss != 0u) {
        return front_fraction_world(flight, pw, nw);
    }
    var towards = fview.frame.origin - pw;
    if (fview.ortho != 0u) {
        towards = -fview.frame.ez;
    }
    return select(0.0, 1.0, dot3(nw, towards) > 0.0);
}

// cpu.rs query, packed as deep_shadow.wgsl reads a query: (u, v, z_p, fixed) and the caster test.
fn frame_query(pw: vec3<f32>, nw: vec3<f32>) -> array<vec4<f32>, 2> {
    var q = array<vec4<f32>, 2>(vec4<f32>(0.0), vec4<f32>(0.0));
    let facing = frame_facing(pw, nw);
    if (!(facing > 0.0)) { return q; }
    let p = view_to_light(fview, pw);
    if (!(p.z > 0.0)) { return q; }
    if (p.z <= fview.n) {
        q[0].w = facing;
        return q;
    }
    let n = view_dir_to_light(fview, nw);
    let uv = project(fview, p);
    let rp = plane_new(F.receiver_plane != 0u, fview, p, n, F.bias, F.slope_bias, 0.0);
    q[0] = vec4<f32>(uv, rp.zp, -facing);
    if (fview.ortho != 0u) {
        q[1] = vec4<f32>(rp.g0, rp.cu, rp.cv, rp.c);
    } else {
        q[1] = vec4<f32>(rp.g0, rp.gu, rp.gv, rp.c);
    }
    return q;
}

// Whether the frame's casters are in lists (`F.lists`, a pipeline override of `frame_lookup`).
override DS_LISTS: bool = false;

// One receiver per invocation: its transmittance in this view, added into acc.
@compute @workgroup_size(WG)
fn frame_lookup(@builtin(workgroup_id) wid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>,
                @builtin(local_invocation_id) lid: vec3<u32>) {
    let k = listed_receiver(linear_id(wid, nwg, lid));
    if (k == NONE_LISTED) { return; }
    // Cut short in an earlier view: stays cut. Outside an earlier view's map: settled at the end.
    if (bitcast<u32>(acc[k]) == CUT_BITS || bitcast<u32>(acc[k]) == OPEN_BITS) { return; }
    let q = frame_query(receivers[k].position, receivers[k].normal);
    // Looked up (fixed < 0) outside the map: no map holds its casters (cpu.rs mark_outside).
    if (q[0].w < 0.0 && !view_contains(fview, q[0].xy)) {
        acc[k] = bitcast<f32>(OPEN_BITS);
        atomicAdd(&status[0], 1u);
        leave_open(k);
        return;
    }
    var t: f32;
    if (DS_LISTS) {
        // Lists short of fragments (the element buffer full, the counter wrapped) or left
        // unsorted (process or link cut by the loop budget): V left NaN and counted, for the
        // caller to redo.
        if (atomicLoad(&counters.count) > P.capacity || atomicLoad(&counters.wraps) != 0u
            || atomicLoad(&counters.cut) != 0u) {
            acc[k] = bitcast<f32>(CUT_BITS);
            atomicAdd(&status[2], 1u);
            return;
        }
        t = list_transmittance(q[0], q[1]);
    } else {
        t = opaque_transmittance(q[0], q[1]);
    }
    // Out of the device's loop budget (shared.wgsl): marked, counted, V left NaN by frame_finish.
    if (loop_limit_hit(P.probe)) {
        acc[k] = bitcast<f32>(CUT_BITS);
        atomicAdd(&status[2], 1u);
        return;
    }
    acc[k] += t;
}

// cpu.rs finish: V = acc / views clamped to [0, 1] (inactive receivers hold NaN from the compaction; 0 behind a
// one-sided light); a non-finite V is written as 0 and counted.
@compute @workgroup_size(WG)
fn frame_finish(@builtin(workgroup_id) wid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>,
                @builtin(local_invocation_id) lid: vec3<u32>) {
    let k = listed_receiver(linear_id(wid, nwg, lid));
    if (k == NONE_LISTED) { return; }
    if (flight.light_one_sided != 0u && frame_to_light(flight.light_frame, receivers[k].position).z <= 0.0) {
        v_out[k] = 0u;
        return;
    }
    if (bitcast<u32>(acc[k]) == CUT_BITS || bitcast<u32>(acc[k]) == OPEN_BITS) {
        v_out[k] = NAN_BITS;
        return;
    }
    let x = acc[k] * F.inv_views;
    if (is_finite(x)) {
        v_out[k] = bitcast<u32>(clamp(x, 0.0, 1.0));
    } else {
        v_out[k] = 0u;
        atomicAdd(&status[1], 1u);
    }
}
