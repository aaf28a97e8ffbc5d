//! The parameter table both twins share, and the settings read from it.
use crate::dsm::{Filter, Traversal};
use shadow_map_core::{
    light_view::{ViewOptions, BIAS, FIT, NEARFAR, RESOLUTION, SLOPE_BIAS},
    Error, ParamKind, ParamSpec, Params, Result,
};

/// Registry name (`--algo deep-shadow`), shared by both twins.
pub const NAME: &str = "deep-shadow";
/// One-line description, shared by both twins.
pub const DESCRIPTION: &str = "deep shadow maps: per-texel linked lists of semi-transparent fragments, sorted and truncated, PCF/EDSM with neighbour links (Fürst et al.); S x S sub-lights for soft transmittance";

/// The parameters, shared by both twins.
pub const SPECS: &[ParamSpec] = &[
    RESOLUTION,
    ParamSpec {
        key: "filter",
        kind: ParamKind::Choice(&["none", "pcf", "edsm", "first"]),
        default: "none",
        help: "none: T(d) of one texel; pcf: mean T over N x N; edsm: exponential DSM over N x N; first: binary SM from the first fragment only (Table 1.1 'SM')",
    },
    ParamSpec {
        key: "kernel",
        kind: ParamKind::Int { min: 1, max: 7 },
        default: "3",
        help: "N: filter kernel side for pcf and edsm (odd: 1, 3, 5, 7)",
    },
    ParamSpec {
        key: "c",
        kind: ParamKind::Float { min: 0.001, max: 1e6 },
        default: "80",
        help: "EDSM sharpness c over depth normalised to [n, far] (docs/methods.md §7)",
    },
    ParamSpec {
        key: "epsilon",
        kind: ParamKind::Float { min: 0.0, max: 1.0 },
        default: "0.001",
        help: "truncate a list after the first element with cumulative transmittance <= epsilon (0: never)",
    },
    ParamSpec {
        key: "traversal",
        kind: ParamKind::Choice(&["linked", "naive"]),
        default: "linked",
        help: "linked: neighbour links guide each tap's search (§1.3.5); naive: every tap walks its list from the head",
    },
    ParamSpec {
        key: "sublights",
        kind: ParamKind::Int { min: 1, max: 4 },
        default: "1",
        help: "S: S x S point sub-lights at the strata centres of the light, one deep shadow map each, T averaged (1: the light centre)",
    },
    BIAS,
    ParamSpec {
        help: "slope-scaled bias: texel footprints times min(tan(theta), 10)",
        ..SLOPE_BIAS
    },
    ParamSpec {
        key: "capacity",
        kind: ParamKind::Int { min: 0, max: u32::MAX as i64 - 1 },
        default: "0",
        help: "initial list-element capacity (0: 4 r^2); an overflow grows the buffer and rebuilds",
    },
    ParamSpec {
        key: "max_capacity",
        kind: ParamKind::Int { min: 1, max: u32::MAX as i64 - 1 },
        default: "67108864",
        help: "most list elements the buffer may grow to (beyond: an error naming the need)",
    },
    FIT,
    NEARFAR,
];

/// The settings of one frame, read from [`Params`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Settings {
    /// Resolution r.
    pub resolution: u32,
    /// Filter.
    pub filter: Filter,
    /// Kernel side N.
    pub kernel: u32,
    /// EDSM c over normalised depth.
    pub c: f32,
    /// Truncation epsilon.
    pub epsilon: f32,
    /// Traversal.
    pub traversal: Traversal,
    /// Sub-lights per side S.
    pub sublights: u32,
    /// Constant bias (texel footprints).
    pub b0: f32,
    /// Slope bias.
    pub b1: f32,
    /// Initial capacity (0: auto).
    pub capacity: u64,
    /// Largest capacity.
    pub max_capacity: u64,
    /// Light-view window and near/far choice of every sub-light's view (`fit`, `nearfar`).
    pub view: ViewOptions,
}

impl Settings {
    /// Reads the settings.
    pub fn from_params(p: &Params) -> Self {
        Settings {
            resolution: p.int("resolution") as u32,
            filter: match p.choice("filter") {
                "pcf" => Filter::Pcf,
                "edsm" => Filter::Edsm,
                "first" => Filter::First,
                _ => Filter::None,
            },
            kernel: p.int("kernel") as u32,
            c: p.float("c") as f32,
            epsilon: p.float("epsilon") as f32,
            traversal: if p.choice("traversal") == "naive" {
                Traversal::Naive
            } else {
                Traversal::Linked
            },
            sublights: p.int("sublights") as u32,
            b0: p.float("bias") as f32,
            b1: p.float("slope_bias") as f32,
            capacity: p.int("capacity") as u64,
            max_capacity: p.int("max_capacity") as u64,
            view: ViewOptions::from_params(p),
        }
    }
}

/// Sets one parameter, with the checks the table cannot express (odd kernel).
pub fn set(p: &mut Params, key: &str, value: &str) -> Result<()> {
    let mut q = p.clone();
    q.set(key, value)?;
    if q.int("kernel") % 2 == 0 {
        return Err(Error::param(
            "kernel",
            format!("must be odd (1, 3, 5, 7), got {}", q.int("kernel")),
        ));
    }
    *p = q;
    Ok(())
}
