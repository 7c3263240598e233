//! The pinhole camera: the sensor responsivity W_e^(j) of the measurement equation (Pauly,
//! Kollig, Keller 2000, eq. 5) for pixel j with a box filter (another reconstruction filter
//! spreads a film point over its neighbours in the film, `film::filter`).
//!
//! The image plane sits at distance 1 in front of the pinhole; pixel (0, 0) is the top-left.
//! `importance` gives W_e for a direction, so light tracing, BDPT (t = 1) and MLT can splat.

use glam::{Vec2, Vec3};

use crate::film::PixelFilter;
use crate::geometry::Ray;

#[derive(Clone, Debug)]
pub struct Camera {
    pub eye: Vec3,
    /// Unit viewing direction.
    pub forward: Vec3,
    /// Unit right and up vectors of the image plane.
    pub right: Vec3,
    pub up: Vec3,
    /// Half-extent of the image plane at distance 1 (tan of the half field of view).
    pub tan_half_y: f32,
    pub tan_half_x: f32,
    pub width: u32,
    pub height: u32,
    /// The pixels' reconstruction filter (the box unless the scene asks for another).
    pub filter: PixelFilter,
}

/// The camera's response to light arriving from a point: where on the film and how much.
#[derive(Clone, Copy, Debug)]
pub struct CameraImportance {
    /// Continuous raster position (pixels, (0,0) top-left).
    pub raster: Vec2,
    /// W_e(eye, direction) per pixel (includes the 1 / pixel-area box filter normalization).
    pub we: f32,
    /// Solid-angle density with which `generate_ray` picks this direction (all pixels together).
    pub pdf_dir: f32,
}

impl Camera {
    pub fn new(
        eye: Vec3,
        look_at: Vec3,
        up: Vec3,
        fov_deg: f32,
        width: u32,
        height: u32,
    ) -> Option<Self> {
        let forward = (look_at - eye).try_normalize()?;
        let right = forward.cross(up).try_normalize()?;
        let up = right.cross(forward);
        let tan_half_y = (0.5 * fov_deg.to_radians()).tan();
        if !(tan_half_y > 0.0 && tan_half_y.is_finite()) || width == 0 || height == 0 {
            return None;
        }
        let tan_half_x = tan_half_y * width as f32 / height as f32;
        Some(Camera {
            eye,
            forward,
            right,
            up,
            tan_half_y,
            tan_half_x,
            width,
            height,
            filter: PixelFilter::Box,
        })
    }

    /// The same view at another resolution (the vertical field of view is kept).
    pub fn with_resolution(&self, width: u32, height: u32) -> Option<Self> {
        if width == 0 || height == 0 {
            return None;
        }
        let mut c = self.clone();
        c.width = width;
        c.height = height;
        c.tan_half_x = self.tan_half_y * width as f32 / height as f32;
        Some(c)
    }

    /// The primary ray through continuous raster position `raster`.
    #[inline]
    pub fn generate_ray(&self, raster: Vec2) -> Ray {
        let ndc_x = 2.0 * raster.x / self.width as f32 - 1.0;
        let ndc_y = 1.0 - 2.0 * raster.y / self.height as f32;
        let d = self.forward
            + self.right * (ndc_x * self.tan_half_x)
            + self.up * (ndc_y * self.tan_half_y);
        Ray::new(self.eye, d.normalize())
    }

    /// Area of the image plane at distance 1.
    pub fn film_area(&self) -> f32 {
        4.0 * self.tan_half_x * self.tan_half_y
    }

    /// W_e and the film position for light arriving at the eye from direction `-dir`
    /// (`dir` points from the eye into the scene). `None` outside the field of view.
    pub fn importance(&self, dir: Vec3) -> Option<CameraImportance> {
        let cos = dir.dot(self.forward);
        if cos <= 0.0 {
            return None;
        }
        let on_plane = dir / cos;
        let x = on_plane.dot(self.right) / self.tan_half_x;
        let y = on_plane.dot(self.up) / self.tan_half_y;
        if !(-1.0..=1.0).contains(&x) || !(-1.0..=1.0).contains(&y) {
            return None;
        }
        let raster = Vec2::new(
            (x + 1.0) * 0.5 * self.width as f32,
            (1.0 - y) * 0.5 * self.height as f32,
        );
        // pdf over the film plane is 1/A; to solid angle: d_omega = cos^3 dA (distance 1)
        let pdf_dir = 1.0 / (self.film_area() * cos * cos * cos);
        // a pixel's W_e is normalized so that its integral over directions (times cos, which the
        // pinhole's delta position absorbs) is one: W_e = pdf_dir * npixels / cos
        let npix = (self.width * self.height) as f32;
        Some(CameraImportance {
            raster,
            we: pdf_dir * npix / cos,
            pdf_dir,
        })
    }
}
