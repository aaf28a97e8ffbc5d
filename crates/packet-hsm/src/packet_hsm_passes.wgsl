@compute @workgroup_size(WG)
fn prepare(@builtin(global_invocation_id) gid: vec3<u32>) {
    let idx = gid.x;
    if idx >= arrayLength(&prep) {
        return;
    }
    var p: PrepGpu;
    p.state = STATE_DONE;
    p.centre = 0u;
    p.cr = vec4<i32>(0);
    p.q = vec2<f32>(0.0);
    let rec = recs[idx];
    if !(rec.zp > 0.0) {
        v_out[idx] = vec2<f32>(0.0, 0.0);
        prep[idx] = p;
        return;
    }
    var valid = false;
    let cr = kernel_cells(rec, &valid);
    let mm = dual_query(cr);
    // cpu.rs trivial: fully lit, fully occluded.
    var lit = !(mm.x < rec.t);
    var umbra = !lit && mm.y < rec.t;
    if valid && !lit && u.receiver_plane != 0u {
        let th = widen(threshold_range(rec, cr));
        lit = true_min(mm.x, cr) >= th.y;
        umbra = !lit && mm.y < rec.t && mm.y < th.x;
    }
    if !valid || lit || umbra {
        prep[idx] = p;
        if loop_limit_hit() {
            v_out[idx] = vec2<f32>(0.0, TRUNCATED);
        } else if !valid || lit {
            v_out[idx] = vec2<f32>(1.0, 0.0);
        } else {
            v_out[idx] = vec2<f32>(0.0, 0.0);
        }
        return;
    }
    // Centre status with the nudge of contour::Receiver::new.
    var q = rec.uv;
    var centre = 2u;
    for (var it = 0; it < 8; it++) {
        centre = centre_status(q, rec);
        if centre != 2u {
            break;
        }
        q += vec2<f32>(1.0 / 4096.0, 1.0 / 8192.0);
    }
    if centre == 2u {
        let ci = i32(floor(q.x));
        let cj = i32(floor(q.y));
        centre = select(0u, 1u, occludes(rec, ci, cj, sample(ci, cj)));
    }
    p.cr = cr;
    p.q = q;
    p.state = STATE_PENUMBRA;
    p.centre = centre;
    if loop_limit_hit() {
        p.state = STATE_DONE;
        prep[idx] = p;
        v_out[idx] = vec2<f32>(0.0, TRUNCATED);
        return;
    }
    prep[idx] = p;
    v_out[idx] = vec2<f32>(0.0, 0.0);
}

// contour::visibility_from_area (A_L = 4 hx hy, or pi R^2 for a disk and a sphere's silhouette:
// hx = R).
fn finish(sum: f32, centre: u32) -> f32 {
    var al = 4.0 * u.hx * u.hy;
    if u.shape != SHAPE_RECT {
        al = PI * u.hx * u.hx;
    }
    var a = sum;
    if centre == 1u {
        a += al;
    }
    var v = 1.0 - clamp(a / al, 0.0, 1.0);
    if !(v >= 0.0 && v <= 1.0) {
        v = select(1.0, 0.0, centre == 1u);
    }
    return v;
}

// Per-pixel GBP07 for every penumbra receiver `prepare` left.
@compute @workgroup_size(WG)
fn pixels(@builtin(global_invocation_id) gid: vec3<u32>) {
    let idx = gid.x;
    if idx >= arrayLength(&prep) {
        return;
    }
    let p = prep[idx];
    if p.state != STATE_PENUMBRA {
        return;
    }
    let rec = recs[idx];
    let cr = p.cr;
    let q = p.q;
    var sum = 0.0;
    var visited = 0u;
    var complete = true;
    if u.hierarchy == 0u {
        let wc = max(cr.z - cr.x, 1);
        let total = max(cr.z - cr.x, 0) * max(cr.w - cr.y, 0);
        var kk = 0;
        loop {
            if kk >= total {
                break;
            }
            let i = cr.x + kk % wc;
            let j = cr.y + kk / wc;
            visited += 1u;
            sum += cell_area(i, j, rec, q, rec.zp);
            kk += 1;
        }
        complete = kk >= total;
    } else {
        var stack: array<vec3<i32>, STACK>;
        var sp = push_roots(&stack, cr);
        let x1 = cr.z + 1;
        let y1 = cr.w + 1;
        loop {
            if sp == 0u {
                break;
            }
            sp -= 1u;
            let nd = stack[sp];
            visited += 1u;
            let l = u32(nd.z);
            let mm = node(nd);
            // Fig. 6 cases 4 and 5: no contour below this node.
            if u.receiver_plane == 0u {
                if mm.y < rec.t || !(mm.x < rec.t) {
                    continue;
                }
            } else {
                let span = i32(1u << l);
                let ns = vec4<i32>(nd.x - 1, nd.y - 1, nd.x - 1 + span, nd.y - 1 + span);
                if plane_prunable(mm, rec.t, rec.t, widen(threshold_range(rec, ns)), ns) {
                    continue;
                }
            }
            if l == 0u {
                sum += cell_area(nd.x - 1, nd.y - 1, rec, q, rec.zp);
                continue;
            }
            sp = push_children(&stack, sp, nd, x1, y1);
        }
        complete = sp == 0u;
    }
    if !complete || stack_overflow || loop_limit_hit() {
        v_out[idx] = vec2<f32>(0.0, TRUNCATED);
        return;
    }
    v_out[idx] = vec2<f32>(finish(sum, p.centre), v_out[idx].y + f32(visited));
}

// Min/max of a padded dual-MSSM node (x, y, level); EMPTY outside.
fn node(nd: vec3<i32>) -> vec2<f32> {
    if u32(nd.x) < u.padded && u32(nd.y) < u.padded {
        let k = u32(nd.z) * u.padded * u.padded + u32(nd.y) * u.padded + u32(nd.x);
        return vec2<f32>(dual_min[k], dual_max[k]);
    }
    return vec2<f32>(pos_inf(), -pos_inf());
}

// The start nodes of contour::extract: the lowest level covering the kernel from its top-left
// corner (tiled with top-level nodes above the top level). Returns the stack size.
fn push_roots(stack: ptr<function, array<vec3<i32>, STACK>>, cr: vec4<i32>) -> u32 {
    var sp = 0u;
    let top = u.dual_levels - 1u;
    let span = u32(max(cr.z - cr.x, cr.w - cr.y));
    var want = 0u;
    if span > 1u {
        want = 32u - countLeadingZeros(span - 1u);
    }
    let l0 = min(want, top);
    let step = i32(1u << l0);
    for (var y = cr.y + 1; y < cr.w + 1; y += step) {
        for (var x = cr.x + 1; x < cr.z + 1; x += step) {
            if sp < STACK {
                (*stack)[sp] = vec3<i32>(x, y, i32(l0));
                sp += 1u;
            } else {
                stack_overflow = true;
            }
        }
    }
    return sp;
}

fn push_children(stack: ptr<function, array<vec3<i32>, STACK>>, sp0: u32, nd: vec3<i32>, x1: i32, y1: i32) -> u32 {
    var sp = sp0;
    let h = i32(1u << (u32(nd.z) - 1u));
    let kids = array<vec2<i32>, 4>(vec2<i32>(h, h), vec2<i32>(0, h), vec2<i32>(h, 0), vec2<i32>(0, 0));
    for (var c = 0u; c < 4u; c++) {
        let cx = nd.x + kids[c].x;
        let cy = nd.y + kids[c].y;
        if cx < x1 && cy < y1 {
            if sp < STACK {
                (*stack)[sp] = vec3<i32>(cx, cy, nd.z - 1);
                sp += 1u;
            } else {
                stack_overflow = true;
            }
        }
    }
    return sp;
}
