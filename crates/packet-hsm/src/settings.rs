//! Packet-hsm's settings: its registry name and description, and its parameters as one typed
//! declaration ([`Config`], [`SPECS`]), read by the CPU twin and the frame alike.
use crate::cpu::extract::Traversal;
use shadow_map_core::{
    light_view::{ViewOptions, RESOLUTION},
    params::FromParam,
    peeling::SelfShadowSettings,
    Error, ParamSpec, ParamValue, Result,
};

/// Registry name (shared with the engine path).
pub const NAME: &str = "packet-hsm";
/// One-line description (shared with the registry's GPU estimator).
pub const DESCRIPTION: &str = "packet-based hierarchical soft shadow mapping: contour backprojection over a dual-grid MSSM, pixel packets, coherence test, S x S sub-lights (Yang 2009, GBP07)";

/// Every packet size from 1x1 to 8x8 (`WxH`).
pub const PACKETS: &[&str] = &[
    "1x1", "1x2", "1x3", "1x4", "1x5", "1x6", "1x7", "1x8", "2x1", "2x2", "2x3", "2x4", "2x5",
    "2x6", "2x7", "2x8", "3x1", "3x2", "3x3", "3x4", "3x5", "3x6", "3x7", "3x8", "4x1", "4x2",
    "4x3", "4x4", "4x5", "4x6", "4x7", "4x8", "5x1", "5x2", "5x3", "5x4", "5x5", "5x6", "5x7",
    "5x8", "6x1", "6x2", "6x3", "6x4", "6x5", "6x6", "6x7", "6x8", "7x1", "7x2", "7x3", "7x4",
    "7x5", "7x6", "7x7", "7x8", "8x1", "8x2", "8x3", "8x4", "8x5", "8x6", "8x7", "8x8",
];

/// Parameters of [`CpuPacketHsm`](crate::CpuPacketHsm) and of the frame
/// ([`crate::gpu`]).
pub const SPECS: &[ParamSpec] = Config::SPECS;

/// The packet size `(w, h)` of a `WxH` parameter value.
pub fn parse_packet(s: &str) -> Result<(u32, u32)> {
    let bad = || {
        Error::param(
            "packet",
            format!("expected WxH with W, H in 1..=8, got {s:?}"),
        )
    };
    let (a, b) = s.split_once('x').ok_or_else(bad)?;
    let w: u32 = a.parse().map_err(|_| bad())?;
    let h: u32 = b.parse().map_err(|_| bad())?;
    if !(1..=8).contains(&w) || !(1..=8).contains(&h) {
        return Err(bad());
    }
    Ok((w, h))
}

/// A packet size `WxH` (the `packet` parameter).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Packet {
    /// Pixels per packet row, W.
    pub w: u32,
    /// Rows per packet, H.
    pub h: u32,
}

impl Packet {
    /// `(w, h)`.
    pub fn size(self) -> (u32, u32) {
        (self.w, self.h)
    }
}

impl std::fmt::Display for Packet {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}x{}", self.w, self.h)
    }
}

impl FromParam for Packet {
    /// A `WxH` word ([`parse_packet`]); `None` for anything else.
    fn from_param(v: ParamValue) -> Option<Self> {
        match v {
            ParamValue::Choice(word) => parse_packet(word).ok().map(|(w, h)| Packet { w, h }),
            _ => None,
        }
    }
}

shadow_map_core::typed_params! {
    /// Settings of one estimate, one field a parameter ([`SPECS`]).
    pub struct Config {
        /// Shadow-map resolution r of each sub-light's map.
        resolution: u32 = ParamSpec {
            help: "shadow-map resolution r (texels per side) of each sub-light's map",
            ..RESOLUTION
        },
        /// packet of WxH neighbouring pixels (Yang §4.1; 1x1 = per pixel); receivers without an
        /// image layout are processed pixel-wise
        packet: Packet = ParamSpec::choice(PACKETS, "3x3"),
        /// S: the light is split into S x S equal sub-lights, one shadow map + MSSM each, V
        /// averaged (Yang §5)
        sublights: u32 = ParamSpec::int(1, 4, "1"),
        /// most opacity levels, one pass each, for semi-transparent meshes (docs/methods.md §3
        /// "Semi-transparent occluders"): V = sum of level weights times V with only the meshes of
        /// at least that opacity as casters; a scene needing more levels (its distinct opacities,
        /// plus one without casters when no mesh is opaque) is treated as opaque; 1 = always opaque
        opacity_levels: u32 = ParamSpec::int(1, 16, "2"),
        /// Td: a packet whose diverging probability P_d (Yang eq. 5) exceeds Td is processed
        /// pixel-wise
        td: f64 = ParamSpec::float(0.0, 1.0, "0.8"),
        /// hierarchical contour extraction over the dual-grid MSSM (Yang §4.2, Algorithm 3); false:
        /// every 2x2 block of the kernel (GBP07)
        hierarchy: bool = ParamSpec::flag(true),
        /// coherence test (Yang §4.3: P_d > Td or cost ratio eq. 6 > 1 sends a packet pixel-wise);
        /// false: every packet is tried packet-wise
        coherence: bool = ParamSpec::flag(true),
        /// Q_e of the cost model (eq. 6): cost of extracting an edge, in units of Q_n = 1 (a node)
        qe: f64 = ParamSpec::float(0.0, 1e6, "2.0"),
        /// Q_v of the cost model (eq. 6): cost of backprojecting and integrating an edge for one
        /// pixel
        qv: f64 = ParamSpec::float(0.0, 1e6, "4.0"),
        ;
        /// Midpoint classification or a receiver bias, and receiver-plane rejection.
        shadow: SelfShadowSettings,
        /// Light-view window and near/far choice of every sub-light's map.
        view: ViewOptions,
    }
}

impl Config {
    /// The contour extraction `hierarchy` chooses.
    pub(crate) fn traversal(&self) -> Traversal {
        if self.hierarchy {
            Traversal::Hierarchical
        } else {
            Traversal::Flat
        }
    }
}
