// Twins of crates/baselines/src/map_estimator.rs `cells` and pcss.rs `Kahan`, `search_width` and
// `filter_width`, shared by every kernel that samples a region of a map by cells (the baselines'
// map estimator and PCSS, deep-shadow's filter=pcss). No bindings: a part that any module may
// include.

// pcss::search_width in texels: the blocker search region W_search = l (z_r - n) / z_r on the
// plane z = n, or l (z_r - n) world units in an orthographic view (the sun); `l` the light's
// extent per axis (world units; the sun's: 2 tan(angle / 2)), `to_texels` = r / w.
fn pcss_search_width(l: vec2<f32>, zr: f32, n: f32, to_texels: f32, ortho: bool) -> vec2<f32> {
    if ortho {
        return l * (zr - n) * to_texels;
    }
    return l * ((zr - n) / zr) * to_texels;
}

// pcss::filter_width in texels: the penumbra w_p = (z_r - z_avg) l / z_avg carried to the plane
// z = n (times n / z_r), or (z_r - z_avg) l world units kept by an orthographic map (the sun).
fn pcss_filter_width(l: vec2<f32>, zr: f32, z_avg: f32, n: f32, to_texels: f32, ortho: bool) -> vec2<f32> {
    if ortho {
        return l * (zr - z_avg) * to_texels;
    }
    return l * ((zr - z_avg) / z_avg) * (n / zr) * to_texels;
}

// map_estimator::cells, as an indexable range: [a, b) split in whole texels clipped to the
// interval when it spans at most `max` texels (mode 1), in `max` equal cells otherwise (mode 2),
// or one cell of weight 1 at floor(a) when empty (mode 0).
struct Cells {
    a: f32,
    b: f32,
    first: f32,
    count: u32,
    mode: u32,
    step: f32,
}

// One cell: texel index and weight; `valid` false for a texel the CPU skips (`hi <= lo`).
struct Cell {
    i: i32,
    w: f32,
    valid: bool,
}

fn cells_new(a: f32, b: f32, max_cells: u32) -> Cells {
    let len = b - a;
    if !(len > 0.0) {
        return Cells(a, b, floor(a), 1u, 0u, 0.0);
    }
    let first = floor(a);
    let last = max(ceil(b) - 1.0, first);
    if last - first + 1.0 <= f32(max_cells) {
        return Cells(a, b, first, u32(last - first) + 1u, 1u, 0.0);
    }
    return Cells(a, b, first, max_cells, 2u, len / f32(max_cells));
}

fn cell(c: Cells, k: u32) -> Cell {
    if c.mode == 0u {
        return Cell(i32(c.first), 1.0, true);
    }
    if c.mode == 1u {
        let i = c.first + f32(k);
        let lo = max(i, c.a);
        let hi = min(i + 1.0, c.b);
        return Cell(i32(i), hi - lo, hi > lo);
    }
    let x = c.a + (f32(k) + 0.5) * c.step;
    return Cell(i32(floor(x)), c.step, true);
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
