// Twins of crates/baselines/src/map_estimator.rs `cells` and pcss.rs `Kahan`, shared by every
// kernel that samples a region of a map by cells (the baselines' map estimator and PCSS,
// deep-shadow's filter=pcss). No bindings: a part that any module may include.

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
