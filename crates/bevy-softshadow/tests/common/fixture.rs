//! A contract scene (`fixtures/NAME/NAME.toml`, docs/methods.md §11) as Bevy entities: its
//! meshes, its light with [`SoftShadowSettings`], and a camera with the contract's view, so the
//! tests and examples render what the report measures. Not part of the crate: `tests/headless.rs`
//! and the examples include it with `#[path]`.
#![allow(dead_code)] // each includer uses its own part

use bevy::{
    asset::RenderAssetUsages,
    core_pipeline::prepass::{DepthPrepass, NormalPrepass},
    mesh::{Indices, PrimitiveTopology},
    prelude::*,
};
use bevy_softshadow::SoftShadowSettings;
use shadow_map_core::{LightShape, Scene};

/// The near plane of the camera [`camera_bundle`] makes, as a fraction of the scene's diagonal.
pub const NEAR_FRACTION: f32 = 1e-3;

/// One Bevy mesh per mesh of `scene`: its world-space triangles (the scene's transforms are
/// already applied), flat-shaded (each triangle's own normal, so the normal prepass holds the
/// geometric normal the contract's receivers have), with `u32` indices.
pub fn meshes(scene: &Scene) -> Vec<Mesh> {
    scene
        .meshes()
        .iter()
        .map(|m| {
            let tris = &scene.triangles()[m.triangles.clone()];
            let mut positions = Vec::with_capacity(3 * tris.len());
            let mut normals = Vec::with_capacity(3 * tris.len());
            for t in tris {
                let n = (t[1] - t[0]).cross(t[2] - t[0]).normalize_or_zero();
                for p in t {
                    positions.push(p.to_array());
                    normals.push(n.to_array());
                }
            }
            let indices = (0..positions.len() as u32).collect();
            Mesh::new(
                PrimitiveTopology::TriangleList,
                RenderAssetUsages::RENDER_WORLD | RenderAssetUsages::MAIN_WORLD,
            )
            .with_inserted_attribute(Mesh::ATTRIBUTE_POSITION, positions)
            .with_inserted_attribute(Mesh::ATTRIBUTE_NORMAL, normals)
            .with_inserted_indices(Indices::U32(indices))
        })
        .collect()
}

/// The scene's camera as a Bevy `Transform` and `Projection` (vertical field of view, near plane
/// [`NEAR_FRACTION`] of the scene's diagonal; Bevy's far plane is infinite, reverse Z).
pub fn camera(scene: &Scene) -> (Transform, Projection) {
    let c = scene.camera();
    let transform = Transform::from_translation(c.eye).looking_at(c.target, c.up);
    let projection = Projection::Perspective(PerspectiveProjection {
        fov: c.fov_y_deg.to_radians(),
        aspect_ratio: c.width as f32 / c.height as f32,
        near: NEAR_FRACTION * scene.bounds().diagonal().max(1e-6),
        ..default()
    });
    (transform, projection)
}

/// The camera's components with the prepasses the plugin needs (`DepthPrepass`,
/// `NormalPrepass`, `Msaa::Off`); add a `RenderTarget` for an image.
pub fn camera_bundle(scene: &Scene) -> impl Bundle {
    let (transform, projection) = camera(scene);
    (
        Camera3d::default(),
        projection,
        transform,
        Msaa::Off,
        DepthPrepass,
        NormalPrepass,
    )
}

/// Spawns the scene's meshes (one grey, double-sided material) and its light with `settings`
/// (Bevy's own shadow maps off); returns the light's entity. The light: a rect as a
/// [`RectLight`], a sphere as a [`PointLight`] of its radius, the sun as a [`DirectionalLight`]
/// (its angle in `settings.sun_angle_deg`); a disk, which Bevy has no light for, as the
/// [`RectLight`] of the same area (reported by the plugin as a rect). A rect light comes with an
/// unshadowed point light at its centre for Bevy's shading (see `spawn_rect`).
pub fn spawn(
    scene: &Scene,
    mut settings: SoftShadowSettings,
    commands: &mut Commands,
    meshes: &mut Assets<Mesh>,
    materials: &mut Assets<StandardMaterial>,
) -> Entity {
    let material = materials.add(StandardMaterial {
        base_color: Color::srgb(0.8, 0.8, 0.8),
        perceptual_roughness: 0.9,
        double_sided: true,
        cull_mode: None,
        ..default()
    });
    for mesh in self::meshes(scene) {
        commands.spawn((
            Mesh3d(meshes.add(mesh)),
            MeshMaterial3d(material.clone()),
            Transform::IDENTITY,
        ));
    }
    let l = scene.light();
    // Bevy's local -z along the light's normal, local x along its tangent (docs: extract.rs).
    let transform =
        Transform::from_translation(l.center).looking_to(l.normal, l.tangent.cross(l.normal));
    match l.shape {
        LightShape::Directional { angle_deg } => {
            settings.sun_angle_deg = angle_deg;
            commands
                .spawn((
                    DirectionalLight {
                        illuminance: 2_500.0,
                        shadow_maps_enabled: false,
                        ..default()
                    },
                    settings,
                    transform,
                ))
                .id()
        }
        LightShape::Sphere { radius } => commands
            .spawn((
                PointLight {
                    intensity: 400_000.0,
                    radius,
                    range: 4.0 * scene.bounds().diagonal(),
                    shadow_maps_enabled: false,
                    ..default()
                },
                settings,
                transform,
            ))
            .id(),
        LightShape::Rect { size } => spawn_rect(commands, settings, transform, size),
        LightShape::Disk { radius } => {
            let side = radius * std::f32::consts::PI.sqrt();
            spawn_rect(commands, settings, transform, [side, side])
        }
    }
}

fn spawn_rect(
    commands: &mut Commands,
    settings: SoftShadowSettings,
    transform: Transform,
    size: [f32; 2],
) -> Entity {
    // Bevy shades a RectLight only with its `area_light_luts` feature (a KTX2/zstd LUT this
    // crate does not pull in): an unshadowed point light at its centre lights the scene instead
    // (the plugin's V is what shadows it).
    commands.spawn((
        PointLight {
            intensity: 400_000.0,
            range: 100.0,
            shadow_maps_enabled: false,
            ..default()
        },
        transform,
    ));
    commands
        .spawn((
            RectLight {
                intensity: 400_000.0,
                width: size[0],
                height: size[1],
                ..default()
            },
            settings,
            transform,
        ))
        .id()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_light_spawned_from_a_fixture_maps_back_to_it() {
        let scene = Scene::load(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../fixtures/bunny/bunny.toml"
        ))
        .unwrap();
        let l = scene.light();
        let t = GlobalTransform::from(
            Transform::from_translation(l.center).looking_to(l.normal, l.tangent.cross(l.normal)),
        );
        let rect = RectLight {
            width: 1.0,
            height: 1.0,
            ..default()
        };
        let back = bevy_softshadow::extract::core_light(
            &SoftShadowSettings::default(),
            &t,
            None,
            None,
            Some(&rect),
            None,
        )
        .unwrap();
        assert_eq!(back.shape, l.shape);
        assert!((back.center - l.center).length() < 1e-6);
        assert!((back.normal - l.normal).length() < 1e-6);
        assert!((back.tangent - l.tangent).length() < 1e-6);
        let m = meshes(&scene);
        assert_eq!(m.len(), scene.meshes().len());
        let tris: usize = m.iter().map(|m| m.indices().unwrap().len() / 3).sum();
        assert_eq!(tris, scene.triangles().len());
    }
}
