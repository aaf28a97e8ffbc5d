//! The method's settings: the parameter table the CPU twin and the frame read
//! ([`Settings`], [`SPECS`]) and the choice enums its words bind to.
use glam::Vec3;
use shadow_map_core::bitmask::MAX_BITS;
use shadow_map_core::{
    light_view::{LightView, ViewOptions, BIAS, RESOLUTION, SLOPE_BIAS},
    receiver_plane::RECEIVER_PLANE,
    ParamSpec, ReceiverPlane,
};

/// Which sum (paper eq. 2 or eq. 1).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Variant {
    /// Factors summed, clamped to [0, 1] (eq. 2, the paper's GPU pseudo-code).
    Additive,
    /// Occlusion bits on the light, counted once (eq. 1, the "obit" algorithm).
    Exact,
}

shadow_map_core::param_words!(Variant { Additive = "additive", Exact = "exact" });

/// How the kernel is chosen. Every mode takes at most K x K taps; a tap reads the depth at the
/// centre texel of a `step x step` block and its elementary caster is the whole block (a lexel of
/// a map `step` times coarser: the paper's lexel).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum KernelMode {
    /// The paper's (§1.1, assumption 1): K x K taps over the light's footprint on the plane
    /// z = n, i.e. a lexel pitch of about `2R / K` there ("n proportional to R"). Here n is the
    /// fitted near plane, the nearest geometry in the light frustum, so no caster is clipped;
    /// casters far from the plane are sampled coarsely.
    Fixed,
    /// Per receiver: the texels whose casters at depth `>= z_min` can reach the light, `z_min` the
    /// MSSM minimum over that same region (refined until it stops shrinking), covered by
    /// multi-resolution rings ([`for_each_ring_cell`](crate::cpu::for_each_ring_cell)): single lexels near the receiver's
    /// projection, cells doubling in size outwards, about K cells per side per level.
    Adaptive,
    /// The paper's kernel taken literally at this map's resolution: K x K single lexels around
    /// the receiver's projection. It covers only casters with
    /// `c_z >= 1 / (1/n_paper + 1/z_p)` ([`crate::math::paper_plane_distance`]) and misses those
    /// nearer the light, whose possible projections grow as `1 / c_z`.
    Lexels,
}

shadow_map_core::param_words!(KernelMode { Fixed = "fixed", Adaptive = "adaptive", Lexels = "lexels" });

/// How an additive caster counts (`coverage`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Coverage {
    /// With its overlap area with the footprint.
    Overlap,
    /// In full when its centre is inside the footprint (the paper's test).
    Centre,
}

shadow_map_core::param_words!(Coverage { Overlap = "overlap", Centre = "centre" });

/// How a sphere light's emitting disk is modelled.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SphereModel {
    /// The contract's silhouette disk: radius R through the centre, perpendicular to the direction
    /// from the receiver to the centre (exact for the project's V).
    Contract,
    /// The paper's: a disk of radius R perpendicular to the light normal (§1.1, assumption 1).
    /// From a receiver at angle theta off the light axis it looks foreshortened by about cos theta
    /// compared with the contract's disk.
    Paper,
}

shadow_map_core::param_words!(SphereModel { Contract = "contract", Paper = "paper" });

shadow_map_core::typed_params! {
    /// The parameters, typed; read by the CPU twin and the engine path.
    pub struct Settings {
        /// Shadow-map resolution r.
        resolution: u32 = RESOLUTION,
        /// kernel size K: taps per side (the paper: 5 for speed, 10 for quality)
        k: u32 = ParamSpec::int(1, 64, "10"),
        /// additive: shadowing factors summed and clamped (paper eq. 2); exact: occlusion bits on
        /// the light, a union (eq. 1)
        variant: Variant = ParamSpec::choice(Variant::WORDS, "additive"),
        /// fixed: K x K taps over the light's footprint on the plane z = n (paper, n the nearest
        /// geometry); adaptive: multi-resolution rings (single lexels near the receiver, cells
        /// doubling outwards, ~K per side per level) over the lexels whose casters at the MSSM's
        /// minimum depth can reach the light; lexels: K x K single lexels (the paper's kernel at
        /// this map's resolution)
        kernel: KernelMode = ParamSpec::choice(KernelMode::WORDS, "adaptive"),
        /// variant=additive: a caster counts with its overlap area with the footprint, or in full
        /// when its centre is inside (the paper's test)
        coverage: Coverage = ParamSpec::choice(Coverage::WORDS, "overlap"),
        /// variant=exact: occlusion-bit grid side B (B x B equal-area bits on the light)
        bits: u32 = ParamSpec::int(2, MAX_BITS as i64, "16"),
        /// variant=exact: depth-peeled layers whose casters set occlusion bits (additive uses layer
        /// 0, as the paper)
        layers: u32 = ParamSpec::int(1, 4, "1"),
        /// sphere lights: the contract's silhouette disk (perpendicular to receiver->centre) or the
        /// paper's disk perpendicular to the light normal
        sphere: SphereModel = ParamSpec::choice(SphereModel::WORDS, "contract"),
        /// Constant receiver bias b0 (texel footprints).
        bias: f32 = BIAS,
        /// Slope-scaled receiver bias b1.
        slope_bias: f32 = ParamSpec {
            help: "slope-scaled bias: texel footprints times min(tan(theta), 10)",
            ..SLOPE_BIAS
        },
        /// Receiver-plane rejection ([`shadow_map_core::receiver_plane`]).
        receiver_plane: bool = RECEIVER_PLANE,
        ;
        /// Light-view window and near/far choice.
        view: ViewOptions,
    }
}

/// Parameters of [`CpuAccumulation`](crate::CpuAccumulation) (and of the engine path,
/// `AccumulationFrame`).
pub const SPECS: &[ParamSpec] = Settings::SPECS;

impl Settings {
    /// The caster test of the receiver at light-space `p` with light-space unit normal `n` in
    /// `view` ([`ReceiverPlane::new`] with `receiver_plane`, `bias`, `slope_bias`).
    pub fn plane(&self, view: &LightView, p: Vec3, n: Vec3) -> ReceiverPlane {
        ReceiverPlane::new(
            self.receiver_plane,
            view,
            p,
            n,
            (self.bias, self.slope_bias),
            0.0,
        )
    }
    /// Additive: whether a caster counts with its overlap area (`coverage=overlap`) rather than
    /// the paper's centre test.
    pub fn overlap(&self) -> bool {
        self.coverage != Coverage::Centre
    }
    /// The layers feeding the estimate: `layers` for the exact variant, 1 for additive.
    pub fn peeled_layers(&self) -> u32 {
        if self.variant == Variant::Exact {
            self.layers
        } else {
            1
        }
    }
}
