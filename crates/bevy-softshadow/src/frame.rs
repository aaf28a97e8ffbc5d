//! The per-view pass (a `Core3d` system after the prepass, before the main pass): the frame API
//! recorded into Bevy's command encoder for each camera with a depth and a normal
//! prepass. Per frame it records, in order:
//! 1. receivers from the view's prepass ([`GpuDepthReceivers`]: Bevy's reverse-Z `Depth32Float`
//!    depth and `Rgb10a2Unorm` world-space normals);
//! 2. casters from Bevy's own mesh buffers ([`GpuCasterBuilder`]: the mesh allocator's slabs,
//!    which the plugin gives `STORAGE` usage, and each instance's world transform);
//! 3. the estimator's frame ([`FrameEstimator::encode`]) in light views fitted to the casters'
//!    world box ([`bounds_stand_in`]: CPU work independent of triangles and pixels, redone only
//!    when the light or the box moves);
//! 4. V into the view-sized `R32Float` texture ([`ViewFrame::v_texture`]).
//!
//! Nothing waits: the only readback is the frame's status words (a few bytes, mapped when the
//! device is done, [`StatusReadback`]), whose warnings (receivers left NaN, outside every view,
//! non-finite V) are logged once per kind and kept in [`ViewFrame::status`]. Errors (a missing
//! prepass, a light the method does
//! not model, device limits) are kept per view ([`ViewFrame::error`]) and printed once.
use crate::{
    extract::{ExtractedCasters, ExtractedSoftLight},
    Method, SoftShadowSettings,
};
use bevy::{
    core_pipeline::prepass::ViewPrepassTextures,
    mesh::{Mesh, PrimitiveTopology},
    platform::collections::HashMap,
    prelude::*,
    render::{
        mesh::{allocator::MeshAllocator, RenderMesh, RenderMeshBufferInfo},
        render_asset::RenderAssets,
        renderer::{RenderContext, RenderQueue, ViewQuery},
        view::ExtractedView,
    },
};
use shadow_map_core::{
    gpu::{
        casters::{CasterIndices, CasterInstance, CasterMesh, GpuCasterBuilder},
        depth_map,
        depth_receivers::{DepthCamera, DepthConvention, GpuDepthReceivers, NormalEncoding},
        frame::{FrameEstimator, FrameInputs, FrameStatus, StatusReadback},
        GpuContext, GpuScene,
    },
    light_view::bounds_stand_in,
    scene::Aabb,
    Camera, Light, LightView,
};
use std::sync::Arc;

/// What every view shares: the device as the core sees it, and the plugin's own pipelines.
pub struct Shared {
    /// Bevy's device and queue ([`GpuContext::from_device`]: Bevy keeps its device-lost callback).
    pub ctx: Arc<GpuContext>,
    v_pipeline: wgpu::ComputePipeline,
    pub(crate) composite: crate::composite::CompositePipelines,
}

impl Shared {
    fn new(device: wgpu::Device, queue: wgpu::Queue) -> Shared {
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("softshadow V texture"),
            source: wgpu::ShaderSource::Wgsl(include_str!("v_texture.wgsl").into()),
        });
        let v_pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some("softshadow V texture"),
            layout: None,
            module: &module,
            entry_point: Some("main"),
            compilation_options: Default::default(),
            cache: None,
        });
        let composite = crate::composite::CompositePipelines::new(&device);
        Shared {
            ctx: Arc::new(GpuContext::from_device(device, queue)),
            v_pipeline,
            composite,
        }
    }
}

/// The render world's state: the shared pipelines and one [`ViewFrame`] per view.
#[derive(Resource, Default)]
pub struct SoftShadowViews {
    /// Made on the first frame with a soft-shadowed light.
    pub shared: Option<Shared>,
    /// Per view entity (the render world's).
    pub views: HashMap<Entity, ViewFrame>,
}

/// What identifies a view's prepared frame: made again when any of these changes.
#[derive(Debug, Clone, Copy, PartialEq)]
struct FrameKey {
    method: Method,
    resolution: Option<u32>,
    width: u32,
    height: u32,
}

/// One view's frame: the estimator prepared for its size, the buffers it reads and writes, and
/// what the last frame used (the headless example reads these back once, at the end).
pub struct ViewFrame {
    key: FrameKey,
    /// The estimator's engine path.
    pub frame: Box<dyn FrameEstimator>,
    /// The receivers (`ReceiverGpu`, 32 bytes each, row by row from the top), from the prepass.
    pub receivers: wgpu::Buffer,
    /// V per receiver (f32; NaN for background pixels).
    pub v: wgpu::Buffer,
    /// V as a view-sized `R32Float` texture (`TEXTURE_BINDING | STORAGE_BINDING | COPY_SRC`),
    /// for a material or the composite pass.
    pub v_texture: wgpu::Texture,
    pub(crate) v_view: wgpu::TextureView,
    size_uniform: wgpu::Buffer,
    pub(crate) composite_uniform: wgpu::Buffer,
    prepass: GpuDepthReceivers,
    builder: GpuCasterBuilder,
    builder_capacity: (u32, u32),
    /// The casters of the last frame, in world space.
    pub casters: GpuScene,
    /// The light views of the last frame.
    pub views: Vec<Option<LightView>>,
    views_for: Option<(Light, [Vec3; 4])>,
    /// The light of the last frame.
    pub light: Option<Light>,
    /// Frames recorded.
    pub frames: u64,
    /// The last frame's error (the frame was not recorded), if any.
    pub error: Option<String>,
    /// The counts of the latest frame whose status has come back (a few frames behind: read
    /// without waiting, [`StatusReadback`]); each kind that appears is logged once as a warning.
    pub status: Option<FrameStatus>,
    status_readback: Option<StatusReadback>,
    /// The composite pass's strength for this view.
    pub(crate) composite: f32,
}

impl ViewFrame {
    fn new(shared: &Shared, key: FrameKey, settings: &SoftShadowSettings) -> Result<Self, String> {
        let ctx = &shared.ctx;
        let params = settings.params_table().map_err(|e| e.to_string())?;
        let n = key.width * key.height;
        let frame = softshadow::frame_estimator(key.method.name(), ctx.clone(), &params, n)
            .map_err(|e| e.to_string())?
            .ok_or_else(|| format!("{} has no engine path", key.method.name()))?;
        let device = &ctx.device;
        let buffer = |label, size| {
            device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size,
                usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
                mapped_at_creation: false,
            })
        };
        let v_texture = device.create_texture(&depth_map::texture_desc(
            "softshadow V",
            key.width,
            key.height,
            1,
            wgpu::TextureFormat::R32Float,
            wgpu::TextureUsages::TEXTURE_BINDING
                | wgpu::TextureUsages::STORAGE_BINDING
                | wgpu::TextureUsages::COPY_SRC,
        ));
        let uniform = |label| {
            device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: 16,
                usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            })
        };
        let (size_uniform, composite_uniform) = (
            uniform("softshadow V size"),
            uniform("softshadow composite"),
        );
        ctx.queue.write_buffer(
            &size_uniform,
            0,
            bytemuck::cast_slice(&[key.width, key.height, 0, 0]),
        );
        Ok(ViewFrame {
            key,
            frame,
            receivers: buffer("softshadow receivers", 32 * n.max(1) as u64),
            v: buffer("softshadow V buffer", 4 * n.max(1) as u64),
            v_view: v_texture.create_view(&Default::default()),
            v_texture,
            size_uniform,
            composite_uniform,
            prepass: GpuDepthReceivers::new(ctx).map_err(|e| e.to_string())?,
            builder: GpuCasterBuilder::new(ctx, 1, 1).map_err(|e| e.to_string())?,
            builder_capacity: (1, 1),
            casters: GpuScene::with_capacity(ctx, 1).map_err(|e| e.to_string())?,
            views: Vec::new(),
            views_for: None,
            light: None,
            frames: 0,
            error: None,
            status: None,
            status_readback: None,
            composite: settings.composite,
        })
    }

    /// The method this view's frame runs.
    pub fn method(&self) -> Method {
        self.key.method
    }

    /// The view's size in pixels (receivers).
    pub fn size(&self) -> (u32, u32) {
        (self.key.width, self.key.height)
    }
}

/// The core's depth camera for a Bevy view: its clip-from-world matrix (Bevy's infinite
/// reverse-Z perspective) and eye, and the prepass's encodings (reverse Z, unorm normals).
pub fn depth_camera(view: &ExtractedView, width: u32, height: u32) -> Result<DepthCamera, String> {
    if view.clip_from_view.w_axis.w == 1.0 {
        return Err("orthographic cameras are not supported (the receivers' normals face a perspective eye)".into());
    }
    let world_from_view = view.world_from_view.to_matrix();
    Ok(DepthCamera {
        view_proj: view.clip_from_view * world_from_view.inverse(),
        eye: view.world_from_view.translation(),
        width,
        height,
        depth: DepthConvention::ReverseZ,
        normals: NormalEncoding::Unorm,
    })
}

/// The contract's camera for a Bevy view (what [`bounds_stand_in`]'s stand-in scene records).
pub fn contract_camera(view: &ExtractedView, width: u32, height: u32) -> Camera {
    let t = &view.world_from_view;
    let eye = t.translation();
    let f = view.clip_from_view.y_axis.y;
    Camera {
        eye,
        target: eye + t.forward().as_vec3(),
        up: t.up().as_vec3(),
        fov_y_deg: (2.0 * (1.0 / f).atan()).to_degrees(),
        width,
        height,
    }
}

/// Drops the frames of views that are gone (a camera despawned), so their buffers and
/// textures are freed. In `Render`, before the views render.
pub fn drop_stale_views(
    mut state: ResMut<SoftShadowViews>,
    views: Query<Entity, With<ExtractedView>>,
) {
    if state.views.keys().any(|e| !views.contains(*e)) {
        state.views.retain(|e, _| views.contains(*e));
    }
}

/// The pass: see the module's documentation.
#[allow(clippy::too_many_arguments)]
pub fn soft_shadow_pass(
    view: ViewQuery<(&ExtractedView, &ViewPrepassTextures)>,
    mut render: RenderContext,
    light: Res<ExtractedSoftLight>,
    casters: Res<ExtractedCasters>,
    allocator: Res<MeshAllocator>,
    meshes: Res<RenderAssets<RenderMesh>>,
    queue: Res<RenderQueue>,
    mut state: ResMut<SoftShadowViews>,
) {
    let entity = view.entity();
    let (extracted, prepass) = view.into_inner();
    let Some((light, settings)) = light.0 else {
        if let Some(vf) = state.views.get_mut(&entity) {
            vf.composite = 0.0;
        }
        return;
    };
    let state = &mut *state;
    let shared = state.shared.get_or_insert_with(|| {
        Shared::new(
            render.render_device().wgpu_device().clone(),
            wgpu::Queue::clone(&queue),
        )
    });
    let slot = state.views.entry(entity);
    let result = record(
        shared,
        slot,
        extracted,
        prepass,
        &light,
        &settings,
        &casters,
        &allocator,
        &meshes,
        render.command_encoder(),
    );
    if let Err(e) = result {
        if let Some(vf) = state.views.get_mut(&entity) {
            vf.composite = 0.0;
            if vf.error.as_deref() != Some(e.as_str()) {
                bevy::log::warn!("bevy-softshadow: {e}");
            }
            vf.error = Some(e);
        } else {
            bevy::log::warn!("bevy-softshadow: {e}");
        }
    }
}

#[allow(clippy::too_many_arguments)]
fn record(
    shared: &Shared,
    slot: bevy::platform::collections::hash_map::Entry<'_, Entity, ViewFrame>,
    extracted: &ExtractedView,
    prepass: &ViewPrepassTextures,
    light: &Light,
    settings: &SoftShadowSettings,
    casters: &ExtractedCasters,
    allocator: &MeshAllocator,
    meshes: &RenderAssets<RenderMesh>,
    enc: &mut wgpu::CommandEncoder,
) -> Result<(), String> {
    let ctx = &shared.ctx;
    let depth = prepass
        .depth
        .as_ref()
        .ok_or("the camera has no DepthPrepass")?;
    let normals = prepass
        .normal
        .as_ref()
        .ok_or("the camera has no NormalPrepass")?;
    let (depth, normals): (&wgpu::Texture, &wgpu::Texture) =
        (&depth.texture.texture, &normals.texture.texture);
    if depth.sample_count() != 1 {
        return Err("the camera's prepass is multisampled: add Msaa::Off to the camera".into());
    }
    let (width, height) = (prepass.size.width, prepass.size.height);
    let key = FrameKey {
        method: settings.method,
        resolution: settings.params.resolution,
        width,
        height,
    };
    let vf = match slot {
        bevy::platform::collections::hash_map::Entry::Occupied(mut o) => {
            if o.get().key != key {
                o.insert(ViewFrame::new(shared, key, settings)?);
            }
            o.into_mut()
        }
        bevy::platform::collections::hash_map::Entry::Vacant(v) => {
            v.insert(ViewFrame::new(shared, key, settings)?)
        }
    };
    vf.composite = 0.0;
    take_status(vf);
    let camera = depth_camera(extracted, width, height)?;

    // Casters: one entry per distinct mesh, one instance per mesh entity.
    let mut index_of: HashMap<AssetId<Mesh>, usize> = HashMap::default();
    let mut mesh_list: Vec<CasterMesh<'_>> = Vec::new();
    let mut instances: Vec<CasterInstance> = Vec::new();
    for c in &casters.0 {
        let k = match index_of.get(&c.mesh) {
            Some(&k) => k,
            None => {
                let Some(m) = caster_mesh(c.mesh, allocator, meshes)? else {
                    continue; // not uploaded yet, or not triangles
                };
                mesh_list.push(m);
                index_of.insert(c.mesh, mesh_list.len() - 1);
                mesh_list.len() - 1
            }
        };
        instances.push(CasterInstance {
            mesh: k,
            transform: c.transform,
        });
    }
    let bounds = casters.bounds();
    if instances.is_empty() || bounds.diagonal() == 0.0 || !bounds.min.is_finite() {
        return Err("no meshes to cast shadows yet".into());
    }
    let (m, i) = (mesh_list.len() as u32, instances.len() as u32);
    if m > vf.builder_capacity.0 || i > vf.builder_capacity.1 {
        let cap = (m.next_power_of_two(), i.next_power_of_two());
        vf.builder = GpuCasterBuilder::new(ctx, cap.0, cap.1).map_err(|e| e.to_string())?;
        vf.builder_capacity = cap;
    }
    let triangles = GpuCasterBuilder::triangles(&mesh_list, &instances);
    if triangles > vf.casters.capacity() as u64 {
        let cap = u32::try_from(triangles.next_power_of_two())
            .map_err(|_| format!("{triangles} caster triangles: more than one buffer holds"))?;
        vf.casters = GpuScene::with_capacity(ctx, cap).map_err(|e| e.to_string())?;
    }

    // Light views from the casters' box and the receivers' (the receivers lie on the casters:
    // the same box, cut to the camera's frustum up to `max_distance` when one is set).
    let camera_c = contract_camera(extracted, width, height);
    let receivers_box = match settings.max_distance {
        Some(d) => receivers_within(&camera_c, d, &bounds)
            .ok_or("no caster within max_distance of the camera")?,
        None => bounds,
    };
    let box_key = (
        *light,
        [bounds.min, bounds.max, receivers_box.min, receivers_box.max],
    );
    if vf.views_for != Some(box_key) {
        let (scene, receivers) = bounds_stand_in(light, &camera_c, &bounds, &receivers_box)
            .map_err(|e| e.to_string())?;
        // A light or setting the frame does not model: checked when the light changes, on the
        // stand-in scene (its light; its casters are opaque, as the frame's are).
        if let Some(why) = vf.frame.refuses(&scene) {
            return Err(format!("{}: {why}", key.method.name()));
        }
        vf.views = vf
            .frame
            .fit_views(&scene, &receivers)
            .map_err(|e| e.to_string())?;
        vf.views_for = Some(box_key);
    }

    // The frame.
    vf.prepass
        .encode(ctx, enc, &camera, depth, normals, &vf.receivers)
        .map_err(|e| e.to_string())?;
    vf.builder
        .encode(ctx, enc, &mesh_list, &instances, &mut vf.casters)
        .map_err(|e| e.to_string())?;
    vf.frame
        .encode(
            enc,
            &FrameInputs {
                casters: &vf.casters,
                views: &vf.views,
                light,
                receivers: &vf.receivers,
                count: width * height,
                v: &vf.v,
                timestamps: None,
            },
        )
        .map_err(|e| e.to_string())?;
    if let Some(status) = vf.frame.status() {
        vf.status_readback
            .get_or_insert_with(|| StatusReadback::new(ctx, status.size()))
            .copy(enc, status);
    }
    let group = ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some("softshadow V texture"),
        layout: &shared.v_pipeline.get_bind_group_layout(0),
        entries: &[
            wgpu::BindGroupEntry {
                binding: 0,
                resource: vf.v.as_entire_binding(),
            },
            wgpu::BindGroupEntry {
                binding: 1,
                resource: wgpu::BindingResource::TextureView(&vf.v_view),
            },
            wgpu::BindGroupEntry {
                binding: 2,
                resource: vf.size_uniform.as_entire_binding(),
            },
        ],
    });
    {
        let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("softshadow V texture"),
            timestamp_writes: None,
        });
        pass.set_pipeline(&shared.v_pipeline);
        pass.set_bind_group(0, &group, &[]);
        pass.dispatch_workgroups(width.div_ceil(8), height.div_ceil(8), 1);
    }
    vf.light = Some(*light);
    vf.frames += 1;
    vf.error = None;
    vf.composite = settings.composite;
    Ok(())
}

/// Takes the view's status if one has come back; logs each warning kind the previous status did
/// not have (so a lasting condition is logged once, not every frame).
fn take_status(vf: &mut ViewFrame) {
    let Some(words) = vf.status_readback.as_ref().and_then(StatusReadback::take) else {
        return;
    };
    let status = vf.frame.decode_status(&words);
    let before = vf.status.unwrap_or_default();
    let had = |w: &shadow_map_core::Warning| {
        before
            .warnings()
            .iter()
            .any(|b| std::mem::discriminant(b) == std::mem::discriminant(w))
    };
    for w in status.warnings().iter().filter(|w| !had(w)) {
        bevy::log::warn!("bevy-softshadow: {}: {w}", vf.key.method.name());
    }
    vf.status = Some(status);
}

/// Starts mapping the status copies this frame recorded, once Bevy has submitted them, and
/// polls the device without waiting. In `Render`, in the cleanup set.
pub fn map_status(state: Res<SoftShadowViews>) {
    let Some(shared) = &state.shared else {
        return;
    };
    for vf in state.views.values() {
        if let Some(rb) = &vf.status_readback {
            rb.submitted(&shared.ctx);
        }
    }
    let _ = shared.ctx.device.poll(wgpu::PollType::Poll);
}

/// The part of `bounds` the camera sees within `distance` of its eye (along its view axis): the
/// box of that frustum slice cut to `bounds`; `None` when they do not meet.
pub fn receivers_within(camera: &Camera, distance: f32, bounds: &Aabb) -> Option<Aabb> {
    let b = camera.basis();
    let ty = (0.5 * camera.fov_y_deg.to_radians()).tan();
    let tx = ty * camera.width as f32 / camera.height.max(1) as f32;
    let mut slice = Aabb::EMPTY;
    slice.grow(camera.eye);
    for (sx, sy) in [(-1.0, -1.0), (1.0, -1.0), (-1.0, 1.0), (1.0, 1.0)] {
        slice.grow(camera.eye + distance * (b.forward + sx * tx * b.right + sy * ty * b.true_up));
    }
    let cut = Aabb {
        min: slice.min.max(bounds.min),
        max: slice.max.min(bounds.max),
    };
    (cut.min.cmple(cut.max).all()).then_some(cut)
}

/// The mesh `id` as the caster builder reads it from Bevy's mesh allocator: `None` while it is
/// not on the GPU yet, or for a mesh that is not a triangle list; an error for a layout without
/// 32-bit float positions at the start of each vertex.
fn caster_mesh<'a>(
    id: AssetId<Mesh>,
    allocator: &'a MeshAllocator,
    meshes: &RenderAssets<RenderMesh>,
) -> Result<Option<CasterMesh<'a>>, String> {
    let Some(rm) = meshes.get(id) else {
        return Ok(None);
    };
    if rm.primitive_topology() != PrimitiveTopology::TriangleList {
        return Ok(None);
    }
    let Some(vslice) = allocator.mesh_vertex_slice(&id) else {
        return Ok(None);
    };
    let layout = rm.layout.0.layout();
    let position = layout
        .attributes
        .iter()
        .zip(rm.layout.0.attribute_ids())
        .find(|(_, id)| **id == Mesh::ATTRIBUTE_POSITION.id)
        .map(|(a, _)| *a)
        .ok_or("a mesh without positions")?;
    if position.format != wgpu::VertexFormat::Float32x3 {
        return Err(format!(
            "a mesh with {:?} positions (compressed?): the casters need Float32x3",
            position.format
        ));
    }
    let base_vertex = vslice.range.start as i32;
    let (indices, first_index, index_count) = match &rm.buffer_info {
        RenderMeshBufferInfo::Indexed {
            count,
            index_format,
        } => {
            let Some(islice) = allocator.mesh_index_slice(&id) else {
                return Ok(None);
            };
            let buffer: &'a wgpu::Buffer = islice.buffer;
            let kind = match index_format {
                wgpu::IndexFormat::Uint16 => CasterIndices::U16(buffer),
                wgpu::IndexFormat::Uint32 => CasterIndices::U32(buffer),
            };
            (kind, islice.range.start, *count)
        }
        RenderMeshBufferInfo::NonIndexed => (CasterIndices::None, 0, rm.vertex_count),
    };
    Ok(Some(CasterMesh {
        vertices: vslice.buffer,
        vertex_stride: layout.array_stride as u32,
        position_offset: position.offset as u32,
        indices,
        first_index,
        index_count,
        base_vertex,
        opacity: 1.0,
    }))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn receivers_within_cut_the_box_to_the_frustum_slice() {
        let camera = Camera {
            eye: Vec3::new(0.0, 1.0, 0.0),
            target: Vec3::new(0.0, 1.0, -1.0),
            up: Vec3::Y,
            fov_y_deg: 90.0,
            width: 2,
            height: 1,
        };
        let ground = Aabb {
            min: Vec3::new(-200.0, 0.0, -200.0),
            max: Vec3::new(200.0, 0.0, 200.0),
        };
        let b = receivers_within(&camera, 10.0, &ground).unwrap();
        // 10 ahead, tan = 1 up and down, 2 sideways: x in [-20, 20], z in [-10, 0].
        assert!(
            (b.min - Vec3::new(-20.0, 0.0, -10.0)).length() < 1e-4,
            "{b:?}"
        );
        assert!((b.max - Vec3::new(20.0, 0.0, 0.0)).length() < 1e-4, "{b:?}");
        let far = Aabb {
            min: Vec3::new(-1.0, 0.0, -100.0),
            max: Vec3::new(1.0, 1.0, -50.0),
        };
        assert!(receivers_within(&camera, 10.0, &far).is_none());
    }
}
