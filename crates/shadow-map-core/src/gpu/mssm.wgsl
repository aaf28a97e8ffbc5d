// GPU twin of crates/shadow-map-core/src/mssm.rs: the anchored MSSM (Schwarz & Stamminger 2007),
// the dual-grid MSSM (Yang et al. 2009, §4.2) and the min/max pyramid (Dmitriev & Uralsky 2007).
// Loaded by gpu/mssm.rs. Every level is a pair of f32 storage buffers (min plane, max plane),
// row-major. A dispatch handles a chunk of output rows [row0, row0 + rows); each buffer is bound
// as a range starting at an aligned offset, and *_base is the element index of the chunk's first
// row inside its range, so levels larger than a storage binding are built chunk by chunk.
// min and max are exact, so results are bit-identical to the CPU.

override WG_X: u32;
override WG_Y: u32;
// anchored_step builds the min planes only (for kernels that query no maximum depth; the max
// planes are neither read nor written).
override MIN_ONLY: bool = false;

// Mirrors gpu::mssm::MinMaxParams (checked by tests/layouts.rs).
struct MinMaxParams {
    // Side of the source level.
    size: u32,
    // Side of the output level (size, or ceil(size / 2) for a pyramid reduction).
    out_size: u32,
    // Window offset h = 2^l of an anchored step.
    h: u32,
    // First output row of the chunk, and the number of rows.
    row0: u32,
    rows: u32,
    // Element index, in its bound range, of the chunk's first source row (row0, or 2 row0 for a
    // reduction), of the first "bottom" row (row0 + h), and of the first output row.
    top_base: u32,
    bot_base: u32,
    out_base: u32,
    // The depth of an empty texel, +inf (WGSL has no infinity literal).
    empty_depth: f32,
    _pad0: u32,
    _pad1: u32,
    _pad2: u32,
}

@group(0) @binding(0) var<uniform> params: MinMaxParams;
// load_depth: the depth map.
@group(0) @binding(1) var depth_map: texture_2d<f32>;
// anchored_step: rows [row0, row0 + rows) and [row0 + h, ...) of the source level;
// reduce: rows [2 row0, 2 (row0 + rows)) of the source level (top_* only).
@group(0) @binding(3) var<storage, read> top_min: array<f32>;
@group(0) @binding(4) var<storage, read> top_max: array<f32>;
@group(0) @binding(5) var<storage, read> bot_min: array<f32>;
@group(0) @binding(6) var<storage, read> bot_max: array<f32>;
// Output rows (load_depth writes out_min only).
@group(0) @binding(7) var<storage, read_write> out_min: array<f32>;
@group(0) @binding(8) var<storage, read_write> out_max: array<f32>;

// mssm::sanitize: NaN is an empty texel. Tested on the bits, so no fast-math assumption can drop it.
fn is_nan(d: f32) -> bool {
    return (bitcast<u32>(d) & 0x7fffffffu) > 0x7f800000u;
}

// mssm::sanitized_level0: the depth map as a buffer, NaN -> +inf.
@compute @workgroup_size(WG_X, WG_Y)
fn load_depth(@builtin(global_invocation_id) id: vec3<u32>) {
    let x = id.x;
    let r = id.y;
    if x >= params.size || r >= params.rows {
        return;
    }
    var d = textureLoad(depth_map, vec2<u32>(x, params.row0 + r), 0).x;
    if is_nan(d) {
        d = params.empty_depth;
    }
    out_min[params.out_base + r * params.size + x] = d;
}

// mssm::anchored_step:
//   out(x, y) = src(x, y) ∪ src(x+h, y) ∪ src(x, y+h) ∪ src(x+h, y+h), fetches outside the map skipped.
@compute @workgroup_size(WG_X, WG_Y)
fn anchored_step(@builtin(global_invocation_id) id: vec3<u32>) {
    let s = params.size;
    let h = params.h;
    let x = id.x;
    let r = id.y;
    if x >= s || r >= params.rows {
        return;
    }
    let y = params.row0 + r;
    let right = x + h < s;
    let t = params.top_base + r * s + x;
    let below = y + h < s;
    let b = params.bot_base + r * s + x;
    // The right anchors, or the left ones again outside the map (min and max are idempotent).
    let tr = select(t, t + h, right);
    let br = select(b, b + h, right);
    let o = params.out_base + r * s + x;
    var mn = min(top_min[t], top_min[tr]);
    if below {
        mn = min(mn, min(bot_min[b], bot_min[br]));
    }
    out_min[o] = mn;
    if MIN_ONLY {
        return;
    }
    var mx = max(top_max[t], top_max[tr]);
    if below {
        mx = max(mx, max(bot_max[b], bot_max[br]));
    }
    out_max[o] = mx;
}

// mssm::anchored_step over a whole level bound at once (no chunks), BLOCK x BLOCK outputs per
// invocation: the outputs (x0 + i h, y0 + j h), i, j < BLOCK, share their sources, so the
// (BLOCK + 1)^2 texels (x0 + i h, y0 + j h), i, j <= BLOCK, are each read once per plane (25 reads
// for 16 outputs instead of 64). Invocation (gx, gy) takes the phase (gx mod h, gy mod h) and the
// block gx / h, gy / h of that phase's lattice; the dispatch covers h ceil(s / (h BLOCK)) per axis
// (gpu::mssm::block_invocations). Same values as anchored_step: min and max are exact.
const BLOCK: u32 = 4u;

// Row y's right-anchored unions m_i = src(x_i) ∪ src(x_i + h) (src(x_i) alone where x_i + h is
// outside), x_i = x0 + i h, i < BLOCK; columns outside the map are left at the identity.
fn block_row_min(base: u32, x0: u32, h: u32, s: u32) -> array<f32, BLOCK> {
    var a: array<f32, 5>;
    for (var i = 0u; i <= BLOCK; i++) {
        a[i] = params.empty_depth;
        if x0 + i * h < s {
            a[i] = top_min[base + x0 + i * h];
        }
    }
    var m: array<f32, BLOCK>;
    for (var i = 0u; i < BLOCK; i++) {
        m[i] = min(a[i], a[i + 1u]);
    }
    return m;
}

fn block_row_max(base: u32, x0: u32, h: u32, s: u32) -> array<f32, BLOCK> {
    var a: array<f32, 5>;
    for (var i = 0u; i <= BLOCK; i++) {
        a[i] = -params.empty_depth;
        if x0 + i * h < s {
            a[i] = top_max[base + x0 + i * h];
        }
    }
    var m: array<f32, BLOCK>;
    for (var i = 0u; i < BLOCK; i++) {
        m[i] = max(a[i], a[i + 1u]);
    }
    return m;
}

@compute @workgroup_size(WG_X, WG_Y)
fn anchored_block(@builtin(global_invocation_id) id: vec3<u32>) {
    let s = params.size;
    let h = params.h;
    let span = h * BLOCK;
    let x0 = id.x % h + (id.x / h) * span;
    let y0 = id.y % h + (id.y / h) * span;
    if x0 >= s || y0 >= s {
        return;
    }
    // Row y0 + j h's unions, j = 0..=BLOCK; output row j is the union of rows j and j + 1 (row j
    // alone where row j + 1 is outside the map). The identity (+inf for min, -inf for max) stands
    // in for texels outside, so the unions skip them as anchored_step's fetches do.
    var up_min = block_row_min(params.top_base + y0 * s, x0, h, s);
    var up_max: array<f32, BLOCK>;
    if !MIN_ONLY {
        up_max = block_row_max(params.top_base + y0 * s, x0, h, s);
    }
    for (var j = 0u; j < BLOCK; j++) {
        let y = y0 + j * h;
        if y >= s {
            return;
        }
        var dn_min: array<f32, BLOCK>;
        var dn_max: array<f32, BLOCK>;
        for (var i = 0u; i < BLOCK; i++) {
            dn_min[i] = params.empty_depth;
            dn_max[i] = -params.empty_depth;
        }
        if y + h < s {
            dn_min = block_row_min(params.top_base + (y + h) * s, x0, h, s);
            if !MIN_ONLY {
                dn_max = block_row_max(params.top_base + (y + h) * s, x0, h, s);
            }
        }
        for (var i = 0u; i < BLOCK; i++) {
            let x = x0 + i * h;
            if x < s {
                out_min[params.out_base + y * s + x] = min(up_min[i], dn_min[i]);
                if !MIN_ONLY {
                    out_max[params.out_base + y * s + x] = max(up_max[i], dn_max[i]);
                }
            }
        }
        up_min = dn_min;
        up_max = dn_max;
    }
}

// MinMaxPyramid::reduce: out(x, y) = ∪ of the 2x2 children (2x..2x+1, 2y..2y+1) inside the source.
@compute @workgroup_size(WG_X, WG_Y)
fn reduce(@builtin(global_invocation_id) id: vec3<u32>) {
    let sp = params.size;
    let x = id.x;
    let r = id.y;
    if x >= params.out_size || r >= params.rows {
        return;
    }
    let y = params.row0 + r;
    let c0 = 2u * x;
    let has_right = c0 + 1u < sp;
    var mn = top_min[params.top_base + 2u * r * sp + c0];
    var mx = top_max[params.top_base + 2u * r * sp + c0];
    if has_right {
        mn = min(mn, top_min[params.top_base + 2u * r * sp + c0 + 1u]);
        mx = max(mx, top_max[params.top_base + 2u * r * sp + c0 + 1u]);
    }
    if 2u * y + 1u < sp {
        let b = params.top_base + (2u * r + 1u) * sp + c0;
        mn = min(mn, top_min[b]);
        mx = max(mx, top_max[b]);
        if has_right {
            mn = min(mn, top_min[b + 1u]);
            mx = max(mx, top_max[b + 1u]);
        }
    }
    let o = params.out_base + r * params.out_size + x;
    out_min[o] = mn;
    out_max[o] = mx;
}
