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

// The weighted tap sums over the cells cy x cx, taps in the CPU's order: the blocker search's
// (the casters' weighted depths, their weight), or with `filtering` the filter's (the lit taps'
// weight, every tap's weight), each weight times the disk edge of radius `rad` when `soft_edge`
// (baselines::math::disk_edge, one texel soft). `filtering` is constant at each call, so each
// inlined copy keeps one side.
fn tap_sums(r: ReceiverSample, cy: Cells, cx: Cells, filtering: bool, soft_edge: bool, rad: f32) -> array<Sum, 2> {
    var a = Sum(0.0, 0.0);
    var b = Sum(0.0, 0.0);
    for (var ky = 0u; ky < cy.count; ky++) {
        let cj = cell(cy, ky);
        if !cj.valid {
            continue;
        }
        for (var kx = 0u; kx < cx.count; kx++) {
            let ci = cell(cx, kx);
            if !ci.valid {
                continue;
            }
            let w0 = ci.w * cj.w;
            if !filtering {
                if caster(r, ci.i, cj.i) {
                    a = sum_add(a, w0 * depth_at(ci.i, cj.i));
                    b = sum_add(b, w0);
                }
                continue;
            }
            var edge = 1.0;
            if soft_edge {
                let c = vec2<f32>(f32(ci.i) + 0.5, f32(cj.i) + 0.5) - r.uv;
                edge = clamp(rad + 0.5 - sqrt(dot2(c, c)), 0.0, 1.0);
                if edge <= 0.0 {
                    continue;
                }
            }
            let w = w0 * edge;
            b = sum_add(b, w);
            if !caster(r, ci.i, cj.i) {
                a = sum_add(a, w);
            }
        }
    }
    return array<Sum, 2>(a, b);
}

fn visibility(r: ReceiverSample) -> f32 {
    let zr = r.p.z;
    let l = 2.0 * est.light_half_extent;
    let to_texels = f32(view.r) / view.w;
    // 1. Blocker search.
    let ws = pcss_search_width(l, zr, view.n, to_texels, view.ortho != 0u);
    let cy = cells_new(r.uv.y - 0.5 * ws.y, r.uv.y + 0.5 * ws.y, est.max_taps);
    let cx = cells_new(r.uv.x - 0.5 * ws.x, r.uv.x + 0.5 * ws.x, est.max_taps);
    let blockers = tap_sums(r, cy, cx, false, false, 0.0);
    let count = blockers[1].s;
    if count <= 0.0 {
        return 1.0;
    }
    let z_avg = blockers[0].s / count;
    // 3. Penumbra width at the receiver, 4. filter width on the plane (texels).
    let wf = pcss_filter_width(l, zr, z_avg, view.n, to_texels, view.ortho != 0u);
    let soft_edge = LIGHT_SHAPE != LIGHT_RECT && wf.x > 1.0;
    let fy = cells_new(r.uv.y - 0.5 * wf.y, r.uv.y + 0.5 * wf.y, est.max_taps);
    let fx = cells_new(r.uv.x - 0.5 * wf.x, r.uv.x + 0.5 * wf.x, est.max_taps);
    let taps = tap_sums(r, fy, fx, true, soft_edge, 0.5 * wf.x);
    if taps[1].s <= 0.0 {
        return 1.0;
    }
    return taps[0].s / taps[1].s;
}
