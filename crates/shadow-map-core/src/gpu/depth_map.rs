//! Depth maps on the GPU: one `R32Float` texture of linear light-space depths, the twin of
//! [`DepthMap`] (texel (i, j) at texture coordinate (i, j), row j = v; +inf = empty).
//!
//! Textures rather than storage buffers, because the rasteriser renders into them; the same
//! texture is read by later passes with `textureLoad` (R32Float is unfilterable without an
//! optional feature, so nothing here samples it) and written by compute passes as a storage
//! texture (midpoint layers).
use super::GpuContext;
use crate::{raster::DepthMap, Error, Result};

/// Format of every depth map on the GPU.
pub const DEPTH_MAP_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::R32Float;

/// Usages of every depth-map texture: rendered to (peeling), read (`textureLoad`), written by a
/// compute pass (midpoints), and copied in and out.
pub const DEPTH_MAP_USAGE: wgpu::TextureUsages = wgpu::TextureUsages::RENDER_ATTACHMENT
    .union(wgpu::TextureUsages::TEXTURE_BINDING)
    .union(wgpu::TextureUsages::STORAGE_BINDING)
    .union(wgpu::TextureUsages::COPY_SRC)
    .union(wgpu::TextureUsages::COPY_DST);

/// An `r x r` map of linear light-space depths on the GPU (`R32Float`, +inf = empty); the twin
/// of [`DepthMap`].
#[derive(Debug, Clone)]
pub struct GpuDepthMap {
    /// Side in texels.
    pub size: u32,
    /// The texture ([`DEPTH_MAP_FORMAT`], usages [`DEPTH_MAP_USAGE`]).
    pub texture: wgpu::Texture,
    /// A default view of the whole texture.
    pub view: wgpu::TextureView,
}

impl GpuDepthMap {
    /// Allocates an uninitialised map of side `size`, labelled `label`. Fails with
    /// [`Error::Limit`] when `size` is 0 or beyond the device's `max_texture_dimension_2d`.
    pub fn new(ctx: &GpuContext, size: u32, label: &str) -> Result<Self> {
        check_size(ctx, size)?;
        let texture = ctx.device.create_texture(&texture_desc(
            label,
            size,
            size,
            1,
            DEPTH_MAP_FORMAT,
            DEPTH_MAP_USAGE,
        ));
        let view = texture.create_view(&wgpu::TextureViewDescriptor {
            label: Some(label),
            ..Default::default()
        });
        Ok(GpuDepthMap {
            size,
            texture,
            view,
        })
    }

    /// Bytes of texture storage (`size^2 * 4`), as [`DepthMap::bytes`] counts them.
    pub fn bytes(&self) -> usize {
        self.size as usize * self.size as usize * 4
    }
}

/// The descriptor of a 2D texture of `width x height` texels and `layers` array layers, with
/// one mip level, one sample and no extra view formats: every texture the GPU twins create.
pub fn texture_desc(
    label: &str,
    width: u32,
    height: u32,
    layers: u32,
    format: wgpu::TextureFormat,
    usage: wgpu::TextureUsages,
) -> wgpu::TextureDescriptor<'_> {
    wgpu::TextureDescriptor {
        label: Some(label),
        size: wgpu::Extent3d {
            width,
            height,
            depth_or_array_layers: layers,
        },
        mip_level_count: 1,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format,
        usage,
        view_formats: &[],
    }
}

/// The texture size of a square map.
pub(crate) fn extent(size: u32) -> wgpu::Extent3d {
    wgpu::Extent3d {
        width: size,
        height: size,
        depth_or_array_layers: 1,
    }
}

/// Fails with [`Error::Limit`] when a square texture of side `size` cannot be created.
pub(crate) fn check_size(ctx: &GpuContext, size: u32) -> Result<()> {
    Error::check_in_range(
        "shadow-map resolution (GPU max_texture_dimension_2d)",
        size,
        ctx.limits().max_texture_dimension_2d,
    )
}

/// The [`Error::Gpu`] of the upload `stage` given `len` `what` (depths, codes) for a square map
/// of side `size`.
pub(crate) fn upload_len_error(stage: &str, what: &str, len: usize, size: u32) -> Error {
    Error::Gpu {
        stage: stage.into(),
        reason: format!("{len} {what} for a {size}x{size} map"),
    }
}

/// Writes `layers` planes of f32 texels (each `size x size`, row-major, one after the other in
/// `texels`) into the first array layers of the R32Float `texture`, bit for bit.
pub fn write_planes(
    ctx: &GpuContext,
    texture: &wgpu::Texture,
    size: u32,
    layers: u32,
    texels: &[f32],
) {
    ctx.queue.write_texture(
        texture.as_image_copy(),
        bytemuck::cast_slice(texels),
        wgpu::TexelCopyBufferLayout {
            offset: 0,
            bytes_per_row: Some(size * 4),
            rows_per_image: Some(size),
        },
        wgpu::Extent3d {
            depth_or_array_layers: layers,
            ..extent(size)
        },
    );
}

/// Uploads a CPU depth map (bit for bit). Fails with [`Error::Limit`] when its side is 0 or
/// beyond `max_texture_dimension_2d`, and with [`Error::Gpu`] when `depth.len() != size^2`.
pub fn upload_depth_map(ctx: &GpuContext, map: &DepthMap) -> Result<GpuDepthMap> {
    let n = map.size as usize * map.size as usize;
    if map.depth.len() != n {
        return Err(upload_len_error(
            "depth-map upload",
            "depths",
            map.depth.len(),
            map.size,
        ));
    }
    ctx.scoped("depth-map upload", || -> Result<GpuDepthMap> {
        let gpu = GpuDepthMap::new(ctx, map.size, "depth-map upload")?;
        write_planes(ctx, &gpu.texture, map.size, 1, &map.depth);
        Ok(gpu)
    })?
}

/// Largest staging buffer one readback chunk uses (bytes).
const READBACK_CHUNK_BYTES: u64 = 64 << 20;

/// Reads a depth map back (bit for bit), through [`read_texture_words`].
pub fn read_depth_map(ctx: &GpuContext, map: &GpuDepthMap) -> Result<DepthMap> {
    let depth = read_texture_words(ctx, &map.texture)?
        .into_iter()
        .map(f32::from_bits)
        .collect();
    Ok(DepthMap {
        size: map.size,
        depth,
    })
}

/// The texels of a texture with 4-byte texels (`R32Float`, `Rgba8Unorm`, ...; layer 0, mip 0;
/// `COPY_SRC` usage), row by row from the top, bit for bit: a readback and a wait, for tests and
/// tools. The texture is copied to a staging buffer whose rows are padded to
/// `COPY_BYTES_PER_ROW_ALIGNMENT` (256 bytes), in chunks of rows so no staging buffer exceeds
/// 64 MiB or `max_buffer_size`, and the padding is dropped. [`Error::Gpu`] for another texel
/// size.
pub fn read_texture_words(ctx: &GpuContext, texture: &wgpu::Texture) -> Result<Vec<u32>> {
    if texture.format().block_copy_size(None) != Some(4) {
        return Err(Error::Gpu {
            stage: "texture readback".into(),
            reason: format!("{:?} has no 4-byte texels", texture.format()),
        });
    }
    let (width, height) = (texture.width(), texture.height());
    let row_bytes = width as u64 * 4;
    let align = wgpu::COPY_BYTES_PER_ROW_ALIGNMENT as u64;
    let padded = row_bytes.div_ceil(align) * align;
    let cap = READBACK_CHUNK_BYTES.min(ctx.limits().max_buffer_size);
    let rows_per_chunk = (cap / padded).clamp(1, height.max(1) as u64) as u32;
    let mut words = Vec::with_capacity(width as usize * height as usize);
    let mut row0 = 0u32;
    while row0 < height {
        let rows = rows_per_chunk.min(height - row0);
        let bytes = padded * rows as u64;
        let staging = ctx.scoped("texture readback", || {
            let staging = ctx.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("texture readback"),
                size: bytes,
                usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::COPY_SRC,
                mapped_at_creation: false,
            });
            let mut enc = ctx
                .device
                .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                    label: Some("texture readback"),
                });
            enc.copy_texture_to_buffer(
                wgpu::TexelCopyTextureInfo {
                    texture,
                    mip_level: 0,
                    origin: wgpu::Origin3d {
                        x: 0,
                        y: row0,
                        z: 0,
                    },
                    aspect: wgpu::TextureAspect::All,
                },
                wgpu::TexelCopyBufferInfo {
                    buffer: &staging,
                    layout: wgpu::TexelCopyBufferLayout {
                        offset: 0,
                        bytes_per_row: Some(padded as u32),
                        rows_per_image: Some(rows),
                    },
                },
                wgpu::Extent3d {
                    width,
                    height: rows,
                    depth_or_array_layers: 1,
                },
            );
            ctx.queue.submit([enc.finish()]);
            staging
        })?;
        let data: Vec<u32> = ctx.read_buffer(&staging, bytes)?;
        let stride = (padded / 4) as usize;
        for r in 0..rows as usize {
            words.extend_from_slice(&data[r * stride..r * stride + width as usize]);
        }
        row0 += rows;
    }
    Ok(words)
}
