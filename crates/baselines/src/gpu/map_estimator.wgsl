// Twin of crates/baselines/src/cpu/map_estimator.rs: one shadow map at the light centre, filtered per
// receiver. The filter file appended after this one defines
//   fn facing(p_world: vec3<f32>, n_world: vec3<f32>) -> f32      (Filter::facing)
//   fn visibility(r: ReceiverSample) -> f32                        (Filter::visibility)
// One invocation per receiver bound at `receivers`.

@group(0) @binding(0) var<uniform> view: LightViewUniform;
@group(0) @binding(1) var<uniform> est: EstimateUniform;
// Binding 2, layer 0 of the light-space data, and `fn depth_texel(i, j) -> f32` come from
// depth_f32.wgsl or depth_unorm16.wgsl (the `depth` parameter).
@group(0) @binding(3) var<storage, read> receivers: array<ReceiverGpu>;
// V per receiver as f32 bits (NaN for inactive receivers is written as bits, never computed).
@group(0) @binding(4) var<storage, read_write> v_out: array<u32>;
// [0]: receivers outside the light frustum (the CPU's `outside`), [1]: non-finite results,
// [2]: receivers cut short by the device's loop limit (written as CUT_BITS, redone on the CPU).
@group(0) @binding(5) var<storage, read_write> counters: array<atomic<u32>, 3>;
// The range's active list (the core's receivers::ActiveLists), read by the core's entry point.
@group(0) @binding(6) var<storage, read> active_list: array<u32>;


// map_estimator::ReceiverSample.
struct ReceiverSample {
    p: vec3<f32>,
    n: vec3<f32>,
    uv: vec2<f32>,
    plane: ReceiverPlane,
}

// ReceiverSample::caster on DepthMap::at(i, j), with texels outside the map +inf (never casters).
fn caster(r: ReceiverSample, i: i32, j: i32) -> bool {
    let size = i32(view.r);
    if i < 0 || j < 0 || i >= size || j >= size {
        return false;
    }
    return plane_caster(r.plane, i, j, depth_texel(i, j));
}

// DepthMap::at for a texel inside the map.
fn depth_at(i: i32, j: i32) -> f32 {
    return depth_texel(i, j);
}

// map_estimator::lit: 1 when the sample at (i, j) does not shadow the receiver r.
fn lit(i: i32, j: i32, r: ReceiverSample) -> f32 {
    return select(1.0, 0.0, caster(r, i, j));
}

// `Cells`, `cell` and the Kahan `Sum` come from cells.wgsl (an earlier part).

// Where a receiver stands before the filter (`Prepared::kind`): facing away (V 0), nearer than
// the map's near plane (V the facing fraction; counted as outside when behind the light's plane),
// outside the map's window (the facing fraction, counted), or sampled for the filter.
const AWAY: u32 = 0u;
const NEAR: u32 = 1u;
const BEHIND: u32 = 2u;
const OUTSIDE: u32 = 3u;
const SAMPLED: u32 = 4u;

struct Prepared {
    kind: u32,
    fac: f32,
    s: ReceiverSample,
}

// The frame of MapEstimator::estimate for one active receiver up to the filter: tangent-plane
// factor, light-space transform, the near-plane and out-of-frustum rules, the receiver bias.
fn prepare(pw: vec3<f32>, nw: vec3<f32>) -> Prepared {
    var none: ReceiverSample;
    let fac = facing(pw, nw);
    if fac <= 0.0 {
        return Prepared(AWAY, 0.0, none);
    }
    let p = view_to_light(view, pw);
    let n = view_dir_to_light(view, nw);
    if p.z <= view.n {
        // Nearer than anything the map records (or behind a sphere light's frustum).
        return Prepared(select(NEAR, BEHIND, p.z <= 0.0), fac, none);
    }
    let uv = project(view, p);
    if !view_contains(view, uv) {
        return Prepared(OUTSIDE, fac, none);
    }
    // Half a code step more under depth=unorm16 (depth_step = 0 for f32 maps).
    let plane = plane_new(est.receiver_plane != 0u, view, p, n, est.bias, est.slope_bias, 0.5 * est.depth_step);
    return Prepared(SAMPLED, fac, ReceiverSample(p, n, uv, plane));
}

// MapEstimator::estimate for one active receiver: `prepare`, the receivers outside the frustum
// counted, then the filter (a filter's -2, deferred to its wide pass, passed on).
fn estimate_receiver(pw: vec3<f32>, nw: vec3<f32>) -> f32 {
    let r = prepare(pw, nw);
    if r.kind == BEHIND || r.kind == OUTSIDE {
        atomicAdd(&counters[0], 1u);
    }
    if r.kind != SAMPLED {
        return r.fac;
    }
    let vis = visibility(r.s);
    if vis <= -2.0 {
        return vis;
    }
    return r.fac * vis;
}

// The entry point is the core's (receivers.wgsl); its loop-budget probe is this uniform's.
fn receiver_probe() -> u32 {
    return est.probe;
}
