//! The engine path's raster resources, allocated once by [`GpuShadowMapper`](super::GpuShadowMapper) and recorded every
//! frame into the caller's command encoder: one map ([`GpuMapFrame`]) or the peeled layers,
//! midpoints and MSSM family ([`GpuLayersFrame`], several views in turn through [`LayersSlot`]).
use super::{begin_depth_tested_pass, begin_layer_pass, GpuScene, LayerPipelines, RasterParams};
use crate::gpu::{
    depth_map::GpuDepthMap,
    frame::compute_pass,
    kernel::{Kernel, SpecializedKernel},
    light_space::GpuLightSpace,
    shared::{LightViewUniform, SHARED_WGSL},
    GpuContext,
};
use crate::{
    light_view::{FitReport, LightView},
    Error, Result,
};

/// A shadow map rendered every frame into the caller's command encoder (the engine path,
/// [`GpuShadowMapper::map_frame`](super::GpuShadowMapper::map_frame)): [`encode`](Self::encode) writes a view into one of its view
/// slots in the encoder's order ([`GpuContext::write_in`]) and records one render pass into the
/// layer; nothing is submitted, nothing waits, and no CPU work grows with the triangles.
/// Multi-view methods render their views in turn into the one layer, each followed by the pass
/// that reads it.
#[derive(Debug)]
pub struct GpuMapFrame {
    /// Side in texels.
    pub r: u32,
    /// The map the pass renders (layer 0: nearest linear depth, +inf where empty).
    pub layer: GpuDepthMap,
    pub(super) depth_test: wgpu::TextureView,
    /// Per view slot: the view uniform ([`LightViewUniform`]) and the raster bind group.
    pub(super) slots: Vec<(wgpu::Buffer, wgpu::BindGroup)>,
    pub(super) pipeline: wgpu::RenderPipeline,
    /// Depth only: the pass writing [`layer`](Self::layer) from the depth test, on request.
    pub(super) linear: Option<LinearLayer>,
}

/// The compute pass that writes a depth-only map's depth test into its linear layer
/// (`linear_layer.wgsl`), for read-back.
#[derive(Debug)]
pub(super) struct LinearLayer(Kernel);

impl LinearLayer {
    pub(super) fn new(ctx: &GpuContext) -> Result<Self> {
        let kernel = SpecializedKernel::new(
            ctx,
            "raster.linear_layer",
            &[SHARED_WGSL, LINEAR_LAYER_WGSL],
            "linear_layer",
            &[],
        )?;
        Ok(LinearLayer(kernel.fixed(ctx)?))
    }
}

/// WGSL of [`GpuMapFrame::fill_layer`]'s pass (after the core's `shared.wgsl`).
pub const LINEAR_LAYER_WGSL: &str = include_str!("../linear_layer.wgsl");

impl GpuMapFrame {
    /// The view uniform of `slot` ([`LightViewUniform`]), for estimate kernels to bind.
    /// Panics on a slot beyond those prepared (a caller's bug, never input data).
    pub fn view_uniform(&self, slot: usize) -> &wgpu::Buffer {
        &self.slots[slot].0
    }

    /// Number of view slots.
    pub fn slots(&self) -> usize {
        self.slots.len()
    }

    /// Whether the pass writes its depth test alone (no fragment stage): the map is then the
    /// depth test ([`depth_binding`](Self::depth_binding): n / z reversed, or an orthographic
    /// view's `1 - (z - n) / s`, 0 where empty; `linear_depth` in the core's `shared.wgsl`), and
    /// [`layer`](Self::layer) holds it only after [`fill_layer`](Self::fill_layer).
    pub fn depth_only(&self) -> bool {
        self.linear.is_some()
    }

    /// The depth test, for kernels of a depth-only map to bind as `texture_depth_2d`.
    pub fn depth_binding(&self) -> wgpu::BindingResource<'_> {
        wgpu::BindingResource::TextureView(&self.depth_test)
    }

    /// For read-back (tests and tools, not per frame): writes the depth test the last submitted
    /// frame left, in the view of `slot`, into [`layer`](Self::layer) as linear depth (what the
    /// kernels read), and submits. Nothing to do for a map that renders its layer itself.
    pub fn fill_layer(&self, ctx: &GpuContext, slot: usize) -> Result<()> {
        let Some(LinearLayer(kernel)) = &self.linear else {
            return Ok(());
        };
        let uniform = &self.view_uniform(slot);
        let group = kernel.bind_group(
            ctx,
            "raster.linear_layer",
            &[
                uniform.as_entire_binding(),
                wgpu::BindingResource::TextureView(&self.depth_test),
                wgpu::BindingResource::TextureView(&self.layer.view),
            ],
        );
        let mut enc = ctx.device.create_command_encoder(&Default::default());
        let groups = self.r.div_ceil(8);
        compute_pass(
            &mut enc,
            "raster.linear_layer",
            &kernel.pipeline,
            &group,
            [groups, groups, 1],
        );
        ctx.queue.submit([enc.finish()]);
        ctx.check_lost()
    }

    /// Stages `view` (its resolution must be this map's) in `slot` and records the pass
    /// rendering `casters` into [`layer`](Self::layer). Errors: [`Error::LightView`] for a view
    /// of another resolution, [`Error::Limit`] for a slot beyond those prepared.
    pub fn encode(
        &self,
        ctx: &GpuContext,
        enc: &mut wgpu::CommandEncoder,
        casters: &GpuScene,
        view: &LightView,
        slot: usize,
    ) -> Result<()> {
        let Some((uniform, group)) = self.slots.get(slot) else {
            return Err(Error::Limit {
                what: "view slot of a frame's shadow map",
                requested: slot as u64,
                max: self.slots.len().saturating_sub(1) as u64,
            });
        };
        if view.r != self.r {
            return Err(Error::LightView(format!(
                "the frame's view has resolution {} but the map was prepared at {}",
                view.r, self.r
            )));
        }
        ctx.write_in(
            enc,
            uniform,
            0,
            bytemuck::bytes_of(&LightViewUniform::from(view)),
        );
        let mut pass = match self.linear {
            Some(_) => begin_depth_tested_pass(enc, "raster.depth_only", &[], &self.depth_test),
            None => begin_layer_pass(enc, 0, &self.layer.view, None, &self.depth_test),
        };
        if casters.triangles > 0 {
            pass.set_pipeline(&self.pipeline);
            pass.set_bind_group(0, group, &[]);
            pass.set_vertex_buffer(0, casters.vertices.slice(..));
            pass.draw(0..3 * casters.triangles, 0..1);
        }
        Ok(())
    }
}

/// One view [`GpuLayersFrame::encode_slot`] renders in: the view, the midpoint clamp (world
/// units; unused without midpoints), the smallest opacity a caster casts with (0: every caster,
/// [`RasterParams::min_opacity`]) and the staging slot of its uniforms.
#[derive(Debug, Clone, Copy)]
pub struct LayersSlot<'a> {
    /// The light view.
    pub view: &'a LightView,
    /// The midpoint clamp.
    pub max_bias: f32,
    /// Casters below this opacity are not rendered.
    pub min_opacity: f32,
    /// The slot, below the `slots` the frame was prepared with.
    pub slot: usize,
    /// The MSSM levels to build (level 0 the depth map itself; `None`: every level prepared).
    pub mssm_levels: Option<u32>,
    /// Whether the MSSM's levels get their max planes too (false: the min planes only, for
    /// kernels that query no maximum; the max planes, and those of [`GpuLayersFrame::light_space`],
    /// then keep stale values).
    pub mssm_max: bool,
    /// Timestamps the passes are marked in (`raster`, `midpoints`, `mssm`), if any.
    pub timestamps: Option<&'a crate::gpu::frame::FrameTimestamps>,
}

/// A [`GpuLayersFrame`]'s view slots and its raster parameters at opacity 0.
#[derive(Debug)]
pub(super) struct LayersStage {
    pub(super) slots: usize,
    pub(super) base: RasterParams,
}

/// The depth-peeled layers, midpoint layers and MSSM family of one view, rendered every frame
/// into the caller's command encoder (the engine path, [`GpuShadowMapper::layers_frame`](super::GpuShadowMapper::layers_frame)): the
/// resources and bind groups of [`GpuShadowMapper::render_layers`](super::GpuShadowMapper::render_layers), allocated once;
/// [`encode`](Self::encode) writes the view and the midpoint clamp in the encoder's order
/// ([`GpuContext::write_in`]) and records the peeling passes, the midpoint pass and the MSSM
/// pass. Nothing is submitted, nothing waits, no CPU work grows with the triangles or texels.
#[derive(Debug)]
pub struct GpuLayersFrame {
    /// Side in texels.
    pub r: u32,
    pub(super) layers_out: usize,
    pub(super) stage: LayersStage,
    pub(super) params: wgpu::Buffer,
    pub(super) view_uniform: wgpu::Buffer,
    /// Every peeled layer, the extra one the midpoints read included.
    pub(super) layers: Vec<GpuDepthMap>,
    /// Per peeled layer, the opacity of its texels' casters (when prepared with opacity).
    pub(super) opacity: Vec<GpuDepthMap>,
    /// Whether the last `encode` wrote the opacity planes (semi-transparent casters).
    pub(super) wrote_opacity: std::sync::atomic::AtomicBool,
    /// The MSSM levels the last `encode` built ([`LayersSlot::mssm_levels`]; `u32::MAX`: all).
    pub(super) mssm_built: std::sync::atomic::AtomicU32,
    pub(super) midpoints: Vec<GpuDepthMap>,
    pub(super) set: crate::gpu::mssm::GpuMinMaxSet,
    pub(super) depth_test: wgpu::TextureView,
    /// Per peeling pass: its pipelines and bind group.
    pub(super) groups: Vec<(LayerPipelines, wgpu::BindGroup)>,
    pub(super) midpoint_pass: Option<crate::gpu::midpoint::GpuMidpointPass>,
    pub(super) mssm_pass: crate::gpu::mssm::GpuMinMaxPass,
}

impl GpuLayersFrame {
    /// The view uniform ([`LightViewUniform`]) the passes read, for estimate kernels to bind.
    pub fn view_uniform(&self) -> &wgpu::Buffer {
        &self.view_uniform
    }

    /// Bytes of the layers, opacity planes, midpoints and MSSM family, counted as
    /// [`GpuLightSpace::bytes`] counts them.
    pub fn bytes(&self) -> usize {
        let set = &self.set;
        let family = (
            set.mssm.as_ref(),
            set.dual_mssm.as_ref(),
            set.pyramid.as_ref(),
        );
        crate::gpu::light_space::maps_bytes([&self.layers, &self.midpoints, &self.opacity], family)
    }

    /// Render passes over the casters per `encode` (the peeled layers, the midpoints' extra one
    /// included).
    pub fn passes(&self) -> u32 {
        self.groups.len() as u32
    }

    /// Whether an `encode` over `casters` writes the opacity planes: prepared with them, and
    /// the casters semi-transparent.
    pub fn writes_opacity(&self, casters: &GpuScene) -> bool {
        !casters.is_opaque() && !self.opacity.is_empty()
    }

    /// The peeled layers the request asked for, nearest first.
    pub fn layers(&self) -> &[GpuDepthMap] {
        &self.layers[..self.layers_out]
    }

    /// Per layer of [`layers`](Self::layers), each texel's opacity (the mesh opacity of the
    /// caster its depth came from, 0 where empty: the CPU's [`crate::LightSpace::opacity`]);
    /// empty unless prepared with `opacity`. Written by frames whose casters are
    /// semi-transparent ([`GpuScene::is_opaque`] false), left as they were otherwise.
    pub fn opacity(&self) -> &[GpuDepthMap] {
        &self.opacity[..self.opacity.len().min(self.layers_out)]
    }

    /// The midpoint layers (empty unless requested).
    pub fn midpoints(&self) -> &[GpuDepthMap] {
        &self.midpoints
    }

    /// The MSSM family of layer 0 as requested.
    pub fn min_max(&self) -> &crate::gpu::mssm::GpuMinMaxSet {
        &self.set
    }

    /// Stages `view` and the midpoint clamp `max_bias` (world units; unused without midpoints)
    /// and records every pass, every caster cast: [`encode_slot`](Self::encode_slot) in slot 0.
    pub fn encode(
        &self,
        ctx: &GpuContext,
        enc: &mut wgpu::CommandEncoder,
        casters: &GpuScene,
        view: &LightView,
        max_bias: f32,
    ) -> Result<()> {
        let slot = LayersSlot {
            view,
            max_bias,
            min_opacity: 0.0,
            slot: 0,
            mssm_levels: None,
            mssm_max: true,
            timestamps: None,
        };
        self.encode_slot(ctx, enc, casters, &slot)
    }

    /// Records every pass in `slot.view`, its uniforms written in the encoder's order
    /// ([`GpuContext::write_in`]), so one encoder can render the layers in several views in
    /// turn, each followed by the passes that read them. Errors: [`Error::LightView`] for a view
    /// of another resolution or a slot beyond those prepared.
    pub fn encode_slot(
        &self,
        ctx: &GpuContext,
        enc: &mut wgpu::CommandEncoder,
        casters: &GpuScene,
        slot: &LayersSlot<'_>,
    ) -> Result<()> {
        let view = slot.view;
        if view.r != self.r {
            return Err(Error::LightView(format!(
                "the frame's view has resolution {} but the layers were prepared at {}",
                view.r, self.r
            )));
        }
        let st = &self.stage;
        if slot.slot >= st.slots {
            return Err(Error::LightView(format!(
                "view slot {} of a frame prepared for {} views",
                slot.slot, st.slots
            )));
        }
        ctx.write_in(
            enc,
            &self.view_uniform,
            0,
            bytemuck::bytes_of(&LightViewUniform::from(view)),
        );
        let params = RasterParams {
            min_opacity: slot.min_opacity,
            ..st.base
        };
        ctx.write_in(enc, &self.params, 0, bytemuck::bytes_of(&params));
        let with_opacity = self.writes_opacity(casters);
        self.wrote_opacity
            .store(with_opacity, std::sync::atomic::Ordering::Relaxed);
        for (m, (pipelines, group)) in self.groups.iter().enumerate() {
            let (pipeline, opacity) = match (&pipelines.opacity, with_opacity) {
                (Some(p), true) => (p, Some(&self.opacity[m].view)),
                _ => (&pipelines.opaque, None),
            };
            let mut pass =
                begin_layer_pass(enc, m, &self.layers[m].view, opacity, &self.depth_test);
            if casters.triangles > 0 {
                pass.set_pipeline(pipeline);
                pass.set_bind_group(0, group, &[]);
                pass.set_vertex_buffer(0, casters.vertices.slice(..));
                pass.draw(0..3 * casters.triangles, 0..1);
            }
        }
        let mark = |enc: &mut wgpu::CommandEncoder, stage| {
            if let Some(t) = slot.timestamps {
                t.mark(enc, stage);
            }
        };
        mark(enc, "raster");
        if let Some(p) = &self.midpoint_pass {
            p.record(ctx, enc, slot.max_bias);
            mark(enc, "midpoints");
        }
        let levels = slot.mssm_levels.unwrap_or(u32::MAX);
        self.mssm_pass.record_levels(enc, levels, slot.mssm_max);
        mark(enc, "mssm");
        self.mssm_built
            .store(levels, std::sync::atomic::Ordering::Relaxed);
        Ok(())
    }

    /// The maps as a [`GpuLightSpace`] in `view` (sharing this frame's textures and buffers),
    /// the opacity planes included when the last `encode` wrote them, the MSSM's levels those
    /// it built.
    pub fn light_space(&self, view: &LightView) -> GpuLightSpace {
        let wrote = self
            .wrote_opacity
            .load(std::sync::atomic::Ordering::Relaxed);
        let built = self.mssm_built.load(std::sync::atomic::Ordering::Relaxed);
        let mut mssm = self.set.mssm.clone();
        if let Some(m) = &mut mssm {
            m.levels.truncate(built.max(1) as usize);
        }
        GpuLightSpace {
            view: *view,
            fit: FitReport::default(),
            view_uniform: self.view_uniform.clone(),
            layers: self.layers().to_vec(),
            opacity: if wrote {
                self.opacity().to_vec()
            } else {
                Vec::new()
            },
            midpoints: self.midpoints.clone(),
            mssm,
            dual_mssm: self.set.dual_mssm.clone(),
            pyramid: self.set.pyramid.clone(),
        }
    }
}
