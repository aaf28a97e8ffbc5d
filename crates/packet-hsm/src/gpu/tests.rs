//! The frame's shared structs against its WGSL, and the WGSL through naga.
use super::*;

#[test]
fn frame_structs_match_the_wgsl_layout() {
    let src = shadow_map_core::gpu::kernel::shader_source(FRAME_SHADER_PARTS);
    test_support::assert_wgsl_layout!(
        src,
        HsmFrameUniform {
            bias,
            slope_bias,
            midpoint,
            receiver_plane,
            _pad0,
            r,
            weight,
            flags,
        }
    );
}

#[test]
fn frame_wgsl_validates_with_naga() {
    test_support::wgsl::assert_shaders_valid([(
        "packet_hsm_frame",
        shadow_map_core::gpu::kernel::shader_source(FRAME_SHADER_PARTS),
    )]);
}
