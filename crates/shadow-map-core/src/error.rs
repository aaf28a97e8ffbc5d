//! Typed errors for the whole workspace's shared layer.
//!
//! Every variant renders as one line that names what is wrong: the file, the key or line, the
//! parameter, or the limit.
use std::path::PathBuf;

/// Result alias used at every boundary of `shadow-map-core`.
pub type Result<T, E = Error> = std::result::Result<T, E>;

/// Everything that can go wrong in the scene model, the light view, the shadow-map core and the
/// estimators built on it.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// A scene file (TOML) is wrong: unknown or missing key, wrong type, non-finite number,
    /// degenerate light, ...
    #[error("{}: {}{reason}", path.display(), key.as_ref().map(|k| format!("key `{k}`: ")).unwrap_or_default())]
    Scene {
        /// The scene file.
        path: PathBuf,
        /// The offending key (dotted, e.g. `light.size`), when one is to blame.
        key: Option<String>,
        /// What is wrong.
        reason: String,
    },
    /// A Wavefront OBJ file is missing or malformed.
    #[error("{}{}: {reason}", path.display(), line.map(|l| format!(":{l}")).unwrap_or_default())]
    Obj {
        /// The OBJ file.
        path: PathBuf,
        /// 1-based line, when known.
        line: Option<usize>,
        /// What is wrong.
        reason: String,
    },
    /// A glTF 2.0 file is missing or malformed (not glTF, truncated, a buffer missing, a
    /// primitive mode other than triangles, ...).
    #[error("{}: {reason}", path.display())]
    Gltf {
        /// The glTF file.
        path: PathBuf,
        /// What is wrong.
        reason: String,
    },
    /// The scene has nothing to render (no triangles left after loading).
    #[error("{}: the scene has no triangles ({skipped} degenerate triangles were skipped)", path.display())]
    EmptyScene {
        /// The scene file.
        path: PathBuf,
        /// How many zero-area triangles were dropped.
        skipped: usize,
    },
    /// An estimator parameter is unknown, malformed or out of range.
    #[error("parameter `{key}`: {reason}")]
    Param {
        /// The parameter key.
        key: String,
        /// What is wrong.
        reason: String,
    },
    /// Receivers given by the user are inconsistent (length mismatch, non-finite values, ...).
    #[error("receivers: {0}")]
    Receivers(String),
    /// A size or count is past what this backend supports.
    #[error("{what}: requested {requested}, maximum {max}")]
    Limit {
        /// What hit the limit.
        what: &'static str,
        /// What was asked for.
        requested: u64,
        /// The largest value supported.
        max: u64,
    },
    /// The light view cannot be fitted (no receiver in front of the light, degenerate frame).
    #[error("light view: {0}")]
    LightView(String),
    /// No Vulkan adapter was found (wgpu is asked for Vulkan only: never a silent GL fall-back).
    #[error(
        "no Vulkan adapter: {0} (install mesa-vulkan-drivers for lavapipe, or use --backend cpu)"
    )]
    NoAdapter(String),
    /// The GPU device was lost.
    #[error("GPU device lost: {0}")]
    DeviceLost(String),
    /// The GPU ran out of memory.
    #[error("GPU out of memory: {0}")]
    OutOfMemory(String),
    /// Any other GPU error (validation of a pipeline, buffer mapping...).
    #[error("GPU error in {stage}: {reason}")]
    Gpu {
        /// The stage (pipeline or pass label).
        stage: String,
        /// What went wrong.
        reason: String,
    },
    /// The render was cancelled through its [`Cancel`](crate::Cancel) token (V is incomplete).
    #[error("cancelled")]
    Cancelled,
    /// An I/O error on a named file.
    #[error("{}: {source}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// The underlying error.
        source: std::io::Error,
    },
}

impl Error {
    /// `Ok` for a count or side `n` in `1..=max`, else [`Error::Limit`] naming `what`.
    pub fn check_in_range(what: &'static str, n: u32, max: u32) -> Result<()> {
        if n == 0 || n > max {
            return Err(Error::Limit {
                what,
                requested: n as u64,
                max: max as u64,
            });
        }
        Ok(())
    }

    /// Shorthand for a [`Error::Param`].
    pub fn param(key: impl Into<String>, reason: impl Into<String>) -> Self {
        Error::Param {
            key: key.into(),
            reason: reason.into(),
        }
    }
}
