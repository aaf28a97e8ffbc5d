// Twin of crates/packet-hsm/src/contour.rs (per-pixel GBP07, hierarchical extraction with an
// explicit stack, Yang 2009 Algorithm 3) and of cpu.rs's kernel_cells and trivial classification,
// in f32. One invocation per receiver.
//
// Known differences from the CPU: the light-plane geometry (backprojection, clipping, sectors) and
// the sum over edges are f32 here (f64 on the CPU); the backprojection gap is floored at 1e-7 z_p
// (1e-12 z_p on the CPU); the nudge of a receiver on a cell boundary is added in f32.

// Mirrors gpu.rs HsmUniform field for field.
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
    count: u32,
    base: u32,
}

// Mirrors gpu.rs RecIn: texel coordinates, depth z_p and classification threshold t_p;
// zp <= 0 marks a receiver the CPU already settled (not evaluated here).
struct RecIn {
    uv: vec2<f32>,
    zp: f32,
    t: f32,
}

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
@group(0) @binding(6) var<storage, read> recs: array<RecIn>;
// Per receiver: V before the facing factor, nodes visited.
@group(0) @binding(7) var<storage, read_write> v_out: array<vec2<f32>>;

const F32_MAX: f32 = 3.40282347e38;
const F32_MIN_POSITIVE: f32 = 1.17549435e-38;
const STACK: u32 = 64u;

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

// Mssm::query (min only) over samples [x0, x1) x [y0, y1), clamped.
fn mssm_query_min(ax0: i32, ay0: i32, ax1: i32, ay1: i32) -> f32 {
    let s = i32(u.r);
    let x0 = clamp(ax0, 0, s);
    let y0 = clamp(ay0, 0, s);
    let x1 = clamp(ax1, 0, s);
    let y1 = clamp(ay1, 0, s);
    if !(x0 < x1 && y0 < y1) {
        return pos_inf();
    }
    let m = u32(min(x1 - x0, y1 - y0));
    let l = min(floor_log2(m), u.mssm_levels - 1u);
    let h = i32(1u << l);
    let lastx = max(x1 - h, x0);
    let lasty = max(y1 - h, y0);
    let off = l * u.r * u.r;
    var acc = pos_inf();
    var y = y0;
    loop {
        var x = x0;
        loop {
            acc = min(acc, mssm_min[off + u32(y) * u.r + u32(x)]);
            if x >= lastx {
                break;
            }
            x = min(x + h, lastx);
        }
        if y >= lasty {
            break;
        }
        y = min(y + h, lasty);
    }
    return acc;
}

// PaddedDualMssm::query over cells cr (unpadded anchors): exact min/max of the touched samples.
fn dual_query(cr: vec4<i32>) -> vec2<f32> {
    let s = i32(u.padded);
    let x0 = clamp(cr.x + 1, 0, s);
    let y0 = clamp(cr.y + 1, 0, s);
    let x1 = clamp(cr.z + 1, 0, s);
    let y1 = clamp(cr.w + 1, 0, s);
    if !(x0 < x1 && y0 < y1) {
        return vec2<f32>(pos_inf(), -pos_inf());
    }
    let m = u32(min(x1 - x0, y1 - y0));
    let l = min(floor_log2(m), u.dual_levels - 1u);
    let h = i32(1u << l);
    let lastx = max(x1 - h, x0);
    let lasty = max(y1 - h, y0);
    let off = l * u.padded * u.padded;
    var acc = vec2<f32>(pos_inf(), -pos_inf());
    var y = y0;
    loop {
        var x = x0;
        loop {
            let k = off + u32(y) * u.padded + u32(x);
            acc = vec2<f32>(min(acc.x, dual_min[k]), max(acc.y, dual_max[k]));
            if x >= lastx {
                break;
            }
            x = min(x + h, lastx);
        }
        if y >= lasty {
            break;
        }
        y = min(y + h, lasty);
    }
    return acc;
}

// cpu.rs kernel_cells; w < 0 in the result's first component flags "lit" (no kernel).
fn kernel_cells(uv: vec2<f32>, zp: f32, valid: ptr<function, bool>) -> vec4<i32> {
    let r = f32(u.r);
    let lx = 2.0 * u.hx;
    let ly = 2.0 * u.hy;
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

fn kernel_rect(uv: vec2<f32>, zp: f32, zm: f32, lx: f32, ly: f32, r: f32) -> vec4<i32> {
    let wx = kernel_width(u.alpha, lx, zm, zp);
    let wy = kernel_width(u.alpha, ly, zm, zp);
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

// contour::cell_edges with the corners' occluder flags (bit k = corner k) and depths.
fn cell_edges(i: i32, j: i32, occ: u32, z: vec4<f32>) -> Cell {
    var c: Cell;
    c.n = 0u;
    c.occ0 = (occ & 1u) != 0u;
    let nocc = countOneBits(occ);
    if nocc == 0u || nocc == 4u {
        return c;
    }
    let saddle = nocc == 2u && (occ == 5u || occ == 10u);
    for (var s = 0u; s < 4u; s++) {
        let s1 = (s + 1u) % 4u;
        let os = (occ >> s) & 1u;
        let os1 = (occ >> s1) & 1u;
        if os == 1u && os1 == 0u {
            var e = s1;
            if !saddle {
                for (var t = 0u; t < 4u; t++) {
                    let t1 = (t + 1u) % 4u;
                    if ((occ >> t) & 1u) == 0u && ((occ >> t1) & 1u) == 1u {
                        e = t;
                        break;
                    }
                }
            }
            var ed: Edge;
            ed.a = side_mid(i, j, s);
            ed.za = z[s];
            ed.b = side_mid(i, j, e);
            // The occluder corner of side e is e + 1 (free -> occluder).
            ed.zb = z[(e + 1u) % 4u];
            if c.n == 0u {
                c.e0 = ed;
            } else {
                c.e1 = ed;
            }
            c.n += 1u;
        }
    }
    return c;
}

fn cell_at(i: i32, j: i32, t: f32) -> Cell {
    let s0 = sample(i, j);
    let s1 = sample(i + 1, j);
    let s2 = sample(i + 1, j + 1);
    let s3 = sample(i, j + 1);
    var occ = 0u;
    if s0.y < t {
        occ |= 1u;
    }
    if s1.y < t {
        occ |= 2u;
    }
    if s2.y < t {
        occ |= 4u;
    }
    if s3.y < t {
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
fn centre_status(q: vec2<f32>, t: f32) -> u32 {
    let fi = floor(q.x - 0.5);
    let fj = floor(q.y - 0.5);
    if fi == q.x - 0.5 || fj == q.y - 0.5 {
        return 2u;
    }
    let c = cell_at(i32(fi), i32(fj), t);
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
    let s = u.k * zs * (zp / gap);
    return (p - q) * s;
}

// contour::sector_rect.
fn sector_rect(a: vec2<f32>, b: vec2<f32>) -> f32 {
    let dth = atan2(cross2(a, b), dot(a, b));
    if dth == 0.0 || all(a == vec2<f32>(0.0)) || all(b == vec2<f32>(0.0)) {
        return 0.0;
    }
    let h = vec2<f32>(u.hx, u.hy);
    let ar = a / max(abs(a.x) / h.x, abs(a.y) / h.y);
    let br = b / max(abs(b.x) / h.x, abs(b.y) / h.y);
    let tha = atan2(a.y, a.x);
    let tau = 6.28318530717958647;
    var cs = array<vec2<f32>, 4>(
        vec2<f32>(h.x, h.y),
        vec2<f32>(-h.x, h.y),
        vec2<f32>(-h.x, -h.y),
        vec2<f32>(h.x, -h.y),
    );
    var off = array<f32, 4>(-1.0, -1.0, -1.0, -1.0);
    for (var i = 0u; i < 4u; i++) {
        let thc = atan2(cs[i].y, cs[i].x);
        var o: f32;
        if dth > 0.0 {
            o = thc - tha;
        } else {
            o = tha - thc;
        }
        o = o - tau * floor(o / tau);
        if o > 0.0 && o < abs(dth) {
            off[i] = o;
        }
    }
    var prev = ar;
    var twice = 0.0;
    var used = array<bool, 4>(false, false, false, false);
    for (var n = 0u; n < 4u; n++) {
        var best = 4u;
        for (var i = 0u; i < 4u; i++) {
            if off[i] > 0.0 && !used[i] && (best == 4u || off[i] < off[best]) {
                best = i;
            }
        }
        if best == 4u {
            break;
        }
        used[best] = true;
        twice += cross2(prev, cs[best]);
        prev = cs[best];
    }
    twice += cross2(prev, br);
    return 0.5 * twice;
}

// contour::edge_area: tri - sector of the clipped backprojected edge.
fn edge_area(e: Edge, q: vec2<f32>, zp: f32) -> f32 {
    let a = backproject(e.a, e.za, q, zp);
    let b = backproject(e.b, e.zb, q, zp);
    let d = b - a;
    var t0 = 0.0;
    var t1 = 1.0;
    let ps = array<f32, 4>(-d.x, d.x, -d.y, d.y);
    let qs = array<f32, 4>(a.x + u.hx, u.hx - a.x, a.y + u.hy, u.hy - a.y);
    for (var i = 0u; i < 4u; i++) {
        let p = ps[i];
        let qq = qs[i];
        if p == 0.0 {
            if qq < 0.0 {
                return 0.0;
            }
        } else {
            let r = qq / p;
            if p < 0.0 {
                t0 = max(t0, r);
            } else {
                t1 = min(t1, r);
            }
        }
    }
    if !(t0 <= t1) {
        return 0.0;
    }
    let ca = a + d * t0;
    let cb = a + d * t1;
    return 0.5 * cross2(ca, cb) - sector_rect(ca, cb);
}

fn cell_area(i: i32, j: i32, t: f32, q: vec2<f32>, zp: f32) -> f32 {
    let c = cell_at(i, j, t);
    var s = 0.0;
    if c.n >= 1u {
        s += edge_area(c.e0, q, zp);
    }
    if c.n == 2u {
        s += edge_area(c.e1, q, zp);
    }
    return s;
}

@compute @workgroup_size(64)
fn estimate(@builtin(global_invocation_id) gid: vec3<u32>) {
    let idx = u.base + gid.x;
    if gid.x >= u.count {
        return;
    }
    let rec = recs[idx];
    if !(rec.zp > 0.0) {
        v_out[idx] = vec2<f32>(0.0, 0.0);
        return;
    }
    var valid = false;
    let cr = kernel_cells(rec.uv, rec.zp, &valid);
    if !valid {
        v_out[idx] = vec2<f32>(1.0, 0.0);
        return;
    }
    let mm = dual_query(cr);
    if !(mm.x < rec.t) {
        v_out[idx] = vec2<f32>(1.0, 0.0);
        return;
    }
    if mm.y < rec.t {
        v_out[idx] = vec2<f32>(0.0, 0.0);
        return;
    }
    // Centre status with the nudge of contour::Receiver::new.
    var q = rec.uv;
    var centre = 2u;
    for (var it = 0; it < 8; it++) {
        centre = centre_status(q, rec.t);
        if centre != 2u {
            break;
        }
        q += vec2<f32>(1.0 / 4096.0, 1.0 / 8192.0);
    }
    if centre == 2u {
        let s = sample(i32(floor(q.x)), i32(floor(q.y)));
        centre = select(0u, 1u, s.y < rec.t);
    }
    var sum = 0.0;
    var visited = 0u;
    if u.hierarchy == 0u {
        for (var j = cr.y; j < cr.w; j++) {
            for (var i = cr.x; i < cr.z; i++) {
                visited += 1u;
                sum += cell_area(i, j, rec.t, q, rec.zp);
            }
        }
    } else {
        var stack: array<vec3<i32>, STACK>;
        var sp = 0u;
        let top = u.dual_levels - 1u;
        let span = u32(max(cr.z - cr.x, cr.w - cr.y));
        var want = 0u;
        if span > 1u {
            want = 32u - countLeadingZeros(span - 1u);
        }
        let l0 = min(want, top);
        let step = i32(1u << l0);
        let x0 = cr.x + 1;
        let y0 = cr.y + 1;
        let x1 = cr.z + 1;
        let y1 = cr.w + 1;
        for (var y = y0; y < y1; y += step) {
            for (var x = x0; x < x1; x += step) {
                if sp < STACK {
                    stack[sp] = vec3<i32>(x, y, i32(l0));
                    sp += 1u;
                }
            }
        }
        loop {
            if sp == 0u {
                break;
            }
            sp -= 1u;
            let nd = stack[sp];
            visited += 1u;
            let l = u32(nd.z);
            var mn = pos_inf();
            var mx = -pos_inf();
            if u32(nd.x) < u.padded && u32(nd.y) < u.padded {
                let k = l * u.padded * u.padded + u32(nd.y) * u.padded + u32(nd.x);
                mn = dual_min[k];
                mx = dual_max[k];
            }
            // Fig. 6 cases 4 and 5: no contour below this node.
            if mx < rec.t || !(mn < rec.t) {
                continue;
            }
            if l == 0u {
                sum += cell_area(nd.x - 1, nd.y - 1, rec.t, q, rec.zp);
                continue;
            }
            let h = i32(1u << (l - 1u));
            let kids = array<vec2<i32>, 4>(vec2<i32>(h, h), vec2<i32>(0, h), vec2<i32>(h, 0), vec2<i32>(0, 0));
            for (var c = 0u; c < 4u; c++) {
                let cx = nd.x + kids[c].x;
                let cy = nd.y + kids[c].y;
                if cx < x1 && cy < y1 && sp < STACK {
                    stack[sp] = vec3<i32>(cx, cy, i32(l) - 1);
                    sp += 1u;
                }
            }
        }
    }
    let al = 4.0 * u.hx * u.hy;
    var a = sum;
    if centre == 1u {
        a += al;
    }
    var v = 1.0 - clamp(a / al, 0.0, 1.0);
    if !(v >= 0.0 && v <= 1.0) {
        v = select(1.0, 0.0, centre == 1u);
    }
    v_out[idx] = vec2<f32>(v, f32(visited));
}
