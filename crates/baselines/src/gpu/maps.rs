//! Light-space data on the GPU for one view: the fitted [`LightView`] and its shadow map (layer 0)
//! as an R32Float texture or as packed 16-bit codes (`depth=unorm16`), and [`MapBuilder`], the
//! one place the maps are made.
use glam::Vec2;
use shadow_map_core::light_view::ViewOptions;
use shadow_map_core::{
    gpu::{
        depth_map::GpuDepthMap, GpuContext, GpuScene, GpuShadowMapper, GpuUnorm16Encoder,
        GpuUnorm16Map,
    },
    light_space::{LightSpace, LightSpaceRequest},
    light_view::{FitReport, LightView},
    DepthMap, DepthPrecision, Error, Receivers, Result, Scene, Unorm16Map,
};

/// A depth map on the GPU: `size x size` texels of linear light-space depth (+inf where empty) in
/// an R32Float texture, read with `textureLoad` (texel (i, j) at x = i, y = j, as
/// [`DepthMap::at`]).
#[derive(Debug)]
pub struct DepthTexture {
    /// The texture.
    pub texture: wgpu::Texture,
    /// A view of it, as the kernels bind it.
    pub view: wgpu::TextureView,
    /// Side in texels.
    pub size: u32,
}

impl DepthTexture {
    /// Uploads a CPU depth map (bit for bit).
    pub fn upload(ctx: &GpuContext, map: &DepthMap) -> Result<Self> {
        let max = ctx.limits().max_texture_dimension_2d;
        if map.size == 0 || map.size > max {
            return Err(Error::Limit {
                what: "shadow-map texture side (max_texture_dimension_2d)",
                requested: map.size as u64,
                max: max as u64,
            });
        }
        let texels = map.size as usize * map.size as usize;
        if map.depth.len() != texels {
            return Err(Error::Gpu {
                stage: "depth map upload".into(),
                reason: format!(
                    "{} depths for a {}x{} map",
                    map.depth.len(),
                    map.size,
                    map.size
                ),
            });
        }
        ctx.scoped("depth map upload", || {
            let size = wgpu::Extent3d {
                width: map.size,
                height: map.size,
                depth_or_array_layers: 1,
            };
            let texture = ctx.device.create_texture(&wgpu::TextureDescriptor {
                label: Some("baselines depth map"),
                size,
                mip_level_count: 1,
                sample_count: 1,
                dimension: wgpu::TextureDimension::D2,
                format: wgpu::TextureFormat::R32Float,
                // COPY_SRC: read back for the CPU fallback of receivers a device cut short.
                usage: wgpu::TextureUsages::TEXTURE_BINDING
                    | wgpu::TextureUsages::COPY_DST
                    | wgpu::TextureUsages::COPY_SRC,
                view_formats: &[],
            });
            ctx.queue.write_texture(
                wgpu::TexelCopyTextureInfo {
                    texture: &texture,
                    mip_level: 0,
                    origin: wgpu::Origin3d::ZERO,
                    aspect: wgpu::TextureAspect::All,
                },
                bytemuck::cast_slice(&map.depth),
                wgpu::TexelCopyBufferLayout {
                    offset: 0,
                    bytes_per_row: Some(4 * map.size),
                    rows_per_image: Some(map.size),
                },
                size,
            );
            let view = texture.create_view(&wgpu::TextureViewDescriptor::default());
            DepthTexture {
                texture,
                view,
                size: map.size,
            }
        })
    }

    /// Bytes of texel storage.
    pub fn bytes(&self) -> usize {
        self.size as usize * self.size as usize * 4
    }
}

/// Where a view's centre of projection is.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum MapOrigin {
    /// The light centre, fitted with the light's half extent (hard, PCF, PCSS).
    LightCentre,
    /// A point `(x, y)` of the light plane (light-space), fitted as a point light (multi-sample).
    Point(Vec2),
}

/// Layer 0 as a kernel binds it (binding 2), in the stored precision.
#[derive(Debug)]
pub enum MapDepth {
    /// `depth=f32`: the R32Float texture.
    F32(DepthTexture),
    /// `depth=unorm16`: packed 16-bit codes (the f32 render target is dropped after encoding).
    Unorm16(GpuUnorm16Map),
}

impl MapDepth {
    /// The binding of binding 2.
    pub fn binding(&self) -> wgpu::BindingResource<'_> {
        match self {
            MapDepth::F32(t) => wgpu::BindingResource::TextureView(&t.view),
            MapDepth::Unorm16(m) => m.buffer.as_entire_binding(),
        }
    }
    /// The precision.
    pub fn precision(&self) -> DepthPrecision {
        match self {
            MapDepth::F32(_) => DepthPrecision::F32,
            MapDepth::Unorm16(_) => DepthPrecision::Unorm16,
        }
    }
    /// The code step s (`EstimateUniform::depth_step`): 0 for f32.
    pub fn step(&self) -> f32 {
        match self {
            MapDepth::F32(_) => 0.0,
            MapDepth::Unorm16(m) => m.step,
        }
    }
    /// Bytes of storage.
    pub fn bytes(&self) -> usize {
        match self {
            MapDepth::F32(t) => t.bytes(),
            MapDepth::Unorm16(m) => m.bytes(),
        }
    }
    /// A 1x1 empty map of a precision, bound where a kernel reads none.
    pub fn placeholder(ctx: &GpuContext, depth: DepthPrecision) -> Result<Self> {
        let empty = DepthMap::empty(1);
        Ok(match depth {
            DepthPrecision::F32 => MapDepth::F32(DepthTexture::upload(ctx, &empty)?),
            DepthPrecision::Unorm16 => MapDepth::Unorm16(GpuUnorm16Map::upload(
                ctx,
                &Unorm16Map::encode(&empty, 1.0, 2.0),
            )?),
        })
    }
}

/// The light-space data a baseline kernel reads: the view and layer 0 on the GPU.
#[derive(Debug)]
pub struct GpuMaps {
    /// The view the map was rendered with.
    pub view: LightView,
    /// Fit statistics.
    pub fit: FitReport,
    /// Layer 0, the ordinary shadow map, in the stored precision.
    pub depth: MapDepth,
}

impl GpuMaps {
    /// Uploads the view and layer 0 of CPU light-space data (so a test can give the CPU and GPU
    /// twins identical data); under `depth=unorm16` the f32 layer is encoded on the GPU by
    /// `encoder`, as a build does.
    pub fn upload(
        ctx: &GpuContext,
        ls: &LightSpace,
        depth: DepthPrecision,
        encoder: &GpuUnorm16Encoder,
    ) -> Result<Self> {
        let layer0 = ls
            .layers
            .first()
            .filter(|l| !l.depth.is_empty())
            .ok_or_else(|| Error::LightView("light-space data without a depth layer".into()))?;
        let depth = match depth {
            DepthPrecision::F32 => MapDepth::F32(DepthTexture::upload(ctx, layer0)?),
            DepthPrecision::Unorm16 => {
                let g = shadow_map_core::gpu::upload_depth_map(ctx, layer0)?;
                MapDepth::Unorm16(encoder.encode(ctx, &g, ls.view.n, ls.view.far)?)
            }
        };
        Ok(GpuMaps {
            view: ls.view,
            fit: ls.fit,
            depth,
        })
    }

    /// Uploads the view of CPU light-space data and CPU 16-bit codes as they are (tests).
    pub fn upload_unorm16(ctx: &GpuContext, ls: &LightSpace, map: &Unorm16Map) -> Result<Self> {
        Ok(GpuMaps {
            view: ls.view,
            fit: ls.fit,
            depth: MapDepth::Unorm16(GpuUnorm16Map::upload(ctx, map)?),
        })
    }

    /// Bytes held on the GPU (what the report lists as light-space memory).
    pub fn bytes(&self) -> usize {
        self.depth.bytes()
    }
}

/// Fits the view for `origin` on the CPU (a few hundred bytes of arithmetic over the receivers)
/// and rasterises its shadow map on the GPU with the core's [`GpuShadowMapper`] (same fill rule,
/// bias and culling as the CPU rasteriser, except texels straddling a triangle edge): the single
/// place where the GPU baselines obtain light-space data, in `build` (hard, PCF, PCSS) and per
/// sub-light in `estimate` (multi-sample).
pub struct MapBuilder {
    mapper: GpuShadowMapper,
    encoder: std::sync::OnceLock<GpuUnorm16Encoder>,
}

impl MapBuilder {
    /// Compiles the rasteriser's pipelines (the 16-bit encoder on first use).
    pub fn new(ctx: &GpuContext) -> Result<Self> {
        Ok(MapBuilder {
            mapper: GpuShadowMapper::new(ctx)?,
            encoder: std::sync::OnceLock::new(),
        })
    }

    /// The 16-bit encoder, compiled on first use.
    pub fn encoder(&self, ctx: &GpuContext) -> Result<&GpuUnorm16Encoder> {
        if let Some(e) = self.encoder.get() {
            return Ok(e);
        }
        let e = GpuUnorm16Encoder::new(ctx)?;
        Ok(self.encoder.get_or_init(|| e))
    }

    /// Builds the view and layer 0 for `origin` from a scene already uploaded as `gpu_scene`,
    /// stored in precision `depth` (encoded on the GPU; the f32 render target is then dropped).
    #[allow(clippy::too_many_arguments)]
    pub fn build(
        &self,
        ctx: &GpuContext,
        gpu_scene: &GpuScene,
        scene: &Scene,
        receivers: &Receivers,
        origin: MapOrigin,
        req: &LightSpaceRequest,
        opts: &ViewOptions,
        depth: DepthPrecision,
    ) -> Result<GpuMaps> {
        let light = scene.light();
        let (frame, half) = match origin {
            MapOrigin::LightCentre => (light.frame(), light.half_extent()),
            MapOrigin::Point(at) => (
                shadow_map_core::light_space::point_frame(light, at)?,
                Vec2::ZERO,
            ),
        };
        let (view, fit) = LightView::fit_with(scene, receivers, frame, half, req.resolution, opts)?;
        let mut one = *req;
        one.layers = 1;
        one.midpoints = None;
        one.mssm_levels = None;
        one.dual_mssm_levels = None;
        one.pyramid = false;
        let mut gls = self.mapper.render_layers(ctx, gpu_scene, &view, &one)?;
        if gls.layers.is_empty() {
            return Err(Error::LightView(
                "the GPU rasteriser returned no layer".into(),
            ));
        }
        let l0: GpuDepthMap = gls.layers.swap_remove(0);
        let depth = match depth {
            DepthPrecision::F32 => MapDepth::F32(DepthTexture {
                texture: l0.texture,
                view: l0.view,
                size: l0.size,
            }),
            DepthPrecision::Unorm16 => {
                MapDepth::Unorm16(self.encoder(ctx)?.encode(ctx, &l0, view.n, view.far)?)
            }
        };
        Ok(GpuMaps { view, fit, depth })
    }
}
