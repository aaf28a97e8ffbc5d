// Mirrors crates/shadow-map-core/src/gpu/shared.rs field for field (checked by tests/layouts.rs).

// gpu::shared::FrameGpu (named Frame here): an origin and three unit axes (world). The Rust twin spells out the
// padding after each vec3 (_pad0.._pad3) that WGSL adds implicitly. Held by LightViewUniform
// (frame), EstimateUniform (light_frame) and GBufferCamera (frame).
struct Frame {
    origin: vec3<f32>,
    ex: vec3<f32>,
    ey: vec3<f32>,
    ez: vec3<f32>,
}

struct LightViewUniform {
    frame: Frame,
    n: f32,
    w: f32,
    far: f32,
    r: u32,
    window_min: vec2<f32>,
    delta: f32,
    ortho: u32,
}

// `active` is a reserved word in WGSL: the Rust field `active` is `is_active` here (the only member
// name that differs; tests/layouts.rs maps it).
struct ReceiverGpu {
    position: vec3<f32>,
    is_active: u32,
    normal: vec3<f32>,
    _pad0: f32,
}

// shadow_map_core::light::LightFrame::to_light
fn to_light(v: LightViewUniform, p: vec3<f32>) -> vec3<f32> {
    let d = p - v.frame.origin;
    return vec3<f32>(dot(d, v.frame.ex), dot(d, v.frame.ey), dot(d, v.frame.ez));
}

fn dir_to_light(v: LightViewUniform, d: vec3<f32>) -> vec3<f32> {
    return vec3<f32>(dot(d, v.frame.ex), dot(d, v.frame.ey), dot(d, v.frame.ez));
}

// shadow_map_core::light_view::LightView::project: continuous texel coordinates.
// Orthographic views (the sun): (x, y) itself, not n (x, y) / z.
fn project(v: LightViewUniform, p: vec3<f32>) -> vec2<f32> {
    if v.ortho != 0u {
        return (vec2<f32>(p.x, p.y) - v.window_min) / v.delta;
    }
    return (vec2<f32>(p.x, p.y) * (v.n / p.z) - v.window_min) / v.delta;
}

// The depth span s of an orthographic view's depth test (raster.wgsl's ortho_depth, 1 at the
// near plane falling linearly to 0 at n + s): beyond all geometry the window holds.
fn ortho_depth_span(v: LightViewUniform) -> f32 {
    return max(2.0 * (v.far - v.n), 1e-3 * v.n);
}

// The linear light-space depth z of a raster depth-test value d (the attachment a depth-only
// map pass leaves: n / z reversed, or an orthographic view's 1 - (z - n) / s), +inf where no
// fragment landed (d = 0, the clear value).
fn linear_depth(v: LightViewUniform, d: f32) -> f32 {
    if !(d > 0.0) {
        return bitcast<f32>(0x7f800000u);
    }
    if v.ortho != 0u {
        return v.n + (1.0 - d) * ortho_depth_span(v);
    }
    return v.n / d;
}

// Some devices bound the loop iterations of one invocation: llvmpipe (lavapipe) ends every loop
// once 65535 iterations in all have run (gallivm's LP_MAX_TGSI_LOOP_ITERATIONS), silently. Called
// at the end of a kernel with a uniform `probe` = 2 (gpu::shared::LOOP_PROBE), this two-trip loop
// trips once only when that budget is spent: the receiver is then written as CUT_BITS (a NaN
// payload distinct from a plain NaN) and redone on the CPU (gpu::redo_cut_receivers).
fn loop_limit_hit(probe: u32) -> bool {
    var trips = 0u;
    for (var i = 0u; i < probe; i++) {
        trips += 1u;
    }
    return trips < probe;
}

const CUT_BITS: u32 = 0x7fc0deadu;
// A receiver a kernel's first pass left for its second (receivers::ActiveLists::encode_deferred
// lists them): a NaN payload the second pass overwrites.
const DEFER_BITS: u32 = 0x7fc0defeu;
// The quiet NaN every kernel writes for an inactive receiver.
const NAN_BITS: u32 = 0x7fc00000u;
