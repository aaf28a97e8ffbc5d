//! The settings of backprojection, [`Settings`] (its `typed_params!` declaration, read by the
//! CPU twin and the frame alike), the choice enums its parameters bind, and how their `auto`
//! words resolve for a scene ([`Settings::resolve`]; docs/methods.md §2 "Defaults").
use shadow_map_core::{
    light_view::{ViewOptions, RESOLUTION},
    peeling::SelfShadowSettings,
    ParamSpec,
};

/// Declares a choice parameter's enum and binds each variant to its word
/// ([`shadow_map_core::param_words!`]): the variants and their words are written once, in the
/// order of the parameter's choice list.
macro_rules! choice_enum {
    ($(#[$attr:meta])* $name:ident {
        $($(#[$vattr:meta])* $variant:ident = $word:literal,)+
    }) => {
        $(#[$attr])*
        #[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
        pub enum $name {
            $($(#[$vattr])* $variant,)+
        }
        shadow_map_core::param_words!($name { $($variant = $word),+ });
    };
}

choice_enum! {
    /// `layer_rule`: which occluding layer of a texel is backprojected (Bavoil 2008 §4.2).
    ///
    /// Measured (CPU, defaults otherwise, RMSE against the ray-traced reference): `first_nonzero` /
    /// `deepest` = 0.1085 / 0.1115 on `fixtures/stacked`, 0.0270 / 0.0271 on `grazing-posts`,
    /// 0.0414 / 0.0286 on `hover-boxes`, 0.0457 / 0.0359 on `bunny`; on the stacked plates of
    /// `tests/accuracy.rs` 0.123 / 0.051, with V at most 0.000 / 0.250 above the exact visibility.
    /// Backprojection sums micropatch areas with no overlap test, so the paper's rule, which adds
    /// the near occluder's micropatch where the far one misses the light, removes the light leak
    /// but overshadows more elsewhere: `deepest` under additive occlusion. With `occlusion=bitmask`
    /// (overlaps counted once) `first_nonzero` wins: 0.0501 on `stacked`, 0.0238 on `bunny`
    /// (docs/methods.md §2 "Bitmask occlusion"). The default `auto` picks by occlusion
    /// (docs/methods.md §2 "Defaults").
    LayerRule {
        /// Bavoil 2008 §4.2: "the samples are processed starting from the deepest shadow map
        /// layer and the first non-zero shadow contribution is selected": the deepest occluding
        /// layer whose backprojected micropatch overlaps the light (its own micropatch, before
        /// gap filling).
        FirstNonzero = "first_nonzero",
        /// The deepest occluding layer, whatever its contribution (a layer whose micropatch
        /// misses the light then hides the shallower ones).
        Deepest = "deepest",
        /// `FirstNonzero` under bitmask occlusion, `Deepest` under additive (the default;
        /// [`Settings::resolve`]).
        #[default]
        Auto = "auto",
    }
}

choice_enum! {
    /// `gap_filling`: extend occluding micropatches to their neighbours (docs/methods.md §2).
    GapFilling {
        /// On under bitmask occlusion (where an extended micropatch's overlap is counted once),
        /// off under additive (where it would be counted twice); the default
        /// ([`Settings::resolve`]).
        #[default]
        Auto = "auto",
        /// On.
        On = "true",
        /// Off.
        Off = "false",
    }
}

choice_enum! {
    /// `occlusion`: how the micropatches' coverage of the light is combined (docs/methods.md §2
    /// "Bitmask occlusion").
    Occlusion {
        /// `V = 1 - clamp01(sum area(B_s ∩ L) / A_L)` (Guennebaud 2006, Bavoil 2008):
        /// overlapping micropatches are counted more than once.
        Additive = "additive",
        /// Occlusion bits (Schwarz & Stamminger 2007): `B x B` light samples
        /// ([`shadow_map_core::bitmask`]), each set by every micropatch containing it, counted
        /// once: `V = 1 - set / B^2`.
        Bitmask = "bitmask",
        /// `Bitmask` on a scene of opaque meshes, `Additive` when a mesh is semi-transparent
        /// (the default; [`Settings::resolve`]).
        #[default]
        Auto = "auto",
    }
}

/// [`Settings`]' occlusion, layer rule and gap filling with `auto` resolved for one scene.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Resolved {
    /// `Additive` or `Bitmask`.
    pub occlusion: Occlusion,
    /// `layer_rule=first_nonzero`.
    pub first_nonzero: bool,
    /// Gap filling on.
    pub gap_filling: bool,
}

impl Settings {
    /// Resolves the `auto` choices (docs/methods.md §2 "Defaults") for a scene with
    /// (`semi_transparent`) or without semi-transparent meshes: bitmask occlusion with Bavoil's
    /// first non-zero layer and gap filling when every mesh is opaque; additive occlusion, weighted
    /// by opacity, with the deepest layer and no gap filling otherwise.
    pub fn resolve(&self, semi_transparent: bool) -> Resolved {
        let occlusion = match self.occlusion {
            Occlusion::Auto if semi_transparent => Occlusion::Additive,
            Occlusion::Auto => Occlusion::Bitmask,
            o => o,
        };
        let bitmask = occlusion == Occlusion::Bitmask;
        Resolved {
            occlusion,
            first_nonzero: match self.layer_rule {
                LayerRule::Auto => bitmask,
                r => r == LayerRule::FirstNonzero,
            },
            gap_filling: match self.gap_filling {
                GapFilling::Auto => bitmask,
                g => g == GapFilling::On,
            },
        }
    }
}

shadow_map_core::typed_params! {
    /// Settings of [`CpuBackprojection`](crate::CpuBackprojection) (and of its engine path),
    /// one field a parameter.
    pub struct Settings {
        /// Shadow-map resolution r.
        resolution: u32 = RESOLUTION,
        /// depth-peeled layers k; per texel one occluding layer is backprojected (Bavoil §4.1;
        /// which one: layer_rule)
        layers: u32 = ParamSpec::int(1, 4, "3"),
        /// which occluding layer of a texel is backprojected: auto = first_nonzero under bitmask
        /// occlusion, deepest under additive; deepest = the deepest occluding layer, even when its
        /// micropatch misses the light; first_nonzero = from the deepest, the first whose
        /// micropatch covers part of the light (Bavoil §4.2's rule; never too bright on stacked
        /// occluders, but more overlapping micropatches: larger RMSE on most fixtures)
        layer_rule: LayerRule = ParamSpec::choice(LayerRule::WORDS, "auto"),
        /// extend each occluding micropatch to its +u and +v occluding neighbours (docs/methods.md
        /// §2, reconstructed): auto = on under bitmask occlusion, off under additive
        gap_filling: GapFilling = ParamSpec::choice(GapFilling::WORDS, "auto"),
        /// auto: bitmask on a scene of opaque meshes, additive (opacity-weighted) when a mesh is
        /// semi-transparent (bits carry no opacity); additive: the light area each backprojected
        /// micropatch covers, summed and clamped (overlaps count twice); bitmask: a bits x bits
        /// grid of light samples, each set once by any micropatch covering it (Schwarz & Stamminger
        /// 2007)
        occlusion: Occlusion = ParamSpec::choice(Occlusion::WORDS, "auto"),
        /// occlusion=bitmask: bit-grid side B (B x B equal-area light samples: a grid on a rect
        /// light, concentric on a disk or a sphere's silhouette disk)
        bits: u32 = ParamSpec::int(2, shadow_map_core::bitmask::MAX_BITS as i64, "8"),
        /// most samples per receiver; wider kernels use a uniform step ceil(W / sqrt(max_nspp))
        /// (Bavoil §5)
        max_nspp: u32 = ParamSpec::int(1, 4096, "121"),
        ;
        /// Midpoints or a receiver bias, and receiver-plane rejection.
        shadow: SelfShadowSettings,
        /// Light-view window and near/far choice.
        view: ViewOptions,
    }
}

/// Parameters of [`CpuBackprojection`](crate::CpuBackprojection).
pub const SPECS: &[ParamSpec] = Settings::SPECS;
