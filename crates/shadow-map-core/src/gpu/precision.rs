//! 16-bit shadow maps on the GPU (`precision.wgsl`), the twin of [`crate::precision`]: an R32Float
//! map is encoded into a storage buffer of packed codes (two per `u32`), bit for bit the CPU's
//! [`Unorm16Map`] codes for the same f32 depths. Kernels read a code with
//!
//! ```text
//! let q = (codes[k >> 1u] >> ((k & 1u) * 16u)) & 0xffffu;   // k = j * size + i
//! depth = select(n + f32(q) * s, +inf, q == 0xffffu);
//! ```
use super::{
    depth_map::{upload_len_error, GpuDepthMap},
    kernel::{buffer_init, uniform_buffer, Kernel, SpecializedKernel},
    GpuContext,
};
use crate::{
    precision::{step_for, Unorm16Map},
    Error, Result,
};
use bytemuck::{Pod, Zeroable};

/// WGSL source of the encoder.
pub const PRECISION_WGSL: &str = include_str!("precision.wgsl");
/// Workgroup size of the encoder (override `WG`).
pub const ENCODE_WORKGROUP: u32 = 64;

/// Uniform of the encoder; mirrors `EncodeParams` in `precision.wgsl`.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable)]
pub struct EncodeParams {
    /// Map side.
    pub size: u32,
    /// Near plane n.
    pub near: f32,
    /// `1 / s`, exact (s is a power of two).
    pub inv_step: f32,
    /// Padding.
    pub _pad0: u32,
}

/// A map of 16-bit codes on the GPU: `ceil(size^2 / 2)` packed `u32`s in a storage buffer.
#[derive(Debug, Clone)]
pub struct GpuUnorm16Map {
    /// Side in texels.
    pub size: u32,
    /// The near plane n (code 0).
    pub near: f32,
    /// The code step s.
    pub step: f32,
    /// The packed codes (`STORAGE | COPY_SRC | COPY_DST`).
    pub buffer: wgpu::Buffer,
}

impl GpuUnorm16Map {
    /// Bytes of the packed codes (2 per texel, rounded up to a whole `u32`).
    pub fn bytes(&self) -> usize {
        words(self.size) as usize * 4
    }

    /// Uploads CPU codes (for tests that give both twins identical data).
    pub fn upload(ctx: &GpuContext, map: &Unorm16Map) -> Result<Self> {
        let texels = map.size as usize * map.size as usize;
        if map.codes.len() != texels || texels == 0 {
            return Err(upload_len_error(
                "unorm16 upload",
                "codes",
                map.codes.len(),
                map.size,
            ));
        }
        check_buffer(ctx, map.size)?;
        let mut packed = vec![0u32; words(map.size) as usize];
        for (k, &q) in map.codes.iter().enumerate() {
            packed[k / 2] |= (q as u32) << (16 * (k % 2));
        }
        if texels % 2 == 1 {
            *packed.last_mut().expect("non-empty") |= 0xffff << 16;
        }
        ctx.scoped("unorm16 upload", || GpuUnorm16Map {
            size: map.size,
            near: map.near,
            step: map.step,
            buffer: buffer_init(
                &ctx.device,
                "unorm16 depth map",
                bytemuck::cast_slice(&packed),
                USAGE,
            ),
        })
    }

    /// Reads the codes back (tests).
    pub fn read(&self, ctx: &GpuContext) -> Result<Unorm16Map> {
        let packed: Vec<u32> = ctx.read_buffer(&self.buffer, self.bytes() as u64)?;
        let texels = self.size as usize * self.size as usize;
        let codes = (0..texels)
            .map(|k| ((packed[k / 2] >> (16 * (k % 2))) & 0xffff) as u16)
            .collect();
        Ok(Unorm16Map {
            size: self.size,
            near: self.near,
            step: self.step,
            codes,
        })
    }
}

const USAGE: wgpu::BufferUsages = wgpu::BufferUsages::STORAGE
    .union(wgpu::BufferUsages::COPY_SRC)
    .union(wgpu::BufferUsages::COPY_DST);

fn words(size: u32) -> u64 {
    (size as u64 * size as u64).div_ceil(2).max(1)
}

fn check_buffer(ctx: &GpuContext, size: u32) -> Result<()> {
    let l = ctx.limits();
    let max = l.max_storage_buffer_binding_size.min(l.max_buffer_size);
    let need = words(size) * 4;
    if need > max {
        return Err(Error::Limit {
            what:
                "16-bit shadow-map bytes in one storage binding (max_storage_buffer_binding_size)",
            requested: need,
            max,
        });
    }
    Ok(())
}

/// The encoder pipeline, created once per estimator.
#[derive(Debug, Clone)]
pub struct GpuUnorm16Encoder {
    kernel: Kernel,
}

impl GpuUnorm16Encoder {
    /// Compiles the pipeline (label `unorm16 encode`).
    pub fn new(ctx: &GpuContext) -> Result<Self> {
        let kernel = SpecializedKernel::new(
            ctx,
            "unorm16 encode",
            &[PRECISION_WGSL],
            "encode_unorm16",
            &[("WG", ENCODE_WORKGROUP as f64)],
        )?
        .fixed(ctx)?;
        Ok(GpuUnorm16Encoder { kernel })
    }

    /// Encodes `map` for a view with planes `n` and `far` into a new code buffer (submitted and
    /// finished before it returns, so the f32 map can be dropped).
    pub fn encode(
        &self,
        ctx: &GpuContext,
        map: &GpuDepthMap,
        n: f32,
        far: f32,
    ) -> Result<GpuUnorm16Map> {
        check_buffer(ctx, map.size)?;
        let step = step_for(n, far);
        let out = ctx.scoped("unorm16 encode", || {
            let device = &ctx.device;
            let buffer = code_buffer(ctx, map.size);
            let params = buffer_init(
                device,
                "unorm16 encode",
                bytemuck::bytes_of(&encode_params(map.size, n, step)),
                wgpu::BufferUsages::UNIFORM,
            );
            let group = self.group(ctx, &params, map, &buffer);
            let mut enc = device.create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("unorm16 encode"),
            });
            self.record(ctx, &mut enc, &group, map.size);
            ctx.queue.submit([enc.finish()]);
            GpuUnorm16Map {
                size: map.size,
                near: n,
                step,
                buffer,
            }
        })?;
        ctx.wait()?;
        Ok(out)
    }

    /// The bind group of one encoding: `params`, the f32 `map`, the `codes` written.
    fn group(
        &self,
        ctx: &GpuContext,
        params: &wgpu::Buffer,
        map: &GpuDepthMap,
        codes: &wgpu::Buffer,
    ) -> wgpu::BindGroup {
        self.kernel.bind_group(
            ctx,
            "unorm16 encode",
            &[
                params.as_entire_binding(),
                wgpu::BindingResource::TextureView(&map.view),
                codes.as_entire_binding(),
            ],
        )
    }

    /// Records the encoding pass of a `size`-texel map with bind group `group` into `enc`.
    fn record(
        &self,
        ctx: &GpuContext,
        enc: &mut wgpu::CommandEncoder,
        group: &wgpu::BindGroup,
        size: u32,
    ) {
        let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("unorm16 encode"),
            timestamp_writes: None,
        });
        pass.set_pipeline(&self.kernel.pipeline);
        pass.set_bind_group(0, group, &[]);
        let groups = words(size).div_ceil(ENCODE_WORKGROUP as u64);
        let max = (ctx.limits().max_compute_workgroups_per_dimension as u64).max(1);
        // Rows of at most `max` workgroups; the shader folds (x, y) back into one index.
        let x = groups.min(max);
        pass.dispatch_workgroups(x as u32, groups.div_ceil(x) as u32, 1);
    }
}

/// The encoder's uniform for a `size`-texel map over `[n, n + 65534 step]`.
fn encode_params(size: u32, n: f32, step: f32) -> EncodeParams {
    EncodeParams {
        size,
        near: n,
        inv_step: 1.0 / step,
        _pad0: 0,
    }
}

/// A code buffer for a `size`-texel map.
fn code_buffer(ctx: &GpuContext, size: u32) -> wgpu::Buffer {
    ctx.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("unorm16 depth map"),
        size: words(size) * 4,
        usage: USAGE,
        mapped_at_creation: false,
    })
}

/// 16-bit encoding on the engine path: the codes of one f32 layer, recorded into the
/// caller's command encoder after each raster of that layer. Allocated once: one code buffer
/// (each encoding overwrites it, so a kernel reads it before the next raster into the layer)
/// and one encoder uniform per view slot.
#[derive(Debug)]
pub struct GpuUnorm16Frame {
    encoder: GpuUnorm16Encoder,
    size: u32,
    codes: wgpu::Buffer,
    /// Per slot: the encoder uniform and its bind group.
    slots: Vec<(wgpu::Buffer, wgpu::BindGroup)>,
}

impl GpuUnorm16Frame {
    /// The encoder compiled and its buffers allocated for `layer` (the frame's f32 map) and
    /// `slots` views per frame. [`Error::Limit`] where the codes exceed a storage binding.
    pub fn new(ctx: &GpuContext, layer: &GpuDepthMap, slots: usize) -> Result<Self> {
        check_buffer(ctx, layer.size)?;
        let encoder = GpuUnorm16Encoder::new(ctx)?;
        ctx.scoped("unorm16 frame", || {
            let codes = code_buffer(ctx, layer.size);
            let slots = (0..slots.max(1))
                .map(|_| {
                    let params = uniform_buffer(
                        ctx,
                        "unorm16 frame params",
                        std::mem::size_of::<EncodeParams>() as u64,
                    );
                    let group = encoder.group(ctx, &params, layer, &codes);
                    (params, group)
                })
                .collect();
            GpuUnorm16Frame {
                encoder,
                size: layer.size,
                codes,
                slots,
            }
        })
    }

    /// Stages slot `slot`'s uniform for planes `n` and `far` and records the encoding of the
    /// layer into `enc`; returns the code step s (`EstimateUniform::depth_step`). Nothing is
    /// submitted or waited for.
    pub fn encode(
        &self,
        ctx: &GpuContext,
        enc: &mut wgpu::CommandEncoder,
        slot: usize,
        n: f32,
        far: f32,
    ) -> Result<f32> {
        let Some((params, group)) = self.slots.get(slot) else {
            return Err(Error::Limit {
                what: "view slot of a frame's 16-bit map",
                requested: slot as u64,
                max: self.slots.len().saturating_sub(1) as u64,
            });
        };
        let step = step_for(n, far);
        ctx.write_in(
            enc,
            params,
            0,
            bytemuck::bytes_of(&encode_params(self.size, n, step)),
        );
        self.encoder.record(ctx, enc, group, self.size);
        Ok(step)
    }

    /// The packed codes, for a kernel's `depth_codes` binding.
    pub fn binding(&self) -> wgpu::BindingResource<'_> {
        self.codes.as_entire_binding()
    }

    /// Bytes of the packed codes.
    pub fn bytes(&self) -> usize {
        words(self.size) as usize * 4
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn encode_params_match_the_wgsl() {
        test_support::assert_wgsl_layout!(
            PRECISION_WGSL,
            EncodeParams {
                size,
                near,
                inv_step,
                _pad0,
            }
        );
    }
}
