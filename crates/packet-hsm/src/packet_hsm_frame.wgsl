// Packet-hsm on the engine path (frame.rs, PacketHsmFrame): the maps come from the core's raster,
// midpoint and MSSM passes; `frame_maps` turns the depth and classification layers into the
// buffers packet_hsm.wgsl reads; `frame_setup` is the twin of cpu.rs `setup_receiver` (every
// light shape; a sphere's silhouette from the core's silhouette_setup.wgsl), writing each
// receiver's RecIn for the kernel's `prepare` and `pixels` passes and what the CPU would have
// settled; `frame_finish` combines them into V, the twin of cpu.rs's sum over the sub-lights
// and SubLights::finish, one view (sub-light, opacity level) at a time. Appended after the
// core's shared.wgsl, estimate.wgsl, math.wgsl, silhouette.wgsl and silhouette_setup.wgsl.

// Mirrors frame.rs HsmFrameUniform.
struct HsmFrameUniform {
    bias: f32,
    slope_bias: f32,
    // 1: midpoint classification (t_p = z_p).
    midpoint: u32,
    // 1: receiver-plane rejection.
    receiver_plane: u32,
    _pad0: u32,
    r: u32,
    // This view's weight in V (1 / S^2 times its opacity level's).
    weight: f32,
    // FIRST_VIEW | LAST_VIEW of the frame's views.
    flags: u32,
}

const FIRST_VIEW: u32 = 1u;
const LAST_VIEW: u32 = 2u;

// What frame_setup decided per receiver (x: SETUP_*, y: V for SETUP_SETTLED, else the facing
// fraction).
const SETUP_SETTLED: f32 = 0.0;
const SETUP_OUTSIDE: f32 = 1.0;
const SETUP_MAP: f32 = 2.0;

@group(0) @binding(0) var<uniform> fview: LightViewUniform;
@group(0) @binding(1) var<uniform> flight: EstimateUniform;
@group(0) @binding(2) var<uniform> F: HsmFrameUniform;
// Bindings 3 to 7 and 13 hold one range of the frame's receivers (gpu.rs ReceiverRange).
@group(0) @binding(3) var<storage, read> receivers: array<ReceiverGpu>;
@group(0) @binding(4) var<storage, read_write> recs: array<RecIn>;
@group(0) @binding(5) var<storage, read_write> setup: array<vec2<f32>>;
// packet_hsm.wgsl's per-receiver output: (V before the facing factor, visited nodes; < 0: cut).
@group(0) @binding(6) var<storage, read> hsm_out: array<vec2<f32>>;
@group(0) @binding(7) var<storage, read_write> v_out: array<u32>;
// [0] receivers projecting outside the map, [1] non-finite V written as 0, [2] receivers the
// device's loop budget cut short (left NaN).
@group(0) @binding(8) var<storage, read_write> status: array<atomic<u32>, 3>;
@group(0) @binding(9) var depth_tex: texture_2d<f32>;
@group(0) @binding(10) var class_tex: texture_2d<f32>;
@group(0) @binding(11) var<storage, read_write> depth_buf: array<f32>;
@group(0) @binding(12) var<storage, read_write> class_buf: array<f32>;
// Per receiver: V summed over the views so far, and 1 once a view was cut.
@group(0) @binding(13) var<storage, read_write> acc: array<vec2<f32>>;

// mssm::sanitize: NaN is an empty texel (+inf), tested on the bits.
fn sanitized(d: f32) -> f32 {
    if (bitcast<u32>(d) & 0x7fffffffu) > 0x7f800000u {
        return pos_inf();
    }
    return d;
}

// One texel per invocation: the layers as the row-major buffers packet_hsm.wgsl reads.
@compute @workgroup_size(WG)
fn frame_maps(@builtin(global_invocation_id) gid: vec3<u32>) {
    let t = gid.x;
    if t >= F.r * F.r {
        return;
    }
    let ij = vec2<i32>(i32(t % F.r), i32(t / F.r));
    depth_buf[t] = sanitized(textureLoad(depth_tex, ij, 0).x);
    class_buf[t] = sanitized(textureLoad(class_tex, ij, 0).x);
}

fn settle(k: u32, kind: f32, x: f32) {
    setup[k] = vec2<f32>(kind, x);
    var r: RecIn;
    r.zp = 0.0;
    recs[k] = r;
}

// cpu.rs setup_receiver, one receiver per invocation.
@compute @workgroup_size(WG)
fn frame_setup(@builtin(global_invocation_id) gid: vec3<u32>) {
    let k = gid.x;
    if k >= arrayLength(&v_out) {
        return;
    }
    if receivers[k].is_active == 0u {
        settle(k, SETUP_SETTLED, 0.0);
        return;
    }
    let pw = receivers[k].position;
    let nw = receivers[k].normal;
    let p = view_to_light(fview, pw);
    let n = view_dir_to_light(fview, nw);
    let size = vec2<f32>(flight.light_size_x, flight.light_size_y);
    var facing = 0.0;
    var sil: Sil;
    sil.ok = false;
    if LIGHT_SHAPE == LIGHT_SPHERE {
        // Two-sided: the contract's silhouette disk in world space; a receiver behind the map's
        // plane or whose silhouette reaches its depth is outside every view (V = facing).
        facing = front_fraction_world(flight, pw, nw);
        if !(facing > 0.0) {
            settle(k, SETUP_SETTLED, 0.0);
            return;
        }
        if p.z > 0.0 {
            sil = sil_new(p, flight.light_size_x);
        }
        if !sil.ok {
            atomicAdd(&status[0], 1u);
            settle(k, SETUP_OUTSIDE, facing);
            return;
        }
    } else if fview.ortho != 0u {
        // The sun: its disk of directions one unit from p.
        facing = front_fraction(LIGHT_DISK, size, vec3<f32>(0.0, 0.0, 1.0), n);
    } else {
        if !(p.z > 0.0) {
            settle(k, SETUP_SETTLED, 0.0);
            return;
        }
        facing = front_fraction(LIGHT_SHAPE, size, p, n);
    }
    if !(facing > 0.0) {
        settle(k, SETUP_SETTLED, 0.0);
        return;
    }
    if p.z <= fview.n {
        settle(k, SETUP_SETTLED, facing);
        return;
    }
    let uv = project(fview, p);
    if !view_contains(fview, uv) {
        atomicAdd(&status[0], 1u);
        settle(k, SETUP_OUTSIDE, facing);
        return;
    }
    var t = p.z;
    if F.midpoint == 0u && F.receiver_plane == 0u {
        t = p.z - receiver_bias(fview, p, n, F.bias, F.slope_bias);
    }
    var r: RecIn;
    r.uv = uv;
    r.zp = p.z;
    r.t = t;
    if sil.ok {
        // kernel.rs RecIn: (a, dist), (e1, radius), (e2, 0), clip.
        r.sil_a = vec4<f32>(sil.a, sil.dist);
        r.sil_e1 = vec4<f32>(sil.e1, sil.radius);
        r.sil_e2 = vec4<f32>(sil.e2, 0.0);
        r.sil_clip = sil.clip;
    }
    if F.receiver_plane != 0u {
        let rp = plane_new(true, fview, p, n, F.bias, F.slope_bias, 0.0);
        r.g0 = rp.g0;
        // Orthographic planes vary their height (cu, cv) where perspective ones vary the slope.
        if fview.ortho != 0u {
            r.gu = rp.cu;
            r.gv = rp.cv;
        } else {
            r.gu = rp.gu;
            r.gv = rp.gv;
        }
        r.c = rp.c;
    }
    recs[k] = r;
    setup[k] = vec2<f32>(SETUP_MAP, facing);
}

// Each receiver's share of this view added to its sum: the settled value, the facing fraction
// outside the map, or facing times the kernel's V, times the view's weight. After the last
// view V is written: cut receivers left NaN (counted), else cpu.rs SubLights::finish's clamp
// and non-finite rule.
@compute @workgroup_size(WG)
fn frame_finish(@builtin(global_invocation_id) gid: vec3<u32>) {
    let k = gid.x;
    if k >= arrayLength(&v_out) {
        return;
    }
    let last = (F.flags & LAST_VIEW) != 0u;
    if receivers[k].is_active == 0u {
        if last {
            v_out[k] = NAN_BITS;
        }
        return;
    }
    var a = vec2<f32>(0.0, 0.0);
    if (F.flags & FIRST_VIEW) == 0u {
        a = acc[k];
    }
    let s = setup[k];
    var x = s.y;
    if s.x == SETUP_MAP {
        let o = hsm_out[k];
        if o.y < 0.0 {
            a.y = 1.0;
            x = 0.0;
        } else {
            x = s.y * o.x;
        }
    }
    a.x = a.x + F.weight * x;
    if !last {
        acc[k] = a;
        return;
    }
    if a.y != 0.0 {
        v_out[k] = NAN_BITS;
        atomicAdd(&status[2], 1u);
        return;
    }
    if is_finite(a.x) {
        v_out[k] = bitcast<u32>(clamp(a.x, 0.0, 1.0));
    } else {
        v_out[k] = 0u;
        atomicAdd(&status[1], 1u);
    }
}
