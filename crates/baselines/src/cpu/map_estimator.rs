//! One shadow map at the light centre, filtered per receiver: the CPU twin shared by the hard,
//! PCF and PCSS baselines. Each supplies only its [`Filter`].
use crate::cpu::encode_layer0;
use crate::settings::MapSettings;
use glam::{Vec2, Vec3};
use shadow_map_core::{
    light_space::LightSpace, light_view::LightView, Cancel, Configured, DepthLookup, Light,
    ParamSpec, Params, ReceiverPlane, Receivers, Report, Result, Scene, SoftShadowEstimator,
    TypedParams, Unorm16Map, Warning,
};
use std::sync::atomic::{AtomicUsize, Ordering};

/// What one receiver looks like to a filter: light-space position and normal, continuous texel
/// coordinates, and its caster test.
#[derive(Debug, Clone, Copy)]
pub struct ReceiverSample {
    /// Light-space position (z > n).
    pub p: Vec3,
    /// Light-space normal.
    pub n: Vec3,
    /// Continuous texel coordinates (inside the map).
    pub uv: Vec2,
    /// Which samples shadow this receiver: receiver-plane rejection, or the classic
    /// `z_s < p.z - eps` under `receiver_plane=false` (half a code step more under
    /// `depth=unorm16`, see [`shadow_map_core::precision`]).
    pub plane: ReceiverPlane,
}

impl ReceiverSample {
    /// True when the sample at depth `z` in texel (i, j) shadows this receiver.
    #[inline]
    pub fn caster(&self, i: i32, j: i32, z: f32) -> bool {
        self.plane.caster(i, j, z)
    }
    /// The texel the receiver projects into: `(floor u, floor v)`.
    #[inline]
    pub fn texel(&self) -> (i32, i32) {
        (self.uv.x.floor() as i32, self.uv.y.floor() as i32)
    }
}

/// What a filter reads besides the receiver: the shadow map (f32 or 16-bit), the view it was
/// rendered in, and the light.
pub struct MapLookup<'a, M> {
    /// The map's light view.
    pub view: &'a LightView,
    /// The shadow map.
    pub map: &'a M,
    /// The scene's light.
    pub light: &'a Light,
}

impl<M: DepthLookup> MapLookup<'_, M> {
    /// `1` when the map sample at texel (i, j) does not shadow the receiver `r`, else `0`.
    #[inline]
    pub fn lit(&self, i: i32, j: i32, r: &ReceiverSample) -> f32 {
        if r.caster(i, j, self.map.at(i, j)) {
            0.0
        } else {
            1.0
        }
    }
}

/// The per-receiver part of a single-map baseline.
pub trait Filter: Send + Sync + Sized {
    /// Registry name.
    const NAME: &'static str;
    /// One-line description.
    const DESCRIPTION: &'static str;
    /// Parameters: [`MapSettings::SPECS`] first, then the filter's own.
    const SPECS: &'static [ParamSpec];
    /// The filter with its own settings read from the parameters (a [`Params`] of
    /// [`SPECS`](Self::SPECS)).
    fn from_params(p: &Params) -> Result<Self>;
    /// Visibility of the light from the receiver as this filter estimates it, before the
    /// tangent-plane factor, in [0, 1], reading the shadow map of `at`.
    fn visibility<M: DepthLookup>(&self, at: &MapLookup<'_, M>, r: &ReceiverSample) -> f32;
    /// The tangent-plane factor: by default the exact fraction of the light in front of the
    /// receiver's tangent plane (contract: light behind the surface is blocked).
    fn facing(&self, light: &Light, p_world: Vec3, n_world: Vec3) -> f32 {
        light.front_fraction_world(p_world, n_world)
    }
}

/// The identity part of a [`Filter`] whose own settings are a `typed_params!` struct in
/// [`crate::settings`] (the implementing type itself): `NAME`, `DESCRIPTION`, the table
/// ([`MapSettings::SPECS`], then the struct's own) and `from_params` (the struct's).
macro_rules! filter_identity {
    ($name:literal, $description:literal) => {
        const NAME: &'static str = $name;
        const DESCRIPTION: &'static str = $description;
        const SPECS: &'static [shadow_map_core::ParamSpec] =
            shadow_map_core::concat_specs!(crate::settings::MapSettings::SPECS, Self::SPECS);
        fn from_params(p: &shadow_map_core::Params) -> shadow_map_core::Result<Self> {
            // The inherent `typed_params!` constructor (inherent items come first).
            Self::from_params(p)
        }
    };
}
pub(crate) use filter_identity;

/// The settings of a single-map baseline, both read from its filter's table
/// ([`Filter::SPECS`]): the shared [`MapSettings`] and the filter with its own.
struct MapConfig<F> {
    map: MapSettings,
    filter: F,
}

impl<F: Filter> TypedParams for MapConfig<F> {
    const SPECS: &'static [ParamSpec] = F::SPECS;
    fn from_params(p: &Params) -> Result<Self> {
        Ok(MapConfig {
            map: MapSettings::from_params(p)?,
            filter: F::from_params(p)?,
        })
    }
}

/// A [`SoftShadowEstimator`] from a [`Filter`]: builds one shadow map at the light centre, fitted
/// to the receivers, then runs the filter per receiver. Under `depth=unorm16` the map is encoded
/// to 16-bit codes after the build and the f32 layer is freed.
pub struct MapEstimator<F: Filter> {
    /// The parameters and their typed settings.
    config: Configured<MapConfig<F>>,
    ls: Option<LightSpace>,
    q16: Option<Unorm16Map>,
    report: Report,
    cancel: Cancel,
}

impl<F: Filter> MapEstimator<F> {
    /// With default parameters.
    pub fn new() -> Result<Self> {
        Ok(MapEstimator {
            config: Configured::new()?,
            ls: None,
            q16: None,
            report: Report::default(),
            cancel: Cancel::new(),
        })
    }
    /// The light-space data of the last build (for tests). Under `depth=unorm16` its layer 0 is
    /// empty (freed); the map is [`unorm16`](Self::unorm16).
    pub fn light_space(&self) -> Option<&LightSpace> {
        self.ls.as_ref()
    }
    /// The 16-bit map of the last build under `depth=unorm16`.
    pub fn unorm16(&self) -> Option<&Unorm16Map> {
        self.q16.as_ref()
    }

    /// [`build`](SoftShadowEstimator::build) in the caller's view (its resolution is the map's)
    /// instead of one fitted to the receivers: the CPU twin of the frame path's
    /// [`MapFrame`](crate::gpu::MapFrame), whose view the caller fits.
    pub fn build_in_view(&mut self, scene: &Scene, view: LightView) -> Result<()> {
        let mut req = self.config.settings().map.request();
        req.resolution = view.r;
        let ls = LightSpace::try_build_in_view(scene, view, Default::default(), &req)?;
        self.set_light_space(ls)
    }

    /// Takes `ls` as the light-space data of the following estimates instead of a build (layer
    /// 0 encoded to 16-bit codes under `depth=unorm16`, as `build` does): e.g. the map a GPU
    /// frame rendered, read back, so the filter runs on the very map the kernel read.
    pub fn set_light_space(&mut self, mut ls: LightSpace) -> Result<()> {
        self.report = Report::default();
        let q16 = encode_layer0(&mut ls, self.config.settings().map.depth);
        self.keep(ls, q16);
        Ok(())
    }

    /// Keeps the map (and its codes) for the following estimates and reports their bytes.
    fn keep(&mut self, ls: LightSpace, q16: Option<Unorm16Map>) {
        self.report.light_space_bytes = ls.bytes() + q16.as_ref().map_or(0, Unorm16Map::bytes);
        self.ls = Some(ls);
        self.q16 = q16;
    }
}

impl<F: Filter> SoftShadowEstimator for MapEstimator<F> {
    shadow_map_core::estimator_identity!(F::NAME, F::DESCRIPTION, Cpu, config: config, cancel: cancel);
    fn build(&mut self, scene: &Scene, receivers: &Receivers) -> Result<()> {
        self.report = Report::default();
        let settings = self.config.settings().map;
        let req = settings.request();
        let (ls, q16) = self.report.time("build", || -> Result<_> {
            let opts = settings.view;
            let mut ls = LightSpace::build_with(scene, receivers, &req, &opts)?;
            let q16 = encode_layer0(&mut ls, settings.depth);
            Ok((ls, q16))
        })?;
        self.keep(ls, q16);
        Ok(())
    }
    fn estimate(&mut self, scene: &Scene, receivers: &Receivers, v: &mut [f32]) -> Result<()> {
        receivers.check_output(v)?;
        let ls = shadow_map_core::estimator::built(self.ls.as_ref())?;
        let MapConfig { map, filter } = self.config.settings();
        let test = map.caster_test();
        let light = scene.light();
        let view = &ls.view;
        let t = std::time::Instant::now();
        let pass = FilterPass {
            cancel: &self.cancel,
            filter,
            receivers,
            test,
        };
        let (nonfinite, outside) = match &self.q16 {
            Some(q) => pass.run(
                &MapLookup {
                    view,
                    map: q,
                    light,
                },
                q.half_step(),
                v,
            )?,
            None => pass.run(
                &MapLookup {
                    view,
                    map: &ls.layers[0],
                    light,
                },
                0.0,
                v,
            )?,
        };
        self.report
            .stages
            .push(("estimate".into(), t.elapsed().as_secs_f64() * 1e3));
        self.report.note("resolution", view.r);
        self.report.note("near", view.n);
        self.report.note("far", view.far);
        self.report
            .note("out_of_frustum", outside + ls.fit.out_of_frustum);
        if let Some(q) = &self.q16 {
            self.report.note("depth_step", q.step);
        }
        self.report.note("window_scale", ls.fit.window_scale);
        self.report.warn(Warning::NonFiniteV {
            receivers: nonfinite,
        });
        self.report
            .warn(Warning::OutsideViews { receivers: outside });
        self.report.warn_all(Warning::opaque_casters(scene));
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

/// One filter over every receiver: what [`FilterPass::run`] reads besides the map.
struct FilterPass<'a, F> {
    cancel: &'a Cancel,
    filter: &'a F,
    receivers: &'a Receivers,
    /// The caster test `(receiver_plane, (b0, b1))`.
    test: (bool, (f32, f32)),
}

impl<F: Filter> FilterPass<'_, F> {
    /// Runs the filter over every receiver with the map of `at` (`extra_eps` is half a code step
    /// for 16-bit maps, else 0), writing V. Returns (non-finite results, receivers outside the
    /// frustum); `Err(Cancelled)` once `cancel` is set.
    fn run<M: DepthLookup>(
        &self,
        at: &MapLookup<'_, M>,
        extra_eps: f32,
        v: &mut [f32],
    ) -> Result<(usize, usize)> {
        let (view, light, filter) = (at.view, at.light, self.filter);
        let (on, biases) = self.test;
        let outside = AtomicUsize::new(0);
        let at_receiver = |pw: Vec3, nw: Vec3| {
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
            let plane = ReceiverPlane::new(on, view, p, n, biases, extra_eps);
            facing * filter.visibility(at, &ReceiverSample { p, n, uv, plane })
        };
        let nonfinite = self
            .receivers
            .estimate_each(self.cancel, v, |p, n| Some(at_receiver(p, n)))?;
        Ok((nonfinite, outside.into_inner()))
    }
}
