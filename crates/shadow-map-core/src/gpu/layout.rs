//! Rendered light-space data laid out for an estimate kernel: the depth layers (then the
//! midpoint layers, then any opacity planes) in one `R32Float` texture array, the anchored MSSM's levels in another (a
//! 1 x 1 plane holding +inf when there is none), the layout `backprojection.wgsl` and
//! `accumulation.wgsl` read. [`GpuLayout::prepare`] allocates the arrays and the copies once;
//! [`KernelMaps::record`] records the copies (textures to texture, MSSM planes by
//! `plane_to_layer.wgsl`) as often as the maps are rendered again: once for a `build`, every
//! frame on the engine path.
use super::{
    depth_map::GpuDepthMap,
    frame::FrameInputs,
    kernel::{plane_array, upload_planes, Kernel, PlaneArray, SpecializedKernel},
    mssm::GpuMssm,
    raster::{GpuLayersFrame, GpuShadowMapper, LayersSlot},
    GpuContext,
};
use crate::gpu::kernel::BufferInitExt;
use crate::{light_view::LightView, LightSpaceRequest};
use crate::{Error, Result};
use bytemuck::{Pod, Zeroable};

/// The MSSM-level copy into a texture array layer.
pub const PLANE_TO_LAYER_WGSL: &str = include_str!("plane_to_layer.wgsl");

/// Uniform of one [`PLANE_TO_LAYER_WGSL`] dispatch (mirrors `PlaneCopy`).
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable)]
pub struct PlaneCopy {
    /// Side of the plane.
    pub size: u32,
    /// Destination array layer.
    pub layer: u32,
    /// Padding.
    pub _pad0: u32,
    /// Padding.
    pub _pad1: u32,
}

/// The plane-copy pipeline, compiled once per context.
#[derive(Debug)]
pub struct GpuLayout {
    copy: Kernel,
}

/// The kernel's texture arrays and the copies that fill them from rendered maps.
#[derive(Debug)]
pub struct KernelMaps {
    /// Depth layers, then midpoint layers, then opacity planes (at least one plane).
    pub maps: PlaneArray,
    /// The MSSM's levels, or one 1 x 1 plane holding +inf.
    pub mssm: PlaneArray,
    /// Depth layers in `maps`.
    pub layers: u32,
    /// Midpoint layers in `maps`, after the depth layers.
    pub midpoints: u32,
    /// Opacity planes in `maps`, after the midpoint layers (one per depth layer, or none).
    pub opacity: u32,
    /// MSSM levels in `mssm` (`None`: no MSSM).
    pub mssm_levels: Option<u32>,
    r: u32,
    planes: Vec<wgpu::Texture>,
    mssm_copy: MssmCopy,
}

/// How the MSSM's level planes reach [`KernelMaps::mssm`], chosen at `prepare`.
#[derive(Debug)]
enum MssmCopy {
    /// No MSSM.
    None,
    /// Rows 256-byte aligned (sides that are multiples of 64): `copy_buffer_to_texture` of each
    /// level's plane, a memory copy on every device.
    Transfer(Vec<wgpu::Buffer>),
    /// Other sides: `plane_to_layer.wgsl`'s compute copy, one bind group a level.
    Compute(wgpu::ComputePipeline, Vec<wgpu::BindGroup>),
}

impl GpuLayout {
    /// Compiles the plane copy (label `layout`).
    pub fn new(ctx: &GpuContext) -> Result<Self> {
        let copy = SpecializedKernel::new(
            ctx,
            "layout plane copy",
            &[PLANE_TO_LAYER_WGSL],
            "copy_plane",
            &[],
        )?
        .fixed(ctx)?;
        Ok(GpuLayout { copy })
    }

    /// Allocates the texture arrays (labels `{label} layers`, `{label} mssm`) for `layers`,
    /// `midpoints` and `opacity` planes of side `r` and the MSSM `mssm`, and prepares the copies
    /// into them. Errors: device limits ([`Error::Limit`]), e.g. an MSSM plane beyond one storage
    /// binding.
    #[allow(clippy::too_many_arguments)]
    pub fn prepare(
        &self,
        ctx: &GpuContext,
        label: &str,
        r: u32,
        layers: &[GpuDepthMap],
        midpoints: &[GpuDepthMap],
        opacity: &[GpuDepthMap],
        mssm: Option<&GpuMssm>,
    ) -> Result<KernelMaps> {
        let planes: Vec<wgpu::Texture> = layers
            .iter()
            .chain(midpoints)
            .chain(opacity)
            .map(|d| d.texture.clone())
            .collect();
        let maps = plane_array(
            ctx,
            &format!("{label} layers"),
            r,
            planes.len().max(1) as u32,
        )?;
        let levels: &[_] = mssm.map_or(&[], |m| &m.levels[..]);
        let mssm_label = format!("{label} mssm");
        let mssm_array = match mssm {
            Some(m) if !levels.is_empty() => {
                let max = ctx.limits().max_storage_buffer_binding_size;
                let bytes = m.size as u64 * m.size as u64 * 4;
                if bytes > max {
                    return Err(Error::Limit {
                        what: "MSSM plane bytes (max_storage_buffer_binding_size)",
                        requested: bytes,
                        max,
                    });
                }
                plane_array(ctx, &mssm_label, m.size, levels.len() as u32)?
            }
            _ => upload_planes(ctx, &mssm_label, 1, &[&[f32::INFINITY]])?,
        };
        let aligned = (4 * mssm_array.size).is_multiple_of(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT);
        let mssm_copy = if levels.is_empty() {
            MssmCopy::None
        } else if aligned {
            MssmCopy::Transfer(levels.iter().map(|l| l.min.clone()).collect())
        } else {
            let groups = ctx.scoped("layout", || {
                levels
                    .iter()
                    .enumerate()
                    .map(|(l, level)| {
                        let pc = PlaneCopy {
                            size: mssm_array.size,
                            layer: l as u32,
                            _pad0: 0,
                            _pad1: 0,
                        };
                        let u = ctx
                            .device
                            .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                                label: Some("layout plane copy"),
                                contents: bytemuck::bytes_of(&pc),
                                usage: wgpu::BufferUsages::UNIFORM,
                            });
                        self.copy.bind_group(
                            ctx,
                            "layout plane copy",
                            &[
                                u.as_entire_binding(),
                                level.min.as_entire_binding(),
                                wgpu::BindingResource::TextureView(&mssm_array.view),
                            ],
                        )
                    })
                    .collect()
            })?;
            MssmCopy::Compute(self.copy.pipeline.clone(), groups)
        };
        Ok(KernelMaps {
            maps,
            mssm: mssm_array,
            layers: layers.len() as u32,
            midpoints: midpoints.len() as u32,
            opacity: opacity.len() as u32,
            mssm_levels: mssm.map(|m| m.levels()),
            r,
            planes,
            mssm_copy,
        })
    }
}

/// One view's peeled layers (with the midpoints and opacity planes its request asks for) and
/// MSSM, rendered every frame and laid out in the texture arrays a kernel samples: the maps of
/// backprojection's and accumulation's frames.
#[derive(Debug)]
pub struct ViewMaps {
    /// The rendered maps.
    pub layers: GpuLayersFrame,
    /// Their texture arrays and the copies that fill them.
    pub km: KernelMaps,
}

impl ViewMaps {
    /// Allocates the maps `req` asks for (resolution, layers, midpoints, opacity planes, MSSM)
    /// and their texture arrays (labels `{label} layers`, `{label} mssm`). Errors: device limits
    /// ([`Error::Limit`]).
    pub fn prepare(ctx: &GpuContext, label: &str, req: &LightSpaceRequest) -> Result<Self> {
        let layers = GpuShadowMapper::new(ctx)?.layers_frame(ctx, req.resolution, req)?;
        let km = GpuLayout::new(ctx)?.prepare(
            ctx,
            label,
            req.resolution,
            layers.layers(),
            layers.midpoints(),
            layers.opacity(),
            layers.min_max().mssm.as_ref(),
        )?;
        Ok(ViewMaps { layers, km })
    }

    /// Records the maps of `view` over the frame's casters (midpoints under the clamp
    /// `max_bias`, the first `mssm_planes` MSSM levels), marked `layers`, then their copies into
    /// the arrays, marked `layout`. Returns whether the opacity planes were copied (prepared,
    /// and the casters semi-transparent): what the kernel is told to read.
    pub fn encode(
        &self,
        ctx: &GpuContext,
        enc: &mut wgpu::CommandEncoder,
        inputs: &FrameInputs<'_>,
        view: &LightView,
        max_bias: f32,
        mssm_planes: u32,
    ) -> Result<bool> {
        let slot = LayersSlot {
            view,
            max_bias,
            min_opacity: 0.0,
            slot: 0,
            mssm_levels: Some(mssm_planes),
            mssm_max: false,
            timestamps: inputs.timestamps,
        };
        self.layers.encode_slot(ctx, enc, inputs.casters, &slot)?;
        let semi = self.layers.writes_opacity(inputs.casters);
        self.km.record(enc, semi, mssm_planes);
        inputs.mark(enc, "layout");
        Ok(semi)
    }
}

impl KernelMaps {
    /// Records the copies into `enc`: every plane, the opacity planes only when `opacity`
    /// (semi-transparent casters; an opaque frame's kernel does not read them), and the first
    /// `mssm_planes` MSSM levels (those the frame built: each copy is a pass over the level, and
    /// the kernel is told how many levels it may read).
    pub fn record(&self, enc: &mut wgpu::CommandEncoder, opacity: bool, mssm_planes: u32) {
        let skip = if opacity { 0 } else { self.opacity as usize };
        for (i, tex) in self.planes[..self.planes.len() - skip].iter().enumerate() {
            enc.copy_texture_to_texture(
                tex.as_image_copy(),
                wgpu::TexelCopyTextureInfo {
                    texture: &self.maps.texture,
                    mip_level: 0,
                    origin: wgpu::Origin3d {
                        x: 0,
                        y: 0,
                        z: i as u32,
                    },
                    aspect: wgpu::TextureAspect::All,
                },
                wgpu::Extent3d {
                    width: self.r,
                    height: self.r,
                    depth_or_array_layers: 1,
                },
            );
        }
        let take = mssm_planes as usize;
        match &self.mssm_copy {
            MssmCopy::None => {}
            MssmCopy::Transfer(planes) => {
                let size = self.mssm.size;
                for (l, plane) in planes.iter().take(take).enumerate() {
                    enc.copy_buffer_to_texture(
                        wgpu::TexelCopyBufferInfo {
                            buffer: plane,
                            layout: wgpu::TexelCopyBufferLayout {
                                offset: 0,
                                bytes_per_row: Some(4 * size),
                                rows_per_image: Some(size),
                            },
                        },
                        wgpu::TexelCopyTextureInfo {
                            texture: &self.mssm.texture,
                            mip_level: 0,
                            origin: wgpu::Origin3d {
                                x: 0,
                                y: 0,
                                z: l as u32,
                            },
                            aspect: wgpu::TextureAspect::All,
                        },
                        wgpu::Extent3d {
                            width: size,
                            height: size,
                            depth_or_array_layers: 1,
                        },
                    );
                }
            }
            MssmCopy::Compute(pipeline, groups) => {
                let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
                    label: Some("layout mssm copy"),
                    timestamp_writes: None,
                });
                pass.set_pipeline(pipeline);
                let g = self.mssm.size.div_ceil(16);
                for group in groups.iter().take(take) {
                    pass.set_bind_group(0, group, &[]);
                    pass.dispatch_workgroups(g, g, 1);
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn plane_copy_matches_the_wgsl() {
        test_support::assert_wgsl_layout!(
            PLANE_TO_LAYER_WGSL,
            PlaneCopy {
                size,
                layer,
                _pad0,
                _pad1,
            }
        );
        assert_eq!(std::mem::size_of::<PlaneCopy>(), 16);
    }
}
