//! The ray-traced ground truth: V by stratified light samples and shadow rays through the BVH.
//!
//! For every active receiver `p` with normal `n` (facing the camera), with `N = s * s` light samples
//! `y_k`:
//!
//! ```text
//! V(p) = (1/N) sum_k vis(p, y_k)
//! vis(p, y) = 0                                   if n.(y - p) <= 0 (behind the receiver's tangent plane)
//!           = T(p + eps n -> y)                   otherwise
//! ```
//!
//! where `T` is the transmittance of the segment ([`SceneBvh::transmittance`]): 0 if any opaque
//! surface is crossed, else the product of `(1 - opacity)` over every semi-transparent surface crossed
//! (docs/methods.md §11, "Visibility image"). Rect and disk lights are one-sided: a receiver with
//! `(p - C).normal <= 0` gets V = 0 without tracing.
//!
//! **Light samples.** Rect and disk: `frame.to_world((x, y, 0))` for the points of
//! [`Light::stratified_points`] (a jittered `s x s` grid, concentric-mapped onto disks). Sphere: the
//! same concentric points on the contract's silhouette disk, the disk of the sphere's radius through
//! the centre perpendicular to `d = normalize(C - p)`, spanned by `default_tangent(d)` and
//! `d x default_tangent(d)`.
//!
//! **Jitter.** Correlated multi-jittered sampling (Kensler 2013, "Correlated Multi-Jittered
//! Sampling", Pixar technical memo 13-01): the sample of stratum (column a, row b) sits in sub-column
//! `sigma(b)` of its column and sub-row `tau(a)` of its row, for two random permutations `sigma`, `tau`
//! of `0..s`, plus a uniform jitter inside that sub-cell. Every sample is still uniform within its
//! stratum (the estimator is unbiased, exactly as plain jittered sampling), and in addition the N
//! samples are stratified into N slabs along each light axis, which removes most of the noise at
//! shadow edges parallel to the light's axes. The permutations and jitters come from a splitmix64
//! hash of `(seed, receiver index, sample index)`, so the result is deterministic and independent
//! of thread scheduling.
//!
//! **Offsets.** The ray starts at `p + eps n` with `eps = `[`RAY_OFFSET_REL`]` * bvh.scale` (scene
//! diagonal) so it cannot hit the receiver's own surface, and stops at
//! `|y - origin| * (1 - `[`SEGMENT_SHORTEN_REL`]`)` so geometry lying in the light's plane at the
//! sample does not count.
use glam::{Vec2, Vec3};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use rayon::prelude::*;
use shadow_map_core::{
    light::default_tangent, Cancel, Error, Light, LightShape, Receivers, Result, Scene, SceneBvh,
};

/// Default samples per side of the stratified grid: `32 * 32 = 1024` samples per receiver.
pub const DEFAULT_SAMPLES_PER_SIDE: u32 = 32;
/// Largest samples per side accepted: `256 * 256 = 65536` samples per receiver.
pub const MAX_SAMPLES_PER_SIDE: u32 = 256;
/// Shadow-ray origin offset along the receiver normal, relative to the scene diagonal
/// ([`SceneBvh::scale`]): `eps = 1e-5 * scale`.
pub const RAY_OFFSET_REL: f32 = 1e-5;
/// Relative shortening of the shadow segment at the light end: `t_max = |y - origin| * (1 - 1e-6)`.
pub const SEGMENT_SHORTEN_REL: f32 = 1e-6;
/// With `progress` on, a progress bar is drawn only from this many active receivers up.
pub const PROGRESS_MIN_RECEIVERS: usize = 16_384;
/// Receivers per parallel work item (and per progress-bar update).
const CHUNK: usize = 64;

/// How the reference samples the light.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct TraceOptions {
    /// `s`: the light is sampled on an `s x s` stratified grid, `N = s * s` samples per receiver.
    /// Must be in `1..=`[`MAX_SAMPLES_PER_SIDE`].
    pub samples_per_side: u32,
    /// Seed of the jitter (any value; the same seed gives bit-identical results).
    pub seed: u64,
}

impl Default for TraceOptions {
    /// `s = 32` (1024 samples per receiver), seed 1.
    fn default() -> Self {
        TraceOptions {
            samples_per_side: DEFAULT_SAMPLES_PER_SIDE,
            seed: 1,
        }
    }
}

impl TraceOptions {
    /// Options for at least `spp` samples: `s = ceil(sqrt(spp))` (at least 1), so the count used,
    /// [`samples`](Self::samples), is the smallest square `>= spp`. `s` is capped at
    /// [`MAX_SAMPLES_PER_SIDE`].
    pub fn from_spp(spp: u32, seed: u64) -> Self {
        let mut s = (spp as f64).sqrt().floor() as u32;
        while s.saturating_mul(s) < spp {
            s += 1;
        }
        TraceOptions {
            samples_per_side: s.clamp(1, MAX_SAMPLES_PER_SIDE),
            seed,
        }
    }
    /// Samples per receiver, `s * s`.
    pub fn samples(&self) -> u32 {
        self.samples_per_side.saturating_mul(self.samples_per_side)
    }
    fn validate(&self) -> Result<()> {
        if self.samples_per_side == 0 || self.samples_per_side > MAX_SAMPLES_PER_SIDE {
            return Err(Error::param(
                "samples_per_side",
                format!(
                    "{} is out of range 1..={MAX_SAMPLES_PER_SIDE}",
                    self.samples_per_side
                ),
            ));
        }
        Ok(())
    }
}

/// Computes V for every receiver into `v` (same length as `receivers`): NaN for inactive receivers,
/// a value in `[0, 1]` for active ones (see the [module documentation](self) for the definition).
/// Runs in parallel over receivers (rayon). With `progress`, draws a progress bar on standard error
/// when there are at least [`PROGRESS_MIN_RECEIVERS`] active receivers; never prints otherwise.
/// Checks `cancel` before every receiver (one relaxed load next to its `s * s` shadow rays) and
/// returns [`Error::Cancelled`] once it is set, V then incomplete; receivers finished are added
/// to [`Cancel::progress`] per chunk of 64.
///
/// Errors: `v`, the normals or the activity flags not matching the receiver count
/// ([`Error::Receivers`]); `samples_per_side` out of range ([`Error::Param`]).
pub fn visibility(
    scene: &Scene,
    bvh: &SceneBvh,
    receivers: &Receivers,
    opts: &TraceOptions,
    v: &mut [f32],
    progress: bool,
    cancel: &Cancel,
) -> Result<()> {
    opts.validate()?;
    let n = receivers.len();
    if v.len() != n || receivers.normal().len() != n || receivers.active().len() != n {
        return Err(Error::Receivers(format!(
            "{} positions, {} normals, {} activity flags and {} output slots must all be equal",
            n,
            receivers.normal().len(),
            receivers.active().len(),
            v.len()
        )));
    }
    let light = scene.light();
    let active = receivers.active_count();
    let bar = (progress && active >= PROGRESS_MIN_RECEIVERS).then(|| progress_bar(active as u64));
    v.par_chunks_mut(CHUNK).enumerate().for_each(|(c, out)| {
        let base = c * CHUNK;
        let mut done = 0u64;
        for (k, slot) in out.iter_mut().enumerate() {
            if cancel.is_cancelled() {
                return;
            }
            let i = base + k;
            *slot = if receivers.active()[i] {
                done += 1;
                receiver_visibility(
                    light,
                    bvh,
                    receivers.position()[i],
                    receivers.normal()[i],
                    opts,
                    i as u64,
                )
            } else {
                f32::NAN
            };
        }
        if let Some(bar) = &bar {
            bar.inc(done);
        }
        cancel.add_progress(out.len());
    });
    if let Some(bar) = bar {
        bar.finish_and_clear();
    }
    cancel.check()
}

fn progress_bar(len: u64) -> ProgressBar {
    let bar = ProgressBar::with_draw_target(Some(len), ProgressDrawTarget::stderr());
    if let Ok(style) = ProgressStyle::with_template(
        "reference {bar:40} {pos}/{len} receivers ({percent}%, {elapsed} elapsed, ~{eta} left)",
    ) {
        bar.set_style(style);
    }
    bar
}

/// V of one receiver at `p` with unit normal `n` (facing the side it is seen from), as
/// [`visibility`] computes it; `index` selects the receiver's jitter stream (use the receiver's
/// slot to reproduce [`visibility`] bit for bit). Returns a value in `[0, 1]`; a non-finite `p` or
/// `n` gives 0. `opts.samples_per_side` is clamped into `1..=`[`MAX_SAMPLES_PER_SIDE`].
pub fn receiver_visibility(
    light: &Light,
    bvh: &SceneBvh,
    p: Vec3,
    n: Vec3,
    opts: &TraceOptions,
    index: u64,
) -> f32 {
    if !p.is_finite() || !n.is_finite() {
        return 0.0;
    }
    if light.one_sided() && (p - light.center).dot(light.normal) <= 0.0 {
        return 0.0;
    }
    let s = opts.samples_per_side.clamp(1, MAX_SAMPLES_PER_SIDE);
    // The sampled disk or rectangle: centre and two in-plane axes.
    let (c, bx, by) = match light.shape {
        LightShape::Sphere { .. } => {
            let d = (light.center - p).try_normalize().unwrap_or(light.normal);
            let bx = default_tangent(d);
            (light.center, bx, d.cross(bx))
        }
        LightShape::Rect { .. } | LightShape::Disk { .. } => {
            let f = light.frame();
            (f.origin, f.ex, f.ey)
        }
        // The contract's disk of directions: radius tan(angle / 2) at unit distance from p,
        // perpendicular to the travel direction; each sample is a direction, its ray unbounded.
        LightShape::Directional { .. } => {
            let f = light.frame();
            (p - f.ez, f.ex, f.ey)
        }
    };
    let distant = light.is_directional();
    let origin = p + n * (RAY_OFFSET_REL * bvh.scale);
    let sampler = Sampler::new(opts.seed, index, s);
    let points = light.stratified_points(s, |k| sampler.jitter(k));
    let mut sum = 0.0f64;
    for pt in points {
        let y = c + pt.x * bx + pt.y * by;
        if n.dot(y - p) <= 0.0 {
            continue;
        }
        let to = if distant { y - p } else { y - origin };
        let dist = to.length();
        if !(dist > 0.0 && dist.is_finite()) {
            continue;
        }
        let t_max = if distant {
            f32::INFINITY
        } else {
            dist * (1.0 - SEGMENT_SHORTEN_REL)
        };
        sum += bvh.transmittance(origin, to / dist, 0.0, t_max) as f64;
    }
    let v = sum / (s as f64 * s as f64);
    if v.is_finite() {
        v.clamp(0.0, 1.0) as f32
    } else {
        0.0
    }
}

/// The largest `f32` below 1.
const ONE_MINUS: f32 = 1.0 - f32::EPSILON / 2.0;

/// Correlated multi-jittered sampler for one receiver (see the module documentation).
struct Sampler {
    key: u64,
    s: u32,
    /// `sigma(b)`: the sub-column of the samples in row b.
    sub_col: Vec<u32>,
    /// `tau(a)`: the sub-row of the samples in column a.
    sub_row: Vec<u32>,
}

impl Sampler {
    fn new(seed: u64, receiver: u64, s: u32) -> Self {
        let key = hash2(seed, receiver);
        Sampler {
            key,
            s,
            sub_col: permutation(s, hash2(key, 0x5ca1ab1e)),
            sub_row: permutation(s, hash2(key, 0x0ddba11)),
        }
    }
    /// Offset in `[0, 1)^2` within stratum `k = b * s + a`.
    fn jitter(&self, k: u32) -> Vec2 {
        let (a, b) = ((k % self.s) as usize, (k / self.s) as usize);
        let h = hash2(self.key, 0x1000_0000_0000 + k as u64);
        let (xi, eta) = (unit_f32(h), unit_f32(h << 32));
        let sc = self.sub_col.get(b).copied().unwrap_or(0) as f32;
        let sr = self.sub_row.get(a).copied().unwrap_or(0) as f32;
        let s = self.s as f32;
        Vec2::new(
            ((sc + xi) / s).min(ONE_MINUS),
            ((sr + eta) / s).min(ONE_MINUS),
        )
    }
}

/// A uniformly random permutation of `0..s` (Fisher-Yates on a splitmix64 stream).
fn permutation(s: u32, seed: u64) -> Vec<u32> {
    let mut v: Vec<u32> = (0..s).collect();
    let mut state = seed;
    for i in (1..v.len()).rev() {
        state = state.wrapping_add(GOLDEN);
        let r = mix64(state);
        // Multiply-shift range reduction to 0..=i (bias < 2^-32 * s, irrelevant here).
        let j = (((r >> 32) * (i as u64 + 1)) >> 32) as usize;
        v.swap(i, j);
    }
    v
}

const GOLDEN: u64 = 0x9E37_79B9_7F4A_7C15;

/// The splitmix64 finalizer (Steele, Lea, Flood 2014): a bijective 64-bit mixer.
#[inline]
fn mix64(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

#[inline]
fn hash2(a: u64, b: u64) -> u64 {
    mix64(
        mix64(a.wrapping_add(GOLDEN)) ^ b.wrapping_mul(GOLDEN).wrapping_add(0x6A09_E667_F3BC_C909),
    )
}

/// The top 24 bits of `h` as a float in `[0, 1)`.
#[inline]
fn unit_f32(h: u64) -> f32 {
    (h >> 40) as f32 * (1.0 / 16_777_216.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn permutations_are_permutations() {
        for s in [1u32, 2, 7, 32] {
            for seed in 0..20 {
                let mut p = permutation(s, seed);
                p.sort_unstable();
                assert_eq!(p, (0..s).collect::<Vec<_>>());
            }
        }
    }

    #[test]
    fn multi_jitter_is_stratified_both_ways() {
        let s = 16u32;
        let sampler = Sampler::new(7, 3, s);
        let n = (s * s) as usize;
        let mut xs = vec![0u32; n];
        let mut ys = vec![0u32; n];
        for k in 0..s * s {
            let j = sampler.jitter(k);
            assert!(j.x >= 0.0 && j.x < 1.0 && j.y >= 0.0 && j.y < 1.0);
            let (a, b) = (k % s, k / s);
            let u = (a as f32 + j.x) / s as f32;
            let v = (b as f32 + j.y) / s as f32;
            xs[((u * n as f32) as usize).min(n - 1)] += 1;
            ys[((v * n as f32) as usize).min(n - 1)] += 1;
        }
        // One sample per fine slab along each axis (N-rooks), as well as one per stratum.
        assert!(xs.iter().all(|&c| c == 1), "{xs:?}");
        assert!(ys.iter().all(|&c| c == 1), "{ys:?}");
    }

    #[test]
    fn from_spp_rounds_up_to_a_square() {
        assert_eq!(TraceOptions::from_spp(0, 0).samples_per_side, 1);
        assert_eq!(TraceOptions::from_spp(1, 0).samples_per_side, 1);
        assert_eq!(TraceOptions::from_spp(1000, 0).samples(), 1024);
        assert_eq!(TraceOptions::from_spp(1024, 0).samples(), 1024);
        assert_eq!(TraceOptions::from_spp(1025, 0).samples_per_side, 33);
        assert_eq!(TraceOptions::from_spp(65536, 0).samples_per_side, 256);
        assert_eq!(
            TraceOptions::from_spp(u32::MAX, 0).samples_per_side,
            MAX_SAMPLES_PER_SIDE
        );
    }
}
