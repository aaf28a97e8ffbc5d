// Twin of crates/packet-hsm/src/math/contour.rs (per-pixel GBP07, hierarchical extraction, Yang
// 2009 Algorithm 3, walked without a stack) and of cpu.rs's kernel_cells and trivial
// classification, in f32. Two entry points (packet_hsm_passes.wgsl), dispatched in order after
// the frame's set-up pass (packet_hsm_frame.wgsl `frame_setup`) wrote each receiver's RecIn:
// `prepare` (one invocation per receiver: kernel, lit / umbra, centre status; penumbra receivers
// queued), `pixels` (one per queued receiver: per-pixel GBP07).
//
// Prepended: the core's disk_edge.wgsl (edge_disk_area, disk_wedge) and silhouette.wgsl
// (silhouette_carry).
//
// Known differences from the CPU: the light-plane geometry (backprojection, clipping, sectors) and
// the sum over edges are f32 here (f64 on the CPU); the backprojection gap is floored at 1e-7 z_p
// (1e-12 z_p on the CPU); the nudge of a receiver on a cell boundary is added in f32.

// Mirrors kernel.rs HsmUniform field for field.
// Threads per workgroup, set from Rust (kernel::WORKGROUP) as a pipeline override.
override WG: u32;
// The view's switches, `HsmUniform`'s fields of the same names passed as pipeline overrides
// (kernel::switches): a lane-predicated device then runs no branch a view does not take.
override HSM_SHAPE: u32 = 0u;
override HSM_ORTHO: bool = false;
override HSM_PLANE: bool = false;
override HSM_CLASS_IS_DEPTH: bool = false;
override HSM_HIERARCHY: bool = true;

struct HsmUniform {
    r: u32,
    padded: u32,
    mssm_levels: u32,
    dual_levels: u32,
    alpha: f32,
    n: f32,
    k: f32,
    hierarchy: u32,
    hx: f32,
    hy: f32,
    // Steps of a receiver's walk a round of `pixels` takes at most.
    walk_budget: u32,
    // Always 2: the trip count of the loop-limit probe (a uniform, so it is not unrolled).
    probe: u32,
    // 1: receiver-plane rejection (RecIn's plane); 0: the classic test c_s < t_p.
    receiver_plane: u32,
    // 1: the classification depths are the true depths (self_shadow=bias).
    class_is_depth: u32,
    // kernel.rs SHAPE_*: 0 rect, 1 disk of radius hx, 2 sphere of radius hx (RecIn's silhouette).
    shape: u32,
    // 1: an orthographic view (the sun): k is the texel pitch, kernels the occluder prism's
    // width, and RecIn's (gu, gv) hold the plane's (cu, cv).
    ortho: u32,
}

// Per-receiver state between the passes (mirrors kernel.rs PrepGpu).
struct PrepGpu {
    cr: vec4<i32>,
    q: vec2<f32>,
    // STATE_*.
    state: u32,
    centre: u32,
    // The walk's place between rounds of `pixels` (packet_hsm_passes.wgsl) and the nodes or
    // cells visited so far (w).
    walk: vec4<u32>,
}

const STATE_DONE: u32 = 0u;
const STATE_PENUMBRA: u32 = 2u;

@group(0) @binding(0) var<uniform> u: HsmUniform;
// True linear depths, r x r.
@group(0) @binding(1) var<storage, read> depth: array<f32>;
// Classification depths (midpoints or true depths), r x r.
@group(0) @binding(2) var<storage, read> class_z: array<f32>;
// Anchored MSSM min planes of the true depths, level-major (level l at l r^2).
@group(0) @binding(3) var<storage, read> mssm_min: array<f32>;
// Padded dual-grid MSSM of the classification depths, (r+2)^2 per level, min and max.
@group(0) @binding(4) var<storage, read> dual_min: array<f32>;
@group(0) @binding(5) var<storage, read> dual_max: array<f32>;
// Bindings 6 to 8 hold one range of receivers (gpu.rs ReceiverRange): the passes run over
// arrayLength(&prep).
@group(0) @binding(6) var<storage, read> recs: array<RecIn>;
// Per receiver: V before the facing factor, nodes visited.
@group(0) @binding(7) var<storage, read_write> v_out: array<vec2<f32>>;
@group(0) @binding(8) var<storage, read_write> prep: array<PrepGpu>;
// The penumbra receivers a round of `pixels` walks: their count, the indirect dispatch's
// workgroups (x, y, z; copied into the argument buffer between the passes), their indices.
// `requeue`: the same for the next round (`prepare` fills the first round's).
@group(0) @binding(9) var<storage, read_write> queue: array<atomic<u32>>;
@group(0) @binding(10) var<storage, read_write> requeue: array<atomic<u32>>;
const QUEUE_COUNT: u32 = 0u;
const QUEUE_ARGS: u32 = 1u;
const QUEUE_LIST: u32 = 4u;

// Some devices bound the loop iterations of one invocation: llvmpipe (lavapipe) ends every loop
// once 65535 iterations in all have run (gallivm's LP_MAX_TGSI_LOOP_ITERATIONS), which would
// silently truncate long contour scans. `loop_limit_hit` runs a two-trip loop whose bound is a
// uniform: it trips once only when that budget is spent. Work cut short is flagged (the frame
// leaves those receivers NaN for its caller to redo), never returned as V.
fn loop_limit_hit() -> bool {
    var trips = 0u;
    for (var i = 0u; i < u.probe; i++) {
        trips += 1u;
    }
    return trips < u.probe;
}

const TRUNCATED: f32 = -1.0;

const F32_MAX: f32 = 3.40282347e38;
const F32_MIN_POSITIVE: f32 = 1.17549435e-38;

fn pos_inf() -> f32 {
    return bitcast<f32>(0x7f800000u);
}

fn floor_log2(m: u32) -> u32 {
    return 31u - countLeadingZeros(max(m, 1u));
}

// cpu.rs kernel_width (Yang eq. 1).
fn kernel_width(alpha: f32, l: f32, z_m: f32, z_p: f32) -> f32 {
    if !(z_m < z_p) {
        return 0.0;
    }
    let zm = max(z_m, F32_MIN_POSITIVE);
    let w = alpha * l * (1.0 / zm - 1.0 / z_p);
    if w <= F32_MAX && w >= -F32_MAX {
        return max(w, 0.0);
    }
    return F32_MAX;
}

// The anchors an MSSM query over samples [x0, x1) x [y0, y1) (clamped to [0, side]) reads: level
// l = min(floor(log2(shorter side)), levels - 1), anchors h = 2^l apart from (x0, y0), the last
// column and row at x1 - h and y1 - h (Mssm::query and PaddedDualMssm::query alike). `first` is
// the first anchor, `last` the last; `ok` false for an empty rectangle.
struct Anchors {
    first: vec2<i32>,
    last: vec2<i32>,
    h: i32,
    off: u32,
    side: u32,
    ok: bool,
}

fn anchors(ax0: i32, ay0: i32, ax1: i32, ay1: i32, side: u32, levels: u32) -> Anchors {
    let s = i32(side);
    let lo = clamp(vec2<i32>(ax0, ay0), vec2<i32>(0), vec2<i32>(s));
    let hi = clamp(vec2<i32>(ax1, ay1), vec2<i32>(0), vec2<i32>(s));
    let ok = lo.x < hi.x && lo.y < hi.y;
    let m = u32(max(min(hi.x - lo.x, hi.y - lo.y), 1));
    let l = min(floor_log2(m), levels - 1u);
    let h = i32(1u << l);
    return Anchors(lo, max(hi - vec2<i32>(h), lo), h, l * side * side, side, ok);
}

// The element of anchor p in its level.
fn anchor_index(a: Anchors, p: vec2<i32>) -> u32 {
    return a.off + u32(p.y) * a.side + u32(p.x);
}

// The anchor after p, row by row (the CPU's order): one loop over the anchors instead of a loop
// per row (on lavapipe each loop costs however few trips it takes).
fn anchor_next(a: Anchors, p: vec2<i32>) -> vec2<i32> {
    if p.x < a.last.x {
        return vec2<i32>(min(p.x + a.h, a.last.x), p.y);
    }
    return vec2<i32>(a.first.x, min(p.y + a.h, a.last.y));
}

// Mssm::query (min only) over samples [x0, x1) x [y0, y1), clamped.
fn mssm_query_min(ax0: i32, ay0: i32, ax1: i32, ay1: i32) -> f32 {
    let a = anchors(ax0, ay0, ax1, ay1, u.r, u.mssm_levels);
    var acc = pos_inf();
    if !a.ok {
        return acc;
    }
    var p = a.first;
    loop {
        acc = min(acc, mssm_min[anchor_index(a, p)]);
        if all(p >= a.last) {
            break;
        }
        p = anchor_next(a, p);
    }
    return acc;
}

// PaddedDualMssm::query over cells cr (unpadded anchors): exact min/max of the touched samples.
fn dual_query(cr: vec4<i32>) -> vec2<f32> {
    let a = anchors(cr.x + 1, cr.y + 1, cr.z + 1, cr.w + 1, u.padded, u.dual_levels);
    var acc = vec2<f32>(pos_inf(), -pos_inf());
    if !a.ok {
        return acc;
    }
    var p = a.first;
    loop {
        let k = anchor_index(a, p);
        acc = vec2<f32>(min(acc.x, dual_min[k]), max(acc.y, dual_max[k]));
        if all(p >= a.last) {
            break;
        }
        p = anchor_next(a, p);
    }
    return acc;
}

// cpu.rs kernel_light: the light size of the kernel (a sphere's from its silhouette's clip
// rectangle).
fn kernel_light(rec: RecIn) -> vec2<f32> {
    if HSM_SHAPE == SHAPE_SPHERE {
        let c = rec.sil_clip;
        return 2.0 * vec2<f32>(max(abs(c.x), abs(c.z)), max(abs(c.y), abs(c.w)));
    }
    return 2.0 * vec2<f32>(u.hx, u.hy);
}

// cpu.rs kernel_cells; w < 0 in the result's first component flags "lit" (no kernel).
fn kernel_cells(rec: RecIn, valid: ptr<function, bool>) -> vec4<i32> {
    let uv = rec.uv;
    let zp = rec.zp;
    let r = f32(u.r);
    let l = kernel_light(rec);
    let lx = l.x;
    let ly = l.y;
    var zm = u.n;
    var s = kernel_rect(uv, zp, zm, lx, ly, r);
    for (var it = 0; it < 16; it++) {
        let zmin = mssm_query_min(s.x - 1, s.y - 1, s.z + 1, s.w + 1);
        if !(zmin < zp) {
            *valid = false;
            return s;
        }
        if !(zmin > zm) {
            break;
        }
        zm = zmin;
        let next = kernel_rect(uv, zp, zm, lx, ly, r);
        let an = (next.z - next.x) * (next.w - next.y);
        let a = (s.z - s.x) * (s.w - s.y);
        if an >= a {
            break;
        }
        s = next;
    }
    if s.x >= s.z || s.y >= s.w {
        *valid = false;
        return s;
    }
    *valid = true;
    return vec4<i32>(s.x - 1, s.y - 1, s.z, s.w);
}

// LightView::kernel_texels: Yang eq. 1, or for the sun l (z_p - z_m) / delta.
fn kernel_texels(l: f32, zm: f32, zp: f32) -> f32 {
    if !HSM_ORTHO {
        return kernel_width(u.alpha, l, zm, zp);
    }
    if !(zm < zp) {
        return 0.0;
    }
    let w = l * (zp - zm) / u.k;
    if w <= F32_MAX && w >= -F32_MAX {
        return max(w, 0.0);
    }
    return F32_MAX;
}

fn kernel_rect(uv: vec2<f32>, zp: f32, zm: f32, lx: f32, ly: f32, r: f32) -> vec4<i32> {
    let wx = kernel_texels(lx, zm, zp);
    let wy = kernel_texels(ly, zm, zp);
    return vec4<i32>(
        i32(clamp(floor(uv.x - 0.5 * wx), 0.0, r)),
        i32(clamp(floor(uv.y - 0.5 * wy), 0.0, r)),
        i32(clamp(ceil(uv.x + 0.5 * wx), 0.0, r)),
        i32(clamp(ceil(uv.y + 0.5 * wy), 0.0, r)),
    );
}

// SampleGrid::at: (true depth, classification depth); +inf outside the map.
fn sample(i: i32, j: i32) -> vec2<f32> {
    let r = i32(u.r);
    if i < 0 || j < 0 || i >= r || j >= r {
        return vec2<f32>(pos_inf(), pos_inf());
    }
    let k = u32(j) * u.r + u32(i);
    return vec2<f32>(depth[k], class_z[k]);
}

fn finite(x: f32) -> bool {
    return x == x && abs(x) <= F32_MAX;
}

// contour::OccluderTest::occludes for receiver rec and sample (i, j) = (true, class depth) s.
fn occludes(rec: RecIn, i: i32, j: i32, s: vec2<f32>) -> bool {
    if !(s.y < rec.t) {
        return false;
    }
    if !HSM_PLANE {
        return true;
    }
    let gc = plane_gc(rec, vec2<f32>(f32(i) + 0.5, f32(j) + 0.5));
    return finite(s.x) && s.x < rec.zp && s.x * gc.x < gc.y;
}

// ReceiverPlane's slope and height at uv: (g0 + gu u + gv v, c) in perspective, (g0, c + cu u +
// cv v) in an orthographic view (packet_hsm_frame.wgsl's set-up packs cu, cv where gu, gv go).
fn plane_gc(rec: RecIn, uv: vec2<f32>) -> vec2<f32> {
    let lin = rec.gu * uv.x + rec.gv * uv.y;
    if HSM_ORTHO {
        return vec2<f32>(rec.g0, rec.c + lin);
    }
    return vec2<f32>(rec.g0 + lin, rec.c);
}

// contour::caster_bounds: (lower, upper) depth bounds of rec's caster test on the ray through uv.
fn caster_bounds(rec: RecIn, uv: vec2<f32>) -> vec2<f32> {
    let gc = plane_gc(rec, uv);
    let g = gc.x;
    if g > 0.0 {
        let t = min(gc.y / g, rec.zp);
        return vec2<f32>(t, t);
    }
    if gc.y > 0.0 {
        return vec2<f32>(rec.zp, rec.zp);
    }
    return vec2<f32>(-pos_inf(), rec.zp);
}

// contour::plane_threshold_range for one receiver, before the margin: (min lower, max upper) over
// the centres of samples [s.x, s.z] x [s.y, s.w].
fn threshold_range(rec: RecIn, s: vec4<i32>) -> vec2<f32> {
    let u0 = f32(s.x) + 0.5;
    let u1 = f32(s.z) + 0.5;
    let v0 = f32(s.y) + 0.5;
    let v1 = f32(s.w) + 0.5;
    let a = caster_bounds(rec, vec2<f32>(u0, v0));
    let b = caster_bounds(rec, vec2<f32>(u1, v0));
    let c = caster_bounds(rec, vec2<f32>(u0, v1));
    let d = caster_bounds(rec, vec2<f32>(u1, v1));
    return vec2<f32>(min(min(a.x, b.x), min(c.x, d.x)), max(max(a.y, b.y), max(c.y, d.y)));
}

// contour::PRUNE_MARGIN applied to a threshold range.
const PRUNE_MARGIN: f32 = 1.0 / 1048576.0;
fn widen(r: vec2<f32>) -> vec2<f32> {
    return vec2<f32>(r.x - abs(r.x) * PRUNE_MARGIN, r.y + abs(r.y) * PRUNE_MARGIN);
}

// contour::true_min: the smallest true depth over samples [s.x, s.z] x [s.y, s.w] (inclusive),
// class_min when the classification depths are the true depths, else from the true-depth MSSM.
fn true_min(class_min: f32, s: vec4<i32>) -> f32 {
    if HSM_CLASS_IS_DEPTH {
        return class_min;
    }
    return mssm_query_min(s.x, s.y, s.z + 1, s.w + 1);
}

// A lower bound of true_min over the samples of traversal node s (inclusive, side 2^l + 1),
// without a loop: four taps of the anchored MSSM's level l at the node's corner and one texel
// further, clamped into the map, cover every sample of the node inside the map (a superset, so
// the bound may be lower than true_min: a node is pruned less often, never wrongly, and the
// cells that are then visited have no contour and add nothing).
fn node_true_min(class_min: f32, s: vec4<i32>, l: u32) -> f32 {
    if HSM_CLASS_IS_DEPTH {
        return class_min;
    }
    if l >= u.mssm_levels {
        return -pos_inf();
    }
    let hi = i32(u.r) - 1;
    let x0 = u32(clamp(s.x, 0, hi));
    let x1 = u32(clamp(s.x + 1, 0, hi));
    let y0 = u32(clamp(s.y, 0, hi)) * u.r + l * u.r * u.r;
    let y1 = u32(clamp(s.y + 1, 0, hi)) * u.r + l * u.r * u.r;
    return min(min(mssm_min[y0 + x0], mssm_min[y0 + x1]), min(mssm_min[y1 + x0], mssm_min[y1 + x1]));
}

// contour::Planes::prunable's plane part, given the node's classification range mm, the
// threshold range [tmin, tmax], the threshold range th (widened) over the node's samples and a
// lower bound true_lo of their true depths.
fn plane_prunable(mm: vec2<f32>, tmin: f32, tmax: f32, th: vec2<f32>, true_lo: f32) -> bool {
    if !(mm.x < tmax) {
        return true;
    }
    if mm.y < tmin && mm.y < th.x {
        return true;
    }
    return true_lo >= th.y;
}

struct Edge {
    a: vec2<f32>,
    b: vec2<f32>,
    za: f32,
    zb: f32,
}

struct Cell {
    e0: Edge,
    e1: Edge,
    n: u32,
    occ0: bool,
}

fn side_mid(i: i32, j: i32, s: u32) -> vec2<f32> {
    var d = vec2<f32>(1.0, 0.5);
    if s == 1u {
        d = vec2<f32>(1.5, 1.0);
    } else if s == 2u {
        d = vec2<f32>(1.0, 1.5);
    } else if s == 3u {
        d = vec2<f32>(0.5, 1.0);
    }
    return vec2<f32>(f32(i), f32(j)) + d;
}

// contour::cell_edges with the corners' occluder flags (bit k = corner k) and depths, without a
// loop (on lavapipe every loop trip counts against the invocation's budget): side s runs from
// corner s to corner s + 1, an edge starts on the side going occluder -> free and ends on the
// side going free -> occluder (a saddle: on the next side), edges in the order of their start.
fn cell_edges(i: i32, j: i32, occ: u32, z: vec4<f32>) -> Cell {
    var c: Cell;
    c.n = 0u;
    c.occ0 = (occ & 1u) != 0u;
    let nocc = countOneBits(occ);
    if nocc == 0u || nocc == 4u {
        return c;
    }
    // Bit s: corner s + 1's flag.
    let next = ((occ >> 1u) | (occ << 3u)) & 15u;
    let starts = occ & ~next;
    let ends = ~occ & next & 15u;
    let saddle = nocc == 2u && (occ == 5u || occ == 10u);
    let s0 = firstTrailingBit(starts);
    var e0 = firstTrailingBit(ends);
    if saddle {
        e0 = (s0 + 1u) % 4u;
    }
    c.e0 = cell_edge(i, j, s0, e0, z);
    c.n = 1u;
    if saddle {
        let s1 = firstLeadingBit(starts);
        c.e1 = cell_edge(i, j, s1, (s1 + 1u) % 4u, z);
        c.n = 2u;
    }
    return c;
}

// The edge from side s's midpoint to side e's; the occluder corner of side e is e + 1.
fn cell_edge(i: i32, j: i32, s: u32, e: u32, z: vec4<f32>) -> Edge {
    var ed: Edge;
    ed.a = side_mid(i, j, s);
    ed.za = z[s];
    ed.b = side_mid(i, j, e);
    ed.zb = z[(e + 1u) % 4u];
    return ed;
}

fn cell_at(i: i32, j: i32, rec: RecIn) -> Cell {
    let s0 = sample(i, j);
    let s1 = sample(i + 1, j);
    let s2 = sample(i + 1, j + 1);
    let s3 = sample(i, j + 1);
    var occ = 0u;
    if occludes(rec, i, j, s0) {
        occ |= 1u;
    }
    if occludes(rec, i + 1, j, s1) {
        occ |= 2u;
    }
    if occludes(rec, i + 1, j + 1, s2) {
        occ |= 4u;
    }
    if occludes(rec, i, j + 1, s3) {
        occ |= 8u;
    }
    return cell_edges(i, j, occ, vec4<f32>(s0.x, s1.x, s2.x, s3.x));
}

fn edge_side(e: Edge, q: vec2<f32>) -> f32 {
    let d = e.b - e.a;
    let w = q - e.a;
    return d.x * w.y - d.y * w.x;
}

// contour::centre_status: 1 occluded, 0 free, 2 degenerate (nudge).
fn centre_status(q: vec2<f32>, rec: RecIn) -> u32 {
    let fi = floor(q.x - 0.5);
    let fj = floor(q.y - 0.5);
    if fi == q.x - 0.5 || fj == q.y - 0.5 {
        return 2u;
    }
    let c = cell_at(i32(fi), i32(fj), rec);
    if c.n == 0u {
        return select(0u, 1u, c.occ0);
    }
    var inside = true;
    let s0 = edge_side(c.e0, q);
    if s0 == 0.0 {
        return 2u;
    }
    inside = inside && s0 > 0.0;
    if c.n == 2u {
        let s1 = edge_side(c.e1, q);
        if s1 == 0.0 {
            return 2u;
        }
        inside = inside && s1 > 0.0;
    }
    return select(0u, 1u, inside);
}

fn cross2(a: vec2<f32>, b: vec2<f32>) -> f32 {
    return a.x * b.y - a.y * b.x;
}

fn backproject(p: vec2<f32>, zs: f32, q: vec2<f32>, zp: f32) -> vec2<f32> {
    let gap = max(max(zp - zs, 1e-7 * zp), F32_MIN_POSITIVE);
    // contour::backproject; the sun: onto its disk of directions, k / (z_p - z_s).
    var s = u.k * zs * (zp / gap);
    if HSM_ORTHO {
        s = u.k / gap;
    }
    return (p - q) * s;
}

// contour::sector_rect, without a loop: the rect's corners inside the sweep from a to b, sorted
// by their angle from a (ties by corner index, as the CPU's selection takes them), summed in
// that order.
fn sector_rect(a: vec2<f32>, b: vec2<f32>) -> f32 {
    let dth = atan2(cross2(a, b), dot(a, b));
    if dth == 0.0 || all(a == vec2<f32>(0.0)) || all(b == vec2<f32>(0.0)) {
        return 0.0;
    }
    let h = vec2<f32>(u.hx, u.hy);
    let ar = a / max(abs(a.x) / h.x, abs(a.y) / h.y);
    let br = b / max(abs(b.x) / h.x, abs(b.y) / h.y);
    let tha = atan2(a.y, a.x);
    // (angle from a or +inf outside the sweep, corner index, corner).
    var c0 = swept_corner(vec2<f32>(h.x, h.y), 0.0, tha, dth);
    var c1 = swept_corner(vec2<f32>(-h.x, h.y), 1.0, tha, dth);
    var c2 = swept_corner(vec2<f32>(-h.x, -h.y), 2.0, tha, dth);
    var c3 = swept_corner(vec2<f32>(h.x, -h.y), 3.0, tha, dth);
    sort_pair(&c0, &c1);
    sort_pair(&c2, &c3);
    sort_pair(&c0, &c2);
    sort_pair(&c1, &c3);
    sort_pair(&c1, &c2);
    var prev = ar;
    var twice = 0.0;
    twice += swept_term(&prev, c0);
    twice += swept_term(&prev, c1);
    twice += swept_term(&prev, c2);
    twice += swept_term(&prev, c3);
    twice += cross2(prev, br);
    return 0.5 * twice;
}

// A rect corner c (index k) as sector_rect sorts it: its angle from a in the sweep's direction,
// +inf unless strictly inside the sweep.
fn swept_corner(c: vec2<f32>, k: f32, tha: f32, dth: f32) -> vec4<f32> {
    let tau = 6.28318530717958647;
    let thc = atan2(c.y, c.x);
    var o: f32;
    if dth > 0.0 {
        o = thc - tha;
    } else {
        o = tha - thc;
    }
    o = o - tau * floor(o / tau);
    var key = pos_inf();
    if o > 0.0 && o < abs(dth) {
        key = o;
    }
    return vec4<f32>(key, k, c);
}

// Orders two swept corners by (angle, index).
fn sort_pair(a: ptr<function, vec4<f32>>, b: ptr<function, vec4<f32>>) {
    let x = *a;
    let y = *b;
    if y.x < x.x || (y.x == x.x && y.y < x.y) {
        *a = y;
        *b = x;
    }
}

// One swept corner's term of sector_rect's sum (none outside the sweep).
fn swept_term(prev: ptr<function, vec2<f32>>, c: vec4<f32>) -> f32 {
    if !(c.x < pos_inf()) {
        return 0.0;
    }
    let t = cross2(*prev, c.zw);
    *prev = c.zw;
    return t;
}

// kernel.rs SHAPE_*.
const SHAPE_RECT: u32 = 0u;
const SHAPE_DISK: u32 = 1u;
const SHAPE_SPHERE: u32 = 2u;
const PI: f32 = 3.14159265358979;

// contour::clip_to_rect (Liang-Barsky) on [-h, h]: the clipped ends in xy, zw; ok = false when
// nothing is left.
struct Clipped {
    ends: vec4<f32>,
    ok: bool,
}

fn clip_rect(a: vec2<f32>, b: vec2<f32>, h: vec2<f32>) -> Clipped {
    var out: Clipped;
    out.ok = false;
    out.ends = vec4<f32>(0.0);
    let d = b - a;
    // (t0, t1, 1 once the segment is outside a side it runs parallel to).
    var t = vec3<f32>(0.0, 1.0, 0.0);
    t = clip_side(t, -d.x, a.x + h.x);
    t = clip_side(t, d.x, h.x - a.x);
    t = clip_side(t, -d.y, a.y + h.y);
    t = clip_side(t, d.y, h.y - a.y);
    if t.z != 0.0 || !(t.x <= t.y) {
        return out;
    }
    out.ends = vec4<f32>(a + d * t.x, a + d * t.y);
    out.ok = true;
    return out;
}

// One side of Liang-Barsky's clip: p the segment's component against the side, qq the start's
// distance inside it.
fn clip_side(t: vec3<f32>, p: f32, qq: f32) -> vec3<f32> {
    var o = t;
    if p == 0.0 {
        if qq < 0.0 {
            o.z = 1.0;
        }
    } else {
        let r = qq / p;
        if p < 0.0 {
            o.x = max(o.x, r);
        } else {
            o.y = min(o.y, r);
        }
    }
    return o;
}

// contour::disk_edge_term: clipped to the disk's bounding square, then the core's
// edge_disk_area - disk_wedge.
fn disk_edge_term(a: vec2<f32>, b: vec2<f32>, r: f32) -> f32 {
    let c = clip_rect(a, b, vec2<f32>(r, r));
    if !c.ok {
        return 0.0;
    }
    return edge_disk_area(c.ends.xy, c.ends.zw, r) - disk_wedge(c.ends.xy, c.ends.zw, r);
}

// contour::sphere_edge_term: clipped to the silhouette's clip rectangle of z = 0, carried onto
// the receiver's silhouette plane (the core's silhouette_carry), measured on its disk.
fn sphere_edge_term(a: vec2<f32>, b: vec2<f32>, rec: RecIn) -> f32 {
    let lo = rec.sil_clip.xy;
    let hi = rec.sil_clip.zw;
    let c = 0.5 * (lo + hi);
    let h = 0.5 * (hi - lo);
    let cl = clip_rect(a - c, b - c, h);
    if !cl.ok {
        return 0.0;
    }
    let pa = cl.ends.xy + c;
    let pb = cl.ends.zw + c;
    let sa = rec.sil_a.xyz;
    let e1 = rec.sil_e1.xyz;
    let e2 = rec.sil_e2.xyz;
    let ca = silhouette_carry(sa, e1, e2, rec.sil_a.w, pa.x, pa.y);
    let cb = silhouette_carry(sa, e1, e2, rec.sil_a.w, pb.x, pb.y);
    return disk_edge_term(ca, cb, rec.sil_e1.w);
}

// contour::edge_area: tri - sector of the backprojected edge clipped to the light (rect), on a
// disk (disk_edge_term), or on the receiver's silhouette disk (sphere_edge_term).
fn edge_area(e: Edge, q: vec2<f32>, rec: RecIn) -> f32 {
    let a = backproject(e.a, e.za, q, rec.zp);
    let b = backproject(e.b, e.zb, q, rec.zp);
    if HSM_SHAPE == SHAPE_DISK {
        return disk_edge_term(a, b, u.hx);
    }
    if HSM_SHAPE == SHAPE_SPHERE {
        return sphere_edge_term(a, b, rec);
    }
    let c = clip_rect(a, b, vec2<f32>(u.hx, u.hy));
    if !c.ok {
        return 0.0;
    }
    return 0.5 * cross2(c.ends.xy, c.ends.zw) - sector_rect(c.ends.xy, c.ends.zw);
}

fn cell_area(i: i32, j: i32, rec: RecIn, q: vec2<f32>, zp: f32) -> f32 {
    let c = cell_at(i, j, rec);
    var s = 0.0;
    if c.n >= 1u {
        s += edge_area(c.e0, q, rec);
    }
    if c.n == 2u {
        s += edge_area(c.e1, q, rec);
    }
    return s;
}

