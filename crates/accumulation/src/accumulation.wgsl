// Twin of crates/accumulation/src/cpu.rs (Accumulator) and math.rs, in f32 and in the CPU's
// operation order. Prepended: the core's SHARED_WGSL, the baselines' shared.wgsl and common.wgsl
// (receiver bias, light frames, default_tangent, front_fraction_world).
//
// The patch's hull points and occlusion-bit points come in in-plane coordinates from the CPU
// (`tables`: LightPatch::hull_local then LightPatch::bit_local), so no trigonometry differs.
// The occlusion-bit mask lives in registers (the core's bitmask.wgsl BitMask, 256 bits at most),
// tested with its bitmask_quad_contains.

// Mirrors gpu.rs AccUniform field for field.
struct AccUniform {
    inv_area: f32,
    n_hull: u32,
    bits: u32,
    nbits: u32,
    k: u32,
    kernel: u32,
    variant: u32,
    layers: u32,
    sphere_contract: u32,
    patch_rect: u32,
    overlap: u32,
    phase_x: i32,
    half: vec2<f32>,
    b0: f32,
    b1: f32,
    mssm_present: u32,
    mssm_levels: u32,
    mssm_size: u32,
    phase_y: i32,
    // Always 2: the trip count of the loop-limit probe (`loop_limit_hit`).
    probe: u32,
    // 1 for the sun (math::SunFrame footprints) and its L (math::sun_lift).
    sun: u32,
    lift: f32,
    _pad0: u32,
}

// The uniform's switches as override constants (gpu.rs `specialization`, the same values as
// AccUniform's fields of the same meaning, which the kernel does not read): the pipeline is
// compiled per combination, without the branches it does not take.
override PATCH_RECT: bool = true;
override SUN: bool = false;
override SPHERE_CONTRACT: bool = false;
override EXACT: bool = false;
override OVERLAP: bool = true;
override KERNEL_MODE: u32 = 1u;
override LAYERS: u32 = 1u;
// Derived: the casters' terms are queued (see Casters) unless the term is a rect patch's additive
// overlap or centre test.
override QUEUE_TERMS: bool = !PATCH_RECT || EXACT;
// The first of the frame's two passes: a receiver whose kernel holds cells to visit is deferred
// (shadowing DEFERRED_S) to the second pass, which runs over those receivers only
// (ActiveLists::encode_deferred), so a lit receiver's lane never runs the cells beside a
// penumbra receiver's.
override DEFER_CELLS: bool = false;
const DEFERRED_S: f32 = -2.0;

const KERNEL_FIXED: u32 = 0u;
const KERNEL_ADAPTIVE: u32 = 1u;
const KERNEL_LEXELS: u32 = 2u;
const HULL_SLOTS: u32 = 16u;
const REFINE_ROUNDS: i32 = 16;
// Corner signs of Footprint::caster_quad (counter-clockwise on the plane).
const SX = array<f32, 4>(-1.0, 1.0, 1.0, -1.0);
const SY = array<f32, 4>(-1.0, -1.0, 1.0, 1.0);

@group(0) @binding(0) var<uniform> view: LightViewUniform;
@group(0) @binding(1) var<uniform> est: EstimateUniform;
@group(0) @binding(2) var<uniform> acc: AccUniform;
// Peeled layers (linear light-space depth, +inf where empty).
@group(0) @binding(3) var maps: texture_2d_array<f32>;
// MSSM min planes, one array layer per level.
@group(0) @binding(4) var mssm: texture_2d_array<f32>;
// HULL_SLOTS hull points, then the bit points (in-plane coordinates).
@group(0) @binding(5) var<storage, read> tables: array<vec2<f32>>;
@group(0) @binding(6) var<storage, read> receivers: array<ReceiverGpu>;
@group(0) @binding(7) var<storage, read_write> v_out: array<u32>;
// [0]: lit receivers outside the frustum, [1]: non-finite V, [2]: receivers cut short by the
// device's loop limit (flagged with CUT_BITS, for the caller to redo on the CPU), [3]: outside
// receivers the settle passes could not prove unshadowed (left NaN).
@group(0) @binding(8) var<storage, read_write> counters: array<atomic<u32>, 4>;
// The range's active list (the core's receivers::ActiveLists), read by the core's entry point.
@group(0) @binding(9) var<storage, read> active_list: array<u32>;
// The range's open list (the core's gpu::settle): the outside receivers, for the settle passes.
@group(0) @binding(10) var<storage, read_write> open_list: array<atomic<u32>>;


// The footprint's frame (math::Footprint): in perspective the view's own (fp_n = view.n); for
// the sun (SUN) math::SunFrame, the receiver at (0, 0, L) (L = acc.lift) and the
// footprint's plane at L / 2, view point (x, y, z) at (x - fp_o.x, y - fp_o.y, z - fp_dz). Set
// per receiver by estimate_receiver.
var<private> fp_n: f32;
var<private> fp_o: vec2<f32>;
var<private> fp_dz: f32;

// math::LightPatch.
struct Patch {
    a: vec3<f32>,
    e1: vec3<f32>,
    e2: vec3<f32>,
}

// LightPatch::for_receiver.
fn patch_for(r: vec3<f32>) -> Patch {
    var p = Patch(vec3<f32>(0.0, 0.0, 1.0), vec3<f32>(1.0, 0.0, 0.0), vec3<f32>(0.0, 1.0, 0.0));
    if SPHERE_CONTRACT {
        let rcp = valid_rcp(r);
        if rcp != 0.0 {
            let a = r * rcp;
            let e1 = default_tangent(a);
            p = Patch(a, e1, cross3(a, e1));
        }
    }
    return p;
}

// LightPatch::embed.
fn embed(p: Patch, l: vec2<f32>) -> vec3<f32> {
    return p.e1 * l.x + p.e2 * l.y;
}

// LightPatch::contains.
fn patch_contains(l: vec2<f32>) -> bool {
    if PATCH_RECT {
        return abs(l.x) <= acc.half.x && abs(l.y) <= acc.half.y;
    }
    return dot2(l, l) <= acc.half.x * acc.half.x;
}

// LightPatch::max_z.
fn patch_max_z(p: Patch) -> f32 {
    if PATCH_RECT {
        return acc.half.x * abs(p.e1.z) + acc.half.y * abs(p.e2.z);
    }
    return acc.half.x * sqrt(max(1.0 - p.a.z * p.a.z, 0.0));
}

// Footprint::at_depth: the point at depth c on the line from r through light point x.
fn at_depth(r: vec3<f32>, x: vec3<f32>, c: f32) -> vec2<f32> {
    let s = (r.z - c) / (r.z - x.z);
    let r2 = vec2<f32>(r.x, r.y);
    return r2 + (vec2<f32>(x.x, x.y) - r2) * s;
}

// math::FrontEdge: the receiver's tangent plane on the patch (in-plane coordinates x in front
// when a.x > c); whole: every hull point in front; fraction: the patch's front fraction.
struct Front {
    a: vec2<f32>,
    c: f32,
    whole: bool,
    fraction: f32,
}

// FrontEdge::new.
fn front_new(p: Patch, r: vec3<f32>, nrm: vec3<f32>) -> Front {
    let a = vec2<f32>(dot3(nrm, p.e1), dot3(nrm, p.e2));
    let c = dot3(nrm, r);
    var whole = true;
    for (var k = 0u; k < acc.n_hull; k++) {
        if !(dot2(a, tables[k]) > c) {
            whole = false;
        }
    }
    var fraction = 1.0;
    if !whole {
        let pl = vec3<f32>(dot3(r, p.e1), dot3(r, p.e2), dot3(r, p.a));
        let nl = vec3<f32>(a.x, a.y, dot3(nrm, p.a));
        if PATCH_RECT {
            fraction = front_fraction(LIGHT_RECT, 2.0 * acc.half, pl, nl);
        } else {
            fraction = front_fraction(LIGHT_DISK, acc.half, pl, nl);
        }
    }
    return Front(a, c, whole, fraction);
}

fn front_of(f: Front, l: vec2<f32>) -> bool {
    return dot2(f.a, l) > f.c;
}

// FrontEdge::clip.
fn front_clip(f: Front, q: array<vec2<f32>, 4>) -> Poly {
    var out: Poly;
    out.m = 0u;
    for (var k = 0u; k < 4u; k++) {
        let p0 = q[k];
        let p1 = q[(k + 1u) % 4u];
        let f0 = dot2(f.a, p0) - f.c;
        let f1 = dot2(f.a, p1) - f.c;
        if f0 > 0.0 {
            out.q[out.m] = p0;
            out.m += 1u;
        }
        if (f0 > 0.0) != (f1 > 0.0) {
            out.q[out.m] = p0 + (p1 - p0) * (f0 / (f0 - f1));
            out.m += 1u;
        }
    }
    return out;
}

// Footprint::additive_term_front.
fn additive_term(p: Patch, r: vec3<f32>, lr: vec2<f32>, area: f32, f: Front) -> f32 {
    let d = vec3<f32>(lr.x - r.x, lr.y - r.y, fp_n - r.z);
    let da = dot3(d, p.a);
    let u = -dot3(r, p.a) / da;
    if !(u > 0.0) || !is_finite(u) {
        return 0.0;
    }
    let x = r + d * u;
    let local = vec2<f32>(dot3(x, p.e1), dot3(x, p.e2));
    if !patch_contains(local) || !(f.whole || front_of(f, local)) {
        return 0.0;
    }
    let jac = u * u * (abs(d.z) / abs(da));
    return area * (jac * acc.inv_area);
}

// Footprint::to_patch's in-plane coordinates (valid = false when the ray misses the patch plane).
struct Local {
    p: vec2<f32>,
    w: f32,
    valid: bool,
}

fn to_patch(p: Patch, r: vec3<f32>, pt: vec2<f32>) -> Local {
    let d = vec3<f32>(pt.x - r.x, pt.y - r.y, fp_n - r.z);
    let da = dot3(d, p.a);
    let u = -dot3(r, p.a) / da;
    if !(u > 0.0) || !is_finite(u) {
        return Local(vec2<f32>(0.0), 0.0, false);
    }
    let x = r + d * u;
    let jac = u * u * (abs(d.z) / abs(da));
    return Local(vec2<f32>(dot3(x, p.e1), dot3(x, p.e2)), jac * acc.inv_area, true);
}

// Footprint::overlap_term_front.
fn overlap_term(p: Patch, r: vec3<f32>, lr: vec2<f32>, hx: f32, hy: f32, f: Front) -> f32 {
    var area = 0.0;
    if PATCH_RECT {
        let lc = to_patch(p, r, lr);
        if !lc.valid {
            return 0.0;
        }
        let sj = sqrt(lc.w / acc.inv_area);
        let ax = hx * sj;
        let ay = hy * sj;
        let x0 = max(lc.p.x - ax, -acc.half.x);
        let x1 = min(lc.p.x + ax, acc.half.x);
        let y0 = max(lc.p.y - ay, -acc.half.y);
        let y1 = min(lc.p.y + ay, acc.half.y);
        let dx = max(x1 - x0, 0.0);
        let dy = max(y1 - y0, 0.0);
        area = dx * dy;
        if !f.whole && area != 0.0 {
            // poly_area(front_clip(f, quad)), the clipped vertices streamed (math.wgsl Shoelace).
            let c0 = vec2<f32>(x0, y0);
            let c1 = vec2<f32>(x1, y0);
            let c2 = vec2<f32>(x1, y1);
            let c3 = vec2<f32>(x0, y1);
            var sl = Shoelace(vec2<f32>(0.0), vec2<f32>(0.0), 0u, 0.0);
            sl = shoelace_clip_edge(sl, f.a, f.c, c0, c1);
            sl = shoelace_clip_edge(sl, f.a, f.c, c1, c2);
            sl = shoelace_clip_edge(sl, f.a, f.c, c2, c3);
            sl = shoelace_clip_edge(sl, f.a, f.c, c3, c0);
            area = abs(0.5 * shoelace_close(sl));
        }
    } else {
        var q: array<vec2<f32>, 4>;
        for (var k = 0u; k < 4u; k++) {
            let lc = to_patch(p, r, lr + vec2<f32>(SX[k] * hx, SY[k] * hy));
            if !lc.valid {
                return 0.0;
            }
            q[k] = lc.p;
        }
        // quad_disk_area(q) when the whole patch is in front, else the front-clipped polygon's:
        // one poly_disk_area call on either polygon (lavapipe runs both sides of a branch, and
        // this call is most of a disk term's cost).
        var pq: Poly;
        if f.whole {
            pq.m = 4u;
            for (var k = 0u; k < 4u; k++) {
                pq.q[k] = q[k];
            }
        } else {
            pq = front_clip(f, q);
        }
        area = poly_disk_area(pq, acc.half.x);
    }
    return area * acc.inv_area;
}

// cpu.rs bounds_rect over Footprint::texel_bounds(c).
fn kernel_bounds(p: Patch, r: vec3<f32>, c_in: f32) -> vec4<i32> {
    // The sun: view depth c is c - fp_dz in the footprint's frame, and a point's view (x, y) is
    // its frame (x, y) + fp_o.
    var c_view = c_in;
    if SUN {
        c_view = c_in - fp_dz;
    }
    let c = max(c_view, F32_MIN_POSITIVE);
    var lo = vec2<f32>(pos_inf());
    var hi = vec2<f32>(-pos_inf());
    for (var k = 0u; k < acc.n_hull; k++) {
        let at = at_depth(r, embed(p, tables[k]), c);
        var y = at * (view.n / c);
        if SUN {
            y = at + fp_o;
        }
        let t = (y - view.window_min) / view.delta;
        lo = min(lo, t);
        hi = max(hi, t);
    }
    let rf = f32(view.r);
    var out = vec4<i32>(0, 0, i32(view.r), i32(view.r));
    if lo.x == lo.x { out.x = i32(clamp(floor(lo.x), 0.0, rf)); }
    if lo.y == lo.y { out.y = i32(clamp(floor(lo.y), 0.0, rf)); }
    if hi.x == hi.x { out.z = i32(clamp(ceil(hi.x), 0.0, rf)); }
    if hi.y == hi.y { out.w = i32(clamp(ceil(hi.y), 0.0, rf)); }
    return out;
}

// Mssm::query(..).min (math.wgsl).
fn mssm_min(rect: vec4<i32>) -> f32 {
    return mssm_min_in(mssm, acc.mssm_present, acc.mssm_size, acc.mssm_levels, rect);
}

// DepthMap::at: +inf outside the map.
fn depth_at(i: i32, j: i32, layer: u32) -> f32 {
    let r = i32(view.r);
    if i < 0 || j < 0 || i >= r || j >= r {
        return pos_inf();
    }
    return textureLoad(maps, vec2<i32>(i, j), i32(layer), 0).x;
}

// math::fixed_kernel_start.
fn fixed_kernel_start(u: f32, k: u32) -> i32 {
    return i32(ceil(u - 0.5 * f32(k) - 0.5));
}

// cpu::Kernel: uniform blocks (rings = false) or multi-resolution rings.
struct Kernel {
    rect: vec4<i32>,
    step: u32,
    empty: bool,
    rings: bool,
    centre: vec2<i32>,
}

// Accumulator::kernel.
fn kernel(p: Patch, r: vec3<f32>, uv: vec2<f32>, rp: ReceiverPlane) -> Kernel {
    let none = vec2<i32>(0);
    if KERNEL_MODE == KERNEL_LEXELS {
        let i0 = fixed_kernel_start(uv.x, acc.k);
        let j0 = fixed_kernel_start(uv.y, acc.k);
        let k = i32(acc.k);
        return Kernel(vec4<i32>(i0, j0, i0 + k, j0 + k), 1u, false, false, none);
    }
    var rect = kernel_bounds(p, r, view.n);
    if KERNEL_MODE == KERNEL_ADAPTIVE {
        var zm = view.n;
        for (var it = 0; it < REFINE_ROUNDS; it++) {
            let zmin = mssm_min(rect);
            if zmin >= plane_max_threshold(rp, f32(rect.x), f32(rect.z), f32(rect.y), f32(rect.w)) {
                return Kernel(rect, 1u, true, false, none);
            }
            if !(zmin > zm) {
                break;
            }
            zm = zmin;
            let next = kernel_bounds(p, r, zm);
            let an = (next.z - next.x) * (next.w - next.y);
            let ar = (rect.z - rect.x) * (rect.w - rect.y);
            if an >= ar {
                break;
            }
            rect = next;
        }
    }
    let nx = u32(max(rect.z - rect.x, 0));
    let ny = u32(max(rect.w - rect.y, 0));
    if nx == 0u || ny == 0u {
        return Kernel(rect, 1u, true, false, none);
    }
    if KERNEL_MODE == KERNEL_ADAPTIVE {
        let c = vec2<i32>(i32(floor(uv.x + 0.5)), i32(floor(uv.y + 0.5)));
        return Kernel(rect, 1u, false, true, c);
    }
    let step = max((max(nx, ny) + acc.k - 1u) / acc.k, 1u);
    return Kernel(rect, step, false, false, none);
}

// What the cells accumulate.
struct State {
    mask: BitMask,
    s_add: f32,
}

// The casters the cells hold, queued before their terms are summed (QUEUE_TERMS): on lavapipe a
// loop's body costs as much on a trip where no lane needs it (docs/gpu.md, "Accumulation's
// kernel"), so where a term is costly (a disk patch's clipped quad, the exact variant's bits) the
// loop over the cells only finds casters, and the terms run in a loop of their own, once per
// caster. A rect patch's additive term is cheaper than the queue's scatter and gather: it is
// summed in place. HITS casters queued at most before a flush; a cell adds one per layer (at
// most 4).
const HITS: u32 = 16u;
struct Casters {
    // Per caster: its footprint's centre on the plane z = n (lr) and half sizes (hx, hy).
    c: array<vec4<f32>, 20>,
    n: u32,
}

// The casters of cell [i0, i1) x [j0, j1), one per layer (math::caster; its footprint's centre
// on the plane z = n and half sizes, (lr, hx, hy)), appended to q: the ring loop's cheap body.
fn queue_casters(q: ptr<function, Casters>, st: ptr<function, State>, p: Patch, f: Front, r: vec3<f32>, rp: ReceiverPlane, i0: i32, i1: i32, j0: i32, j1: i32) {
    let delta = view.delta;
    let n = view.n;
    let ic = i0 + (i1 - i0 - 1) / 2;
    let jc = j0 + (j1 - j0 - 1) / 2;
    let l = view.window_min + vec2<f32>(f32(i0 + i1), f32(j0 + j1)) * (0.5 * delta);
    for (var layer = 0u; layer < LAYERS; layer++) {
        let cz = depth_at(ic, jc, layer);
        // The receiver-plane test of the sample (cpu.rs: deeper layers fail too).
        if !plane_caster(rp, ic, jc, cz) {
            break;
        }
        // math::caster.
        if !(cz > 0.0) || !(cz < r.z) {
            continue;
        }
        var size: f32;
        var lr: vec2<f32>;
        if SUN {
            // Footprint::caster for the sun: the lexel (l - o, cz - dz) of the footprint's frame.
            let c = cz - fp_dz;
            if !(c > 0.0) || !(c < r.z) {
                continue;
            }
            let gap = max(r.z - c, 1e-7 * r.z);
            size = (r.z - fp_n) / gap;
            lr = (l - fp_o) * size;
        } else {
            let gap = max(r.z - cz, 1e-7 * r.z);
            size = ((r.z - n) / gap) * (cz / n);
            lr = vec2<f32>(r.x, r.y) * ((n - cz) / gap) + l * size;
        }
        if !is_finite(size) || !is_finite(lr.x) || !is_finite(lr.y) {
            continue;
        }
        let h = 0.5 * delta * size * vec2<f32>(f32(i1 - i0), f32(j1 - j0));
        let c = vec4<f32>(lr, h);
        if QUEUE_TERMS {
            (*q).c[(*q).n] = c;
            (*q).n += 1u;
        } else {
            caster_term(st, p, r, f, c);
        }
    }
}

// The costly part: one queued caster's term (additive) or occlusion bits (exact); true when
// every bit is set.
fn caster_term(st: ptr<function, State>, p: Patch, r: vec3<f32>, f: Front, c: vec4<f32>) -> bool {
    let lr = c.xy;
    let hx = c.z;
    let hy = c.w;
    if !EXACT {
        if OVERLAP {
            (*st).s_add += overlap_term(p, r, lr, hx, hy, f);
        } else {
            (*st).s_add += additive_term(p, r, lr, 4.0 * hx * hy, f);
        }
        return false;
    }
    // Footprint::caster_quad.
    var q: array<vec2<f32>, 4>;
    for (var c4 = 0u; c4 < 4u; c4++) {
        let lc = to_patch(p, r, lr + vec2<f32>(SX[c4] * hx, SY[c4] * hy));
        if !lc.valid {
            return false;
        }
        q[c4] = lc.p;
    }
    let flat = p.a.x == 0.0 && p.a.y == 0.0 && p.a.z == 1.0;
    // BitMask::set_in_quad (on a local copy: naga's SPIR-V backend rejects a pointer to a
    // member through a pointer argument).
    var m = (*st).mask;
    for (var k = 0u; k < acc.nbits; k++) {
        if !bitmask_is_set(&m, k) && bitmask_quad_contains(q, flat, tables[HULL_SLOTS + k]) {
            bitmask_set(&m, k);
        }
    }
    (*st).mask = m;
    return m.n_set == acc.nbits;
}

// The terms of the queued casters in queue order; true when every bit is set (the rest are
// then left unsummed, as the CPU stops there).
fn flush(st: ptr<function, State>, p: Patch, r: vec3<f32>, f: Front, q: ptr<function, Casters>) -> bool {
    for (var k = 0u; k < (*q).n; k++) {
        if caster_term(st, p, r, f, (*q).c[k]) {
            (*q).n = 0u;
            return true;
        }
    }
    (*q).n = 0u;
    return false;
}

fn covers(rr: vec4<i32>, b: vec4<i32>) -> bool {
    return rr.x <= b.x && rr.y <= b.y && rr.z >= b.z && rr.w >= b.w;
}

// cpu.rs floor_to and ceil_to for a = 2^k (arithmetic shifts round towards -inf).
fn floor_sh(x: i32, k: u32) -> i32 {
    return (x >> k) << k;
}

fn ceil_sh(x: i32, k: u32) -> i32 {
    return -floor_sh(-x, k);
}

// cpu::for_each_ring_cell over the cells, in lattice indices (map index + phase, cpu::ring_phase),
// the cells handed on in map indices. One cell per trip of a flat loop (the level's set-up, its
// rows and columns as state), which stops to flush whenever HITS casters are queued: the ring
// loop's body stays small, and the casters' terms run once per caster (see Casters).
fn rings(st: ptr<function, State>, p: Patch, r: vec3<f32>, rp: ReceiverPlane, f: Front, bound_map: vec4<i32>, c_map: vec2<i32>) {
    let ph = vec2<i32>(acc.phase_x, acc.phase_y);
    let bound = bound_map + vec4<i32>(ph, ph);
    let c = c_map + ph;
    let m = i32(max((acc.k + 3u) / 4u, 1u));
    var raw = vec4<i32>(c.x - m, c.y - m, c.x + m, c.y + m);
    var inner = vec4<i32>(c.x, c.y, c.x, c.y);
    // The level: its cell side s = 2^sh, and whether its set-up is still to do.
    var lvl = 0;
    var sh = 0u;
    var fresh = true;
    var last = false;
    var outer = vec4<i32>(0);
    var x0 = 0;
    var x1 = 0;
    var y1 = 0;
    var x = 0;
    var y = 0;
    var done = false;
    var q: Casters;
    q.n = 0u;
    loop {
        loop {
            if done || q.n >= HITS {
                break;
            }
            let s = 1 << sh;
            if fresh {
                last = covers(raw, bound);
                let ash = select(sh + 1u, sh, last);
                outer = vec4<i32>(floor_sh(raw.x, ash), floor_sh(raw.y, ash), ceil_sh(raw.z, ash), ceil_sh(raw.w, ash));
                x0 = max(outer.x, floor_sh(bound.x, sh));
                x1 = min(outer.z, bound.z);
                y = max(outer.y, floor_sh(bound.y, sh));
                y1 = min(outer.w, bound.w);
                x = x0;
                if x0 >= x1 {
                    y = y1;
                }
                fresh = false;
            }
            if y < y1 {
                let in_inner = x >= inner.x && x + s <= inner.z && y >= inner.y && y + s <= inner.w;
                if !in_inner {
                    let i0 = max(x, bound.x);
                    let i1 = min(x + s, bound.z);
                    let j0 = max(y, bound.y);
                    let j1 = min(y + s, bound.w);
                    if i0 < i1 && j0 < j1 {
                        queue_casters(&q, st, p, f, r, rp, i0 - ph.x, i1 - ph.x, j0 - ph.y, j1 - ph.y);
                    }
                }
                x += s;
                if x >= x1 {
                    x = x0;
                    y += s;
                }
            }
            if y >= y1 {
                if last || covers(outer, bound) || lvl >= 31 {
                    done = true;
                } else {
                    inner = outer;
                    sh += 1u;
                    let s2 = 1 << sh;
                    raw = vec4<i32>(outer.x - m * s2, outer.y - m * s2, outer.z + m * s2, outer.w + m * s2);
                    lvl++;
                    fresh = true;
                }
            }
        }
        if flush(st, p, r, f, &q) || done {
            return;
        }
    }
}

// Accumulator::shadowing: the shadowing factor s in [0, 1].
// r: the receiver in the footprint's frame (Footprint::r); the caster test takes its view
// position (Footprint::receiver).
fn shadowing(p: Patch, r: vec3<f32>, nrm: vec3<f32>, uv: vec2<f32>) -> f32 {
    var rv = r;
    if SUN {
        rv = r + vec3<f32>(fp_o, fp_dz);
    }
    let rp = plane_new(est.receiver_plane != 0u, view, rv, nrm, acc.b0, acc.b1, 0.0);
    let f = front_new(p, r, nrm);
    if !(f.fraction > 0.0) {
        return 0.0;
    }
    let kr = kernel(p, r, uv, rp);
    if kr.empty {
        return 0.0;
    }
    if DEFER_CELLS {
        return DEFERRED_S;
    }
    var st = State(bitmask_new(), 0.0);
    // The exact variant: bits behind the tangent plane set from the start, never counted.
    var behind = 0u;
    if EXACT && !f.whole {
        var m0 = bitmask_new();
        for (var k = 0u; k < acc.nbits; k++) {
            if !front_of(f, tables[HULL_SLOTS + k]) {
                bitmask_set(&m0, k);
            }
        }
        st.mask = m0;
        behind = m0.n_set;
    }
    if kr.rings {
        rings(&st, p, r, rp, f, kr.rect, kr.centre);
    } else {
        // Blocks of step x step lexels (at most K x K), row by row, their casters queued as in
        // rings.
        let rect = kr.rect;
        let step = kr.step;
        let bx = (u32(rect.z - rect.x) + step - 1u) / step;
        let by = select(0u, (u32(rect.w - rect.y) + step - 1u) / step, bx > 0u);
        var q: Casters;
        q.n = 0u;
        var a = 0u;
        var b = 0u;
        loop {
            loop {
                if b >= by || q.n >= HITS {
                    break;
                }
                let j0 = rect.y + i32(b * step);
                let i0 = rect.x + i32(a * step);
                queue_casters(&q, &st, p, f, r, rp, i0, min(i0 + i32(step), rect.z), j0, min(j0 + i32(step), rect.w));
                a++;
                if a >= bx {
                    a = 0u;
                    b++;
                }
            }
            if flush(&st, p, r, f, &q) || b >= by {
                break;
            }
        }
    }
    if EXACT {
        if st.mask.n_set == acc.nbits {
            return 1.0;
        }
        return f32(st.mask.n_set - behind) / f32(acc.nbits - behind);
    }
    if st.s_add >= f.fraction * (1.0 - 1e-6) {
        return 1.0;
    }
    return clamp(st.s_add / f.fraction, 0.0, 1.0);
}

// CpuAccumulation::estimate_with, per receiver; -1 for a lit receiver outside the frustum
// (counted, and listed for the settle passes, the CPU's settle_outside).
fn estimate_receiver(pw: vec3<f32>, nw: vec3<f32>) -> f32 {
    let facing = front_fraction_world(est, pw, nw);
    if !(facing > 0.0) {
        return 0.0;
    }
    let rv = view_to_light(view, pw);
    // Footprint::for_light: the sun's frame puts the receiver at (0, 0, L).
    var r = rv;
    fp_n = view.n;
    if SUN {
        r = vec3<f32>(0.0, 0.0, acc.lift);
        fp_n = 0.5 * acc.lift;
        fp_o = vec2<f32>(rv.x, rv.y);
        fp_dz = rv.z - acc.lift;
    }
    let p = patch_for(r);
    let uv = project(view, rv);
    let covered = r.z > fp_n && patch_max_z(p) < r.z * (1.0 - 1e-4);
    if !covered || !view_contains(view, uv) {
        atomicAdd(&counters[0], 1u);
        leave_open(current_receiver);
        return -1.0;
    }
    let s = shadowing(p, r, view_dir_to_light(view, nw), uv);
    if s == DEFERRED_S {
        return -2.0;
    }
    return facing * (1.0 - s);
}

// The entry point is the core's (receivers.wgsl); its loop-budget probe is this uniform's.
fn receiver_probe() -> u32 {
    return acc.probe;
}
