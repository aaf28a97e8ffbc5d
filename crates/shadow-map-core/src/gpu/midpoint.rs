//! Midpoint layers on the GPU (`midpoint.wgsl`), the twin of [`crate::peeling::midpoints`]:
//! `M_m = min((L_m + L_{m+1}) / 2, L_m + max_bias)` per texel, one compute dispatch per layer,
//! each reading two peeled layers and writing a storage texture. The arithmetic is the CPU's, in
//! the same f32 order, so results are bit-identical for identical layers.
use super::{
    depth_map::GpuDepthMap,
    kernel::{buffer_init, Kernel, SpecializedKernel},
    GpuContext,
};
use crate::Result;
use bytemuck::{Pod, Zeroable};

/// WGSL source of the midpoint stage (it uses no shared struct, so nothing is prepended).
pub const MIDPOINT_WGSL: &str = include_str!("midpoint.wgsl");

/// Workgroup size (x and y) of the midpoint dispatch, passed as WGSL overrides `WG_X`, `WG_Y`.
pub const MIDPOINT_WORKGROUP: u32 = 8;

/// Uniform of one midpoint dispatch; mirrors `MidpointParams` in `midpoint.wgsl`.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable)]
pub struct MidpointParams {
    /// Map side.
    pub size: u32,
    /// Maximum bias (world units), the clamp of [`crate::peeling::midpoint`].
    pub max_bias: f32,
    /// Padding.
    pub _pad0: u32,
    /// Padding.
    pub _pad1: u32,
}

/// The midpoint compute pipeline, created once per context.
#[derive(Debug, Clone)]
pub struct GpuMidpoints {
    layout: wgpu::BindGroupLayout,
    pipeline: wgpu::ComputePipeline,
}

impl GpuMidpoints {
    /// Compiles the pipeline (label `midpoint`).
    pub fn new(ctx: &GpuContext) -> Result<Self> {
        let wg = MIDPOINT_WORKGROUP as f64;
        let Kernel { layout, pipeline } = SpecializedKernel::new(
            ctx,
            "midpoint",
            &[MIDPOINT_WGSL],
            "midpoint_layer",
            &[("WG_X", wg), ("WG_Y", wg)],
        )?
        .fixed(ctx)?;
        Ok(GpuMidpoints { layout, pipeline })
    }

    /// Records one dispatch per midpoint layer: `out[m]` from `layers[m]` and `layers[m + 1]`
    /// (`out.len() + 1 <= layers.len()`; all maps of one size).
    pub fn encode(
        &self,
        ctx: &GpuContext,
        encoder: &mut wgpu::CommandEncoder,
        layers: &[GpuDepthMap],
        out: &[GpuDepthMap],
        max_bias: f32,
    ) {
        if let Some(pass) = self.prepare(ctx, layers, out) {
            pass.record(ctx, encoder, max_bias);
        }
    }

    /// The bind groups and the parameter buffer of the dispatches [`encode`](Self::encode)
    /// records, created once (`None` for no layers): the engine path records them every frame.
    pub fn prepare(
        &self,
        ctx: &GpuContext,
        layers: &[GpuDepthMap],
        out: &[GpuDepthMap],
    ) -> Option<GpuMidpointPass> {
        let size = layers.first()?.size;
        let params = buffer_init(
            &ctx.device,
            "midpoint",
            bytemuck::bytes_of(&MidpointParams {
                size,
                max_bias: 0.0,
                _pad0: 0,
                _pad1: 0,
            }),
            wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
        );
        let groups = out
            .iter()
            .zip(layers.windows(2))
            .map(|(o, pair)| {
                ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
                    label: Some("midpoint"),
                    layout: &self.layout,
                    entries: &[
                        wgpu::BindGroupEntry {
                            binding: 0,
                            resource: params.as_entire_binding(),
                        },
                        wgpu::BindGroupEntry {
                            binding: 1,
                            resource: wgpu::BindingResource::TextureView(&pair[0].view),
                        },
                        wgpu::BindGroupEntry {
                            binding: 2,
                            resource: wgpu::BindingResource::TextureView(&pair[1].view),
                        },
                        wgpu::BindGroupEntry {
                            binding: 3,
                            resource: wgpu::BindingResource::TextureView(&o.view),
                        },
                    ],
                })
            })
            .collect();
        Some(GpuMidpointPass {
            pipeline: self.pipeline.clone(),
            params,
            size,
            groups,
        })
    }
}

/// The midpoint dispatches of fixed layers ([`GpuMidpoints::prepare`]), recorded as often as the
/// layers change, with the clamp of the frame.
#[derive(Debug)]
pub struct GpuMidpointPass {
    pipeline: wgpu::ComputePipeline,
    params: wgpu::Buffer,
    size: u32,
    groups: Vec<wgpu::BindGroup>,
}

impl GpuMidpointPass {
    /// Writes `max_bias` in the encoder's order ([`GpuContext::write_in`]) and records the
    /// pass.
    pub fn record(&self, ctx: &GpuContext, encoder: &mut wgpu::CommandEncoder, max_bias: f32) {
        ctx.write_in(
            encoder,
            &self.params,
            0,
            bytemuck::bytes_of(&self.params_of(max_bias)),
        );
        self.dispatch(encoder);
    }

    fn params_of(&self, max_bias: f32) -> MidpointParams {
        MidpointParams {
            size: self.size,
            max_bias,
            _pad0: 0,
            _pad1: 0,
        }
    }

    fn dispatch(&self, encoder: &mut wgpu::CommandEncoder) {
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("midpoint"),
            timestamp_writes: None,
        });
        pass.set_pipeline(&self.pipeline);
        let n = self.size.div_ceil(MIDPOINT_WORKGROUP);
        for g in &self.groups {
            pass.set_bind_group(0, g, &[]);
            pass.dispatch_workgroups(n, n, 1);
        }
    }
}
