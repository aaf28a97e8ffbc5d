use super::*;
use crate::settings::SPECS;
use shadow_map_core::gpu::frame::FrameStatus;

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

/// One frame of `frame` over `scene` and `rec` in the views it fits
/// ([`test_support::frame_run::run_frame`]): V and the decoded status.
fn one_frame(
    ctx: &GpuContext,
    frame: &DeepShadowFrame,
    scene: &Scene,
    rec: &Receivers,
) -> (Vec<f32>, FrameStatus) {
    let (_, out) = test_support::frame_run::run_frame(ctx, frame, scene, rec).unwrap();
    (out.v, out.status.expect("deep-shadow's frame has a status"))
}

/// The element counter is a u32: a frame past 2^32 fragments wraps it, and the wrapped indices
/// would overwrite live elements under a count that passes the capacity check. Started just
/// below the wrap, the frame takes none of its lists: every active receiver is left NaN and
/// counted for the caller's redo, and the wrap is counted. Started at 0 again, the lists are the
/// first frame's and V is bit for bit the first frame's.
#[test]
fn a_wrapped_element_counter_cuts_the_frame() {
    let Some(ctx) = test_support::gpu("a_wrapped_element_counter_cuts_the_frame") else {
        return;
    };
    let (scene, rec) = test_support::fixtures::fixture("strands", 32, 24);
    let active = rec.active_count();
    let mut params = Params::new(SPECS).unwrap();
    params.set("resolution", "64").unwrap();
    let frame = DeepShadowFrame::prepare(ctx.clone(), &params, rec.len() as u32).unwrap();
    let (v_full, st) = one_frame(&ctx, &frame, &scene, &rec);
    assert_eq!(st.left_nan, 0, "{st:?}");
    let FrameMap::Lists(full) = frame.read_map().unwrap() else {
        panic!("a semi-transparent scene builds lists");
    };
    let fragments = full.stats().fragments;
    assert!(fragments > 100, "{fragments}");

    let start = u32::MAX - 10;
    frame.set_counter_start(start);
    let (v, st) = one_frame(&ctx, &frame, &scene, &rec);
    let c: Vec<u32> = ctx
        .read_buffer(&frame.lists.counters, COUNTER_BYTES)
        .unwrap();
    // The counter wrapped once and came to the true need past 2^32.
    assert_eq!(c[2], 1, "wraps");
    assert_eq!(
        (1u64 << 32) + c[0] as u64,
        start as u64 + fragments,
        "elements asked for"
    );
    assert_eq!(st.left_nan as usize, active, "{st:?}");
    for (k, (x, a)) in v.iter().zip(rec.active()).enumerate() {
        assert!(
            x.is_nan(),
            "receiver {k} (active {a}): {x} from wrapped lists"
        );
    }

    frame.set_counter_start(0);
    let (v_again, st) = one_frame(&ctx, &frame, &scene, &rec);
    assert_eq!(st.left_nan, 0, "{st:?}");
    let FrameMap::Lists(again) = frame.read_map().unwrap() else {
        panic!("a semi-transparent scene builds lists");
    };
    assert_eq!(again.stats().fragments, fragments);
    assert!(lists(&full) == lists(&again), "the lists differ");
    let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    assert_eq!(bits(&v_full), bits(&v_again));
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
    let src = shadow_map_core::gpu::kernel::shader_source(FRAME_SHADER_PARTS);
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
        DsUniform {
            r,
            capacity,
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
        }
    );
    test_support::assert_wgsl_layout!(
        src,
        DsFrameUniform {
            bias,
            slope_bias,
            receiver_plane,
            pcss,
            inv_views,
            lists,
            _pad0,
            _pad1,
        }
    );
}
