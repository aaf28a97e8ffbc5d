//! Occlusion bit masks on a light (Schwarz & Stamminger 2007, "Bitmask soft shadows";
//! docs/methods.md §2 "Bitmask occlusion" and §4): a B x B grid of light samples (bits), each set
//! once by whichever occluder covers it, so overlapping occluders count once. Shared by the
//! occlusion-bit variants of `accumulation` (`variant=exact`) and `backprojection`
//! (`occlusion=bitmask`); the WGSL twin is [`crate::gpu::estimate::BITMASK_WGSL`].
//!
//! Bit `k = j B + i` (`0 <= i, j < B`) sits at the centre `u = ((i + 1/2)/B, (j + 1/2)/B)` of
//! its cell of the unit square, mapped onto the light: `(2u - 1) h` on a rect of half extents
//! h, `concentric_disk(u) r` on a disk of radius r (equal-area bits, all inside the disk).
use crate::light::concentric_disk;
use glam::Vec2;

/// Largest bit-grid side (16 x 16 = 256 bits).
pub const MAX_BITS: u32 = 16;
/// u32 words of a mask of [`MAX_BITS`]^2 bits.
pub const MASK_WORDS: usize = (MAX_BITS * MAX_BITS / 32) as usize;

/// Centre of bit `(i, j)` of a `b x b` grid on the unit square.
#[inline]
pub fn bit_unit(i: u32, j: u32, b: u32) -> Vec2 {
    Vec2::new((i as f32 + 0.5) / b as f32, (j as f32 + 0.5) / b as f32)
}

/// Bit `(i, j)` on the rect `[-h.x, h.x] x [-h.y, h.y]`.
#[inline]
pub fn rect_bit(h: Vec2, i: u32, j: u32, b: u32) -> Vec2 {
    (bit_unit(i, j, b) * 2.0 - 1.0) * h
}

/// Bit `(i, j)` on the disk of radius `r` at the origin (equal-area, Shirley's concentric map).
#[inline]
pub fn disk_bit(r: f32, i: u32, j: u32, b: u32) -> Vec2 {
    concentric_disk(bit_unit(i, j, b)) * r
}

/// All `b^2` bits of a rect (`disk = None`) or of a disk of radius `disk`, in bit order.
pub fn bit_points(h: Vec2, disk: Option<f32>, b: u32) -> Vec<Vec2> {
    (0..b * b)
        .map(|k| {
            let (i, j) = (k % b, k / b);
            match disk {
                Some(r) => disk_bit(r, i, j, b),
                None => rect_bit(h, i, j, b),
            }
        })
        .collect()
}

/// True when `b` lies in the axis-aligned rectangle `[lo, hi]` (boundary included).
#[inline]
pub fn rect_contains(lo: Vec2, hi: Vec2, b: Vec2) -> bool {
    b.x >= lo.x && b.x <= hi.x && b.y >= lo.y && b.y <= hi.y
}

/// True when `b` lies in the convex quadrilateral `q` (either orientation, boundary included).
/// For an axis-aligned rectangle `flat` takes its bounds from the diagonal `q[0]`, `q[2]`.
#[inline]
pub fn quad_contains(q: &[Vec2; 4], flat: bool, b: Vec2) -> bool {
    if flat {
        return rect_contains(q[0].min(q[2]), q[0].max(q[2]), b);
    }
    let mut pos = true;
    let mut neg = true;
    for k in 0..4 {
        let e = q[(k + 1) % 4] - q[k];
        let c = e.perp_dot(b - q[k]);
        pos &= c >= 0.0;
        neg &= c <= 0.0;
    }
    pos || neg
}

/// A mask of up to [`MAX_BITS`]^2 bits and how many are set.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct BitMask {
    words: [u32; MASK_WORDS],
    set: u32,
}

impl BitMask {
    /// No bit set.
    pub fn new() -> Self {
        Self::default()
    }
    /// Bits set.
    #[inline]
    pub fn count(&self) -> u32 {
        self.set
    }
    /// Whether bit `k` is set.
    #[inline]
    pub fn is_set(&self, k: usize) -> bool {
        self.words[k / 32] & (1u32 << (k % 32)) != 0
    }
    /// Sets bit `k` (counted once).
    #[inline]
    pub fn set(&mut self, k: usize) {
        let (w, m) = (k / 32, 1u32 << (k % 32));
        if self.words[w] & m == 0 {
            self.words[w] |= m;
            self.set += 1;
        }
    }
    /// Sets every bit `k` whose point `pts[k]` lies in `[lo, hi]` ([`rect_contains`]); returns
    /// the count after.
    #[inline]
    pub fn set_in_rect(&mut self, pts: &[Vec2], lo: Vec2, hi: Vec2) -> u32 {
        for (k, b) in pts.iter().enumerate() {
            if !self.is_set(k) && rect_contains(lo, hi, *b) {
                self.set(k);
            }
        }
        self.set
    }
    /// [`BitMask::set_in_rect`] for points on a grid, bit `k = j B + i` at `(xs[i], ys[j])`
    /// (`B = xs.len()`; [`rect_bit`]'s points, whose x depends on i only and y on j only): the
    /// same bits, found from the columns and rows in range (`2B` tests, then one per bit set).
    #[inline]
    pub fn set_in_grid(&mut self, xs: &[f32], ys: &[f32], lo: Vec2, hi: Vec2) -> u32 {
        let b = xs.len();
        // Columns in range, one bit each (B <= MAX_BITS = 16).
        let mut cols = 0u32;
        for (i, &x) in xs.iter().enumerate() {
            if x >= lo.x && x <= hi.x {
                cols |= 1 << i;
            }
        }
        if cols == 0 {
            return self.set;
        }
        for (j, &y) in ys.iter().enumerate() {
            if !(y >= lo.y && y <= hi.y) {
                continue;
            }
            let mut c = cols;
            while c != 0 {
                self.set(j * b + c.trailing_zeros() as usize);
                c &= c - 1;
            }
        }
        self.set
    }
    /// Sets every bit `k` whose point `pts[k]` lies in the quad `q` ([`quad_contains`]); returns
    /// the count after.
    #[inline]
    pub fn set_in_quad(&mut self, pts: &[Vec2], q: &[Vec2; 4], flat: bool) -> u32 {
        for (k, b) in pts.iter().enumerate() {
            if !self.is_set(k) && quad_contains(q, flat, *b) {
                self.set(k);
            }
        }
        self.set
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn overlapping_rects_count_once() {
        let pts = bit_points(Vec2::splat(1.0), None, 8);
        let mut m = BitMask::new();
        // Left half, then a rect overlapping it: 32 bits, then 16 more (not 32).
        assert_eq!(
            m.set_in_rect(&pts, Vec2::new(-2.0, -2.0), Vec2::new(0.0, 2.0)),
            32
        );
        assert_eq!(
            m.set_in_rect(&pts, Vec2::new(-0.5, -2.0), Vec2::new(0.5, 2.0)),
            48
        );
        let q = [
            Vec2::new(-2.0, -2.0),
            Vec2::new(2.0, -2.0),
            Vec2::new(2.0, 2.0),
            Vec2::new(-2.0, 2.0),
        ];
        assert_eq!(m.set_in_quad(&pts, &q, false), 64);
        assert_eq!(m.set_in_quad(&pts, &q, true), 64);
    }

    #[test]
    fn grid_test_sets_the_same_bits() {
        let h = Vec2::new(0.7, 0.3);
        for b in [2u32, 5, 8, 16] {
            let pts = bit_points(h, None, b);
            let xs: Vec<f32> = (0..b).map(|i| rect_bit(h, i, 0, b).x).collect();
            let ys: Vec<f32> = (0..b).map(|j| rect_bit(h, 0, j, b).y).collect();
            let mut m1 = BitMask::new();
            let mut m2 = BitMask::new();
            for k in 0..200 {
                let t = k as f32 * 0.37;
                let lo = Vec2::new((t.sin() - 0.4) * 0.8, (t * 1.3).cos() * 0.4 - 0.1);
                let hi = lo + Vec2::new(t.cos().abs() * 0.6, (t * 0.7).sin().abs() * 0.4);
                let hi = if k % 7 == 0 { pts[k % pts.len()] } else { hi };
                assert_eq!(
                    m1.set_in_rect(&pts, lo, hi),
                    m2.set_in_grid(&xs, &ys, lo, hi)
                );
                assert_eq!(m1, m2);
            }
        }
    }

    #[test]
    fn disk_bits_are_inside_and_balanced() {
        let pts = bit_points(Vec2::ZERO, Some(2.0), 16);
        assert_eq!(pts.len(), 256);
        assert!(pts.iter().all(|p| p.length() < 2.0));
        // Equal-area: each half-plane holds half of the bits.
        assert_eq!(pts.iter().filter(|p| p.x > 0.0).count(), 128);
    }
}
