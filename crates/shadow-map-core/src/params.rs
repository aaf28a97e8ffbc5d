//! Estimator parameters: declared once per estimator as a table of [`ParamSpec`]s, set from
//! `KEY=VALUE` strings with errors naming the key, listed by `softshadow algos`.
use crate::{Error, Result};

/// The type and range of a parameter.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ParamKind {
    /// Integer in `min..=max`.
    Int {
        /// Smallest value.
        min: i64,
        /// Largest value.
        max: i64,
    },
    /// Finite float in `min..=max`.
    Float {
        /// Smallest value.
        min: f64,
        /// Largest value.
        max: f64,
    },
    /// One of a fixed set of words.
    Choice(&'static [&'static str]),
    /// `true` or `false`.
    Bool,
}

/// One declared parameter.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ParamSpec {
    /// Key, as given to `--param KEY=VALUE`.
    pub key: &'static str,
    /// Type and range.
    pub kind: ParamKind,
    /// Default, as a string in the same syntax.
    pub default: &'static str,
    /// One-line description.
    pub help: &'static str,
}

impl ParamSpec {
    const fn of(kind: ParamKind, default: &'static str) -> Self {
        Self {
            key: "",
            kind,
            default,
            help: "",
        }
    }

    /// An integer in `min..=max`. Inside [`typed_params!`](crate::typed_params) the key is the
    /// field's name and the help its doc comment; elsewhere give both with [`Self::named`].
    pub const fn int(min: i64, max: i64, default: &'static str) -> Self {
        Self::of(ParamKind::Int { min, max }, default)
    }

    /// A finite float in `min..=max` (key and help as [`Self::int`]).
    pub const fn float(min: f64, max: f64, default: &'static str) -> Self {
        Self::of(ParamKind::Float { min, max }, default)
    }

    /// One of `words` (key and help as [`Self::int`]).
    pub const fn choice(words: &'static [&'static str], default: &'static str) -> Self {
        Self::of(ParamKind::Choice(words), default)
    }

    /// `true` or `false` (key and help as [`Self::int`]).
    pub const fn flag(default: bool) -> Self {
        Self::of(ParamKind::Bool, if default { "true" } else { "false" })
    }

    /// This spec under `key`, described by `help`.
    pub const fn named(self, key: &'static str, help: &'static str) -> Self {
        Self { key, help, ..self }
    }

    /// The spec of a [`typed_params!`](crate::typed_params) field: an empty key becomes the
    /// field's name, an empty help its doc comment (the lines joined, trimmed). A spec declared
    /// with its own key and help (a shared one, such as
    /// [`RESOLUTION`](crate::light_view::RESOLUTION)) is kept as it is.
    pub const fn declared(self, field: &'static str, doc: &'static str) -> Self {
        Self {
            key: if self.key.is_empty() { field } else { self.key },
            help: if self.help.is_empty() {
                doc.trim_ascii()
            } else {
                self.help
            },
            ..self
        }
    }
}

/// A parsed value.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ParamValue {
    /// Integer.
    Int(i64),
    /// Float.
    Float(f64),
    /// A word from a [`ParamKind::Choice`].
    Choice(&'static str),
    /// Boolean.
    Bool(bool),
}

impl std::fmt::Display for ParamValue {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            ParamValue::Int(v) => write!(f, "{v}"),
            ParamValue::Float(v) => write!(f, "{v}"),
            ParamValue::Choice(v) => write!(f, "{v}"),
            ParamValue::Bool(v) => write!(f, "{v}"),
        }
    }
}

impl ParamSpec {
    /// Parses a value for this parameter.
    pub fn parse(&self, s: &str) -> Result<ParamValue> {
        let s = s.trim();
        let bad = |why: String| Error::param(self.key, why);
        match self.kind {
            ParamKind::Int { min, max } => {
                let v: i64 = s
                    .parse()
                    .map_err(|_| bad(format!("expected an integer, got {s:?}")))?;
                if v < min || v > max {
                    return Err(bad(format!("{v} is out of range {min}..={max}")));
                }
                Ok(ParamValue::Int(v))
            }
            ParamKind::Float { min, max } => {
                let v: f64 = s
                    .parse()
                    .map_err(|_| bad(format!("expected a number, got {s:?}")))?;
                if !v.is_finite() || v < min || v > max {
                    return Err(bad(format!("{v} is out of range [{min}, {max}]")));
                }
                Ok(ParamValue::Float(v))
            }
            ParamKind::Choice(words) => words
                .iter()
                .find(|w| **w == s)
                .map(|w| ParamValue::Choice(w))
                .ok_or_else(|| bad(format!("expected one of {}, got {s:?}", words.join("|")))),
            ParamKind::Bool => match s {
                "true" | "on" | "1" => Ok(ParamValue::Bool(true)),
                "false" | "off" | "0" => Ok(ParamValue::Bool(false)),
                _ => Err(bad(format!("expected true or false, got {s:?}"))),
            },
        }
    }
    /// The range, in words (for `softshadow algos`).
    pub fn range(&self) -> String {
        match self.kind {
            ParamKind::Int { min, max } => format!("{min}..={max}"),
            ParamKind::Float { min, max } => format!("[{min}, {max}]"),
            ParamKind::Choice(w) => w.join("|"),
            ParamKind::Bool => "true|false".into(),
        }
    }
}

/// Current values of an estimator's parameters.
#[derive(Debug, Clone, PartialEq)]
pub struct Params {
    specs: &'static [ParamSpec],
    values: Vec<ParamValue>,
}

impl Params {
    /// All parameters at their defaults. Fails only if a default does not parse (a bug the
    /// estimator registry test catches).
    pub fn new(specs: &'static [ParamSpec]) -> Result<Self> {
        let values = specs
            .iter()
            .map(|s| s.parse(s.default))
            .collect::<Result<_>>()?;
        Ok(Params { specs, values })
    }
    /// The declarations.
    pub fn specs(&self) -> &'static [ParamSpec] {
        self.specs
    }
    /// Sets `key` from a string.
    pub fn set(&mut self, key: &str, value: &str) -> Result<()> {
        let k = self.position(key)?;
        self.values[k] = self.specs[k].parse(value)?;
        Ok(())
    }
    /// Where `key` is declared; an error listing the known keys when it is not.
    fn position(&self, key: &str) -> Result<usize> {
        self.specs.iter().position(|s| s.key == key).ok_or_else(|| {
            let known: Vec<&str> = self.specs.iter().map(|s| s.key).collect();
            Error::param(
                key,
                format!("unknown parameter (known: {})", known.join(", ")),
            )
        })
    }
    /// Sets from `KEY=VALUE`.
    pub fn set_assignment(&mut self, kv: &str) -> Result<()> {
        let (k, v) = parse_assignment(kv)?;
        self.set(k, v)
    }
    /// The value of `key`, if declared.
    pub fn get(&self, key: &str) -> Option<ParamValue> {
        self.specs
            .iter()
            .position(|s| s.key == key)
            .map(|k| self.values[k])
    }
    /// The value of `key`, or an error naming it when the table does not declare it (a
    /// misspelled key is an error, never a default).
    pub fn value(&self, key: &str) -> Result<ParamValue> {
        Ok(self.values[self.position(key)?])
    }
    /// Integer value of `key`; an error when undeclared or not an integer.
    pub fn int(&self, key: &str) -> Result<i64> {
        match self.value(key)? {
            ParamValue::Int(v) => Ok(v),
            v => Err(Error::param(key, format!("{v} is not an integer"))),
        }
    }
    /// Float value of `key` (integers convert); an error when undeclared or not a number.
    pub fn float(&self, key: &str) -> Result<f64> {
        match self.value(key)? {
            ParamValue::Float(v) => Ok(v),
            ParamValue::Int(v) => Ok(v as f64),
            v => Err(Error::param(key, format!("{v} is not a number"))),
        }
    }
    /// Word value of `key`; an error when undeclared or not a choice.
    pub fn choice(&self, key: &str) -> Result<&'static str> {
        match self.value(key)? {
            ParamValue::Choice(v) => Ok(v),
            v => Err(Error::param(
                key,
                format!("{v} is not one of a set of words"),
            )),
        }
    }
    /// Boolean value of `key`; an error when undeclared or not a boolean.
    pub fn flag(&self, key: &str) -> Result<bool> {
        match self.value(key)? {
            ParamValue::Bool(v) => Ok(v),
            v => Err(Error::param(key, format!("{v} is not true or false"))),
        }
    }
    /// `(key, value)` pairs in declaration order.
    pub fn iter(&self) -> impl Iterator<Item = (&'static str, ParamValue)> + '_ {
        self.specs
            .iter()
            .zip(&self.values)
            .map(|(s, v)| (s.key, *v))
    }
}

/// Splits `KEY=VALUE`.
pub fn parse_assignment(kv: &str) -> Result<(&str, &str)> {
    match kv.split_once('=') {
        Some((k, v)) if !k.trim().is_empty() => Ok((k.trim(), v.trim())),
        _ => Err(Error::param(kv, "expected KEY=VALUE")),
    }
}

/// A Rust type a parameter's value can be read as (see [`typed_params!`](crate::typed_params)).
pub trait FromParam: Sized {
    /// The value, or `None` when the declared kind does not convert to `Self`.
    fn from_param(v: ParamValue) -> Option<Self>;
}

/// The words of a [`ParamKind::Choice`] parameter bound to the variants of a fieldless enum, once:
/// `WORDS` (the choice list, in the order given, for the [`ParamSpec`]), `word()`, `Display`
/// (the word) and [`FromParam`] (the word back to the variant; `None` for any other value).
///
/// ```
/// use shadow_map_core::{FromParam, ParamKind, ParamValue};
/// #[derive(Debug, Clone, Copy, PartialEq)]
/// enum Mode { Fast, Exact }
/// shadow_map_core::param_words!(Mode { Exact = "exact", Fast = "fast" });
/// assert_eq!(Mode::WORDS, ["exact", "fast"]);
/// assert_eq!((Mode::Fast.word(), Mode::Exact.to_string()), ("fast", "exact".to_string()));
/// assert_eq!(Mode::from_param(ParamValue::Choice("fast")), Some(Mode::Fast));
/// assert_eq!(Mode::from_param(ParamValue::Choice("slow")), None);
/// let _ = ParamKind::Choice(Mode::WORDS);
/// ```
#[macro_export]
macro_rules! param_words {
    ($t:ident { $($variant:ident = $word:literal),+ $(,)? }) => {
        impl $t {
            /// The parameter's words, one a variant (the [`ParamKind::Choice`]($crate::ParamKind::Choice) list).
            pub const WORDS: &'static [&'static str] = &[$($word),+];
            /// This variant's word.
            pub fn word(self) -> &'static str {
                match self {
                    $($t::$variant => $word,)+
                }
            }
        }
        impl ::std::fmt::Display for $t {
            fn fmt(&self, f: &mut ::std::fmt::Formatter<'_>) -> ::std::fmt::Result {
                f.write_str(self.word())
            }
        }
        impl $crate::FromParam for $t {
            /// The variant of a word of [`Self::WORDS`]; `None` for any other value.
            fn from_param(v: $crate::ParamValue) -> Option<Self> {
                match v {
                    $($crate::ParamValue::Choice($word) => Some($t::$variant),)+
                    _ => None,
                }
            }
        }
    };
}

macro_rules! from_int {
    ($($t:ty),*) => {$(
        impl FromParam for $t {
            fn from_param(v: ParamValue) -> Option<Self> {
                match v {
                    ParamValue::Int(i) => <$t>::try_from(i).ok(),
                    _ => None,
                }
            }
        }
    )*};
}
from_int!(i64, i32, u32, u64, usize);

impl FromParam for f64 {
    fn from_param(v: ParamValue) -> Option<Self> {
        match v {
            ParamValue::Float(x) => Some(x),
            ParamValue::Int(i) => Some(i as f64),
            _ => None,
        }
    }
}
impl FromParam for f32 {
    fn from_param(v: ParamValue) -> Option<Self> {
        f64::from_param(v).map(|x| x as f32)
    }
}
impl FromParam for bool {
    fn from_param(v: ParamValue) -> Option<Self> {
        match v {
            ParamValue::Bool(b) => Some(b),
            _ => None,
        }
    }
}
impl FromParam for &'static str {
    fn from_param(v: ParamValue) -> Option<Self> {
        match v {
            ParamValue::Choice(w) => Some(w),
            _ => None,
        }
    }
}

impl Params {
    /// The value of `spec` as a `T`: a one-line error when `spec` is not in this table or its
    /// kind does not convert (both are bugs of the code that asks, caught by its first test).
    pub fn typed<T: FromParam>(&self, spec: &ParamSpec) -> Result<T> {
        let v = self
            .get(spec.key)
            .ok_or_else(|| Error::param(spec.key, "not in this estimator's parameter table"))?;
        T::from_param(v).ok_or_else(|| {
            Error::param(
                spec.key,
                format!("{v} does not convert to {}", std::any::type_name::<T>()),
            )
        })
    }
}

/// A settings struct read whole from a [`Params`] of its own table: what
/// [`typed_params!`](crate::typed_params) declares (its inherent `SPECS` and `from_params`), or a
/// hand-written pair of such structs over one concatenated table. [`Configured`] keeps one in
/// step with its table.
pub trait TypedParams: Sized {
    /// The parameter table `from_params` reads.
    const SPECS: &'static [ParamSpec];
    /// Every field read from `p` (a [`Params`] holding [`Self::SPECS`]).
    fn from_params(p: &Params) -> Result<Self>;
}

/// An estimator's parameter table and its typed settings `S`, kept in step: every change to the
/// table is read back into `S` at once, so the estimator reads typed fields, never keys, and the
/// two never disagree (a refused change leaves both as they were).
///
/// ```
/// use shadow_map_core::{params::Configured, ParamSpec};
/// shadow_map_core::typed_params! {
///     /// Demo settings.
///     pub struct Demo {
///         /// kernel side
///         kernel: u32 = ParamSpec::int(1, 9, "3"),
///     }
/// }
/// let mut c = Configured::<Demo>::new().unwrap();
/// c.set("kernel", "5").unwrap();
/// assert_eq!((c.settings().kernel, c.params().int("kernel").unwrap()), (5, 5));
/// let odd = |d: &Demo| match d.kernel % 2 {
///     1 => Ok(()),
///     _ => Err(shadow_map_core::Error::param("kernel", "must be odd")),
/// };
/// assert!(c.set_checked("kernel", "4", odd).is_err());
/// assert!(c.set("kernel", "10").is_err());
/// assert_eq!((c.settings().kernel, c.params().int("kernel").unwrap()), (5, 5));
/// ```
#[derive(Debug, Clone, PartialEq)]
pub struct Configured<S> {
    params: Params,
    settings: S,
}

impl<S: TypedParams> Configured<S> {
    /// Every parameter at its default. Fails only if a default does not parse or convert (a bug
    /// the estimator registry test catches).
    pub fn new() -> Result<Self> {
        let params = Params::new(S::SPECS)?;
        Ok(Self {
            settings: S::from_params(&params)?,
            params,
        })
    }
    /// Sets `key` from a string and re-reads the settings; on an error (unknown key, a value
    /// the table refuses) both stay as they were.
    pub fn set(&mut self, key: &str, value: &str) -> Result<()> {
        self.set_checked(key, value, |_| Ok(()))
    }
    /// [`set`](Self::set), also refusing new settings that `check` refuses: the rules the table
    /// cannot express (e.g. an odd kernel).
    pub fn set_checked(
        &mut self,
        key: &str,
        value: &str,
        check: impl FnOnce(&S) -> Result<()>,
    ) -> Result<()> {
        let mut params = self.params.clone();
        params.set(key, value)?;
        let settings = S::from_params(&params)?;
        check(&settings)?;
        (self.params, self.settings) = (params, settings);
        Ok(())
    }
    /// The current parameters (and their declarations).
    pub fn params(&self) -> &Params {
        &self.params
    }
    /// The current parameters, typed.
    pub fn settings(&self) -> &S {
        &self.settings
    }
}

/// Whether two strings are equal, in a `const` context ([`typed_params!`](crate::typed_params)
/// checks at compile time that every field is named like its key).
pub const fn same_key(a: &str, b: &str) -> bool {
    let (a, b) = (a.as_bytes(), b.as_bytes());
    if a.len() != b.len() {
        return false;
    }
    let mut i = 0;
    while i < a.len() {
        if a[i] != b[i] {
            return false;
        }
        i += 1;
    }
    true
}

/// The total length of `parts`, in a `const` context (the `N` of [`concat_spec_parts`]).
pub const fn spec_parts_len(parts: &[&[ParamSpec]]) -> usize {
    let mut n = 0;
    let mut k = 0;
    while k < parts.len() {
        n += parts[k].len();
        k += 1;
    }
    n
}

/// `parts` one after another, as an array of `N = spec_parts_len(parts)` specs, in a `const`
/// context (see [`concat_specs!`](crate::concat_specs), which supplies `N`).
pub const fn concat_spec_parts<const N: usize>(parts: &[&[ParamSpec]]) -> [ParamSpec; N] {
    assert!(
        spec_parts_len(parts) == N,
        "concat_spec_parts: N is not the sum of the lengths"
    );
    const BLANK: ParamSpec = ParamSpec::flag(false);
    let mut out = [BLANK; N];
    let (mut i, mut k) = (0, 0);
    while k < parts.len() {
        let mut j = 0;
        while j < parts[k].len() {
            out[i] = parts[k][j];
            i += 1;
            j += 1;
        }
        k += 1;
    }
    out
}

/// The parameter tables `$a`, `$b`, ... (each a `&[ParamSpec]` constant) one after another, as a
/// `&'static [ParamSpec]` constant: a table shared by several estimators (one
/// [`typed_params!`](crate::typed_params) struct's `SPECS`) followed by one estimator's own (a
/// second struct's), each read by its own `from_params` from the same [`Params`].
///
/// ```
/// use shadow_map_core::{light_view::{BIAS, RESOLUTION}, ParamKind, ParamSpec, Params};
/// shadow_map_core::typed_params! {
///     /// Shared.
///     pub struct Shared { resolution: u32 = RESOLUTION, bias: f32 = BIAS }
/// }
/// shadow_map_core::typed_params! {
///     /// Own.
///     pub struct Own {
///         kernel: u32 = ParamSpec::int(1, 9, "3").named("kernel", "kernel side"),
///     }
/// }
/// const SPECS: &[ParamSpec] = shadow_map_core::concat_specs!(Shared::SPECS, Own::SPECS);
/// let keys: Vec<_> = SPECS.iter().map(|s| s.key).collect();
/// assert_eq!(keys, ["resolution", "bias", "kernel"]);
/// let p = Params::new(SPECS).unwrap();
/// assert_eq!((Shared::from_params(&p).unwrap().resolution, Own::from_params(&p).unwrap().kernel), (1024, 3));
/// ```
#[macro_export]
macro_rules! concat_specs {
    ($($a:expr),+ $(,)?) => {
        &$crate::params::concat_spec_parts::<{ $crate::params::spec_parts_len(&[$($a),+]) }>(&[$($a),+])
    };
}

/// Declares an estimator's parameters once: a struct with one typed field a parameter, its
/// [`ParamSpec`] table (`SPECS`, what `softshadow algos`, `--param` and
/// [`SoftShadowEstimator::set_param`](crate::SoftShadowEstimator::set_param) use) and
/// `from_params`, which reads every field from a [`Params`] of that table (both also as its
/// [`TypedParams`] impl, for [`Configured`]). A field declared with
/// [`ParamSpec::int`], `float`, `choice` or `flag` is keyed by its name and described by its doc
/// comment (one text for rustdoc and `softshadow algos`); a spec shared from elsewhere keeps its
/// own key and help, and its key must equal the field's name (checked at compile time), so code
/// never spells a key as a string.
///
/// ```
/// use shadow_map_core::{light_view::RESOLUTION, ParamSpec, Params};
/// shadow_map_core::typed_params! {
///     /// Settings of a demo estimator.
///     pub struct Demo {
///         /// Shadow-map side.
///         resolution: u32 = RESOLUTION,
///         /// kernel side
///         kernel: u32 = ParamSpec::int(1, 9, "3"),
///     }
/// }
/// let mut p = Params::new(Demo::SPECS).unwrap();
/// p.set("kernel", "5").unwrap();
/// let d = Demo::from_params(&p).unwrap();
/// assert_eq!((d.resolution, d.kernel), (1024, 5));
/// assert_eq!((Demo::SPECS[1].key, Demo::SPECS[1].help), ("kernel", "kernel side"));
/// assert!(p.set("kernle", "5").is_err());
/// ```
///
/// Groups declared once elsewhere (another `typed_params!` struct, e.g. the shared
/// [`ViewOptions`](crate::light_view::ViewOptions)) follow the own fields after a `;`: each is a
/// field of that type, and its table follows the own parameters in `SPECS`.
///
/// ```
/// use shadow_map_core::{light_view::{ViewOptions, RESOLUTION}, Params};
/// shadow_map_core::typed_params! {
///     /// Settings with a group.
///     pub struct WithView {
///         /// Shadow-map side.
///         resolution: u32 = RESOLUTION,
///         ;
///         /// Window and near/far choice.
///         view: ViewOptions,
///     }
/// }
/// let keys: Vec<_> = WithView::SPECS.iter().map(|s| s.key).collect();
/// assert_eq!(keys, ["resolution", "fit", "nearfar"]);
/// let mut p = Params::new(WithView::SPECS).unwrap();
/// p.set("fit", "stable").unwrap();
/// let w = WithView::from_params(&p).unwrap();
/// assert_eq!(w.view.fit.word(), "stable");
/// ```
#[macro_export]
macro_rules! typed_params {
    (
        $(#[$meta:meta])*
        $vis:vis struct $name:ident {
            $( $(#[doc = $doc:literal])* $field:ident : $ty:ty = $spec:expr ),* $(,)?
            $( ; $( $(#[$gmeta:meta])* $group:ident : $gty:ty ),+ $(,)? )?
        }
    ) => {
        $(#[$meta])*
        #[derive(Debug, Clone, Copy, PartialEq)]
        $vis struct $name {
            $( $(#[doc = $doc])* pub $field: $ty, )*
            $($( $(#[$gmeta])* pub $group: $gty, )+)?
        }

        impl $name {
            /// This struct's own parameters, in declaration order (its groups' follow in
            /// [`Self::SPECS`]).
            pub const OWN_SPECS: &'static [$crate::ParamSpec] = &[$(
                $crate::ParamSpec::declared($spec, stringify!($field), concat!("" $(, $doc)*))
            ),*];

            /// The parameter table: the own parameters, then each group's table in order.
            pub const SPECS: &'static [$crate::ParamSpec] =
                $crate::concat_specs!($name::OWN_SPECS $($(, <$gty>::SPECS)+)?);

            /// Every field read from `p` (a [`Params`]($crate::Params) holding [`Self::SPECS`]).
            pub fn from_params(p: &$crate::Params) -> $crate::Result<Self> {
                let specs = Self::OWN_SPECS;
                let mut k = 0usize;
                $(
                    let $field: $ty = p.typed(&specs[k])?;
                    k += 1;
                )*
                let _ = k;
                $($( let $group = <$gty>::from_params(p)?; )+)?
                Ok(Self { $($field,)* $($($group,)+)? })
            }
        }

        impl $crate::TypedParams for $name {
            // The inherent items above (inherent items come first in path resolution).
            const SPECS: &'static [$crate::ParamSpec] = $name::SPECS;
            fn from_params(p: &$crate::Params) -> $crate::Result<Self> {
                $name::from_params(p)
            }
        }

        const _: () = {
            let specs = $name::OWN_SPECS;
            let mut k = 0usize;
            $(
                assert!(
                    $crate::params::same_key(stringify!($field), specs[k].key),
                    concat!("typed_params!: field `", stringify!($field), "` is not named like its key")
                );
                k += 1;
            )*
            let _ = k;
        };
    };
}

#[cfg(test)]
mod tests {
    use super::*;

    const SPECS: &[ParamSpec] = &[
        ParamSpec::int(1, 9, "3").named("k", ""),
        ParamSpec::choice(&["a", "b"], "a").named("mode", ""),
    ];

    /// A misspelled or mistyped key is an error naming it, never 0 or "".
    #[test]
    fn typed_getters_refuse_unknown_and_mistyped_keys() {
        let p = Params::new(SPECS).unwrap();
        assert_eq!(p.int("k").unwrap(), 3);
        assert_eq!(p.float("k").unwrap(), 3.0);
        assert_eq!(p.choice("mode").unwrap(), "a");
        let e = p.int("kk").unwrap_err().to_string();
        assert!(e.contains("kk") && e.contains("known: k, mode"), "{e}");
        assert!(p.choice("k").unwrap_err().to_string().contains("k"));
        assert!(p.flag("mode").is_err());
        assert!(p.int("mode").is_err());
    }
}
