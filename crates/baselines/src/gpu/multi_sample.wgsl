// Twin of crates/baselines/src/cpu/multi_sample.rs (Heckbert & Herf 1997, docs/methods.md §6):
// `accumulate` adds one sub-light's hard test into a per-receiver count, once per sub-light map;
// `finalize` divides by the number of sub-lights and applies the one-sided rule. Both run over the
// active list (inactive receivers hold V = NaN from the compaction).
// The view uniform is the sub-light's: its origin is the light point y_k (world), bit for bit
// the CPU's `frame.to_world(y.extend(0.0))`.

@group(0) @binding(0) var<uniform> view: LightViewUniform;
@group(0) @binding(1) var<uniform> est: EstimateUniform;
// Binding 2, the sub-light's shadow map, and `fn depth_texel(i, j) -> f32` come from
// depth_f32.wgsl or depth_unorm16.wgsl (the `depth` parameter).
@group(0) @binding(3) var<storage, read> receivers: array<ReceiverGpu>;
// Per receiver: how many sub-lights so far light it (exact small integers in f32, as on the CPU).
@group(0) @binding(4) var<storage, read_write> acc: array<f32>;
// V per receiver as f32 bits (written by `finalize`).
@group(0) @binding(5) var<storage, read_write> v_out: array<u32>;
// The range's active list (the core's receivers::ActiveLists, active.wgsl): inactive receivers
// already hold V = NaN.
@group(0) @binding(6) var<storage, read> active_list: array<u32>;


// No caster at texel (i, j) (ReceiverPlane::caster), texels outside the map +inf (always lit).
fn lit_at(rp: ReceiverPlane, i: i32, j: i32) -> bool {
    let r = i32(view.r);
    if i < 0 || j < 0 || i >= r || j >= r {
        return true;
    }
    return !plane_caster(rp, i, j, depth_texel(i, j));
}

@compute @workgroup_size(WG)
fn accumulate(@builtin(global_invocation_id) gid: vec3<u32>) {
    let k = listed_receiver(gid.x);
    if k == NONE_LISTED {
        return;
    }
    let rec = receivers[k];
    let pw = rec.position;
    let nw = rec.normal;
    // The sun: the sub-light is a direction, the view's e_z (orthographic).
    var towards = view.frame.origin - pw;
    if view.ortho != 0u {
        towards = -view.frame.ez;
    }
    if dot3(nw, towards) <= 0.0 {
        return; // the sample is behind the receiver's tangent plane
    }
    let p = view_to_light(view, pw);
    if p.z <= 0.0 {
        return; // behind this light point: no light from it
    }
    if p.z <= view.n {
        acc[k] += 1.0;
        return;
    }
    let uv = project(view, p);
    if !view_contains(view, uv) {
        acc[k] += 1.0;
        return;
    }
    let n = view_dir_to_light(view, nw);
    // Half a code step more under depth=unorm16 (depth_step = 0 for f32 maps).
    let rp = plane_new(est.receiver_plane != 0u, view, p, n, est.bias, est.slope_bias, 0.5 * est.depth_step);
    if lit_at(rp, i32(floor(uv.x)), i32(floor(uv.y))) {
        acc[k] += 1.0;
    }
}

@compute @workgroup_size(WG)
fn finalize(@builtin(global_invocation_id) gid: vec3<u32>) {
    let k = listed_receiver(gid.x);
    if k == NONE_LISTED {
        return;
    }
    let rec = receivers[k];
    let pl = frame_to_light(est.light_frame, rec.position);
    if est.light_one_sided != 0u && pl.z <= 0.0 {
        v_out[k] = 0u;
        return;
    }
    v_out[k] = bitcast<u32>(clamp(acc[k] * est.inv_samples, 0.0, 1.0));
}
