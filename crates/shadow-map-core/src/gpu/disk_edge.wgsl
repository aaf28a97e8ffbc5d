// Twins of shadow_map_core::overlap::{disk_wedge, edge_disk_area} (docs/methods.md §9, §3 "Disk
// lights"), in f32 and in the CPU's operation order (glam's perp_dot and dot written out). Self-
// contained (builtins only), so a kernel without the estimate head (packet-hsm) can prepend it;
// overlap.wgsl's poly_disk_area sums edge_disk_area.

// overlap::disk_wedge: r^2 atan2(cross(p, q), dot(p, q)) / 2.
fn disk_wedge(p: vec2<f32>, q: vec2<f32>, r: f32) -> f32 {
    return 0.5 * r * r * atan2((p.x * q.y) - (p.y * q.x), (p.x * q.x) + (p.y * q.y));
}

// overlap::edge_disk_area: signed area of the triangle (0, p0, p1) inside the disk.
fn edge_disk_area(p0: vec2<f32>, p1: vec2<f32>, r: f32) -> f32 {
    let d = p1 - p0;
    let a = (d.x * d.x) + (d.y * d.y);
    let b = (p0.x * d.x) + (p0.y * d.y);
    let cc = ((p0.x * p0.x) + (p0.y * p0.y)) - r * r;
    let disc = b * b - a * cc;
    if !(disc > 0.0) || !(a > 0.0) {
        return disk_wedge(p0, p1, r);
    }
    let sq = sqrt(disc);
    let t1 = clamp((-b - sq) / a, 0.0, 1.0);
    let t2 = clamp((-b + sq) / a, 0.0, 1.0);
    let q1 = p0 + d * t1;
    let q2 = p0 + d * t2;
    var area = 0.0;
    if t1 > 0.0 {
        area += disk_wedge(p0, q1, r);
    }
    if t2 > t1 {
        area += 0.5 * ((q1.x * q2.y) - (q1.y * q2.x));
    }
    if t2 < 1.0 {
        area += disk_wedge(q2, p1, r);
    }
    return area;
}
