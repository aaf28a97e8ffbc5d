//! What adding a method takes (docs/layout.md, "Add an algorithm"): a toy method, `unshadowed`
//! (V = the light's fraction in front of each receiver's tangent plane, no caster), written the
//! way a method crate writes one: a CPU estimator, its parameter table, its descriptor. The
//! registry line is the only other edit; here the descriptor is checked the way the registry's
//! own tests check every listed one (it runs on a fixture, its sweep applies, its name is new).
use shadow_map_core::{
    estimator_identity,
    light_view::RESOLUTION,
    method::{MethodDescriptor, Sweep},
    Cancel, ParamSpec, Params, Receivers, Report, Result, Scene, SceneBvh, SoftShadowEstimator,
};

/// The toy's one parameter (shared from core, so the report's resolution sweep applies; the toy
/// ignores it).
const SPECS: &[ParamSpec] = &[RESOLUTION];

struct Unshadowed {
    params: Params,
}

impl Unshadowed {
    fn new() -> Result<Self> {
        Ok(Unshadowed {
            params: Params::new(SPECS)?,
        })
    }
}

impl SoftShadowEstimator for Unshadowed {
    estimator_identity!(
        "unshadowed",
        "the light's fraction in front of the receiver, no caster",
        Cpu,
        params
    );
    fn set_param(&mut self, key: &str, value: &str) -> Result<()> {
        self.params.set(key, value)
    }
    fn build(&mut self, _scene: &Scene, _receivers: &Receivers) -> Result<()> {
        Ok(())
    }
    fn estimate(&mut self, scene: &Scene, receivers: &Receivers, v: &mut [f32]) -> Result<()> {
        receivers.check_output(v)?;
        for (k, out) in v.iter_mut().enumerate() {
            *out = if receivers.active()[k] {
                scene
                    .light()
                    .front_fraction_world(receivers.position()[k], receivers.normal()[k])
            } else {
                f32::NAN
            };
        }
        Ok(())
    }
    fn report(&self) -> Report {
        Report::default()
    }
    fn set_cancel(&mut self, _cancel: Cancel) {}
}

/// The toy's descriptor, as its crate's `lib.rs` would export it (a GPU method adds
/// `.with_frame(..)`, its frame, under its `gpu` feature).
const UNSHADOWED: MethodDescriptor = MethodDescriptor::new(
    "unshadowed",
    || Ok(Box::new(Unshadowed::new()?)),
    Sweep::RESOLUTIONS,
);

#[test]
fn a_toy_method_needs_its_estimator_and_one_descriptor() {
    assert!(
        !softshadow::ALGOS.contains(&UNSHADOWED.name()),
        "the toy's name is taken"
    );
    assert!(!UNSHADOWED.has_gpu() && !UNSHADOWED.has_frame());
    let scene = Scene::load(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/fixtures/bunny/bunny.toml"
    ))
    .unwrap();
    let rec = Receivers::from_camera(&scene, &SceneBvh::new(&scene));
    let mut e = UNSHADOWED.cpu().unwrap();
    assert_eq!(e.name(), UNSHADOWED.name());
    for s in UNSHADOWED.sweep(true) {
        for (k, v) in &s {
            e.set_param(k, v).unwrap();
        }
    }
    let (v, _) = shadow_map_core::run(e.as_mut(), &scene, &rec).unwrap();
    let active = rec.active_count();
    assert!(active > 0);
    let lit = (0..rec.len())
        .filter(|&k| rec.active()[k] && v[k].is_finite() && (0.0..=1.0).contains(&v[k]))
        .count();
    assert_eq!(lit, active, "every active receiver gets a V in [0, 1]");
    // No casters: the toy is an upper bound of the ray-traced truth (up to its noise: at 16
    // samples 129 of the bunny's receivers lie more than 0.05 above it, at 256 none).
    let mut reference = softshadow::estimator("reference", softshadow::Backend::Cpu).unwrap();
    reference.set_param("spp", "256").unwrap();
    let (truth, _) = shadow_map_core::run(reference.as_mut(), &scene, &rec).unwrap();
    let above = (0..rec.len())
        .filter(|&k| rec.active()[k] && truth[k] > v[k] + 0.05)
        .count();
    assert_eq!(
        above, 0,
        "the reference saw more light than an unshadowed receiver"
    );
}
