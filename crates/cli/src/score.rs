//! Scoring a candidate visibility image against a reference (ground truth).
//!
//! Both images follow the EXR contract: channel `V` (visible fraction of the
//! light, NaN on background) and channel `Z` (view-space depth, +inf on
//! background). A pixel is a *hit* in an image when its `Z` is finite.
//!
//! Per-pixel classification, shared by [`score`] and [`write_error_png`]:
//! - **matched**: both images hit and `|Zc - Zr| <= 0.01 * |Zr|` (the two
//!   renderers see the same surface within 1 % of the reference depth);
//! - **non-finite**: the candidate hits (finite `Zc`) but its `Vc` is NaN or
//!   infinite, whether or not the pixel is matched;
//! - **scored**: matched, with both `Vc` and `Vr` finite. Only scored pixels
//!   enter the error statistics (`e = Vc - Vr`).

use std::path::Path;

use crate::exr_io::{write_rgb_png, ImageError, VisibilityImage, CHANNEL_V, CHANNEL_Z};

/// Relative depth tolerance for two hits to count as the same surface point.
pub const DEPTH_TOLERANCE: f64 = 0.01;

/// Absolute error above which a pixel counts in [`Score::frac_abs_error_gt_0_1`].
pub const LARGE_ERROR: f64 = 0.1;

/// The comparison of a candidate image with a reference; see [`score`].
///
/// All floating-point fields are finite (0 when there is nothing to measure),
/// so the JSON from [`score_json`] never contains `null` or `NaN`.
#[derive(Debug, Clone, serde::Serialize, PartialEq)]
pub struct Score {
    /// Image width in pixels (same for both images).
    pub width: usize,
    /// Image height in pixels (same for both images).
    pub height: usize,
    /// `matched / (number of reference hit pixels)`, in [0, 1];
    /// 0 when the reference has no hit pixels.
    pub matched_fraction: f64,
    /// Number of matched pixels (depth criterion only, whatever their V).
    pub matched: usize,
    /// Root-mean-square of `e = Vc - Vr` over the scored pixels.
    pub rmse: f64,
    /// Mean of `|e|` over the scored pixels.
    pub mae: f64,
    /// 99th percentile of `|e|` over the scored pixels, nearest-rank
    /// definition: the `ceil(0.99 * n)`-th smallest value (1-based).
    pub p99_abs_error: f64,
    /// Fraction of the scored pixels with `|e| > 0.1`.
    pub frac_abs_error_gt_0_1: f64,
    /// Number of candidate hit pixels (finite `Zc`) whose `Vc` is NaN or
    /// infinite. These are excluded from every error statistic, so check
    /// this field: a candidate with non-finite output is broken even when its
    /// errors look small.
    pub nonfinite_v: usize,
    /// Scored pixels whose reference is fully lit (`Vr >= 1 - 1e-6`): where any darkening is
    /// false shadow (self-shadowing acne, a filter reaching the receiver's own surface).
    pub lit_pixels: usize,
    /// Mean of `|e|` over the [`lit_pixels`](Self::lit_pixels) (0 when there are none).
    pub lit_mae: f64,
}

/// Reference V at or above which a pixel counts as fully lit ([`Score::lit_pixels`]).
pub const FULLY_LIT: f64 = 1.0 - 1e-6;

/// The class of one pixel; see the module documentation.
#[derive(Debug, Clone, Copy, PartialEq)]
enum PixelClass {
    /// Neither image hits a surface.
    Background,
    /// The candidate hits but its V is not finite.
    NonFinite,
    /// Matched with finite V in both: the signed error `Vc - Vr`.
    Scored(f64),
    /// Everything else: only one image hits, the depths disagree by more than
    /// the tolerance, or the reference V is not finite on a matched pixel.
    Unmatched,
}

/// The `V` and `Z` channels of both images, checked for size and length.
struct Pair<'a> {
    vc: &'a [f32],
    zc: &'a [f32],
    vr: &'a [f32],
    zr: &'a [f32],
}

impl Pair<'_> {
    /// `(Vc, Zc, Vr, Zr)` for every pixel, row-major.
    fn pixels(&self) -> impl Iterator<Item = (f32, f32, f32, f32)> + '_ {
        self.vc
            .iter()
            .zip(self.zc)
            .zip(self.vr.iter().zip(self.zr))
            .map(|((&vc, &zc), (&vr, &zr))| (vc, zc, vr, zr))
    }
}

fn channel<'a>(
    img: &'a VisibilityImage,
    role: &'static str,
    name: &str,
) -> Result<&'a [f32], ImageError> {
    let data = img.channel(name).ok_or_else(|| ImageError::NoChannel {
        role,
        channel: name.to_string(),
    })?;
    if data.len() != img.pixel_count() {
        return Err(ImageError::ChannelLength {
            channel: name.to_string(),
            expected: img.pixel_count(),
            found: data.len(),
        });
    }
    Ok(data)
}

fn pair<'a>(
    candidate: &'a VisibilityImage,
    reference: &'a VisibilityImage,
) -> Result<Pair<'a>, ImageError> {
    if (candidate.width, candidate.height) != (reference.width, reference.height) {
        return Err(ImageError::SizeMismatch {
            candidate: (candidate.width, candidate.height),
            reference: (reference.width, reference.height),
        });
    }
    Ok(Pair {
        vc: channel(candidate, "candidate", CHANNEL_V)?,
        zc: channel(candidate, "candidate", CHANNEL_Z)?,
        vr: channel(reference, "reference", CHANNEL_V)?,
        zr: channel(reference, "reference", CHANNEL_Z)?,
    })
}

/// Whether two depths hit the same surface: both finite and within
/// [`DEPTH_TOLERANCE`] of the reference depth.
fn depths_match(zc: f32, zr: f32) -> bool {
    if !zc.is_finite() || !zr.is_finite() {
        return false;
    }
    let (zc, zr) = (f64::from(zc), f64::from(zr));
    (zc - zr).abs() <= DEPTH_TOLERANCE * zr.abs()
}

fn classify(vc: f32, zc: f32, vr: f32, zr: f32) -> PixelClass {
    if zc.is_finite() && !vc.is_finite() {
        PixelClass::NonFinite
    } else if !zc.is_finite() && !zr.is_finite() {
        PixelClass::Background
    } else if depths_match(zc, zr) && vr.is_finite() {
        PixelClass::Scored(f64::from(vc) - f64::from(vr))
    } else {
        PixelClass::Unmatched
    }
}

/// Compares `candidate` with `reference` (both need channels `V` and `Z`, of
/// the same size).
///
/// - `matched` counts the pixels where both images hit (finite `Z`) and
///   `|Zc - Zr| <= 0.01 * |Zr|`; `matched_fraction` divides it by the number
///   of pixels where the **reference** hits, so it measures how much of the
///   ground truth's visible geometry the candidate reproduces (candidate-only
///   hits do not raise it). It is 0 when the reference has no hits.
/// - The error statistics (`rmse`, `mae`, `p99_abs_error`,
///   `frac_abs_error_gt_0_1`) are over the matched pixels whose `Vc` and `Vr`
///   are both finite, with `e = Vc - Vr` computed in f64; all are 0 when there
///   is no such pixel. The percentile uses the nearest-rank definition.
/// - `nonfinite_v` counts the candidate's hit pixels (finite `Zc`) whose `Vc`
///   is not finite, matched or not; they never enter the error statistics.
///
/// Errors: [`ImageError::SizeMismatch`] when the sizes differ,
/// [`ImageError::NoChannel`] when `V` or `Z` is missing, and
/// [`ImageError::ChannelLength`] for a channel of the wrong length.
pub fn score(
    candidate: &VisibilityImage,
    reference: &VisibilityImage,
) -> Result<Score, ImageError> {
    let p = pair(candidate, reference)?;

    let mut reference_hits = 0usize;
    let mut matched = 0usize;
    let mut nonfinite_v = 0usize;
    let mut abs_errors: Vec<f64> = Vec::new();
    let mut sum_sq = 0.0f64;
    let mut sum_abs = 0.0f64;
    let mut large = 0usize;
    let (mut lit_pixels, mut lit_abs) = (0usize, 0.0f64);

    for (vc, zc, vr, zr) in p.pixels() {
        if zr.is_finite() {
            reference_hits += 1;
        }
        if depths_match(zc, zr) {
            matched += 1;
        }
        match classify(vc, zc, vr, zr) {
            PixelClass::NonFinite => nonfinite_v += 1,
            PixelClass::Scored(e) => {
                let a = e.abs();
                sum_sq += e * e;
                sum_abs += a;
                if a > LARGE_ERROR {
                    large += 1;
                }
                abs_errors.push(a);
                if f64::from(vr) >= FULLY_LIT {
                    lit_pixels += 1;
                    lit_abs += a;
                }
            }
            PixelClass::Background | PixelClass::Unmatched => {}
        }
    }

    let n = abs_errors.len();
    let (rmse, mae, p99, frac) = if n == 0 {
        (0.0, 0.0, 0.0, 0.0)
    } else {
        let nf = n as f64;
        abs_errors.sort_by(f64::total_cmp);
        // Nearest rank: k = ceil(99 n / 100), exact in integers, 1 <= k <= n.
        let k = (99 * n).div_ceil(100).clamp(1, n);
        (
            (sum_sq / nf).sqrt(),
            sum_abs / nf,
            abs_errors.get(k - 1).copied().unwrap_or(0.0),
            large as f64 / nf,
        )
    };
    let matched_fraction = if reference_hits == 0 {
        0.0
    } else {
        matched as f64 / reference_hits as f64
    };

    Ok(Score {
        width: reference.width,
        height: reference.height,
        matched_fraction: finite_or_zero(matched_fraction),
        matched,
        rmse: finite_or_zero(rmse),
        mae: finite_or_zero(mae),
        p99_abs_error: finite_or_zero(p99),
        frac_abs_error_gt_0_1: finite_or_zero(frac),
        nonfinite_v,
        lit_pixels,
        lit_mae: if lit_pixels == 0 {
            0.0
        } else {
            finite_or_zero(lit_abs / lit_pixels as f64)
        },
    })
}

/// Guards the "all reported floats are finite" promise (the inputs are finite
/// f32 differences, so this never triggers in practice).
fn finite_or_zero(x: f64) -> f64 {
    if x.is_finite() {
        x
    } else {
        0.0
    }
}

/// The score as one line of JSON (no trailing newline), with the fields in
/// declaration order, e.g.
/// `{"width":320,"height":240,"matched_fraction":1.0,"matched":51234,"rmse":0.01,...}`.
pub fn score_json(s: &Score) -> String {
    match serde_json::to_string(s) {
        Ok(json) => json,
        // Serializing a struct of integers and floats cannot fail.
        Err(e) => format!("{{\"error\":{:?}}}", e.to_string()),
    }
}

/// Colour of candidate hit pixels (finite `Zc`) whose `Vc` is not finite.
pub const ERROR_NONFINITE: [u8; 3] = [255, 0, 255];
/// Colour of pixels where exactly one image hits, or the depths disagree.
pub const ERROR_UNMATCHED: [u8; 3] = [128, 128, 128];
/// Colour of pixels that are background in both images.
pub const ERROR_BACKGROUND: [u8; 3] = [48, 48, 48];

/// The default of `score --err-range`: errors of +-0.1 and beyond get the map's end colours,
/// so the typical errors of 0.02 to 0.1 are visible (a map over +-1 left them white).
pub const DEFAULT_ERR_RANGE: f64 = 0.1;

/// The false colour of a signed error `e = Vc - Vr` under a diverging map over `[-range, range]`
/// (ColorBrewer's RdBu through `colorous`, built for perception: equal steps look alike on both
/// sides): blue for a candidate too dark, near-white at 0, red for too bright, clamped at the
/// range's ends.
fn error_colour(e: f64, range: f64) -> [u8; 3] {
    let x = (0.5 + 0.5 * e / range).clamp(0.0, 1.0);
    // RED_BLUE runs red (0) to blue (1): too bright (x near 1) must be red.
    let c = colorous::RED_BLUE.eval_continuous(1.0 - x);
    [c.r, c.g, c.b]
}

/// Writes a false-colour PNG of the per-pixel error of `candidate` against
/// `reference` (same size, both with `V` and `Z`), row 0 at the top:
///
/// - scored pixels (see the module documentation): the signed error
///   `Vc - Vr` on a perceptual diverging map over `[-range, range]`
///   ([`error_colour`]): blue (candidate too dark) through near-white (0) to red
///   (too bright), clamped;
/// - candidate hit pixels with non-finite `Vc`: magenta [`ERROR_NONFINITE`];
/// - other unmatched pixels (only one image hits, depths differ by more than
///   1 %, or the reference V is not finite): grey [`ERROR_UNMATCHED`];
/// - background in both images: dark grey [`ERROR_BACKGROUND`].
///
/// The write is atomic; errors as for [`score`], plus [`ImageError::Write`].
pub fn write_error_png(
    path: &Path,
    candidate: &VisibilityImage,
    reference: &VisibilityImage,
    range: f64,
) -> Result<(), ImageError> {
    if !(range.is_finite() && range > 0.0) {
        return Err(ImageError::Write {
            path: path.to_path_buf(),
            reason: format!("--err-range must be a finite number > 0, got {range}"),
        });
    }
    let p = pair(candidate, reference)?;
    let mut rgb = Vec::with_capacity(p.zr.len().saturating_mul(3));
    for (vc, zc, vr, zr) in p.pixels() {
        let colour = match classify(vc, zc, vr, zr) {
            PixelClass::Scored(e) => error_colour(e, range),
            PixelClass::NonFinite => ERROR_NONFINITE,
            PixelClass::Unmatched => ERROR_UNMATCHED,
            PixelClass::Background => ERROR_BACKGROUND,
        };
        rgb.extend_from_slice(&colour);
    }
    write_rgb_png(path, reference.width, reference.height, &rgb)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn image(w: usize, h: usize, v: Vec<f32>, z: Vec<f32>) -> VisibilityImage {
        let mut img = VisibilityImage::new(w, h);
        img.push_channel("V", v).unwrap();
        img.push_channel("Z", z).unwrap();
        img
    }

    fn assert_all_finite(s: &Score) {
        for x in [
            s.matched_fraction,
            s.rmse,
            s.mae,
            s.p99_abs_error,
            s.frac_abs_error_gt_0_1,
            s.lit_mae,
        ] {
            assert!(x.is_finite(), "{s:?}");
        }
    }

    #[test]
    fn identical_images_score_zero() {
        let n = 12;
        let mut v: Vec<f32> = (0..n).map(|i| i as f32 / 11.0).collect();
        let mut z: Vec<f32> = (0..n).map(|i| 2.0 + i as f32).collect();
        v[5] = f32::NAN;
        z[5] = f32::INFINITY; // one background pixel
        let img = image(4, 3, v, z);
        let s = score(&img, &img).unwrap();
        assert_eq!(
            s,
            Score {
                width: 4,
                height: 3,
                matched_fraction: 1.0,
                matched: 11,
                rmse: 0.0,
                mae: 0.0,
                p99_abs_error: 0.0,
                frac_abs_error_gt_0_1: 0.0,
                nonfinite_v: 0,
                lit_pixels: 1,
                lit_mae: 0.0,
            }
        );
    }

    #[test]
    fn lit_mae_counts_only_fully_lit_reference_pixels() {
        // Reference: two fully lit pixels, one in penumbra; the candidate darkens all three.
        let r = image(3, 1, vec![1.0, 1.0, 0.5], vec![1.0; 3]);
        let c = image(3, 1, vec![0.75, 0.5, 0.0], vec![1.0; 3]);
        let s = score(&c, &r).unwrap();
        assert_eq!(s.lit_pixels, 2);
        assert!((s.lit_mae - 0.375).abs() < 1e-12, "{s:?}");
        assert!((s.mae - (0.25 + 0.5 + 0.5) / 3.0).abs() < 1e-12, "{s:?}");
    }

    #[test]
    fn known_synthetic_case() {
        // 8 x 1: five scored pixels with exactly representable errors,
        // one reference hit the candidate misses, one background in both,
        // one candidate-only hit.
        let inf = f32::INFINITY;
        let nan = f32::NAN;
        let vr = vec![0.5, 0.5, 0.5, 0.5, 0.5, 0.5, nan, nan];
        let zr = vec![3.0, 3.0, 3.0, 3.0, 3.0, 3.0, inf, inf];
        let vc = vec![0.5, 0.75, 0.25, 0.5625, 1.0, nan, nan, 0.3];
        let zc = vec![3.0, 3.0, 3.0, 3.0, 3.0, inf, inf, 4.0];
        let s = score(&image(8, 1, vc, zc), &image(8, 1, vr, zr)).unwrap();
        // errors: 0, 0.25, -0.25, 0.0625, 0.5
        assert_eq!(s.matched, 5);
        assert_eq!(s.matched_fraction, 5.0 / 6.0);
        assert_eq!(s.mae, 1.0625 / 5.0);
        let mse = (0.0625 + 0.0625 + 0.00390625 + 0.25) / 5.0;
        assert!((s.rmse - f64::sqrt(mse)).abs() < 1e-15, "{}", s.rmse);
        assert!((s.rmse - 0.275_283_944_319_315_5).abs() < 1e-12);
        assert_eq!(s.p99_abs_error, 0.5); // ceil(0.99 * 5) = 5th smallest
        assert_eq!(s.frac_abs_error_gt_0_1, 0.6);
        assert_eq!(s.nonfinite_v, 0);
    }

    #[test]
    fn p99_is_nearest_rank() {
        // 200 scored pixels with |e| = i / 256: nearest rank k = 198.
        let n = 200;
        let vr = vec![0.0f32; n];
        let vc: Vec<f32> = (0..n).rev().map(|i| i as f32 / 256.0).collect();
        let z = vec![1.0f32; n];
        let s = score(&image(n, 1, vc, z.clone()), &image(n, 1, vr, z)).unwrap();
        assert_eq!(s.p99_abs_error, 197.0 / 256.0);
        // |e| > 0.1 <=> i / 256 > 0.1 <=> i >= 26: 174 of 200.
        assert_eq!(s.frac_abs_error_gt_0_1, 174.0 / 200.0);
    }

    #[test]
    fn depth_mismatch_beyond_one_percent_is_excluded() {
        let vr = vec![0.5f32; 4];
        let zr = vec![10.0f32; 4];
        let vc = vec![0.5, 0.5625, 1.0, 0.0];
        // 0 %, 0.5 % (matched), 2 % and -5 % (unmatched)
        let zc = vec![10.0, 10.05, 10.2, 9.5];
        let s = score(&image(2, 2, vc, zc), &image(2, 2, vr, zr)).unwrap();
        assert_eq!(s.matched, 2);
        assert_eq!(s.matched_fraction, 0.5);
        // errors over the matched pixels: 0 and 0.0625
        assert_eq!(s.mae, 0.03125);
        assert_eq!(s.rmse, (0.00390625f64 / 2.0).sqrt());
        assert_eq!(s.p99_abs_error, 0.0625);
        assert_eq!(s.frac_abs_error_gt_0_1, 0.0);
    }

    #[test]
    fn nonfinite_candidate_v_is_counted_not_scored() {
        let vr = vec![0.5f32; 4];
        let zr = vec![2.0f32; 4];
        let vc = vec![f32::NAN, 0.75, f32::INFINITY, 0.5];
        let zc = vec![2.0, 2.0, 50.0, 2.0]; // the inf-V pixel is also unmatched
        let s = score(&image(4, 1, vc, zc), &image(4, 1, vr, zr)).unwrap();
        assert_eq!(s.nonfinite_v, 2);
        assert_eq!(s.matched, 3); // depth criterion only
        assert_eq!(s.mae, 0.125); // over the two finite matched pixels
        assert_eq!(s.rmse, (0.0625f64 / 2.0).sqrt());
        assert_all_finite(&s);
        let json = score_json(&s);
        assert!(!json.contains("null") && !json.contains("NaN"), "{json}");
    }

    #[test]
    fn all_nonfinite_or_no_hits_reports_zeros() {
        let inf = f32::INFINITY;
        let nan = f32::NAN;
        // Candidate entirely NaN where the reference hits.
        let r = image(2, 1, vec![0.5, 0.5], vec![1.0, 1.0]);
        let c = image(2, 1, vec![nan, nan], vec![1.0, 1.0]);
        let s = score(&c, &r).unwrap();
        assert_eq!(s.nonfinite_v, 2);
        assert_eq!(
            (s.rmse, s.mae, s.p99_abs_error, s.frac_abs_error_gt_0_1),
            (0.0, 0.0, 0.0, 0.0)
        );
        assert_all_finite(&s);

        // Reference with no hits at all.
        let r = image(2, 1, vec![nan, nan], vec![inf, inf]);
        let c = image(2, 1, vec![0.5, 0.5], vec![1.0, 1.0]);
        let s = score(&c, &r).unwrap();
        assert_eq!(s.matched, 0);
        assert_eq!(s.matched_fraction, 0.0);
        assert_all_finite(&s);
    }

    #[test]
    fn size_mismatch_and_missing_channels_are_errors() {
        let a = image(2, 2, vec![0.0; 4], vec![1.0; 4]);
        let b = image(4, 1, vec![0.0; 4], vec![1.0; 4]);
        let err = score(&a, &b).unwrap_err();
        assert!(matches!(
            err,
            ImageError::SizeMismatch {
                candidate: (2, 2),
                reference: (4, 1)
            }
        ));
        assert!(err.to_string().contains("2x2") && err.to_string().contains("4x1"));

        let mut no_z = VisibilityImage::new(2, 2);
        no_z.push_channel("V", vec![0.0; 4]).unwrap();
        let err = score(&no_z, &a).unwrap_err();
        assert!(
            matches!(
                err,
                ImageError::NoChannel {
                    role: "candidate",
                    ..
                }
            ),
            "{err}"
        );

        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("err.png");
        assert!(write_error_png(&path, &a, &b, DEFAULT_ERR_RANGE).is_err());
        assert!(!path.exists());
    }

    #[test]
    fn json_is_one_line_with_all_fields() {
        let img = image(1, 1, vec![0.25], vec![1.0]);
        let json = score_json(&score(&img, &img).unwrap());
        assert!(!json.contains('\n'));
        let v: serde_json::Value = serde_json::from_str(&json).unwrap();
        for key in [
            "width",
            "height",
            "matched_fraction",
            "matched",
            "rmse",
            "mae",
            "p99_abs_error",
            "frac_abs_error_gt_0_1",
            "nonfinite_v",
        ] {
            assert!(v.get(key).is_some(), "missing {key} in {json}");
        }
        assert_eq!(v["matched_fraction"], 1.0);
    }

    #[test]
    fn error_png_colours() {
        let inf = f32::INFINITY;
        let nan = f32::NAN;
        // pixels: exact, -1, +1, +0.5, nonfinite, unmatched, background
        let vr = vec![0.5, 1.0, 0.0, 0.25, 0.5, 0.5, nan];
        let zr = vec![1.0, 1.0, 1.0, 1.0, 1.0, 1.0, inf];
        let vc = vec![0.5, 0.0, 1.0, 0.75, nan, 0.5, nan];
        let zc = vec![1.0, 1.0, 1.0, 1.0, 1.0, inf, inf];
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("err.png");
        write_error_png(
            &path,
            &image(7, 1, vc.clone(), zc.clone()),
            &image(7, 1, vr.clone(), zr.clone()),
            1.0,
        )
        .unwrap();
        let png = image::open(&path).unwrap().to_rgb8();
        let px = |x| png.get_pixel(x, 0).0;
        // RdBu: its middle near-white, its ends dark red and dark blue (range 1 here).
        let (red, blue) = (
            colorous::RED_BLUE.eval_continuous(0.0),
            colorous::RED_BLUE.eval_continuous(1.0),
        );
        let mid = colorous::RED_BLUE.eval_continuous(0.5);
        assert_eq!(px(0), [mid.r, mid.g, mid.b]);
        assert!(mid.r > 230 && mid.g > 230 && mid.b > 230, "{mid:?}");
        assert_eq!(px(1), [blue.r, blue.g, blue.b]);
        assert_eq!(px(2), [red.r, red.g, red.b]);
        // +0.5: half way to red, redder than it is blue.
        assert!(px(3)[0] > px(3)[2], "{:?}", px(3));
        assert_eq!(px(4), ERROR_NONFINITE);
        assert_eq!(px(5), ERROR_UNMATCHED);
        assert_eq!(px(6), ERROR_BACKGROUND);
        let names: Vec<_> = std::fs::read_dir(dir.path()).unwrap().collect();
        assert_eq!(names.len(), 1);
        // The default range, 0.1: an error of 0.05 is half way to the end colour, far from white
        // (over +-1 it was 97% white); +0.5 and -1 are clamped to the ends.
        let vc2 = vec![0.55, 0.0, 1.0, 0.75, nan, 0.5, nan];
        write_error_png(
            &path,
            &image(7, 1, vc2, zc),
            &image(7, 1, vr, zr),
            DEFAULT_ERR_RANGE,
        )
        .unwrap();
        let png = image::open(&path).unwrap().to_rgb8();
        let px = |x| png.get_pixel(x, 0).0;
        let q = colorous::RED_BLUE.eval_continuous(0.25);
        assert_eq!(px(0), [q.r, q.g, q.b]);
        assert!(px(0)[2] < 200, "{:?}", px(0));
        assert_eq!(px(1), [blue.r, blue.g, blue.b]);
        assert_eq!(px(3), [red.r, red.g, red.b]);
        assert!(write_error_png(
            &path,
            &image(1, 1, vec![0.5], vec![1.0]),
            &image(1, 1, vec![0.5], vec![1.0]),
            0.0
        )
        .is_err());
    }
}
