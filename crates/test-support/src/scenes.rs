//! Random scenes for the CPU-vs-GPU twin tests.
//!
//! A scene ([`SceneSpec`]): a light (rect, disk or sphere, tilted, 2.5 to 5 above the ground)
//! over up to three boxes on the ground `[-4, 4]^2`, seen by [`camera`]; its receivers: points
//! on the ground (`ground`), on box tops (`tops`), grazing ones (normals nearly perpendicular to
//! the direction to the light), ones outside the light's frustum (`outside`: behind the light,
//! far out, under the ground facing down), every m-th one inactive. Each method draws from its
//! own [`SceneRanges`] (the shapes it supports, its light and box sizes, which receiver kinds);
//! the method's settings are drawn after the scene ([`arb_case`]), so each method's stream of
//! random draws is what its own generator drew before (persisted failures replay as they were).

use crate::fixtures::{cuboid, quad};
use glam::Vec3;
use proptest::prelude::*;
use shadow_map_core::{light::default_tangent, Camera, Light, LightShape, Receivers, Scene};
use std::ops::Range;

/// The twin scenes' camera: from (0, 5, 8) at the origin, 8 x 8 pixels (the receivers are
/// explicit points; the camera only bounds the scene).
pub fn camera() -> Camera {
    Camera {
        eye: Vec3::new(0.0, 5.0, 8.0),
        target: Vec3::ZERO,
        up: Vec3::Y,
        fov_y_deg: 40.0,
        width: 8,
        height: 8,
    }
}

/// A light: its shape, size, centre and tilt.
#[derive(Debug, Clone)]
pub struct LightSpec {
    /// 0 rect, 1 disk, 2 sphere.
    pub shape: u8,
    /// Rect sides; disk and sphere diameter `size.0`.
    pub size: (f32, f32),
    /// Centre (x, y, z).
    pub center: (f32, f32, f32),
    /// The normal is `(tilt.0, -1, tilt.1)`, normalised.
    pub tilt: (f32, f32),
}

impl LightSpec {
    /// A light of `shape` (0 rect, 1 disk, 2 sphere), `size`, `center` and `tilt`.
    pub const fn new(
        shape: u8,
        size: (f32, f32),
        center: (f32, f32, f32),
        tilt: (f32, f32),
    ) -> Self {
        LightSpec {
            shape,
            size,
            center,
            tilt,
        }
    }

    /// The light: a rect's tangent is +x projected on its plane, a disk's or sphere's the
    /// default tangent of its normal.
    pub fn light(&self) -> Light {
        let normal = Vec3::new(self.tilt.0, -1.0, self.tilt.1).normalize();
        let center = Vec3::new(self.center.0, self.center.1, self.center.2);
        let (shape, tangent) = match self.shape {
            0 => (
                LightShape::Rect {
                    size: [self.size.0, self.size.1],
                },
                (Vec3::X - Vec3::X.dot(normal) * normal).normalize(),
            ),
            1 => (
                LightShape::Disk {
                    radius: 0.5 * self.size.0,
                },
                default_tangent(normal),
            ),
            _ => (
                LightShape::Sphere {
                    radius: 0.5 * self.size.0,
                },
                default_tangent(normal),
            ),
        };
        Light {
            shape,
            center,
            normal,
            tangent,
        }
    }
}

/// An axis-aligned box: centre (x, z) on the ground plane, sides, bottom height, height.
#[derive(Debug, Clone)]
pub struct BoxSpec {
    /// Centre x.
    pub x: f32,
    /// Centre z.
    pub z: f32,
    /// Side along x.
    pub sx: f32,
    /// Side along z.
    pub sz: f32,
    /// Bottom height.
    pub y0: f32,
    /// Height (top at `y0 + h`).
    pub h: f32,
}

impl BoxSpec {
    /// The box centred at (x, z) with sides `sx`, `sz`, from `y0` up to `y0 + h`.
    pub const fn new(x: f32, z: f32, sx: f32, sz: f32, y0: f32, h: f32) -> Self {
        BoxSpec {
            x,
            z,
            sx,
            sz,
            y0,
            h,
        }
    }

    /// The box's twelve outward-facing triangles.
    pub fn triangles(&self) -> Vec<[Vec3; 3]> {
        let lo = Vec3::new(self.x - 0.5 * self.sx, self.y0, self.z - 0.5 * self.sz);
        let hi = Vec3::new(
            self.x + 0.5 * self.sx,
            self.y0 + self.h,
            self.z + 0.5 * self.sz,
        );
        cuboid(lo, hi)
    }
}

/// A random twin scene and its receivers.
#[derive(Debug, Clone)]
pub struct SceneSpec {
    /// The light.
    pub light: LightSpec,
    /// The boxes (occluders, and receivers on their tops).
    pub boxes: Vec<BoxSpec>,
    /// Ground points (x, z), normal +y.
    pub ground: Vec<(f32, f32)>,
    /// Points on box tops: (box index, u, v) in [0, 1]^2 of the top face.
    pub tops: Vec<(usize, f32, f32)>,
    /// Ground points with a normal nearly perpendicular to the direction to the light:
    /// (x, z, tilt towards the light, angle around it).
    pub grazing: Vec<(f32, f32, f32, f32)>,
    /// 0: above the light plane (behind it), 1: far out (outside the frustum), 2: under the
    /// ground facing down.
    pub outside: Vec<(u8, f32, f32)>,
    /// Every m-th receiver inactive (never the first).
    pub inactive_every: Option<usize>,
    /// Every other ground point moved near a box (within 1.5 box sides of its centre), so that
    /// penumbrae are well represented.
    pub ground_near_boxes: bool,
}

/// A random case: a scene and a method's settings.
#[derive(Debug, Clone)]
pub struct Case<S> {
    /// The scene and its receivers.
    pub scene: SceneSpec,
    /// The method's settings.
    pub settings: S,
}

impl SceneSpec {
    /// The scene: the ground and the boxes, all opaque, under the light.
    pub fn scene(&self) -> Scene {
        let mut meshes = vec![(quad(-4.0, -4.0, 4.0, 4.0, 0.0), 1.0)];
        for b in &self.boxes {
            meshes.push((b.triangles(), 1.0));
        }
        match Scene::from_meshes("gpu-twins", camera(), self.light.light(), meshes) {
            Ok(s) => s,
            Err(e) => panic!("scene: {e}"),
        }
    }

    /// The scene and its receivers ([`SceneSpec::scene`], [`SceneSpec::receivers`]).
    pub fn scene_and_receivers(&self) -> (Scene, Receivers) {
        let scene = self.scene();
        let receivers = self.receivers(scene.light());
        (scene, receivers)
    }

    /// The receivers, in the order ground, tops, grazing, outside (`light` is the scene's).
    pub fn receivers(&self, light: &Light) -> Receivers {
        let mut pos = Vec::new();
        let mut nrm = Vec::new();
        for (i, &(x, z)) in self.ground.iter().enumerate() {
            let p = if self.ground_near_boxes && i % 2 == 1 && !self.boxes.is_empty() {
                let b = &self.boxes[(i / 2) % self.boxes.len()];
                Vec3::new(b.x + x / 3.5 * 1.5 * b.sx, 0.0, b.z + z / 3.5 * 1.5 * b.sz)
            } else {
                Vec3::new(x, 0.0, z)
            };
            pos.push(p);
            nrm.push(Vec3::Y);
        }
        if !self.boxes.is_empty() {
            for &(k, u, v) in &self.tops {
                let b = &self.boxes[k % self.boxes.len()];
                pos.push(Vec3::new(
                    b.x + (u - 0.5) * b.sx,
                    b.y0 + b.h,
                    b.z + (v - 0.5) * b.sz,
                ));
                nrm.push(Vec3::Y);
            }
        }
        for &(x, z, s, a) in &self.grazing {
            let p = Vec3::new(x, 0.0, z);
            let d = (light.center - p).normalize();
            let t1 = default_tangent(d);
            let t2 = d.cross(t1);
            let q = t1 * a.cos() + t2 * a.sin();
            pos.push(p);
            nrm.push((q + s * d).normalize());
        }
        for &(kind, x, z) in &self.outside {
            match kind {
                0 => {
                    pos.push(light.center + Vec3::new(x, 0.5 + z.abs(), z));
                    nrm.push(if x > 0.0 { Vec3::Y } else { -Vec3::Y });
                }
                1 => {
                    pos.push(Vec3::new(
                        x.signum() * (60.0 + 140.0 * x.abs()),
                        0.0,
                        50.0 * z,
                    ));
                    nrm.push(Vec3::Y);
                }
                _ => {
                    pos.push(Vec3::new(3.0 * x, -0.5, 3.0 * z));
                    nrm.push(-Vec3::Y);
                }
            }
        }
        let mut r = match Receivers::from_points(pos, nrm) {
            Ok(r) => r,
            Err(e) => panic!("receivers: {e}"),
        };
        if let Some(m) = self.inactive_every {
            for (k, a) in r.active_mut().iter_mut().enumerate() {
                // Keep the first receiver (a ground point) active so the light view can be fitted.
                if k > 0 && k % m == m - 1 {
                    *a = false;
                }
            }
        }
        r
    }
}

/// How a method draws its light's shape.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Shapes {
    /// Rect lights only (nothing drawn).
    Rect,
    /// Rect, disk or sphere, one of three equally weighted choices.
    OneOf,
    /// Rect, disk or sphere, a uniform integer in `0..3`.
    Uniform,
}

/// The ranges a method's random scenes are drawn from.
#[derive(Debug, Clone)]
pub struct SceneRanges {
    /// The light shapes.
    pub shapes: Shapes,
    /// Each side of a rect light (a disk's or sphere's diameter).
    pub light_size: Range<f32>,
    /// A box's bottom height.
    pub box_bottom: Range<f32>,
    /// A box's height.
    pub box_height: Range<f32>,
    /// Whether grazing receivers are drawn.
    pub grazing: bool,
    /// Whether receivers outside the light's frustum are drawn.
    pub outside: bool,
    /// Whether every other ground receiver is moved near a box.
    pub ground_near_boxes: bool,
}

impl SceneRanges {
    /// Every light shape, sides 0.05 to 1.5, boxes from 0 to 1.5 above the ground and 0.05 to
    /// 0.8 high, grazing and outside receivers, ground receivers anywhere.
    pub const ALL: SceneRanges = SceneRanges {
        shapes: Shapes::OneOf,
        light_size: 0.05..1.5,
        box_bottom: 0.0..1.5,
        box_height: 0.05..0.8,
        grazing: true,
        outside: true,
        ground_near_boxes: false,
    };
}

/// A random light.
pub fn arb_light(r: &SceneRanges) -> BoxedStrategy<LightSpec> {
    let shape = match r.shapes {
        Shapes::Rect => Just(0u8).boxed(),
        Shapes::OneOf => prop_oneof![Just(0u8), Just(1u8), Just(2u8)].boxed(),
        Shapes::Uniform => (0u32..3).prop_map(|s| s as u8).boxed(),
    };
    (
        shape,
        (r.light_size.clone(), r.light_size.clone()),
        (-1.0f32..1.0, 2.5f32..5.0, -1.0f32..1.0),
        (-0.4f32..0.4, -0.4f32..0.4),
    )
        .prop_map(|(shape, size, center, tilt)| LightSpec {
            shape,
            size,
            center,
            tilt,
        })
        .boxed()
}

/// A random box: centre in `[-2, 2]^2`, sides 0.1 to 1.2.
pub fn arb_box(r: &SceneRanges) -> BoxedStrategy<BoxSpec> {
    (
        (-2.0f32..2.0, -2.0f32..2.0),
        (0.1f32..1.2, 0.1f32..1.2),
        (r.box_bottom.clone(), r.box_height.clone()),
    )
        .prop_map(|((x, z), (sx, sz), (y0, h))| BoxSpec {
            x,
            z,
            sx,
            sz,
            y0,
            h,
        })
        .boxed()
}

/// A random scene: a light, up to 3 boxes, 1 to 159 ground receivers in `[-3.5, 3.5]^2`, up to
/// 11 on box tops, up to 15 grazing and 5 outside ones (when `r` draws them), and maybe every
/// m-th receiver inactive (m from 2 to 7).
pub fn arb_scene(r: &SceneRanges) -> BoxedStrategy<SceneSpec> {
    let grazing = if r.grazing {
        prop::collection::vec(
            (-3.5f32..3.5, -3.5f32..3.5, -0.05f32..0.05, 0.0f32..6.3),
            0..16,
        )
        .boxed()
    } else {
        Just(Vec::new()).boxed()
    };
    let outside = if r.outside {
        prop::collection::vec((0u8..3, -1.0f32..1.0, -1.0f32..1.0), 0..6).boxed()
    } else {
        Just(Vec::new()).boxed()
    };
    let ground_near_boxes = r.ground_near_boxes;
    (
        arb_light(r),
        prop::collection::vec(arb_box(r), 0..4),
        prop::collection::vec((-3.5f32..3.5, -3.5f32..3.5), 1..160),
        prop::collection::vec((0usize..4, 0.0f32..1.0, 0.0f32..1.0), 0..12),
        grazing,
        outside,
        prop::option::of(2usize..8),
    )
        .prop_map(
            move |(light, boxes, ground, tops, grazing, outside, inactive_every)| SceneSpec {
                light,
                boxes,
                ground,
                tops,
                grazing,
                outside,
                inactive_every,
                ground_near_boxes,
            },
        )
        .boxed()
}

/// A random case: a scene from `r`, then the method's settings.
pub fn arb_case<S: Strategy + 'static>(
    r: &SceneRanges,
    settings: S,
) -> BoxedStrategy<Case<S::Value>>
where
    S::Value: Clone + std::fmt::Debug,
{
    (arb_scene(r), settings)
        .prop_map(|(scene, settings)| Case { scene, settings })
        .boxed()
}

/// The depth bias of the random settings, `(bias, slope_bias)` in texel footprints: a quarter
/// of the cases in the acne regime (almost no bias), where depth ties abound.
pub fn arb_bias() -> impl Strategy<Value = (f32, f32)> {
    (
        prop_oneof![1 => 0.0f32..0.02, 3 => 0.2f32..3.0],
        prop_oneof![1 => Just(0.0f32), 3 => 0.0f32..3.0],
    )
}
