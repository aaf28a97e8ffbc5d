//! The settings both twins read: the parameter table (`typed_params!`), the name and description,
//! and the choice enums its words bind to (`param_words!`).
use shadow_map_core::{
    light_view::{ViewOptions, BIAS, RESOLUTION, SLOPE_BIAS},
    receiver_plane::RECEIVER_PLANE,
    Error, ParamSpec, Result,
};

/// How a lookup filters the transmittance over the shadow-map plane.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Filter {
    /// Binary shadow map from the first (nearest) fragment only: `T = [d <= z_0]` (Table 1.1 "SM").
    First,
    /// One tap: `T(d)` of the receiver's texel (Eq. 1.1, §1.3.4).
    None,
    /// Percentage-closer filtering: the mean of `T(d)` over N x N texels (§1.3.5).
    Pcf,
    /// Exponential deep shadow maps (EDSM, §1.3.5, docs/methods.md §7): the mean over N x N
    /// texels of `tau_c(d) = prod_j (1 - alpha_j o_c(d - z_j))`, `o_c(t) = 1 - exp(-c' max(0, t))`.
    Edsm,
    /// Percentage-closer soft transmittance (docs/methods.md §8 "Percentage-closer soft
    /// transmittance"): PCSS's blocker search over the first fragment of each list, then the mean
    /// of `T(d)` over a kernel as wide as the penumbra ([`soft_transmittance`](crate::math::soft_transmittance)).
    Pcss,
}

shadow_map_core::param_words!(Filter { None = "none", Pcf = "pcf", Edsm = "edsm", First = "first", Pcss = "pcss" });

/// How each tap's list is searched (both give identical results; only the cost differs).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Traversal {
    /// From the previous tap's element through its `right`/`upper` link, then `next`/`prev`
    /// (Fürst et al. §1.3.5, Figure 1.5): each list is walked from its head once per pixel at most.
    Linked,
    /// Every tap's list walked from its head.
    Naive,
}

shadow_map_core::param_words!(Traversal { Linked = "linked", Naive = "naive" });

/// Registry name (`--algo deep-shadow`), shared by both twins.
pub const NAME: &str = "deep-shadow";
/// One-line description, shared by both twins.
pub const DESCRIPTION: &str = "deep shadow maps: per-texel linked lists of semi-transparent fragments, sorted and truncated, PCF/EDSM with neighbour links (Fürst et al.); soft by default: percentage-closer soft transmittance (PCSS's blocker search, mean T over the penumbra); S x S sub-lights";

shadow_map_core::typed_params! {
    /// The settings of one frame, one field a parameter ([`SPECS`]).
    pub struct Settings {
        /// Resolution r.
        resolution: u32 = RESOLUTION,
        /// none: T(d) of one texel; pcf: mean T over N x N; edsm: exponential DSM over N x N;
        /// first: binary SM from the first fragment only (Table 1.1 'SM'); pcss: percentage-closer
        /// soft transmittance, PCSS's blocker search over the first fragments, then mean T over the
        /// penumbra's width (docs/methods.md §8)
        filter: Filter = ParamSpec::choice(Filter::WORDS, "pcss"),
        /// N: filter kernel side for pcf and edsm (odd: 1, 3, 5, 7)
        kernel: u32 = ParamSpec::int(1, 7, "3"),
        /// EDSM sharpness c over depth normalised to [n, far] (docs/methods.md §7)
        c: f32 = ParamSpec::float(0.001, 1e6, "80"),
        /// truncate a list after the first element with cumulative transmittance <= epsilon (0:
        /// never)
        epsilon: f32 = ParamSpec::float(0.0, 1.0, "0.001"),
        /// linked: neighbour links guide each tap's search (§1.3.5); naive: every tap walks its
        /// list from the head
        traversal: Traversal = ParamSpec::choice(Traversal::WORDS, "linked"),
        /// pcss: most samples per side in the blocker search and in the kernel (as PCSS's
        /// max_taps); wider regions are sampled by that many equal cells
        max_taps: u32 = ParamSpec::int(1, 1024, "32"),
        /// S: S x S point sub-lights at the strata centres of the light, one deep shadow map each,
        /// T averaged (1: the light centre)
        sublights: u32 = ParamSpec::int(1, 4, "1"),
        /// Constant bias b0 (texel footprints).
        bias: f32 = BIAS,
        /// Slope bias b1.
        slope_bias: f32 = ParamSpec {
            help: "slope-scaled bias: texel footprints times min(tan(theta), 10)",
            ..SLOPE_BIAS
        },
        /// Receiver-plane rejection ([`shadow_map_core::receiver_plane`]).
        receiver_plane: bool = RECEIVER_PLANE,
        /// initial list-element capacity (0: 4 r^2); an overflow grows the buffer and rebuilds
        capacity: u64 = ParamSpec::int(0, u32::MAX as i64 - 1, "0"),
        /// most list elements the buffer may grow to (beyond: an error naming the need)
        max_capacity: u64 = ParamSpec::int(1, u32::MAX as i64 - 1, "67108864"),
        ;
        /// Light-view window and near/far choice of every sub-light's view.
        view: ViewOptions,
    }
}

/// The parameters, shared by both twins.
pub const SPECS: &[ParamSpec] = Settings::SPECS;

/// The checks the table cannot express (an odd kernel), run on every `set_param` before the
/// new settings are taken ([`shadow_map_core::Configured::set_checked`]).
pub fn check(s: &Settings) -> Result<()> {
    if s.kernel.is_multiple_of(2) {
        return Err(Error::param(
            "kernel",
            format!("must be odd (1, 3, 5, 7), got {}", s.kernel),
        ));
    }
    Ok(())
}
