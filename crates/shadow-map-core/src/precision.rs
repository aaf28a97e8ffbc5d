//! Depth precision of a stored shadow map (`--param depth=f32|unorm16`).
//!
//! Common techniques ("Calculating the near plane and far plane"): with tight near and far planes
//! a 16-bit depth map may be enough, at half the memory and bandwidth of 32-bit floats. Model only
//! what a scene needs: the map is rendered in f32 (the render target is transient) and stored for
//! the estimate as 16-bit codes over `[n, far]`.
//!
//! **Encoding.** With the step `s` the smallest power of two at or above `(far - n) / 65534`
//! (a power of two so that decoding is one exact multiply and one correctly rounded add, bit for
//! bit the same on every backend; it costs at most one bit against the ideal step), a depth `z`
//! is stored as the code `q = round_half_even((z - n) / s)`, clamped below at 0; a depth with
//! `(z - n) / s >= 65534.5`, +inf (empty) or NaN is stored as [`EMPTY_CODE`] (never occludes:
//! no receiver lies beyond far, which every near/far mode keeps at or beyond the farthest
//! receiver). Decoding gives `z' = n + q s`, so `|z' - z| <= s / 2` for stored depths.
//!
//! **Bias.** A receiver on the surface the map stores may find it up to `s / 2` nearer than it
//! is, so estimators add `s / 2` ([`Unorm16Map::half_step`]) to their receiver bias under
//! `unorm16`: the quantisation never adds acne, at the price of up to `s / 2` more
//! peter-panning (measured in `scripts/depth-table.sh`).
use crate::{params::ParamSpec, raster::DepthMap};

/// The code of an empty texel (and of depths beyond the representable range): +inf.
pub const EMPTY_CODE: u16 = u16::MAX;
/// The largest code of a stored depth.
pub const MAX_CODE: u16 = u16::MAX - 1;

/// How an estimator stores its shadow map.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub enum DepthPrecision {
    /// 32-bit float linear depth (4 bytes per texel), the default.
    #[default]
    F32,
    /// 16-bit codes over `[n, far]` (2 bytes per texel), see the module documentation.
    Unorm16,
}

crate::param_words!(DepthPrecision { F32 = "f32", Unorm16 = "unorm16" });

/// `depth`: the stored precision ([`DepthPrecision`]).
pub const DEPTH: ParamSpec = ParamSpec::choice(DepthPrecision::WORDS, "f32").named("depth", "stored shadow-map depth: 32-bit float, or 16-bit codes over [near, far] (half the memory; bias grows by half a code step)");

impl DepthPrecision {
    /// Bytes per stored texel.
    pub fn bytes_per_texel(self) -> usize {
        match self {
            DepthPrecision::F32 => 4,
            DepthPrecision::Unorm16 => 2,
        }
    }
}

/// Reads one depth per texel: implemented by the f32 [`DepthMap`] and the 16-bit
/// [`Unorm16Map`], so a filter is written once and compiled for each.
pub trait DepthLookup: Sync {
    /// Side in texels.
    fn size(&self) -> u32;
    /// Depth at texel (i, j); +inf outside the map or where empty.
    fn at(&self, i: i32, j: i32) -> f32;
}

impl DepthLookup for DepthMap {
    #[inline]
    fn size(&self) -> u32 {
        self.size
    }
    #[inline]
    fn at(&self, i: i32, j: i32) -> f32 {
        DepthMap::at(self, i, j)
    }
}

/// The code step `s`: the smallest power of two at or above `(far - n) / 65534` (at least the
/// smallest normal f32, and 1 for a non-finite or empty range).
pub fn step_for(n: f32, far: f32) -> f32 {
    let range = far as f64 - n as f64;
    if !(range > 0.0) || !range.is_finite() {
        return 1.0;
    }
    let e = (range / MAX_CODE as f64).log2().ceil() as i32;
    (2f64.powi(e.clamp(-126, 127)) as f32).max(f32::MIN_POSITIVE)
}

/// Encodes one depth (see the module documentation); `inv_step` is `1 / s`, exact for a power of
/// two. The GPU encoder (`gpu::precision`) performs the same operations.
#[inline]
pub fn encode(z: f32, n: f32, inv_step: f32) -> u16 {
    let t = (z - n) * inv_step;
    if !(t < MAX_CODE as f32 + 0.5) {
        // Beyond the range, +inf or NaN: empty.
        return EMPTY_CODE;
    }
    if !(t > 0.0) {
        return 0;
    }
    t.round_ties_even() as u16
}

/// Decodes one code: `n + q s`, +inf for [`EMPTY_CODE`].
#[inline]
pub fn decode(q: u16, n: f32, step: f32) -> f32 {
    if q == EMPTY_CODE {
        f32::INFINITY
    } else {
        n + q as f32 * step
    }
}

/// A shadow map stored as 16-bit codes over `[n, far]` (see the module documentation).
#[derive(Debug, Clone, PartialEq)]
pub struct Unorm16Map {
    /// Side in texels.
    pub size: u32,
    /// The near plane n (code 0).
    pub near: f32,
    /// The code step s (a power of two).
    pub step: f32,
    /// Codes, row-major, texel (i, j) at `j * size + i`.
    pub codes: Vec<u16>,
}

impl Unorm16Map {
    /// Encodes an f32 map for a view with planes `n` and `far`.
    pub fn encode(map: &DepthMap, n: f32, far: f32) -> Self {
        let step = step_for(n, far);
        let inv = 1.0 / step;
        Unorm16Map {
            size: map.size,
            near: n,
            step,
            codes: map.depth.iter().map(|&z| encode(z, n, inv)).collect(),
        }
    }
    /// Half a code step: the bias an estimator adds under `unorm16`.
    pub fn half_step(&self) -> f32 {
        0.5 * self.step
    }
    /// Bytes of storage (2 per texel).
    pub fn bytes(&self) -> usize {
        self.codes.len() * 2
    }
    /// The decoded map (f32 depths `n + q s`), for comparisons.
    pub fn decode_map(&self) -> DepthMap {
        DepthMap {
            size: self.size,
            depth: self
                .codes
                .iter()
                .map(|&q| decode(q, self.near, self.step))
                .collect(),
        }
    }
}

impl DepthLookup for Unorm16Map {
    #[inline]
    fn size(&self) -> u32 {
        self.size
    }
    #[inline]
    fn at(&self, i: i32, j: i32) -> f32 {
        if i < 0 || j < 0 || i >= self.size as i32 || j >= self.size as i32 {
            f32::INFINITY
        } else {
            decode(
                self.codes[j as usize * self.size as usize + i as usize],
                self.near,
                self.step,
            )
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn step_is_a_power_of_two_covering_the_range() {
        for (n, far) in [(0.1f32, 10.0f32), (1.0, 1.0001), (1e-4, 1e5), (3.0, 3.0)] {
            let s = step_for(n, far);
            assert_eq!(s.to_bits() & 0x007f_ffff, 0, "{s} not a power of two");
            if far > n {
                assert!(n as f64 + MAX_CODE as f64 * s as f64 >= far as f64);
                assert!(s as f64 / 2.0 < (far - n) as f64 / MAX_CODE as f64 * 1.0000001);
            }
        }
    }

    #[test]
    fn round_trip_error_is_at_most_half_a_step() {
        let (n, far) = (0.37f32, 12.9f32);
        let s = step_for(n, far);
        let inv = 1.0 / s;
        let mut worst = 0.0f32;
        for k in 0..=100_000 {
            let z = n + (far - n) * k as f32 / 100_000.0;
            let q = encode(z, n, inv);
            assert_ne!(q, EMPTY_CODE, "z = {z} inside [n, far] must be stored");
            worst = worst.max((decode(q, n, s) - z).abs());
        }
        // Half a step plus the rounding of z - n and of the decode.
        assert!(
            worst <= 0.5 * s + 4.0 * f32::EPSILON * far,
            "{worst} vs {s}"
        );
    }

    #[test]
    fn empty_nan_and_beyond_range_never_occlude() {
        let (n, s) = (1.0f32, step_for(1.0, 2.0));
        let inv = 1.0 / s;
        for z in [f32::INFINITY, f32::NAN, 1e30, n + 65535.0 * s] {
            assert_eq!(encode(z, n, inv), EMPTY_CODE, "{z}");
        }
        assert_eq!(decode(EMPTY_CODE, n, s), f32::INFINITY);
        assert_eq!(encode(-5.0, n, inv), 0);
        assert_eq!(encode(f32::NEG_INFINITY, n, inv), 0);
        let map = DepthMap {
            size: 2,
            depth: vec![1.5, f32::INFINITY, 0.5, 2.0],
        };
        let q = Unorm16Map::encode(&map, n, 2.0);
        assert_eq!(q.bytes(), 8);
        assert_eq!(q.at(1, 0), f32::INFINITY);
        assert_eq!(q.at(-1, 0), f32::INFINITY);
        assert!((q.at(0, 0) - 1.5).abs() <= q.half_step());
        assert_eq!(q.at(0, 1), 1.0);
    }
}
