//! Receivers from the caller's depth texture, normal texture and camera matrices: a renderer
//! that already has a depth
//! prepass and a normal target records [`GpuDepthReceivers::encode`] into its frame, then passes
//! the receiver buffer it wrote to any estimator's `encode`
//! ([`FrameInputs::receivers`](super::frame::FrameInputs)). One compute pass, no readback, no
//! CPU work that grows with the pixels.
//!
//! Per pixel (i, j) (row 0 at the top), receiver `j * width + i`: the pixel centre's clip
//! position `(ndc_x, ndc_y, depth)` with `ndc_x = (i + 0.5) / width * 2 - 1` and
//! `ndc_y = 1 - (j + 0.5) / height * 2` (the contract's [`Camera::ray_dir`] convention), carried
//! to world by the inverse view-projection; the stored normal decoded ([`NormalEncoding`]),
//! normalised and turned to face the eye (the contract's receiver normal). The background (depth
//! at the far end of its [`DepthConvention`]), a non-finite position or a zero normal gives an
//! inactive slot (origin, normal +Z, as the core's G-buffer writes one).
//!
//! The receivers are as exact as the depth: a 32-bit float depth places a receiver within a few
//! ulps of `d` along its ray, which moves it off its surface by about `1e-7 z^2 / near` under a
//! standard projection (reverse Z keeps that error nearly constant in z). `tests/depth_receivers.rs`
//! measures it against the ray-traced G-buffer.
use super::{
    depth_map::texture_desc,
    kernel::{Kernel, SpecializedKernel},
    shared::{ReceiverGpu, SHARED_WGSL},
    GpuContext,
};
use crate::{Camera, Error, Result};
use bytemuck::{Pod, Zeroable};
use glam::{Mat4, Vec3};

/// The pass's own WGSL (after [`SHARED_WGSL`]).
pub const DEPTH_RECEIVERS_WGSL: &str = include_str!("depth_receivers.wgsl");
/// The whole module as the pass compiles it (and [`super::SHADERS`] validates it).
pub const DEPTH_RECEIVERS_SOURCE: &str = concat!(
    include_str!("shared.wgsl"),
    include_str!("depth_receivers.wgsl")
);

/// Workgroup side of the pass (`@workgroup_size(8, 8)` in the WGSL).
const TILE: u32 = 8;

/// How the caller's depth texture stores depth (NDC z).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DepthConvention {
    /// 0 at the near plane, 1 at the far plane and the background (wgpu's default).
    ZeroToOne,
    /// 1 at the near plane, 0 at the far plane (or infinity) and the background (Bevy's, most
    /// engines').
    ReverseZ,
}

/// How the caller's normal texture stores a world-space normal.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum NormalEncoding {
    /// `xyz` as is (a float target).
    Signed,
    /// `xyz * 0.5 + 0.5` (an unorm target such as Bevy's normal prepass, `Rgb10a2Unorm`).
    Unorm,
}

/// The camera of one frame as the pass needs it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DepthCamera {
    /// World to clip (the projection the depth texture was rendered with, times the view).
    pub view_proj: Mat4,
    /// The eye in world space (normals are turned to face it).
    pub eye: Vec3,
    /// Texture size in pixels (both textures, and receivers written).
    pub width: u32,
    /// Texture height.
    pub height: u32,
    /// How depth is stored.
    pub depth: DepthConvention,
    /// How normals are stored.
    pub normals: NormalEncoding,
}

impl DepthCamera {
    /// The contract's pinhole `camera` ([`Camera::ray_dir`]: pixel centres, row 0 at the top)
    /// as a right-handed perspective projection with near plane `near` and far plane `far`
    /// (`far = f32::INFINITY` allowed under [`DepthConvention::ReverseZ`]). Errors
    /// ([`Error::Receivers`]): a degenerate camera (eye at the target, up along the view) or
    /// `0 < near < far` not holding.
    pub fn perspective(
        camera: &Camera,
        near: f32,
        far: f32,
        depth: DepthConvention,
        normals: NormalEncoding,
    ) -> Result<DepthCamera> {
        let b = camera.basis();
        if !(b.forward.is_finite() && b.right.is_finite()) {
            return Err(Error::Receivers(format!(
                "depth receivers: degenerate camera (eye {}, target {}, up {})",
                camera.eye, camera.target, camera.up
            )));
        }
        if !(near > 0.0 && far > near) || near.is_infinite() {
            return Err(Error::Receivers(format!(
                "depth receivers: near {near} and far {far} must satisfy 0 < near < far"
            )));
        }
        if far.is_infinite() && depth == DepthConvention::ZeroToOne {
            return Err(Error::Receivers(
                "depth receivers: an infinite far plane needs reverse Z".into(),
            ));
        }
        if !(camera.fov_y_deg > 0.0 && camera.fov_y_deg < 180.0)
            || camera.width == 0
            || camera.height == 0
        {
            return Err(Error::Receivers(format!(
                "depth receivers: field of view {} degrees (must be in (0, 180)) or image \
                 {}x{} (must not be empty)",
                camera.fov_y_deg, camera.width, camera.height
            )));
        }
        use glam::camera::rh::{proj::directx, view::look_at_mat4};
        let aspect = camera.width as f32 / camera.height as f32;
        let fov = camera.fov_y_deg.to_radians();
        // NDC z in [0, 1], y up: wgpu's clip space.
        let proj = match (depth, far.is_infinite()) {
            (DepthConvention::ZeroToOne, _) => directx::perspective(fov, aspect, near, far),
            (DepthConvention::ReverseZ, true) => {
                directx::perspective_infinite_reverse(fov, aspect, near)
            }
            // Reverse Z with a far plane: the standard projection with near and far swapped.
            (DepthConvention::ReverseZ, false) => directx::perspective(fov, aspect, far, near),
        };
        let view = look_at_mat4(camera.eye, camera.target, camera.up);
        Ok(DepthCamera {
            view_proj: proj * view,
            eye: camera.eye,
            width: camera.width,
            height: camera.height,
            depth,
            normals,
        })
    }
}

/// The pass's uniform; mirrors `DepthReceiversParams` in `depth_receivers.wgsl`.
#[repr(C, align(16))]
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable)]
pub struct DepthReceiversParams {
    /// Clip to world.
    pub inv_view_proj: [[f32; 4]; 4],
    /// The eye.
    pub eye: [f32; 3],
    /// 1 under [`DepthConvention::ReverseZ`].
    pub reverse_z: u32,
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// 1 under [`NormalEncoding::Unorm`].
    pub unorm_normals: u32,
    /// Padding.
    pub _pad0: u32,
}

impl DepthReceiversParams {
    /// The uniform of `camera`; [`Error::Receivers`] when its view-projection is not invertible
    /// or not finite.
    pub fn new(camera: &DepthCamera) -> Result<Self> {
        let inv = camera.view_proj.inverse();
        if !(camera.view_proj.is_finite() && inv.is_finite())
            || camera.view_proj.determinant() == 0.0
        {
            return Err(Error::Receivers(
                "depth receivers: the view-projection matrix is singular or not finite".into(),
            ));
        }
        Ok(DepthReceiversParams {
            inv_view_proj: inv.to_cols_array_2d(),
            eye: camera.eye.to_array(),
            reverse_z: u32::from(camera.depth == DepthConvention::ReverseZ),
            width: camera.width,
            height: camera.height,
            unorm_normals: u32::from(camera.normals == NormalEncoding::Unorm),
            _pad0: 0,
        })
    }
}

/// The pass, prepared once per context ([`new`](Self::new)); [`encode`](Self::encode) per frame.
#[derive(Debug)]
pub struct GpuDepthReceivers {
    kernel: Kernel,
    uniform: wgpu::Buffer,
}

impl GpuDepthReceivers {
    /// Compiles the pass and allocates its uniform.
    pub fn new(ctx: &GpuContext) -> Result<Self> {
        let kernel = SpecializedKernel::new(
            ctx,
            "depth receivers",
            &[SHARED_WGSL, DEPTH_RECEIVERS_WGSL],
            "depth_receivers",
            &[],
        )?
        .fixed(ctx)?;
        let uniform = super::kernel::uniform_buffer(
            ctx,
            "depth receivers.params",
            std::mem::size_of::<DepthReceiversParams>() as u64,
        );
        Ok(GpuDepthReceivers { kernel, uniform })
    }

    /// Writes `camera` in the encoder's order ([`GpuContext::write_in`]) and records the pass
    /// writing `camera.width * camera.height` receivers into `out` (`STORAGE`, at least
    /// `32 * width * height` bytes) from `depth` (a `texture_depth_2d` view: `Depth32Float`, or
    /// the depth aspect of a depth-stencil texture) and `normals` (an unfilterable-float view:
    /// `Rgba16Float`, `Rgba32Float`, `Rgb10a2Unorm`, ...), both `width` x `height`. Errors before
    /// anything is recorded ([`Error::Receivers`], [`Error::Limit`]): textures of another size,
    /// a buffer too small or beyond the device's storage-binding limit, a singular camera.
    pub fn encode(
        &self,
        ctx: &GpuContext,
        enc: &mut wgpu::CommandEncoder,
        camera: &DepthCamera,
        depth: &wgpu::Texture,
        normals: &wgpu::Texture,
        out: &wgpu::Buffer,
    ) -> Result<()> {
        ctx.check_lost()?;
        let params = DepthReceiversParams::new(camera)?;
        let (w, h) = (camera.width, camera.height);
        for (what, t) in [("depth", depth), ("normal", normals)] {
            if t.width() != w || t.height() != h {
                return Err(Error::Receivers(format!(
                    "depth receivers: the {what} texture is {}x{}, the camera {w}x{h}",
                    t.width(),
                    t.height()
                )));
            }
        }
        let bytes = std::mem::size_of::<ReceiverGpu>() as u64 * w as u64 * h as u64;
        if out.size() < bytes {
            return Err(Error::Receivers(format!(
                "depth receivers: the receiver buffer holds {} bytes, {w}x{h} receivers need {bytes}",
                out.size()
            )));
        }
        let max = ctx.limits().max_storage_buffer_binding_size;
        if bytes > max {
            return Err(Error::Limit {
                what: "depth receivers' storage binding (bytes)",
                requested: bytes,
                max,
            });
        }
        if w == 0 || h == 0 {
            return Ok(());
        }
        ctx.write_in(enc, &self.uniform, 0, bytemuck::bytes_of(&params));
        let depth_view = depth.create_view(&wgpu::TextureViewDescriptor {
            aspect: wgpu::TextureAspect::DepthOnly,
            ..Default::default()
        });
        let normal_view = normals.create_view(&Default::default());
        let group = self.kernel.bind_group(
            ctx,
            "depth receivers",
            &[
                self.uniform.as_entire_binding(),
                wgpu::BindingResource::TextureView(&depth_view),
                wgpu::BindingResource::TextureView(&normal_view),
                wgpu::BindingResource::Buffer(wgpu::BufferBinding {
                    buffer: out,
                    offset: 0,
                    size: std::num::NonZeroU64::new(bytes),
                }),
            ],
        );
        let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("depth receivers"),
            timestamp_writes: None,
        });
        pass.set_pipeline(&self.kernel.pipeline);
        pass.set_bind_group(0, &group, &[]);
        pass.dispatch_workgroups(w.div_ceil(TILE), h.div_ceil(TILE), 1);
        Ok(())
    }
}

/// A `Depth32Float` texture (`RENDER_ATTACHMENT | TEXTURE_BINDING`) holding `depth` per pixel
/// (row-major, row 0 at the top), written by a full-screen pass (a depth texture takes no
/// `write_texture`): for a caller whose depth comes from elsewhere (a CPU G-buffer, a file), and
/// for tests of [`GpuDepthReceivers`]. Submits and returns without waiting. Errors: `depth` not
/// `w * h` long or not finite in [0, 1] ([`Error::Receivers`]), an empty size.
pub fn depth_texture(ctx: &GpuContext, w: u32, h: u32, depth: &[f32]) -> Result<wgpu::Texture> {
    use wgpu::util::DeviceExt;
    if depth.len() as u64 != w as u64 * h as u64 || w == 0 || h == 0 {
        return Err(Error::Receivers(format!(
            "depth texture: {} depths for {w}x{h} pixels",
            depth.len()
        )));
    }
    if let Some(k) = depth.iter().position(|d| !(0.0..=1.0).contains(d)) {
        return Err(Error::Receivers(format!(
            "depth texture: depth {} at pixel {k} is outside [0, 1]",
            depth[k]
        )));
    }
    ctx.check_lost()?;
    let src = "
        @group(0) @binding(0) var<storage, read> d: array<f32>;
        @group(0) @binding(1) var<uniform> width: vec4<u32>;
        @vertex fn vs(@builtin(vertex_index) i: u32) -> @builtin(position) vec4<f32> {
            let x = f32(i32(i & 1u) * 4 - 1);
            let y = f32(i32(i >> 1u) * 4 - 1);
            return vec4<f32>(x, y, 0.0, 1.0);
        }
        @fragment fn fs(@builtin(position) p: vec4<f32>) -> @builtin(frag_depth) f32 {
            return d[u32(p.y) * width.x + u32(p.x)];
        }";
    let dev = &ctx.device;
    let module = dev.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some("test depth writer"),
        source: wgpu::ShaderSource::Wgsl(src.into()),
    });
    let tex = dev.create_texture(&texture_desc(
        "caller's depth",
        w,
        h,
        1,
        wgpu::TextureFormat::Depth32Float,
        wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::TEXTURE_BINDING,
    ));
    let pipeline = dev.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
        label: Some("test depth writer"),
        layout: None,
        vertex: wgpu::VertexState {
            module: &module,
            entry_point: Some("vs"),
            compilation_options: Default::default(),
            buffers: &[],
        },
        primitive: Default::default(),
        depth_stencil: Some(wgpu::DepthStencilState {
            format: wgpu::TextureFormat::Depth32Float,
            depth_write_enabled: Some(true),
            depth_compare: Some(wgpu::CompareFunction::Always),
            stencil: Default::default(),
            bias: Default::default(),
        }),
        multisample: Default::default(),
        fragment: Some(wgpu::FragmentState {
            module: &module,
            entry_point: Some("fs"),
            compilation_options: Default::default(),
            targets: &[],
        }),
        multiview_mask: None,
        cache: None,
    });
    let dbuf = dev.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: None,
        contents: bytemuck::cast_slice(depth),
        usage: wgpu::BufferUsages::STORAGE,
    });
    let wbuf = dev.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: None,
        contents: bytemuck::cast_slice(&[w, 0, 0, 0]),
        usage: wgpu::BufferUsages::UNIFORM,
    });
    let group = dev.create_bind_group(&wgpu::BindGroupDescriptor {
        label: None,
        layout: &pipeline.get_bind_group_layout(0),
        entries: &[
            wgpu::BindGroupEntry {
                binding: 0,
                resource: dbuf.as_entire_binding(),
            },
            wgpu::BindGroupEntry {
                binding: 1,
                resource: wbuf.as_entire_binding(),
            },
        ],
    });
    let view = tex.create_view(&Default::default());
    let mut enc = dev.create_command_encoder(&Default::default());
    {
        let mut pass = enc.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: None,
            color_attachments: &[],
            depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                view: &view,
                depth_ops: Some(wgpu::Operations {
                    load: wgpu::LoadOp::Clear(0.5),
                    store: wgpu::StoreOp::Store,
                }),
                stencil_ops: None,
            }),
            timestamp_writes: None,
            occlusion_query_set: None,
            multiview_mask: None,
        });
        pass.set_pipeline(&pipeline);
        pass.set_bind_group(0, &group, &[]);
        pass.draw(0..3, 0..1);
    }
    ctx.queue.submit([enc.finish()]);
    Ok(tex)
}

/// A normal texture (`TEXTURE_BINDING`) holding `normals` per pixel (row-major, row 0 at the
/// top), stored as `encoding` says: `Rgba32Float` for [`NormalEncoding::Signed`],
/// `Rgb10a2Unorm` holding `n * 0.5 + 0.5` for [`NormalEncoding::Unorm`] (Bevy's normal prepass):
/// the companion of [`depth_texture`]. Errors: `normals` not `w * h` long, an empty size
/// ([`Error::Receivers`]).
pub fn normal_texture(
    ctx: &GpuContext,
    w: u32,
    h: u32,
    normals: &[Vec3],
    encoding: NormalEncoding,
) -> Result<wgpu::Texture> {
    use wgpu::util::DeviceExt;
    if normals.len() as u64 != w as u64 * h as u64 || w == 0 || h == 0 {
        return Err(Error::Receivers(format!(
            "normal texture: {} normals for {w}x{h} pixels",
            normals.len()
        )));
    }
    ctx.check_lost()?;
    let (format, bytes): (_, Vec<u8>) = match encoding {
        NormalEncoding::Unorm => {
            let q = |x: f32| ((x * 0.5 + 0.5).clamp(0.0, 1.0) * 1023.0).round() as u32;
            let words: Vec<u32> = normals
                .iter()
                .map(|v| q(v.x) | (q(v.y) << 10) | (q(v.z) << 20) | (3 << 30))
                .collect();
            (
                wgpu::TextureFormat::Rgb10a2Unorm,
                bytemuck::cast_slice(&words).to_vec(),
            )
        }
        NormalEncoding::Signed => {
            let f: Vec<[f32; 4]> = normals.iter().map(|v| v.extend(0.0).to_array()).collect();
            (
                wgpu::TextureFormat::Rgba32Float,
                bytemuck::cast_slice(&f).to_vec(),
            )
        }
    };
    Ok(ctx.device.create_texture_with_data(
        &ctx.queue,
        &texture_desc(
            "caller's normals",
            w,
            h,
            1,
            format,
            wgpu::TextureUsages::TEXTURE_BINDING,
        ),
        Default::default(),
        &bytes,
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn params_layout_matches_wgsl() {
        test_support::assert_wgsl_layout!(
            DEPTH_RECEIVERS_SOURCE,
            DepthReceiversParams {
                inv_view_proj,
                eye,
                reverse_z,
                width,
                height,
                unorm_normals,
                _pad0
            }
        );
    }

    #[test]
    fn perspective_refuses_bad_planes() {
        let cam = Camera {
            eye: Vec3::new(0.0, 1.0, 3.0),
            target: Vec3::ZERO,
            up: Vec3::Y,
            fov_y_deg: 45.0,
            width: 4,
            height: 3,
        };
        use DepthConvention::*;
        let n = NormalEncoding::Signed;
        assert!(DepthCamera::perspective(&cam, 0.1, 10.0, ZeroToOne, n).is_ok());
        assert!(DepthCamera::perspective(&cam, 0.1, f32::INFINITY, ReverseZ, n).is_ok());
        for (near, far, d) in [
            (0.0, 10.0, ZeroToOne),
            (1.0, 0.5, ZeroToOne),
            (0.1, f32::INFINITY, ZeroToOne),
            (f32::NAN, 1.0, ReverseZ),
        ] {
            let e = DepthCamera::perspective(&cam, near, far, d, n).unwrap_err();
            assert!(e.to_string().contains("depth receivers"), "{e}");
        }
        let mut bad = cam;
        bad.target = bad.eye;
        assert!(DepthCamera::perspective(&bad, 0.1, 10.0, ZeroToOne, n).is_err());
    }
}
