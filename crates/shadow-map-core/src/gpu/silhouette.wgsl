// Twin of shadow_map_core::silhouette::Silhouette::carry, in f32 and in the CPU's operation order
// (glam's Vec3::dot written out). Self-contained (builtins only), so a kernel without the estimate
// head (packet-hsm) can prepend it; backprojection's sil_carry calls it.

// Silhouette::carry: the point (x, y, 0) of z = 0 onto the silhouette plane (unit normal a, axes
// e1, e2, dist = |p|), in-plane coordinates t (Y.e1, Y.e2), t = |p| / (|p| - a.Y).
fn silhouette_carry(a: vec3<f32>, e1: vec3<f32>, e2: vec3<f32>, dist: f32, x: f32, y: f32) -> vec2<f32> {
    let yv = vec3<f32>(x, y, 0.0);
    let t = dist / (dist - ((a.x * yv.x) + (a.y * yv.y) + (a.z * yv.z)));
    let c1 = (yv.x * e1.x) + (yv.y * e1.y) + (yv.z * e1.z);
    let c2 = (yv.x * e2.x) + (yv.y * e2.y) + (yv.z * e2.z);
    return vec2<f32>(c1, c2) * t;
}
