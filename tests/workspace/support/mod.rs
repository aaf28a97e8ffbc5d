//! What the workspace's integration tests share.
use glam::{Mat3, Vec3};
use softshadow::{Backend, SoftShadowEstimator};

/// The backend a registry row names (`"cpu"` or `"gpu"`), or `None` for a GPU row without a
/// Vulkan adapter (a loud skip naming `test`; under `SOFTSHADOW_REQUIRE_GPU=1` a missing adapter
/// fails instead).
pub fn runnable(backend: &str, test: &str) -> Option<Backend> {
    if backend != "gpu" {
        return Some(Backend::Cpu);
    }
    test_support::gate::context_for_tests(test)
        .expect("adapter")
        .map(|_| Backend::Gpu)
}

/// The backends of `algo`'s registry rows that run here, each with its row's name (a GPU row
/// without an adapter: [`runnable`]'s loud skip).
pub fn runnable_backends(algo: &str, test: &str) -> Vec<(&'static str, Backend)> {
    softshadow::backends(algo)
        .iter()
        .filter_map(|&b| Some((b, runnable(b, test)?)))
        .collect()
}

/// Every estimator of `algos` on each backend it runs on here ([`runnable_backends`]), with the
/// backend's name.
pub fn estimators<'a>(
    algos: impl IntoIterator<Item = &'a str>,
    test: &str,
) -> Vec<(Box<dyn SoftShadowEstimator>, &'static str)> {
    let mut out = Vec::new();
    for algo in algos {
        for (b, backend) in runnable_backends(algo, test) {
            out.push((softshadow::estimator(algo, backend).expect("registered"), b));
        }
    }
    out
}

/// A square of side `2 half` centred at `c`, in the plane y = 0 turned by `m`, as two triangles
/// (counter-clockwise seen from +y before the turn).
pub fn square(c: Vec3, half: f32, m: Mat3) -> Vec<[Vec3; 3]> {
    let p = [(-half, -half), (-half, half), (half, half), (half, -half)]
        .map(|(x, z)| c + m * Vec3::new(x, 0.0, z));
    vec![[p[0], p[1], p[2]], [p[0], p[2], p[3]]]
}
