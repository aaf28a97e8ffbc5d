//! The reference as a [`SoftShadowEstimator`] (`--algo reference`).
use crate::trace::{visibility, TraceOptions};
use shadow_map_core::{
    estimator::{Report, SoftShadowEstimator},
    Cancel, Configured, ParamSpec, Receivers, Result, Scene, SceneBvh,
};

shadow_map_core::typed_params! {
    /// The reference's settings, one field a parameter.
    pub struct ReferenceSettings {
        /// light samples per receiver; rounded up to the next square s*s (s = ceil(sqrt(spp))),
        /// the count used is reported in the notes
        spp: u32 = ParamSpec::int(1, 65536, "1024"),
        /// seed of the deterministic sample jitter (same seed, same V bit for bit)
        seed: u64 = ParamSpec::int(0, 1 << 31, "1"),
    }
}

/// The reference's parameters.
pub const PARAMS: &[ParamSpec] = ReferenceSettings::SPECS;

/// Ray-traced ground truth: stratified light samples through the scene's BVH, with transmittance
/// for semi-transparent meshes ([`crate::trace`]).
///
/// `build` builds the [`SceneBvh`] (stage `build`); `estimate` traces (stage `estimate`). Notes:
/// `spp` (the sample count actually used, a square), `samples_per_side`, `seed`,
/// `active_receivers`, `triangles`.
pub struct ReferenceEstimator {
    /// The parameters and their typed settings.
    config: Configured<ReferenceSettings>,
    bvh: Option<SceneBvh>,
    report: Report,
    progress: bool,
    cancel: Cancel,
}

impl std::fmt::Debug for ReferenceEstimator {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ReferenceEstimator")
            .field("params", self.config.params())
            .field("built", &self.bvh.is_some())
            .field("progress", &self.progress)
            .finish()
    }
}

impl ReferenceEstimator {
    /// The reference at its defaults (1024 samples per receiver, seed 1), progress bar off. Fails
    /// only if a declared default does not parse (a bug).
    pub fn new() -> Result<Self> {
        Ok(ReferenceEstimator {
            config: Configured::new()?,
            bvh: None,
            report: Report::default(),
            progress: false,
            cancel: Cancel::new(),
        })
    }
    /// Turns the progress bar (standard error, large receiver sets only) on or off.
    pub fn with_progress(mut self, on: bool) -> Self {
        self.progress = on;
        self
    }
    /// Turns the progress bar on or off in place.
    pub fn set_progress(&mut self, on: bool) {
        self.progress = on;
    }
    /// The trace options the current parameters give (`s = ceil(sqrt(spp))`).
    pub fn options(&self) -> TraceOptions {
        let s = self.config.settings();
        TraceOptions::from_spp(s.spp, s.seed)
    }
}

impl SoftShadowEstimator for ReferenceEstimator {
    shadow_map_core::estimator_identity!(
        "reference",
        "ray-traced ground truth: stratified light samples through the BVH (transmittance for \
         semi-transparent meshes)",
        Cpu,
        config: config,
        cancel: cancel
    );
    fn build(&mut self, scene: &Scene, _receivers: &Receivers) -> Result<()> {
        self.report = Report::default();
        let bvh = self.report.time("build", || SceneBvh::new(scene));
        self.report.note("triangles", scene.triangles().len());
        self.bvh = Some(bvh);
        Ok(())
    }
    fn estimate(&mut self, scene: &Scene, receivers: &Receivers, v: &mut [f32]) -> Result<()> {
        receivers.check_output(v)?;
        if self.bvh.is_none() {
            // `estimate` without `build`: build now (timed as a stage of its own).
            let bvh = self.report.time("build", || SceneBvh::new(scene));
            self.bvh = Some(bvh);
        }
        let opts = self.options();
        let progress = self.progress;
        let mut out = Ok(());
        if let Some(bvh) = self.bvh.as_ref() {
            out = self.report.time("estimate", || {
                let cancel = &self.cancel;
                visibility(scene, bvh, receivers, &opts, v, progress, cancel)
            });
        }
        out?;
        self.report.note("spp", opts.samples());
        self.report.note("samples_per_side", opts.samples_per_side);
        self.report.note("seed", opts.seed);
        self.report
            .note("active_receivers", receivers.active_count());
        Ok(())
    }
    fn report(&self) -> Report {
        self.report.clone()
    }
}
