//! Packet-hsm's pure functions, shared by the CPU twin and the frame's set-up (Yang, Feng,
//! Guennebaud, Liu 2009; Guennebaud, Barthe, Paulin 2007, "GBP07"; docs/methods.md §3):
//!
//! - here: the sub-light geometry (Yang §5), the tight kernel (Yang eq. 1 refined with the MSSM)
//!   and its side, and the coherence test's pieces (Yang §4.3: `P_null` eq. 4, the diverging
//!   probability `P_d` eq. 5, the cost model eq. 6);
//! - [`contour`]: a dual cell's contour (the occluder status, Yang eq. 3; marching squares; the
//!   centre status) and the receiver-plane bounds the pruning uses;
//! - [`radial`]: the backprojection of contour edges onto the light and their radial
//!   integration over a rect, a disk or a sphere's silhouette disk.
use glam::Vec2;
use shadow_map_core::{light_view::LightView, mssm::Mssm};

pub mod contour;
pub mod radial;

pub use contour::CellRect;

/// Centre of sub-light (a, b) of S x S in light-plane coordinates, for a light of half extents
/// `half` (Yang §5): `((a + 1/2) / S - 1/2) 2 half.x`, likewise y.
pub fn sublight_centre(half: Vec2, s: u32, a: u32, b: u32) -> Vec2 {
    let f = |k: u32, h: f32| ((k as f32 + 0.5) / s as f32 - 0.5) * 2.0 * h;
    Vec2::new(f(a, half.x), f(b, half.y))
}

/// The tight kernel of a receiver in dual cells (Yang eq. 1 with the MSSM, docs/methods.md §2
/// "Refining the kernel"), or `None` when no sample it could see is nearer than `z_p` (lit).
///
/// Samples rect `[x0, x1)` from `W = alpha l (1/z_m - 1/z_p)` around `(u_p, v_p)`, starting at
/// `z_m = n`; `z_m` is then the exact minimum depth over the samples touched by the cells
/// `[x0 - 1, x1)` (the cells touching the rect), until the kernel stops shrinking. Cells are
/// clamped to anchors `[-1, r)`.
pub fn kernel_cells(view: &LightView, mssm: &Mssm, uv: Vec2, zp: f32, l: Vec2) -> Option<CellRect> {
    let r = view.r as f32;
    let rect = |zm: f32| -> [i32; 4] {
        let (wx, wy) = (
            view.kernel_texels(l.x, zm, zp),
            view.kernel_texels(l.y, zm, zp),
        );
        let lo = |c: f32, w: f32| (c - 0.5 * w).floor().clamp(0.0, r) as i32;
        let hi = |c: f32, w: f32| (c + 0.5 * w).ceil().clamp(0.0, r) as i32;
        [lo(uv.x, wx), lo(uv.y, wy), hi(uv.x, wx), hi(uv.y, wy)]
    };
    let area = |q: &[i32; 4]| (q[2] - q[0]) as i64 * (q[3] - q[1]) as i64;
    let mut zm = view.n;
    let mut s = rect(zm);
    for _ in 0..16 {
        let zmin = mssm.query(s[0] - 1, s[1] - 1, s[2] + 1, s[3] + 1).min;
        if !(zmin < zp) {
            return None;
        }
        if !(zmin > zm) {
            break;
        }
        zm = zmin;
        let next = rect(zm);
        if area(&next) >= area(&s) {
            break;
        }
        s = next;
    }
    if s[0] >= s[2] || s[1] >= s[3] {
        return None;
    }
    Some([s[0] - 1, s[1] - 1, s[2], s[3]])
}

/// Side of a kernel in cells (`w_i` of Yang eq. 6).
#[inline]
pub fn kernel_side(cr: &CellRect) -> u32 {
    (cr[2] - cr[0]).max(cr[3] - cr[1]).max(0) as u32
}

/// `P_null` of Yang eq. 4: the share of a packet kernel's depth range `[z_min, z_max]` inside
/// its threshold range `[t_min, t_max]`,
/// `max(min(t_max, z_max) - max(t_min, z_min), 0) / (z_max - z_min)`; for an empty depth range,
/// 1 when `z_min` lies in `[t_min, t_max)`, else 0.
pub fn p_null([z_min, z_max]: [f64; 2], [t_min, t_max]: [f64; 2]) -> f64 {
    let inter = (t_max.min(z_max) - t_min.max(z_min)).max(0.0);
    let range = z_max - z_min;
    if range > 0.0 {
        (inter / range).min(1.0)
    } else if t_min <= z_min && z_min < t_max {
        1.0
    } else {
        0.0
    }
}

/// The diverging probability `P_d = 1 - (1 - P_null)^(wbar^2)` of a packet whose kernel side is
/// `wbar` (Yang eq. 5): the chance that some sample of its kernel has a null status.
pub fn diverging_probability(p_null: f64, wbar: f64) -> f64 {
    1.0 - (1.0 - p_null).powf(wbar * wbar)
}

/// The cost model's term of one extraction over a kernel of side `w` backprojected for `n`
/// pixels (Yang eq. 6, `Q_n = 1`, log base 2): `log(w) w + (Q_e + Q_v n) w`.
pub fn extraction_cost(w: f64, n: f64, qe: f64, qv: f64) -> f64 {
    w.log2() * w + (qe + qv * n) * w
}

/// Yang eq. 6's test: true when one extraction over the packet kernel of side `wbar` for all
/// the pixels of `sides` costs no more than one extraction per pixel over its own kernel of side
/// `w_i` (the cost ratio at most 1).
pub fn packet_pays(wbar: f64, sides: &[u32], qe: f64, qv: f64) -> bool {
    let packet = extraction_cost(wbar, sides.len() as f64, qe, qv);
    let pixels: f64 = sides
        .iter()
        .map(|&w| extraction_cost(w.max(1) as f64, 1.0, qe, qv))
        .sum();
    packet <= pixels
}
