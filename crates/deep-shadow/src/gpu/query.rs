//! The lookup uniform and the receivers' queries as the WGSL reads them (packed on the CPU for
//! the twin; the engine path makes them on the GPU).
use super::*;

/// The uniform of a lookup of `n_queries` queries in an `r x r` map with element capacity
/// `capacity` under `ls` (the lookup stages read nothing else of it).
pub(crate) fn lookup_uniform(
    r: u32,
    capacity: u32,
    n_queries: u32,
    ls: &LookupSettings,
) -> DsUniform {
    DsUniform {
        r,
        capacity,
        n_items: 0,
        n_queries,
        epsilon: 0.0,
        filter_mode: match ls.filter {
            Filter::First => 0,
            Filter::None => 1,
            Filter::Pcf => 2,
            Filter::Edsm => 3,
            Filter::Pcss => 4,
        },
        kernel: ls.kernel,
        traversal: match ls.traversal {
            Traversal::Linked => 0,
            Traversal::Naive => 1,
        },
        c_world: ls.c_world,
        near: ls.soft.near,
        to_texels: ls.soft.to_texels,
        max_taps: ls.soft.max_taps,
        light_x: ls.soft.light.x,
        light_y: ls.soft.light.y,
        disk: ls.soft.disk as u32,
        ortho: ls.soft.ortho as u32,
        probe: LOOP_PROBE,
        ..Default::default()
    }
}

/// A [`Query`] as the WGSL reads it, two `vec4`s: `(u, v, z_p, fixed)` (fixed >= 0: the
/// transmittance, no lookup; fixed < 0: look up and multiply by `-fixed`, the facing factor) and the caster test's `(g0, gu, gv, c)` ([`shadow_map_core::ReceiverPlane`]; its
/// `hs` is always 0 here, deep shadow maps store f32 depths). An orthographic view's plane (the
/// sun) has `gu = gv = 0` and varies its height instead: it packs `(g0, cu, cv, c)`, and the
/// WGSL reads it by the view's `ortho` flag (`q_slope_height`).
pub type PackedQuery = [f32; 8];

/// Packs a [`Query`] as the WGSL reads it ([`PackedQuery`]).
pub fn pack_query(q: Query) -> PackedQuery {
    match q {
        Query::Fixed(x) => [0.0, 0.0, 0.0, x, 0.0, 0.0, 0.0, 0.0],
        Query::Look {
            uv,
            plane: p,
            facing,
        } => {
            // Perspective planes have cu = cv = 0, orthographic ones gu = gv = 0.
            debug_assert!((p.cu == 0.0 && p.cv == 0.0) || (p.gu == 0.0 && p.gv == 0.0));
            let (a, b) = if p.cu != 0.0 || p.cv != 0.0 {
                (p.cu, p.cv)
            } else {
                (p.gu, p.gv)
            };
            [uv.x, uv.y, p.zp, -facing, p.g0, a, b, p.c]
        }
    }
}

/// The lookup a packed `Look` query holds (the inverse of [`pack_query`]): texel coordinates,
/// the caster test (`ortho`: the plane's `(cu, cv)`, else `(gu, gv)`), the facing factor.
pub fn unpack_look(q: &PackedQuery, ortho: bool) -> (Vec2, ReceiverPlane, f32) {
    let (a, b) = (q[5], q[6]);
    let (gu, gv, cu, cv) = if ortho {
        (0.0, 0.0, a, b)
    } else {
        (a, b, 0.0, 0.0)
    };
    let plane = ReceiverPlane {
        g0: q[4],
        gu,
        gv,
        c: q[7],
        cu,
        cv,
        zp: q[2],
        hs: 0.0,
    };
    (Vec2::new(q[0], q[1]), plane, -q[3])
}

/// The packed query of a lookup at `uv` with the plain depth test `z < d`
/// ([`crate::dsm::depth_test`]).
pub fn pack_depth_query(uv: Vec2, d: f32) -> PackedQuery {
    pack_query(Query::Look {
        uv,
        plane: crate::dsm::depth_test(d),
        facing: 1.0,
    })
}
