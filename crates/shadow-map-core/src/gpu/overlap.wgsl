// Twins of shadow_map_core::overlap (areas of overlap with a light on its plane), in f32 and in
// the CPU's operation order. Shared by accumulation and backprojection. The per-edge term
// (edge_disk_area, disk_wedge) is in disk_edge.wgsl, prepended before this file.

// A convex polygon of up to 5 corners (accumulation's MAX_CLIP: a quadrilateral clipped by one
// half-plane).
struct Poly {
    q: array<vec2<f32>, 5>,
    m: u32,
}

// overlap::poly_area.
fn poly_area(pq: Poly) -> f32 {
    var a = 0.0;
    for (var k = 0u; k < pq.m; k++) {
        a += perp_dot(pq.q[k], pq.q[(k + 1u) % pq.m]);
    }
    return abs(0.5 * a);
}

// glam::Vec2::perp_dot.
fn perp_dot(p: vec2<f32>, q: vec2<f32>) -> f32 {
    return (p.x * q.y) - (p.y * q.x);
}

// overlap::quad_disk_area.
fn quad_disk_area(q4: array<vec2<f32>, 4>, r: f32) -> f32 {
    var pq: Poly;
    pq.m = 4u;
    for (var k = 0u; k < 4u; k++) {
        pq.q[k] = q4[k];
    }
    return poly_disk_area(pq, r);
}

// overlap::poly_disk_area.
fn poly_disk_area(pq: Poly, r: f32) -> f32 {
    let m = pq.m;
    var q = pq.q;
    if !(r > 0.0) || m < 3u {
        return 0.0;
    }
    var lo = q[0];
    var hi = q[0];
    for (var k = 1u; k < m; k++) {
        lo = min(lo, q[k]);
        hi = max(hi, q[k]);
    }
    if !(lo.x < r && lo.y < r && hi.x > -r && hi.y > -r) {
        return 0.0;
    }
    let full = PI_F32 * r * r;
    var all_in = true;
    for (var k = 0u; k < m; k++) {
        if !(dot2(q[k], q[k]) <= r * r) {
            all_in = false;
        }
    }
    if all_in {
        var a = 0.0;
        for (var k = 0u; k < m; k++) {
            a += perp_dot(q[k], q[(k + 1u) % m]);
        }
        return min(abs(0.5 * a), full);
    }
    var a2 = 0.0;
    for (var k = 0u; k < m; k++) {
        a2 += perp_dot(q[k], q[(k + 1u) % m]);
    }
    let orient = select(1.0, -1.0, a2 < 0.0);
    var contains = true;
    for (var k = 0u; k < m; k++) {
        let e = q[(k + 1u) % m] - q[k];
        let d = orient * perp_dot(e, -q[k]);
        if !(d >= r * sqrt(dot2(e, e))) {
            contains = false;
        }
    }
    if contains {
        return full;
    }
    var area = 0.0;
    for (var k = 0u; k < m; k++) {
        area += edge_disk_area(q[k], q[(k + 1u) % m], r);
    }
    return min(abs(area), full);
}

// overlap::rect_disk_area.
fn rect_disk_area(x0: f32, y0: f32, x1: f32, y1: f32, r: f32) -> f32 {
    if !(x1 > x0 && y1 > y0) {
        return 0.0;
    }
    var q: array<vec2<f32>, 4>;
    q[0] = vec2<f32>(x0, y0);
    q[1] = vec2<f32>(x1, y0);
    q[2] = vec2<f32>(x1, y1);
    q[3] = vec2<f32>(x0, y1);
    return quad_disk_area(q, r);
}
