//! `[camera]` and `[[sensors]]`: the camera (pinhole or thin lens) and the irradiance meters, the
//! instruments of the measurement equation (eq. 5), each placed in the medium around it.

use super::values::finite3;
use crate::film::filter::{PixelFilter, MAX_RADIUS};
use crate::geometry::shape::Quad;
use crate::scene::file::{self, path, SceneFile, SensorDesc};
use crate::scene::{Camera, IrradianceMeter, Scene, SceneError, SceneSource};

/// Installs the `[camera]`, if the file has one, with the medium its eye is in.
pub(super) fn camera(
    src: &SceneSource,
    desc: &SceneFile,
    scene: &mut Scene,
) -> Result<(), SceneError> {
    if let Some(file::CameraDesc::Pinhole {
        eye,
        look_at,
        up,
        fov_deg,
        resolution,
        aperture_radius,
        focus_distance,
        filter,
    }) = &desc.camera
    {
        let key = path("camera");
        let eye = finite3(src, &key.clone().key("eye"), *eye)?;
        let look_at = finite3(src, &key.clone().key("look_at"), *look_at)?;
        let up = finite3(src, &key.clone().key("up"), *up)?;
        if !(*fov_deg > 0.0 && *fov_deg < 180.0) {
            return Err(src.error(
                &key.clone().key("fov_deg"),
                format!("fov_deg = {fov_deg} must be in (0, 180)"),
            ));
        }
        if resolution[0] == 0
            || resolution[1] == 0
            || resolution[0] > 16384
            || resolution[1] > 16384
        {
            return Err(src.error(
                &key.clone().key("resolution"),
                format!("resolution {resolution:?} must be in 1..=16384"),
            ));
        }
        if (look_at - eye).length_squared() == 0.0 {
            return Err(src.error(
                &key.clone().key("look_at"),
                "look_at equals eye: the camera looks nowhere",
            ));
        }
        let filter = pixel_filter(src, &key.clone().key("filter"), *filter)?;
        let cam = Camera::new(eye, look_at, up, *fov_deg, resolution[0], resolution[1])
            .ok_or_else(|| {
                src.error(
                    &key.clone().key("up"),
                    "up is zero or parallel to the viewing direction look_at - eye",
                )
            })?;
        let mut cam = lens(src, cam, *aperture_radius, *focus_distance)?;
        cam.filter = filter;
        scene.camera_medium = scene.medium_at(eye);
        scene.camera = Some(cam);
    }
    Ok(())
}

/// The camera through a thin lens of radius `aperture_radius` focused at `focus_distance`, or
/// the pinhole for radius 0.
fn lens(
    src: &SceneSource,
    cam: Camera,
    aperture_radius: f32,
    focus_distance: Option<f32>,
) -> Result<Camera, SceneError> {
    let key = path("camera");
    if !(aperture_radius >= 0.0 && aperture_radius.is_finite()) {
        return Err(src.error(
            &key.key("aperture_radius"),
            format!("aperture_radius = {aperture_radius} must be finite and >= 0 (0: a pinhole)"),
        ));
    }
    let focus = match focus_distance {
        Some(f) if !(f > 0.0 && f.is_finite()) => {
            return Err(src.error(
                &key.key("focus_distance"),
                format!("focus_distance = {f} must be finite and > 0"),
            ))
        }
        Some(f) => f,
        None if aperture_radius > 0.0 => {
            return Err(src.error(
                &key.key("focus_distance"),
                "a thin lens (aperture_radius > 0) needs focus_distance",
            ))
        }
        None => 1.0,
    };
    // both checked above
    cam.with_lens(aperture_radius, focus)
        .ok_or_else(|| src.error(&key.key("aperture_radius"), "invalid thin lens"))
}

/// The reconstruction filter of `[camera] filter`, its parameter positive and its radius at
/// most [`MAX_RADIUS`] pixels.
fn pixel_filter(
    src: &SceneSource,
    key: &file::KeyPath,
    desc: file::FilterDesc,
) -> Result<PixelFilter, SceneError> {
    let (filter, name, v) = match desc {
        file::FilterDesc::Box => return Ok(PixelFilter::Box),
        file::FilterDesc::Tent { radius } => (PixelFilter::Tent { radius }, "radius", radius),
        file::FilterDesc::Gaussian { stddev } => {
            (PixelFilter::Gaussian { stddev }, "stddev", stddev)
        }
    };
    if !(v > 0.0 && filter.radius() <= MAX_RADIUS) {
        return Err(src.error(
            &key.clone().key(name),
            format!("{name} = {v} must be positive, with a filter radius of at most {MAX_RADIUS} pixels"),
        ));
    }
    Ok(filter)
}

/// Installs every `[[sensors]]` entry, each with the medium at its centre; names are unique.
pub(super) fn meters(
    src: &SceneSource,
    desc: &SceneFile,
    scene: &mut Scene,
) -> Result<(), SceneError> {
    for (i, s) in desc.sensors.iter().enumerate() {
        let key = path("sensors").index(i);
        match s {
            SensorDesc::IrradianceMeter { name, origin, u, v } => {
                let o = finite3(src, &key.clone().key("origin"), *origin)?;
                let u = finite3(src, &key.clone().key("u"), *u)?;
                let v = finite3(src, &key.clone().key("v"), *v)?;
                let quad = Quad::new(o, u, v).ok_or_else(|| {
                    src.error(
                        &key.clone().key("u"),
                        "u and v are parallel: the meter has no area",
                    )
                })?;
                if scene
                    .sensors
                    .iter()
                    .any(|m: &IrradianceMeter| &m.name == name)
                {
                    return Err(src.error(
                        &key.clone().key("name"),
                        format!("two sensors are called `{name}`"),
                    ));
                }
                let centre = o + 0.5 * (u + v);
                let medium = scene.medium_at(centre);
                scene.sensors.push(IrradianceMeter {
                    name: name.clone(),
                    quad,
                    medium,
                });
            }
        }
    }
    Ok(())
}
