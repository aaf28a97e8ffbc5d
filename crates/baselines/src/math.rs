//! The baselines' pure functions, shared by the CPU twins and the frames: PCF's block size,
//! multi-sample's stratum jitter and average, and PCSS's widths (blocker search, penumbra and
//! filter), which live in the core because deep-shadow's `filter=pcss` sizes its kernel the same
//! way. The formulas are those of docs/methods.md; each function cites its section.
use glam::Vec2;

pub use shadow_map_core::soft_transmittance::{
    cells, disk_edge, filter_width, is_disk, search_width,
};

/// PCF's block half width for the filter size N (Reeves, Salesin & Cook 1987; docs/methods.md
/// §5): `(N - 1) / 2` after rounding even N up to N + 1, so the block of texels
/// `|di|, |dj| <= half` is `2 half + 1` texels per side, centred on the receiver's texel.
pub fn pcf_half(kernel: i32) -> i32 {
    kernel / 2
}

/// The jitter of stratum `k` under `seed`, in [0, 1)^2: multi-sample's jittered stratified
/// points on the light (Heckbert & Herf 1997; docs/methods.md §6), drawn by splitmix64 so a
/// seed gives the same points on every platform and in both twins.
pub fn jitter(seed: u64, k: u32) -> Vec2 {
    let mut x = seed ^ ((k as u64 + 1).wrapping_mul(0x9E37_79B9_7F4A_7C15));
    let mut next = || {
        x = x.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = x;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^= z >> 31;
        (z >> 40) as f32 / (1u64 << 24) as f32
    };
    Vec2::new(next(), next())
}

/// `1 / N`, the weight of each of the N sub-light samples in multi-sample's average
/// `V = (1/N) sum_k V_k` (docs/methods.md §6); a light with no sample weighs its (empty) sum
/// by 1.
pub fn inv_samples(n: usize) -> f32 {
    1.0 / n.max(1) as f32
}

#[cfg(test)]
mod tests {
    use super::cells;

    /// Windows of absurd or infinite width give finite cells, never an overflow (the CLI fuzz
    /// found `attempt to subtract with overflow` here under a light 1e30 wide).
    #[test]
    fn cells_of_infinite_windows_are_finite() {
        for (a, b) in [
            (f32::NEG_INFINITY, f32::INFINITY),
            (-1e30, 1e30),
            (f32::NEG_INFINITY, 3.0),
            (2.0, f32::INFINITY),
        ] {
            let mut n = 0;
            let mut total = 0.0f64;
            cells(a, b, 8, |_, w| {
                n += 1;
                assert!(w.is_finite() && w > 0.0, "{a} {b}: weight {w}");
                total += w as f64;
            });
            assert_eq!(n, 8, "{a} {b}");
            assert!(total.is_finite());
        }
        let mut seen = Vec::new();
        cells(0.25, 2.5, 8, |i, w| seen.push((i, w)));
        assert_eq!(seen, vec![(0, 0.75), (1, 1.0), (2, 0.5)]);
    }
}
