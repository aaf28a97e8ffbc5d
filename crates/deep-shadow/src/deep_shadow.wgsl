// Deep shadow maps on the GPU (Fürst et al.), the twin of dsm.rs stage for stage, for the engine
// path (gpu.rs): clear, process (§1.3.2: sort, tau, prev, truncation), link (§1.3.3), and the
// per-query transmittance of the lists (§1.3.4, §1.3.5; filter=pcss: soft_transmittance) or of
// the opaque path's nearest depths, which frame.wgsl's `frame_lookup` calls. The lists
// themselves are inserted by insert.wgsl.
// `Cells`, `cells_new`, `cell`, `Sum`, `sum_add` come from the core's cells.wgsl, the part
// before this one; the workgroup size WG from the core's estimate.wgsl.
// Structs mirror gpu/kernel.rs field for field (Node: node.wgsl, math/node.rs).
//
// A query (frame.wgsl `frame_query`, the twin of cpu.rs `query`) is two vec4: q0 = (u, v, z_p,
// fixed), fixed >= 0 the transmittance without a lookup, fixed < 0 a lookup whose result is
// multiplied by -fixed (the facing factor); then q1, the caster test of
// shadow_map_core::ReceiverPlane (hs = 0; see q_slope_height).

// Set from Rust as a pipeline override (math::EDSM_CUTOFF; NIL and Node come from node.wgsl).
override EDSM_CUTOFF: f32;
// The lookup's switches, `DsUniform`'s fields of the same names passed as pipeline overrides
// to `frame_lookup` (gpu::lookup_switches): a lane-predicated device then runs no filter, walk
// or light shape the view does not use. The per-texel passes read none of them.
override DS_FILTER: u32 = 4u;
override DS_TRAVERSAL: u32 = 0u;
override DS_DISK: bool = false;
const SORT_LOCAL: u32 = 64u;
const FILTER_FIRST: u32 = 0u;
const FILTER_NONE: u32 = 1u;
const FILTER_PCF: u32 = 2u;
const FILTER_EDSM: u32 = 3u;
const FILTER_PCSS: u32 = 4u;

struct DsUniform {
    r: u32,
    capacity: u32,
    epsilon: f32,
    filter_mode: u32,
    kernel: u32,
    traversal: u32,
    c_world: f32,
    near: f32,
    to_texels: f32,
    max_taps: u32,
    light_x: f32,
    light_y: f32,
    disk: u32,
    ortho: u32,
    probe: u32,
    trunc_window: f32,
}

// gpu/kernel.rs COUNTER_BYTES. `count` the elements asked for, `wraps` the element counter's wraps
// past u32::MAX (insert.wgsl), `cut` the texels whose process or link the device's loop budget
// cut short (shared.wgsl loop_limit_hit): frame.wgsl then leaves the frame's receivers for the
// caller to redo.
struct Counters {
    count: atomic<u32>,
    steps: atomic<u32>,
    wraps: atomic<u32>,
    cut: atomic<u32>,
    // process: elements left in the lists after truncation, and the longest list before it
    // (the CPU twin's BuildStats::kept and max_len).
    kept: atomic<u32>,
    max_len: atomic<u32>,
}

@group(0) @binding(0) var<uniform> P: DsUniform;
@group(0) @binding(3) var<storage, read_write> head: array<atomic<u32>>;
@group(0) @binding(4) var<storage, read_write> nodes: array<Node>;
@group(0) @binding(5) var<storage, read_write> counters: Counters;
// frame.wgsl's bindings follow from 8 on.

fn linear_id(wid: vec3<u32>, nwg: vec3<u32>, lid: vec3<u32>) -> u32 {
    return (wid.y * nwg.x + wid.x) * WG + lid.x;
}

@compute @workgroup_size(WG)
fn clear(@builtin(workgroup_id) wid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>,
         @builtin(local_invocation_id) lid: vec3<u32>) {
    let t = linear_id(wid, nwg, lid);
    if (t >= P.r * P.r) { return; }
    atomicStore(&head[t], NIL);
}

fn less(za: f32, aa: f32, zb: f32, ab: f32) -> bool {
    return za < zb || (za == zb && aa < ab);
}

// §1.3.2, one texel per invocation: sort the payloads by (depth, alpha) (insertion sort in a
// private array for lists up to SORT_LOCAL, selection sort in place beyond), then tau, prev and
// truncation after the first element with tau <= epsilon.
@compute @workgroup_size(WG)
fn process(@builtin(workgroup_id) wid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>,
           @builtin(local_invocation_id) lid: vec3<u32>) {
    let t = linear_id(wid, nwg, lid);
    if (t >= P.r * P.r) { return; }
    let h = atomicLoad(&head[t]);
    if (h == NIL) { return; }
    var len = 0u;
    var e = h;
    while (e != NIL) { len++; e = nodes[e].next; }
    if (len <= SORT_LOCAL) {
        var zs: array<f32, 64>;
        var als: array<f32, 64>;
        e = h;
        for (var k = 0u; k < len; k++) {
            let z = nodes[e].depth;
            let al = nodes[e].alpha;
            var m = k;
            while (m > 0u && less(z, al, zs[m - 1u], als[m - 1u])) {
                zs[m] = zs[m - 1u];
                als[m] = als[m - 1u];
                m--;
            }
            zs[m] = z;
            als[m] = al;
            e = nodes[e].next;
        }
        e = h;
        for (var k = 0u; k < len; k++) {
            nodes[e].depth = zs[k];
            nodes[e].alpha = als[k];
            e = nodes[e].next;
        }
    } else {
        var a = h;
        while (a != NIL) {
            var m = a;
            var b = nodes[a].next;
            while (b != NIL) {
                if (less(nodes[b].depth, nodes[b].alpha, nodes[m].depth, nodes[m].alpha)) { m = b; }
                b = nodes[b].next;
            }
            let z = nodes[a].depth;
            let al = nodes[a].alpha;
            nodes[a].depth = nodes[m].depth;
            nodes[a].alpha = nodes[m].alpha;
            nodes[m].depth = z;
            nodes[m].alpha = al;
            a = nodes[a].next;
        }
    }
    atomicMax(&counters.max_len, len);
    var tau = 1.0;
    var prev = NIL;
    var kept = 0u;
    // dsm.rs process_list: once tau_K <= epsilon, EDSM keeps the elements nearer than
    // z_K + trunc_window; the hard filters truncate right after K (trunc_window 0).
    var cutting = false;
    var cut_at = 0.0;
    e = h;
    while (e != NIL) {
        if (cutting && nodes[e].depth >= cut_at) {
            nodes[prev].next = NIL;
            break;
        }
        kept++;
        tau = tau * (1.0 - nodes[e].alpha);
        nodes[e].tau = tau;
        nodes[e].prev = prev;
        if (!cutting && P.epsilon > 0.0 && tau <= P.epsilon) {
            if (P.trunc_window > 0.0) {
                cutting = true;
                cut_at = nodes[e].depth + P.trunc_window;
            } else {
                nodes[e].next = NIL;
                break;
            }
        }
        prev = e;
        e = nodes[e].next;
    }
    atomicAdd(&counters.kept, kept);
    // Out of the device's loop budget (a long list's selection sort): counted; frame.wgsl then
    // leaves the frame's receivers NaN for the caller to redo.
    if (loop_limit_hit(P.probe)) { atomicAdd(&counters.cut, 1u); }
}

// The depth-nearest element of list `b` for every element of list `a` (ties to the shallower).
fn link_list(a: u32, b: u32, upper: bool) {
    var cur = b;
    var e = a;
    while (e != NIL) {
        let z = nodes[e].depth;
        var best = NIL;
        if (cur != NIL) {
            loop {
                let nx = nodes[cur].next;
                if (nx != NIL && nodes[nx].depth <= z) { cur = nx; } else { break; }
            }
            let zc = nodes[cur].depth;
            let nx = nodes[cur].next;
            best = cur;
            if (zc <= z && nx != NIL && nodes[nx].depth - z < z - zc) { best = nx; }
        }
        if (upper) { nodes[e].upper = best; } else { nodes[e].right = best; }
        e = nodes[e].next;
    }
}

// §1.3.3, one texel per invocation.
@compute @workgroup_size(WG)
fn link(@builtin(workgroup_id) wid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>,
        @builtin(local_invocation_id) lid: vec3<u32>) {
    let t = linear_id(wid, nwg, lid);
    let r = P.r;
    if (t >= r * r) { return; }
    let i = t % r;
    let j = t / r;
    let h = atomicLoad(&head[t]);
    var right = NIL;
    var upper = NIL;
    if (i + 1u < r) { right = atomicLoad(&head[t + 1u]); }
    if (j + 1u < r) { upper = atomicLoad(&head[t + r]); }
    link_list(h, right, false);
    link_list(h, upper, true);
    if (loop_limit_hit(P.probe)) { atomicAdd(&counters.cut, 1u); }
}

// The slope g and height c of the caster test at the centre of texel (i, j): q1 = (g0, gu, gv, c)
// in perspective; in an orthographic view (the sun, gu = gv = 0) q1 = (g0, cu, cv, c).
fn q_slope_height(q1: vec4<f32>, i: i32, j: i32) -> vec2<f32> {
    let lin = q1.y * (f32(i) + 0.5) + q1.z * (f32(j) + 0.5);
    if (P.ortho != 0u) {
        return vec2<f32>(q1.x, q1.w + lin);
    }
    return vec2<f32>(q1.x + lin, q1.w);
}

// ReceiverPlane::caster (math.wgsl plane_caster, hs = 0): the fragment at depth z in texel (i, j)
// attenuates the receiver of query q0 = (u, v, z_p, _), q1 (q_slope_height).
fn q_caster(q0: vec4<f32>, q1: vec4<f32>, i: i32, j: i32, z: f32) -> bool {
    let gc = q_slope_height(q1, i, j);
    return z == z && abs(z) <= 3.40282347e38 && z < q0.z && z * gc.x < gc.y;
}

// math::caster_depth: ReceiverPlane::threshold_at at the centre of texel (i, j): exact where the
// ray descends towards the tangent plane (g > 0), z_p elsewhere.
fn q_threshold(q0: vec4<f32>, q1: vec4<f32>, i: i32, j: i32) -> f32 {
    let gc = q_slope_height(q1, i, j);
    if gc.x > 0.0 {
        return min(gc.y / gc.x, q0.z);
    }
    return q0.z;
}

// math::find_by with q_caster in texel (i, j): the last element that is a caster, searched from
// `start` along next or prev; and the steps.
fn find_caster(start: u32, q0: vec4<f32>, q1: vec4<f32>, i: i32, j: i32) -> vec2<u32> {
    var s = start;
    var steps = 1u;
    if (q_caster(q0, q1, i, j, nodes[s].depth)) {
        loop {
            let nx = nodes[s].next;
            if (nx != NIL && q_caster(q0, q1, i, j, nodes[nx].depth)) { s = nx; steps++; } else { break; }
        }
        return vec2<u32>(s, steps);
    }
    loop {
        let pv = nodes[s].prev;
        if (pv == NIL) { return vec2<u32>(NIL, steps); }
        s = pv;
        steps++;
        if (q_caster(q0, q1, i, j, nodes[s].depth)) { return vec2<u32>(s, steps); }
    }
    return vec2<u32>(NIL, steps);
}

// The last element with depth < d, searched from `start` along next or prev; and the steps:
// find_caster with the plain depth test (math::find is math::find_by of `z < d` the same way).
fn find(start: u32, d: f32) -> vec2<u32> {
    return find_caster(start, vec4<f32>(0.0, 0.0, d, 0.0), vec4<f32>(1.0, 0.0, 0.0, d), 0, 0);
}

// EDSM (docs/methods.md §7): prod (1 - alpha_j (1 - exp(-c' (d - z_j)))), exponents <= 0 only.
fn soft_tau(k: u32, d: f32) -> f32 {
    var prod = 1.0;
    var j = k;
    while (j != NIL) {
        let t = (d - nodes[j].depth) * P.c_world;
        if (t >= EDSM_CUTOFF) { return nodes[j].tau * prod; }
        prod = prod * (1.0 - nodes[j].alpha * (1.0 - exp(-max(t, 0.0))));
        j = nodes[j].prev;
    }
    return prod;
}

// The head of texel (i, j); NIL outside the map or when empty (the opaque path: the depth bits).
fn head_at(i: i32, j: i32) -> u32 {
    let r = i32(P.r);
    if (i < 0 || j < 0 || i >= r || j >= r) { return NIL; }
    return atomicLoad(&head[u32(j * r + i)]);
}

// A tap's transmittance and the list elements visited.
struct TapT {
    t: f32,
    steps: u32,
}

// DeepShadowMap's SoftTaps::tap: tau of the last caster of texel (i, j), 1 when none (the opaque path: 0 or
// 1 from the nearest depth).
fn soft_tap(i: i32, j: i32, q0: vec4<f32>, q1: vec4<f32>, opaque: bool) -> TapT {
    let hd = head_at(i, j);
    if (hd == NIL) { return TapT(1.0, 0u); }
    if (opaque) { return TapT(select(1.0, 0.0, q_caster(q0, q1, i, j, bitcast<f32>(hd))), 1u); }
    let f = find_caster(hd, q0, q1, i, j);
    if (f.x == NIL) { return TapT(1.0, f.y); }
    return TapT(nodes[f.x].tau, f.y);
}

// The two Kahan sums and the list steps of one region of cells ([`region_sums`]).
struct RegionSums {
    a: Sum,
    b: Sum,
    steps: u32,
}

// One region of soft_transmittance, `width` texels wide around the query, in cells of at most
// max_taps a side, row by row. `search`: PCSS's blocker search over the first fragments, a = the
// casters' w z, b = their w. Otherwise the kernel (for disk lights with disk_edge's one-texel soft
// edge): a = w T of each tap, b = w.
fn region_sums(q0: vec4<f32>, q1: vec4<f32>, opaque: bool, width: vec2<f32>, search: bool) -> RegionSums {
    let uv = q0.xy;
    var out = RegionSums(Sum(0.0, 0.0), Sum(0.0, 0.0), 0u);
    let cy = cells_new(uv.y - 0.5 * width.y, uv.y + 0.5 * width.y, P.max_taps);
    for (var ky = 0u; ky < cy.count; ky++) {
        let cj = cell(cy, ky);
        if (!cj.valid) { continue; }
        let cx = cells_new(uv.x - 0.5 * width.x, uv.x + 0.5 * width.x, P.max_taps);
        for (var kx = 0u; kx < cx.count; kx++) {
            let ci = cell(cx, kx);
            if (!ci.valid) { continue; }
            if (search) {
                let hd = head_at(ci.i, cj.i);
                if (hd == NIL) { continue; }
                var z = 0.0;
                if (opaque) { z = bitcast<f32>(hd); } else { z = nodes[hd].depth; }
                out.steps++;
                if (q_caster(q0, q1, ci.i, cj.i, z)) {
                    let w = ci.w * cj.w;
                    out.a = sum_add(out.a, w * z);
                    out.b = sum_add(out.b, w);
                }
            } else {
                var edge = 1.0;
                if (DS_DISK && width.x > 1.0) {
                    let rad = 0.5 * width.x;
                    let c = vec2<f32>(f32(ci.i) + 0.5, f32(cj.i) + 0.5) - uv;
                    edge = clamp(rad + 0.5 - sqrt(c.x * c.x + c.y * c.y), 0.0, 1.0);
                }
                if (edge <= 0.0) { continue; }
                let w = ci.w * cj.w * edge;
                out.b = sum_add(out.b, w);
                let tt = soft_tap(ci.i, cj.i, q0, q1, opaque);
                out.steps += tt.steps;
                if (tt.t != 0.0) { out.a = sum_add(out.a, w * tt.t); }
            }
        }
    }
    return out;
}

// soft_transmittance::soft_transmittance of the core (docs/methods.md §8 "Percentage-closer soft transmittance"), the same
// steps in the same order: PCSS's blocker search over the first fragments (search_width), z_avg,
// the kernel width (filter_width), the weighted mean of the taps' T (disk_edge for disk lights).
fn soft_transmittance(q0: vec4<f32>, q1: vec4<f32>, opaque: bool) -> TapT {
    let zr = q0.z;
    let l = vec2<f32>(P.light_x, P.light_y);
    let ws = pcss_search_width(l, zr, P.near, P.to_texels, P.ortho != 0u);
    let search = region_sums(q0, q1, opaque, ws, true);
    if (!(search.b.s > 0.0)) { return TapT(1.0, search.steps); }
    let z_avg = search.a.s / search.b.s;
    let wf = pcss_filter_width(l, zr, z_avg, P.near, P.to_texels, P.ortho != 0u);
    let kernel = region_sums(q0, q1, opaque, wf, false);
    let steps = search.steps + kernel.steps;
    if (!(kernel.b.s > 0.0)) { return TapT(1.0, steps); }
    let t = kernel.a.s / kernel.b.s;
    if (t == t && abs(t) <= 3.40282347e38) { return TapT(clamp(t, 0.0, 1.0), steps); }
    return TapT(1.0, steps);
}

// LookupSettings::first_tap: the kernel's first tap (i, j) around texel coordinates uv, the
// receiver's texel less half the n x n kernel on each axis.
fn first_tap(uv: vec2<f32>, n: i32) -> vec2<i32> {
    return vec2<i32>(i32(floor(uv.x)), i32(floor(uv.y))) - vec2<i32>(n / 2);
}

fn kernel_side() -> i32 {
    if (DS_FILTER == FILTER_PCF || DS_FILTER == FILTER_EDSM) { return i32(max(P.kernel, 1u)); }
    return 1;
}

// The transmittance of one query (q = (u, v, z_p, fixed), q1 the caster test) in the lists, as
// DeepShadowMap::transmittance_plane; its list steps added to counters.steps.
fn list_transmittance(q: vec4<f32>, q1: vec4<f32>) -> f32 {
    if (q.w >= 0.0) { return q.w; }
    if (DS_FILTER == FILTER_PCSS) {
        let tt = soft_transmittance(q, q1, false);
        atomicAdd(&counters.steps, tt.steps);
        return -q.w * tt.t;
    }
    let r = i32(P.r);
    let n = kernel_side();
    let t0 = first_tap(q.xy, n);
    var sum = 0.0;
    var steps = 0u;
    var row_anchor = NIL;
    for (var b = 0; b < n; b++) {
        let j = t0.y + b;
        var anchor = NIL;
        for (var a = 0; a < n; a++) {
            let i = t0.x + a;
            if (i < 0 || j < 0 || i >= r || j >= r) {
                sum += 1.0;
                anchor = NIL;
                if (a == 0) { row_anchor = NIL; }
                continue;
            }
            let hd = atomicLoad(&head[u32(j * r + i)]);
            if (hd == NIL) {
                sum += 1.0;
                anchor = NIL;
                if (a == 0) { row_anchor = NIL; }
                continue;
            }
            if (DS_FILTER == FILTER_FIRST) {
                steps++;
                if (!q_caster(q, q1, i, j, nodes[hd].depth)) { sum += 1.0; }
                continue;
            }
            var start = hd;
            if (DS_TRAVERSAL == 0u) {
                var src = anchor;
                if (a == 0) { src = row_anchor; }
                if (src != NIL) {
                    var link = nodes[src].right;
                    if (a == 0) { link = nodes[src].upper; }
                    if (link != NIL) { start = link; }
                }
            }
            var f: vec2<u32>;
            var d = 0.0;
            if (DS_FILTER == FILTER_EDSM) {
                d = q_threshold(q, q1, i, j);
                f = find(start, d);
            } else {
                f = find_caster(start, q, q1, i, j);
            }
            let k = f.x;
            steps += f.y;
            if (DS_FILTER == FILTER_EDSM) {
                sum += soft_tau(k, d);
            } else if (k != NIL) {
                sum += nodes[k].tau;
            } else {
                sum += 1.0;
            }
            anchor = hd;
            if (k != NIL) { anchor = k; }
            if (a == 0) { row_anchor = anchor; }
        }
    }
    atomicAdd(&counters.steps, steps);
    return -q.w * clamp(sum / f32(n * n), 0.0, 1.0);
}

// The opaque path's transmittance of one query (q0 = (u, v, z_p, fixed), q1 the caster test), as
// math::transmittance_opaque_plane: head[] holds the nearest depth's bits (NIL: empty), no lists.
fn opaque_transmittance(q: vec4<f32>, q1: vec4<f32>) -> f32 {
    if (q.w >= 0.0) { return q.w; }
    if (DS_FILTER == FILTER_PCSS) {
        return -q.w * soft_transmittance(q, q1, true).t;
    }
    let r = i32(P.r);
    let n = kernel_side();
    let t0 = first_tap(q.xy, n);
    var sum = 0.0;
    for (var b = 0; b < n; b++) {
        for (var a = 0; a < n; a++) {
            let i = t0.x + a;
            let j = t0.y + b;
            var lit = 1.0;
            if (i >= 0 && j >= 0 && i < r && j < r) {
                let bits = atomicLoad(&head[u32(j * r + i)]);
                if (bits != NIL) {
                    let z = bitcast<f32>(bits);
                    if (q_caster(q, q1, i, j, z)) {
                        lit = 0.0;
                        if (DS_FILTER == FILTER_EDSM) {
                            let t = max((q_threshold(q, q1, i, j) - z) * P.c_world, 0.0);
                            if (t < EDSM_CUTOFF) { lit = exp(-t); }
                        }
                    }
                }
            }
            sum += lit;
        }
    }
    return -q.w * clamp(sum / f32(n * n), 0.0, 1.0);
}
