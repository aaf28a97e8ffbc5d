// Twins of shadow_map_core::light_view::LightView::receiver_bias and of the pieces of
// shadow_map_core::light the estimators use (LightFrame::to_light, default_tangent, front_fraction,
// Light::front_fraction_world), in f32 and in the CPU's operation order: glam's dot, cross and
// normalize are written out rather than left to builtins whose order the driver picks.
//
// Known difference: front_fraction computes the clipped rect area and the disk segment in f64 on
// the CPU; here they are f32 (about 1e-7 of the light area apart). The disk segment uses a
// Cephes-style acos (about 1 ulp) rather than the driver's, whose accuracy WGSL leaves open.

const PI_F32: f32 = 3.14159265358979;
const HALF_PI_F32: f32 = 1.57079632679490;
const F32_MAX: f32 = 3.40282347e38;
const F32_MIN_POSITIVE: f32 = 1.17549435e-38;

fn pos_inf() -> f32 {
    return bitcast<f32>(0x7f800000u);
}

// glam::Vec3::dot: (x x') + (y y') + (z z').
fn dot3(a: vec3<f32>, b: vec3<f32>) -> f32 {
    return (a.x * b.x) + (a.y * b.y) + (a.z * b.z);
}

// glam::Vec2::dot.
fn dot2(a: vec2<f32>, b: vec2<f32>) -> f32 {
    return (a.x * b.x) + (a.y * b.y);
}

// glam::Vec3::cross.
fn cross3(a: vec3<f32>, b: vec3<f32>) -> vec3<f32> {
    return vec3<f32>(a.y * b.z - b.y * a.z, a.z * b.x - b.z * a.x, a.x * b.y - b.x * a.y);
}

// f32::is_finite, on the bits (immune to a compiler's finite-math assumptions).
fn is_finite(x: f32) -> bool {
    return (bitcast<u32>(x) & 0x7f800000u) != 0x7f800000u;
}

// glam's length_recip (1 / sqrt(v.v)) when it is finite and positive, else 0: the test of
// try_normalize and normalize_or.
fn valid_rcp(v: vec3<f32>) -> f32 {
    let len = sqrt(dot3(v, v));
    if !(len > 0.0) {
        return 0.0;
    }
    let rcp = 1.0 / len;
    if rcp > 0.0 && is_finite(rcp) {
        return rcp;
    }
    return 0.0;
}

// glam::Vec3::normalize_or_zero.
fn normalize_or_zero(v: vec3<f32>) -> vec3<f32> {
    let rcp = valid_rcp(v);
    if rcp == 0.0 {
        return vec3<f32>(0.0);
    }
    return v * rcp;
}

// shadow_map_core::light::LightFrame::to_light for the frame f.
fn frame_to_light(f: Frame, p: vec3<f32>) -> vec3<f32> {
    let d = p - f.origin;
    return vec3<f32>(dot3(d, f.ex), dot3(d, f.ey), dot3(d, f.ez));
}

// shadow_map_core::light::LightFrame::dir_to_light.
fn frame_dir_to_light(f: Frame, d: vec3<f32>) -> vec3<f32> {
    return vec3<f32>(dot3(d, f.ex), dot3(d, f.ey), dot3(d, f.ez));
}

// The light view's LightFrame::to_light (shared.wgsl's to_light with glam's dot order).
fn view_to_light(v: LightViewUniform, p: vec3<f32>) -> vec3<f32> {
    return frame_to_light(v.frame, p);
}

fn view_dir_to_light(v: LightViewUniform, d: vec3<f32>) -> vec3<f32> {
    return frame_dir_to_light(v.frame, d);
}

// shadow_map_core::light_view::LightView::contains.
fn view_contains(v: LightViewUniform, uv: vec2<f32>) -> bool {
    let r = f32(v.r);
    return uv.x >= 0.0 && uv.y >= 0.0 && uv.x < r && uv.y < r;
}

// LightView::receiver_bias: eps = (w z_p / (n r)) (b0 + b1 min(tan theta, 10)).
fn receiver_bias(v: LightViewUniform, p: vec3<f32>, n: vec3<f32>, b0: f32, b1: f32) -> f32 {
    let texel = view_texel_at(v, p.z);
    var to_light = normalize_or_zero(-p);
    if v.ortho != 0u {
        to_light = vec3<f32>(0.0, 0.0, -1.0);
    }
    let cos_t = max(abs(dot3(n, to_light)), 1e-6);
    let tan_t = sqrt(max(1.0 - cos_t * cos_t, 0.0)) / cos_t;
    return texel * (b0 + b1 * min(tan_t, 10.0));
}

// shadow_map_core::light::default_tangent.
fn default_tangent(normal: vec3<f32>) -> vec3<f32> {
    let n = abs(normal);
    var a = vec3<f32>(0.0, 0.0, 1.0);
    if n.x <= n.y && n.x <= n.z {
        a = vec3<f32>(1.0, 0.0, 0.0);
    } else if n.y <= n.z {
        a = vec3<f32>(0.0, 1.0, 0.0);
    }
    let t = a - dot3(a, normal) * normal;
    let rcp = valid_rcp(t);
    if rcp == 0.0 {
        return vec3<f32>(1.0, 0.0, 0.0);
    }
    return t * rcp;
}

// asin for |x| <= 1 after Cephes asinf (S. L. Moshier), about 1 ulp in f32.
fn asin_f32(x: f32) -> f32 {
    let a = abs(x);
    let big = a > 0.5;
    var z = a * a;
    var y = a;
    if big {
        z = 0.5 * (1.0 - a);
        y = sqrt(z);
    }
    var r = ((((4.2163199048e-2 * z + 2.4181311049e-2) * z + 4.5470025998e-2) * z
        + 7.4953002686e-2) * z + 1.6666752422e-1) * z * y + y;
    if big {
        r = HALF_PI_F32 - (r + r);
    }
    return select(r, -r, x < 0.0);
}

// acos after Cephes acosf.
fn acos_f32(x: f32) -> f32 {
    if x < -0.5 {
        return PI_F32 - 2.0 * asin_f32(sqrt(0.5 * (1.0 + x)));
    }
    if x > 0.5 {
        return 2.0 * asin_f32(sqrt(0.5 * (1.0 - x)));
    }
    return HALF_PI_F32 - asin_f32(x);
}

// The shoelace sum of a polygon whose vertices come one at a time (no vertex array: on
// lavapipe a private array indexed by a per-lane count is a scatter and a gather): each vertex
// after the first adds cross(previous, vertex), and shoelace_close adds the closing
// cross(last, first), the terms in the order of the CPU's sum over (v_i, v_(i+1 mod m)).
struct Shoelace {
    first: vec2<f32>,
    prev: vec2<f32>,
    m: u32,
    area: f32,
}

fn shoelace_add(s: Shoelace, v: vec2<f32>) -> Shoelace {
    var o = s;
    if s.m == 0u {
        o.first = v;
    } else {
        o.area += s.prev.x * v.y - v.x * s.prev.y;
    }
    o.prev = v;
    o.m = s.m + 1u;
    return o;
}

fn shoelace_close(s: Shoelace) -> f32 {
    if s.m == 0u {
        return 0.0;
    }
    return s.area + (s.prev.x * s.first.y - s.first.x * s.prev.y);
}

// One edge p0 -> p1 of Sutherland-Hodgman against the half-plane a.y > c: p0 when inside, then
// the crossing when the edge crosses, into the sum.
fn shoelace_clip_edge(s: Shoelace, a: vec2<f32>, c: f32, p0: vec2<f32>, p1: vec2<f32>) -> Shoelace {
    let f0 = dot2(a, p0) - c;
    let f1 = dot2(a, p1) - c;
    var o = s;
    if f0 > 0.0 {
        o = shoelace_add(o, p0);
    }
    if (f0 > 0.0) != (f1 > 0.0) {
        let t = f0 / (f0 - f1);
        o = shoelace_add(o, p0 + (p1 - p0) * t);
    }
    return o;
}

// shadow_map_core::light::front_fraction: fraction of the light (rect or disk in the plane z = 0
// of the frame p and n are given in) strictly in front of the tangent plane {y : n.(y - p) > 0}.
// `size`: rect (width, height); disk and sphere (radius, radius).
fn front_fraction(shape: u32, size: vec2<f32>, p: vec3<f32>, n: vec3<f32>) -> f32 {
    let c = dot3(n, p);
    let a = vec2<f32>(n.x, n.y);
    let la = sqrt(dot2(a, a));
    if shape == LIGHT_RECT {
        let hx = 0.5 * size.x;
        let hy = 0.5 * size.y;
        if la < 1e-12 {
            return select(0.0, 1.0, 0.0 > c);
        }
        // Clip the rectangle polygon by the half-plane a.y > c (Sutherland-Hodgman, one edge),
        // its vertices streamed into the shoelace sum (shoelace_clip_edge).
        let c0 = vec2<f32>(-hx, -hy);
        let c1 = vec2<f32>(hx, -hy);
        let c2 = vec2<f32>(hx, hy);
        let c3 = vec2<f32>(-hx, hy);
        var sl = Shoelace(vec2<f32>(0.0), vec2<f32>(0.0), 0u, 0.0);
        sl = shoelace_clip_edge(sl, a, c, c0, c1);
        sl = shoelace_clip_edge(sl, a, c, c1, c2);
        sl = shoelace_clip_edge(sl, a, c, c2, c3);
        sl = shoelace_clip_edge(sl, a, c, c3, c0);
        let area = shoelace_close(sl);
        let total = size.x * size.y;
        if total <= 0.0 {
            return select(0.0, 1.0, 0.0 > c);
        }
        return clamp((0.5 * area) / total, 0.0, 1.0);
    }
    // Disk (and a sphere's silhouette disk).
    let radius = size.x;
    if la < 1e-12 || radius <= 0.0 {
        return select(0.0, 1.0, 0.0 > c);
    }
    // Signed distance of the line from the disk centre along a/|a|; the segment beyond t.
    let d = c / la;
    let t = clamp(d / radius, -1.0, 1.0);
    // (acos t - t sqrt(1 - t^2)) / pi, with 1 - t^2 = (1 - t)(1 + t) (no cancellation at |t| ~ 1).
    let seg = (acos_f32(t) - t * sqrt((1.0 - t) * (1.0 + t))) / PI_F32;
    return clamp(seg, 0.0, 1.0);
}

// shadow_map_core::light::Light::front_fraction_world: the fraction of the light in front of the
// tangent plane of world point p with unit normal n; 0 behind a one-sided emitter; for a sphere
// over its silhouette disk (frame at the centre whose z axis points from the light towards p).
// The shape is the pipeline's LIGHT_SHAPE (u's own light_shape is the same).
fn front_fraction_world(u: EstimateUniform, p: vec3<f32>, n: vec3<f32>) -> f32 {
    let size = vec2<f32>(u.light_size_x, u.light_size_y);
    if LIGHT_SHAPE == LIGHT_DIRECTIONAL {
        // Light::front_fraction_world: the disk of directions one unit from p, facing it.
        return front_fraction(LIGHT_DISK, size, vec3<f32>(0.0, 0.0, 1.0), frame_dir_to_light(u.light_frame, n));
    }
    if LIGHT_SHAPE != LIGHT_SPHERE {
        let pl = frame_to_light(u.light_frame, p);
        if pl.z <= 0.0 {
            return 0.0;
        }
        return front_fraction(LIGHT_SHAPE, size, pl, frame_dir_to_light(u.light_frame, n));
    }
    let d = u.light_frame.origin - p;
    let md = -d;
    let rcp = valid_rcp(md);
    if rcp == 0.0 {
        return 0.0;
    }
    let dz = md * rcp;
    let ex = default_tangent(dz);
    let f = Frame(u.light_frame.origin, ex, cross3(dz, ex), dz);
    return front_fraction(LIGHT_SHAPE, size, frame_to_light(f, p), frame_dir_to_light(f, n));
}

// shadow_map_core::mssm::kernel_width: the blocker-search kernel width in texels (Guennebaud's
// search area, Yang eq. 1), 0 when nothing nearer than the receiver, f32::MAX when not finite.
fn kernel_width(alpha: f32, l: f32, z_m: f32, z_p: f32) -> f32 {
    if !(z_m < z_p) {
        return 0.0;
    }
    let zm = max(z_m, F32_MIN_POSITIVE);
    let w = alpha * l * (1.0 / zm - 1.0 / z_p);
    if is_finite(w) {
        return max(w, 0.0);
    }
    return F32_MAX;
}

// shadow_map_core::light_view::LightView::kernel_texels: kernel_width in perspective; for the
// sun's orthographic view the occluder prism's width l (z_p - z_m) / delta.
fn view_kernel_texels(v: LightViewUniform, l: f32, z_m: f32, z_p: f32) -> f32 {
    if v.ortho == 0u {
        return kernel_width(v.n * f32(v.r) / v.w, l, z_m, z_p);
    }
    if !(z_m < z_p) {
        return 0.0;
    }
    let w = l * (z_p - z_m) / v.delta;
    if is_finite(w) {
        return max(w, 0.0);
    }
    return F32_MAX;
}

// shadow_map_core::mssm::Mssm::query(..).min over the texel rectangle (x0, y0, x1, y1) of an MSSM
// stored as the levels of a texture array: the same level choice and window starts as the CPU,
// so the same fetches. -inf when there is no MSSM (`present == 0`), +inf for an empty rectangle.
fn mssm_min_in(mssm: texture_2d_array<f32>, present: u32, size: u32, levels: u32, rect: vec4<i32>) -> f32 {
    if present == 0u {
        return -pos_inf();
    }
    let s = i32(size);
    let x0 = clamp(rect.x, 0, s);
    let y0 = clamp(rect.y, 0, s);
    let x1 = clamp(rect.z, 0, s);
    let y1 = clamp(rect.w, 0, s);
    if !(x0 < x1 && y0 < y1) || levels == 0u {
        return pos_inf();
    }
    let m = u32(min(x1 - x0, y1 - y0));
    let l = min(firstLeadingBit(m), levels - 1u);
    let h = i32(1u << l);
    let last_x = max(x1 - h, x0);
    let last_y = max(y1 - h, y0);
    var best = pos_inf();
    var y = y0;
    loop {
        let yc = select(last_y, y, y < last_y);
        var x = x0;
        loop {
            let xc = select(last_x, x, x < last_x);
            best = min(best, textureLoad(mssm, vec2<i32>(xc, yc), i32(l), 0).x);
            if x >= last_x {
                break;
            }
            x += h;
        }
        if y >= last_y {
            break;
        }
        y += h;
    }
    return best;
}

// shadow_map_core::light_view::LightView::texel_at: w z / (n r), orthographic w / r.
fn view_texel_at(v: LightViewUniform, z: f32) -> f32 {
    if v.ortho != 0u {
        return v.delta;
    }
    return v.w * z / (v.n * f32(v.r));
}

// shadow_map_core::light_view::LightView::max_dir_len.
fn view_max_dir_len(v: LightViewUniform) -> f32 {
    if v.ortho != 0u {
        return 1.0;
    }
    let a = max(abs(v.window_min), abs(v.window_min + vec2<f32>(v.w))) / v.n;
    return sqrt(dot2(a, a) + 1.0);
}

// shadow_map_core::receiver_plane::ReceiverPlane (docs/methods.md §2, "Receiver plane"): a sample
// at depth z on the ray through texel coordinates uv is a caster when
// z finite && z < zp && (z + hs) (g0 + gu u + gv v) < c + cu u + cv v, zp = z_p - hs. PLANE_ROUNDING and PLANE_SNAP are overrides set
// from receiver_plane::{ROUNDING, SNAP}.
struct ReceiverPlane {
    g0: f32,
    gu: f32,
    gv: f32,
    c: f32,
    cu: f32,
    cv: f32,
    zp: f32,
    hs: f32,
}

// ReceiverPlane::new: the plane test when `on`, else the classic z < z_p - receiver_bias.
fn plane_new(on: bool, v: LightViewUniform, p: vec3<f32>, n: vec3<f32>, b0: f32, b1: f32, hs: f32) -> ReceiverPlane {
    if !on {
        return ReceiverPlane(1.0, 0.0, 0.0, p.z - receiver_bias(v, p, n, b0, b1), 0.0, 0.0, p.z - hs, hs);
    }
    let texel = view_texel_at(v, p.z);
    if v.ortho != 0u {
        let corner = max(max(abs(v.window_min.x), abs(v.window_min.y)), 0.0) + v.w;
        let tau_o = PLANE_ROUNDING * (sqrt(dot3(p, p)) + corner) + (PLANE_SNAP + b0) * texel;
        let c0 = -dot3(n, p) - tau_o + n.x * v.window_min.x + n.y * v.window_min.y;
        return ReceiverPlane(-n.z + PLANE_ROUNDING, 0.0, 0.0, c0, n.x * v.delta, n.y * v.delta, p.z - hs, hs);
    }
    let kappa = PLANE_ROUNDING * view_max_dir_len(v);
    let tau = PLANE_ROUNDING * sqrt(dot3(p, p)) + (PLANE_SNAP + b0) * texel;
    let s = v.delta / v.n;
    let o = v.window_min / v.n;
    return ReceiverPlane(-(n.x * o.x + n.y * o.y + n.z) + kappa, -n.x * s, -n.y * s, -dot3(n, p) - tau, 0.0, 0.0, p.z - hs, hs);
}

fn plane_slope_at(rp: ReceiverPlane, uv: vec2<f32>) -> f32 {
    return rp.g0 + rp.gu * uv.x + rp.gv * uv.y;
}

// ReceiverPlane::height_at: c + cu u + cv v.
fn plane_height_at(rp: ReceiverPlane, uv: vec2<f32>) -> f32 {
    return rp.c + rp.cu * uv.x + rp.cv * uv.y;
}

fn plane_caster_at(rp: ReceiverPlane, uv: vec2<f32>, z: f32) -> bool {
    return is_finite(z) && z < rp.zp && (z + rp.hs) * plane_slope_at(rp, uv) < plane_height_at(rp, uv);
}

fn plane_caster(rp: ReceiverPlane, i: i32, j: i32, z: f32) -> bool {
    return plane_caster_at(rp, vec2<f32>(f32(i) + 0.5, f32(j) + 0.5), z);
}

// ReceiverPlane::threshold_at.
fn plane_threshold_at(rp: ReceiverPlane, uv: vec2<f32>) -> f32 {
    let g = plane_slope_at(rp, uv);
    if g > 0.0 {
        return min(plane_height_at(rp, uv) / g - rp.hs, rp.zp);
    }
    return rp.zp;
}

// ReceiverPlane::max_threshold over the texel rectangle [u0, u1] x [v0, v1] (g is affine: the
// largest bound is at a corner).
fn plane_max_threshold(rp: ReceiverPlane, u0: f32, u1: f32, v0: f32, v1: f32) -> f32 {
    let a = max(plane_threshold_at(rp, vec2<f32>(u0, v0)), plane_threshold_at(rp, vec2<f32>(u1, v0)));
    let b = max(plane_threshold_at(rp, vec2<f32>(u0, v1)), plane_threshold_at(rp, vec2<f32>(u1, v1)));
    return max(a, b);
}
