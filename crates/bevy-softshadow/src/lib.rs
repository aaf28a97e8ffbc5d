//! softshadow's measured soft-shadow methods in Bevy 0.20.
//!
//! Add [`SoftShadowPlugin`] after Bevy's `DefaultPlugins`, put [`SoftShadowSettings`] on one
//! light (a `DirectionalLight`, a `RectLight` or a `PointLight` with a radius), and give each
//! 3D camera that should show the shadows a `DepthPrepass`, a `NormalPrepass` and `Msaa::Off`.
//! Each frame, for each such camera, the plugin records the frame API of the chosen method
//! (the casters straight from Bevy's mesh buffers, the receivers from the camera's prepass) into
//! Bevy's command encoder and writes V into a view-sized texture, which its composite pass
//! multiplies into the view's colour (see [`composite`] for when that is exact). Nothing waits, the
//! only readback is the frame's few status words (its warnings are logged), and the CPU work per
//! frame is a matrix and a box per mesh instance.
//!
//! ```no_run
//! use bevy::prelude::*;
//! use bevy::core_pipeline::prepass::{DepthPrepass, NormalPrepass};
//! use bevy_softshadow::{Method, SoftShadowPlugin, SoftShadowSettings};
//!
//! fn setup(mut commands: Commands) {
//!     commands.spawn((Camera3d::default(), DepthPrepass, NormalPrepass, Msaa::Off));
//!     commands.spawn((
//!         DirectionalLight { shadow_maps_enabled: false, ..default() },
//!         SoftShadowSettings::new(Method::Backprojection),
//!         Transform::from_xyz(1.0, 3.0, 2.0).looking_at(Vec3::ZERO, Vec3::Y),
//!     ));
//! }
//!
//! App::new()
//!     .add_plugins((DefaultPlugins, SoftShadowPlugin))
//!     .add_systems(Startup, setup)
//!     .run();
//! ```
//!
//! The error of every setting on the repository's scenes is compiled in ([`measured()`]).
#![warn(missing_docs)]

pub mod composite;
pub mod extract;
pub mod frame;
pub mod measured;
mod settings;

pub use frame::{SoftShadowViews, ViewFrame};
pub use measured::{mean_rmse, measured, Measured};
pub use settings::{Method, MethodParams, SoftShadowSettings, DEFAULT_SUN_ANGLE_DEG};

use bevy::{
    core_pipeline::schedule::{Core3d, Core3dSystems},
    prelude::*,
    render::{
        mesh::allocator::MeshAllocatorSettings, render_resource::BufferUsages, ExtractSchedule,
        Render, RenderApp, RenderSystems,
    },
};

/// The plugin: extraction, the per-view frame pass and the composite pass (see the crate's
/// documentation). Add it after `DefaultPlugins`; without a render app (a headless test app
/// with no renderer) it does nothing.
pub struct SoftShadowPlugin;

impl Plugin for SoftShadowPlugin {
    fn build(&self, app: &mut App) {
        app.register_type::<SoftShadowSettings>();
        let Some(render_app) = app.get_sub_app_mut(RenderApp) else {
            return;
        };
        // The caster builder reads Bevy's vertex and index slabs as storage buffers: they need
        // STORAGE usage, set before the mesh allocator makes its first slab.
        let world = render_app.world_mut();
        if let Some(mut s) = world.get_resource_mut::<MeshAllocatorSettings>() {
            s.extra_buffer_usages |= BufferUsages::STORAGE;
        } else {
            world.insert_resource(MeshAllocatorSettings {
                extra_buffer_usages: BufferUsages::STORAGE,
                ..default()
            });
        }
        render_app
            .init_resource::<extract::ExtractedSoftLight>()
            .init_resource::<extract::ExtractedCasters>()
            .init_resource::<SoftShadowViews>()
            .add_systems(ExtractSchedule, extract::extract)
            .add_systems(
                Render,
                (
                    frame::drop_stale_views.in_set(RenderSystems::PrepareResources),
                    frame::map_status.in_set(RenderSystems::Cleanup),
                ),
            )
            .add_systems(
                Core3d,
                (
                    frame::soft_shadow_pass
                        .after(Core3dSystems::Prepass)
                        .before(Core3dSystems::MainPass),
                    composite::composite_pass
                        .after(Core3dSystems::MainPass)
                        .before(Core3dSystems::EarlyPostProcess),
                ),
            );
    }
}
