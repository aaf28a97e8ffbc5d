//! The provided composite pass (a `Core3d` system after the main pass, before post-processing):
//! the view's colour scaled by V, `colour * mix(1, V, SoftShadowSettings::composite)`, through
//! Bevy's post-process ping-pong ([`ViewTarget::post_process_write`]).
//!
//! It scales all of a pixel's light, ambient and other lights included, so it is exact only for
//! a scene lit by this light alone. An app with more lights samples [`crate::ViewFrame::v_texture`]
//! in its own material instead (the texture is `TEXTURE_BINDING`) and sets `composite` to 0.
use crate::frame::SoftShadowViews;
use bevy::{
    platform::collections::HashMap,
    prelude::*,
    render::{
        renderer::{RenderContext, RenderQueue, ViewQuery},
        view::ViewTarget,
    },
};
use std::sync::Mutex;

/// The composite pipeline per colour format (Bevy's HDR and LDR targets differ).
pub(crate) struct CompositePipelines {
    module: wgpu::ShaderModule,
    by_format: Mutex<HashMap<wgpu::TextureFormat, wgpu::RenderPipeline>>,
}

impl CompositePipelines {
    pub(crate) fn new(device: &wgpu::Device) -> Self {
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("softshadow composite"),
            source: wgpu::ShaderSource::Wgsl(include_str!("composite.wgsl").into()),
        });
        CompositePipelines {
            module,
            by_format: Mutex::new(HashMap::default()),
        }
    }

    fn pipeline(&self, device: &wgpu::Device, format: wgpu::TextureFormat) -> wgpu::RenderPipeline {
        let mut map = self.by_format.lock().unwrap_or_else(|e| e.into_inner());
        map.entry(format)
            .or_insert_with(|| {
                device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
                    label: Some("softshadow composite"),
                    layout: None,
                    vertex: wgpu::VertexState {
                        module: &self.module,
                        entry_point: Some("vertex"),
                        compilation_options: Default::default(),
                        buffers: &[],
                    },
                    primitive: wgpu::PrimitiveState::default(),
                    depth_stencil: None,
                    multisample: wgpu::MultisampleState::default(),
                    fragment: Some(wgpu::FragmentState {
                        module: &self.module,
                        entry_point: Some("fragment"),
                        compilation_options: Default::default(),
                        targets: &[Some(format.into())],
                    }),
                    multiview_mask: None,
                    cache: None,
                })
            })
            .clone()
    }
}

/// The pass: see the module's documentation. Views without a frame this frame are left alone.
pub fn composite_pass(
    view: ViewQuery<&ViewTarget>,
    mut render: RenderContext,
    state: Res<SoftShadowViews>,
    queue: Res<RenderQueue>,
) {
    let entity = view.entity();
    let target = view.into_inner();
    let (Some(shared), Some(vf)) = (state.shared.as_ref(), state.views.get(&entity)) else {
        return;
    };
    if vf.composite.is_nan()
        || vf.composite <= 0.0
        || vf.v_texture.size() != target.main_texture().size()
    {
        return;
    }
    let device = render.render_device().wgpu_device().clone();
    let pipelines = &shared.composite;
    let pipeline = pipelines.pipeline(&device, target.main_texture_format());
    queue.write_buffer(
        &vf.composite_uniform,
        0,
        bytemuck::cast_slice(&[vf.composite.min(1.0), 0.0, 0.0, 0.0]),
    );
    let post = target.post_process_write();
    let group = device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some("softshadow composite"),
        layout: &pipeline.get_bind_group_layout(0),
        entries: &[
            wgpu::BindGroupEntry {
                binding: 0,
                resource: wgpu::BindingResource::TextureView(post.source),
            },
            wgpu::BindGroupEntry {
                binding: 1,
                resource: wgpu::BindingResource::TextureView(&vf.v_view),
            },
            wgpu::BindGroupEntry {
                binding: 2,
                resource: vf.composite_uniform.as_entire_binding(),
            },
        ],
    });
    let enc = render.command_encoder();
    let mut pass = enc.begin_render_pass(&wgpu::RenderPassDescriptor {
        label: Some("softshadow composite"),
        color_attachments: &[Some(wgpu::RenderPassColorAttachment {
            view: post.destination,
            depth_slice: None,
            resolve_target: None,
            ops: wgpu::Operations {
                load: wgpu::LoadOp::Clear(wgpu::Color::BLACK),
                store: wgpu::StoreOp::Store,
            },
        })],
        depth_stencil_attachment: None,
        timestamp_writes: None,
        occlusion_query_set: None,
        multiview_mask: None,
    });
    pass.set_pipeline(&pipeline);
    pass.set_bind_group(0, &group, &[]);
    pass.draw(0..3, 0..1);
}
