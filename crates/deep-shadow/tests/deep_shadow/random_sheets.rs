//! The frame against the CPU twin on random stacks of parallel sheets (proptest), the conformance
//! suite's `random_scenes` for deep shadow maps. The sheets' edges sit a quarter texel off the
//! texel centres (so the hardware rasteriser's sub-pixel snapping and the CPU's exact fill rule
//! cannot disagree) in a view made for them; the frame renders each case, then its map is read
//! back and compared with the CPU twin's build per texel: the processed lists as sorted sequences
//! (depth within `DEPTH_REL`, alpha and tau equal), the truncation points, the neighbour links (as
//! ranks in the neighbour's list: element indices depend on insertion order; a link may differ
//! only where two elements of the neighbour's list are equally near, a tie), or on the opaque path
//! the nearest depths; and the frame's V against the CPU twin's lookup on that same map,
//! every filter mode and traversal (within `T_TOL`, each receiver beyond it a tie the explainer
//! shows).
#![cfg(feature = "gpu")]
use crate::common::{camera, params, quad};
use crate::on_map::{cpu_on_map, explain};
use deep_shadow::{
    cpu::{build_deep_map, dsm::DeepShadowMap},
    gpu::FrameMap,
    math::NIL,
    settings::Settings,
    DeepShadowFrame,
};
use glam::{Vec2, Vec3};
use proptest::prelude::*;
use shadow_map_core::{
    gpu::GpuContext,
    light_space::{LightSpace, LightSpaceRequest},
    light_view::FitReport,
    Light, LightFrame, LightView, Receivers, Scene,
};
use std::collections::HashMap;
use std::sync::Arc;
use test_support::{
    frame_run::FrameRig,
    tolerance::{CaseStats, Tolerance},
};

/// Depths of one fragment on both sides: the frame interpolates z in f32 in the rasteriser.
const DEPTH_REL: f32 = 2e-6;
/// V of one lookup on both sides: the same steps in f32 in another order.
pub const T_TOL: f32 = 2e-5;
/// Receivers per case.
const RECEIVERS: usize = 40;

/// A sheet: texel rectangle [a0, a1) x [b0, b1), depth index, alpha.
#[derive(Debug, Clone)]
struct Sheet {
    a: (u32, u32),
    b: (u32, u32),
    depth: u32,
    alpha: f32,
}

#[derive(Debug, Clone)]
pub struct Case {
    r: u32,
    sheets: Vec<Sheet>,
    ground: bool,
    epsilon: f32,
    /// Receivers at texel coordinates (u, v) and light-space depth z.
    receivers: Vec<(f32, f32, f32)>,
}

pub fn arb_case() -> impl Strategy<Value = Case> {
    prop_oneof![Just(16u32), Just(32), Just(48)].prop_flat_map(|r| {
        let sheet = (
            0..r,
            1..r,
            0..r,
            1..r,
            0u32..12,
            prop_oneof![Just(1.0f32), 0.05f32..0.95],
        )
            .prop_map(move |(a0, da, b0, db, depth, alpha)| Sheet {
                a: (a0, (a0 + da).min(r)),
                b: (b0, (b0 + db).min(r)),
                depth,
                alpha,
            });
        (
            Just(r),
            prop::collection::vec(sheet, 1..14),
            any::<bool>(),
            prop_oneof![Just(0.0f32), Just(0.001), Just(0.05)],
            prop::collection::vec((0.0f32..1.0, 0.0f32..1.0, 0u32..26), RECEIVERS),
        )
            .prop_map(|(r, sheets, ground, epsilon, q)| Case {
                r,
                sheets,
                ground,
                epsilon,
                // Depths halfway between sheet depths (never a tie with a fragment).
                receivers: q
                    .into_iter()
                    .map(|(u, v, k)| {
                        (
                            u * r as f32,
                            v * r as f32,
                            1.05 + 0.1 * k as f32 / 2.0 + 0.025,
                        )
                    })
                    .collect(),
            })
    })
}

/// Sheet depth k is at light-space z = 1.1 + 0.1 k; the ground at z = 2.5.
fn sheet_z(k: u32) -> f32 {
    1.1 + 0.1 * k as f32
}

/// The light view: centre of projection at (0, 3, 0) looking down, n = 1, window [-1, 1]^2.
fn view(r: u32) -> LightView {
    LightView {
        frame: LightFrame::new(Vec3::new(0.0, 3.0, 0.0), -Vec3::Y, Vec3::X).unwrap(),
        n: 1.0,
        far: 3.0,
        window_min: Vec2::splat(-1.0),
        w: 2.0,
        r,
        projection: Default::default(),
    }
}

/// Light space (x, y, z) is world (x, 3 - z, y) for this frame (e_y = e_z x e_x = +Z); texel
/// coordinate u is at x = z (u delta - 1).
fn world(r: u32, u: f32, v: f32, z: f32) -> Vec3 {
    let delta = 2.0 / r as f32;
    Vec3::new(z * (u * delta - 1.0), 3.0 - z, z * (v * delta - 1.0))
}

fn scene_of(c: &Case, light: Light) -> Scene {
    let mut meshes = Vec::new();
    if c.ground {
        meshes.push((quad(-5.0, -5.0, 5.0, 5.0, 0.5), 1.0));
    }
    for s in &c.sheets {
        let z = sheet_z(s.depth);
        // A quarter texel off the centres.
        let lo = world(c.r, s.a.0 as f32 + 0.25, s.b.0 as f32 + 0.25, z);
        let hi = world(c.r, s.a.1 as f32 + 0.25, s.b.1 as f32 + 0.25, z);
        meshes.push((quad(lo.x, lo.z, hi.x, hi.z, lo.y), s.alpha));
    }
    Scene::from_meshes("twin", camera(), light, meshes).unwrap()
}

/// The case's receivers, facing the light; every ninth inactive.
fn receivers_of(c: &Case) -> Receivers {
    let pos: Vec<Vec3> = c
        .receivers
        .iter()
        .map(|&(u, v, z)| world(c.r, u, v, z))
        .collect();
    let mut rec = Receivers::from_points(pos.clone(), vec![Vec3::Y; pos.len()]).unwrap();
    for (k, a) in rec.active_mut().iter_mut().enumerate() {
        *a = k % 9 != 8;
    }
    rec
}

fn rank(d: &DeepShadowMap, t: usize, e: u32) -> Option<usize> {
    if e == NIL {
        return None;
    }
    d.list(t).iter().position(|x| *x == e)
}

/// Whether the CPU's and the frame's links from an element at depth `z` into list `t` agree: the
/// same rank, or a tie (two elements of that list equally near `z` within the depth tolerance,
/// as sheets at whole depths make common: the element at 6 between neighbours at 5 and 7), where
/// depths within `DEPTH_REL` may send the nearest-element walk either way. Ties are counted.
fn links_agree(
    c: &DeepShadowMap,
    g: &DeepShadowMap,
    t: usize,
    z: f32,
    (ec, eg): (u32, u32),
    ties: &mut usize,
) -> bool {
    let (a, b) = (rank(c, t, ec), rank(g, t, eg));
    if a == b {
        return true;
    }
    let (Some(a), Some(b)) = (a, b) else {
        return false;
    };
    let dist = |k: usize| (c.nodes()[c.list(t)[k] as usize].depth() - z).abs();
    // Each of the three depths may move by DEPTH_REL of itself between the two sides.
    let tie = (dist(a) - dist(b)).abs() <= 4.0 * DEPTH_REL * z.abs().max(1.0);
    *ties += usize::from(tie);
    tie
}

/// The frame's lists against the CPU twin's; `Ok` with the number of neighbour links that differ
/// only by a tie ([`links_agree`]).
fn compare_maps(c: &DeepShadowMap, g: &DeepShadowMap) -> Result<usize, String> {
    let check = |ok: bool, what: String| if ok { Ok(()) } else { Err(what) };
    let mut ties = 0;
    check(
        c.stats().fragments == g.stats().fragments,
        format!(
            "fragments {} vs {}",
            c.stats().fragments,
            g.stats().fragments
        ),
    )?;
    let r = c.r() as usize;
    for t in 0..c.head().len() {
        let (lc, lg) = (c.list(t), g.list(t));
        check(
            lc.len() == lg.len(),
            format!(
                "texel {t}: truncation point / length {} vs {}",
                lc.len(),
                lg.len()
            ),
        )?;
        for (k, (&ec, &eg)) in lc.iter().zip(&lg).enumerate() {
            let (nc, ng) = (&c.nodes()[ec as usize], &g.nodes()[eg as usize]);
            check(
                (nc.depth() - ng.depth()).abs() <= DEPTH_REL * nc.depth(),
                format!("texel {t} #{k}: depth {} vs {}", nc.depth(), ng.depth()),
            )?;
            check(
                nc.alpha() == ng.alpha() && nc.tau() == ng.tau(),
                format!(
                    "texel {t} #{k}: alpha, tau {} {} vs {} {}",
                    nc.alpha(),
                    nc.tau(),
                    ng.alpha(),
                    ng.tau()
                ),
            )?;
            check(
                rank(c, t, nc.prev()) == rank(g, t, ng.prev()),
                format!("texel {t} #{k}: prev"),
            )?;
            let (i, j) = (t % r, t / r);
            let z = nc.depth();
            check(
                i + 1 >= r || links_agree(c, g, t + 1, z, (nc.right(), ng.right()), &mut ties),
                format!("texel {t} #{k}: right"),
            )?;
            check(
                j + 1 >= r || links_agree(c, g, t + r, z, (nc.upper(), ng.upper()), &mut ties),
                format!("texel {t} #{k}: upper"),
            )?;
            check(
                k == 0 || g.nodes()[lg[k - 1] as usize].depth() <= ng.depth(),
                format!("texel {t}: the frame's list unsorted"),
            )?;
        }
    }
    Ok(ties)
}

/// The frame's nearest depths against the CPU raster's (the CPU twin's opaque path).
fn compare_depths(
    c: &shadow_map_core::DepthMap,
    g: &shadow_map_core::DepthMap,
) -> Result<(), String> {
    for (t, (zc, zg)) in c.depth.iter().zip(&g.depth).enumerate() {
        let same = if zc.is_finite() {
            (zc - zg).abs() <= DEPTH_REL * zc
        } else {
            zc == zg
        };
        if !same {
            return Err(format!("texel {t}: depth {zc} vs {zg}"));
        }
    }
    Ok(())
}

/// The lookups of the random scenes, as parameters: every filter, kernel 3 and 7 where the
/// filter has a kernel, both traversals where it walks lists from tap to tap; `filter=pcss` with
/// a box light whose regions span whole texels, and a disk light wide enough to be sampled by
/// `max_taps` equal cells (`shape` as [`test_support::fixtures::light_of_shape`]).
struct Lookup {
    params: &'static [(&'static str, &'static str)],
    shape: u8,
    l: f32,
}

const LOOKUPS: &[Lookup] = {
    const fn box_(params: &'static [(&'static str, &'static str)]) -> Lookup {
        Lookup {
            params,
            shape: 0,
            l: 0.5,
        }
    }
    &[
        box_(&[("filter", "first")]),
        box_(&[("filter", "none"), ("traversal", "linked")]),
        box_(&[("filter", "none"), ("traversal", "naive")]),
        box_(&[("filter", "pcf"), ("kernel", "3"), ("traversal", "linked")]),
        box_(&[("filter", "pcf"), ("kernel", "3"), ("traversal", "naive")]),
        box_(&[("filter", "pcf"), ("kernel", "7"), ("traversal", "linked")]),
        box_(&[("filter", "pcf"), ("kernel", "7"), ("traversal", "naive")]),
        box_(&[("filter", "edsm"), ("kernel", "3"), ("traversal", "linked")]),
        box_(&[("filter", "edsm"), ("kernel", "3"), ("traversal", "naive")]),
        box_(&[("filter", "edsm"), ("kernel", "7"), ("traversal", "linked")]),
        box_(&[("filter", "edsm"), ("kernel", "7"), ("traversal", "naive")]),
        Lookup {
            params: &[("filter", "pcss"), ("max_taps", "32")],
            shape: 0,
            l: 0.4,
        },
        Lookup {
            params: &[("filter", "pcss"), ("max_taps", "4")],
            shape: 1,
            l: 1.5,
        },
    ]
};

/// What one random case's frames measured besides V.
#[derive(Debug, Default)]
pub struct MapTally {
    /// Frames whose map was read back and compared (lists, nearest depths).
    pub lists: usize,
    pub depths: usize,
    /// Fragments in the compared lists.
    pub fragments: u64,
    /// Neighbour links that differ only by a tie between two equally near elements.
    pub link_ties: usize,
}

/// The random cases' frames, one per parameter table (resolution, epsilon's bits, the index of
/// the lookup in [`LOOKUPS`]): a frame is reusable across scenes and receivers up to the
/// [`RECEIVERS`] it was prepared for, so each table's pipelines are compiled once however many
/// cases and scenes share it.
#[derive(Default)]
pub struct Frames(HashMap<(u32, u32, usize), DeepShadowFrame>);

/// One random case: for each lookup of [`LOOKUPS`], on the case's scene (lists) and on the
/// scene made opaque (the opaque path), a frame with the lookup's parameters (the classic depth
/// test without bias, as the receivers sit halfway between sheets; EDSM's `c' = 30`) run in the
/// case's view, its map read back and compared with the CPU twin's, and its V with the CPU
/// twin's lookup on that map.
pub fn random_case(
    ctx: &Arc<GpuContext>,
    c: &Case,
    tally: &mut MapTally,
    frames: &mut Frames,
) -> Result<CaseStats, String> {
    let tol = Tolerance {
        abs: T_TOL,
        ..Tolerance::TWIN
    };
    let rec = receivers_of(c);
    let v = view(c.r);
    let mut all = CaseStats::default();
    for (index, lk) in LOOKUPS.iter().enumerate() {
        let light = test_support::fixtures::light_of_shape(lk.shape, lk.l, 3.0);
        let semi = scene_of(c, light);
        let r = c.r.to_string();
        let eps = c.epsilon.to_string();
        let fixed = [
            ("resolution", r.as_str()),
            ("epsilon", eps.as_str()),
            ("receiver_plane", "false"),
            ("bias", "0"),
            ("slope_bias", "0"),
            ("c", "60"),
        ];
        let kv: Vec<(&str, &str)> = fixed.iter().chain(lk.params).copied().collect();
        let table = params(&kv);
        let s = Settings::from_params(&table).unwrap();
        let what = format!("{:?} light shape {} l {}", lk.params, lk.shape, lk.l);
        let frame = match frames.0.entry((c.r, c.epsilon.to_bits(), index)) {
            std::collections::hash_map::Entry::Occupied(e) => e.into_mut(),
            std::collections::hash_map::Entry::Vacant(e) => e.insert(
                DeepShadowFrame::prepare(ctx.clone(), &table, RECEIVERS as u32)
                    .map_err(|e| format!("{what}: {e}"))?,
            ),
        };
        for scene in [semi.opaque(), semi] {
            let what = if scene.is_opaque() {
                format!("{what} (opaque)")
            } else {
                what.clone()
            };
            // The case's own view, not the one the frame fits to the receivers.
            let mut rig =
                FrameRig::new(ctx, frame, &scene, &rec).map_err(|e| format!("{what}: {e}"))?;
            rig.views = vec![Some(v)];
            let out = rig.run(ctx, frame).map_err(|e| format!("{what}: {e}"))?;
            if out.status != Some(Default::default()) {
                return Err(format!("{what}: status {:?}", out.status));
            }
            let vg = out.v;
            let map = frame.read_map().map_err(|e| format!("{what}: {e}"))?;
            match &map {
                FrameMap::Lists(g) => {
                    let cm = build_deep_map(&scene, &v, &s).unwrap();
                    tally.link_ties +=
                        compare_maps(&cm, g).map_err(|e| format!("{what}: lists: {e}"))?;
                    tally.lists += 1;
                    tally.fragments += g.stats().fragments;
                }
                FrameMap::Depths(g) => {
                    let ls = LightSpace::try_build_in_view(
                        &scene,
                        v,
                        FitReport::default(),
                        &LightSpaceRequest::single(c.r),
                    )
                    .unwrap();
                    compare_depths(&ls.layers[0], g).map_err(|e| format!("{what}: depths: {e}"))?;
                    tally.depths += 1;
                }
            }
            if scene.is_opaque() != matches!(map, FrameMap::Depths(_)) {
                return Err(format!("{what}: the frame took the other path"));
            }
            let vc = cpu_on_map(&map, &scene, &rec, &v, &s);
            let cmp = tol.compare(&what, rec.active(), &vc, &vg)?;
            let st = tol.judge(&what, &cmp, &rec, &vc, &vg, |beyond| {
                Ok(beyond
                    .iter()
                    .map(|&k| explain(&tol, &map, &scene, &rec, &v, &s, k, (vc[k], vg[k])))
                    .collect())
            })?;
            all.receivers += st.receivers;
            all.beyond += st.beyond;
            all.ties += st.ties;
            all.max_dv = all.max_dv.max(st.max_dv);
            for (a, b) in all.classes.iter_mut().zip(st.classes) {
                *a += b;
            }
        }
    }
    Ok(all)
}
