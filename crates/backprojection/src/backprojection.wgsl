// Twin of crates/backprojection/src/cpu.rs and math.rs, in f32 and in the CPU's operation order.
// Prepended: the core's SHARED_WGSL, the baselines' shared.wgsl and common.wgsl (receiver bias,
// light frames, front_fraction_world).
//
// Known difference: the CPU sums area(B_s ∩ L) in f64 (each term from f64 differences of f32
// bounds); here each term is f32 and the sum is Kahan-compensated f32 (about 1e-7 of the light
// area apart). Per-block occluder depths are recomputed for the gap-filling neighbours instead of
// being stored (same values).

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
    _pad1: u32,
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
// [0]: receivers outside the light frustum, [1]: non-finite results.
@group(0) @binding(7) var<storage, read_write> counters: array<atomic<u32>, 2>;

const FAR_BOUND: f32 = 1e30;

// math::micropatch_scale.
fn micropatch_scale(k: f32, z_s: f32, z_p: f32) -> f32 {
    if !(z_s > 0.0) || !(z_s < z_p) || !(k > 0.0) {
        return 0.0;
    }
    let gap = max(max(z_p - z_s, 1e-7 * z_p), F32_MIN_POSITIVE);
    let s = k * z_s * (z_p / gap);
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
// coordinates and the receiver plane (est.receiver_plane != 0).
struct Rec {
    zp: f32,
    eps: f32,
    uv: vec2<f32>,
    plane: ReceiverPlane,
}

// cpu.rs: true depth of the occluding layer backprojected at block (a, b)'s centre texel
// (layer_rule: the deepest occluding one, or the deepest whose micropatch overlaps the light),
// or +inf.
fn block_occluder(kr: Kernel, a: u32, b: u32, rc: Rec) -> f32 {
    let zp = rc.zp;
    let j0 = kr.rect.y + i32(b * kr.step);
    let j1 = min(j0 + i32(kr.step), kr.rect.w);
    let jc = j0 + (j1 - j0 - 1) / 2;
    let i0 = kr.rect.x + i32(a * kr.step);
    let i1 = min(i0 + i32(kr.step), kr.rect.z);
    let ic = i0 + (i1 - i0 - 1) / 2;
    let on = est.receiver_plane != 0u;
    let first_nonzero = bp.first_nonzero != 0u && bp.area > 0.0;
    let k = view.delta / view.n;
    for (var mm = i32(bp.layers) - 1; mm >= 0; mm--) {
        let z = textureLoad(maps, vec2<i32>(ic, jc), mm, 0).x;
        var occludes = false;
        if bp.midpoint != 0u {
            var cls = z;
            if u32(mm) < bp.midpoints {
                cls = textureLoad(maps, vec2<i32>(ic, jc), i32(bp.layers) + mm, 0).x;
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
            let dx = max(min(x1, bp.half.x) - max(x0, -bp.half.x), 0.0);
            let dy = max(min(y1, bp.half.y) - max(y0, -bp.half.y), 0.0);
            if !(dx * dy > 0.0) {
                continue;
            }
        }
        return z;
    }
    return pos_inf();
}

// Kahan-compensated f32 sum.
struct Sum {
    s: f32,
    c: f32,
}

fn sum_add(a: Sum, x: f32) -> Sum {
    let y = x - a.c;
    let t = a.s + y;
    return Sum(t, (t - a.s) - y);
}

// cpu::Setup::visibility: visibility before the facing factor, in [0, 1].
fn visibility(p: vec3<f32>, n: vec3<f32>, uv: vec2<f32>) -> f32 {
    let zp = p.z;
    var eps = 0.0;
    if bp.midpoint == 0u {
        eps = receiver_bias(view, p, n, bp.b0, bp.b1);
    }
    let on = est.receiver_plane != 0u;
    // The plane test when on (plane_new's classic form is unused: the plane-off tests are
    // written out as cpu.rs has them).
    let rc = Rec(zp, eps, uv, plane_new(on, view, p, n, bp.b0, bp.b1, 0.0));
    let lx = 2.0 * bp.half.x;
    let ly = 2.0 * bp.half.y;
    let alpha = view.n * f32(view.r) / view.w;
    var zm = view.n;
    var rect = kernel_rect(uv, kernel_width(alpha, lx, zm, zp), kernel_width(alpha, ly, zm, zp));
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
        let next = kernel_rect(uv, kernel_width(alpha, lx, zm, zp), kernel_width(alpha, ly, zm, zp));
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
    var step = 1u;
    if nx * ny > bp.max_nspp {
        step = u32(max(ceil(f32(max(nx, ny)) / bp.sqrt_nspp), 1.0));
    }
    let bx = (nx + step - 1u) / step;
    let by = (ny + step - 1u) / step;
    let kr = Kernel(rect, step, bx, by);
    let k = view.delta / view.n;
    var a_occ = Sum(0.0, 0.0);
    for (var b = 0u; b < by; b++) {
        let j0 = rect.y + i32(b * step);
        let j1 = min(j0 + i32(step), rect.w);
        for (var a = 0u; a < bx; a++) {
            let z = block_occluder(kr, a, b, rc);
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
            if bp.gap_filling != 0u {
                if a + 1u < bx {
                    let zt = block_occluder(kr, a + 1u, b, rc);
                    if is_finite(zt) {
                        let st = micropatch_scale(k, zt, zp);
                        let d = f32(i1) - uv.x;
                        if d != 0.0 && st > 0.0 {
                            x1 = max(x1, clamp(d * st, -FAR_BOUND, FAR_BOUND));
                        }
                    }
                }
                if b + 1u < by {
                    let zt = block_occluder(kr, a, b + 1u, rc);
                    if is_finite(zt) {
                        let st = micropatch_scale(k, zt, zp);
                        let d = f32(j1) - uv.y;
                        if d != 0.0 && st > 0.0 {
                            y1 = max(y1, clamp(d * st, -FAR_BOUND, FAR_BOUND));
                        }
                    }
                }
            }
            // math::light_overlap_area (f64 on the CPU).
            let dx = max(min(x1, bp.half.x) - max(x0, -bp.half.x), 0.0);
            let dy = max(min(y1, bp.half.y) - max(y0, -bp.half.y), 0.0);
            a_occ = sum_add(a_occ, dx * dy);
        }
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
    if !(facing > 0.0) || p.z <= 0.0 {
        return 0.0;
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
    return facing * visibility(p, n, uv);
}

@compute @workgroup_size(WG)
fn estimate(@builtin(global_invocation_id) gid: vec3<u32>) {
    let k = gid.x;
    if !active_receiver(k) {
        return;
    }
    let x = estimate_receiver(receivers[k].position, receivers[k].normal);
    store_v(k, x);
}
