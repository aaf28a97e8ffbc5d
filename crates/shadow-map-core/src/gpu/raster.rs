//! The GPU shadow-map rasteriser and depth peeling (`raster.wgsl`), the twin of
//! [`crate::raster`] and [`crate::peeling`].
//!
//! **Storage.** Layers are `R32Float` textures ([`GpuDepthMap`]) of linear light-space z, +inf
//! where empty (the colour target is cleared to `f64::INFINITY`). Textures rather than buffers
//! because they are render targets; later stages read them with `textureLoad`. A map frame may
//! instead be depth only ([`GpuShadowMapper::map_frame`]): no fragment stage runs, the depth
//! test is the map, and its kernels read `n / z` and invert it (`linear_depth` in `shared.wgsl`;
//! docs/gpu.md, "Depth-only maps").
//!
//! **Fill rule.** The GPU's: a texel is covered when its centre is inside the projected
//! triangle, with the rasteriser's tie rule (top-left on Vulkan), after snapping vertices to its
//! sub-pixel grid (8 bits on lavapipe and NVIDIA). The CPU works in f64 without snapping, so
//! texels whose centre lies within about 1/256 texel of an edge may differ (`tests/gpu_maps.rs`
//! measures and bounds that fraction).
//!
//! **Projection.** `clip = (2 u z / r - z, z - 2 v z / r, n, z)` with `u z = (n x - x0 z) / delta`,
//! `v z = (n y - y0 z) / delta` (the CPU's `u = (n x / z - x0) / delta`, times z). wgpu's
//! framebuffer row 0 is NDC y = +1, so row j is texel row j (v). Depth is `n / z`: reversed with an
//! infinite far plane (compare `Greater`, clear 0), and the clip volume `0 <= clip.z <= clip.w` is
//! exactly the CPU's near-plane clip `z >= n`, with no far clip.
//!
//! **Depth.** The fragment writes the perspective-correct interpolated z plus the slope-scaled
//! bias `constant + slope * max(|dz/du|, |dz/dv|)`, with `dz/du = -z^2 d(1/z)/du` and `d(1/z)/du`
//! from `dpdx` of the fragment depth `n / z`, which is affine in screen space: the 2x2-quad
//! difference equals the CPU's analytic plane gradient up to f32 rounding. With a bias, the
//! fragment also writes `frag_depth = n / z_biased`, so the depth test keeps the smallest stored
//! value, as the CPU's `min` does.
//!
//! **Culling.** The pipeline's cull mode, front face counter-clockwise in NDC. A triangle whose
//! winding normal faces the light centre (the CPU's `facing_light`) is counter-clockwise on the
//! plane z = n seen from the light with +x right and +y up; the framebuffer flip (row j = +v)
//! flips it on screen but NDC keeps y up, so such a triangle is counter-clockwise in NDC: a
//! front face. [`Cull::Back`] culls `Face::Back`, [`Cull::Front`] culls `Face::Front`.
//!
//! **Peeling.** Pass m binds layer m - 1 and discards fragments with
//! `!(z > prev * (1 + PEEL_EPS_REL))`, `PEEL_EPS_REL` passed as a WGSL override constant from
//! [`crate::raster::PEEL_EPS_REL`].
use super::{
    depth_map::{check_size, texture_desc, GpuDepthMap, DEPTH_MAP_FORMAT},
    kernel::{buffer_init, wgsl_module, Binding},
    light_space::GpuLightSpace,
    midpoint::GpuMidpoints,
    mssm::{GpuMssmBuilder, MinMaxRequest},
    shared::LightViewUniform,
    GpuContext,
};
use crate::{
    light_view::{LightView, ViewOptions},
    raster::{Cull, DepthBias, RasterOptions, PEEL_EPS_REL},
    receivers::Receivers,
    scene::Scene,
    Error, LightSpaceRequest, Result,
};
use bytemuck::{Pod, Zeroable};
use std::collections::HashMap;
use std::sync::Mutex;

mod frames;
use frames::LayersStage;
pub use frames::{GpuLayersFrame, GpuMapFrame, LayersSlot};

/// `linear_layer.wgsl` (the pass of [`GpuMapFrame::fill_layer`]) after the core's `shared.wgsl`, as
/// [`super::SHADERS`] validates it.
pub const LINEAR_LAYER_CHECK_WGSL: &str = concat!(
    include_str!("shared.wgsl"),
    include_str!("linear_layer.wgsl")
);

/// WGSL source of the rasteriser: `shared.wgsl` followed by `raster.wgsl`.
pub const RASTER_WGSL: &str = concat!(include_str!("shared.wgsl"), include_str!("raster.wgsl"));

/// Format of the depth attachment used for the nearest-surface test.
pub const DEPTH_TEST_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;

/// The vertex buffers of every raster pipeline: one, a `vec4<f32>` position per vertex at
/// location 0 (the vertices of [`GpuScene`]).
pub const VERTEX_BUFFERS: &[Option<wgpu::VertexBufferLayout<'static>>] =
    &[Some(wgpu::VertexBufferLayout {
        array_stride: 16,
        step_mode: wgpu::VertexStepMode::Vertex,
        attributes: &[wgpu::VertexAttribute {
            format: wgpu::VertexFormat::Float32x4,
            offset: 0,
            shader_location: 0,
        }],
    })];

/// Uniform of the raster passes; mirrors `RasterParams` in `raster.wgsl`.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable)]
pub struct RasterParams {
    /// [`DepthBias::constant`].
    pub bias_constant: f32,
    /// [`DepthBias::slope`].
    pub bias_slope: f32,
    /// Casters of a smaller opacity (the vertex's w) are dropped: one opacity level of
    /// [`crate::Scene::opacity_levels`] (0: every caster; +inf: none).
    pub min_opacity: f32,
    /// Padding.
    pub _pad1: f32,
}

impl From<DepthBias> for RasterParams {
    fn from(b: DepthBias) -> Self {
        RasterParams {
            bias_constant: b.constant,
            bias_slope: b.slope,
            min_opacity: 0.0,
            _pad1: 0.0,
        }
    }
}

/// A scene's world-space triangles on the GPU, uploaded once and rendered in any light view: a
/// vertex buffer of `vec4<f32>`, three per triangle, non-indexed, each the vertex's position in
/// xyz and its triangle's opacity in w (the mesh's `opacity`, 1 for an opaque caster): the
/// caster buffer every engine path reads. Raster passes take the position; passes that model
/// semi-transparent casters also write the opacity ([`GpuLayersFrame`] with opacity planes).
#[derive(Debug, Clone)]
pub struct GpuScene {
    /// The vertex buffer (label `raster.scene`, usages `VERTEX | STORAGE | COPY_DST | COPY_SRC`).
    pub vertices: wgpu::Buffer,
    /// Number of triangles.
    pub triangles: u32,
    /// Some caster has an opacity below 1.
    pub(crate) semi_transparent: bool,
    /// The casters' opacity levels ([`crate::Scene::opacity_levels`]), empty when opaque.
    pub(crate) levels: Vec<crate::OpacityLevel>,
}

/// Usages of [`GpuScene::vertices`].
const SCENE_USAGE: wgpu::BufferUsages = wgpu::BufferUsages::VERTEX
    .union(wgpu::BufferUsages::STORAGE)
    .union(wgpu::BufferUsages::COPY_DST)
    .union(wgpu::BufferUsages::COPY_SRC);

/// [`Error::Limit`] (naming `what`) when `n` triangles (48 bytes each) exceed the device's
/// `max_buffer_size` or a `u32` vertex count.
fn check_triangles(ctx: &GpuContext, n: u64, what: &'static str) -> Result<()> {
    let max = (ctx.limits().max_buffer_size / 48).min(u32::MAX as u64 / 3);
    if n > max {
        return Err(Error::Limit {
            what,
            requested: n,
            max,
        });
    }
    Ok(())
}

impl GpuScene {
    /// Room for `triangles` triangles and none in it yet: the buffer
    /// [`GpuCasterBuilder`](super::casters::GpuCasterBuilder) fills from the caller's meshes
    /// every frame. [`Error::Limit`] beyond the device's `max_buffer_size`.
    pub fn with_capacity(ctx: &GpuContext, triangles: u32) -> Result<Self> {
        check_triangles(
            ctx,
            triangles as u64,
            "caster triangles on the GPU (max_buffer_size / 48 bytes)",
        )?;
        ctx.scoped("raster.scene", || GpuScene {
            vertices: ctx.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("raster.scene"),
                size: 48 * triangles.max(1) as u64,
                usage: SCENE_USAGE,
                mapped_at_creation: false,
            }),
            triangles: 0,
            semi_transparent: false,
            levels: Vec::new(),
        })
    }

    /// How many triangles the buffer holds room for.
    pub fn capacity(&self) -> u32 {
        (self.vertices.size() / 48) as u32
    }

    /// Uploads `scene.triangles`. Fails with [`Error::Limit`] when the buffer would exceed the
    /// device's `max_buffer_size` or the vertex count `u32`.
    pub fn upload(ctx: &GpuContext, scene: &Scene) -> Result<Self> {
        let n = scene.triangles().len() as u64;
        check_triangles(
            ctx,
            n,
            "scene triangles on the GPU (max_buffer_size / 48 bytes)",
        )?;
        let mut verts: Vec<[f32; 4]> = Vec::with_capacity(3 * n as usize);
        for (ti, t) in scene.triangles().iter().enumerate() {
            let opacity = scene.triangle_opacity(ti);
            for v in t {
                verts.push([v.x, v.y, v.z, opacity]);
            }
        }
        if verts.is_empty() {
            verts.push([0.0; 4]);
        }
        ctx.scoped("raster.scene", || GpuScene {
            vertices: buffer_init(
                &ctx.device,
                "raster.scene",
                bytemuck::cast_slice(&verts),
                SCENE_USAGE,
            ),
            triangles: n as u32,
            semi_transparent: !scene.is_opaque(),
            levels: if scene.is_opaque() {
                Vec::new()
            } else {
                scene.opacity_levels()
            },
        })
    }

    /// Whether every caster is opaque (opacity 1): what passes that model opacity need not
    /// write or read.
    pub fn is_opaque(&self) -> bool {
        !self.semi_transparent
    }

    /// The casters' opacity levels ([`crate::Scene::opacity_levels`]), empty when every caster
    /// is opaque: what a frame renders one pass per level for ([`RasterParams::min_opacity`]).
    pub fn opacity_levels(&self) -> &[crate::OpacityLevel] {
        &self.levels
    }

    /// Bytes of the vertex buffer.
    pub fn bytes(&self) -> u64 {
        self.vertices.size()
    }
}

/// Pipeline variant: culling, peeling pass (m >= 1), bias, opacity target.
/// (cull, peel, biased, opacity, depth only: no fragment stage, the depth test the map).
type PipelineKey = (u8, bool, bool, bool, bool);

/// The GPU shadow-map core of one context: raster pipelines (created on first use per variant
/// and cached), the midpoint pipeline and the MSSM builder.
#[derive(Debug)]
pub struct GpuShadowMapper {
    module: wgpu::ShaderModule,
    layout: wgpu::BindGroupLayout,
    pipeline_layout: wgpu::PipelineLayout,
    pipelines: Mutex<HashMap<PipelineKey, wgpu::RenderPipeline>>,
    /// Bound as "layer m - 1" in pass 0, where the shader never reads it.
    no_prev: wgpu::TextureView,
    midpoints: GpuMidpoints,
    mssm: GpuMssmBuilder,
}

fn cull_key(c: Cull) -> u8 {
    match c {
        Cull::None => 0,
        Cull::Back => 1,
        Cull::Front => 2,
    }
}

fn lock_error<T>(_: T) -> Error {
    Error::Gpu {
        stage: "raster".into(),
        reason: "pipeline cache lock poisoned".into(),
    }
}

impl GpuShadowMapper {
    /// Compiles the shaders and creates the layouts (label `raster`), the midpoint pipeline and
    /// the MSSM pipelines.
    pub fn new(ctx: &GpuContext) -> Result<Self> {
        let (module, layout, pipeline_layout, no_prev) = ctx.scoped("raster", || {
            let device = &ctx.device;
            let module = wgsl_module(device, "raster", RASTER_WGSL);
            let uniform =
                |binding| Binding::Uniform.entry_in(binding, wgpu::ShaderStages::VERTEX_FRAGMENT);
            let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
                label: Some("raster"),
                entries: &[
                    uniform(0),
                    uniform(1),
                    Binding::Texture2d.entry_in(2, wgpu::ShaderStages::FRAGMENT),
                ],
            });
            let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
                label: Some("raster"),
                bind_group_layouts: &[Some(&layout)],
                immediate_size: 0,
            });
            let no_prev = device
                .create_texture(&texture_desc(
                    "raster.no_prev",
                    1,
                    1,
                    1,
                    DEPTH_MAP_FORMAT,
                    wgpu::TextureUsages::TEXTURE_BINDING,
                ))
                .create_view(&Default::default());
            (module, layout, pipeline_layout, no_prev)
        })?;
        Ok(GpuShadowMapper {
            module,
            layout,
            pipeline_layout,
            pipelines: Mutex::new(HashMap::new()),
            no_prev,
            midpoints: GpuMidpoints::new(ctx)?,
            mssm: GpuMssmBuilder::new(ctx)?,
        })
    }

    /// The MSSM builder (to build over depth maps that were not rendered here).
    pub fn mssm_builder(&self) -> &GpuMssmBuilder {
        &self.mssm
    }

    /// Caps the storage-binding size the MSSM builds plan chunks against (see
    /// [`GpuMssmBuilder::with_max_binding_bytes`]); `None` restores the device limit.
    pub fn set_max_binding_bytes(&mut self, bytes: Option<u64>) {
        self.mssm.set_max_binding_bytes(bytes);
    }

    fn pipeline(&self, ctx: &GpuContext, key: PipelineKey) -> Result<wgpu::RenderPipeline> {
        let mut cache = self.pipelines.lock().map_err(lock_error)?;
        if let Some(p) = cache.get(&key) {
            return Ok(p.clone());
        }
        let (cull, peel, biased, opacity, depth_only) = key;
        let label = format!(
            "raster.{}{}{}{}{}",
            ["cull_none", "cull_back", "cull_front"][cull as usize % 3],
            if peel { ".peel" } else { ".first" },
            if biased { ".biased" } else { "" },
            if opacity { ".opacity" } else { "" },
            if depth_only { ".depth_only" } else { "" }
        );
        let target = Some(wgpu::ColorTargetState {
            format: DEPTH_MAP_FORMAT,
            blend: None,
            write_mask: wgpu::ColorWrites::ALL,
        });
        let targets = [target.clone(), target];
        let constants = [
            ("PEEL_EPS_REL", PEEL_EPS_REL as f64),
            ("PEEL", if peel { 1.0 } else { 0.0 }),
        ];
        let p = ctx.scoped("raster", || {
            ctx.device
                .create_render_pipeline(&wgpu::RenderPipelineDescriptor {
                    label: Some(&label),
                    layout: Some(&self.pipeline_layout),
                    vertex: wgpu::VertexState {
                        module: &self.module,
                        entry_point: Some("vs_layer"),
                        compilation_options: wgpu::PipelineCompilationOptions {
                            constants: &constants,
                            ..Default::default()
                        },
                        buffers: VERTEX_BUFFERS,
                    },
                    primitive: wgpu::PrimitiveState {
                        topology: wgpu::PrimitiveTopology::TriangleList,
                        front_face: wgpu::FrontFace::Ccw,
                        cull_mode: match cull {
                            1 => Some(wgpu::Face::Back),
                            2 => Some(wgpu::Face::Front),
                            _ => None,
                        },
                        ..Default::default()
                    },
                    depth_stencil: Some(nearest_surface_test()),
                    multisample: Default::default(),
                    // Depth only: the rasteriser's n / z is the map, no fragment stage runs.
                    fragment: (!depth_only).then_some(wgpu::FragmentState {
                        module: &self.module,
                        entry_point: Some(match (biased, opacity) {
                            (false, false) => "fs_layer",
                            (true, false) => "fs_layer_biased",
                            (false, true) => "fs_layer_opacity",
                            (true, true) => "fs_layer_biased_opacity",
                        }),
                        compilation_options: wgpu::PipelineCompilationOptions {
                            constants: &constants,
                            ..Default::default()
                        },
                        targets: &targets[..1 + usize::from(opacity)],
                    }),
                    multiview_mask: None,
                    cache: None,
                })
        })?;
        cache.insert(key, p.clone());
        Ok(p)
    }

    /// Fits a view at the light centre to `receivers` (as [`crate::LightSpace::build`] does) and
    /// renders what `req` asks for (see [`GpuShadowMapper::render_layers`]).
    pub fn render(
        &self,
        ctx: &GpuContext,
        scene: &Scene,
        gpu_scene: &GpuScene,
        receivers: &Receivers,
        req: &LightSpaceRequest,
    ) -> Result<GpuLightSpace> {
        let (view, fit) = req.fit_view(scene, receivers, &ViewOptions::default())?;
        let mut ls = self.render_layers(ctx, gpu_scene, &view, req)?;
        ls.fit = fit;
        Ok(ls)
    }

    /// Renders in `view` (its resolution `view.r`, as [`crate::LightSpace::build_in_view`] uses):
    /// `req.layers` peeled layers (at least 1), plus one more when midpoints are requested, the
    /// midpoint layers (compute pass), and the MSSM family over layer 0 as requested. All work is
    /// recorded in one command encoder and submitted; nothing waits. The result's `fit` is
    /// [`FitReport::default`](crate::light_view::FitReport::default).
    ///
    /// Errors: [`Error::Limit`] when `view.r` is 0 or beyond the device's
    /// `max_texture_dimension_2d` (or an MSSM plane is beyond `max_buffer_size`); GPU validation
    /// and out-of-memory errors as [`Error::Gpu`] / [`Error::OutOfMemory`] (stage `raster`).
    pub fn render_layers(
        &self,
        ctx: &GpuContext,
        scene: &GpuScene,
        view: &LightView,
        req: &LightSpaceRequest,
    ) -> Result<GpuLightSpace> {
        let frame = self.layers_frame(ctx, view.r, req)?;
        ctx.scoped("raster", || -> Result<GpuLightSpace> {
            let mut enc = ctx
                .device
                .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                    label: Some("raster"),
                });
            frame.encode(ctx, &mut enc, scene, view, req.midpoints.unwrap_or(0.0))?;
            ctx.queue.submit([enc.finish()]);
            Ok(frame.light_space(view))
        })?
    }

    /// The resources of [`render_layers`](Self::render_layers) for views of side `r`, allocated
    /// once and rendered every frame into the caller's command encoder ([`GpuLayersFrame`], the
    /// engine path): the peeled layers (`req.layers`, at least 1, plus one when midpoints are
    /// requested), the midpoint layers, the MSSM family of layer 0 as requested, the uniforms
    /// and every bind group. `req.resolution` is ignored (`r` is the side). Errors as
    /// `render_layers`.
    pub fn layers_frame(
        &self,
        ctx: &GpuContext,
        r: u32,
        req: &LightSpaceRequest,
    ) -> Result<GpuLayersFrame> {
        self.layers_frame_slots(ctx, r, req, 1)
    }

    /// [`layers_frame`](Self::layers_frame) for frames that render the layers in up to `slots`
    /// views in turn within one encoder ([`GpuLayersFrame::encode_slot`]).
    pub fn layers_frame_slots(
        &self,
        ctx: &GpuContext,
        r: u32,
        req: &LightSpaceRequest,
        slots: u32,
    ) -> Result<GpuLayersFrame> {
        check_size(ctx, r)?;
        let layers_out = req.layers.max(1);
        let k = layers_out + u32::from(req.midpoints.is_some());
        let cull = cull_key(req.raster.cull);
        let bias = req.raster.bias;
        let biased = bias.constant != 0.0 || bias.slope != 0.0;
        // Per pass: the depth-only pipeline, and the one that also writes opacity when asked.
        let pipelines = |peel: bool| -> Result<LayerPipelines> {
            Ok(LayerPipelines {
                opaque: self.pipeline(ctx, (cull, peel, biased, false, false))?,
                opacity: if req.opacity {
                    Some(self.pipeline(ctx, (cull, peel, biased, true, false))?)
                } else {
                    None
                },
            })
        };
        let first = pipelines(false)?;
        let peel = if k > 1 { Some(pipelines(true)?) } else { None };
        ctx.scoped("raster", || -> Result<GpuLayersFrame> {
            let device = &ctx.device;
            let (view_uniform, params) =
                create_raster_uniforms(device, &LightView::placeholder(r), bias);
            let depth_test = create_depth_test(device, r, wgpu::TextureUsages::RENDER_ATTACHMENT);
            let mut layers = Vec::with_capacity(k as usize);
            let mut opacity = Vec::new();
            for m in 0..k {
                layers.push(GpuDepthMap::new(ctx, r, &format!("raster.layer{m}"))?);
                if req.opacity {
                    opacity.push(GpuDepthMap::new(ctx, r, &format!("raster.opacity{m}"))?);
                }
            }
            let groups = (0..k as usize)
                .map(|m| {
                    let prev = if m == 0 {
                        &self.no_prev
                    } else {
                        &layers[m - 1].view
                    };
                    let pipeline = match (&peel, m) {
                        (Some(p), 1..) => p.clone(),
                        _ => first.clone(),
                    };
                    let group = self.layer_bind_group(device, &view_uniform, &params, prev);
                    (pipeline, group)
                })
                .collect();
            let mut midpoints = Vec::new();
            let mut midpoint_pass = None;
            if req.midpoints.is_some() {
                for m in 0..k - 1 {
                    midpoints.push(GpuDepthMap::new(ctx, r, &format!("midpoint.layer{m}"))?);
                }
                midpoint_pass = self.midpoints.prepare(ctx, &layers, &midpoints);
            }
            let (set, mssm_pass) = self.mssm.prepare(
                ctx,
                &layers[0],
                MinMaxRequest {
                    mssm_levels: req.mssm_levels,
                    dual_mssm_levels: req.dual_mssm_levels,
                    pyramid: req.pyramid,
                },
            )?;
            Ok(GpuLayersFrame {
                r,
                layers_out: layers_out as usize,
                stage: LayersStage {
                    slots: slots.max(1) as usize,
                    base: RasterParams::from(bias),
                },
                params,
                view_uniform,
                layers,
                opacity,
                wrote_opacity: Default::default(),
                mssm_built: u32::MAX.into(),
                midpoints,
                set,
                depth_test,
                groups,
                midpoint_pass,
                mssm_pass,
            })
        })?
    }

    /// The resources of a shadow map rendered every frame into the caller's command encoder
    /// ([`GpuMapFrame`], the engine path): an `r x r` layer and its depth test, `views` view
    /// uniforms (one per view a frame renders in turn, at least 1) with the bias uniform, and the
    /// first-layer pipeline of `raster`, all allocated here, once. With `depth_only` (and no
    /// bias, whose stored depth needs the fragment stage) the pass writes the depth test alone,
    /// which is then the map ([`GpuMapFrame::depth_only`]).
    pub fn map_frame(
        &self,
        ctx: &GpuContext,
        r: u32,
        raster: RasterOptions,
        views: u32,
        depth_only: bool,
    ) -> Result<GpuMapFrame> {
        check_size(ctx, r)?;
        let bias = raster.bias;
        let biased = bias.constant != 0.0 || bias.slope != 0.0;
        let depth_only = depth_only && !biased;
        let key = (cull_key(raster.cull), false, biased, false, depth_only);
        let pipeline = self.pipeline(ctx, key)?;
        let linear = match depth_only {
            true => Some(frames::LinearLayer::new(ctx)?),
            false => None,
        };
        ctx.scoped("raster.frame", || -> Result<GpuMapFrame> {
            let device = &ctx.device;
            let placeholder = LightView::placeholder(r);
            let slots = (0..views.max(1))
                .map(|_| {
                    let (view_uniform, params) = create_raster_uniforms(device, &placeholder, bias);
                    let group =
                        self.layer_bind_group(device, &view_uniform, &params, &self.no_prev);
                    (view_uniform, group)
                })
                .collect();
            let mut usage = wgpu::TextureUsages::RENDER_ATTACHMENT;
            if depth_only {
                usage |= wgpu::TextureUsages::TEXTURE_BINDING;
            }
            Ok(GpuMapFrame {
                r,
                layer: GpuDepthMap::new(ctx, r, "raster.frame.layer0")?,
                depth_test: create_depth_test(device, r, usage),
                slots,
                pipeline,
                linear,
            })
        })?
    }

    /// Binds a peeling pass's uniforms and its previous layer `prev` (label `raster`).
    fn layer_bind_group(
        &self,
        device: &wgpu::Device,
        view_uniform: &wgpu::Buffer,
        params: &wgpu::Buffer,
        prev: &wgpu::TextureView,
    ) -> wgpu::BindGroup {
        device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("raster"),
            layout: &self.layout,
            entries: &[
                wgpu::BindGroupEntry {
                    binding: 0,
                    resource: view_uniform.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 1,
                    resource: params.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 2,
                    resource: wgpu::BindingResource::TextureView(prev),
                },
            ],
        })
    }
}

/// Creates the view uniform (`raster.view`), then the bias parameters (`raster.params`).
fn create_raster_uniforms(
    device: &wgpu::Device,
    view: &LightView,
    bias: DepthBias,
) -> (wgpu::Buffer, wgpu::Buffer) {
    let view_uniform = buffer_init(
        device,
        "raster.view",
        bytemuck::bytes_of(&LightViewUniform::from(view)),
        wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::COPY_SRC,
    );
    let params = buffer_init(
        device,
        "raster.params",
        bytemuck::bytes_of(&RasterParams::from(bias)),
        wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
    );
    (view_uniform, params)
}

/// Creates the `r` x `r` depth attachment of the nearest-surface test (`raster.depth_test`).
fn create_depth_test(
    device: &wgpu::Device,
    r: u32,
    usage: wgpu::TextureUsages,
) -> wgpu::TextureView {
    device
        .create_texture(&texture_desc(
            "raster.depth_test",
            r,
            r,
            1,
            DEPTH_TEST_FORMAT,
            usage,
        ))
        .create_view(&Default::default())
}

/// A peeling pass's pipelines: depth only, and depth with opacity (when prepared with opacity).
#[derive(Debug, Clone)]
struct LayerPipelines {
    opaque: wgpu::RenderPipeline,
    opacity: Option<wgpu::RenderPipeline>,
}

/// Begins layer `m`'s render pass (`raster.layer{m}`): colour cleared to +inf, the opacity
/// target (if any) to 0, depth to 0.
fn begin_layer_pass<'e>(
    enc: &'e mut wgpu::CommandEncoder,
    m: usize,
    target: &wgpu::TextureView,
    opacity: Option<&wgpu::TextureView>,
    depth_test: &wgpu::TextureView,
) -> wgpu::RenderPass<'e> {
    let inf = wgpu::Color {
        r: f64::INFINITY,
        g: 0.0,
        b: 0.0,
        a: 0.0,
    };
    let mut targets = vec![(target, inf)];
    targets.extend(opacity.map(|o| (o, wgpu::Color::TRANSPARENT)));
    begin_depth_tested_pass(enc, &format!("raster.layer{m}"), &targets, depth_test)
}

/// The nearest-surface test of the raster pipelines: reversed z on a [`DEPTH_TEST_FORMAT`]
/// attachment (cleared to 0), the greater depth wins and is written.
pub(crate) fn nearest_surface_test() -> wgpu::DepthStencilState {
    wgpu::DepthStencilState {
        format: DEPTH_TEST_FORMAT,
        depth_write_enabled: Some(true),
        depth_compare: Some(wgpu::CompareFunction::Greater),
        stencil: Default::default(),
        bias: Default::default(),
    }
}

/// Begins the render pass `label` into `targets`, each cleared to its colour and stored, with
/// the nearest-surface test `depth_test` (a [`DEPTH_TEST_FORMAT`] attachment cleared to 0,
/// discarded after the pass unless there are no targets: then the depth test is the pass's
/// product).
pub(crate) fn begin_depth_tested_pass<'e>(
    enc: &'e mut wgpu::CommandEncoder,
    label: &str,
    targets: &[(&wgpu::TextureView, wgpu::Color)],
    depth_test: &wgpu::TextureView,
) -> wgpu::RenderPass<'e> {
    let color_attachments: Vec<_> = targets
        .iter()
        .map(|&(view, clear)| {
            Some(wgpu::RenderPassColorAttachment {
                view,
                depth_slice: None,
                resolve_target: None,
                ops: wgpu::Operations {
                    load: wgpu::LoadOp::Clear(clear),
                    store: wgpu::StoreOp::Store,
                },
            })
        })
        .collect();
    enc.begin_render_pass(&wgpu::RenderPassDescriptor {
        label: Some(label),
        color_attachments: &color_attachments,
        depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
            view: depth_test,
            depth_ops: Some(wgpu::Operations {
                load: wgpu::LoadOp::Clear(0.0),
                store: match targets.is_empty() {
                    true => wgpu::StoreOp::Store,
                    false => wgpu::StoreOp::Discard,
                },
            }),
            stencil_ops: None,
        }),
        timestamp_writes: None,
        occlusion_query_set: None,
        multiview_mask: None,
    })
}
