//! The parameter table both twins share, and the settings read from it.
use crate::dsm::{Filter, Traversal};
use shadow_map_core::{
    light_view::{ViewOptions, BIAS, RESOLUTION, SLOPE_BIAS},
    receiver_plane::RECEIVER_PLANE,
    Error, ParamKind, ParamSpec, Params, Result,
};

/// Registry name (`--algo deep-shadow`), shared by both twins.
pub const NAME: &str = "deep-shadow";
/// One-line description, shared by both twins.
pub const DESCRIPTION: &str = "deep shadow maps: per-texel linked lists of semi-transparent fragments, sorted and truncated, PCF/EDSM with neighbour links (Fürst et al.); soft by default: percentage-closer soft transmittance (PCSS's blocker search, mean T over the penumbra); S x S sub-lights";

shadow_map_core::typed_params! {
    /// The settings of one frame, one field a parameter ([`SPECS`]).
    pub struct Settings {
        /// Resolution r.
        resolution: u32 = RESOLUTION,
        /// Filter.
        filter: Filter = ParamSpec {
            key: "filter",
            kind: ParamKind::Choice(Filter::WORDS),
            default: "pcss",
            help: "none: T(d) of one texel; pcf: mean T over N x N; edsm: exponential DSM over N x N; first: binary SM from the first fragment only (Table 1.1 'SM'); pcss: percentage-closer soft transmittance, PCSS's blocker search over the first fragments, then mean T over the penumbra's width (docs/methods.md §8)",
        },
        /// Kernel side N.
        kernel: u32 = ParamSpec {
            key: "kernel",
            kind: ParamKind::Int { min: 1, max: 7 },
            default: "3",
            help: "N: filter kernel side for pcf and edsm (odd: 1, 3, 5, 7)",
        },
        /// EDSM c over normalised depth.
        c: f32 = ParamSpec {
            key: "c",
            kind: ParamKind::Float { min: 0.001, max: 1e6 },
            default: "80",
            help: "EDSM sharpness c over depth normalised to [n, far] (docs/methods.md §7)",
        },
        /// Truncation epsilon.
        epsilon: f32 = ParamSpec {
            key: "epsilon",
            kind: ParamKind::Float { min: 0.0, max: 1.0 },
            default: "0.001",
            help: "truncate a list after the first element with cumulative transmittance <= epsilon (0: never)",
        },
        /// Traversal.
        traversal: Traversal = ParamSpec {
            key: "traversal",
            kind: ParamKind::Choice(Traversal::WORDS),
            default: "linked",
            help: "linked: neighbour links guide each tap's search (§1.3.5); naive: every tap walks its list from the head",
        },
        /// Most cells per side in `pcss`'s search and kernel.
        max_taps: u32 = ParamSpec {
            key: "max_taps",
            kind: ParamKind::Int { min: 1, max: 1024 },
            default: "32",
            help: "pcss: most samples per side in the blocker search and in the kernel (as PCSS's max_taps); wider regions are sampled by that many equal cells",
        },
        /// Sub-lights per side S.
        sublights: u32 = ParamSpec {
            key: "sublights",
            kind: ParamKind::Int { min: 1, max: 4 },
            default: "1",
            help: "S: S x S point sub-lights at the strata centres of the light, one deep shadow map each, T averaged (1: the light centre)",
        },
        /// Constant bias b0 (texel footprints).
        bias: f32 = BIAS,
        /// Slope bias b1.
        slope_bias: f32 = ParamSpec {
            help: "slope-scaled bias: texel footprints times min(tan(theta), 10)",
            ..SLOPE_BIAS
        },
        /// Receiver-plane rejection ([`shadow_map_core::receiver_plane`]).
        receiver_plane: bool = RECEIVER_PLANE,
        /// Initial capacity (0: auto).
        capacity: u64 = ParamSpec {
            key: "capacity",
            kind: ParamKind::Int { min: 0, max: u32::MAX as i64 - 1 },
            default: "0",
            help: "initial list-element capacity (0: 4 r^2); an overflow grows the buffer and rebuilds",
        },
        /// Largest capacity.
        max_capacity: u64 = ParamSpec {
            key: "max_capacity",
            kind: ParamKind::Int { min: 1, max: u32::MAX as i64 - 1 },
            default: "67108864",
            help: "most list elements the buffer may grow to (beyond: an error naming the need)",
        },
        ;
        /// Light-view window and near/far choice of every sub-light's view.
        view: ViewOptions,
    }
}

/// The parameters, shared by both twins.
pub const SPECS: &[ParamSpec] = Settings::SPECS;

/// Sets one parameter, with the checks the table cannot express (odd kernel); the settings of
/// the new parameters.
pub fn set(p: &mut Params, key: &str, value: &str) -> Result<Settings> {
    let mut q = p.clone();
    q.set(key, value)?;
    let s = Settings::from_params(&q)?;
    if s.kernel % 2 == 0 {
        return Err(Error::param(
            "kernel",
            format!("must be odd (1, 3, 5, 7), got {}", s.kernel),
        ));
    }
    *p = q;
    Ok(s)
}
