// Twin of crates/backprojection/src/cpu.rs and math.rs, in f32 and in the CPU's operation order.
// Rect, disk and sphere lights (LIGHT_SHAPE): the overlap of B_s with the light is the core's
// overlap.wgsl on a disk, on the sphere's silhouette disk after the central projection from p.
// Prepended: the parts before it in gpu.rs SHADER_PARTS (the core's estimate head, cells.wgsl for
// the Kahan `Sum`, the silhouette set-up, the receivers and the bit mask).
//
// Known difference: the CPU sums area(B_s ∩ L) in f64 (each term from f64 differences of f32
// bounds); here each term is f32 and the sum is Kahan-compensated f32 (about 1e-7 of the light
// area apart). Gap filling keeps one row of block occluders where the CPU keeps them all
// (ROW_BUFFER), or, with rows that may exceed LINE blocks, computes the neighbours' again (same
// values).

// The uniforms' switches as override constants (gpu.rs `specialization`, with the core's
// LIGHT_SHAPE: the values of the uniform fields of the same meaning, which the kernel does not
// read): the pipeline is compiled per combination, without the branches it does not take.
override BITMASK: bool = true;
override MIDPOINT: bool = true;
override GAP_FILLING: bool = true;
override FIRST_NONZERO: bool = true;
// Gap filling with rows of at most LINE blocks (max_nspp <= LINE, gpu.rs `specialization`):
// `visibility` keeps one row of block occluders.
override ROW_BUFFER: bool = false;
const LINE: u32 = 128u;
override OPACITY: bool = false;
override PLANE_ON: bool = true;
override LAYERS: u32 = 3u;
// The first of the frame's two passes: a receiver that reaches the block loop is deferred
// (visibility DEFERRED_V) to the second pass, which runs over those receivers only
// (ActiveLists::encode_deferred), so a lit receiver's lane never runs the loop beside a
// penumbra receiver's.
override DEFER_BLOCKS: bool = false;
const DEFERRED_V: f32 = -2.0;

// Settings of the estimate (mirrors gpu.rs BpUniform field for field).
struct BpUniform {
    half: vec2<f32>,
    area: f32,
    b0: f32,
    b1: f32,
    midpoint: u32,
    gap_filling: u32,
    max_nspp: u32,
    sqrt_nspp: f32,
    layers: u32,
    midpoints: u32,
    mssm_present: u32,
    mssm_levels: u32,
    mssm_size: u32,
    first_nonzero: u32,
    nbits: u32,
    opacity: u32,
    probe: u32,
    _pad1: u32,
    _pad2: u32,
}

// occlusion=bitmask: the bit points, two per vec4 (mirrors gpu.rs BitTable; cpu.rs emitter_bits).
struct BitTable {
    pts: array<vec4<f32>, 128>,
}

@group(0) @binding(0) var<uniform> view: LightViewUniform;
@group(0) @binding(1) var<uniform> est: EstimateUniform;
@group(0) @binding(2) var<uniform> bp: BpUniform;
// Layers 0..layers, then midpoints 0..midpoints (linear light-space depth, +inf where empty).
@group(0) @binding(3) var maps: texture_2d_array<f32>;
// MSSM min planes, one array layer per level.
@group(0) @binding(4) var mssm: texture_2d_array<f32>;
@group(0) @binding(5) var<storage, read> receivers: array<ReceiverGpu>;
@group(0) @binding(6) var<storage, read_write> v_out: array<u32>;
// [0] outside the light frustum, [1] non-finite V replaced by 0, [2] cut short by the loop
// budget and left NaN (gpu/frame.rs, BackprojectionFrame).
@group(0) @binding(7) var<storage, read_write> counters: array<atomic<u32>, 3>;
@group(0) @binding(8) var<uniform> bits: BitTable;
// The range's active list (the core's receivers::ActiveLists), read by the core's entry point.
@group(0) @binding(9) var<storage, read> active_list: array<u32>;

const FAR_BOUND: f32 = 1e30;

// math::micropatch_k: the texel pitch over n, or the pitch itself in an orthographic view.
fn micropatch_k() -> f32 {
    if view.ortho != 0u {
        return view.delta;
    }
    return view.delta / view.n;
}

// math::micropatch_scale (the orthographic form for the sun: k / (z_p - z_s)).
fn micropatch_scale(k: f32, z_s: f32, z_p: f32) -> f32 {
    if !(z_s > 0.0) || !(z_s < z_p) || !(k > 0.0) {
        return 0.0;
    }
    let gap = max(max(z_p - z_s, 1e-7 * z_p), F32_MIN_POSITIVE);
    var s: f32;
    if view.ortho != 0u {
        s = k / gap;
    } else {
        s = k * z_s * (z_p / gap);
    }
    if is_finite(s) {
        return s;
    }
    return F32_MAX;
}

// One bound of math::backprojected_micropatch.
fn bound(t: f32, c: f32, s: f32) -> f32 {
    let d = t - c;
    if d == 0.0 || s == 0.0 {
        return 0.0;
    }
    return clamp(d * s, -FAR_BOUND, FAR_BOUND);
}

// cpu::kernel_rect: half-open [x0, x1) x [y0, y1) as (x0, y0, x1, y1).
fn kernel_rect(uv: vec2<f32>, wx: f32, wy: f32) -> vec4<i32> {
    let r = f32(view.r);
    return vec4<i32>(
        i32(clamp(floor(uv.x - 0.5 * wx), 0.0, r)),
        i32(clamp(floor(uv.y - 0.5 * wy), 0.0, r)),
        i32(clamp(ceil(uv.x + 0.5 * wx), 0.0, r)),
        i32(clamp(ceil(uv.y + 0.5 * wy), 0.0, r)),
    );
}

// hull_dir, hull_point, Sil, sil_new and sil_carry: the core's silhouette_setup.wgsl.

// Silhouette::overlap_rect.
fn sil_overlap(s: Sil, rx0: f32, ry0: f32, rx1: f32, ry1: f32) -> f32 {
    let x0 = max(rx0, s.clip.x);
    let y0 = max(ry0, s.clip.y);
    let x1 = min(rx1, s.clip.z);
    let y1 = min(ry1, s.clip.w);
    if !(x1 > x0 && y1 > y0) {
        return 0.0;
    }
    var q: array<vec2<f32>, 4>;
    q[0] = sil_carry(s, x0, y0);
    q[1] = sil_carry(s, x1, y0);
    q[2] = sil_carry(s, x1, y1);
    q[3] = sil_carry(s, x0, y1);
    return quad_disk_area(q, s.radius);
}

// Silhouette::kernel_bounds then cpu.rs bounds_rect (the whole map for None).
fn sil_kernel(s: Sil, p: vec3<f32>, z_m: f32) -> vec4<i32> {
    let whole = vec4<i32>(0, 0, i32(view.r), i32(view.r));
    var b = vec4<f32>(pos_inf(), pos_inf(), -pos_inf(), -pos_inf());
    let zm = max(z_m, F32_MIN_POSITIVE);
    for (var k = 0u; k < 8u; k++) {
        let x = hull_point(s.e1, s.e2, s.radius, k);
        if !(x.z < zm) || !(zm < p.z) {
            return whole;
        }
        let c = p + (x - p) * ((p.z - zm) / (p.z - x.z));
        let t = (vec2<f32>(c.x, c.y) * (view.n / zm) - view.window_min) / view.delta;
        b = vec4<f32>(min(b.x, t.x), min(b.y, t.y), max(b.z, t.x), max(b.w, t.y));
    }
    if !(is_finite(b.x) && is_finite(b.y) && is_finite(b.z) && is_finite(b.w)) {
        return whole;
    }
    let r = f32(view.r);
    return vec4<i32>(
        i32(clamp(floor(b.x), 0.0, r)),
        i32(clamp(floor(b.y), 0.0, r)),
        i32(clamp(ceil(b.z), 0.0, r)),
        i32(clamp(ceil(b.w), 0.0, r)),
    );
}

// math::Emitter::of: a disk light and the sun (its disk of directions at unit distance, radius
// light_size_x = tan(angle / 2)) are both Emitter::Disk.
fn disk_emitter() -> bool {
    return LIGHT_SHAPE == LIGHT_DISK || LIGHT_SHAPE == LIGHT_DIRECTIONAL;
}

// math::Emitter::overlap: area(B_s ∩ L) (rect: f64 on the CPU).
fn light_overlap(x0: f32, y0: f32, x1: f32, y1: f32, s: Sil) -> f32 {
    if LIGHT_SHAPE == LIGHT_RECT {
        let dx = max(min(x1, bp.half.x) - max(x0, -bp.half.x), 0.0);
        let dy = max(min(y1, bp.half.y) - max(y0, -bp.half.y), 0.0);
        return dx * dy;
    }
    if disk_emitter() {
        let r = est.light_size_x;
        return rect_disk_area(max(x0, -r), max(y0, -r), min(x1, r), min(y1, r), r);
    }
    if !s.ok {
        return 0.0;
    }
    return sil_overlap(s, x0, y0, x1, y1);
}

// math::Emitter::contributes (CONTRIBUTION_REL = 1e-6).
fn light_contributes(x0: f32, y0: f32, x1: f32, y1: f32, s: Sil) -> bool {
    if LIGHT_SHAPE == LIGHT_RECT {
        return light_overlap(x0, y0, x1, y1, s) > 0.0;
    }
    if disk_emitter() {
        if !(x1 > x0 && y1 > y0) {
            return false;
        }
        let r = est.light_size_x;
        let cx = clamp(0.0, x0, x1);
        let cy = clamp(0.0, y0, y1);
        return cx * cx + cy * cy < r * r;
    }
    let a = PI_F32 * est.light_size_x * est.light_size_x;
    return s.ok && sil_overlap(s, x0, y0, x1, y1) > 1e-6 * a;
}

// Coordinate of rank r of the rect lattice (bitmask::lattice_ranges): x of x rank
// X = i side + j (bit k = j side + i), or y of bit k = r.
fn lattice_at(r: i32, side: u32, along_x: bool) -> f32 {
    let b = i32(side);
    if along_x {
        return bit_point(u32((r % b) * b + r / b)).x;
    }
    return bit_point(u32(r)).y;
}

// Predicate of bitmask::lattice_ranges: c >= bound (lower), or !(c <= bound) (upper).
fn lattice_pass(c: f32, bound: f32, upper: bool) -> bool {
    if upper {
        return !(c <= bound);
    }
    return c >= bound;
}

// bitmask::partition: the first rank whose coordinate passes, walked from the evenly spaced
// guess.
fn lattice_partition(n: i32, side: u32, along_x: bool, bound: f32, upper: bool) -> i32 {
    let c0 = lattice_at(0, side, along_x);
    let c1 = lattice_at(n - 1, side, along_x);
    let step = (c1 - c0) / f32(max(n - 1, 1));
    let guess = ceil((bound - c0) / step);
    var r = 0;
    // Finite (not NaN, not +-inf): clamp to [0, n].
    if guess == guess && abs(guess) <= 3.0e38 {
        r = i32(clamp(guess, 0.0, f32(n)));
    }
    // The CPU's two walks (down while the rank below passes, then up while this one fails) as
    // one loop: a step down lands on a rank that passes and a step up leaves one that fails, so
    // the loop never turns back and ends where the CPU's walks do. Lavapipe pays for each loop
    // however few trips it takes, and the guess is almost always right.
    loop {
        if r > 0 && lattice_pass(lattice_at(r - 1, side, along_x), bound, upper) {
            r -= 1;
        } else if r < n && !lattice_pass(lattice_at(r, side, along_x), bound, upper) {
            r += 1;
        } else {
            break;
        }
    }
    return r;
}

// Floor division (i32::div_euclid for b > 0).
fn div_floor(a: i32, b: i32) -> i32 {
    let q = a / b;
    if (a % b) != 0 && a < 0 {
        return q - 1;
    }
    return q;
}

// Bit k of the table.
fn bit_point(k: u32) -> vec2<f32> {
    let v = bits.pts[k / 2u];
    if (k % 2u) == 1u {
        return v.zw;
    }
    return v.xy;
}

// cpu.rs occlusion=bitmask: sets the bits B_s contains (BitMask::set_in_rect on the light plane;
// a sphere: Silhouette::carry_rect then BitMask::set_in_quad on the silhouette disk).
fn set_bits(m: ptr<function, BitMask>, side: u32, x0: f32, y0: f32, x1: f32, y1: f32, s: Sil) {
    if LIGHT_SHAPE == LIGHT_SPHERE {
        if !s.ok {
            return;
        }
        let cx0 = max(x0, s.clip.x);
        let cy0 = max(y0, s.clip.y);
        let cx1 = min(x1, s.clip.z);
        let cy1 = min(y1, s.clip.w);
        if !(cx1 > cx0 && cy1 > cy0) {
            return;
        }
        var q: array<vec2<f32>, 4>;
        q[0] = sil_carry(s, cx0, cy0);
        q[1] = sil_carry(s, cx1, cy0);
        q[2] = sil_carry(s, cx1, cy1);
        q[3] = sil_carry(s, cx0, cy1);
        for (var k = 0u; k < bp.nbits; k++) {
            if !bitmask_is_set(m, k) && bitmask_quad_contains(q, false, bit_point(k)) {
                bitmask_set(m, k);
            }
        }
        return;
    }
    let lo = vec2<f32>(x0, y0);
    let hi = vec2<f32>(x1, y1);
    if LIGHT_SHAPE == LIGHT_RECT {
        // BitMask::set_in_lattice: the x ranks X = i side + j with lo.x <= x <= hi.x and the
        // bits k with lo.y <= y <= hi.y (bitmask::lattice_ranges), then one run per row.
        let n = i32(bp.nbits);
        let xa = lattice_partition(n, side, true, lo.x, false);
        let xb = lattice_partition(n, side, true, hi.x, true);
        let ya = lattice_partition(n, side, false, lo.y, false);
        let yb = lattice_partition(n, side, false, hi.y, true);
        if xa >= xb || ya >= yb {
            return;
        }
        let b = i32(side);
        for (var j = ya / b; j <= (yb - 1) / b; j++) {
            // ceil((xa - j) / b) and floor((xb - 1 - j) / b) for possibly negative numerators.
            let i0 = max(max(div_floor(xa - j + b - 1, b), ya - j * b), 0);
            let i1 = min(min(div_floor(xb - 1 - j, b), yb - 1 - j * b), b - 1);
            if i0 <= i1 {
                bitmask_set_run(m, u32(j * b + i0), u32(i1 - i0 + 1));
            }
        }
        return;
    }
    for (var k = 0u; k < bp.nbits; k++) {
        if !bitmask_is_set(m, k) && bitmask_rect_contains(lo, hi, bit_point(k)) {
            bitmask_set(m, k);
        }
    }
}

// The kernel at occluder depths >= zm: cpu.rs kernel_rect for rect and disk lights, the
// silhouette's for a sphere.
fn kernel_at(p: vec3<f32>, uv: vec2<f32>, zm: f32, s: Sil) -> vec4<i32> {
    if LIGHT_SHAPE == LIGHT_SPHERE {
        return sil_kernel(s, p, zm);
    }
    return kernel_rect(uv, view_kernel_texels(view, 2.0 * bp.half.x, zm, p.z), view_kernel_texels(view, 2.0 * bp.half.y, zm, p.z));
}

// Mssm::query(..).min (math.wgsl).
fn mssm_min(rect: vec4<i32>) -> f32 {
    return mssm_min_in(mssm, bp.mssm_present, bp.mssm_size, bp.mssm_levels, rect);
}

// The kernel after refinement and its sampling blocks.
struct Kernel {
    rect: vec4<i32>,
    step: u32,
    bx: u32,
    by: u32,
}

// plane_max_threshold (ReceiverPlane::max_threshold) is core's, in math.wgsl.

// The receiver as the kernel's caster test sees it: depth, bias (bias mode, plane off), texel
// coordinates and the receiver plane (PLANE_ON).
struct Rec {
    zp: f32,
    eps: f32,
    uv: vec2<f32>,
    plane: ReceiverPlane,
    sil: Sil,
}

// cpu.rs: true depth of the occluding layer backprojected at block (a, b)'s centre texel
// (layer_rule: the deepest occluding one, or the deepest whose micropatch overlaps the light),
// or +inf.
fn block_occluder(kr: Kernel, a: u32, b: u32, rc: Rec) -> vec2<f32> {
    let zp = rc.zp;
    let j0 = kr.rect.y + i32(b * kr.step);
    let j1 = min(j0 + i32(kr.step), kr.rect.w);
    let jc = j0 + (j1 - j0 - 1) / 2;
    let i0 = kr.rect.x + i32(a * kr.step);
    let i1 = min(i0 + i32(kr.step), kr.rect.z);
    let ic = i0 + (i1 - i0 - 1) / 2;
    let on = PLANE_ON;
    let first_nonzero = FIRST_NONZERO && bp.area > 0.0;
    let k = micropatch_k();
    for (var mm = i32(LAYERS) - 1; mm >= 0; mm--) {
        let z = textureLoad(maps, vec2<i32>(ic, jc), mm, 0).x;
        var occludes = false;
        if MIDPOINT {
            var cls = z;
            if u32(mm) < bp.midpoints {
                cls = textureLoad(maps, vec2<i32>(ic, jc), i32(LAYERS) + mm, 0).x;
            }
            if on {
                occludes = cls < zp && plane_caster(rc.plane, ic, jc, z);
            } else {
                occludes = cls < zp && z < zp;
            }
        } else if on {
            occludes = plane_caster(rc.plane, ic, jc, z);
        } else {
            occludes = z + rc.eps < zp && z < zp;
        }
        if !occludes {
            continue;
        }
        if first_nonzero {
            // The block's own micropatch (before gap filling) against the light.
            let s = micropatch_scale(k, z, zp);
            let x0 = bound(f32(i0), rc.uv.x, s);
            let x1 = bound(f32(i1), rc.uv.x, s);
            let y0 = bound(f32(j0), rc.uv.y, s);
            let y1 = bound(f32(j1), rc.uv.y, s);
            if !light_contributes(x0, y0, x1, y1, rc.sil) {
                continue;
            }
        }
        return vec2<f32>(z, block_opacity(ic, jc, mm, zp));
    }
    return vec2<f32>(pos_inf(), 1.0);
}

// cpu.rs: the opacity of texel (ic, jc)'s layers 0..=m in front of the receiver, one minus the
// product of their transmittances (opacity planes follow the midpoints in `maps`); 1 for an
// opaque scene (bp.opacity = 0).
fn block_opacity(ic: i32, jc: i32, m: i32, zp: f32) -> f32 {
    if !OPACITY {
        return 1.0;
    }
    let base = i32(LAYERS + bp.midpoints);
    var tr = 1.0;
    for (var mm = 0; mm <= m; mm++) {
        if textureLoad(maps, vec2<i32>(ic, jc), mm, 0).x < zp {
            tr *= 1.0 - textureLoad(maps, vec2<i32>(ic, jc), base + mm, 0).x;
        }
    }
    return 1.0 - tr;
}

// cpu::Setup::visibility: visibility before the facing factor, in [0, 1].
fn visibility(p: vec3<f32>, n: vec3<f32>, uv: vec2<f32>, sil: Sil) -> f32 {
    let zp = p.z;
    var eps = 0.0;
    if !MIDPOINT {
        eps = receiver_bias(view, p, n, bp.b0, bp.b1);
    }
    let on = PLANE_ON;
    // The plane test when on (plane_new's classic form is unused: the plane-off tests are
    // written out as cpu.rs has them).
    let rc = Rec(zp, eps, uv, plane_new(on, view, p, n, bp.b0, bp.b1, 0.0), sil);
    var zm = view.n;
    var rect = kernel_at(p, uv, zm, sil);
    for (var it = 0; it < 16; it++) {
        let zmin = mssm_min(rect);
        var zbound = zp - eps;
        if on {
            zbound = plane_max_threshold(rc.plane, f32(rect.x), f32(rect.z), f32(rect.y), f32(rect.w));
        }
        if zmin >= zbound {
            return 1.0;
        }
        if !(zmin > zm) {
            break;
        }
        zm = zmin;
        let next = kernel_at(p, uv, zm, sil);
        let an = (next.z - next.x) * (next.w - next.y);
        let ar = (rect.z - rect.x) * (rect.w - rect.y);
        if an >= ar {
            break;
        }
        rect = next;
    }
    let nx = u32(rect.z - rect.x);
    let ny = u32(rect.w - rect.y);
    if nx == 0u || ny == 0u {
        return 1.0;
    }
    if DEFER_BLOCKS {
        return DEFERRED_V;
    }
    var step = 1u;
    if nx * ny > bp.max_nspp {
        step = u32(max(ceil(f32(max(nx, ny)) / bp.sqrt_nspp), 1.0));
    }
    let bx = (nx + step - 1u) / step;
    let by = (ny + step - 1u) / step;
    let kr = Kernel(rect, step, bx, by);
    let k = micropatch_k();
    var a_occ = Sum(0.0, 0.0);
    var mask = bitmask_new();
    // The bit grid's side B (nbits = B^2).
    var side = 0u;
    while side * side < bp.nbits {
        side++;
    }
    // Gap filling reads each block's right and lower neighbours' occluders. ROW_BUFFER keeps
    // one row of them (row b's, each replaced by row b + 1's once read), so each block's
    // occluder is computed once, as the CPU's per-block array holds it; without it (rows that
    // may be longer than LINE) the neighbours' are computed again.
    var row: array<vec2<f32>, LINE>;
    if ROW_BUFFER {
        for (var a = 0u; a < bx; a++) {
            row[a] = block_occluder(kr, a, 0u, rc);
        }
    }
    for (var b = 0u; b < by; b++) {
        let j0 = rect.y + i32(b * step);
        let j1 = min(j0 + i32(step), rect.w);
        for (var a = 0u; a < bx; a++) {
            var occ: vec2<f32>;
            // The right and lower neighbours' occluder depths (+inf: none, or not read).
            var zr = pos_inf();
            var zb = pos_inf();
            if ROW_BUFFER {
                occ = row[a];
                if a + 1u < bx {
                    zr = row[a + 1u].x;
                }
                if b + 1u < by {
                    row[a] = block_occluder(kr, a, b + 1u, rc);
                    zb = row[a].x;
                }
            } else {
                occ = block_occluder(kr, a, b, rc);
                if GAP_FILLING && is_finite(occ.x) {
                    if a + 1u < bx {
                        zr = block_occluder(kr, a + 1u, b, rc).x;
                    }
                    if b + 1u < by {
                        zb = block_occluder(kr, a, b + 1u, rc).x;
                    }
                }
            }
            let z = occ.x;
            if !is_finite(z) {
                continue;
            }
            let i0 = rect.x + i32(a * step);
            let i1 = min(i0 + i32(step), rect.z);
            let s = micropatch_scale(k, z, zp);
            let x0 = bound(f32(i0), uv.x, s);
            var x1 = bound(f32(i1), uv.x, s);
            let y0 = bound(f32(j0), uv.y, s);
            var y1 = bound(f32(j1), uv.y, s);
            if GAP_FILLING {
                if is_finite(zr) {
                    let st = micropatch_scale(k, zr, zp);
                    let d = f32(i1) - uv.x;
                    if d != 0.0 && st > 0.0 {
                        x1 = max(x1, clamp(d * st, -FAR_BOUND, FAR_BOUND));
                    }
                }
                if is_finite(zb) {
                    let st = micropatch_scale(k, zb, zp);
                    let d = f32(j1) - uv.y;
                    if d != 0.0 && st > 0.0 {
                        y1 = max(y1, clamp(d * st, -FAR_BOUND, FAR_BOUND));
                    }
                }
            }
            if BITMASK {
                set_bits(&mask, side, x0, y0, x1, y1, sil);
                if mask.n_set == bp.nbits {
                    return 1.0 - f32(mask.n_set) / f32(bp.nbits);
                }
                continue;
            }
            a_occ = sum_add(a_occ, occ.y * light_overlap(x0, y0, x1, y1, sil));
        }
    }
    if BITMASK {
        return 1.0 - f32(mask.n_set) / f32(bp.nbits);
    }
    if !(bp.area > 0.0) {
        return select(1.0, 0.0, a_occ.s > 0.0);
    }
    let f = a_occ.s / bp.area;
    if f >= 1.0 - 1e-6 {
        return 0.0;
    }
    return 1.0 - clamp(f, 0.0, 1.0);
}

// CpuBackprojection::estimate, per receiver.
fn estimate_receiver(pw: vec3<f32>, nw: vec3<f32>) -> f32 {
    let facing = front_fraction_world(est, pw, nw);
    let p = view_to_light(view, pw);
    // A sphere's silhouette disk seen from p (ok = false: it reaches p's depth).
    let sphere = LIGHT_SHAPE == LIGHT_SPHERE;
    var sil: Sil;
    sil.ok = false;
    if sphere && p.z > 0.0 {
        sil = sil_new(p, est.light_size_x);
    }
    if !(facing > 0.0) {
        return 0.0;
    }
    if p.z <= 0.0 || (sphere && !sil.ok) {
        atomicAdd(&counters[0], 1u);
        return facing;
    }
    if p.z <= view.n {
        return facing;
    }
    let uv = project(view, p);
    if !view_contains(view, uv) {
        atomicAdd(&counters[0], 1u);
        return facing;
    }
    let n = view_dir_to_light(view, nw);
    let vis = visibility(p, n, uv, sil);
    if vis == DEFERRED_V {
        return DEFERRED_V;
    }
    return facing * vis;
}

// The entry point is the core's (receivers.wgsl); its loop-budget probe is this uniform's.
fn receiver_probe() -> u32 {
    return bp.probe;
}
