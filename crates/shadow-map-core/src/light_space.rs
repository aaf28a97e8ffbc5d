//! The light-space data an estimator asks for, and nothing more (model only what a scene needs):
//! the fitted light view, k peeled depth layers, optional midpoint layers, and optional MSSM,
//! dual-grid MSSM and min/max pyramid over layer 0.
use crate::{
    light::LightFrame,
    light_view::{FitReport, LightView, ViewOptions},
    mssm::{DualMssm, MinMaxPyramid, Mssm},
    peeling::{midpoints, peel, peel_with_opacity},
    raster::{DepthMap, PreparedScene, RasterOptions},
    receivers::Receivers,
    scene::Scene,
    Result,
};
use glam::Vec2;

/// What an estimator needs built for a frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LightSpaceRequest {
    /// Shadow-map resolution r.
    pub resolution: u32,
    /// Depth layers to peel (>= 1).
    pub layers: u32,
    /// Midpoint layers with this maximum bias (world units); needs one extra peeled layer.
    pub midpoints: Option<f32>,
    /// Build the anchored MSSM up to this level (inclusive).
    pub mssm_levels: Option<u32>,
    /// Build the dual-grid MSSM up to this level (inclusive).
    pub dual_mssm_levels: Option<u32>,
    /// Build the min/max mip pyramid (HSM).
    pub pyramid: bool,
    /// Rasteriser bias and culling.
    pub raster: RasterOptions,
    /// Also each layer's per-texel opacity ([`LightSpace::opacity`]), when the scene has
    /// semi-transparent meshes (an opaque scene gets none, whatever this says).
    pub opacity: bool,
}

/// Host memory available for new allocations (`MemAvailable` of `/proc/meminfo`), where the
/// system says; `None` elsewhere (no check is made then).
pub fn host_memory_available() -> Option<u64> {
    let info = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = info.lines().find(|l| l.starts_with("MemAvailable:"))?;
    let kb: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb * 1024)
}

/// Refuses (`Error::Limit` naming the bytes, before anything is allocated) a build whose planes
/// need more than half the host memory available ([`host_memory_available`]; the other half is
/// left to the estimator's own structures, the rasteriser's working sets and the rest of the
/// process). Without it, at `resolution=16384` backprojection and packet-hsm were killed by the
/// OOM killer at 24 GB on a 23 GB machine.
pub fn check_host_bytes(what: &'static str, bytes: u64) -> Result<()> {
    match host_memory_available() {
        Some(avail) if bytes > avail / 2 => Err(crate::Error::Limit {
            what,
            requested: bytes,
            max: avail / 2,
        }),
        _ => Ok(()),
    }
}

impl LightSpaceRequest {
    /// The anchored MSSM's planes this request builds (its levels 0 to `mssm_levels`), as a
    /// frame's `LayersSlot::mssm_levels` and `KernelMaps::record` take them; `u32::MAX`, every
    /// level prepared, when it asks for no MSSM.
    pub fn mssm_planes(&self) -> u32 {
        self.mssm_levels.map_or(u32::MAX, |l| l + 1)
    }

    /// Host bytes a build of this request at side `r` holds at its peak, from above: every
    /// peeled layer (the midpoints' extra one included), one opacity plane per layer when asked
    /// for, the midpoint layers, the anchored MSSM's levels, the dual-grid MSSM's two planes per
    /// level and the pyramid (4/3 of two planes).
    pub fn host_bytes(&self, r: u32) -> u64 {
        let plane = 4 * r as u64 * r as u64;
        let top = 31 - r.max(1).leading_zeros();
        let k = self.layers.max(1) as u64 + u64::from(self.midpoints.is_some());
        let mut planes = k;
        if self.opacity {
            planes += k;
        }
        if self.midpoints.is_some() {
            planes += k - 1;
        }
        if let Some(l) = self.mssm_levels {
            planes += l.min(top) as u64 + 1;
        }
        if let Some(l) = self.dual_mssm_levels {
            planes += 2 * (l.min(top) as u64 + 1);
        }
        let mut bytes = planes.saturating_mul(plane);
        if self.pyramid {
            bytes = bytes.saturating_add(plane.saturating_mul(8) / 3);
        }
        bytes
    }

    /// Refuses, before anything is allocated, a build at side `r` whose planes
    /// ([`host_bytes`](Self::host_bytes)) need more than half the host memory available
    /// ([`check_host_bytes`]).
    pub fn check_host_memory(&self, r: u32) -> Result<()> {
        check_host_bytes(
            "light-space bytes (half the host memory available)",
            self.host_bytes(r),
        )
    }

    /// A single plain shadow map of resolution `r`.
    pub fn single(r: u32) -> Self {
        LightSpaceRequest {
            resolution: r,
            layers: 1,
            midpoints: None,
            mssm_levels: None,
            dual_mssm_levels: None,
            pyramid: false,
            raster: RasterOptions::default(),
            opacity: false,
        }
    }

    /// The view at the light centre, axes along the light frame, fitted to `receivers` at this
    /// request's resolution ([`LightView::fit_with`]): what [`LightSpace::build_with`] and the
    /// GPU mapper render in.
    pub fn fit_view(
        &self,
        scene: &Scene,
        receivers: &Receivers,
        opts: &ViewOptions,
    ) -> Result<(LightView, FitReport)> {
        let light = scene.light();
        LightView::fit_with(
            scene,
            receivers,
            light.frame(),
            light.half_extent(),
            self.resolution,
            opts,
        )
    }
}

/// The frame of a point light at `at` on the light (light-plane x, y; the multi-view methods'
/// sub-lights): the light's frame moved to that point. For the sun, `at` is a point of its disk
/// of directions at unit distance and the frame looks along `e_z + at.x e_x + at.y e_y` (an
/// orthographic view along that one direction, docs/methods.md §14 "Multi-sample"). Shared by the CPU and GPU
/// twins so both fit the same views.
pub fn point_frame(light: &crate::Light, at: Vec2) -> Result<LightFrame> {
    let frame = light.frame();
    if light.is_directional() {
        return LightFrame::new(
            frame.origin,
            frame.ez + at.x * frame.ex + at.y * frame.ey,
            frame.ex,
        )
        .ok_or_else(|| {
            crate::Error::LightView(format!("sun direction sample {at} is degenerate"))
        });
    }
    Ok(LightFrame {
        origin: frame.to_world(at.extend(0.0)),
        ..frame
    })
}

/// Light-space data for one view.
#[derive(Debug, Clone)]
pub struct LightSpace {
    /// The view the maps were rendered with.
    pub view: LightView,
    /// Fit statistics.
    pub fit: FitReport,
    /// Peeled layers, nearest first (`layers[0]` is the ordinary shadow map).
    pub layers: Vec<DepthMap>,
    /// Per layer, each texel's opacity (the nearest fragment's mesh `opacity`, 0 where empty);
    /// empty unless requested ([`LightSpaceRequest::opacity`]) for a scene with semi-transparent
    /// meshes.
    pub opacity: Vec<Vec<f32>>,
    /// Midpoint layers, when requested.
    pub midpoints: Vec<DepthMap>,
    /// Anchored MSSM of layer 0, when requested.
    pub mssm: Option<Mssm>,
    /// Dual-grid MSSM of layer 0, when requested.
    pub dual_mssm: Option<DualMssm>,
    /// Min/max pyramid of layer 0, when requested.
    pub pyramid: Option<MinMaxPyramid>,
}

impl LightSpace {
    /// Fits a view at the light centre to the receivers (see [`LightView::fit`]) and builds what
    /// `req` asks for.
    pub fn build(scene: &Scene, receivers: &Receivers, req: &LightSpaceRequest) -> Result<Self> {
        Self::build_with(scene, receivers, req, &ViewOptions::default())
    }

    /// [`build`](Self::build) with a window and near/far choice ([`LightView::fit_with`]).
    pub fn build_with(
        scene: &Scene,
        receivers: &Receivers,
        req: &LightSpaceRequest,
        opts: &ViewOptions,
    ) -> Result<Self> {
        let (view, fit) = req.fit_view(scene, receivers, opts)?;
        Self::try_build_in_view(scene, view, fit, req)
    }

    /// Fits a view whose centre of projection is the point `at` of the light plane (light-space
    /// x, y), axes parallel to the light frame, for a point light there (multi-view methods).
    pub fn build_point(
        scene: &Scene,
        receivers: &Receivers,
        at: Vec2,
        req: &LightSpaceRequest,
    ) -> Result<Self> {
        Self::build_point_with(scene, receivers, at, req, &ViewOptions::default())
    }

    /// [`build_point`](Self::build_point) with a window and near/far choice.
    pub fn build_point_with(
        scene: &Scene,
        receivers: &Receivers,
        at: Vec2,
        req: &LightSpaceRequest,
        opts: &ViewOptions,
    ) -> Result<Self> {
        let frame = point_frame(scene.light(), at)?;
        let (view, fit) =
            LightView::fit_with(scene, receivers, frame, Vec2::ZERO, req.resolution, opts)?;
        Self::try_build_in_view(scene, view, fit, req)
    }

    /// [`build_in_view`](Self::build_in_view) after
    /// [`LightSpaceRequest::check_host_memory`]: a build that cannot fit in host memory is an
    /// [`Error::Limit`](crate::Error::Limit) instead of an allocation failure. What every
    /// estimator calls.
    pub fn try_build_in_view(
        scene: &Scene,
        view: LightView,
        fit: FitReport,
        req: &LightSpaceRequest,
    ) -> Result<Self> {
        req.check_host_memory(view.r)?;
        Ok(Self::build_in_view(scene, view, fit, req))
    }

    /// Builds the maps in a given view.
    pub fn build_in_view(
        scene: &Scene,
        view: LightView,
        fit: FitReport,
        req: &LightSpaceRequest,
    ) -> Self {
        let prepared = PreparedScene::new(scene, &view, req.raster.cull);
        let k = req.layers.max(1) + u32::from(req.midpoints.is_some());
        // Semi-transparent meshes: each layer's opacity too (an opaque scene needs none).
        let (mut layers, mut opacity) = if !req.opacity || scene.is_opaque() {
            (peel(&prepared, req.raster.bias, k), Vec::new())
        } else {
            peel_with_opacity(&prepared, req.raster.bias, k)
        };
        let mids = match req.midpoints {
            Some(max_bias) => midpoints(&layers, max_bias),
            None => Vec::new(),
        };
        layers.truncate(req.layers.max(1) as usize);
        opacity.truncate(layers.len());
        let l0 = &layers[0];
        let mssm = req.mssm_levels.map(|l| Mssm::build(&l0.depth, l0.size, l));
        let dual_mssm = req
            .dual_mssm_levels
            .map(|l| DualMssm::build(&l0.depth, l0.size, l));
        let pyramid = req
            .pyramid
            .then(|| MinMaxPyramid::build(&l0.depth, l0.size));
        LightSpace {
            view,
            fit,
            layers,
            opacity,
            midpoints: mids,
            mssm,
            dual_mssm,
            pyramid,
        }
    }

    /// The opacity of texel `t`'s layers `0..=m` that lie in front of depth `zp`: one minus the
    /// product of their transmittances (docs/methods.md §2 "Semi-transparent occluders"); 1 when
    /// no opacity was built (an opaque scene).
    pub fn opacity_in_front(&self, t: usize, m: usize, zp: f32) -> f32 {
        if self.opacity.is_empty() {
            return 1.0;
        }
        let mut tr = 1.0f32;
        for (layer, alpha) in self.layers.iter().zip(&self.opacity).take(m + 1) {
            if layer.depth[t] < zp {
                tr *= 1.0 - alpha[t];
            }
        }
        1.0 - tr
    }

    /// Bytes held by the maps (what `report` lists as light-space memory).
    pub fn bytes(&self) -> usize {
        self.layers
            .iter()
            .chain(&self.midpoints)
            .map(DepthMap::bytes)
            .sum::<usize>()
            + self.mssm.as_ref().map_or(0, Mssm::bytes)
            + self.dual_mssm.as_ref().map_or(0, DualMssm::bytes)
            + self.pyramid.as_ref().map_or(0, MinMaxPyramid::bytes)
    }
}

#[cfg(test)]
mod host_memory_tests {
    use super::*;

    /// The planes a request holds, and the refusal before allocation.
    #[test]
    fn host_bytes_count_the_planes_and_huge_builds_are_refused() {
        let mut req = LightSpaceRequest::single(1024);
        assert_eq!(req.host_bytes(1024), 4 << 20);
        req.layers = 3;
        req.midpoints = Some(0.1);
        req.mssm_levels = Some(20);
        req.dual_mssm_levels = Some(2);
        // 4 peeled + 3 midpoint + 11 MSSM levels (capped at log2 1024) + 2 x 3 dual planes.
        assert_eq!(req.host_bytes(1024), 24 * (4 << 20));
        assert!(check_host_bytes("test", 1).is_ok());
        if host_memory_available().is_some() {
            match check_host_bytes("test", u64::MAX) {
                Err(crate::Error::Limit { requested, max, .. }) => {
                    assert!(requested == u64::MAX && max > 0)
                }
                other => panic!("expected a limit error, got {other:?}"),
            }
        }
    }
}
