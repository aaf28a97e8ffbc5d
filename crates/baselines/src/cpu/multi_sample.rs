//! Multi-sample shadows (Heckbert & Herf 1997; docs/methods.md §6): the average of S x S hard
//! shadow maps rendered from jittered stratified points on the light, the papers' brute-force
//! reference. Only one map is alive at a time.
use super::encode_layer0;
use crate::math::{inv_samples, jitter};
use crate::settings::{
    MultiSampleParams, MultiSampleSettings, MULTI_SAMPLE_DESCRIPTION, MULTI_SAMPLE_NAME,
};
use shadow_map_core::{
    light_space::LightSpace, Cancel, Configured, DepthLookup, Error, LightShape, ReceiverPlane,
    Receivers, Report, Result, Scene, SoftShadowEstimator, Unorm16Map, Warning,
};

/// `V(p) = (1/N) sum_k [y_k in front of p's tangent plane] [z_k(p) - eps_k <= D_k(u_k(p))]`
/// over N = S^2 jittered strata y_k of the light (concentric-mapped for disks). Each map has its
/// centre of projection at y_k with axes parallel to the light frame and its own fitted window.
///
/// Sphere lights: the samples lie on the disk through the centre perpendicular to the light
/// normal, which equals the contract's silhouette disk only for receivers on the light axis
/// (an approximation, labelled in `--stats`).
///
/// The sun: the strata y_k cover its disk of directions at unit distance and each map is an
/// orthographic view along `e_z + y_k` (docs/methods.md §14 "Multi-sample"): exact sampling of the contract's
/// V, as for rect and disk lights.
pub struct MultiSample {
    /// The parameters and their typed settings.
    config: Configured<MultiSampleSettings>,
    report: Report,
    cancel: Cancel,
}

impl MultiSample {
    /// With default parameters.
    pub fn new() -> Result<Self> {
        Ok(MultiSample {
            config: Configured::new()?,
            report: Report::default(),
            cancel: Cancel::new(),
        })
    }
}

impl SoftShadowEstimator for MultiSample {
    shadow_map_core::estimator_identity!(MULTI_SAMPLE_NAME, MULTI_SAMPLE_DESCRIPTION, Cpu, config: config, cancel: cancel);
    fn build(&mut self, _scene: &Scene, _receivers: &Receivers) -> Result<()> {
        // Multi-view: each sub-light's map is built inside `estimate`, one at a time.
        self.report = Report::default();
        Ok(())
    }
    fn estimate(&mut self, scene: &Scene, receivers: &Receivers, v: &mut [f32]) -> Result<()> {
        let MultiSampleSettings {
            map: settings,
            sample: MultiSampleParams { sublights: s, seed },
        } = *self.config.settings();
        let (req, opts) = (settings.request(), settings.view);
        let points = scene.light().stratified_points(s, |k| jitter(seed, k));
        let maps = points
            .iter()
            .map(|y| LightSpace::build_point_with(scene, receivers, *y, &req, &opts));
        self.accumulate(scene, receivers, v, maps)
    }
    fn report(&self) -> Report {
        self.report.clone()
    }
}

impl MultiSample {
    /// [`estimate`](SoftShadowEstimator::estimate) in the caller's sub-light views, one per
    /// stratum in the order of [`Light::stratified_points`](shadow_map_core::Light::stratified_points) (`None`: a sub-light no receiver is
    /// in front of, counted in N): the CPU twin of the frame path's
    /// [`MultiSampleFrame`](crate::gpu::MultiSampleFrame), whose views the caller fits.
    pub fn estimate_in_views(
        &mut self,
        scene: &Scene,
        receivers: &Receivers,
        views: &[Option<shadow_map_core::LightView>],
        v: &mut [f32],
    ) -> Result<()> {
        self.report = Report::default();
        let req = self.config.settings().map.request();
        let maps = views.iter().map(|view| match view {
            Some(view) => LightSpace::try_build_in_view(scene, *view, Default::default(), &req),
            None => Err(Error::LightView(
                "no receiver in front of this sub-light".into(),
            )),
        });
        self.accumulate(scene, receivers, v, maps)
    }

    /// [`estimate`](SoftShadowEstimator::estimate) on the caller's light-space data, one per
    /// stratum in the order of [`estimate_in_views`](Self::estimate_in_views) (`None`: a
    /// sub-light no receiver is in front of, counted in N; layer 0 encoded to 16-bit codes under
    /// `depth=unorm16`): e.g. the maps a GPU frame rendered, read back, so the per-sample test
    /// runs on the very maps the kernel read.
    pub fn estimate_in_light_spaces(
        &mut self,
        scene: &Scene,
        receivers: &Receivers,
        light_spaces: Vec<Option<LightSpace>>,
        v: &mut [f32],
    ) -> Result<()> {
        self.report = Report::default();
        let maps = light_spaces.into_iter().map(|ls| {
            ls.ok_or_else(|| Error::LightView("no receiver in front of this sub-light".into()))
        });
        self.accumulate(scene, receivers, v, maps)
    }

    /// V from one light space per sub-light (`Err(Error::LightView)`: a sub-light that lights
    /// nothing, counted in N).
    fn accumulate(
        &mut self,
        scene: &Scene,
        receivers: &Receivers,
        v: &mut [f32],
        mut maps: impl ExactSizeIterator<Item = Result<LightSpace>>,
    ) -> Result<()> {
        receivers.check_output(v)?;
        let MultiSampleSettings {
            map: settings,
            sample: MultiSampleParams { sublights: s, .. },
        } = *self.config.settings();
        let (on, biases) = settings.caster_test();
        let precision = settings.depth;
        let light = *scene.light();
        let n_points = maps.len();
        let frame = light.frame();
        let mut acc = vec![0.0f32; receivers.len()];
        let (mut t_build, mut t_est) = (0.0, 0.0);
        let mut peak = 0usize;
        let mut behind = 0usize;
        loop {
            // Between sub-lights, before `next()` builds another map.
            self.cancel.check()?;
            let Some(built) = maps.next() else { break };
            let t = std::time::Instant::now();
            let mut ls = match built {
                Ok(ls) => ls,
                // No receiver in front of this light point: it lights nothing.
                Err(Error::LightView(_)) => continue,
                Err(e) => return Err(e),
            };
            let q16 = encode_layer0(&mut ls, precision);
            let half_step = q16.as_ref().map_or(0.0, Unorm16Map::half_step);
            t_build += t.elapsed().as_secs_f64() * 1e3;
            peak = peak.max(ls.bytes() + q16.as_ref().map_or(0, Unorm16Map::bytes));
            behind = behind.max(ls.fit.out_of_frustum);
            let t = std::time::Instant::now();
            let view = &ls.view;
            let yw = view.frame.origin;
            // The sun: y is a point of its disk of directions and the view looks along
            // e_z + y_x e_x + y_y e_y (docs/methods.md §14 "Multi-sample"); the light arrives from -e_z.
            let toward_sun = view.is_ortho().then_some(-view.frame.ez);
            self.cancel.par_for_each(&mut acc, |k, a| {
                if !receivers.active()[k] {
                    return;
                }
                let (pw, nw) = (receivers.position()[k], receivers.normal()[k]);
                let towards = toward_sun.unwrap_or(yw - pw);
                if nw.dot(towards) <= 0.0 {
                    return; // the sample is behind the receiver's tangent plane
                }
                let p = view.frame.to_light(pw);
                if p.z <= 0.0 {
                    return; // behind this light point: no light from it
                }
                if p.z <= view.n {
                    *a += 1.0;
                    return;
                }
                let uv = view.project(p);
                if !view.contains(uv) {
                    *a += 1.0;
                    return;
                }
                let n = view.frame.dir_to_light(nw);
                let plane = ReceiverPlane::new(on, view, p, n, biases, half_step);
                let (i, j) = (uv.x.floor() as i32, uv.y.floor() as i32);
                let z = match &q16 {
                    Some(q) => q.at(i, j),
                    None => ls.layers[0].at(i, j),
                };
                if !plane.caster(i, j, z) {
                    *a += 1.0;
                }
            })?;
            t_est += t.elapsed().as_secs_f64() * 1e3;
        }
        let inv = inv_samples(n_points);
        let one_sided = light.one_sided();
        for (k, out) in v.iter_mut().enumerate() {
            *out = if !receivers.active()[k] {
                f32::NAN
            } else if one_sided && frame.to_light(receivers.position()[k]).z <= 0.0 {
                0.0
            } else {
                (acc[k] * inv).clamp(0.0, 1.0)
            };
        }
        note_run(&mut self.report, (t_build, t_est), peak, s, behind, &light);
        self.report.warn_all(Warning::opaque_casters(scene));
        Ok(())
    }
}

/// The report of one multi-sample run: build and estimate stage times (ms), peak light-space
/// bytes, the `S x S` sub-lights, receivers behind every sub-light's frustum, and the
/// sphere-light approximation when it applies.
fn note_run(
    report: &mut Report,
    (t_build, t_est): (f64, f64),
    peak: usize,
    s: u32,
    behind: usize,
    light: &shadow_map_core::Light,
) {
    report.stages.push(("build".into(), t_build));
    report.stages.push(("estimate".into(), t_est));
    report.light_space_bytes = peak;
    report.note("sublights", s * s);
    report.note("out_of_frustum", behind);
    report.warn(Warning::OutsideViews { receivers: behind });
    if matches!(light.shape, LightShape::Sphere { .. }) {
        report.note(
            "approximation",
            "sphere sampled on the disk perpendicular to the light normal",
        );
    }
}
