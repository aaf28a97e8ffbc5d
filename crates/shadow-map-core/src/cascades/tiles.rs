//! Direction tiles: several light-centre views of one cascade, split by the receivers'
//! directions from the light.
use super::*;

/// The tiles of directions of one cascade: `count` of them, `of[i]` the tile of receiver `i`
/// (receivers behind the light plane, and inactive ones, in tile 0).
#[derive(Debug, Clone, PartialEq)]
pub struct Tiles {
    /// Number of tiles (at least 1).
    pub count: usize,
    /// Tile of each receiver.
    pub of: Vec<u32>,
}

/// Splits the active `receivers` by their direction from the light centre (several views where
/// one cannot serve). In the light frame a receiver at `p` (in front, `p_z > 0`) has
/// the tan-space position `t = p_xy / p_z`; a tile is a box of `t`, and each tile's view is the
/// estimator's own light-centre view fitted to that tile's receivers only, so every formula that
/// assumes the map plane parallel to the light plane holds, while texels go where the tile's
/// receivers are. The split is a k-d tree on `t`: the tile with the widest extent is cut at the
/// median of its receivers along its longer side. Receivers beyond
/// [`MAX_TAN`](crate::light_view::MAX_TAN), outside every view, stay in tile 0 and count in no
/// extent.
///
/// `tiles = k >= 1`: k tiles (fewer when the receivers run out). `tiles = 0`: one tile unless
/// the receivers span more than `tile_span` and one view's texel-density p95 (`p95`, computed
/// only then) exceeds [`AUTO_MAX_DENSITY`]; then tiles are split while one spans more than
/// `tile_span`, up to [`MAX_AUTO_TILES`].
pub fn direction_tiles(
    settings: &CascadeSettings,
    scene: &Scene,
    receivers: &Receivers,
    p95: impl FnOnce() -> Option<f32>,
) -> Tiles {
    let frame = scene.light().frame();
    let mut pts: Vec<(usize, [f32; 2])> = Vec::new();
    for i in 0..receivers.len() {
        if !receivers.active()[i] {
            continue;
        }
        let p = frame.to_light(receivers.position()[i]);
        if scene.light().is_directional() {
            // The sun: one direction; tiles split the receivers by position across it.
            pts.push((i, [p.x, p.y]));
            continue;
        }
        let t = [p.x / p.z, p.y / p.z];
        // Receivers outside every view (beyond MAX_TAN) would only stretch the extents.
        if p.z > 0.0 && t.iter().all(|x| x.abs() <= crate::light_view::MAX_TAN) {
            pts.push((i, t));
        }
    }
    let one = Tiles {
        count: 1,
        of: vec![0; receivers.len()],
    };
    let extent = |t: &[(usize, [f32; 2])]| -> (f32, usize, f32) {
        // (largest side, its axis, its middle)
        let (mut lo, mut hi) = ([f32::INFINITY; 2], [f32::NEG_INFINITY; 2]);
        for (_, q) in t {
            for a in 0..2 {
                lo[a] = lo[a].min(q[a]);
                hi[a] = hi[a].max(q[a]);
            }
        }
        let a = if hi[1] - lo[1] > hi[0] - lo[0] { 1 } else { 0 };
        (hi[a] - lo[a], a, 0.5 * (lo[a] + hi[a]))
    };
    let (want, span) = match settings.tiles {
        // The sun's views are orthographic: no direction to tile, and cascades resolve depth.
        0 if scene.light().is_directional() => return one,
        0 => {
            if pts.len() < 2 || !(extent(&pts).0 > settings.tile_span) {
                return one;
            }
            if !p95().is_some_and(|d| d > AUTO_MAX_DENSITY) {
                return one;
            }
            (MAX_AUTO_TILES, settings.tile_span)
        }
        k => (k as usize, 0.0),
    };
    let mut tiles: Vec<Vec<(usize, [f32; 2])>> = vec![pts];
    while tiles.len() < want {
        let Some((w, (e, a, mid))) = tiles
            .iter()
            .enumerate()
            .filter(|(_, t)| t.len() >= 2)
            .map(|(w, t)| (w, extent(t)))
            .max_by(|x, y| x.1 .0.total_cmp(&y.1 .0))
        else {
            break;
        };
        if !(e > span) {
            break;
        }
        let mut t = tiles.swap_remove(w);
        // At the median along the longer side (balanced tiles); the middle of the extent when
        // the median sits at an end (many receivers at one direction).
        t.sort_by(|x, y| x.1[a].total_cmp(&y.1[a]));
        let m = t.len() / 2;
        let cut = if t[m].1[a] > t[0].1[a] {
            t[m].1[a]
        } else {
            mid
        };
        let (lo, hi): (Vec<_>, Vec<_>) = t.into_iter().partition(|(_, q)| q[a] < cut);
        if lo.is_empty() || hi.is_empty() {
            break; // every receiver at one direction
        }
        tiles.push(lo);
        tiles.push(hi);
    }
    let mut of = vec![0u32; receivers.len()];
    for (k, t) in tiles.iter().enumerate() {
        for (i, _) in t {
            of[*i] = k as u32;
        }
    }
    Tiles {
        count: tiles.len(),
        of,
    }
}
