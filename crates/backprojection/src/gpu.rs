//! wgpu twin of [`CpuBackprojection`] (cargo feature `gpu`, on by default): the same name,
//! description and parameters; light-space data built on the CPU exactly as the CPU twin builds
//! them (layers, midpoints, MSSM), uploaded as R32Float texture arrays, and V from one compute
//! dispatch per chunk of receivers (`backprojection.wgsl`, one invocation per receiver), modelled
//! on the baselines' GPU twins (`baselines::gpu`).
//!
//! The WGSL follows `cpu.rs` and [`crate::math`] step by step in f32. Known differences: the CPU
//! sums the overlap areas in f64, the kernel in Kahan-compensated f32 (about 1e-7 of the light
//! area); the driver may fuse a multiply and an add, which can flip a depth comparison that is a
//! tie to within f32 rounding.
use crate::cpu::CpuBackprojection;
use baselines::gpu::{
    kernel::{max_chunk, shader_source},
    map_estimator::COMMON_WGSL,
    shared::{EstimateUniform, OVERRIDES, SHARED_WGSL as BASELINES_SHARED_WGSL, WORKGROUP_SIZE},
};
use bytemuck::{Pod, Zeroable};
use shadow_map_core::{
    gpu::{
        shared::{pack_receivers, LightViewUniform, SHARED_WGSL},
        GpuContext,
    },
    light_space::LightSpace,
    Backend, Error, Light, LightShape, Params, Receivers, Report, Result, Scene,
    SoftShadowEstimator,
};
use std::{sync::Arc, time::Instant};
use wgpu::util::DeviceExt;

/// The estimator's own WGSL (appended after the parts in [`SHADER_PARTS`]' head).
pub const BACKPROJECTION_WGSL: &str = include_str!("backprojection.wgsl");

/// The WGSL parts of the kernel, in order.
pub const SHADER_PARTS: [&str; 4] = [
    SHARED_WGSL,
    BASELINES_SHARED_WGSL,
    COMMON_WGSL,
    BACKPROJECTION_WGSL,
];

/// The settings the kernel reads besides the light view and the light (mirrored in
/// `backprojection.wgsl`).
#[repr(C, align(16))]
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable)]
pub struct BpUniform {
    /// `Light::half_extent()`.
    pub half: [f32; 2],
    /// Light area `4 hx hy` (computed in f64, rounded to f32).
    pub area: f32,
    /// Constant receiver bias (texel footprints).
    pub b0: f32,
    /// Slope-scaled receiver bias.
    pub b1: f32,
    /// 1: classify by midpoints; 0: by the receiver bias.
    pub midpoint: u32,
    /// 1: gap filling on.
    pub gap_filling: u32,
    /// Most samples per receiver.
    pub max_nspp: u32,
    /// `sqrt(max_nspp)` as the CPU computes it (correctly rounded).
    pub sqrt_nspp: f32,
    /// Depth layers in the layer texture array.
    pub layers: u32,
    /// Midpoint layers, after the depth layers in the same array.
    pub midpoints: u32,
    /// 1 when the light-space data hold an MSSM.
    pub mssm_present: u32,
    /// MSSM levels (array layers of the MSSM texture).
    pub mssm_levels: u32,
    /// MSSM side in texels.
    pub mssm_size: u32,
    /// Padding.
    pub _pad0: u32,
    /// Padding.
    pub _pad1: u32,
}

/// `size x size` R32Float planes in one texture array.
struct PlaneArray {
    _texture: wgpu::Texture,
    view: wgpu::TextureView,
    bytes: usize,
}

fn upload_planes(
    ctx: &GpuContext,
    label: &str,
    size: u32,
    planes: &[&[f32]],
) -> Result<PlaneArray> {
    let l = ctx.limits();
    if size == 0 || size > l.max_texture_dimension_2d {
        return Err(Error::Limit {
            what: "backprojection texture side",
            requested: size as u64,
            max: l.max_texture_dimension_2d as u64,
        });
    }
    if planes.len() as u64 > l.max_texture_array_layers as u64 {
        return Err(Error::Limit {
            what: "backprojection texture array layers",
            requested: planes.len() as u64,
            max: l.max_texture_array_layers as u64,
        });
    }
    let texels = size as usize * size as usize;
    let mut data = Vec::with_capacity(texels * planes.len());
    for p in planes {
        if p.len() != texels {
            return Err(Error::Gpu {
                stage: format!("{label} upload"),
                reason: format!("{} depths for a {size}x{size} plane", p.len()),
            });
        }
        data.extend_from_slice(p);
    }
    ctx.scoped(label, || {
        let extent = wgpu::Extent3d {
            width: size,
            height: size,
            depth_or_array_layers: planes.len() as u32,
        };
        let texture = ctx.device.create_texture(&wgpu::TextureDescriptor {
            label: Some(label),
            size: extent,
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
            bytemuck::cast_slice(&data),
            wgpu::TexelCopyBufferLayout {
                offset: 0,
                bytes_per_row: Some(4 * size),
                rows_per_image: Some(size),
            },
            extent,
        );
        let view = texture.create_view(&wgpu::TextureViewDescriptor {
            dimension: Some(wgpu::TextureViewDimension::D2Array),
            ..Default::default()
        });
        PlaneArray {
            _texture: texture,
            view,
            bytes: data.len() * 4,
        }
    })
}

/// The GPU twin of [`CpuBackprojection`].
pub struct GpuBackprojection {
    ctx: Arc<GpuContext>,
    cpu: CpuBackprojection,
    layout: wgpu::BindGroupLayout,
    pipeline: wgpu::ComputePipeline,
    report: Report,
    chunk_cap: usize,
}

const LABEL: &str = "backprojection estimate";

impl GpuBackprojection {
    /// With default parameters, compiling the kernel on `ctx`'s device.
    pub fn new(ctx: Arc<GpuContext>) -> Result<Self> {
        let src = shader_source(&SHADER_PARTS);
        let module = ctx.scoped(LABEL, || {
            ctx.device
                .create_shader_module(wgpu::ShaderModuleDescriptor {
                    label: Some(LABEL),
                    source: wgpu::ShaderSource::Wgsl(src.into()),
                })
        })?;
        let buffer = |binding, ty| wgpu::BindGroupLayoutEntry {
            binding,
            visibility: wgpu::ShaderStages::COMPUTE,
            ty: wgpu::BindingType::Buffer {
                ty,
                has_dynamic_offset: false,
                min_binding_size: None,
            },
            count: None,
        };
        let texture = |binding| wgpu::BindGroupLayoutEntry {
            binding,
            visibility: wgpu::ShaderStages::COMPUTE,
            ty: wgpu::BindingType::Texture {
                sample_type: wgpu::TextureSampleType::Float { filterable: false },
                view_dimension: wgpu::TextureViewDimension::D2Array,
                multisampled: false,
            },
            count: None,
        };
        let storage = |read_only| wgpu::BufferBindingType::Storage { read_only };
        let (layout, pipeline) = ctx.scoped(LABEL, || {
            let layout = ctx
                .device
                .create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
                    label: Some(LABEL),
                    entries: &[
                        buffer(0, wgpu::BufferBindingType::Uniform),
                        buffer(1, wgpu::BufferBindingType::Uniform),
                        buffer(2, wgpu::BufferBindingType::Uniform),
                        texture(3),
                        texture(4),
                        buffer(5, storage(true)),
                        buffer(6, storage(false)),
                        buffer(7, storage(false)),
                    ],
                });
            let pl = ctx
                .device
                .create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
                    label: Some(LABEL),
                    bind_group_layouts: &[Some(&layout)],
                    immediate_size: 0,
                });
            let pipeline = ctx
                .device
                .create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                    label: Some(LABEL),
                    layout: Some(&pl),
                    module: &module,
                    entry_point: Some("estimate"),
                    compilation_options: wgpu::PipelineCompilationOptions {
                        constants: OVERRIDES,
                        zero_initialize_workgroup_memory: true,
                    },
                    cache: None,
                });
            (layout, pipeline)
        })?;
        Ok(GpuBackprojection {
            ctx,
            cpu: CpuBackprojection::new()?,
            layout,
            pipeline,
            report: Report::default(),
            chunk_cap: usize::MAX,
        })
    }

    /// Caps the receivers per dispatch (tests use small caps to exercise chunking).
    pub fn set_max_chunk(&mut self, receivers: usize) {
        self.chunk_cap = receivers.max(1);
    }

    /// Estimates V from given light-space data (as [`CpuBackprojection`] builds them: layers,
    /// midpoints in midpoint mode, MSSM), so a test can feed both twins identical data.
    /// Replaces the report.
    pub fn estimate_with(
        &mut self,
        ls: &LightSpace,
        light: &Light,
        receivers: &Receivers,
        v: &mut [f32],
    ) -> Result<()> {
        if v.len() != receivers.len() {
            return Err(Error::Receivers(format!(
                "output has {} slots for {} receivers",
                v.len(),
                receivers.len()
            )));
        }
        if !matches!(light.shape, LightShape::Rect { .. }) {
            return Err(Error::param(
                "light",
                "backprojection supports rect lights only",
            ));
        }
        self.report = Report::default();
        let ctx = self.ctx.clone();
        let ctx = &*ctx;
        let p = self.cpu.params();
        let midpoint = p.choice("self_shadow") == "midpoint";
        let t = Instant::now();
        let r = ls.view.r;
        // Layers, then midpoints; a dummy plane keeps the array non-empty.
        let dummy = vec![f32::INFINITY; r as usize * r as usize];
        let mut planes: Vec<&[f32]> = ls.layers.iter().map(|d| d.depth.as_slice()).collect();
        planes.extend(ls.midpoints.iter().map(|d| d.depth.as_slice()));
        if planes.is_empty() {
            planes.push(&dummy);
        }
        let maps = upload_planes(ctx, "backprojection layers", r, &planes)?;
        let one = [f32::INFINITY];
        let (mssm_planes, mssm_size): (Vec<&[f32]>, u32) = match &ls.mssm {
            Some(m) if m.levels() > 0 => {
                ((0..m.levels()).map(|l| m.level(l).0).collect(), m.size())
            }
            _ => (vec![&one[..]], 1),
        };
        let mssm = upload_planes(ctx, "backprojection mssm", mssm_size, &mssm_planes)?;
        self.report
            .stages
            .push(("upload".into(), t.elapsed().as_secs_f64() * 1e3));
        self.report.light_space_bytes = maps.bytes + mssm.bytes;
        let h = light.half_extent();
        let max_nspp = p.int("max_nspp") as u32;
        let bpu = BpUniform {
            half: [h.x, h.y],
            area: (4.0 * h.x as f64 * h.y as f64) as f32,
            b0: p.float("bias") as f32,
            b1: p.float("slope_bias") as f32,
            midpoint: u32::from(midpoint),
            gap_filling: u32::from(p.flag("gap_filling")),
            max_nspp,
            sqrt_nspp: (max_nspp as f32).sqrt(),
            layers: ls.layers.len() as u32,
            midpoints: if midpoint {
                ls.midpoints.len() as u32
            } else {
                0
            },
            mssm_present: u32::from(ls.mssm.is_some()),
            mssm_levels: ls.mssm.as_ref().map_or(0, |m| m.levels()),
            mssm_size: ls.mssm.as_ref().map_or(0, |m| m.size()),
            _pad0: 0,
            _pad1: 0,
        };
        let eu = EstimateUniform::new(light, bpu.b0, bpu.b1);
        let (outside, nonfinite, est_ms, read_ms) =
            self.dispatch(&ls.view, &eu, &bpu, &maps, &mssm, receivers, v)?;
        let view = &ls.view;
        self.report.stages.push(("estimate".into(), est_ms));
        self.report.stages.push(("readback".into(), read_ms));
        self.report.note("resolution", view.r);
        self.report.note("layers", ls.layers.len());
        self.report.note("self_shadow", p.choice("self_shadow"));
        self.report.note("near", view.n);
        self.report.note("far", view.far);
        self.report
            .note("out_of_frustum", outside + ls.fit.out_of_frustum);
        if nonfinite > 0 {
            self.report.note("nonfinite_replaced", nonfinite);
        }
        Ok(())
    }

    #[allow(clippy::too_many_arguments)]
    fn dispatch(
        &self,
        view: &shadow_map_core::LightView,
        eu: &EstimateUniform,
        bpu: &BpUniform,
        maps: &PlaneArray,
        mssm: &PlaneArray,
        receivers: &Receivers,
        v: &mut [f32],
    ) -> Result<(usize, usize, f64, f64)> {
        if receivers.is_empty() {
            return Ok((0, 0, 0.0, 0.0));
        }
        let ctx = &*self.ctx;
        let t = Instant::now();
        let chunk = max_chunk(ctx, self.chunk_cap);
        let packed = pack_receivers(receivers);
        let (outs, counters) = ctx.scoped(LABEL, || {
            let uniform = |label, contents: &[u8]| {
                ctx.device
                    .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                        label: Some(label),
                        contents,
                        usage: wgpu::BufferUsages::UNIFORM,
                    })
            };
            let view_buf = uniform(
                "light view",
                bytemuck::bytes_of(&LightViewUniform::from(view)),
            );
            let est_buf = uniform("estimate uniform", bytemuck::bytes_of(eu));
            let bp_buf = uniform("backprojection uniform", bytemuck::bytes_of(bpu));
            let counters = ctx
                .device
                .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                    label: Some("backprojection counters"),
                    contents: bytemuck::cast_slice(&[0u32; 2]),
                    usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
                });
            let mut enc = ctx
                .device
                .create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some(LABEL) });
            let mut outs = Vec::new();
            {
                let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
                    label: Some(LABEL),
                    timestamp_writes: None,
                });
                pass.set_pipeline(&self.pipeline);
                for (c, part) in packed.chunks(chunk).enumerate() {
                    let rec = ctx
                        .device
                        .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                            label: Some("backprojection receivers"),
                            contents: bytemuck::cast_slice(part),
                            usage: wgpu::BufferUsages::STORAGE,
                        });
                    let out = ctx.device.create_buffer(&wgpu::BufferDescriptor {
                        label: Some("backprojection V"),
                        size: (part.len() * 4) as u64,
                        usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
                        mapped_at_creation: false,
                    });
                    let e = |binding, resource| wgpu::BindGroupEntry { binding, resource };
                    let group = ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
                        label: Some(LABEL),
                        layout: &self.layout,
                        entries: &[
                            e(0, view_buf.as_entire_binding()),
                            e(1, est_buf.as_entire_binding()),
                            e(2, bp_buf.as_entire_binding()),
                            e(3, wgpu::BindingResource::TextureView(&maps.view)),
                            e(4, wgpu::BindingResource::TextureView(&mssm.view)),
                            e(5, rec.as_entire_binding()),
                            e(6, out.as_entire_binding()),
                            e(7, counters.as_entire_binding()),
                        ],
                    });
                    pass.set_bind_group(0, &group, &[]);
                    pass.dispatch_workgroups(
                        part.len().div_ceil(WORKGROUP_SIZE as usize) as u32,
                        1,
                        1,
                    );
                    outs.push((c * chunk, part.len(), out));
                }
            }
            ctx.queue.submit([enc.finish()]);
            (outs, counters)
        })?;
        ctx.wait()?;
        let est_ms = t.elapsed().as_secs_f64() * 1e3;
        let t = Instant::now();
        for (start, len, out) in &outs {
            let part: Vec<f32> = ctx.read_buffer(out, (*len * 4) as u64)?;
            v[*start..*start + *len].copy_from_slice(&part);
        }
        let c: Vec<u32> = ctx.read_buffer(&counters, 8)?;
        Ok((
            c.first().copied().unwrap_or(0) as usize,
            c.get(1).copied().unwrap_or(0) as usize,
            est_ms,
            t.elapsed().as_secs_f64() * 1e3,
        ))
    }
}

impl SoftShadowEstimator for GpuBackprojection {
    fn name(&self) -> &'static str {
        self.cpu.name()
    }
    fn description(&self) -> &'static str {
        self.cpu.description()
    }
    fn backend(&self) -> Backend {
        Backend::Gpu
    }
    fn params(&self) -> &Params {
        self.cpu.params()
    }
    fn set_param(&mut self, key: &str, value: &str) -> Result<()> {
        self.cpu.set_param(key, value)
    }
    /// Builds the light-space data on the CPU, exactly as [`CpuBackprojection`] does.
    fn build(&mut self, scene: &Scene, receivers: &Receivers) -> Result<()> {
        self.cpu.build(scene, receivers)?;
        self.report = self.cpu.report();
        Ok(())
    }
    fn estimate(&mut self, scene: &Scene, receivers: &Receivers, v: &mut [f32]) -> Result<()> {
        let build = self.report.clone();
        let ls = self
            .cpu
            .light_space()
            .cloned()
            .ok_or_else(|| Error::param("build", "estimate called before build"))?;
        let out = self.estimate_with(&ls, &scene.light, receivers, v);
        let mut stages = build.stages;
        stages.append(&mut self.report.stages);
        self.report.stages = stages;
        out
    }
    fn report(&self) -> Report {
        self.report.clone()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shader_validates_with_naga() {
        let src = shader_source(&SHADER_PARTS);
        let module = match naga::front::wgsl::parse_str(&src) {
            Ok(m) => m,
            Err(e) => panic!("{}", e.emit_to_string(&src)),
        };
        let mut v = naga::valid::Validator::new(
            naga::valid::ValidationFlags::all(),
            naga::valid::Capabilities::all(),
        );
        if let Err(e) = v.validate(&module) {
            panic!("{e:?}");
        }
    }

    #[test]
    fn uniform_is_64_bytes() {
        assert_eq!(std::mem::size_of::<BpUniform>(), 64);
    }
}
