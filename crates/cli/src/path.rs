//! Camera paths (`render --frames N --orbit DEG` or `--pan X,Y,Z`) and the flicker measure: how
//! much V changes from frame to frame at the same world points while the scene stands still
//! (common techniques, "Moving the light in texel-sized increments": shimmering edges).
//!
//! **Path.** Frame k of N (k = 0 is the scene's camera): `orbit` turns the eye about the vertical
//! axis through the target by `DEG * k / (N - 1)` degrees; `pan` moves eye and target together by
//! `(X, Y, Z) * k / (N - 1)`.
//!
//! **Flicker.** For consecutive frames a, b: every active pixel of b (world point P_b) is projected
//! through a's camera (the contract's pinhole) to its nearest pixel; the pair counts when that
//! pixel is active in a and its world point P_a lies within one pixel footprint of P_b (a
//! disocclusion or a silhouette fails the test). Its sample is |V_b - V_a|. Reported: the mean and
//! the 99th percentile over all pairs of all transitions, and the number of pairs. Nearest-pixel
//! matching pairs points up to half a pixel apart, so a perfectly stable estimator still shows
//! the image's spatial gradient; compare fit modes on the same path, not against zero.
use glam::Vec3;
use shadow_map_core::Camera;

/// A camera path.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum CameraPath {
    /// Orbit about the vertical axis through the target, this many degrees over the path.
    Orbit(f32),
    /// Translate eye and target by this vector over the path.
    Pan(Vec3),
}

impl CameraPath {
    /// Parses `--pan X,Y,Z`.
    pub fn parse_pan(s: &str) -> Result<Vec3, String> {
        let v: Vec<f32> = s
            .split(',')
            .map(|c| c.trim().parse::<f32>())
            .collect::<Result<_, _>>()
            .map_err(|_| format!("--pan {s:?}: expected X,Y,Z (three numbers)"))?;
        match v[..] {
            [x, y, z] if x.is_finite() && y.is_finite() && z.is_finite() => Ok(Vec3::new(x, y, z)),
            _ => Err(format!(
                "--pan {s:?}: expected X,Y,Z (three finite numbers)"
            )),
        }
    }

    /// The camera of frame `k` of `n`.
    pub fn camera(&self, base: &Camera, k: usize, n: usize) -> Camera {
        let f = if n > 1 {
            k as f32 / (n - 1) as f32
        } else {
            0.0
        };
        let mut c = *base;
        match *self {
            CameraPath::Orbit(deg) => {
                let rot = glam::Quat::from_rotation_y((deg * f).to_radians());
                c.eye = base.target + rot * (base.eye - base.target);
            }
            CameraPath::Pan(d) => {
                c.eye = base.eye + d * f;
                c.target = base.target + d * f;
            }
        }
        c
    }
}

/// What one frame leaves for the flicker measure.
#[derive(Debug, Clone)]
pub struct Frame {
    /// Its camera.
    pub camera: Camera,
    /// World point per pixel.
    pub position: Vec<Vec3>,
    /// Camera hit per pixel.
    pub active: Vec<bool>,
    /// V per pixel.
    pub v: Vec<f32>,
}

/// Nearest pixel of `c` through which `p` is seen, with the pixel footprint at p's depth.
fn project(c: &Camera, p: Vec3) -> Option<(usize, f32)> {
    let b = c.basis();
    let d = p - c.eye;
    let z = d.dot(b.forward);
    if z.is_nan() || z <= 0.0 {
        return None;
    }
    let t = (c.fov_y_deg.to_radians() * 0.5).tan();
    let aspect = c.width as f32 / c.height as f32;
    let ndc_x = d.dot(b.right) / (z * t * aspect);
    let ndc_y = d.dot(b.true_up) / (z * t);
    let i = ((ndc_x + 1.0) * 0.5 * c.width as f32 - 0.5).round();
    let j = ((1.0 - ndc_y) * 0.5 * c.height as f32 - 0.5).round();
    if !(i >= 0.0 && j >= 0.0 && i < c.width as f32 && j < c.height as f32) {
        return None;
    }
    let footprint = 2.0 * z * t / c.height as f32;
    Some((j as usize * c.width as usize + i as usize, footprint))
}

/// |dV| samples of the transition a -> b.
pub fn flicker_samples(a: &Frame, b: &Frame) -> Vec<f32> {
    let mut out = Vec::new();
    for k in 0..b.v.len() {
        if !b.active[k] {
            continue;
        }
        let p = b.position[k];
        let Some((ka, footprint)) = project(&a.camera, p) else {
            continue;
        };
        if !a.active[ka] || a.position[ka].distance(p) > footprint {
            continue;
        }
        let d = (b.v[k] - a.v[ka]).abs();
        if d.is_finite() {
            out.push(d);
        }
    }
    out
}

/// The flicker of a sequence of frames: [`flicker_samples`] of each consecutive pair.
#[derive(Debug, Default)]
pub struct Flicker {
    prev: Option<Frame>,
    samples: Vec<f32>,
}

impl Flicker {
    /// Adds the next frame of the sequence.
    pub fn push(&mut self, frame: Frame) {
        if let Some(a) = &self.prev {
            self.samples.extend(flicker_samples(a, &frame));
        }
        self.prev = Some(frame);
    }

    /// (mean, p99, pairs) over every transition so far ([`summarize`]).
    pub fn summary(self) -> (f64, f64, usize) {
        summarize(self.samples)
    }
}

/// (mean, p99, pairs) over samples.
pub fn summarize(mut s: Vec<f32>) -> (f64, f64, usize) {
    if s.is_empty() {
        return (f64::NAN, f64::NAN, 0);
    }
    s.sort_by(f32::total_cmp);
    let mean = s.iter().map(|x| *x as f64).sum::<f64>() / s.len() as f64;
    let p99 = s[((s.len() - 1) as f64 * 0.99).round() as usize] as f64;
    (mean, p99, s.len())
}

/// Numbered output path: `out.exr` -> `out.0003.exr`.
pub fn numbered(path: &std::path::Path, k: usize) -> std::path::PathBuf {
    let stem = path
        .file_stem()
        .map(|s| s.to_string_lossy().to_string())
        .unwrap_or_default();
    let ext = path
        .extension()
        .map(|e| format!(".{}", e.to_string_lossy()))
        .unwrap_or_default();
    path.with_file_name(format!("{stem}.{k:04}{ext}"))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cam() -> Camera {
        Camera {
            eye: Vec3::new(0.0, 2.0, 4.0),
            target: Vec3::ZERO,
            up: Vec3::Y,
            fov_y_deg: 40.0,
            width: 64,
            height: 48,
        }
    }

    #[test]
    fn projection_inverts_the_pixel_ray() {
        let c = cam();
        let b = c.basis();
        for (i, j) in [(0u32, 0u32), (63, 47), (10, 30), (32, 24)] {
            let p = c.eye + c.ray_dir(&b, i, j) * 3.7;
            let (k, f) = project(&c, p).unwrap();
            assert_eq!(k, (j * 64 + i) as usize);
            assert!(f > 0.0);
        }
        assert!(project(&c, c.eye - b.forward).is_none());
    }

    #[test]
    fn paths_start_at_the_scene_camera_and_end_at_the_full_move() {
        let c = cam();
        let o = CameraPath::Orbit(90.0);
        assert_eq!(o.camera(&c, 0, 5).eye, c.eye);
        let e = o.camera(&c, 4, 5).eye;
        assert!((e - Vec3::new(4.0, 2.0, 0.0)).length() < 1e-5, "{e}");
        let p = CameraPath::Pan(Vec3::new(1.0, 0.0, 0.0));
        assert_eq!(p.camera(&c, 2, 3).target, Vec3::X);
        assert!(CameraPath::parse_pan("1,2").is_err());
        assert!(CameraPath::parse_pan("1,nan,2").is_err());
        assert_eq!(
            CameraPath::parse_pan("1, 2,3").unwrap(),
            Vec3::new(1.0, 2.0, 3.0)
        );
    }

    #[test]
    fn flicker_of_identical_frames_is_zero_and_of_changed_v_is_seen() {
        let c = cam();
        let b = c.basis();
        let position: Vec<Vec3> = (0..48u32)
            .flat_map(|j| (0..64u32).map(move |i| (i, j)))
            .map(|(i, j)| {
                let d = c.ray_dir(&b, i, j);
                c.eye + d * (c.eye.y / -d.y).abs()
            })
            .collect();
        let a = Frame {
            camera: c,
            position: position.clone(),
            active: vec![true; position.len()],
            v: vec![0.5; position.len()],
        };
        let (m, p, n) = summarize(flicker_samples(&a, &a));
        assert_eq!((m, p), (0.0, 0.0));
        assert_eq!(n, position.len());
        let mut b2 = a.clone();
        b2.v[100] = 1.0;
        let (m, p, _) = summarize(flicker_samples(&a, &b2));
        assert!(m > 0.0 && p == 0.0);
    }
}
