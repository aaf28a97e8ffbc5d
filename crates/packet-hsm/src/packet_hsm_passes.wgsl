@compute @workgroup_size(WG)
fn prepare(@builtin(global_invocation_id) gid: vec3<u32>) {
    let idx = gid.x;
    if idx >= arrayLength(&prep) {
        return;
    }
    open_requeue(idx);
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
    if valid && !lit && HSM_PLANE {
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
    p.walk = vec4<u32>(0u, 0u, walk_top(cr), 0u);
    prep[idx] = p;
    v_out[idx] = vec2<f32>(0.0, 0.0);
    // Queued for `pixels` (prepare fills `requeue`, the first round's queue), which runs over
    // the queue alone: the penumbra receivers are a few of all, and lanes of a workgroup that
    // have no penumbra to walk would wait on those that have.
    requeue_walk(idx);
}

// Invocation 0 sets the y and z workgroup counts of the indirect dispatch over `requeue`.
fn open_requeue(i: u32) {
    if i == 0u {
        atomicStore(&requeue[QUEUE_ARGS + 1u], 1u);
        atomicStore(&requeue[QUEUE_ARGS + 2u], 1u);
    }
}

// Appends receiver idx to the queue of the next round of `pixels`, counting a workgroup of its
// indirect dispatch per WG receivers.
fn requeue_walk(idx: u32) {
    let slot = atomicAdd(&requeue[QUEUE_COUNT], 1u);
    atomicStore(&requeue[QUEUE_LIST + slot], idx);
    if slot % WG == 0u {
        atomicAdd(&requeue[QUEUE_ARGS], 1u);
    }
}

// The level of the walk's roots for kernel cells cr: the lowest covering the kernel from its
// top-left corner, or the dual-grid MSSM's top.
fn walk_top(cr: vec4<i32>) -> u32 {
    let span = u32(max(cr.z - cr.x, cr.w - cr.y));
    var want = 0u;
    if span > 1u {
        want = 32u - countLeadingZeros(span - 1u);
    }
    return min(want, u.dual_levels - 1u);
}

// contour::visibility_from_area (A_L = 4 hx hy, or pi R^2 for a disk and a sphere's silhouette:
// hx = R).
fn finish(sum: f32, centre: u32) -> f32 {
    var al = 4.0 * u.hx * u.hy;
    if HSM_SHAPE != SHAPE_RECT {
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

// Per-pixel GBP07 for the penumbra receivers of `queue` (dispatched indirectly, one invocation
// per queued receiver), each walking at most `u.walk_budget` steps a round: a receiver whose
// walk is left goes on the next round's queue (`requeue`) with its place (prep's walk) and its
// sum so far (v_out.x; v_out.y = TRUNCATED until it is done, so a receiver the last round
// leaves is counted as cut, never returned as V). No invocation comes near a device's loop
// budget, and the long walks run in later rounds with full workgroups.
@compute @workgroup_size(WG)
fn pixels(@builtin(global_invocation_id) gid: vec3<u32>) {
    open_requeue(gid.x);
    if gid.x >= atomicLoad(&queue[QUEUE_COUNT]) {
        return;
    }
    let idx = atomicLoad(&queue[QUEUE_LIST + gid.x]);
    let p = prep[idx];
    let rec = recs[idx];
    let cr = p.cr;
    let q = p.q;
    var sum = v_out[idx].x;
    var visited = p.walk.w;
    var steps = 0u;
    // Flat: the next cell (walk.x); hierarchy: the root (walk.x), the Morton code c (walk.y)
    // and the level l (walk.z) of the next node.
    var w = p.walk;
    var live = true;
    if !HSM_HIERARCHY {
        let wc = max(cr.z - cr.x, 1);
        let total = u32(max(cr.z - cr.x, 0) * max(cr.w - cr.y, 0));
        var kk = w.x;
        loop {
            if kk >= total || steps >= u.walk_budget {
                break;
            }
            steps += 1u;
            let i = cr.x + i32(kk) % wc;
            let j = cr.y + i32(kk) / wc;
            visited += 1u;
            sum += cell_area(i, j, rec, q, rec.zp);
            kk += 1u;
        }
        live = kk < total;
        w.x = kk;
    } else {
        // Yang's Algorithm 3 without a stack: the nodes in the CPU's order (roots row-major,
        // children row-major), each root's subtree walked along its Morton code c at level l:
        // after a node that is pruned or a cell, c steps past its subtree and the next node is
        // at the highest level c is aligned to. Nodes starting outside the kernel are skipped.
        let l0 = walk_top(cr);
        let step = i32(1u << l0);
        let x1 = cr.z + 1;
        let y1 = cr.w + 1;
        let nx = max((cr.z - cr.x + step - 1) / step, 0);
        let roots = u32(nx * max((cr.w - cr.y + step - 1) / step, 0));
        let end = 1u << (2u * l0);
        var root = w.x;
        var c = w.y;
        var l = w.z;
        live = root < roots;
        loop {
            if !live || steps >= u.walk_budget {
                break;
            }
            steps += 1u;
            let nd = vec3<i32>(
                cr.x + 1 + (i32(root) % nx) * step + i32(even_bits(c)),
                cr.y + 1 + (i32(root) / nx) * step + i32(even_bits(c >> 1u)),
                i32(l),
            );
            var down = false;
            if nd.x < x1 && nd.y < y1 {
                visited += 1u;
                let mm = node(nd);
                // Fig. 6 cases 4 and 5: no contour below this node.
                var pruned = mm.y < rec.t || !(mm.x < rec.t);
                if HSM_PLANE {
                    let span = i32(1u << l);
                    let ns = vec4<i32>(nd.x - 1, nd.y - 1, nd.x - 1 + span, nd.y - 1 + span);
                    let lo = node_true_min(mm.x, ns, l);
                    pruned = plane_prunable(mm, rec.t, rec.t, widen(threshold_range(rec, ns)), lo);
                }
                if !pruned {
                    if l == 0u {
                        sum += cell_area(nd.x - 1, nd.y - 1, rec, q, rec.zp);
                    } else {
                        down = true;
                    }
                }
            }
            if down {
                l -= 1u;
            } else {
                c += 1u << (2u * l);
                if c >= end {
                    c = 0u;
                    l = l0;
                    root += 1u;
                    live = root < roots;
                } else {
                    l = min(countTrailingZeros(c) / 2u, l0);
                }
            }
        }
        w = vec4<u32>(root, c, l, 0u);
    }
    if loop_limit_hit() {
        // The device's own budget ran out mid-round (never with walk_budget well below it):
        // the place saved would be wrong, so the receiver is left cut.
        v_out[idx] = vec2<f32>(0.0, TRUNCATED);
        return;
    }
    if live {
        w.w = visited;
        prep[idx].walk = w;
        v_out[idx] = vec2<f32>(sum, TRUNCATED);
        requeue_walk(idx);
        return;
    }
    v_out[idx] = vec2<f32>(finish(sum, p.centre), f32(visited));
}

// Min/max of a padded dual-MSSM node (x, y, level); EMPTY outside.
fn node(nd: vec3<i32>) -> vec2<f32> {
    if u32(nd.x) < u.padded && u32(nd.y) < u.padded {
        let k = u32(nd.z) * u.padded * u.padded + u32(nd.y) * u.padded + u32(nd.x);
        return vec2<f32>(dual_min[k], dual_max[k]);
    }
    return vec2<f32>(pos_inf(), -pos_inf());
}

// The even bits of v packed (a Morton code's x; of v >> 1, its y).
fn even_bits(v: u32) -> u32 {
    var x = v & 0x55555555u;
    x = (x | (x >> 1u)) & 0x33333333u;
    x = (x | (x >> 2u)) & 0x0f0f0f0fu;
    x = (x | (x >> 4u)) & 0x00ff00ffu;
    return (x | (x >> 8u)) & 0x0000ffffu;
}
