// Deep shadow maps on the GPU (Fürst et al.), the twin of dsm.rs and raster.rs, stage for stage:
// clear, raster (compute rasteriser: §1.3.1 with atomics), process (§1.3.2: sort, tau, prev,
// truncation), link (§1.3.3), lookup (§1.3.4, §1.3.5; filter=pcss: soft_transmittance). The
// opaque path (no lists): raster_opaque (atomicMin of the depth bits) and lookup_opaque.
// `Cells`, `cells_new`, `cell`, `Sum`, `sum_add` come from the baselines' cells.wgsl, the part
// before this one.
// Structs mirror shared.rs field for field (Node: node.wgsl).

// Set from Rust as a pipeline override (dsm::EDSM_CUTOFF; NIL and Node come from node.wgsl, the
// part before this one; the workgroup size WG,
// gpu::WORKGROUP_SIZE, is declared by the part before this one: gpu.rs WG_WGSL for the twin's
// module, the core's estimate.wgsl for the engine path's).
override EDSM_CUTOFF: f32;
const SORT_LOCAL: u32 = 64u;
const FILTER_FIRST: u32 = 0u;
const FILTER_NONE: u32 = 1u;
const FILTER_PCF: u32 = 2u;
const FILTER_EDSM: u32 = 3u;
const FILTER_PCSS: u32 = 4u;

struct Tri {
    u0: f32, v0: f32, u1: f32, v1: f32, u2: f32, v2: f32,
    iz0: f32, iz1: f32, iz2: f32,
    alpha: f32,
    _pad0: u32,
    _pad1: u32,
}

struct DsUniform {
    r: u32,
    capacity: u32,
    n_items: u32,
    n_queries: u32,
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
    _pad1: u32,
    _pad2: u32,
}

// gpu.rs COUNTER_BYTES. `wraps` counts the element counter's wraps past u32::MAX (gpu.rs turns
// any into Error::Limit); `cut` the invocations the device's loop budget cut short (shared.wgsl
// loop_limit_hit): texels of process/link (gpu.rs then builds the map with the CPU twin) or
// lookups (written as CUT_BITS, redone on the CPU).
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
@group(0) @binding(1) var<storage, read> tris: array<Tri>;
// (triangle, first texel column, first texel row, unused) per work item: a 16 x 16 tile.
@group(0) @binding(2) var<storage, read> items: array<vec4<u32>>;
@group(0) @binding(3) var<storage, read_write> head: array<atomic<u32>>;
@group(0) @binding(4) var<storage, read_write> nodes: array<Node>;
@group(0) @binding(5) var<storage, read_write> counters: Counters;
// Two per query (gpu.rs PackedQuery): (u, v, z_p, fixed), fixed >= 0 the transmittance without a
// lookup, fixed < 0 a lookup whose result is multiplied by -fixed (the facing factor); then the caster test (g0, gu, gv, c) of shadow_map_core::ReceiverPlane (hs = 0).
@group(0) @binding(6) var<storage, read> queries: array<vec4<f32>>;
@group(0) @binding(7) var<storage, read_write> out_t: array<f32>;

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

fn owns_ties(du: f32, dv: f32) -> bool {
    return dv < 0.0 || (dv == 0.0 && du > 0.0);
}

fn perp(a: vec2<f32>, b: vec2<f32>) -> f32 {
    return a.x * b.y - a.y * b.x;
}

// As raster.rs edge_function: from the lexicographically smaller endpoint, so shared edges give
// exactly opposite values (watertight).
fn edge(s: vec2<f32>, e: vec2<f32>, p: vec2<f32>) -> f32 {
    if (s.x < e.x || (s.x == e.x && s.y <= e.y)) {
        return perp(e - s, p - s);
    }
    return -perp(s - e, p - e);
}

// Rasterises one work item; `mode` 0 inserts list elements, 1 keeps the nearest depth.
fn raster_item(k: u32, mode: u32) {
    if (k >= P.n_items) { return; }
    let it = items[k];
    let t = tris[it.x];
    let a = vec2<f32>(t.u0, t.v0);
    let b = vec2<f32>(t.u1, t.v1);
    let c = vec2<f32>(t.u2, t.v2);
    let area = edge(a, b, c);
    if (!(area > 0.0)) { return; }
    let e1 = b - a;
    let e2 = c - a;
    let gu = ((t.iz1 - t.iz0) * e2.y - (t.iz2 - t.iz0) * e1.y) / area;
    let gv = ((t.iz2 - t.iz0) * e1.x - (t.iz1 - t.iz0) * e2.x) / area;
    let rf = f32(P.r);
    let lo = min(min(a, b), c);
    let hi = max(max(a, b), c);
    let i0 = max(u32(clamp(ceil(lo.x - 0.5), 0.0, rf)), it.y);
    let i1 = min(u32(clamp(floor(hi.x - 0.5) + 1.0, 0.0, rf)), it.y + 16u);
    let j0 = max(u32(clamp(ceil(lo.y - 0.5), 0.0, rf)), it.z);
    let j1 = min(u32(clamp(floor(hi.y - 0.5) + 1.0, 0.0, rf)), it.z + 16u);
    let own0 = owns_ties(b.x - a.x, b.y - a.y);
    let own1 = owns_ties(c.x - b.x, c.y - b.y);
    let own2 = owns_ties(a.x - c.x, a.y - c.y);
    for (var j = j0; j < j1; j++) {
        for (var i = i0; i < i1; i++) {
            let p = vec2<f32>(f32(i) + 0.5, f32(j) + 0.5);
            let f0 = edge(a, b, p);
            let f1 = edge(b, c, p);
            let f2 = edge(c, a, p);
            let in0 = f0 > 0.0 || (f0 == 0.0 && own0);
            let in1 = f1 > 0.0 || (f1 == 0.0 && own1);
            let in2 = f2 > 0.0 || (f2 == 0.0 && own2);
            if (!(in0 && in1 && in2)) { continue; }
            let iz = t.iz0 + gu * (p.x - a.x) + gv * (p.y - a.y);
            if (!(iz > 0.0)) { continue; }
            // An orthographic view (the sun) interpolates z itself (raster.rs raster_tri).
            var z = 1.0 / iz;
            if (P.ortho != 0u) {
                z = iz;
            }
            let texel = j * P.r + i;
            if (mode == 1u) {
                atomicMin(&head[texel], bitcast<u32>(z));
                continue;
            }
            // Listing 1.2: allocate with the counter, write, exchange the head.
            let e = atomicAdd(&counters.count, 1u);
            if (e == 0xffffffffu) { atomicAdd(&counters.wraps, 1u); }
            if (e >= P.capacity) { continue; } // overflow: counted, never linked
            nodes[e].depth = z;
            nodes[e].alpha = t.alpha;
            nodes[e].tau = 1.0;
            nodes[e].prev = NIL;
            nodes[e].right = NIL;
            nodes[e].upper = NIL;
            nodes[e].next = atomicExchange(&head[texel], e);
        }
    }
}

@compute @workgroup_size(WG)
fn raster(@builtin(workgroup_id) wid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>,
          @builtin(local_invocation_id) lid: vec3<u32>) {
    raster_item(linear_id(wid, nwg, lid), 0u);
}

@compute @workgroup_size(WG)
fn raster_opaque(@builtin(workgroup_id) wid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>,
                 @builtin(local_invocation_id) lid: vec3<u32>) {
    raster_item(linear_id(wid, nwg, lid), 1u);
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
    // Out of the device's loop budget (a long list's selection sort): counted; gpu.rs replaces
    // the whole map by the CPU twin's.
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
// in perspective; in an orthographic view (the sun, gu = gv = 0) q1 = (g0, cu, cv, c)
// (gpu.rs pack_query).
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

// dsm::caster_depth: ReceiverPlane::threshold_at at the centre of texel (i, j): exact where the
// ray descends towards the tangent plane (g > 0), z_p elsewhere.
fn q_threshold(q0: vec4<f32>, q1: vec4<f32>, i: i32, j: i32) -> f32 {
    let gc = q_slope_height(q1, i, j);
    if gc.x > 0.0 {
        return min(gc.y / gc.x, q0.z);
    }
    return q0.z;
}

// dsm::find_by with q_caster in texel (i, j): the last element that is a caster, searched from
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
// find_caster with the plain depth test (dsm::find is dsm::find_by of `z < d` the same way).
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

// dsm::SoftTaps::tap: tau of the last caster of texel (i, j), 1 when none (the opaque path: 0 or
// 1 from the nearest depth).
fn soft_tap(i: i32, j: i32, q0: vec4<f32>, q1: vec4<f32>, opaque: bool) -> TapT {
    let hd = head_at(i, j);
    if (hd == NIL) { return TapT(1.0, 0u); }
    if (opaque) { return TapT(select(1.0, 0.0, q_caster(q0, q1, i, j, bitcast<f32>(hd))), 1u); }
    let f = find_caster(hd, q0, q1, i, j);
    if (f.x == NIL) { return TapT(1.0, f.y); }
    return TapT(nodes[f.x].tau, f.y);
}

// dsm::soft_transmittance (docs/methods.md §8 "Percentage-closer soft transmittance"), the same
// steps in the same order: PCSS's blocker search over the first fragments (search_width), z_avg,
// the kernel width (filter_width), the weighted mean of the taps' T (disk_edge for disk lights).
fn soft_transmittance(q0: vec4<f32>, q1: vec4<f32>, opaque: bool) -> TapT {
    let uv = q0.xy;
    let zr = q0.z;
    let l = vec2<f32>(P.light_x, P.light_y);
    let ws = pcss_search_width(l, zr, P.near, P.to_texels, P.ortho != 0u);
    var steps = 0u;
    var sum = Sum(0.0, 0.0);
    var count = Sum(0.0, 0.0);
    let cy = cells_new(uv.y - 0.5 * ws.y, uv.y + 0.5 * ws.y, P.max_taps);
    for (var ky = 0u; ky < cy.count; ky++) {
        let cj = cell(cy, ky);
        if (!cj.valid) { continue; }
        let cx = cells_new(uv.x - 0.5 * ws.x, uv.x + 0.5 * ws.x, P.max_taps);
        for (var kx = 0u; kx < cx.count; kx++) {
            let ci = cell(cx, kx);
            if (!ci.valid) { continue; }
            let hd = head_at(ci.i, cj.i);
            if (hd == NIL) { continue; }
            var z = 0.0;
            if (opaque) { z = bitcast<f32>(hd); } else { z = nodes[hd].depth; }
            steps++;
            if (q_caster(q0, q1, ci.i, cj.i, z)) {
                let w = ci.w * cj.w;
                sum = sum_add(sum, w * z);
                count = sum_add(count, w);
            }
        }
    }
    if (!(count.s > 0.0)) { return TapT(1.0, steps); }
    let z_avg = sum.s / count.s;
    let wf = pcss_filter_width(l, zr, z_avg, P.near, P.to_texels, P.ortho != 0u);
    var lit = Sum(0.0, 0.0);
    var total = Sum(0.0, 0.0);
    let fy = cells_new(uv.y - 0.5 * wf.y, uv.y + 0.5 * wf.y, P.max_taps);
    for (var ky = 0u; ky < fy.count; ky++) {
        let cj = cell(fy, ky);
        if (!cj.valid) { continue; }
        let fx = cells_new(uv.x - 0.5 * wf.x, uv.x + 0.5 * wf.x, P.max_taps);
        for (var kx = 0u; kx < fx.count; kx++) {
            let ci = cell(fx, kx);
            if (!ci.valid) { continue; }
            var edge = 1.0;
            if (P.disk != 0u && wf.x > 1.0) {
                let rad = 0.5 * wf.x;
                let c = vec2<f32>(f32(ci.i) + 0.5, f32(cj.i) + 0.5) - uv;
                edge = clamp(rad + 0.5 - sqrt(c.x * c.x + c.y * c.y), 0.0, 1.0);
            }
            if (edge <= 0.0) { continue; }
            let w = ci.w * cj.w * edge;
            total = sum_add(total, w);
            let tt = soft_tap(ci.i, cj.i, q0, q1, opaque);
            steps += tt.steps;
            if (tt.t != 0.0) { lit = sum_add(lit, w * tt.t); }
        }
    }
    if (!(total.s > 0.0)) { return TapT(1.0, steps); }
    let t = lit.s / total.s;
    if (t == t && abs(t) <= 3.40282347e38) { return TapT(clamp(t, 0.0, 1.0), steps); }
    return TapT(1.0, steps);
}

fn kernel_side() -> i32 {
    if (P.filter_mode == FILTER_PCF || P.filter_mode == FILTER_EDSM) { return i32(max(P.kernel, 1u)); }
    return 1;
}

// §1.3.4, §1.3.5: one query per invocation, as DeepShadowMap::transmittance.
@compute @workgroup_size(WG)
fn lookup(@builtin(workgroup_id) wid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>,
          @builtin(local_invocation_id) lid: vec3<u32>) {
    let q_id = linear_id(wid, nwg, lid);
    if (q_id >= P.n_queries) { return; }
    out_t[q_id] = lookup_result(list_transmittance(queries[2u * q_id], queries[2u * q_id + 1u]));
}

// The transmittance of one query (q = (u, v, z_p, fixed), q1 the caster test; gpu.rs
// PackedQuery) in the lists, its list steps added to counters.steps. `lookup` and the engine
// path's `frame_lookup` both call it.
fn list_transmittance(q: vec4<f32>, q1: vec4<f32>) -> f32 {
    if (q.w >= 0.0) { return q.w; }
    if (P.filter_mode == FILTER_PCSS) {
        let tt = soft_transmittance(q, q1, false);
        atomicAdd(&counters.steps, tt.steps);
        return -q.w * tt.t;
    }
    let r = i32(P.r);
    let ci = i32(floor(q.x));
    let cj = i32(floor(q.y));
    let n = kernel_side();
    let hk = n / 2;
    var sum = 0.0;
    var steps = 0u;
    var row_anchor = NIL;
    for (var b = 0; b < n; b++) {
        let j = cj - hk + b;
        var anchor = NIL;
        for (var a = 0; a < n; a++) {
            let i = ci - hk + a;
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
            if (P.filter_mode == FILTER_FIRST) {
                steps++;
                if (!q_caster(q, q1, i, j, nodes[hd].depth)) { sum += 1.0; }
                continue;
            }
            var start = hd;
            if (P.traversal == 0u) {
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
            if (P.filter_mode == FILTER_EDSM) {
                d = q_threshold(q, q1, i, j);
                f = find(start, d);
            } else {
                f = find_caster(start, q, q1, i, j);
            }
            let k = f.x;
            steps += f.y;
            if (P.filter_mode == FILTER_EDSM) {
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

// A lookup's result, or CUT_BITS (counted) when the device's loop budget cut the invocation
// short (long lists under the naive walk, large kernels): gpu.rs redoes it on the CPU.
fn lookup_result(t: f32) -> f32 {
    if (loop_limit_hit(P.probe)) {
        atomicAdd(&counters.cut, 1u);
        return bitcast<f32>(CUT_BITS);
    }
    return t;
}

// The opaque path's transmittance of one query (q0 = (u, v, z_p, fixed), q1 the caster test;
// gpu.rs PackedQuery): head[] holds the nearest depth's bits (NIL: empty), no lists. `lookup_opaque`
// and the engine path's `frame_lookup` both call it.
fn opaque_transmittance(q: vec4<f32>, q1: vec4<f32>) -> f32 {
    if (q.w >= 0.0) { return q.w; }
    if (P.filter_mode == FILTER_PCSS) {
        return -q.w * soft_transmittance(q, q1, true).t;
    }
    let r = i32(P.r);
    let ci = i32(floor(q.x));
    let cj = i32(floor(q.y));
    let n = kernel_side();
    let hk = n / 2;
    var sum = 0.0;
    for (var b = 0; b < n; b++) {
        for (var a = 0; a < n; a++) {
            let i = ci - hk + a;
            let j = cj - hk + b;
            var lit = 1.0;
            if (i >= 0 && j >= 0 && i < r && j < r) {
                let bits = atomicLoad(&head[u32(j * r + i)]);
                if (bits != NIL) {
                    let z = bitcast<f32>(bits);
                    if (q_caster(q, q1, i, j, z)) {
                        lit = 0.0;
                        if (P.filter_mode == FILTER_EDSM) {
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

@compute @workgroup_size(WG)
fn lookup_opaque(@builtin(workgroup_id) wid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>,
                 @builtin(local_invocation_id) lid: vec3<u32>) {
    let q_id = linear_id(wid, nwg, lid);
    if (q_id >= P.n_queries) { return; }
    out_t[q_id] = lookup_result(opaque_transmittance(queries[2u * q_id], queries[2u * q_id + 1u]));
}

// The in-run ceiling of the build: P.n_items bare list inserts (counter + head exchange + one
// element write) at hashed texels, nothing else. Measured by GpuDeepShadow::insert_ceiling.
@compute @workgroup_size(WG)
fn ceiling_insert(@builtin(workgroup_id) wid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>,
                  @builtin(local_invocation_id) lid: vec3<u32>) {
    let k = linear_id(wid, nwg, lid);
    if (k >= P.n_items) { return; }
    var x = k * 747796405u + 2891336453u;
    x = ((x >> ((x >> 28u) + 4u)) ^ x) * 277803737u;
    x = (x >> 22u) ^ x;
    let e = atomicAdd(&counters.count, 1u);
    if (e >= P.capacity) { return; }
    nodes[e].depth = f32(k);
    nodes[e].next = atomicExchange(&head[x % (P.r * P.r)], e);
}
