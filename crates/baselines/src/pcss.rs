//! Percentage-closer soft shadows (Fernando 2005), in the exact form of docs/methods.md §5: all
//! depths linear light-space z, lengths on the plane z = n, filter widths (not radii).
use crate::common::MapSettings;
use crate::map_estimator::{cells, Filter, MapEstimator, ReceiverSample};
use glam::Vec2;
use shadow_map_core::light_view::LightView;
use shadow_map_core::{DepthLookup, Light, LightShape, ParamKind, ParamSpec, Params, Result};

shadow_map_core::typed_params! {
    /// PCSS, step by step (docs/methods.md §5):
    /// 1. blocker search over the cut of the receiver-light pyramid at the near plane,
    ///    `W_search = l (z_r - n) / z_r` on the plane z = n (per axis for rect lights);
    /// 2. `z_avg` = mean depth of the samples with `z_i < z_r - eps` (none: V = 1);
    /// 3. penumbra at the receiver `w_p = (z_r - z_avg) l / z_avg`;
    /// 4. PCF over a box of full width `W_filter = w_p n / z_r` on the plane (a disk of that diameter
    ///    for disk and sphere lights, with a one-texel soft edge), each texel weighted by its overlap
    ///    with the box, so a single planar blocker parallel to the light is reproduced exactly.
    ///
    /// Both regions are sampled texel by texel up to `max_taps` texels per side, and by `max_taps`
    /// equal cells beyond (a documented approximation for very wide penumbrae).
    ///
    /// PCSS's own parameter (after the shared [`MapSettings`]).
    pub struct Pcss {
        /// Most samples per side in the blocker search and in the filter.
        max_taps: u32 = ParamSpec {
            key: "max_taps",
            kind: ParamKind::Int { min: 1, max: 1024 },
            default: "32",
            help: "most samples per side in the blocker search and in the filter",
        },
    }
}

/// The PCSS estimator.
pub type PcssShadow = MapEstimator<Pcss>;

impl Filter for Pcss {
    const NAME: &'static str = "pcss";
    const DESCRIPTION: &'static str =
        "percentage-closer soft shadows: blocker search, penumbra estimate, PCF (Fernando 2005)";
    const SPECS: &'static [ParamSpec] =
        shadow_map_core::concat_specs!(MapSettings::SPECS, Pcss::SPECS);
    fn from_params(p: &Params) -> Result<Self> {
        Pcss::from_params(p)
    }
    fn visibility<M: DepthLookup>(
        &self,
        view: &LightView,
        map: &M,
        light: &Light,
        r: &ReceiverSample,
    ) -> f32 {
        let zr = r.p.z;
        let l = 2.0 * light.half_extent(); // (l_x, l_y)
        let to_texels = view.r as f32 / view.w;
        // 1. Blocker search.
        let ws = search_width(l, zr, view.n, to_texels);
        let (mut sum, mut count) = (Kahan::default(), Kahan::default());
        let d = map;
        cells(
            r.uv.y - 0.5 * ws.y,
            r.uv.y + 0.5 * ws.y,
            self.max_taps,
            |j, wy| {
                cells(
                    r.uv.x - 0.5 * ws.x,
                    r.uv.x + 0.5 * ws.x,
                    self.max_taps,
                    |i, wx| {
                        let z = d.at(i, j);
                        if r.caster(i, j, z) {
                            let w = wx * wy;
                            sum.add(w * z);
                            count.add(w);
                        }
                    },
                )
            },
        );
        if count.s <= 0.0 {
            return 1.0;
        }
        let z_avg = sum.s / count.s;
        // 3. Penumbra width at the receiver, 4. filter width on the plane (texels).
        let wf = filter_width(l, zr, z_avg, view.n, to_texels);
        let disk = is_disk(light);
        let (mut lit, mut total) = (Kahan::default(), Kahan::default());
        cells(
            r.uv.y - 0.5 * wf.y,
            r.uv.y + 0.5 * wf.y,
            self.max_taps,
            |j, wy| {
                cells(
                    r.uv.x - 0.5 * wf.x,
                    r.uv.x + 0.5 * wf.x,
                    self.max_taps,
                    |i, wx| {
                        let edge = disk_edge(disk, wf, i, j, r.uv);
                        if edge <= 0.0 {
                            return;
                        }
                        let w = wx * wy * edge;
                        total.add(w);
                        if !r.caster(i, j, d.at(i, j)) {
                            lit.add(w);
                        }
                    },
                )
            },
        );
        if total.s <= 0.0 {
            return 1.0;
        }
        lit.s / total.s
    }
}

/// The blocker-search width on the plane z = n, in texels (docs/methods.md §5 step 1): the cut of
/// the pyramid from the receiver at depth `zr` to the light of extent `l` (per axis, light-plane
/// units), `W_search = l (z_r - n) / z_r`, times `to_texels = r / w`.
#[inline]
pub fn search_width(l: Vec2, zr: f32, n: f32, to_texels: f32) -> Vec2 {
    l * ((zr - n) / zr) * to_texels
}

/// The filter width on the plane z = n, in texels (docs/methods.md §5 steps 3 and 4): penumbra
/// `w_p = (z_r - z_avg) l / z_avg` at the receiver, `W_filter = w_p n / z_r`, times `to_texels`.
#[inline]
pub fn filter_width(l: Vec2, zr: f32, z_avg: f32, n: f32, to_texels: f32) -> Vec2 {
    l * ((zr - z_avg) / z_avg) * (n / zr) * to_texels
}

/// True for the lights whose PCSS filter is a disk (disk and sphere lights; a rect's is a box).
#[inline]
pub fn is_disk(light: &Light) -> bool {
    matches!(
        light.shape,
        LightShape::Disk { .. } | LightShape::Sphere { .. }
    )
}

/// The weight of texel (i, j) in a disk filter of diameter `wf.x` texels centred on `uv`, with a
/// one-texel soft edge (continuous in the filter width, so rounding in z_avg moves V by a
/// rounding error, not a texel); 1 for a box filter (`disk` false) or a filter within a texel.
#[inline]
pub fn disk_edge(disk: bool, wf: Vec2, i: i32, j: i32, uv: Vec2) -> f32 {
    if disk && wf.x > 1.0 {
        let rad = 0.5 * wf.x;
        let c = Vec2::new(i as f32 + 0.5, j as f32 + 0.5) - uv;
        (rad + 0.5 - c.length()).clamp(0.0, 1.0)
    } else {
        1.0
    }
}

/// Kahan-compensated f32 sum. PCSS accumulates its weights with it, in the same order as its GPU
/// twin, so both backends get the same blocker depth and filter width bit for bit (an f64 sum
/// on one side only moved the filter's cells and flipped sampled texels).
/// Public so that other PCSS-style filters (deep-shadow's `filter=pcss`) sum the same way; its
/// WGSL twin is `Sum` / `sum_add` in `gpu/cells.wgsl`.
#[derive(Debug, Clone, Copy, Default)]
pub struct Kahan {
    s: f32,
    c: f32,
}

impl Kahan {
    /// The sum so far.
    #[inline]
    pub fn sum(&self) -> f32 {
        self.s
    }
    /// Adds `x`.
    #[inline]
    pub fn add(&mut self, x: f32) {
        let y = x - self.c;
        let t = self.s + y;
        self.c = (t - self.s) - y;
        self.s = t;
    }
}
