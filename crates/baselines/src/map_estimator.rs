//! One shadow map at the light centre, filtered per receiver: the frame shared by the hard, PCF
//! and PCSS baselines. Each supplies only its [`Filter`].
use crate::common::{self, receiver_bias};
use glam::{Vec2, Vec3};
use shadow_map_core::{
    light_space::LightSpace, light_view::ViewOptions, Backend, Error, Light, ParamSpec, Params,
    Receivers, Report, Result, Scene, SoftShadowEstimator,
};
use std::sync::atomic::{AtomicUsize, Ordering};

/// What one receiver looks like to a filter: light-space position and normal, continuous texel
/// coordinates, and its depth bias.
#[derive(Debug, Clone, Copy)]
pub struct ReceiverSample {
    /// Light-space position (z > n).
    pub p: Vec3,
    /// Light-space normal.
    pub n: Vec3,
    /// Continuous texel coordinates (inside the map).
    pub uv: Vec2,
    /// Depth bias in world units: a sample occludes when `z_s < p.z - eps`.
    pub eps: f32,
}

/// The per-receiver part of a single-map baseline.
pub trait Filter: Send + Sync {
    /// Registry name.
    const NAME: &'static str;
    /// One-line description.
    const DESCRIPTION: &'static str;
    /// Parameters (the shared resolution/bias/cull ones included).
    const SPECS: &'static [ParamSpec];
    /// Reads the typed settings from the parameters.
    fn from_params(p: &Params) -> Self;
    /// Visibility of the light from the receiver as this filter estimates it, before the
    /// tangent-plane factor, in [0, 1].
    fn visibility(&self, ls: &LightSpace, light: &Light, r: &ReceiverSample) -> f32;
    /// The tangent-plane factor: by default the exact fraction of the light in front of the
    /// receiver's tangent plane (contract: light behind the surface is blocked).
    fn facing(&self, light: &Light, p_world: Vec3, n_world: Vec3) -> f32 {
        light.front_fraction_world(p_world, n_world)
    }
}

/// A [`SoftShadowEstimator`] from a [`Filter`]: builds one shadow map at the light centre, fitted
/// to the receivers, then runs the filter per receiver.
pub struct MapEstimator<F: Filter> {
    params: Params,
    ls: Option<LightSpace>,
    report: Report,
    _f: std::marker::PhantomData<F>,
}

impl<F: Filter> MapEstimator<F> {
    /// With default parameters.
    pub fn new() -> Result<Self> {
        Ok(MapEstimator {
            params: Params::new(F::SPECS)?,
            ls: None,
            report: Report::default(),
            _f: Default::default(),
        })
    }
    /// The light-space data of the last build (for tests and the GPU twin).
    pub fn light_space(&self) -> Option<&LightSpace> {
        self.ls.as_ref()
    }
}

impl<F: Filter> SoftShadowEstimator for MapEstimator<F> {
    fn name(&self) -> &'static str {
        F::NAME
    }
    fn description(&self) -> &'static str {
        F::DESCRIPTION
    }
    fn backend(&self) -> Backend {
        Backend::Cpu
    }
    fn params(&self) -> &Params {
        &self.params
    }
    fn set_param(&mut self, key: &str, value: &str) -> Result<()> {
        self.params.set(key, value)
    }
    fn build(&mut self, scene: &Scene, receivers: &Receivers) -> Result<()> {
        self.report = Report::default();
        let req = common::map_request(&self.params);
        let ls = self.report.time("build", || {
            let opts = ViewOptions::from_params(&self.params);
            LightSpace::build_with(scene, receivers, &req, &opts)
        })?;
        self.report.light_space_bytes = ls.bytes();
        self.ls = Some(ls);
        Ok(())
    }
    fn estimate(&mut self, scene: &Scene, receivers: &Receivers, v: &mut [f32]) -> Result<()> {
        common::check_len(receivers, v)?;
        let ls = self
            .ls
            .as_ref()
            .ok_or_else(|| Error::param("build", "estimate called before build"))?;
        let filter = F::from_params(&self.params);
        let (b0, b1) = (
            self.params.float("bias") as f32,
            self.params.float("slope_bias") as f32,
        );
        let light = &scene.light;
        let view = &ls.view;
        let outside = AtomicUsize::new(0);
        let t = std::time::Instant::now();
        let nonfinite = common::for_each_receiver(receivers, v, |pw, nw| {
            let facing = filter.facing(light, pw, nw);
            if facing <= 0.0 {
                return 0.0;
            }
            let p = view.frame.to_light(pw);
            let n = view.frame.dir_to_light(nw);
            if p.z <= view.n {
                // Nearer than anything the map records (or behind a sphere light's frustum).
                if p.z <= 0.0 {
                    outside.fetch_add(1, Ordering::Relaxed);
                }
                return facing;
            }
            let uv = view.project(p);
            if !view.contains(uv) {
                outside.fetch_add(1, Ordering::Relaxed);
                return facing;
            }
            let eps = receiver_bias(view, p, n, b0, b1);
            facing * filter.visibility(ls, light, &ReceiverSample { p, n, uv, eps })
        });
        self.report
            .stages
            .push(("estimate".into(), t.elapsed().as_secs_f64() * 1e3));
        self.report.note("resolution", view.r);
        self.report.note("near", view.n);
        self.report.note("far", view.far);
        self.report.note(
            "out_of_frustum",
            outside.into_inner() + ls.fit.out_of_frustum,
        );
        self.report.note("window_scale", ls.fit.window_scale);
        if nonfinite > 0 {
            self.report.note("nonfinite_replaced", nonfinite);
        }
        if matches!(light.shape, shadow_map_core::LightShape::Sphere { .. }) {
            self.report.note(
                "approximation",
                "sphere light filtered as the disk perpendicular to the light normal (exact on the light axis)",
            );
        }
        Ok(())
    }
    fn report(&self) -> Report {
        self.report.clone()
    }
}

/// `1` when the map sample at texel (i, j) does not occlude a receiver at depth `z - eps`.
#[inline]
pub fn lit(ls: &LightSpace, i: i32, j: i32, z: f32, eps: f32) -> f32 {
    if ls.layers[0].at(i, j) < z - eps {
        0.0
    } else {
        1.0
    }
}

/// Splits `[a, b)` (texel coordinates) into at most `max` cells: whole texels clipped to the
/// interval when it spans at most `max` texels, equal cells otherwise. Yields
/// `(texel index sampled, weight = cell length)`.
pub fn cells(a: f32, b: f32, max: u32, mut f: impl FnMut(i32, f32)) {
    let len = b - a;
    if !(len > 0.0) {
        f(a.floor() as i32, 1.0);
        return;
    }
    let first = a.floor() as i64;
    let last = (b.ceil() as i64 - 1).max(first);
    if (last - first + 1) as u64 <= max as u64 {
        for i in first..=last {
            let lo = (i as f32).max(a);
            let hi = ((i + 1) as f32).min(b);
            if hi > lo {
                f(i as i32, hi - lo);
            }
        }
    } else {
        let step = len / max as f32;
        for k in 0..max {
            let c = a + (k as f32 + 0.5) * step;
            f(c.floor() as i32, step);
        }
    }
}
