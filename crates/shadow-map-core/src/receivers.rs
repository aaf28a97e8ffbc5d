//! Receivers: the points whose visibility an estimator computes.
//!
//! Either the camera's G-buffer (one receiver per pixel, in image layout) or a user's own arrays of
//! points and normals. Estimators never care where they came from; those that exploit screen-space
//! coherence (pixel packets) use [`Receivers::layout`] when present and fall back to per-receiver
//! work when it is absent.
use crate::{bvh::SceneBvh, cancel::Cancel, scene::Scene, Error, Result};
use glam::Vec3;
use rayon::prelude::*;

/// Image layout of receivers that come from an image: receiver `j * width + i` is pixel (i, j).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ImageLayout {
    /// Columns.
    pub width: u32,
    /// Rows.
    pub height: u32,
}

/// A set of receivers. Inactive receivers (background pixels) keep their slot so the image layout
/// is preserved; every estimator writes NaN for them (the contract's background V).
///
/// The fields are private so the constructors' checks hold for every value: one normal, active
/// flag and view depth per position, a layout of exactly `len()` pixels, finite positions and
/// unit normals for active receivers.
#[derive(Debug, Clone, Default)]
pub struct Receivers {
    /// World positions.
    position: Vec<Vec3>,
    /// Unit geometric normals, on the side the receiver is seen from (the contract: light behind
    /// this tangent plane is blocked).
    normal: Vec<Vec3>,
    /// Whether each slot holds a receiver (a camera hit).
    active: Vec<bool>,
    /// View depth per receiver (distance along the camera's view axis; +inf for background),
    /// present for G-buffer receivers.
    view_depth: Option<Vec<f32>>,
    /// Image layout, when the receivers are pixels.
    layout: Option<ImageLayout>,
}

impl Receivers {
    /// Runs `f(position, normal)` for every active receiver in parallel into `v` (checked to hold
    /// one value a receiver): inactive receivers and those `f` leaves unmodelled (`None`, for
    /// the caller to settle) get NaN, results are clamped into [0, 1], and a non-finite result is
    /// written as 0 and counted (the count returned; non-zero is a bug the caller reports).
    /// Checks `cancel` between chunks of receivers ([`Cancel::par_sum`]).
    pub fn estimate_each(
        &self,
        cancel: &Cancel,
        v: &mut [f32],
        f: impl Fn(Vec3, Vec3) -> Option<f32> + Sync + Send,
    ) -> Result<usize> {
        self.check_output(v)?;
        cancel.par_sum(v, |k, out| {
            let x = match self.active[k] {
                true => f(self.position[k], self.normal[k]),
                false => None,
            };
            match x {
                None => *out = f32::NAN,
                Some(x) if x.is_finite() => *out = x.clamp(0.0, 1.0),
                Some(_) => {
                    *out = 0.0;
                    return 1;
                }
            }
            0
        })
    }

    /// Receivers from a user's own arrays (no image layout). Normals are normalised; every value
    /// must be finite and normals non-zero.
    pub fn from_points(position: Vec<Vec3>, normal: Vec<Vec3>) -> Result<Self> {
        if position.len() != normal.len() {
            return Err(Error::Receivers(format!(
                "{} positions but {} normals",
                position.len(),
                normal.len()
            )));
        }
        let mut n = normal;
        for (k, (p, nn)) in position.iter().zip(n.iter_mut()).enumerate() {
            if !p.is_finite() {
                return Err(Error::Receivers(format!("position {k} is not finite: {p}")));
            }
            *nn = nn
                .try_normalize()
                .ok_or_else(|| Error::Receivers(format!("normal {k} is zero or not finite")))?;
        }
        let len = position.len();
        Ok(Receivers {
            position,
            normal: n,
            active: vec![true; len],
            view_depth: None,
            layout: None,
        })
    }

    /// Receivers read from a G-buffer: one slot per pixel of `layout`, `active` marking the camera
    /// hits and `view_depth` (when given) one depth per slot. Every length must match; active
    /// slots need a finite position and a finite unit normal (kept bit for bit, as the twins
    /// compare them), inactive slots are kept as given; view depths must not be NaN.
    pub fn from_gbuffer(
        position: Vec<Vec3>,
        normal: Vec<Vec3>,
        active: Vec<bool>,
        view_depth: Option<Vec<f32>>,
        layout: Option<ImageLayout>,
    ) -> Result<Self> {
        let len = position.len();
        for (what, n) in [
            ("normals", normal.len()),
            ("active flags", active.len()),
            ("view depths", view_depth.as_ref().map_or(len, Vec::len)),
        ] {
            if n != len {
                return Err(Error::Receivers(format!("{len} positions but {n} {what}")));
            }
        }
        for (k, ((p, n), &a)) in position.iter().zip(&normal).zip(&active).enumerate() {
            if !a {
                continue;
            }
            if !p.is_finite() {
                return Err(Error::Receivers(format!("position {k} is not finite: {p}")));
            }
            if !(n.is_finite() && (n.length() - 1.0).abs() <= 1e-3) {
                return Err(Error::Receivers(format!(
                    "normal {k} is not a unit vector: {n}"
                )));
            }
        }
        if let Some(k) = view_depth
            .as_ref()
            .and_then(|z| z.iter().position(|z| z.is_nan()))
        {
            return Err(Error::Receivers(format!("view depth {k} is NaN")));
        }
        let r = Receivers {
            position,
            normal,
            active,
            view_depth,
            layout: None,
        };
        match layout {
            Some(l) => r.with_layout(l),
            None => Ok(r),
        }
    }

    /// Replaces the active mask (one flag per slot).
    pub fn with_active(mut self, active: Vec<bool>) -> Result<Self> {
        self.check_per_slot(active.len(), format_args!("{} active flags", active.len()))?;
        self.active = active;
        Ok(self)
    }

    /// Attaches view depths (one per slot, none NaN; +inf marks background).
    pub fn with_view_depth(mut self, view_depth: Vec<f32>) -> Result<Self> {
        self.check_per_slot(
            view_depth.len(),
            format_args!("{} view depths", view_depth.len()),
        )?;
        if let Some(k) = view_depth.iter().position(|z| z.is_nan()) {
            return Err(Error::Receivers(format!("view depth {k} is NaN")));
        }
        self.view_depth = Some(view_depth);
        Ok(self)
    }

    /// Attaches an image layout (`width * height` must equal the receiver count).
    pub fn with_layout(mut self, layout: ImageLayout) -> Result<Self> {
        if layout.width as usize * layout.height as usize != self.len() {
            return Err(Error::Receivers(format!(
                "layout {}x{} does not match {} receivers",
                layout.width,
                layout.height,
                self.len()
            )));
        }
        self.layout = Some(layout);
        Ok(self)
    }

    /// The camera's G-buffer: one ray per pixel exactly as the contract defines it, closest hit
    /// through the BVH; normals face the camera.
    pub fn from_camera(scene: &Scene, bvh: &SceneBvh) -> Self {
        let cam = scene.camera();
        let basis = cam.basis();
        let (w, h) = (cam.width, cam.height);
        let px: Vec<(Vec3, Vec3, bool, f32)> = (0..w * h)
            .into_par_iter()
            .map(|k| {
                let (i, j) = (k % w, k / w);
                let d = cam.ray_dir(&basis, i, j);
                match bvh.closest_hit(cam.eye, d, 0.0, f32::INFINITY) {
                    Some(hit) => {
                        let p = cam.eye + d * hit.t;
                        let mut n = bvh.normal(hit.triangle);
                        if n.dot(d) > 0.0 {
                            n = -n;
                        }
                        (p, n, true, hit.t * d.dot(basis.forward))
                    }
                    None => (Vec3::ZERO, Vec3::Z, false, f32::INFINITY),
                }
            })
            .collect();
        let mut r = Receivers {
            position: Vec::with_capacity(px.len()),
            normal: Vec::with_capacity(px.len()),
            active: Vec::with_capacity(px.len()),
            view_depth: Some(Vec::with_capacity(px.len())),
            layout: Some(ImageLayout {
                width: w,
                height: h,
            }),
        };
        for (p, n, a, z) in px {
            r.position.push(p);
            r.normal.push(n);
            r.active.push(a);
            if let Some(v) = r.view_depth.as_mut() {
                v.push(z);
            }
        }
        r
    }

    /// World positions.
    #[inline]
    pub fn position(&self) -> &[Vec3] {
        &self.position
    }
    /// Unit geometric normals, on the side the receiver is seen from (the contract: light behind
    /// this tangent plane is blocked).
    #[inline]
    pub fn normal(&self) -> &[Vec3] {
        &self.normal
    }
    /// Whether each slot holds a receiver (a camera hit).
    #[inline]
    pub fn active(&self) -> &[bool] {
        &self.active
    }
    /// The active mask, to switch receivers on or off (the slot count cannot change).
    #[inline]
    pub fn active_mut(&mut self) -> &mut [bool] {
        &mut self.active
    }
    /// View depth per receiver (distance along the camera's view axis; +inf for background),
    /// present for G-buffer receivers.
    #[inline]
    pub fn view_depth(&self) -> Option<&[f32]> {
        self.view_depth.as_deref()
    }
    /// Image layout, when the receivers are pixels.
    #[inline]
    pub fn layout(&self) -> Option<ImageLayout> {
        self.layout
    }

    /// Number of slots.
    #[inline]
    pub fn len(&self) -> usize {
        self.position.len()
    }
    /// No slots.
    #[inline]
    pub fn is_empty(&self) -> bool {
        self.position.is_empty()
    }
    /// Number of active receivers.
    pub fn active_count(&self) -> usize {
        self.active.iter().filter(|&&a| a).count()
    }
    /// Fails with [`Error::Receivers`] unless `v` has one output slot per receiver.
    pub fn check_output(&self, v: &[f32]) -> Result<()> {
        self.check_per_slot(v.len(), format_args!("output has {} slots", v.len()))
    }
    /// Fails with [`Error::Receivers`] ("`what` for `len` receivers") unless `n`, the length of
    /// what `what` describes, is one per slot.
    fn check_per_slot(&self, n: usize, what: std::fmt::Arguments<'_>) -> Result<()> {
        if n != self.len() {
            return Err(Error::Receivers(format!(
                "{what} for {} receivers",
                self.len()
            )));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every way to build or change receivers keeps one normal, flag and depth per slot, a
    /// layout of `len()` pixels and finite active geometry; what used to be settable field by
    /// field (and then indexed out of range by the estimators) is a typed error.
    #[test]
    fn checked_constructors_reject_inconsistent_receivers() {
        let p = vec![Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::Z];
        let n = vec![Vec3::Y * 2.0; 4];
        let bad = |r: Result<Receivers>| matches!(r, Err(Error::Receivers(_)));
        assert!(bad(Receivers::from_points(p.clone(), n[..3].to_vec())));
        assert!(bad(Receivers::from_points(vec![Vec3::NAN], vec![Vec3::Y])));
        let r = Receivers::from_points(p.clone(), n.clone()).unwrap();
        assert_eq!(r.normal()[0], Vec3::Y);
        assert!(bad(r.clone().with_active(vec![true; 3])));
        assert!(bad(r.clone().with_view_depth(vec![1.0; 5])));
        assert!(bad(r.clone().with_view_depth(vec![f32::NAN; 4])));
        let layout = |width, height| ImageLayout { width, height };
        assert!(bad(r.clone().with_layout(layout(3, 1))));
        let mut r = r
            .with_active(vec![true, false, true, true])
            .unwrap()
            .with_view_depth(vec![1.0, f32::INFINITY, 2.0, 3.0])
            .unwrap()
            .with_layout(layout(2, 2))
            .unwrap();
        assert_eq!(r.active_count(), 3);
        assert_eq!(r.view_depth().map(<[f32]>::len), Some(4));
        assert_eq!(r.layout(), Some(layout(2, 2)));
        r.active_mut()[0] = false;
        assert_eq!(r.active_count(), 2);
        // G-buffer parts: lengths, layout, active geometry, depths.
        let a = vec![true, false, true, true];
        let unit = vec![Vec3::Y; 4];
        let gb = |p: Vec<Vec3>, n: Vec<Vec3>, a: Vec<bool>, z: Option<Vec<f32>>, l| {
            Receivers::from_gbuffer(p, n, a, z, l)
        };
        assert!(gb(p.clone(), unit.clone(), a.clone(), None, Some(layout(2, 2))).is_ok());
        assert!(bad(gb(
            p.clone(),
            unit.clone(),
            a[..2].to_vec(),
            None,
            None
        )));
        assert!(bad(gb(
            p.clone(),
            unit.clone(),
            a.clone(),
            Some(vec![0.0]),
            None
        )));
        assert!(bad(gb(
            p.clone(),
            unit.clone(),
            a.clone(),
            None,
            Some(layout(4, 4))
        )));
        assert!(bad(gb(p.clone(), n, a.clone(), None, None)));
        let mut far = p.clone();
        far[0] = Vec3::INFINITY;
        assert!(bad(gb(far.clone(), unit.clone(), a.clone(), None, None)));
        // An inactive slot may hold anything.
        far.swap(0, 1);
        assert!(gb(far, unit, a, None, None).is_ok());
    }
}
