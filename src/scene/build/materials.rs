//! `[materials.NAME]`: the BSDFs of eq. (2) by name, `null` built in.

use std::collections::BTreeMap;

use super::values::albedo;
use crate::bsdf::Bsdf;
use crate::scene::file::{path, MaterialDesc, SceneFile};
use crate::scene::{SceneError, SceneSource};

/// Every material of the file by name, with the built-in `null` (the index-matched boundary of
/// a medium).
pub(super) fn materials(
    src: &SceneSource,
    desc: &SceneFile,
) -> Result<BTreeMap<String, Bsdf>, SceneError> {
    let mut materials: BTreeMap<String, Bsdf> = BTreeMap::new();
    materials.insert("null".into(), Bsdf::Null);
    for (name, m) in &desc.materials {
        let key = path("materials").key(name);
        if name == "null" {
            return Err(src.error(
                &key,
                "`null` is the built-in index-matched boundary; choose another name",
            ));
        }
        let bsdf = match m {
            MaterialDesc::Lambert { albedo: a } => Bsdf::Lambert {
                albedo: albedo(src, &key.clone().key("albedo"), *a)?,
            },
            MaterialDesc::Mirror { reflectance } => Bsdf::Mirror {
                reflectance: albedo(src, &key.clone().key("reflectance"), *reflectance)?,
            },
            MaterialDesc::Dielectric { ior } => {
                if !(ior.is_finite() && *ior > 0.0) {
                    return Err(src.error(
                        &key.clone().key("ior"),
                        format!("ior = {ior} must be positive"),
                    ));
                }
                Bsdf::Dielectric { ior: *ior }
            }
            MaterialDesc::Null {} => Bsdf::Null,
        };
        materials.insert(name.clone(), bsdf);
    }
    Ok(materials)
}
