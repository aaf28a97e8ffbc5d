//! wgpu twins of the four baselines (cargo feature `gpu`, on by default).
//!
//! | CPU twin | GPU twin | kernel |
//! |---|---|---|
//! | [`HardShadow`](crate::HardShadow) | [`GpuHardShadow`] | `map_estimator.wgsl` + `hard.wgsl` |
//! | [`PcfShadow`](crate::PcfShadow) | [`GpuPcfShadow`] | `map_estimator.wgsl` + `pcf.wgsl` |
//! | [`PcssShadow`](crate::PcssShadow) | [`GpuPcssShadow`] | `map_estimator.wgsl` + `pcss.wgsl` |
//! | [`MultiSample`](crate::MultiSample) | [`GpuMultiSample`] | `multi_sample.wgsl` |
//!
//! Each implements [`SoftShadowEstimator`](shadow_map_core::SoftShadowEstimator) with
//! `backend() == Backend::Gpu` and the CPU twin's name, description and parameter table, and
//! offers `estimate_with`, which takes the light-space data as input so a test can give both
//! twins identical data. The per-receiver stage is a compute kernel (one invocation per receiver,
//! [`WORKGROUP_SIZE`] per workgroup, receivers in chunks that fit the device's limits) reading
//! receivers as the core's `ReceiverGpu`, the shadow map as an R32Float texture, and writing V
//! to a storage buffer that is read back.
//!
//! The WGSL repeats the CPU math in f32 in the same operation order (glam's dot/cross order written
//! out). Differences that remain, each far below the twin tolerance of `tests/gpu_twins.rs`:
//! `front_fraction` clips and integrates in f64 on the CPU and in f32 here; PCSS sums its weights
//! with the same compensated f32 sum on both sides; the driver may fuse a multiply and an add
//! (WGSL does not forbid it), which moves a transform or a bias by an ulp and can flip a depth
//! comparison that is a tie to within f32 rounding.
//!
//! Light-space data come from [`MapBuilder`]: the view fitted on the CPU, the map rasterised on the
//! GPU by the core's `GpuShadowMapper` (tests feed CPU maps through `estimate_with` instead).
pub mod hard;
pub mod kernel;
pub mod map_estimator;
pub mod maps;
pub mod multi_sample;
pub mod pcf;
pub mod pcss;
pub mod shared;

pub use hard::GpuHardShadow;
pub use map_estimator::{GpuFilter, GpuMapEstimator};
pub use maps::{DepthTexture, GpuMaps, MapBuilder, MapDepth, MapOrigin};
pub use multi_sample::GpuMultiSample;
pub use pcf::GpuPcfShadow;
pub use pcss::GpuPcssShadow;
pub use shared::{EstimateUniform, WORKGROUP_SIZE};

use crate::{hard::Hard, pcf::Pcf, pcss::Pcss};

/// Every shader of the crate as `(name, parts in order)`; [`kernel::shader_source`] joins them.
/// A unit test validates each with naga, so a WGSL error fails CPU-only CI.
pub const SHADERS: &[(&str, &[&str])] = &[
    ("hard", &map_estimator::shader_parts::<Hard>(F32)),
    ("pcf", &map_estimator::shader_parts::<Pcf>(F32)),
    ("pcss", &map_estimator::shader_parts::<Pcss>(F32)),
    ("multi-sample", &multi_sample::shader_parts(F32)),
    ("hard unorm16", &map_estimator::shader_parts::<Hard>(U16)),
    ("pcf unorm16", &map_estimator::shader_parts::<Pcf>(U16)),
    ("pcss unorm16", &map_estimator::shader_parts::<Pcss>(U16)),
    ("multi-sample unorm16", &multi_sample::shader_parts(U16)),
];
const F32: shadow_map_core::DepthPrecision = shadow_map_core::DepthPrecision::F32;
const U16: shadow_map_core::DepthPrecision = shadow_map_core::DepthPrecision::Unorm16;

#[cfg(test)]
mod tests {
    use super::*;
    use std::mem::{align_of, offset_of, size_of};

    fn parse(name: &str, parts: &[&str]) -> naga::Module {
        let src = kernel::shader_source(parts);
        match naga::front::wgsl::parse_str(&src) {
            Ok(m) => m,
            Err(e) => panic!("{name}: {}", e.emit_to_string(&src)),
        }
    }

    #[test]
    fn every_shader_validates_with_naga() {
        for (name, parts) in SHADERS {
            let module = parse(name, parts);
            let mut v = naga::valid::Validator::new(
                naga::valid::ValidationFlags::all(),
                naga::valid::Capabilities::all(),
            );
            if let Err(e) = v.validate(&module) {
                panic!("{name}: {e:?}");
            }
        }
    }

    #[test]
    fn estimate_uniform_layout_matches_wgsl() {
        let module = parse("shared", &[shared::SHARED_WGSL]);
        let mut layouter = naga::proc::Layouter::default();
        layouter.update(module.to_ctx()).expect("layout");
        let (handle, ty) = module
            .types
            .iter()
            .find(|(_, t)| t.name.as_deref() == Some("EstimateUniform"))
            .expect("EstimateUniform in shared.wgsl");
        let naga::TypeInner::Struct { members, span } = &ty.inner else {
            panic!("EstimateUniform is not a struct");
        };
        assert_eq!(*span as usize, size_of::<EstimateUniform>());
        assert_eq!(
            (layouter[handle].alignment * 1u32) as usize,
            align_of::<EstimateUniform>()
        );
        let rust = [
            ("light_center", offset_of!(EstimateUniform, light_center)),
            ("light_shape", offset_of!(EstimateUniform, light_shape)),
            ("light_ex", offset_of!(EstimateUniform, light_ex)),
            ("light_size_x", offset_of!(EstimateUniform, light_size_x)),
            ("light_ey", offset_of!(EstimateUniform, light_ey)),
            ("light_size_y", offset_of!(EstimateUniform, light_size_y)),
            ("light_ez", offset_of!(EstimateUniform, light_ez)),
            (
                "light_one_sided",
                offset_of!(EstimateUniform, light_one_sided),
            ),
            (
                "light_half_extent",
                offset_of!(EstimateUniform, light_half_extent),
            ),
            ("bias", offset_of!(EstimateUniform, bias)),
            ("slope_bias", offset_of!(EstimateUniform, slope_bias)),
            ("kernel_half", offset_of!(EstimateUniform, kernel_half)),
            ("max_taps", offset_of!(EstimateUniform, max_taps)),
            ("inv_samples", offset_of!(EstimateUniform, inv_samples)),
            ("depth_step", offset_of!(EstimateUniform, depth_step)),
            ("probe", offset_of!(EstimateUniform, probe)),
            ("_pad0", offset_of!(EstimateUniform, _pad)),
            ("_pad1", offset_of!(EstimateUniform, _pad) + 4),
            ("_pad2", offset_of!(EstimateUniform, _pad) + 8),
        ];
        assert_eq!(members.len(), rust.len());
        for (m, (name, off)) in members.iter().zip(rust) {
            assert_eq!(m.name.as_deref(), Some(name));
            assert_eq!(m.offset as usize, off, "offset of {name}");
        }
    }
}
