// Twin of crates/baselines/src/cpu/pcss.rs (Fernando 2005, docs/methods.md §5): blocker search over
// W_search = l (z_r - n) / z_r, z_avg, penumbra w_p = (z_r - z_avg) l / z_avg, then PCF over
// W_filter = w_p n / z_r with overlap weights (a disk of that diameter for disk and sphere lights).
//
// The CPU twin is pcss::soft_transmittance over DepthTaps: both sum in f32 with Kahan
// compensation (cells.wgsl `Sum`) in the same order, adding only lit taps; it clamps the ratio to
// [0, 1], which here can differ by an ulp where Kahan rounding puts lit above total.

fn facing(p: vec3<f32>, n: vec3<f32>) -> f32 {
    return front_fraction_world(est, p, n);
}

// One tap of cells ci, cj added to the sums `acc`: the blocker search's (the casters' weighted
// depths, their weight), or with `filtering` the filter's (the lit taps' weight, every tap's
// weight), each weight times the disk edge of radius `rad` when `soft_edge`
// (baselines::math::disk_edge, one texel soft). `filtering` is constant at each call, so each
// inlined copy keeps one side.
fn tap(r: ReceiverSample, ci: Cell, cj: Cell, filtering: bool, soft_edge: bool, rad: f32, acc: array<Sum, 2>) -> array<Sum, 2> {
    var a = acc[0];
    var b = acc[1];
    let w0 = ci.w * cj.w;
    if !filtering {
        if caster(r, ci.i, cj.i) {
            a = sum_add(a, w0 * depth_at(ci.i, cj.i));
            b = sum_add(b, w0);
        }
        return array<Sum, 2>(a, b);
    }
    var edge = 1.0;
    if soft_edge {
        let c = vec2<f32>(f32(ci.i) + 0.5, f32(cj.i) + 0.5) - r.uv;
        edge = clamp(rad + 0.5 - sqrt(dot2(c, c)), 0.0, 1.0);
        if edge <= 0.0 {
            return array<Sum, 2>(a, b);
        }
    }
    let w = w0 * edge;
    b = sum_add(b, w);
    if !caster(r, ci.i, cj.i) {
        a = sum_add(a, w);
    }
    return array<Sum, 2>(a, b);
}

// The tap sums over the cells cy x cx, taps in the CPU's order.
fn tap_sums(r: ReceiverSample, cy: Cells, cx: Cells, filtering: bool, soft_edge: bool, rad: f32) -> array<Sum, 2> {
    var acc = array<Sum, 2>(Sum(0.0, 0.0), Sum(0.0, 0.0));
    for (var ky = 0u; ky < cy.count; ky++) {
        let cj = cell(cy, ky);
        if !cj.valid {
            continue;
        }
        for (var kx = 0u; kx < cx.count; kx++) {
            let ci = cell(cx, kx);
            if ci.valid {
                acc = tap(r, ci, cj, filtering, soft_edge, rad, acc);
            }
        }
    }
    return acc;
}

// A region of more cells than this defers its receiver from `estimate` to `estimate_wide`
// (gpu::pcss::WIDE_CELLS; the default never defers: the frame has no wide pass).
override WIDE_CELLS: u32 = 0xffffffffu;

// The value `visibility` returns for a receiver it defers (receivers.wgsl's -2).
const DEFERRED: f32 = -2.0;

// One region of `visibility`: its cells per axis, and the disk edge its taps take (`soft_edge`,
// of radius `rad`; the filter's under a disk or sphere light, never the search's).
struct Region {
    cy: Cells,
    cx: Cells,
    soft_edge: bool,
    rad: f32,
}

// The cells of a region `w` texels wide around the receiver, max_taps a side at most.
fn region_cells(r: ReceiverSample, w: vec2<f32>, soft_edge: bool) -> Region {
    let cy = cells_new(r.uv.y - 0.5 * w.y, r.uv.y + 0.5 * w.y, est.max_taps);
    let cx = cells_new(r.uv.x - 0.5 * w.x, r.uv.x + 0.5 * w.x, est.max_taps);
    return Region(cy, cx, soft_edge, 0.5 * w.x);
}

// 1. The blocker search's region (W_search on the plane z = n).
fn search_region(r: ReceiverSample) -> Region {
    let l = 2.0 * est.light_half_extent;
    let to_texels = f32(view.r) / view.w;
    return region_cells(r, pcss_search_width(l, r.p.z, view.n, to_texels, view.ortho != 0u), false);
}

// 3, 4. The filter's region for the blockers' mean depth z_avg: the penumbra at the receiver
// carried to the plane (W_filter), with the disk edge for disk and sphere lights.
fn filter_region(r: ReceiverSample, z_avg: f32) -> Region {
    let l = 2.0 * est.light_half_extent;
    let to_texels = f32(view.r) / view.w;
    let wf = pcss_filter_width(l, r.p.z, z_avg, view.n, to_texels, view.ortho != 0u);
    return region_cells(r, wf, LIGHT_SHAPE != LIGHT_RECT && wf.x > 1.0);
}

fn region_taps(g: Region) -> u32 {
    return g.cy.count * g.cx.count;
}

fn visibility(r: ReceiverSample) -> f32 {
    let search = search_region(r);
    if region_taps(search) > WIDE_CELLS {
        return DEFERRED;
    }
    let blockers = tap_sums(r, search.cy, search.cx, false, false, 0.0);
    let count = blockers[1].s;
    if count <= 0.0 {
        return 1.0;
    }
    let kernel = filter_region(r, blockers[0].s / count);
    if region_taps(kernel) > WIDE_CELLS {
        return DEFERRED;
    }
    let taps = tap_sums(r, kernel.cy, kernel.cx, true, kernel.soft_edge, kernel.rad);
    if taps[1].s <= 0.0 {
        return 1.0;
    }
    return taps[0].s / taps[1].s;
}

// The wide pass over the receivers `estimate` deferred (a region past WIDE_CELLS), one
// workgroup per receiver (receivers::ListKind::DeferredWide): the same steps as `visibility`,
// each region's taps dealt to the lanes in turn (tap t to lane t mod WG), the lanes' Kahan sums
// added in a tree. The sums' order differs from the CPU's, by rounding only; at most
// ceil(max_taps^2 / WG) taps a region per lane (16,384 at max_taps = 1,024 and WG = 64), well
// inside any loop budget. Lane 0 prepares the receiver and the workgroup reads it back, so no
// barrier lies in a branch.
var<workgroup> lane_sums: array<array<Sum, 2>, WG>;
var<workgroup> wide_receiver: Prepared;

// The sums over region g of every lane's taps (`taps` of them; 0 for none), added in a tree in
// lane_sums, every lane returning the total.
fn wide_sums(r: ReceiverSample, g: Region, filtering: bool, taps: u32, lane: u32) -> array<Sum, 2> {
    var acc = array<Sum, 2>(Sum(0.0, 0.0), Sum(0.0, 0.0));
    for (var t = lane; t < taps; t += WG) {
        let ci = cell(g.cx, t % g.cx.count);
        let cj = cell(g.cy, t / g.cx.count);
        if ci.valid && cj.valid {
            acc = tap(r, ci, cj, filtering, g.soft_edge, g.rad, acc);
        }
    }
    lane_sums[lane] = acc;
    for (var half = WG / 2u; half > 0u; half /= 2u) {
        workgroupBarrier();
        if lane < half {
            let mine = lane_sums[lane];
            let other = lane_sums[lane + half];
            lane_sums[lane] = array<Sum, 2>(
                sum_add(mine[0], other[0].s - other[0].c),
                sum_add(mine[1], other[1].s - other[1].c),
            );
        }
    }
    workgroupBarrier();
    let total = lane_sums[0];
    workgroupBarrier();
    return total;
}

@compute @workgroup_size(WG)
fn estimate_wide(@builtin(workgroup_id) wid: vec3<u32>, @builtin(local_invocation_index) lane: u32) {
    let k = listed_receiver_of_group(wid);
    let listed = k != NONE_LISTED;
    if lane == 0u && listed {
        wide_receiver = prepare(receivers[k].position, receivers[k].normal);
    }
    workgroupBarrier();
    let pr = wide_receiver;
    let sampled = listed && pr.kind == SAMPLED;
    let r = pr.s;
    let search = search_region(r);
    let blockers = wide_sums(r, search, false, select(0u, region_taps(search), sampled), lane);
    let count = blockers[1].s;
    let kernel = filter_region(r, blockers[0].s / count);
    let filtered = sampled && count > 0.0;
    let taps = wide_sums(r, kernel, true, select(0u, region_taps(kernel), filtered), lane);
    if lane != 0u || !listed {
        return;
    }
    var vis = 1.0;
    if filtered && taps[1].s > 0.0 {
        vis = taps[0].s / taps[1].s;
    }
    // Every deferred receiver was sampled by `estimate`; the other kinds only for safety.
    store_v(k, select(pr.fac, pr.fac * vis, sampled));
}
