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
        let k = self
            .specs
            .iter()
            .position(|s| s.key == key)
            .ok_or_else(|| {
                let known: Vec<&str> = self.specs.iter().map(|s| s.key).collect();
                Error::param(
                    key,
                    format!("unknown parameter (known: {})", known.join(", ")),
                )
            })?;
        self.values[k] = self.specs[k].parse(value)?;
        Ok(())
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
    /// Integer value of `key` (0 if undeclared or not an integer).
    pub fn int(&self, key: &str) -> i64 {
        match self.get(key) {
            Some(ParamValue::Int(v)) => v,
            _ => 0,
        }
    }
    /// Float value of `key` (integers convert; 0 if undeclared).
    pub fn float(&self, key: &str) -> f64 {
        match self.get(key) {
            Some(ParamValue::Float(v)) => v,
            Some(ParamValue::Int(v)) => v as f64,
            _ => 0.0,
        }
    }
    /// Word value of `key` ("" if undeclared).
    pub fn choice(&self, key: &str) -> &'static str {
        match self.get(key) {
            Some(ParamValue::Choice(v)) => v,
            _ => "",
        }
    }
    /// Boolean value of `key` (false if undeclared).
    pub fn flag(&self, key: &str) -> bool {
        matches!(self.get(key), Some(ParamValue::Bool(true)))
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
