// Twin of crates/baselines/src/cpu/pcf.rs (Reeves, Salesin, Cook 1987):
// V = (1/N^2) sum_{|di|,|dj| <= half} [D(i + di, j + dj) is no caster], N = 2 half + 1.

fn facing(p: vec3<f32>, n: vec3<f32>) -> f32 {
    return front_fraction_world(est, p, n);
}

fn visibility(r: ReceiverSample) -> f32 {
    let i0 = i32(floor(r.uv.x));
    let j0 = i32(floor(r.uv.y));
    let half = est.kernel_half;
    var sum = 0.0;
    for (var dj = -half; dj <= half; dj++) {
        for (var di = -half; di <= half; di++) {
            sum += lit(i0 + di, j0 + dj, r);
        }
    }
    let side = f32(2 * half + 1);
    return sum / (side * side);
}
