//! Deep-shadow's GPU estimator (its engine path, [`DeepShadowFrame`], run by the core's
//! `FrameTwin`) against the CPU twin: the conformance suite of `test-support`
//! (`twin::deep_shadow`), with what is specific to deep shadow maps here: random stacks of
//! sheets ([`crate::random_sheets`]), the estimators on fixtures (the CLI path) and the loop
//! budget. Cases: 8 by default, `SOFTSHADOW_PROPTEST_CASES=N` for more.
#![cfg(feature = "gpu")]
use crate::common::{check_contract, fixture, note, params};
use crate::on_map::{assert_fixture_within, frame_on_its_map, raster_bound};
use crate::random_sheets::{arb_case, random_case, Frames, MapTally, T_TOL};
use deep_shadow::{settings::SPECS, CpuDeepShadow, DeepShadowFrame};
use glam::Vec3;
use shadow_map_core::{gpu::GpuContext, run, Scene, SoftShadowEstimator};
use std::sync::Arc;
use test_support::{
    conformance::{random_twins, table, BoxedFrame, FixedCase, TwinPair},
    frame_run::run_frame,
    proptest_config,
    tolerance::{RunStats, Tolerance},
};

test_support::twin_suite! {
    deep_shadow [
        cli_path_matches_the_cpu_twin,
        frame_path_matches_the_cpu_twin,
        loop_limit_is_detected_and_redone
    ] => DeepShadow,
}

/// The fixture `strands` at 32 x 24 with every seventh receiver inactive, `pcf` over 5 x 5.
fn strands_case() -> FixedCase {
    let (scene, mut receivers) = fixture("strands", 32, 24);
    for (k, a) in receivers.active_mut().iter_mut().enumerate() {
        if k % 7 == 6 {
            *a = false;
        }
    }
    let params = [("resolution", "128"), ("filter", "pcf"), ("kernel", "5")];
    FixedCase {
        scene,
        receivers,
        params: params.iter().map(|(k, v)| (*k, v.to_string())).collect(),
    }
}

/// The deep-shadow twins, as the conformance suite drives them.
struct DeepShadow;

impl TwinPair for DeepShadow {
    test_support::twin_constructors!(
        CpuDeepShadow,
        descriptor = deep_shadow::DESCRIPTOR,
        fixed = strands_case()
    );

    /// The engine path on the strands (semi-transparent: the frame builds lists, as the CPU
    /// twin does).
    fn frame(
        &self,
        ctx: &Arc<GpuContext>,
        params: &test_support::conformance::Params,
    ) -> Option<BoxedFrame> {
        let t = table(SPECS, params);
        Some(Box::new(
            DeepShadowFrame::prepare(ctx.clone(), &t, 1 << 16).unwrap(),
        ))
    }

    /// The engine path renders its lists with the hardware rasteriser (fragments inserted by a
    /// fragment shader), whose sub-pixel vertex snapping (8 bits on lavapipe) can cover a texel
    /// centre within 1/256 texel of a strand's edge that the CPU's exact fill rule does not, or
    /// the reverse: on the strands (filter=pcf, 5 x 5) a receiver then moves by a tap's
    /// transmittance over 25. Checked: at most 1% of the receivers beyond 1e-4, none beyond
    /// 2 / 25 (two taps), RMSE within 3e-3; and V is the semi-transparent scene's, far from the
    /// CPU twin's on the scene made opaque.
    fn frame_path_matches_the_cpu_twin(&self, ctx: &Arc<GpuContext>) {
        let case = strands_case();
        let frame = self.frame(ctx, &case.params).expect("engine path");
        assert!(frame.models_opacity());
        let c = test_support::conformance::frames_match_the_cpu_twin(
            "deep-shadow strands",
            ctx,
            &*frame,
            &case.scene,
            &case.receivers,
        );
        assert_eq!(c.status.left_nan, 0, "{:?}", c.status);
        assert!(
            c.active > 0 && c.beyond * 100 <= c.active && c.max_dv <= 2.0 / 25.0 && c.rmse <= 3e-3,
            "{} of {} beyond 1e-4, max |dV| {}, rmse {}",
            c.beyond,
            c.active,
            c.max_dv,
            c.rmse
        );
        let views = frame.fit_views(&case.scene, &case.receivers).unwrap();
        let opaque = frame
            .cpu_twin(&case.scene.opaque(), &case.receivers, &views)
            .unwrap();
        let apart = test_support::fixtures::rmse(&c.v, &opaque, case.receivers.active());
        println!("deep-shadow strands: frame RMSE to the opaque scene's CPU twin {apart:.3}");
        assert!(
            apart > 10.0 * c.rmse.max(1e-3),
            "V is the opaque scene's: {apart}"
        );
    }

    /// The frame's maps and V against the CPU twin's on random stacks of sheets
    /// ([`random_case`]).
    fn random_scenes(&self, ctx: &Arc<GpuContext>, source_file: &'static str) {
        let mut tally = MapTally::default();
        let mut frames = Frames::default();
        let tol = Tolerance {
            abs: T_TOL,
            ..Tolerance::TWIN
        };
        let st = random_twins(
            "deep-shadow random sheets",
            proptest_config(source_file, 8),
            &arb_case(),
            &tol,
            |c| random_case(ctx, c, &mut tally, &mut frames).map(Some),
        );
        println!("deep-shadow random sheets: maps compared {tally:?}");
        assert!(
            tally.lists > 0 && tally.depths > 0 && tally.fragments > 0,
            "{tally:?}"
        );
        st.assert_met("deep-shadow random sheets", true, true, true);
    }

    /// Lists long enough to spend llvmpipe's loop budget (65535 iterations per invocation):
    /// 1500 stacked sheets of opacity 0.002 over a ground, no truncation (`epsilon=0`), so
    /// every covered texel holds a list of 1500 elements, sorted by selection (past 64) in
    /// `process`, and the receivers on the ground under them walk whole lists at each of the
    /// 7 x 7 PCF taps (`traversal=naive`). The frame leaves the receivers its cut `process` or
    /// lookups reach NaN and counts them (status word 2); the GPU estimator redoes them with the
    /// CPU twin in the same views (`frame_cpu_redo`): V must equal the CPU twin's on any device,
    /// and on llvmpipe the cut must have happened (the probe is what found it).
    fn loop_limit_is_detected_and_redone(&self, ctx: &Arc<GpuContext>) {
        let light = test_support::fixtures::rect_light(1.0, 3.0);
        let mut meshes = vec![(test_support::fixtures::quad(-4.0, -4.0, 4.0, 4.0, 0.0), 1.0)];
        for k in 0..1500 {
            let y = 1.0 + k as f32 * 0.0004;
            meshes.push((test_support::fixtures::quad(-1.0, -1.0, 1.0, 1.0, y), 0.002));
        }
        let scene = Scene::from_meshes(
            "stacked sheets",
            test_support::fixtures::camera(8, 6),
            light,
            meshes,
        )
        .unwrap();
        let pos: Vec<Vec3> = (0..36)
            .map(|k| {
                Vec3::new(
                    -0.7 + 0.28 * (k % 6) as f32,
                    0.0,
                    -0.7 + 0.28 * (k / 6) as f32,
                )
            })
            .collect();
        let rec = test_support::fixtures::points(pos, Vec3::Y);
        let kv = [
            ("resolution", "16"),
            ("filter", "pcf"),
            ("kernel", "7"),
            ("traversal", "naive"),
            ("epsilon", "0"),
        ];
        let mut c = CpuDeepShadow::new().unwrap();
        let mut g = self.gpu(ctx);
        for (k, v) in kv {
            c.set_param(k, v).unwrap();
            g.set_param(k, v).unwrap();
        }
        // The GPU estimator's V, then the CPU twin's.
        let (vg, rg) = run(&mut *g, &scene, &rec).unwrap();
        let (vc, _) = run(&mut c, &scene, &rec).unwrap();
        // The frame alone: the receivers it cuts are NaN and counted, the others the CPU's.
        let frame = DeepShadowFrame::prepare(ctx.clone(), &params(&kv), rec.len() as u32).unwrap();
        let (_, out) = run_frame(ctx, &frame, &scene, &rec).unwrap();
        let (vf, st) = (out.v, out.status.expect("deep-shadow's frame has a status"));
        let cut = (0..rec.len()).filter(|&k| vf[k].is_nan()).count();
        assert_eq!(cut, st.left_nan as usize, "{st:?}");
        for k in (0..rec.len()).filter(|&k| !vf[k].is_nan()) {
            assert!(
                (vf[k] - vc[k]).abs() <= 1e-4,
                "receiver {k}: {} vs {}",
                vf[k],
                vc[k]
            );
        }
        // The GPU estimator: every cut receiver redone on the CPU.
        let redone = note(&rg, "frame_cpu_redo").unwrap_or_else(|| "0".into());
        eprintln!(
            "loop-limit CPU redo on {}: {redone} of {} receivers (the frame alone: {cut} cut)",
            ctx.describe(),
            rec.len(),
        );
        assert_eq!(redone, cut.to_string(), "{rg:?}");
        for (k, (a, b)) in vc.iter().zip(&vg).enumerate() {
            assert!((a - b).abs() <= 1e-6, "receiver {k}: CPU {a}, GPU {b}");
        }
        assert!(
            vc.iter().any(|&v| v < 0.2),
            "the sheets should shadow: {vc:?}"
        );
        if ctx.describe().contains("llvmpipe") {
            assert!(cut > 0, "no receiver cut on llvmpipe: {st:?}");
        }
    }

    /// Both estimators on the fixtures `hair`, `strands` and `bunny` through the CLI path, every
    /// filter mode: the same name and description, the same views, the GPU estimator's V within
    /// the contract and within [`raster_bound`] of the CPU twin's (the opaque bunny renders one
    /// depth map per view, the strands and the hair lists); with one view, the CPU twin's
    /// lookups on the frame's own map give the GPU estimator's V within the twins' tolerance
    /// ([`frame_on_its_map`]).
    fn cli_path_matches_the_cpu_twin(&self, ctx: &Arc<GpuContext>) {
        let mut on_map = RunStats::default();
        let fixtures = ["hair", "strands", "bunny"].map(|name| (name, fixture(name, 40, 30)));
        for kv in [
            &[("filter", "none")][..],
            &[("filter", "pcf"), ("kernel", "5"), ("sublights", "2")][..],
            &[("filter", "edsm"), ("kernel", "7")][..],
            &[("filter", "first")][..],
            &[("filter", "pcss")][..],
            &[("filter", "pcss"), ("sublights", "2"), ("max_taps", "4")][..],
        ] {
            // One estimator pair and one frame per setting, each reused across the fixtures (a
            // frame serves any scene up to the receivers it was prepared for).
            let kv: Vec<(&str, &str)> =
                kv.iter().chain(&[("resolution", "256")]).copied().collect();
            let mut c = CpuDeepShadow::new().unwrap();
            let mut g = self.gpu(ctx);
            for (k, v) in &kv {
                c.set_param(k, v).unwrap();
                g.set_param(k, v).unwrap();
            }
            let table = params(&kv);
            let frame = DeepShadowFrame::prepare(ctx.clone(), &table, 40 * 30).unwrap();
            for (name, (scene, rec)) in &fixtures {
                assert_eq!((c.name(), c.description()), (g.name(), g.description()));
                let (vc, rc) = run(&mut c, scene, rec).unwrap();
                let (vg, rg) = run(&mut *g, scene, rec).unwrap();
                check_contract(&vg, rec);
                assert_eq!(note(&rg, "engine_path").as_deref(), Some("frame twin"));
                assert_eq!(note(&rc, "views"), note(&rg, "views"), "{name} {kv:?}");
                let what = format!("{name} {kv:?}");
                assert_fixture_within(&what, &vc, &vg, rec, raster_bound(scene, &kv));
                if let Some(st) = frame_on_its_map(&what, ctx, (&frame, &table), scene, rec, &vg) {
                    on_map.add(&st);
                }
            }
        }
        let label = "deep-shadow fixtures, frame vs the CPU twin on the frame's map";
        println!("{}", on_map.summary(label, &Tolerance::TWIN));
        on_map.assert_within(label, &Tolerance::TWIN);
    }
}
