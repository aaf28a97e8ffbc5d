// GPU twin of crates/shadow-map-core/src/raster.rs (one peeling pass of peeling.rs per draw).
// Prepended by shared.wgsl (LightViewUniform, to_light). Loaded by gpu/raster.rs.

// crate::raster::PEEL_EPS_REL, set from Rust (no default: never a copied literal).
override PEEL_EPS_REL: f32;
// true for peeling passes m >= 1, which keep only fragments strictly behind layer m - 1.
override PEEL: bool;

// Mirrors gpu::raster::RasterParams (checked by tests/layouts.rs).
struct RasterParams {
    bias_constant: f32,
    bias_slope: f32,
    // Casters below this opacity (the vertex's w) are dropped: one opacity level.
    min_opacity: f32,
    _pad1: f32,
}

@group(0) @binding(0) var<uniform> view: LightViewUniform;
@group(0) @binding(1) var<uniform> params: RasterParams;
// Layer m - 1 (a 1x1 placeholder in pass 0, never read there).
@group(0) @binding(2) var prev_layer: texture_2d<f32>;

struct VsOut {
    @builtin(position) clip: vec4<f32>,
    // Linear light-space z, interpolated perspective-correctly (clip.w = z).
    @location(0) z: f32,
    // The caster's opacity (the vertex's w in the GpuScene layout; 1 for an opaque caster).
    @location(1) @interpolate(flat) opacity: f32,
}

// World vertex -> light space -> clip space of the light view, with
//   u z = (n x - x0 z) / delta,  v z = (n y - y0 z) / delta   (light_view::LightView::project, times z)
//   clip = (2 u z / r - z,  z - 2 v z / r,  n,  z)
// so that framebuffer column u and row v are texel (i, j) (wgpu's framebuffer row 0 is NDC y = +1),
// depth = n / z (reversed, infinite far: compare Greater, clear 0), and the clip volume's
// 0 <= clip.z <= clip.w is exactly the CPU near-plane clip z >= n (no far clip).
//
// Orthographic views (the sun, view.ortho = 1): u = (x - x0) / delta, v = (y - y0) / delta,
// clip = (2 u / r - 1, 1 - 2 v / r, ortho_depth(z), 1), z interpolated linearly (clip.w = 1),
// as the CPU's orthographic raster interpolates z itself.
@vertex
fn vs_main(@location(0) world: vec4<f32>) -> VsOut {
    return light_clip(world);
}

// The layer passes' vertex stage: vs_main, except that a caster below params.min_opacity (all
// three vertices share the mesh's opacity) is put behind the near plane (clip.z < 0) and
// clipped whole, so no fragment stage runs for it (one opacity level).
@vertex
fn vs_layer(@location(0) world: vec4<f32>) -> VsOut {
    if world.w < params.min_opacity {
        var out: VsOut;
        out.clip = vec4<f32>(0.0, 0.0, -1.0, 1.0);
        out.z = 0.0;
        out.opacity = world.w;
        return out;
    }
    return light_clip(world);
}

fn light_clip(world: vec4<f32>) -> VsOut {
    let l = to_light(view, world.xyz);
    let r = f32(view.r);
    if view.ortho != 0u {
        let u = (l.x - view.window_min.x) / view.delta;
        let v = (l.y - view.window_min.y) / view.delta;
        var out: VsOut;
        out.clip = vec4<f32>(2.0 * u / r - 1.0, 1.0 - 2.0 * v / r, ortho_depth(l.z), 1.0);
        out.z = l.z;
        out.opacity = world.w;
        return out;
    }
    let uz = (view.n * l.x - view.window_min.x * l.z) / view.delta;
    let vz = (view.n * l.y - view.window_min.y * l.z) / view.delta;
    var out: VsOut;
    out.clip = vec4<f32>(2.0 * uz / r - l.z, l.z - 2.0 * vz / r, view.n, l.z);
    out.z = l.z;
    out.opacity = world.w;
    return out;
}

// Stored depth of a fragment: z plus the slope-scaled bias of raster.rs,
//   constant + slope * max(|dz/du|, |dz/dv|),  dz/du = -z^2 d(1/z)/du.
// d(1/z)/du comes from dpdx of the fragment depth n/z, which is affine in (u, v); the 2x2-quad
// difference is therefore the CPU's analytic plane gradient up to f32 rounding (an approximation
// only in that rounding, about 6e-8 * slope * z absolute).
// Orthographic views: the depth test's value, 1 at the near plane falling linearly with z (0
// at n + 2 (far - n), beyond all geometry the window holds, so the rasteriser clips only
// z < n, as the CPU does), and dz/du is z's own screen-space difference.
fn ortho_depth(z: f32) -> f32 {
    return 1.0 - (z - view.n) / ortho_depth_span(view);
}

fn stored_depth(frag: vec4<f32>, z: f32) -> f32 {
    var slope: f32;
    if view.ortho != 0u {
        slope = max(abs(dpdx(z)), abs(dpdy(z)));
    } else {
        let g = max(abs(dpdx(frag.z)), abs(dpdy(frag.z))) / view.n;
        slope = z * z * g;
    }
    var zs = z;
    if params.bias_constant != 0.0 || params.bias_slope != 0.0 {
        zs = zs + (params.bias_constant + params.bias_slope * slope);
    }
    return zs;
}

// Peeling test of peeling.rs: keep only `z > prev * (1 + PEEL_EPS_REL)` (false for NaN and for an
// empty previous texel, prev = +inf).
fn behind_previous(frag: vec4<f32>, zs: f32) -> bool {
    if !PEEL {
        return true;
    }
    let prev = textureLoad(prev_layer, vec2<u32>(frag.xy), 0).x;
    return zs > prev * (1.0 + PEEL_EPS_REL);
}

// Without bias: the depth test uses the rasteriser's n / z.
@fragment
fn fs_layer(in: VsOut) -> @location(0) f32 {
    let zs = stored_depth(in.clip, in.z);
    if !behind_previous(in.clip, zs) {
        discard;
    }
    return zs;
}

struct BiasedOut {
    @location(0) depth: f32,
    @builtin(frag_depth) frag_depth: f32,
}

// With bias: the depth test compares the biased depth (n / zs), so the nearest *stored* value
// wins, as on the CPU (min over biased depths). Returns (stored depth, depth-test value).
fn biased_layer(in: VsOut) -> vec2<f32> {
    let zs = stored_depth(in.clip, in.z);
    if !behind_previous(in.clip, zs) {
        discard;
    }
    if view.ortho != 0u {
        return vec2<f32>(zs, clamp(ortho_depth(zs), 0.0, 1.0));
    }
    return vec2<f32>(zs, clamp(view.n / zs, 0.0, 1.0));
}

@fragment
fn fs_layer_biased(in: VsOut) -> BiasedOut {
    let b = biased_layer(in);
    return BiasedOut(b.x, b.y);
}

// Semi-transparent casters: the layer's depth as above and, in a second target, the opacity of
// the fragment the depth test keeps (the CPU's `rasterize_with_opacity`: the nearest stored
// fragment's mesh opacity; the target is cleared to 0 where no fragment lands).
struct OpacityOut {
    @location(0) depth: f32,
    @location(1) opacity: f32,
}

@fragment
fn fs_layer_opacity(in: VsOut) -> OpacityOut {
    let zs = stored_depth(in.clip, in.z);
    if !behind_previous(in.clip, zs) {
        discard;
    }
    return OpacityOut(zs, in.opacity);
}

struct BiasedOpacityOut {
    @location(0) depth: f32,
    @location(1) opacity: f32,
    @builtin(frag_depth) frag_depth: f32,
}

@fragment
fn fs_layer_biased_opacity(in: VsOut) -> BiasedOpacityOut {
    let b = biased_layer(in);
    return BiasedOpacityOut(b.x, in.opacity, b.y);
}
