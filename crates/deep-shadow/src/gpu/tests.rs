use super::*;
use crate::shared::NIL;

/// Each texel's list, element by element: depth, alpha, tau and the ranks of `prev`, `right`
/// and `upper` in their texels' lists. Two builds of one map give the same lists whatever
/// order the device's atomics wrote the elements in.
type Lists = Vec<Vec<(f32, f32, f32, Option<usize>, Option<usize>, Option<usize>)>>;

fn lists(m: &DeepShadowMap) -> Lists {
    let r = m.r() as usize;
    let rank = |t: usize, e: u32| {
        if e == NIL {
            return None;
        }
        m.list(t).iter().position(|x| *x == e)
    };
    (0..m.head().len())
        .map(|t| {
            let (i, j) = (t % r, t / r);
            let list = m.list(t);
            for w in list.windows(2) {
                let (a, b) = (&m.nodes()[w[0] as usize], &m.nodes()[w[1] as usize]);
                assert!(a.depth() <= b.depth(), "texel {t}: list unsorted");
            }
            list.iter()
                .map(|&e| {
                    let n = &m.nodes()[e as usize];
                    (
                        n.depth(),
                        n.alpha(),
                        n.tau(),
                        rank(t, n.prev()),
                        rank(t + 1, n.right()).filter(|_| i + 1 < r),
                        rank(t + r, n.upper()).filter(|_| j + 1 < r),
                    )
                })
                .collect()
        })
        .collect()
}

/// The element counter is a u32: a pass past 2^32 fragments used to wrap, the wrapped
/// indices overwrote live elements and the wrapped count passed the capacity check. Started
/// just below the wrap (`set_counter_start`), the build is refused with the true need.
#[test]
fn gpu_counter_wrap_is_a_limit_error() {
    let Some(ctx) = test_support::gpu("gpu_counter_wrap_is_a_limit_error") else {
        return;
    };
    let (scene, rec) = test_support::fixtures::fixture("strands", 32, 24);
    let mut g = GpuDeepShadow::new(ctx).unwrap();
    let mut s = Settings::from_params(crate::CpuDeepShadow::new().unwrap().params()).unwrap();
    s.resolution = 64;
    let (v, _) = crate::cpu::sublight_view(&scene, &rec, Vec2::ZERO, 64, 0).unwrap();
    let full = g.build_map(&scene, &v, &s).unwrap();
    assert!(full.stats.fragments > 100, "{}", full.stats.fragments);
    let start = u32::MAX - 10;
    g.set_counter_start(start);
    match g.build_map(&scene, &v, &s) {
        Err(Error::Limit { requested, max, .. }) => {
            assert_eq!(requested, start as u64 + full.stats.fragments);
            assert!(max < u32::MAX as u64);
        }
        Err(e) => panic!("expected a limit error, got {e}"),
        Ok(m) => panic!(
            "a wrapped counter was taken for {} fragments",
            m.stats.fragments
        ),
    }
    // Below the wrap the same start is an ordinary need: grown, then built (from 0 again).
    g.set_counter_start(0);
    let again = g.build_map(&scene, &v, &s).unwrap();
    let (full, again) = (g.read_map(&full).unwrap(), g.read_map(&again).unwrap());
    assert_eq!(full.stats().fragments, again.stats().fragments);
    assert!(lists(&full) == lists(&again), "the lists differ");
}

#[test]
fn shader_validates_with_naga() {
    test_support::wgsl::assert_shaders_valid(
        SHADERS
            .iter()
            .map(|(name, parts)| (*name, shadow_map_core::gpu::kernel::shader_source(parts))),
    );
}

/// Every mirrored struct agrees with the WGSL by member name and offset, and in size.
#[test]
fn shared_structs_match_the_wgsl_layouts() {
    let src = shadow_map_core::gpu::kernel::shader_source(SHADER_PARTS);
    test_support::assert_wgsl_layout!(
        src,
        Node {
            depth,
            alpha,
            tau,
            next,
            prev,
            right,
            upper,
            _pad0,
        }
    );
    test_support::assert_wgsl_layout!(
        src,
        Tri {
            u0,
            v0,
            u1,
            v1,
            u2,
            v2,
            iz0,
            iz1,
            iz2,
            alpha,
            _pad0,
            _pad1,
        }
    );
    test_support::assert_wgsl_layout!(
        src,
        DsUniform {
            r,
            capacity,
            n_items,
            n_queries,
            epsilon,
            filter_mode,
            kernel,
            traversal,
            c_world,
            near,
            to_texels,
            max_taps,
            light_x,
            light_y,
            disk,
            ortho,
            probe,
            trunc_window,
            _pad1,
            _pad2,
        }
    );
}
