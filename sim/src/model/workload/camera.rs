//! The pinhole camera of the path tracer: one jittered primary ray per pixel sample,
//! LumiBench style (`(x + rnd, y + rnd) / size`), y up, row 0 at the top of the image.

use glam::Vec3;

use crate::model::geometry::Ray;
use crate::model::scene::Camera;
use crate::model::workload::rng::Rng;

/// A camera could not be used: its vectors do not define an orthonormal frame.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum CameraError {
    /// A camera vector or the field of view is NaN or infinite.
    #[error("camera has a non-finite eye, look_at, up or fov_y")]
    NonFinite,
    /// `eye == look_at`, or `up` is parallel to the view direction.
    #[error(
        "camera frame is degenerate (eye equals look_at, or up is parallel to the view direction)"
    )]
    Degenerate,
    /// The field of view is not in `(0, 180)` degrees.
    #[error("camera fov_y {0} degrees is not in (0, 180)")]
    Fov(f32),
}

/// A camera's orthonormal frame and image-plane extent, precomputed for one image size.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CameraFrame {
    eye: Vec3,
    /// Unit vector from the eye towards the look-at point.
    forward: Vec3,
    /// Image-plane right, scaled by half the plane width at distance 1.
    right: Vec3,
    /// Image-plane up, scaled by half the plane height at distance 1.
    up: Vec3,
    width: f32,
    height: f32,
}

impl CameraFrame {
    /// The frame of `camera` for a `width` x `height` image (aspect = width / height).
    /// Checks that the camera is usable.
    pub fn new(camera: &Camera, width: u32, height: u32) -> Result<CameraFrame, CameraError> {
        let finite = camera.eye.is_finite()
            && camera.look_at.is_finite()
            && camera.up.is_finite()
            && camera.fov_y_deg.is_finite();
        if !finite {
            return Err(CameraError::NonFinite);
        }
        if !(camera.fov_y_deg > 0.0 && camera.fov_y_deg < 180.0) {
            return Err(CameraError::Fov(camera.fov_y_deg));
        }
        let forward = (camera.look_at - camera.eye).normalize_or_zero();
        let right = forward.cross(camera.up).normalize_or_zero();
        if forward == Vec3::ZERO || right == Vec3::ZERO {
            return Err(CameraError::Degenerate);
        }
        let up = right.cross(forward);
        let half_h = (camera.fov_y_deg.to_radians() * 0.5).tan();
        let half_w = half_h * width as f32 / height as f32;
        Ok(CameraFrame {
            eye: camera.eye,
            forward,
            right: right * half_w,
            up: up * half_h,
            width: width as f32,
            height: height as f32,
        })
    }

    /// The primary ray through pixel `(x, y)` (row 0 at the top), jittered inside the pixel by
    /// two draws from `rng` (x first, then y). The direction is unit length.
    pub fn ray(&self, x: u32, y: u32, rng: &mut Rng) -> Ray {
        let jx = rng.next_f32();
        let jy = rng.next_f32();
        let u = (x as f32 + jx) / self.width * 2.0 - 1.0;
        let v = 1.0 - (y as f32 + jy) / self.height * 2.0;
        let dir = (self.forward + u * self.right + v * self.up).normalize();
        Ray::new(self.eye, dir)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn camera() -> Camera {
        Camera {
            eye: Vec3::ZERO,
            look_at: Vec3::new(0.0, 0.0, -1.0),
            up: Vec3::Y,
            fov_y_deg: 90.0,
        }
    }

    #[test]
    fn top_row_looks_up_and_left_column_looks_left() {
        let frame = CameraFrame::new(&camera(), 4, 4).unwrap();
        let mut rng = Rng::for_pixel(0, 0);
        let top_left = frame.ray(0, 0, &mut rng);
        assert!(top_left.dir.y > 0.0 && top_left.dir.x < 0.0 && top_left.dir.z < 0.0);
        let bottom_right = frame.ray(3, 3, &mut rng);
        assert!(bottom_right.dir.y < 0.0 && bottom_right.dir.x > 0.0);
    }

    #[test]
    fn fov_bounds_the_ray_slope() {
        // fov 90 degrees: |y/z| <= tan(45) = 1 for every pixel, and aspect 2 doubles the x range.
        let frame = CameraFrame::new(&camera(), 8, 4).unwrap();
        let mut rng = Rng::for_pixel(1, 0);
        for y in 0..4 {
            for x in 0..8 {
                let r = frame.ray(x, y, &mut rng);
                assert!((r.dir.y / r.dir.z).abs() <= 1.0 + 1e-6);
                assert!((r.dir.x / r.dir.z).abs() <= 2.0 + 1e-6);
                assert!((r.dir.length() - 1.0).abs() < 1e-6);
            }
        }
    }

    #[test]
    fn degenerate_cameras_are_rejected() {
        let mut c = camera();
        c.up = Vec3::new(0.0, 0.0, 2.0);
        assert_eq!(CameraFrame::new(&c, 4, 4), Err(CameraError::Degenerate));
        let mut c = camera();
        c.fov_y_deg = 0.0;
        assert_eq!(CameraFrame::new(&c, 4, 4), Err(CameraError::Fov(0.0)));
        let mut c = camera();
        c.eye.x = f32::NAN;
        assert_eq!(CameraFrame::new(&c, 4, 4), Err(CameraError::NonFinite));
    }
}
