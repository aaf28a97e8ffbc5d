// The receivers a kernel left open (lit, but outside every map it has: accumulation's one
// frustum), settled on the device the way the CPU's settle::Settler settles them: a receiver p
// whose light pyramid (the convex hull of p and the light polygon, in front of p's tangent
// plane) meets no caster triangle is unshadowed, and its V is its facing fraction exactly. The
// test is conservative (a triangle touching the pyramid counts) and exact where it settles.
//
// Four passes over the range's open list (word 0 the count, then the receivers' indices), each
// dispatched indirectly, with no work when the list is empty: `settle_args` (settle_args.wgsl)
// writes the dispatches; `settle_boxes` bounds the casters in blocks of BLOCK triangles and runs
// of RUN (a two-level hierarchy, the CPU's BVH in its simplest form); `settle_test` runs one
// invocation per open receiver and SPAN triangles, testing a block's box, then its runs' boxes,
// then their triangles against the receiver's pyramid, and marks the receiver BLOCKED_BITS when
// a triangle meets it; `settle_finish` writes the facing fraction of the receivers no invocation
// blocked and leaves NaN (counted) for the others. Loops per invocation of `settle_test`: at most
// SPAN = RUN * RUNS * BLOCKS = 256 triangles, each at most 10 planes of at most 13 vertices
// (about 85 trips), 22k in all: within lavapipe's 65,535.
// Prepended: shared.wgsl, estimate.wgsl, math.wgsl (the light head), settle_uniform.wgsl.

@group(0) @binding(0) var<uniform> est: EstimateUniform;
@group(0) @binding(1) var<uniform> settle: SettleUniform;
@group(0) @binding(2) var<storage, read> casters: array<vec4<f32>>;
@group(0) @binding(3) var<storage, read> receivers: array<ReceiverGpu>;
@group(0) @binding(4) var<storage, read_write> v_out: array<u32>;
@group(0) @binding(5) var<storage, read> open_list: array<u32>;
@group(0) @binding(6) var<storage, read_write> counters: array<atomic<u32>>;
// Per block its box (lo, hi), then per run its box: written by settle_boxes.
@group(0) @binding(7) var<storage, read_write> boxes: array<vec4<f32>>;

// A receiver some caster may shadow: a NaN payload settle_finish turns into NAN_BITS.
const BLOCKED_BITS: u32 = 0x7fc0b10cu;
// settle::DISK_POLYGON: the octagon circumscribing a disk.
const NGON: u32 = 8u;
// Lateral planes, the light's plane and the tangent plane.
const MAX_PLANES: u32 = 10u;
// A triangle clipped by MAX_PLANES planes.
const MAX_CLIP: u32 = 13u;

// Triangles per run, runs per block, blocks per invocation of settle_test (the Rust side's
// BLOCK_TRIANGLES and SPAN_TRIANGLES are RUN * RUNS and RUN * RUNS * BLOCKS; gpu::settle's
// tests tie the three sides).
const RUN: u32 = 8u;
const RUNS: u32 = 8u;
const BLOCKS: u32 = 4u;

// The pyramid of one receiver, relative to p (p at the origin): plane (a, w) holds x where
// dot(a, x) + w >= 0.
var<private> planes: array<vec4<f32>, MAX_PLANES>;
// Its light polygon relative to p (a directional light's: directions).
var<private> corners: array<vec3<f32>, NGON>;
// Its bounding box relative to p (directional lights: unbounded).
var<private> box_lo: vec3<f32>;
var<private> box_hi: vec3<f32>;

// Vertex k of the regular NGON circumscribing the circle of radius r in the plane (e1, e2),
// relative to its centre (settle::light_polygon's ngon).
fn ngon_vertex(k: u32, e1: vec3<f32>, e2: vec3<f32>, r: f32) -> vec3<f32> {
    let m = f32(NGON);
    let rr = r / cos(3.14159265358979 / m);
    let phi = 2.0 * 3.14159265358979 * f32(k) / m;
    return (e1 * cos(phi) + e2 * sin(phi)) * rr;
}

// The pyramid's planes: one per polygon edge, the light's plane (not for a directional light),
// the tangent plane. A constant of the pipeline (LIGHT_SHAPE), so the loops over the planes
// unroll and the planes stay in registers.
fn plane_count() -> u32 {
    if LIGHT_SHAPE == LIGHT_DIRECTIONAL {
        return NGON + 1u;
    }
    return polygon_count() + 2u;
}

fn polygon_count() -> u32 {
    if LIGHT_SHAPE == LIGHT_RECT {
        return 4u;
    }
    return NGON;
}

// Vertex k of the light polygon (settle::light_polygon) relative to p; for a directional light
// the polygon of directions one unit from p.
fn polygon_vertex(k: u32, p: vec3<f32>) -> vec3<f32> {
    let f = est.light_frame;
    if LIGHT_SHAPE == LIGHT_RECT {
        let hx = 0.5 * est.light_size_x;
        let hy = 0.5 * est.light_size_y;
        let sx = array<f32, 4>(-1.0, 1.0, 1.0, -1.0);
        let sy = array<f32, 4>(-1.0, -1.0, 1.0, 1.0);
        return (f.origin - p) + f.ex * (sx[k] * hx) + f.ey * (sy[k] * hy);
    }
    if LIGHT_SHAPE == LIGHT_DISK {
        return (f.origin - p) + ngon_vertex(k, f.ex, f.ey, est.light_size_x);
    }
    if LIGHT_SHAPE == LIGHT_SPHERE {
        var a = p - f.origin;
        let rcp = valid_rcp(a);
        if rcp == 0.0 {
            a = f.ez;
        } else {
            a = a * rcp;
        }
        let e1 = default_tangent(a);
        return (f.origin - p) + ngon_vertex(k, e1, cross3(a, e1), est.light_size_x);
    }
    // Directional: the direction towards the light, -ez, widened to the disk of directions.
    return -f.ez + ngon_vertex(k, f.ex, f.ey, est.light_size_x);
}

// settle::pyramid relative to p; false when degenerate (p in the light's plane or at its
// centre).
fn build_pyramid(p: vec3<f32>, n: vec3<f32>) -> bool {
    let f = est.light_frame;
    let directional = LIGHT_SHAPE == LIGHT_DIRECTIONAL;
    var c = f.origin - p;
    if directional {
        c = -f.ez;
    }
    let dist = sqrt(dot(c, c));
    if !(dist > 0.0) {
        return false;
    }
    let count = polygon_count();
    box_lo = vec3<f32>(0.0);
    box_hi = vec3<f32>(0.0);
    for (var k = 0u; k < count; k++) {
        let a = polygon_vertex(k, p);
        let b = polygon_vertex((k + 1u) % count, p);
        corners[k] = a;
        box_lo = min(box_lo, a);
        box_hi = max(box_hi, a);
        var m = cross3(a, b);
        let s = dot(m, c);
        // The centre clearly inside (relative to |m| |c|), else no interior.
        if !(abs(s) > 1e-6 * sqrt(dot(m, m)) * dist) {
            return false;
        }
        if s < 0.0 {
            m = -m;
        }
        planes[k] = vec4<f32>(m, 0.0);
    }
    if !directional {
        // The light polygon's plane, p's side (p is the origin).
        let a0 = polygon_vertex(0u, p);
        var e = cross3(polygon_vertex(1u, p) - a0, polygon_vertex(2u, p) - a0);
        var w = -dot(e, c);
        if w < 0.0 {
            e = -e;
            w = -w;
        }
        planes[count] = vec4<f32>(e, w);
    }
    // The tangent plane moved towards the light: casters lie strictly in front of it. A
    // directional light's scale is p's distance from the origin (the CPU's: the scene's).
    var eps = 1e-5 * dist;
    if directional {
        eps = 1e-5 * (2.0 * sqrt(dot(p, p)) + 1.0);
    }
    planes[plane_count() - 1u] = vec4<f32>(n, -eps);
    for (var i = 0u; i < plane_count(); i++) {
        let pl = planes[i];
        if !(is_finite(pl.x) && is_finite(pl.y) && is_finite(pl.z) && is_finite(pl.w)) {
            return false;
        }
    }
    return true;
}

fn side(pl: vec4<f32>, x: vec3<f32>) -> f32 {
    return dot(pl.xyz, x) + pl.w;
}

// SceneBvh::any_in_convex's node test: the box (relative to p) overlaps the pyramid's box and
// reaches inside every plane.
fn box_meets(lo: vec3<f32>, hi: vec3<f32>) -> bool {
    if LIGHT_SHAPE != LIGHT_DIRECTIONAL {
        if any(lo > box_hi) || any(hi < box_lo) {
            return false;
        }
    }
    for (var i = 0u; i < plane_count(); i++) {
        let pl = planes[i];
        let x = select(lo, hi, pl.xyz >= vec3<f32>(0.0));
        if side(pl, x) < 0.0 {
            return false;
        }
    }
    return true;
}

// The cheap tests of a triangle (relative to p) against the pyramid: APART when a box, a
// pyramid plane or the triangle's own plane separates them, MEETS when the triangle lies inside
// every plane, else CLIP (clip_meets decides).
const APART: u32 = 0u;
const MEETS: u32 = 1u;
const CLIP: u32 = 2u;

fn cheap_test(t0: vec3<f32>, t1: vec3<f32>, t2: vec3<f32>) -> u32 {
    if LIGHT_SHAPE != LIGHT_DIRECTIONAL {
        let lo = min(t0, min(t1, t2));
        let hi = max(t0, max(t1, t2));
        if any(lo > box_hi) || any(hi < box_lo) {
            return APART;
        }
    }
    // Most triangles lie wholly outside one plane.
    var straddles = false;
    for (var i = 0u; i < plane_count(); i++) {
        let pl = planes[i];
        let s0 = side(pl, t0) >= 0.0;
        let s1 = side(pl, t1) >= 0.0;
        let s2 = side(pl, t2) >= 0.0;
        if !(s0 || s1 || s2) {
            return APART;
        }
        straddles = straddles || !(s0 && s1 && s2);
    }
    if !straddles {
        return MEETS;
    }
    // The triangle's own plane, with the pyramid's apex (p) strictly on one side and every
    // light corner (or direction) on that side too: a separating axis, cheaper than clipping.
    let nt = cross3(t1 - t0, t2 - t0);
    let sa = -dot(nt, t0);
    if sa != 0.0 {
        var apart = true;
        for (var k = 0u; k < polygon_count(); k++) {
            if LIGHT_SHAPE == LIGHT_DIRECTIONAL {
                apart = apart && sa * dot(nt, corners[k]) >= 0.0;
            } else {
                apart = apart && sa * dot(nt, corners[k] - t0) > 0.0;
            }
        }
        if apart {
            return APART;
        }
    }
    return CLIP;
}

// Polygon::clip of the triangle (relative to p) by the pyramid's planes: true when some of it
// is left (touching counts).
fn clip_meets(t0: vec3<f32>, t1: vec3<f32>, t2: vec3<f32>) -> bool {
    // Two polygons in one array, read from `src` and written to the other half in turn.
    var poly: array<vec3<f32>, 2 * MAX_CLIP>;
    poly[0] = t0;
    poly[1] = t1;
    poly[2] = t2;
    var count = 3u;
    var src = 0u;
    for (var i = 0u; i < plane_count(); i++) {
        let pl = planes[i];
        let dst = MAX_CLIP - src;
        var m = 0u;
        for (var k = 0u; k < count; k++) {
            let a = poly[src + k];
            let b = poly[src + (k + 1u) % count];
            let da = side(pl, a);
            let db = side(pl, b);
            if da >= 0.0 && m < MAX_CLIP {
                poly[dst + m] = a;
                m++;
            }
            if (da >= 0.0) != (db >= 0.0) && m < MAX_CLIP {
                poly[dst + m] = a + (b - a) * (da / (da - db));
                m++;
            }
        }
        if m == 0u {
            return false;
        }
        src = dst;
        count = m;
    }
    return true;
}

fn triangle(t: u32, p: vec3<f32>) -> array<vec3<f32>, 3> {
    return array<vec3<f32>, 3>(
        casters[3u * t].xyz - p,
        casters[3u * t + 1u].xyz - p,
        casters[3u * t + 2u].xyz - p
    );
}

fn blocks() -> u32 {
    return (settle.triangles + RUN * RUNS - 1u) / (RUN * RUNS);
}

// One invocation per block: its runs' boxes and its own.
@compute @workgroup_size(WG)
fn settle_boxes(@builtin(global_invocation_id) gid: vec3<u32>) {
    let b = gid.x;
    if b >= blocks() {
        return;
    }
    var block_lo = vec3<f32>(F32_MAX);
    var block_hi = vec3<f32>(-F32_MAX);
    for (var r = 0u; r < RUNS; r++) {
        var lo = vec3<f32>(F32_MAX);
        var hi = vec3<f32>(-F32_MAX);
        let first = (b * RUNS + r) * RUN;
        for (var t = first; t < min(first + RUN, settle.triangles); t++) {
            for (var i = 0u; i < 3u; i++) {
                let x = casters[3u * t + i].xyz;
                lo = min(lo, x);
                hi = max(hi, x);
            }
        }
        let run = 2u * (blocks() + b * RUNS + r);
        boxes[run] = vec4<f32>(lo, 0.0);
        boxes[run + 1u] = vec4<f32>(hi, 0.0);
        block_lo = min(block_lo, lo);
        block_hi = max(block_hi, hi);
    }
    boxes[2u * b] = vec4<f32>(block_lo, 0.0);
    boxes[2u * b + 1u] = vec4<f32>(block_hi, 0.0);
}

// One invocation per open receiver (x) and SPAN triangles (y, then z).
@compute @workgroup_size(WG)
fn settle_test(@builtin(global_invocation_id) gid: vec3<u32>,
               @builtin(workgroup_id) wid: vec3<u32>) {
    let i = gid.x;
    if i >= open_list[0] {
        return;
    }
    let k = open_list[1u + i];
    if v_out[k] != NAN_BITS {
        return;
    }
    let p = receivers[k].position;
    if !build_pyramid(p, receivers[k].normal) {
        v_out[k] = BLOCKED_BITS;
        return;
    }
    let span = wid.y + wid.z * settle.rows;
    let first_block = span * BLOCKS;
    let n_blocks = blocks();
    for (var b = first_block; b < min(first_block + BLOCKS, n_blocks); b++) {
        if !box_meets(boxes[2u * b].xyz - p, boxes[2u * b + 1u].xyz - p) {
            continue;
        }
        for (var r = b * RUNS; r < (b + 1u) * RUNS; r++) {
            let run = 2u * (n_blocks + r);
            if r * RUN >= settle.triangles || !box_meets(boxes[run].xyz - p, boxes[run + 1u].xyz - p) {
                continue;
            }
            // The run's cheap tests first; the few triangles they leave are clipped in a loop
            // of their own, which a lane-predicated device skips when no lane has one.
            var clip = 0u;
            for (var t = r * RUN; t < min((r + 1u) * RUN, settle.triangles); t++) {
                let v = triangle(t, p);
                let c = cheap_test(v[0], v[1], v[2]);
                if c == MEETS {
                    v_out[k] = BLOCKED_BITS;
                    return;
                }
                if c == CLIP {
                    clip |= 1u << (t - r * RUN);
                }
            }
            while clip != 0u {
                let j = firstTrailingBit(clip);
                clip &= clip - 1u;
                let v = triangle(r * RUN + j, p);
                if clip_meets(v[0], v[1], v[2]) {
                    v_out[k] = BLOCKED_BITS;
                    return;
                }
            }
        }
    }
}

@compute @workgroup_size(WG)
fn settle_finish(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.x;
    if i >= open_list[0] {
        return;
    }
    let k = open_list[1u + i];
    let bits = v_out[k];
    if bits == BLOCKED_BITS {
        v_out[k] = NAN_BITS;
        atomicAdd(&counters[settle.unsettled_word], 1u);
    } else if bits == NAN_BITS {
        let p = receivers[k].position;
        let n = receivers[k].normal;
        // With no casters settle_test did not run: a degenerate pyramid settles nothing (the
        // CPU's `unshadowed` is false there too).
        if settle.triangles == 0u && !build_pyramid(p, n) {
            atomicAdd(&counters[settle.unsettled_word], 1u);
            return;
        }
        let x = front_fraction_world(est, p, n);
        if is_finite(x) {
            v_out[k] = bitcast<u32>(clamp(x, 0.0, 1.0));
        } else {
            v_out[k] = 0u;
        }
    }
}
