//! What a Bevy app sets on a light: [`SoftShadowSettings`], with a typed [`Method`] and its
//! typed [`MethodParams`].
use bevy::prelude::*;

/// `Method` and its tables from [`softshadow::for_each_method!`]'s list: a variant per method
/// with an engine path (`frame = true`), in the registry's order, with the registry's docs.
macro_rules! frame_methods {
    ($($(#[$doc:meta])* $variant:ident = $descriptor:path, frame = $frame:literal;)*) => {
        /// The estimators this plugin runs each frame: every method with an engine path
        /// ([`softshadow::FRAME_ALGOS`]), generated from the registry's list
        /// ([`softshadow::for_each_method!`]), named as the registry names them
        /// ([`Method::name`]).
        #[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Reflect)]
        pub enum Method {
            $($(#[$doc])* $variant,)*
        }

        impl Method {
            /// Every method, in the registry's order.
            pub const ALL: &'static [Method] = &[$(Method::$variant),*];

            /// The method's registry entry: its name, CPU twin, engine path and report sweep.
            pub fn descriptor(self) -> &'static softshadow::MethodDescriptor {
                match self {
                    $(Method::$variant => &$descriptor,)*
                }
            }
        }
    };
}

/// Keeps the methods with an engine path (`frame = true`) and hands them to [`frame_methods`].
macro_rules! only_frames {
    (@keep [$($kept:tt)*]) => { frame_methods! { $($kept)* } };
    (@keep [$($kept:tt)*] $(#[$doc:meta])* $v:ident = $d:path, frame = true; $($rest:tt)*) => {
        only_frames! { @keep [$($kept)* $(#[$doc])* $v = $d, frame = true;] $($rest)* }
    };
    (@keep [$($kept:tt)*] $(#[$doc:meta])* $v:ident = $d:path, frame = false; $($rest:tt)*) => {
        only_frames! { @keep [$($kept)*] $($rest)* }
    };
    ($($all:tt)*) => { only_frames! { @keep [] $($all)* } };
}

softshadow::for_each_method!(only_frames);

/// PCSS: the baseline every method is measured against.
impl Default for Method {
    fn default() -> Self {
        Method::Pcss
    }
}

impl Method {
    /// The registry name (`softshadow render --algo NAME`, `docs/report/results.csv`'s `algo`).
    pub fn name(self) -> &'static str {
        self.descriptor().name()
    }

    /// The method called `name` in the registry, if it is one of these.
    pub fn from_name(name: &str) -> Option<Method> {
        Method::ALL.iter().copied().find(|m| m.name() == name)
    }
}

/// A method's parameters. Every method takes its shadow map's resolution; everything else stays
/// at the defaults `docs/report/` measures ([`crate::measured()`] gives those figures).
#[derive(Debug, Clone, Copy, PartialEq, Default, Reflect)]
pub struct MethodParams {
    /// Texels per side of the light's shadow map (`resolution`); `None`: the method's default
    /// (1024 for most).
    pub resolution: Option<u32>,
}

/// Soft shadows from the light this component is on, by `method`, for every 3D camera with a
/// [`DepthPrepass`](bevy::core_pipeline::prepass::DepthPrepass) and a
/// [`NormalPrepass`](bevy::core_pipeline::prepass::NormalPrepass) (and `Msaa::Off`).
///
/// The light it is on gives the shape (docs/methods.md §1, the contract's lights):
/// - [`DirectionalLight`]: the sun, a disk of directions of angular diameter
///   [`SunDisk::angular_size`](bevy::light::SunDisk) when the entity has a `SunDisk`, else
///   [`sun_angle_deg`](Self::sun_angle_deg);
/// - [`PointLight`] with a `radius` above 0: a sphere light of that radius;
/// - [`RectLight`]: a one-sided rect light of its `width` (along the entity's local x) and
///   `height` (local y), emitting along its local -z.
///
/// One light per app carries it (the first found; the others are ignored). Bevy's own shadow
/// maps for that light should be off (`shadow_maps_enabled: false`): this plugin's V replaces
/// them.
#[derive(Component, Debug, Clone, Copy, PartialEq, Reflect)]
pub struct SoftShadowSettings {
    /// The estimator.
    pub method: Method,
    /// Its parameters.
    pub params: MethodParams,
    /// The sun's angular diameter in degrees for a [`DirectionalLight`] without a `SunDisk`.
    pub sun_angle_deg: f32,
    /// Shadows only within this distance of the camera (world units, along its view axis), as
    /// Bevy's own cascades' `maximum_distance`: the light views are fitted to the part of the
    /// scene's box the camera sees up to here, so a large ground gets finer texels near the
    /// camera; receivers beyond get whatever the views give (outside the light's window: lit).
    /// `None` (the default): the whole box.
    pub max_distance: Option<f32>,
    /// How much of the view's colour V scales in the provided composite pass
    /// (`colour * mix(1, V, composite)`; 0 turns the pass off, leaving V to the app's own
    /// material). The pass scales all light, ambient included: exact only where this light is
    /// the only one.
    pub composite: f32,
}

/// The sun's mean angular diameter seen from the Earth, in degrees.
pub const DEFAULT_SUN_ANGLE_DEG: f32 = 0.53;

impl Default for SoftShadowSettings {
    fn default() -> Self {
        SoftShadowSettings {
            method: Method::default(),
            params: MethodParams::default(),
            sun_angle_deg: DEFAULT_SUN_ANGLE_DEG,
            max_distance: None,
            composite: 1.0,
        }
    }
}

impl SoftShadowSettings {
    /// The settings for `method`, everything else at its default.
    pub fn new(method: Method) -> Self {
        SoftShadowSettings {
            method,
            ..Default::default()
        }
    }

    /// The method's parameter table with these settings applied (what the frame estimator is
    /// prepared with). Errors: a resolution the method does not take.
    pub fn params_table(&self) -> softshadow::Result<softshadow::core::Params> {
        let cpu = softshadow::method(self.method.name())?.cpu()?;
        let mut p = softshadow::own_params(self.method.name(), cpu.params())?;
        if let Some(r) = self.params.resolution {
            p.set(softshadow::core::light_view::RESOLUTION.key, &r.to_string())?;
        }
        Ok(p)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_method_is_a_frame_estimator() {
        let names: Vec<&str> = Method::ALL.iter().map(|m| m.name()).collect();
        assert_eq!(names, softshadow::FRAME_ALGOS);
        for &m in Method::ALL {
            assert_eq!(Method::from_name(m.name()), Some(m));
            assert!(m.descriptor().has_frame(), "{}", m.name());
        }
        assert_eq!(Method::default(), Method::Pcss);
    }

    #[test]
    fn resolution_reaches_the_table_and_bad_ones_are_errors() {
        let mut s = SoftShadowSettings::new(Method::Backprojection);
        s.params.resolution = Some(512);
        let p = s.params_table().unwrap();
        assert_eq!(
            p.get(softshadow::core::light_view::RESOLUTION.key)
                .unwrap()
                .to_string(),
            "512"
        );
        s.params.resolution = Some(0);
        let e = s.params_table().unwrap_err().to_string();
        assert!(e.contains("resolution"), "{e}");
    }
}
