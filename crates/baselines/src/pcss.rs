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
        let ws = l * ((zr - view.n) / zr) * to_texels;
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
        let wf: Vec2 = l * ((zr - z_avg) / z_avg) * (view.n / zr) * to_texels;
        let disk = matches!(
            light.shape,
            LightShape::Disk { .. } | LightShape::Sphere { .. }
        );
        let (mut lit, mut total) = (Kahan::default(), Kahan::default());
        let rad = 0.5 * wf.x;
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
                        // Disk filter with a one-texel soft edge: continuous in the filter
                        // width, so rounding in z_avg moves V by a rounding error, not a texel.
                        let mut edge = 1.0f32;
                        if disk && wf.x > 1.0 {
                            let c = Vec2::new(i as f32 + 0.5, j as f32 + 0.5) - r.uv;
                            edge = (rad + 0.5 - c.length()).clamp(0.0, 1.0);
                            if edge <= 0.0 {
                                return;
                            }
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

/// Kahan-compensated f32 sum. PCSS accumulates its weights with it, in the same order as its GPU
/// twin, so both backends get the same blocker depth and filter width bit for bit (an f64 sum
/// on one side only moved the filter's cells and flipped sampled texels).
#[derive(Debug, Clone, Copy, Default)]
struct Kahan {
    s: f32,
    c: f32,
}

impl Kahan {
    #[inline]
    fn add(&mut self, x: f32) {
        let y = x - self.c;
        let t = self.s + y;
        self.c = (t - self.s) - y;
        self.s = t;
    }
}
