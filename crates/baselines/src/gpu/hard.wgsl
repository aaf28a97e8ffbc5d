// Twin of crates/baselines/src/cpu/hard.rs: V = [z_p - eps <= D(floor u, floor v)], and 0 when the
// light centre is behind the receiver's tangent plane (or the receiver behind a one-sided light).

fn facing(p: vec3<f32>, n: vec3<f32>) -> f32 {
    let behind = est.light_one_sided != 0u && dot3(p - est.light_frame.origin, est.light_frame.ez) <= 0.0;
    var towards = est.light_frame.origin - p;
    if LIGHT_SHAPE == LIGHT_DIRECTIONAL {
        towards = -est.light_frame.ez;
    }
    if behind || dot3(n, towards) <= 0.0 {
        return 0.0;
    }
    return 1.0;
}

fn visibility(r: ReceiverSample) -> f32 {
    return lit(i32(floor(r.uv.x)), i32(floor(r.uv.y)), r);
}
