//! Two GPU estimators used from two threads on one device (one of the faults a renderer meets):
//! every GPU estimator (`FRAME_ALGOS`: all eight), two instances on the shared context, each in its own thread, each
//! rendering the same scene three times while the other does; every run must succeed and give
//! what one instance gives alone (within 1e-5: the twins' atomics may order ties differently).
use shadow_map_core::{run, Receivers, Scene, SceneBvh};
use softshadow::{estimator, Backend, FRAME_ALGOS};
use test_support::gate::gpu;

#[test]
fn two_threads_share_one_device() {
    if gpu("two_threads_share_one_device").is_none() {
        return;
    }
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/fixtures/parallel-squares/parallel-squares.toml"
    );
    let mut scene = Scene::load(path).unwrap();
    scene.set_resolution(40, 30).unwrap();
    let rec = Receivers::from_camera(&scene, &SceneBvh::new(&scene));
    for algo in FRAME_ALGOS {
        let alone = {
            let mut e = estimator(algo, Backend::Gpu).unwrap();
            e.set_param("resolution", "256").unwrap();
            run(e.as_mut(), &scene, &rec).unwrap().0
        };
        let runs: Vec<Vec<Vec<f32>>> = std::thread::scope(|s| {
            let handles: Vec<_> = (0..2)
                .map(|_| {
                    s.spawn(|| {
                        let mut e = estimator(algo, Backend::Gpu).unwrap();
                        e.set_param("resolution", "256").unwrap();
                        (0..3)
                            .map(|_| {
                                run(e.as_mut(), &scene, &rec)
                                    .unwrap_or_else(|err| panic!("{algo}: {err}"))
                                    .0
                            })
                            .collect()
                    })
                })
                .collect();
            handles
                .into_iter()
                .map(|h| h.join().expect("thread"))
                .collect()
        });
        let mut worst = 0.0f32;
        for v in runs.iter().flatten() {
            for (k, (a, b)) in alone.iter().zip(v).enumerate() {
                assert_eq!(a.is_nan(), b.is_nan(), "{algo}: receiver {k}: {a} / {b}");
                if a.is_finite() {
                    worst = worst.max((a - b).abs());
                }
            }
        }
        println!("{algo}: 2 threads x 3 runs, max |dV| against one instance alone {worst:.2e}");
        assert!(worst <= 1e-5, "{algo}: {worst}");
    }
}
