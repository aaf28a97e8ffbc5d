//! Main world to render world, each frame: the light carrying [`SoftShadowSettings`] as the
//! core's [`Light`], and every mesh instance (its mesh asset, world transform and world box).
//! Work per frame: one light and one matrix and box per instance, never per triangle.
use crate::SoftShadowSettings;
use bevy::{
    camera::primitives::Aabb,
    light::{DirectionalLight, PointLight, RectLight, SunDisk},
    prelude::*,
    render::Extract,
};
use shadow_map_core::{scene::Aabb as CoreAabb, Light, LightShape};

/// The light to shade, as the core models it, with its settings.
#[derive(Resource, Default, Debug, Clone)]
pub struct ExtractedSoftLight(pub Option<(Light, SoftShadowSettings)>);

/// One mesh instance: its mesh, world transform and world-space box.
#[derive(Debug, Clone, Copy)]
pub struct ExtractedCaster {
    /// The mesh asset.
    pub mesh: AssetId<Mesh>,
    /// World from local.
    pub transform: Mat4,
    /// The world box of its local [`Aabb`] (empty when the mesh has none yet).
    pub world_box: CoreAabb,
}

/// Every mesh instance this frame.
#[derive(Resource, Default, Debug, Clone)]
pub struct ExtractedCasters(pub Vec<ExtractedCaster>);

impl ExtractedCasters {
    /// The world box of every instance.
    pub fn bounds(&self) -> CoreAabb {
        let mut b = CoreAabb::EMPTY;
        for c in &self.0 {
            if c.world_box.min.x <= c.world_box.max.x {
                b.grow(c.world_box.min);
                b.grow(c.world_box.max);
            }
        }
        b
    }
}

/// The world box of a local box under `m` (its eight corners).
pub fn world_box(local: &Aabb, m: Mat4) -> CoreAabb {
    let (c, h) = (Vec3::from(local.center), Vec3::from(local.half_extents));
    let mut b = CoreAabb::EMPTY;
    for k in 0..8 {
        let s = Vec3::new(
            if k & 1 == 0 { -1.0 } else { 1.0 },
            if k & 2 == 0 { -1.0 } else { 1.0 },
            if k & 4 == 0 { -1.0 } else { 1.0 },
        );
        b.grow(m.transform_point3(c + s * h));
    }
    b
}

/// The core's light for a Bevy light entity ([`SoftShadowSettings`] says which shapes map to
/// which); `None` for a light this plugin does not model (a point light of radius 0, a spot
/// light) or a transform that is not finite.
pub fn core_light(
    settings: &SoftShadowSettings,
    transform: &GlobalTransform,
    directional: Option<&DirectionalLight>,
    point: Option<&PointLight>,
    rect: Option<&RectLight>,
    sun_disk: Option<&SunDisk>,
) -> Option<Light> {
    let forward = transform.forward().as_vec3();
    let right = transform.right().as_vec3();
    let center = transform.translation();
    if !(forward.is_finite() && right.is_finite() && center.is_finite()) {
        return None;
    }
    if directional.is_some() {
        let angle = sun_disk
            .map(|d| d.angular_size.to_degrees())
            .unwrap_or(settings.sun_angle_deg);
        return (angle > 0.0 && angle < 90.0).then(|| Light::directional(forward, angle));
    }
    let (shape, normal, tangent) = if let Some(r) = rect {
        if !(r.width > 0.0 && r.height > 0.0) {
            return None;
        }
        (
            LightShape::Rect {
                size: [r.width, r.height],
            },
            forward,
            right,
        )
    } else {
        let p = point.filter(|p| p.radius > 0.0)?;
        // A sphere emits all round: the frame's axis is only a convention (down, as the
        // contract's sphere fixtures have it).
        let normal = Vec3::NEG_Y;
        (
            LightShape::Sphere { radius: p.radius },
            normal,
            shadow_map_core::light::default_tangent(normal),
        )
    };
    Some(Light {
        shape,
        center,
        normal,
        tangent,
    })
}

/// Copies the first light with [`SoftShadowSettings`] and every mesh instance into the render
/// world.
#[allow(clippy::type_complexity)]
pub fn extract(
    mut light: ResMut<ExtractedSoftLight>,
    mut casters: ResMut<ExtractedCasters>,
    lights: Extract<
        Query<(
            &SoftShadowSettings,
            &GlobalTransform,
            Option<&DirectionalLight>,
            Option<&PointLight>,
            Option<&RectLight>,
            Option<&SunDisk>,
        )>,
    >,
    meshes: Extract<Query<(&Mesh3d, &GlobalTransform, Option<&Aabb>)>>,
) {
    light.0 = lights
        .iter()
        .find_map(|(s, t, d, p, r, sd)| core_light(s, t, d, p, r, sd).map(|l| (l, *s)));
    casters.0.clear();
    for (mesh, t, aabb) in &meshes {
        let m = t.to_matrix();
        casters.0.push(ExtractedCaster {
            mesh: mesh.id(),
            transform: m,
            world_box: aabb.map_or(CoreAabb::EMPTY, |a| world_box(a, m)),
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bevy_lights_map_to_the_contracts() {
        let s = SoftShadowSettings::default();
        let t = GlobalTransform::from(
            Transform::from_xyz(1.0, 3.0, 0.0).looking_at(Vec3::new(1.0, 0.0, 0.0), Vec3::X),
        );
        // The sun: along the entity's forward, SunDisk's angle when there is one.
        let sun = core_light(&s, &t, Some(&DirectionalLight::default()), None, None, None).unwrap();
        assert!((sun.normal - Vec3::NEG_Y).length() < 1e-6);
        assert!(matches!(sun.shape, LightShape::Directional { angle_deg } if angle_deg == 0.53));
        let disk = SunDisk {
            angular_size: 2f32.to_radians(),
            intensity: 1.0,
        };
        let sun = core_light(
            &s,
            &t,
            Some(&DirectionalLight::default()),
            None,
            None,
            Some(&disk),
        )
        .unwrap();
        assert!(
            matches!(sun.shape, LightShape::Directional { angle_deg } if (angle_deg - 2.0).abs() < 1e-5)
        );
        // A rect light faces its forward, its width along its local x.
        let rect = RectLight {
            width: 2.0,
            height: 0.5,
            ..Default::default()
        };
        let l = core_light(&s, &t, None, None, Some(&rect), None).unwrap();
        assert_eq!(l.shape, LightShape::Rect { size: [2.0, 0.5] });
        assert!((l.normal - Vec3::NEG_Y).length() < 1e-6);
        assert!((l.tangent - t.right().as_vec3()).length() < 1e-6);
        assert!((l.center - Vec3::new(1.0, 3.0, 0.0)).length() < 1e-6);
        // A point light with a radius is a sphere; without one it is not modelled.
        let mut p = PointLight {
            radius: 0.25,
            ..Default::default()
        };
        let l = core_light(&s, &t, None, Some(&p), None, None).unwrap();
        assert_eq!(l.shape, LightShape::Sphere { radius: 0.25 });
        p.radius = 0.0;
        assert!(core_light(&s, &t, None, Some(&p), None, None).is_none());
    }

    #[test]
    fn world_boxes_hold_the_moved_corners() {
        let local = Aabb::from_min_max(Vec3::splat(-1.0), Vec3::splat(1.0));
        let m = Mat4::from_scale_rotation_translation(
            Vec3::splat(2.0),
            Quat::from_rotation_y(std::f32::consts::FRAC_PI_4),
            Vec3::new(10.0, 0.0, 0.0),
        );
        let b = world_box(&local, m);
        let r = 2.0 * std::f32::consts::SQRT_2;
        assert!(
            (b.min - Vec3::new(10.0 - r, -2.0, -r)).length() < 1e-5,
            "{b:?}"
        );
        assert!(
            (b.max - Vec3::new(10.0 + r, 2.0, r)).length() < 1e-5,
            "{b:?}"
        );
    }
}
