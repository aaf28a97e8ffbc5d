// One receiver as packet-hsm's kernel reads it, written by the frame's set-up pass (packet_hsm_frame.wgsl
// `frame_setup`). Mirrors kernel.rs RecIn: texel coordinates, depth z_p and classification
// threshold t_p; zp <= 0 marks a receiver the set-up already settled (not evaluated here).
// g0, gu, gv, c: the receiver plane (shadow_map_core::ReceiverPlane; its zp is z_p, hs 0).
struct RecIn {
    uv: vec2<f32>,
    zp: f32,
    t: f32,
    g0: f32,
    gu: f32,
    gv: f32,
    c: f32,
    // A sphere light's silhouette seen from the receiver (shadow_map_core::silhouette::Silhouette,
    // set up by packet_hsm_frame.wgsl): (a, |p|), (e1, R), (e2, 0), clip rectangle of z = 0 (x0, y0, x1, y1).
    sil_a: vec4<f32>,
    sil_e1: vec4<f32>,
    sil_e2: vec4<f32>,
    sil_clip: vec4<f32>,
}
