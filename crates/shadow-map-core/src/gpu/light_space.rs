//! Light-space data on the GPU, the twin of [`LightSpace`]: the view, peeled layers, midpoint
//! layers and the MSSM family of layer 0, as rendered by
//! [`GpuShadowMapper::render_layers`](super::GpuShadowMapper::render_layers).
use super::{
    depth_map::{read_depth_map, GpuDepthMap},
    mssm::{GpuDualMssm, GpuMinMaxPyramid, GpuMssm},
    GpuContext,
};
use crate::{
    light_view::{FitReport, LightView},
    mssm::{DualMssm, MinMaxPyramid, Mssm},
    LightSpace, Result,
};

/// Light-space data for one view, on the GPU.
#[derive(Debug, Clone)]
pub struct GpuLightSpace {
    /// The view the maps were rendered with.
    pub view: LightView,
    /// Fit statistics (default unless the view was fitted by
    /// [`GpuShadowMapper::render`](super::GpuShadowMapper::render)).
    pub fit: FitReport,
    /// The view as a uniform buffer of [`super::shared::LightViewUniform`] (label `raster.view`,
    /// usages `UNIFORM | COPY_DST | COPY_SRC`), ready to bind in later stages.
    pub view_uniform: wgpu::Buffer,
    /// Peeled layers, nearest first (`layers[0]` is the ordinary shadow map).
    pub layers: Vec<GpuDepthMap>,
    /// Per layer, each texel's opacity, when requested and the casters were semi-transparent
    /// (see [`GpuLayersFrame::opacity`](super::GpuLayersFrame::opacity)); empty otherwise.
    pub opacity: Vec<GpuDepthMap>,
    /// Midpoint layers, when requested.
    pub midpoints: Vec<GpuDepthMap>,
    /// Anchored MSSM of layer 0, when requested.
    pub mssm: Option<GpuMssm>,
    /// Dual-grid MSSM of layer 0, when requested.
    pub dual_mssm: Option<GpuDualMssm>,
    /// Min/max pyramid of layer 0, when requested.
    pub pyramid: Option<GpuMinMaxPyramid>,
}

/// Bytes of the `[layers, midpoints, opacity]` maps and an MSSM family `(mssm, dual-grid MSSM,
/// pyramid)`, counted as [`LightSpace::bytes`] counts them: [`GpuLightSpace::bytes`] and the
/// engine path's layers.
pub(crate) fn maps_bytes(
    maps: [&[GpuDepthMap]; 3],
    (mssm, dual, pyramid): (
        Option<&GpuMssm>,
        Option<&GpuDualMssm>,
        Option<&GpuMinMaxPyramid>,
    ),
) -> usize {
    maps.iter()
        .flat_map(|m| m.iter())
        .map(GpuDepthMap::bytes)
        .sum::<usize>()
        + mssm.map_or(0, GpuMssm::bytes)
        + dual.map_or(0, GpuDualMssm::bytes)
        + pyramid.map_or(0, GpuMinMaxPyramid::bytes)
}

impl GpuLightSpace {
    /// Bytes held by the maps, counted as [`LightSpace::bytes`] counts them (each structure's
    /// depth-map level counted in it, although on the GPU the MSSM and the pyramid share one
    /// buffer for it).
    pub fn bytes(&self) -> usize {
        let family = (
            self.mssm.as_ref(),
            self.dual_mssm.as_ref(),
            self.pyramid.as_ref(),
        );
        maps_bytes([&self.layers, &self.midpoints, &self.opacity], family)
    }

    /// Reads everything back into a [`LightSpace`]: layers, opacity planes and midpoints bit for
    /// bit. The MSSM
    /// family is rebuilt on the CPU from the read-back layer 0 with the same number of levels,
    /// because [`crate::mssm`] has no constructor from planes; the GPU planes are bit-identical
    /// to that rebuild (`tests/shadow_map_core/gpu_maps/transfers.rs` checks it with `read_levels`).
    pub fn to_cpu(&self, ctx: &GpuContext) -> Result<LightSpace> {
        let layers = self
            .layers
            .iter()
            .map(|l| read_depth_map(ctx, l))
            .collect::<Result<Vec<_>>>()?;
        let midpoints = self
            .midpoints
            .iter()
            .map(|l| read_depth_map(ctx, l))
            .collect::<Result<Vec<_>>>()?;
        let (mssm, dual_mssm, pyramid) = match layers.first() {
            Some(l0) => (
                self.mssm
                    .as_ref()
                    .map(|m| Mssm::build(&l0.depth, l0.size, m.levels().saturating_sub(1))),
                self.dual_mssm
                    .as_ref()
                    .map(|m| DualMssm::build(&l0.depth, l0.size, m.levels().saturating_sub(1))),
                self.pyramid
                    .as_ref()
                    .map(|_| MinMaxPyramid::build(&l0.depth, l0.size)),
            ),
            None => (None, None, None),
        };
        Ok(LightSpace {
            view: self.view,
            fit: self.fit,
            layers,
            opacity: self
                .opacity
                .iter()
                .map(|l| read_depth_map(ctx, l).map(|m| m.depth))
                .collect::<Result<Vec<_>>>()?,
            midpoints,
            mssm,
            dual_mssm,
            pyramid,
        })
    }
}
