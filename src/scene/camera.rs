//! The camera: the sensor responsivity W_e^(j) of the measurement equation (Pauly, Kollig,
//! Keller 2000, eq. 5) for pixel j with a box filter, of a pinhole or of a thin lens (another
//! reconstruction filter spreads a film point over its neighbours in the film, `film::filter`).
//!
//! The image plane sits at distance 1 in front of the lens centre `eye`; pixel (0, 0) is the
//! top-left. A thin lens (Kolb, Mitchell, Hanrahan 1995; Mitsuba 3 documentation, plugin
//! `thinlens`) is a disk of radius `lens_radius` around `eye`, perpendicular to `forward`: every
//! ray through a film point passes through that point's image on the focus plane, at distance
//! `focus_distance` along `forward`. `importance` gives W_e for a lens point and a direction,
//! so light tracing, BDPT (t = 1) and MLT can splat.

use glam::{Vec2, Vec3};

use crate::film::PixelFilter;
use crate::geometry::Ray;
use crate::math::{warp, Sampler};

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
    /// Radius of the lens disk; 0 for the pinhole.
    pub lens_radius: f32,
    /// Distance of the plane in focus from the lens along `forward` (unused by the pinhole).
    pub focus_distance: f32,
    /// The pixels' reconstruction filter (the box unless the scene asks for another).
    pub filter: PixelFilter,
}

/// The camera's response to light arriving from a point: where on the film and how much.
#[derive(Clone, Copy, Debug)]
pub struct CameraImportance {
    /// Continuous raster position (pixels, (0,0) top-left).
    pub raster: Vec2,
    /// W_e(lens point, direction) per pixel (includes the 1 / pixel-area box filter
    /// normalization, and the 1 / lens area of a thin lens).
    pub we: f32,
    /// Solid-angle density with which `generate_ray` picks this direction from the lens point
    /// (all pixels together).
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
            lens_radius: 0.0,
            focus_distance: 1.0,
            filter: PixelFilter::Box,
        })
    }

    /// The same view through a thin lens of radius `lens_radius` focused at `focus_distance`
    /// (`lens_radius` 0: the pinhole, unchanged). `None` for a negative or non-finite radius or
    /// a focus distance that is not positive and finite.
    pub fn with_lens(mut self, lens_radius: f32, focus_distance: f32) -> Option<Self> {
        if !(lens_radius >= 0.0 && lens_radius.is_finite()) {
            return None;
        }
        if lens_radius > 0.0 {
            if !(focus_distance > 0.0 && focus_distance.is_finite()) {
                return None;
            }
            self.lens_radius = lens_radius;
            self.focus_distance = focus_distance;
        }
        Some(self)
    }

    /// True for the pinhole: its position is a Dirac and its rays need no lens sample.
    #[inline]
    pub fn is_pinhole(&self) -> bool {
        self.lens_radius == 0.0
    }

    /// Area density of the lens points [`Camera::sample_lens`] draws: 1 / (pi r^2), or 1 for
    /// the pinhole (whose Dirac position the measure absorbs).
    #[inline]
    pub fn lens_pdf_area(&self) -> f32 {
        if self.is_pinhole() {
            1.0
        } else {
            1.0 / (std::f32::consts::PI * self.lens_radius * self.lens_radius)
        }
    }

    /// A lens point uniform on the disk: `eye` itself for the pinhole, which draws no numbers.
    pub fn sample_lens(&self, sampler: &mut Sampler) -> Vec3 {
        if self.is_pinhole() {
            return self.eye;
        }
        let d = self.lens_radius * warp::concentric_disk(sampler.next_2d());
        self.eye + self.right * d.x + self.up * d.y
    }

    /// The primary ray through `raster`, from a lens point drawn from `sampler` (the pinhole
    /// draws none and returns [`Camera::generate_ray`]).
    pub fn sample_ray(&self, raster: Vec2, sampler: &mut Sampler) -> Ray {
        if self.is_pinhole() {
            return self.generate_ray(raster);
        }
        let lens = self.sample_lens(sampler);
        self.ray_through(raster, lens)
    }

    /// The ray from lens point `lens` through the image of raster position `raster` on the
    /// focus plane (the pinhole ignores `lens`).
    pub fn ray_through(&self, raster: Vec2, lens: Vec3) -> Ray {
        if self.is_pinhole() {
            return self.generate_ray(raster);
        }
        let focus = self.eye + self.film_direction(raster) * self.focus_distance;
        Ray::new(lens, (focus - lens).normalize())
    }

    /// The film point of `raster` as a vector from `eye` with unit component along `forward`.
    #[inline]
    fn film_direction(&self, raster: Vec2) -> Vec3 {
        let ndc_x = 2.0 * raster.x / self.width as f32 - 1.0;
        let ndc_y = 1.0 - 2.0 * raster.y / self.height as f32;
        self.forward + self.right * (ndc_x * self.tan_half_x) + self.up * (ndc_y * self.tan_half_y)
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

    /// The pinhole's primary ray through continuous raster position `raster` (the ray from
    /// the lens centre; a thin lens samples its rays with [`Camera::sample_ray`]).
    #[inline]
    pub fn generate_ray(&self, raster: Vec2) -> Ray {
        Ray::new(self.eye, self.film_direction(raster).normalize())
    }

    /// Area of the image plane at distance 1.
    pub fn film_area(&self) -> f32 {
        4.0 * self.tan_half_x * self.tan_half_y
    }

    /// W_e and the film position for light arriving at lens point `lens` from direction `-dir`
    /// (`dir` points from the lens into the scene; the pinhole ignores `lens`). `None` outside
    /// the field of view.
    pub fn importance(&self, lens: Vec3, dir: Vec3) -> Option<CameraImportance> {
        let cos = dir.dot(self.forward);
        if cos <= 0.0 {
            return None;
        }
        let on_plane = if self.is_pinhole() {
            dir / cos
        } else {
            // the ray meets the focus plane where the film point's image is; seen from `eye`
            // that point lies along the film point
            (lens - self.eye + dir * (self.focus_distance / cos)) / self.focus_distance
        };
        let x = on_plane.dot(self.right) / self.tan_half_x;
        let y = on_plane.dot(self.up) / self.tan_half_y;
        if !(-1.0..=1.0).contains(&x) || !(-1.0..=1.0).contains(&y) {
            return None;
        }
        let raster = Vec2::new(
            (x + 1.0) * 0.5 * self.width as f32,
            (1.0 - y) * 0.5 * self.height as f32,
        );
        // pdf over the film plane is 1/A; to solid angle: d_omega = cos^3 dA (distance 1). From
        // a lens point the focus plane's image of the film, scaled by f, is seen at distance
        // f / cos: the same density.
        let pdf_dir = 1.0 / (self.film_area() * cos * cos * cos);
        // a pixel's W_e is normalized so that its integral over the lens area and directions,
        // with the cosine at the lens, is one: W_e = pdf_dir * npixels / cos / (lens area)
        // (the pinhole's Dirac position takes the area's place)
        let npix = (self.width * self.height) as f32;
        Some(CameraImportance {
            raster,
            we: pdf_dir * npix / cos * self.lens_pdf_area(),
            pdf_dir,
        })
    }
}
