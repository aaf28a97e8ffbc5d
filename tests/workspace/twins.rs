//! End to end across backends: every estimator with a GPU twin, built from the scene by each
//! backend (the GPU rasterises its own maps), on every fixture, over the same receivers. Unlike the
//! per-crate twin tests (identical light-space data, |dV| <= 1e-4), this includes the rasterisers'
//! differences on texels that straddle a triangle edge (about 0.006% of covered texels on random
//! scenes, see `crates/shadow-map-core/tests/shadow_map_core/gpu_maps.rs`), so it bounds the fraction of receivers
//! that differ, and the RMSE of the soft estimators (a hard test flips a whole receiver from 0 to 1
//! on such a texel: its RMSE on a small image says little).
use shadow_map_core::{run, Receivers, Scene, SceneBvh};
use softshadow::{backends, estimator, Backend, Error, ALGOS};
use test_support::gate::context_for_tests;

/// Largest RMSE between the backends on a fixture, for the soft estimators (PCF, PCSS). The worst
/// measured is the strands fixture (ribbons two to three texels wide at r = 512, so most of their
/// texels straddle an edge): 2.5e-3 for PCF.
const MAX_RMSE_SOFT: f64 = 5e-3;
/// A receiver "differs" when its V moves by more than this between the backends. (PCSS averages
/// blocker depths over its search region, so one straddled texel moves V by ~1e-4 over a whole
/// penumbra: 10% of the strands receivers move by more than 1e-4, none by more than 1e-2.)
const DIFF: f64 = 1e-2;
/// Largest fraction of receivers that differ.
const MAX_DIFFERING: f64 = 0.01;

/// The light-view and depth options (common techniques) joined to the cross-backend test: each
/// set is applied to every estimator that declares all its keys, on the fixtures listed.
/// Parameter settings, `(key, value)`.
type Settings = &'static [(&'static str, &'static str)];

const OPTION_SETS: &[(&[&str], Settings)] = &[
    (
        &[
            "parallel-squares",
            "overlapping",
            "thin-sticks",
            "strands",
            "sphere-light",
            "bunny",
        ],
        &[],
    ),
    (&["bunny", "sphere-light"], &[("depth", "unorm16")]),
    (
        &["bunny", "thin-sticks"],
        &[("fit", "stable"), ("nearfar", "aabb")],
    ),
    (
        &["bunny", "strands"],
        &[
            ("fit", "scene"),
            ("nearfar", "frustum"),
            ("depth", "unorm16"),
        ],
    ),
];

#[test]
fn gpu_backend_matches_cpu_backend_on_every_fixture() {
    let Some(_ctx) = context_for_tests("gpu_backend_matches_cpu_backend_on_every_fixture").unwrap()
    else {
        return;
    };
    let dir = concat!(env!("CARGO_MANIFEST_DIR"), "/fixtures");
    let mut worst = (0.0f64, 0.0f64);
    for (fixture, options) in OPTION_SETS
        .iter()
        .flat_map(|(fs, o)| fs.iter().map(move |f| (*f, *o)))
    {
        let mut scene = Scene::load(format!("{dir}/{fixture}/{fixture}.toml")).unwrap();
        scene.set_resolution(96, 72).unwrap();
        let rec = Receivers::from_camera(&scene, &SceneBvh::new(&scene));
        for &algo in ALGOS.iter().filter(|a| backends(a).contains(&"gpu")) {
            let has = |k: &str| {
                estimator(algo, Backend::Cpu)
                    .unwrap()
                    .params()
                    .specs()
                    .iter()
                    .any(|s| s.key == k)
            };
            if !options.iter().all(|(k, _)| has(k)) {
                continue;
            }
            let mut out = Vec::new();
            let mut refused = Vec::new();
            for backend in [Backend::Cpu, Backend::Gpu] {
                let mut e = estimator(algo, backend).unwrap();
                e.set_param("resolution", "512").unwrap();
                for (k, v) in options {
                    e.set_param(k, v).unwrap();
                }
                match run(e.as_mut(), &scene, &rec) {
                    Ok((v, _)) => out.push(v),
                    // An estimator may refuse a light shape it does not model (backprojection:
                    // rect lights only), but both backends must refuse it the same way.
                    Err(Error::Param { key, reason }) if key == "light" => refused.push(reason),
                    Err(e) => panic!("{algo} on {fixture} ({backend}): {e}"),
                }
            }
            if !refused.is_empty() {
                assert!(
                    refused.len() == 2 && refused[0] == refused[1],
                    "{algo} on {fixture}: {refused:?}"
                );
                continue;
            }
            let (mut sq, mut n, mut differing) = (0.0f64, 0usize, 0usize);
            for ((&c, &g), &active) in out[0].iter().zip(&out[1]).zip(rec.active()) {
                if !active {
                    assert!(
                        c.is_nan() && g.is_nan(),
                        "{algo} on {fixture}: background {c} / {g}"
                    );
                    continue;
                }
                assert!((0.0..=1.0).contains(&g), "{algo} on {fixture}: GPU V = {g}");
                let d = (c - g) as f64;
                sq += d * d;
                n += 1;
                differing += usize::from(d.abs() > DIFF);
            }
            let rmse = (sq / n as f64).sqrt();
            let frac = differing as f64 / n as f64;
            eprintln!(
                "{algo:>12} on {fixture:<16} {options:?}: rmse {rmse:.2e}, differing {frac:.4}"
            );
            if algo == "pcf" || algo == "pcss" {
                assert!(
                    rmse <= MAX_RMSE_SOFT,
                    "{algo} on {fixture} {options:?}: rmse {rmse}"
                );
            }
            assert!(
                frac <= MAX_DIFFERING,
                "{algo} on {fixture} {options:?}: {frac} of receivers differ"
            );
            worst = (worst.0.max(rmse), worst.1.max(frac));
        }
    }
    eprintln!(
        "worst rmse {:.2e}, worst differing fraction {:.4}",
        worst.0, worst.1
    );
}
