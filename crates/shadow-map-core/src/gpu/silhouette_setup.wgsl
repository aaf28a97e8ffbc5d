// Twin of shadow_map_core::silhouette::Silhouette::new and its hull (silhouette::HULL_DIRS,
// HULL_SCALE, hull_point), in f32 and in the CPU's operation order: the per-receiver set-up of a
// sphere light's silhouette disk that backprojection's kernel and packet-hsm's frame set-up share.
// After math.wgsl (dot3, valid_rcp, default_tangent, cross3, pos_inf, is_finite) and
// silhouette.wgsl (silhouette_carry).

// silhouette::HULL_DIRS and HULL_SCALE: the octagon circumscribing a silhouette disk.
const S45: f32 = 0.70710677;
const HULL_SCALE: f32 = 1.0823922;

fn hull_dir(k: u32) -> vec2<f32> {
    switch k {
        case 0u: { return vec2<f32>(1.0, 0.0); }
        case 1u: { return vec2<f32>(S45, S45); }
        case 2u: { return vec2<f32>(0.0, 1.0); }
        case 3u: { return vec2<f32>(-S45, S45); }
        case 4u: { return vec2<f32>(-1.0, 0.0); }
        case 5u: { return vec2<f32>(-S45, -S45); }
        case 6u: { return vec2<f32>(0.0, -1.0); }
        default: { return vec2<f32>(S45, -S45); }
    }
}

// silhouette::hull_point.
fn hull_point(e1: vec3<f32>, e2: vec3<f32>, r: f32, k: u32) -> vec3<f32> {
    let d = hull_dir(k);
    let rr = r * HULL_SCALE;
    return e1 * (d.x * rr) + e2 * (d.y * rr);
}

// silhouette::Silhouette (ok = false for None).
struct Sil {
    a: vec3<f32>,
    e1: vec3<f32>,
    e2: vec3<f32>,
    dist: f32,
    radius: f32,
    clip: vec4<f32>,
    ok: bool,
}

// Silhouette::new.
fn sil_new(p: vec3<f32>, radius: f32) -> Sil {
    var s: Sil;
    s.ok = false;
    s.dist = sqrt(dot3(p, p));
    let rcp = valid_rcp(p);
    if rcp == 0.0 {
        return s;
    }
    s.a = p * rcp;
    s.e1 = default_tangent(s.a);
    s.e2 = cross3(s.a, s.e1);
    s.radius = radius;
    var clip = vec4<f32>(pos_inf(), pos_inf(), -pos_inf(), -pos_inf());
    for (var k = 0u; k < 8u; k++) {
        let x = hull_point(s.e1, s.e2, radius, k);
        if !(x.z < p.z) {
            return s;
        }
        let y = p + (x - p) * (p.z / (p.z - x.z));
        clip = vec4<f32>(min(clip.x, y.x), min(clip.y, y.y), max(clip.z, y.x), max(clip.w, y.y));
    }
    s.clip = clip;
    s.ok = is_finite(clip.x) && is_finite(clip.y) && is_finite(clip.z) && is_finite(clip.w);
    return s;
}

// Silhouette::carry: a point of z = 0 onto the silhouette plane, in-plane coordinates (the core's
// silhouette.wgsl).
fn sil_carry(s: Sil, x: f32, y: f32) -> vec2<f32> {
    return silhouette_carry(s.a, s.e1, s.e2, s.dist, x, y);
}
