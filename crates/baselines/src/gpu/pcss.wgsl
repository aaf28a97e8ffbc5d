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

fn visibility(r: ReceiverSample) -> f32 {
    let zr = r.p.z;
    let l = 2.0 * est.light_half_extent;
    let to_texels = f32(view.r) / view.w;
    // 1. Blocker search.
    let ws = pcss_search_width(l, zr, view.n, to_texels, view.ortho != 0u);
    let cy = cells_new(r.uv.y - 0.5 * ws.y, r.uv.y + 0.5 * ws.y, est.max_taps);
    let cx = cells_new(r.uv.x - 0.5 * ws.x, r.uv.x + 0.5 * ws.x, est.max_taps);
    var sum = Sum(0.0, 0.0);
    var count = Sum(0.0, 0.0);
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
            if caster(r, ci.i, cj.i) {
                let w = ci.w * cj.w;
                sum = sum_add(sum, w * depth_at(ci.i, cj.i));
                count = sum_add(count, w);
            }
        }
    }
    if count.s <= 0.0 {
        return 1.0;
    }
    let z_avg = sum.s / count.s;
    // 3. Penumbra width at the receiver, 4. filter width on the plane (texels).
    let wf = pcss_filter_width(l, zr, z_avg, view.n, to_texels, view.ortho != 0u);
    let disk = LIGHT_SHAPE != LIGHT_RECT;
    let rad = 0.5 * wf.x;
    let fy = cells_new(r.uv.y - 0.5 * wf.y, r.uv.y + 0.5 * wf.y, est.max_taps);
    let fx = cells_new(r.uv.x - 0.5 * wf.x, r.uv.x + 0.5 * wf.x, est.max_taps);
    var lit_sum = Sum(0.0, 0.0);
    var total = Sum(0.0, 0.0);
    for (var ky = 0u; ky < fy.count; ky++) {
        let cj = cell(fy, ky);
        if !cj.valid {
            continue;
        }
        for (var kx = 0u; kx < fx.count; kx++) {
            let ci = cell(fx, kx);
            if !ci.valid {
                continue;
            }
            // Disk filter with a one-texel soft edge (baselines::math::disk_edge).
            var edge = 1.0;
            if disk && wf.x > 1.0 {
                let c = vec2<f32>(f32(ci.i) + 0.5, f32(cj.i) + 0.5) - r.uv;
                edge = clamp(rad + 0.5 - sqrt(dot2(c, c)), 0.0, 1.0);
                if edge <= 0.0 {
                    continue;
                }
            }
            let w = ci.w * cj.w * edge;
            total = sum_add(total, w);
            if !caster(r, ci.i, cj.i) {
                lit_sum = sum_add(lit_sum, w);
            }
        }
    }
    if total.s <= 0.0 {
        return 1.0;
    }
    return lit_sum.s / total.s;
}
