//! Checked values of a scene file: finite vectors, non-negative colours and albedos, each
//! error reported at its line and key.

use glam::Vec3;

use crate::scene::file::{KeyPath, RgbValue};
use crate::scene::{SceneError, SceneSource};

/// A finite 3-vector, or an error at `key`.
pub(super) fn finite3(src: &SceneSource, key: &KeyPath, v: [f32; 3]) -> Result<Vec3, SceneError> {
    if v.iter().all(|c| c.is_finite()) {
        Ok(Vec3::from_array(v))
    } else {
        Err(src.error(key, format!("{v:?} is not a finite vector")))
    }
}

/// A colour (`what`) finite and >= 0 on every channel, or an error at `key`.
pub(super) fn non_negative(
    src: &SceneSource,
    key: &KeyPath,
    v: RgbValue,
    what: &str,
) -> Result<Vec3, SceneError> {
    let c = v.to_rgb();
    if c.to_array().iter().all(|x| x.is_finite() && *x >= 0.0) {
        Ok(c)
    } else {
        Err(src.error(key, format!("{what} must be finite and >= 0, got {v}")))
    }
}

/// A surface albedo: non-negative and at most 1 (energy conservation of eq. (2)).
pub(super) fn albedo(src: &SceneSource, key: &KeyPath, v: RgbValue) -> Result<Vec3, SceneError> {
    let c = non_negative(src, key, v, "an albedo")?;
    if c.max_element() > 1.0 {
        return Err(src.error(
            key,
            format!("albedo {v} is above 1: the surface would reflect more light than it receives"),
        ));
    }
    Ok(c)
}

/// The key `k` below `key`.
pub(super) fn key_of(key: &KeyPath, k: &str) -> KeyPath {
    key.clone().key(k)
}
