//! Unit tests of the kernel's WGSL: naga validation and the uniforms' layout.
use super::*;
use shadow_map_core::gpu::kernel::shader_source;
use test_support::wgsl::assert_shaders_valid;

#[test]
fn shader_validates_with_naga() {
    assert_shaders_valid([("backprojection", shader_source(&SHADER_PARTS))]);
}

/// `specialization` turns `ROW_BUFFER` on only where a row of blocks fits the WGSL's row array.
#[test]
fn the_row_buffer_bound_is_the_wgsl_one() {
    let line = test_support::wgsl::u32_constant(&shader_source(&SHADER_PARTS), "LINE");
    assert_eq!(line, Ok(ROW_BUFFER_LINE));
}

#[test]
fn uniforms_match_the_wgsl() {
    test_support::assert_wgsl_layout!(
        shader_source(&SHADER_PARTS),
        BpUniform {
            half,
            area,
            b0,
            b1,
            midpoint,
            gap_filling,
            max_nspp,
            sqrt_nspp,
            layers,
            midpoints,
            mssm_present,
            mssm_levels,
            mssm_size,
            first_nonzero,
            nbits,
            opacity,
            probe,
            _pad1,
            _pad2,
        }
    );
    assert_eq!(std::mem::size_of::<BpUniform>(), 80);
    assert_eq!(std::mem::size_of::<BitTable>(), 16 * BIT_TABLE_VEC4S);
}
