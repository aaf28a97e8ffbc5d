//! Light-space data on the GPU for one view: the fitted [`LightView`] and its shadow map (layer 0)
//! as an R32Float texture, and [`MapBuilder`], the one place the maps are made.
use glam::Vec2;
use shadow_map_core::light_view::ViewOptions;
use shadow_map_core::{
    gpu::{GpuContext, GpuScene, GpuShadowMapper},
    light_space::{LightSpace, LightSpaceRequest},
    light_view::{FitReport, LightView},
    DepthMap, Error, Receivers, Result, Scene,
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
                what: "shadow-map texture side",
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
                usage: wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
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

/// The light-space data a baseline kernel reads: the view and layer 0 on the GPU.
#[derive(Debug)]
pub struct GpuMaps {
    /// The view the map was rendered with.
    pub view: LightView,
    /// Fit statistics.
    pub fit: FitReport,
    /// Layer 0, the ordinary shadow map.
    pub depth: DepthTexture,
}

impl GpuMaps {
    /// Uploads the view and layer 0 of CPU light-space data (so a test can give the CPU and GPU
    /// twins identical data).
    pub fn upload(ctx: &GpuContext, ls: &LightSpace) -> Result<Self> {
        let layer0 = ls
            .layers
            .first()
            .ok_or_else(|| Error::LightView("light-space data without a depth layer".into()))?;
        Ok(GpuMaps {
            view: ls.view,
            fit: ls.fit,
            depth: DepthTexture::upload(ctx, layer0)?,
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
}

impl MapBuilder {
    /// Compiles the rasteriser's pipelines on first use.
    pub fn new(ctx: &GpuContext) -> Result<Self> {
        Ok(MapBuilder {
            mapper: GpuShadowMapper::new(ctx)?,
        })
    }

    /// Builds the view and layer 0 for `origin` from a scene already uploaded as `gpu_scene`.
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
    ) -> Result<GpuMaps> {
        let light = &scene.light;
        let mut frame = light.frame();
        let half = match origin {
            MapOrigin::LightCentre => light.half_extent(),
            MapOrigin::Point(at) => {
                frame.origin = frame.to_world(at.extend(0.0));
                Vec2::ZERO
            }
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
        let l0 = gls.layers.swap_remove(0);
        Ok(GpuMaps {
            view,
            fit,
            depth: DepthTexture {
                texture: l0.texture,
                view: l0.view,
                size: l0.size,
            },
        })
    }
}
