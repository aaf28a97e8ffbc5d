//! The camera G-buffer on the GPU (`gbuffer.wgsl`), the twin of [`Receivers::from_camera`]: one
//! receiver per pixel of the contract's camera, in image layout (receiver `j * width + i` is
//! pixel (i, j), row 0 at the top), with view depth and the triangle seen.
//!
//! **Rasterisation.** The scene's triangles ([`GpuScene`], reused as is) are drawn as one
//! instance of three vertices each: the vertex buffer is read with a 48-byte *instance* stride,
//! so every vertex sees its triangle's three corners and computes the face normal
//! `cross(v1 - v0, v2 - v0)` exactly as [`crate::SceneBvh::normal`] does (no primitive-index
//! feature, no extra per-triangle buffer). Culling is off: both sides of every triangle are seen.
//!
//! **Projection.** View coordinates `x = (p - eye)·right`, `y = (p - eye)·true_up`,
//! `z = (p - eye)·forward` and `clip = (x / (t aspect), y / t, near, z)`, `t = tan(fov_y / 2)`:
//! NDC `(x / (z t aspect), y / (z t))` is the contract's `(ndc_x, ndc_y)` of the ray through `p`,
//! and wgpu's framebuffer row 0 is NDC y = +1, so framebuffer pixel (i, j) is contract pixel
//! (i, j) and the rasteriser (one sample, at the pixel centre) covers it when the contract's ray
//! through its centre crosses the triangle, up to the rasteriser's vertex snapping (1/256 pixel on
//! lavapipe and NVIDIA) and its tie rule: only pixels whose centre lies on or within about 1/256
//! pixel of a projected edge can differ from the CPU's ray casts (`tests/gpu_gbuffer.rs` measures
//! it).
//!
//! **Exact values.** The fragment shader does not interpolate: it casts the contract's ray through
//! its pixel centre (`ray_dir`, the CPU's [`crate::Camera::ray_dir`] in the same order of
//! operations, with `t` and `aspect` computed on the CPU exactly as there) and intersects the
//! triangle's plane, so position `eye + d t`, view depth `Z = t (d·forward)` and the normal
//! (flipped to face the camera when `n·d > 0`) are the CPU's up to f32 rounding.
//!
//! **Depth test: reversed Z with an infinite far plane.** Depth is `near / Z` (clear 0, compare
//! `Greater`), written by the fragment from the exact ray-plane `Z` rather than interpolated, so
//! the nearest surface at the pixel centre wins as on the CPU (which matters where surfaces meet,
//! e.g. an object standing on the ground). Reversed Z because the camera has no far plane and the
//! [`GpuScene`] carries no bounds: `near / Z` in f32 has the same relative precision (2^-24) at
//! every distance, needs no far plane at all, and lets `near` be tiny. `near` is
//! [`NEAR_REL`] times `|target - eye|`; the CPU casts rays from `t = 0`, so only geometry closer
//! than that to the eye plane (clipped here) can differ.
//!
//! **Resolve.** The render targets are `Rgba32Float` (unit normal, ray distance `t`) and
//! `R32Uint` (triangle index, cleared to [`NO_TRIANGLE`]). A compute pass writes one
//! [`ReceiverGpu`] per pixel (the storage buffer of a [`GpuReceivers`]), the view depth `Z` (`f32`,
//! +inf for background) and the triangle index (`u32`, [`NO_TRIANGLE`] for background).
//! Background receivers are inactive, at the origin with normal +Z, as [`Receivers::from_camera`]
//! writes them.
//!
//! **Big images.** The three outputs are single buffers, limited by `max_buffer_size` (and the
//! image by `max_texture_dimension_2d`): beyond those, [`Error::Limit`]. The resolve binds them a
//! chunk of pixels at a time, each chunk within `max_storage_buffer_binding_size` (or the cap of
//! [`GpuGBuffer::set_max_binding_bytes`]) and at offsets aligned to
//! `min_storage_buffer_offset_alignment`, so images larger than one storage binding are chunked,
//! not refused.
use super::{
    depth_map::texture_desc,
    kernel::{buffer_init, wgsl_module, Binding},
    raster::{begin_depth_tested_pass, nearest_surface_test, GpuScene, DEPTH_TEST_FORMAT},
    receivers::{GpuReceivers, RECEIVER_BYTES},
    shared::{FrameGpu, ReceiverGpu},
    GpuContext,
};
use crate::{
    camera::Camera,
    receivers::{ImageLayout, Receivers},
    Error, Result,
};
use bytemuck::{Pod, Zeroable};
use glam::Vec3;
use std::num::NonZeroU64;

/// WGSL source of the G-buffer: `shared.wgsl` followed by `gbuffer.wgsl`.
pub const GBUFFER_WGSL: &str = concat!(include_str!("shared.wgsl"), include_str!("gbuffer.wgsl"));

/// `near = NEAR_REL * |target - eye|`: the near clip distance of the G-buffer projection.
pub const NEAR_REL: f32 = 1e-5;

/// Triangle index of a background pixel in [`GpuGBufferImage::triangles`].
pub const NO_TRIANGLE: u32 = u32::MAX;

/// Threads per workgroup of the resolve pass (`RESOLVE_WG` in `gbuffer.wgsl`).
pub const RESOLVE_WORKGROUP: u32 = 64;

/// Format of the (normal, ray distance) render target.
pub const NORMAL_T_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba32Float;

/// Format of the triangle-index render target.
pub const TRIANGLE_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::R32Uint;

/// The camera as the G-buffer shaders see it; mirrors `GBufferCamera` in `gbuffer.wgsl`.
///
/// The camera's basis is a [`FrameGpu`] mapped as: `origin` = eye, `ex` = right,
/// `ey` = true up, `ez` = forward, so view coordinates are
/// `((p - origin)·ex, (p - origin)·ey, (p - origin)·ez)`.
#[repr(C, align(16))]
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable)]
pub struct GBufferCamera {
    /// The eye and the basis: `origin` = eye, `ex` = right, `ey` = true up, `ez` = forward.
    pub frame: FrameGpu,
    /// `tan(fov_y / 2)`, computed as [`Camera::ray_dir`] computes it.
    pub t: f32,
    /// `width / height`, computed as [`Camera::ray_dir`] computes it.
    pub aspect: f32,
    /// Near clip distance along `forward` ([`NEAR_REL`] times `|target - eye|`).
    pub near: f32,
    /// Image width in pixels.
    pub width: f32,
    /// Image height in pixels.
    pub height: f32,
    /// Padding.
    pub _pad0: f32,
    /// Padding.
    pub _pad1: f32,
    /// Padding.
    pub _pad2: f32,
}

impl GBufferCamera {
    /// The uniform of `camera`. Fails with [`Error::Receivers`] when the camera's basis or
    /// field of view is degenerate (eye at the target, up parallel to the view direction, zero
    /// image size, fov outside (0, 180) degrees).
    pub fn new(camera: &Camera) -> Result<Self> {
        let b = camera.basis();
        let t = (camera.fov_y_deg.to_radians() * 0.5).tan();
        let aspect = camera.width as f32 / camera.height as f32;
        let near = NEAR_REL * (camera.target - camera.eye).length();
        let finite = |v: Vec3| v.is_finite() && v != Vec3::ZERO;
        if camera.width == 0 || camera.height == 0 {
            return Err(Error::Receivers(format!(
                "the camera image is {}x{} pixels",
                camera.width, camera.height
            )));
        }
        let basis_ok =
            finite(b.forward) && finite(b.right) && finite(b.true_up) && camera.eye.is_finite();
        let projection_ok = t > 0.0 && t.is_finite() && near > 0.0 && near.is_finite();
        if !(basis_ok && projection_ok) {
            return Err(Error::Receivers(format!(
                "degenerate camera (eye {}, target {}, up {}, fov_y {} degrees)",
                camera.eye, camera.target, camera.up, camera.fov_y_deg
            )));
        }
        Ok(GBufferCamera {
            frame: FrameGpu::new(camera.eye, b.right, b.true_up, b.forward),
            t,
            aspect,
            near,
            width: camera.width as f32,
            height: camera.height as f32,
            _pad0: 0.0,
            _pad1: 0.0,
            _pad2: 0.0,
        })
    }
}

/// Uniform of one resolve dispatch (pixels `first .. first + count`); mirrors `ResolveParams` in
/// `gbuffer.wgsl`.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable)]
pub struct ResolveParams {
    /// Image width.
    pub width: u32,
    /// First pixel of the chunk (`j * width + i`).
    pub first: u32,
    /// Pixels in the chunk.
    pub count: u32,
    /// View depth written for background pixels (+inf).
    pub background_z: f32,
}

/// A rendered G-buffer on the GPU. The buffers hold their values once the work submitted by
/// [`GpuGBuffer::render`] has run (any later submission or [`GpuContext::wait`] orders after it).
#[derive(Debug, Clone)]
pub struct GpuGBufferImage {
    /// One [`ReceiverGpu`] per pixel, receiver `j * width + i` is pixel (i, j) (usages
    /// `STORAGE | COPY_SRC | COPY_DST`): pass it to any GPU estimator.
    pub receivers: GpuReceivers,
    /// View depth `Z` per pixel (`f32`, +inf for background; usages `STORAGE | COPY_SRC`).
    pub depth: wgpu::Buffer,
    /// Index into [`crate::Scene::triangles`] of the triangle seen per pixel (`u32`,
    /// [`NO_TRIANGLE`] for background; usages `STORAGE | COPY_SRC`).
    pub triangles: wgpu::Buffer,
    /// The image size.
    pub layout: ImageLayout,
}

impl GpuGBufferImage {
    /// Number of pixels.
    pub fn pixels(&self) -> u32 {
        self.receivers.count
    }

    /// Reads the G-buffer back as [`Receivers`] with image layout and view depth, the form
    /// [`Receivers::from_camera`] produces (waits for the GPU).
    pub fn read_back(&self, ctx: &GpuContext) -> Result<Receivers> {
        read_back(ctx, &self.receivers, &self.depth, self.layout)
    }

    /// Reads back the triangle index per pixel ([`NO_TRIANGLE`] for background).
    pub fn read_triangles(&self, ctx: &GpuContext) -> Result<Vec<u32>> {
        ctx.read_buffer(&self.triangles, self.pixels() as u64 * 4)
    }
}

/// Reads G-buffer receivers and their view-depth buffer (`f32` per receiver) back as
/// [`Receivers`] with image `layout` (whose pixel count must equal `receivers.count`) and
/// `view_depth`. Inactive slots keep the GPU's background values (origin, normal +Z).
pub fn read_back(
    ctx: &GpuContext,
    receivers: &GpuReceivers,
    depth: &wgpu::Buffer,
    layout: ImageLayout,
) -> Result<Receivers> {
    let n = layout.width as u64 * layout.height as u64;
    if n != receivers.count as u64 {
        return Err(Error::Receivers(format!(
            "layout {}x{} does not match {} receivers",
            layout.width, layout.height, receivers.count
        )));
    }
    if depth.size() < n * 4 || !depth.usage().contains(wgpu::BufferUsages::COPY_SRC) {
        return Err(Error::Receivers(format!(
            "the view-depth buffer needs COPY_SRC and {} bytes (it has {})",
            n * 4,
            depth.size()
        )));
    }
    let packed: Vec<ReceiverGpu> = receivers.read(ctx)?;
    let z: Vec<f32> = if n == 0 {
        Vec::new()
    } else {
        ctx.read_buffer(depth, n * 4)?
    };
    Receivers::from_gbuffer(
        packed
            .iter()
            .map(|p| Vec3::from_array(p.position))
            .collect(),
        packed.iter().map(|p| Vec3::from_array(p.normal)).collect(),
        packed.iter().map(|p| p.active != 0).collect(),
        Some(z),
        Some(layout),
    )
}

/// The G-buffer pipelines of one context (the render pipeline and the resolve compute pipeline,
/// created once by [`GpuGBuffer::new`]).
#[derive(Debug)]
pub struct GpuGBuffer {
    raster_layout: wgpu::BindGroupLayout,
    raster: wgpu::RenderPipeline,
    resolve_layout: wgpu::BindGroupLayout,
    resolve: wgpu::ComputePipeline,
    max_binding_bytes: Option<u64>,
}

/// A sampled-texture layout entry of the resolve pass.
fn texture_entry(binding: u32, sample_type: wgpu::TextureSampleType) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility: wgpu::ShaderStages::COMPUTE,
        ty: wgpu::BindingType::Texture {
            sample_type,
            view_dimension: wgpu::TextureViewDimension::D2,
            multisampled: false,
        },
        count: None,
    }
}

/// A binding of `bytes` bytes of `buffer` from `offset`.
fn range(buffer: &wgpu::Buffer, offset: u64, bytes: u64) -> wgpu::BindingResource<'_> {
    wgpu::BindingResource::Buffer(wgpu::BufferBinding {
        buffer,
        offset,
        size: NonZeroU64::new(bytes.max(4)),
    })
}

impl GpuGBuffer {
    /// Compiles the shader and creates the render and resolve pipelines (label `gbuffer`).
    pub fn new(ctx: &GpuContext) -> Result<Self> {
        ctx.scoped("gbuffer", || {
            let device = &ctx.device;
            let module = wgsl_module(device, "gbuffer", GBUFFER_WGSL);
            let raster_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
                label: Some("gbuffer.raster"),
                entries: &[Binding::Uniform.entry_in(0, wgpu::ShaderStages::VERTEX_FRAGMENT)],
            });
            let raster_pl = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
                label: Some("gbuffer.raster"),
                bind_group_layouts: &[Some(&raster_layout)],
                immediate_size: 0,
            });
            let corner = |k: u32| wgpu::VertexAttribute {
                format: wgpu::VertexFormat::Float32x4,
                offset: 16 * k as u64,
                shader_location: k,
            };
            let raster = device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
                label: Some("gbuffer.raster"),
                layout: Some(&raster_pl),
                vertex: wgpu::VertexState {
                    module: &module,
                    entry_point: Some("vs_main"),
                    compilation_options: Default::default(),
                    // GpuScene's vertices, one triangle (three vec4 corners) per instance.
                    buffers: &[Some(wgpu::VertexBufferLayout {
                        array_stride: 48,
                        step_mode: wgpu::VertexStepMode::Instance,
                        attributes: &[corner(0), corner(1), corner(2)],
                    })],
                },
                primitive: wgpu::PrimitiveState {
                    topology: wgpu::PrimitiveTopology::TriangleList,
                    front_face: wgpu::FrontFace::Ccw,
                    cull_mode: None,
                    ..Default::default()
                },
                depth_stencil: Some(nearest_surface_test()),
                multisample: Default::default(),
                fragment: Some(wgpu::FragmentState {
                    module: &module,
                    entry_point: Some("fs_main"),
                    compilation_options: Default::default(),
                    targets: &[
                        Some(wgpu::ColorTargetState {
                            format: NORMAL_T_FORMAT,
                            blend: None,
                            write_mask: wgpu::ColorWrites::ALL,
                        }),
                        Some(wgpu::ColorTargetState {
                            format: TRIANGLE_FORMAT,
                            blend: None,
                            write_mask: wgpu::ColorWrites::ALL,
                        }),
                    ],
                }),
                multiview_mask: None,
                cache: None,
            });
            let resolve_layout =
                device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
                    label: Some("gbuffer.resolve"),
                    entries: &[
                        Binding::Uniform.entry(0),
                        Binding::Uniform.entry(1),
                        texture_entry(2, wgpu::TextureSampleType::Float { filterable: false }),
                        texture_entry(3, wgpu::TextureSampleType::Uint),
                        Binding::StorageRw.entry(4),
                        Binding::StorageRw.entry(5),
                        Binding::StorageRw.entry(6),
                    ],
                });
            let resolve_pl = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
                label: Some("gbuffer.resolve"),
                bind_group_layouts: &[Some(&resolve_layout)],
                immediate_size: 0,
            });
            let resolve = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                label: Some("gbuffer.resolve"),
                layout: Some(&resolve_pl),
                module: &module,
                entry_point: Some("resolve_main"),
                compilation_options: Default::default(),
                cache: None,
            });
            GpuGBuffer {
                raster_layout,
                raster,
                resolve_layout,
                resolve,
                max_binding_bytes: None,
            }
        })
    }

    /// Caps the storage-binding size the resolve plans its chunks against (the device's
    /// `max_storage_buffer_binding_size` still applies); `None` restores the device limit. A test
    /// knob: a tiny cap forces chunked resolves on any device.
    pub fn set_max_binding_bytes(&mut self, bytes: Option<u64>) {
        self.max_binding_bytes = bytes;
    }

    /// The storage-binding size chunks are planned against.
    pub fn binding_limit(&self, ctx: &GpuContext) -> u64 {
        let device = ctx.limits().max_storage_buffer_binding_size;
        self.max_binding_bytes.map_or(device, |b| b.min(device))
    }

    /// The pixel ranges the resolve binds one at a time: each within [`GpuGBuffer::binding_limit`]
    /// bytes of receivers, starting at pixels whose offsets in all three output buffers are
    /// multiples of `min_storage_buffer_offset_alignment`. One range for an empty image.
    pub fn chunks(&self, ctx: &GpuContext, pixels: u32) -> Vec<std::ops::Range<u32>> {
        let align = ctx.limits().min_storage_buffer_offset_alignment.max(1) as u64;
        // Offsets are k * 4 (depth, triangles) and k * 32 (receivers): k a multiple of `unit`.
        let unit = align / gcd(align, 4);
        let per = ((self.binding_limit(ctx) / RECEIVER_BYTES) / unit * unit).max(unit);
        let mut out = Vec::new();
        let mut first = 0u64;
        loop {
            let end = (first + per).min(pixels as u64);
            out.push(first as u32..end as u32);
            if end >= pixels as u64 {
                break;
            }
            first = end;
        }
        out
    }

    /// Renders the G-buffer of `camera` over `scene` and resolves it into buffers (one command
    /// encoder, submitted; nothing waits: read with [`GpuGBufferImage::read_back`] or bind
    /// [`GpuGBufferImage::receivers`] in later GPU work).
    ///
    /// Errors: [`Error::Receivers`] for a degenerate camera (see [`GBufferCamera::new`]);
    /// [`Error::Limit`] when the image is beyond `max_texture_dimension_2d` on a side, beyond
    /// `u32::MAX` pixels, or its receiver buffer beyond `max_buffer_size`; GPU validation and
    /// out-of-memory errors as [`Error::Gpu`] / [`Error::OutOfMemory`] (stage `gbuffer`).
    pub fn render(
        &self,
        ctx: &GpuContext,
        scene: &GpuScene,
        camera: &Camera,
    ) -> Result<GpuGBufferImage> {
        let uniform = GBufferCamera::new(camera)?;
        let limits = ctx.limits();
        let (w, h) = (camera.width, camera.height);
        let pixels = check_image_size(&limits, w, h)?;
        let chunks = self.chunks(ctx, pixels as u32);
        let max_groups = limits.max_compute_workgroups_per_dimension.max(1) as u64;
        ctx.scoped("gbuffer", || {
            let device = &ctx.device;
            let cam = buffer_init(
                device,
                "gbuffer.camera",
                bytemuck::bytes_of(&uniform),
                wgpu::BufferUsages::UNIFORM,
            );
            let res = RenderResources::new(device, w, h, pixels);

            let mut enc = device.create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("gbuffer"),
            });
            self.encode_raster(device, &mut enc, scene, &cam, &res);
            let groups = self.resolve_groups(device, &chunks, w, &cam, &res, max_groups);
            self.encode_resolve(&mut enc, &groups);
            ctx.queue.submit([enc.finish()]);
            GpuGBufferImage {
                receivers: GpuReceivers {
                    buffer: res.receivers,
                    count: pixels as u32,
                },
                depth: res.depth,
                triangles: res.triangles,
                layout: ImageLayout {
                    width: w,
                    height: h,
                },
            }
        })
    }

    /// Records the raster pass: clears the targets and draws every triangle of `scene` into them.
    fn encode_raster(
        &self,
        device: &wgpu::Device,
        enc: &mut wgpu::CommandEncoder,
        scene: &GpuScene,
        cam: &wgpu::Buffer,
        res: &RenderResources,
    ) {
        let (normal_t, triangle, depth_test) = (&res.normal_t, &res.triangle, &res.depth_test);
        let group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("gbuffer.raster"),
            layout: &self.raster_layout,
            entries: &[wgpu::BindGroupEntry {
                binding: 0,
                resource: cam.as_entire_binding(),
            }],
        });
        let background = wgpu::Color {
            r: 0.0,
            g: 0.0,
            b: 1.0,
            a: f64::INFINITY,
        };
        let no_triangle = wgpu::Color {
            r: NO_TRIANGLE as f64,
            g: 0.0,
            b: 0.0,
            a: 0.0,
        };
        let mut pass = begin_depth_tested_pass(
            enc,
            "gbuffer.raster",
            &[(normal_t, background), (triangle, no_triangle)],
            depth_test,
        );
        if scene.triangles > 0 {
            pass.set_pipeline(&self.raster);
            pass.set_bind_group(0, &group, &[]);
            pass.set_vertex_buffer(0, scene.vertices.slice(..scene.triangles as u64 * 48));
            pass.draw(0..3, 0..scene.triangles);
        }
    }

    /// One resolve bind group per pixel chunk, with its workgroup grid.
    fn resolve_groups(
        &self,
        device: &wgpu::Device,
        chunks: &[std::ops::Range<u32>],
        w: u32,
        cam: &wgpu::Buffer,
        res: &RenderResources,
        max_groups: u64,
    ) -> Vec<(wgpu::BindGroup, (u32, u32))> {
        let (normal_t, triangle) = (&res.normal_t, &res.triangle);
        let (receivers, depth, triangles) = (&res.receivers, &res.depth, &res.triangles);
        chunks
            .iter()
            .map(|c| {
                let count = c.end - c.start;
                let params = buffer_init(
                    device,
                    "gbuffer.resolve",
                    bytemuck::bytes_of(&ResolveParams {
                        width: w,
                        first: c.start,
                        count,
                        background_z: f32::INFINITY,
                    }),
                    wgpu::BufferUsages::UNIFORM,
                );
                let first = c.start as u64;
                let n = count as u64;
                let group = device.create_bind_group(&wgpu::BindGroupDescriptor {
                    label: Some("gbuffer.resolve"),
                    layout: &self.resolve_layout,
                    entries: &[
                        wgpu::BindGroupEntry {
                            binding: 0,
                            resource: cam.as_entire_binding(),
                        },
                        wgpu::BindGroupEntry {
                            binding: 1,
                            resource: params.as_entire_binding(),
                        },
                        wgpu::BindGroupEntry {
                            binding: 2,
                            resource: wgpu::BindingResource::TextureView(normal_t),
                        },
                        wgpu::BindGroupEntry {
                            binding: 3,
                            resource: wgpu::BindingResource::TextureView(triangle),
                        },
                        wgpu::BindGroupEntry {
                            binding: 4,
                            resource: range(receivers, first * RECEIVER_BYTES, n * RECEIVER_BYTES),
                        },
                        wgpu::BindGroupEntry {
                            binding: 5,
                            resource: range(depth, first * 4, n * 4),
                        },
                        wgpu::BindGroupEntry {
                            binding: 6,
                            resource: range(triangles, first * 4, n * 4),
                        },
                    ],
                });
                let wg = n.div_ceil(RESOLVE_WORKGROUP as u64);
                let gx = wg.clamp(1, max_groups);
                let gy = wg.div_ceil(gx).max(1);
                (group, (gx as u32, gy as u32))
            })
            .collect()
    }

    /// Records the resolve pass: one dispatch per chunk's bind group.
    fn encode_resolve(
        &self,
        enc: &mut wgpu::CommandEncoder,
        groups: &[(wgpu::BindGroup, (u32, u32))],
    ) {
        let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("gbuffer.resolve"),
            timestamp_writes: None,
        });
        pass.set_pipeline(&self.resolve);
        for (group, (gx, gy)) in groups {
            pass.set_bind_group(0, group, &[]);
            pass.dispatch_workgroups(*gx, *gy, 1);
        }
    }
}

/// Checks a `w x h` G-buffer against the device's texture side and buffer size limits; returns
/// its pixel count.
fn check_image_size(limits: &wgpu::Limits, w: u32, h: u32) -> Result<u64> {
    let max_side = limits.max_texture_dimension_2d;
    if w.max(h) > max_side {
        return Err(Error::Limit {
            what: "G-buffer image side (max_texture_dimension_2d)",
            requested: w.max(h) as u64,
            max: max_side as u64,
        });
    }
    let pixels = w as u64 * h as u64;
    let max_pixels = (limits.max_buffer_size / RECEIVER_BYTES).min(u32::MAX as u64);
    if pixels > max_pixels {
        return Err(Error::Limit {
            what: "G-buffer pixels (max_buffer_size / 32 bytes)",
            requested: pixels,
            max: max_pixels,
        });
    }
    Ok(pixels)
}

/// The render targets and output buffers of one [`GpuGBuffer::render`].
struct RenderResources {
    /// Unit normal and ray distance t (`Rgba32Float`).
    normal_t: wgpu::TextureView,
    /// Triangle index (`R32Uint`).
    triangle: wgpu::TextureView,
    /// The reversed-Z depth test attachment.
    depth_test: wgpu::TextureView,
    /// One [`ReceiverGpu`] per pixel.
    receivers: wgpu::Buffer,
    /// View depth per pixel.
    depth: wgpu::Buffer,
    /// Triangle index per pixel.
    triangles: wgpu::Buffer,
}

impl RenderResources {
    /// Creates the three `w x h` render targets, then the three output buffers of `pixels`.
    fn new(device: &wgpu::Device, w: u32, h: u32, pixels: u64) -> Self {
        let target = |label, format, usage| {
            device
                .create_texture(&texture_desc(label, w, h, 1, format, usage))
                .create_view(&Default::default())
        };
        let sampled = wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::TEXTURE_BINDING;
        let normal_t = target("gbuffer.normal_t", NORMAL_T_FORMAT, sampled);
        let triangle = target("gbuffer.triangle", TRIANGLE_FORMAT, sampled);
        let depth_test = target(
            "gbuffer.depth_test",
            DEPTH_TEST_FORMAT,
            wgpu::TextureUsages::RENDER_ATTACHMENT,
        );
        let out_buffer = |label, bytes: u64, usage| {
            device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: bytes.max(RECEIVER_BYTES),
                usage,
                mapped_at_creation: false,
            })
        };
        let storage = wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC;
        let receivers = out_buffer(
            "gbuffer.receivers",
            pixels * RECEIVER_BYTES,
            storage | wgpu::BufferUsages::COPY_DST,
        );
        let depth = out_buffer("gbuffer.depth", pixels * 4, storage);
        let triangles = out_buffer("gbuffer.triangles", pixels * 4, storage);
        RenderResources {
            normal_t,
            triangle,
            depth_test,
            receivers,
            depth,
            triangles,
        }
    }
}

fn gcd(a: u64, b: u64) -> u64 {
    if b == 0 {
        a
    } else {
        gcd(b, a % b)
    }
}
