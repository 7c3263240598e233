//! `[materials.NAME]`: the BSDFs of eq. (2) by name, `null` built in.

use std::collections::BTreeMap;

use std::sync::Arc;

use super::textures::{colour, mean, reflectance, texture, Texels};
use super::values::albedo;
use crate::bsdf::microfacet::{Anisotropy, ALPHA_MAX, ALPHA_MIN};
use crate::bsdf::named_conductor::{named_conductor, NAMED_CONDUCTORS};
use crate::bsdf::plastic::default_eta;
use crate::bsdf::{
    Bsdf, Conductor, ConductorFresnel, Dielectric, Distribution, Lambert, Microfacet, Mirror, Null,
    Plastic, RoughConductor, RoughDielectric, RoughPlastic, Specular, ThinDielectric,
};
use crate::scene::file::{
    path, DistributionDesc, KeyPath, MaterialDesc, ReflectanceValue, RgbValue, RoughnessValue,
    SceneFile,
};
use crate::scene::{SceneError, SceneSource};
use crate::spectrum::Rgb;
use crate::texture::{Texture, MITSUBA_LUMINANCE};
use glam::Vec3;

/// The materials by name, and the textured parameters of those that have some.
pub(super) struct Materials {
    pub(super) bsdfs: BTreeMap<String, Bsdf>,
    pub(super) textures: BTreeMap<String, Textured>,
}

/// A material's textured parameters: its reflectance (`albedo`, a plastic's `diffuse`), its
/// roughness (`alpha` or `alpha_u`, and `alpha_v`), a conductor's or plastic's `specular` or a dielectric's
/// `specular_reflectance`, a dielectric's `specular_transmittance`, and a conductor's complex
/// index (`eta`, `k`); and whether its roughness is anisotropic (`tangent`).
#[derive(Default)]
pub(super) struct Textured {
    pub(super) reflectance: Option<Arc<Texture>>,
    pub(super) alpha: Option<Arc<Texture>>,
    pub(super) alpha_v: Option<Arc<Texture>>,
    pub(super) specular: Option<Arc<Texture>>,
    pub(super) transmittance: Option<Arc<Texture>>,
    pub(super) eta: Option<Arc<Texture>>,
    pub(super) k: Option<Arc<Texture>>,
    /// An anisotropic roughness: the BSDF at a point takes the shape's dp/du there.
    pub(super) tangent: bool,
}

impl Textured {
    fn reflectance(t: Option<Texture>) -> Self {
        Textured {
            reflectance: t.map(Arc::new),
            ..Textured::default()
        }
    }

    /// A rough material's textured `alpha` (or `alpha_u`) and `alpha_v`, and its tangent.
    fn roughness(r: Roughness) -> Self {
        Textured {
            alpha: r.texture.map(Arc::new),
            alpha_v: r.texture_v.map(Arc::new),
            tangent: r.anisotropy.is_some(),
            ..Textured::default()
        }
    }

    fn is_some(&self) -> bool {
        self.reflectance.is_some()
            || self.alpha.is_some()
            || self.alpha_v.is_some()
            || self.specular.is_some()
            || self.transmittance.is_some()
            || self.eta.is_some()
            || self.k.is_some()
            || self.tangent
    }
}

/// Every material of the file by name, with the built-in `null` (the index-matched boundary of
/// a medium).
pub(super) fn materials(src: &SceneSource, desc: &SceneFile) -> Result<Materials, SceneError> {
    let mut materials: BTreeMap<String, Bsdf> = BTreeMap::new();
    let mut textures = BTreeMap::new();
    materials.insert("null".into(), Bsdf::Null(Null));
    for (name, m) in &desc.materials {
        let key = path("materials").key(name);
        if name == "null" {
            return Err(src.error(
                &key,
                "`null` is the built-in index-matched boundary; choose another name",
            ));
        }
        let mut textured = Textured::default();
        let bsdf = match m {
            MaterialDesc::Lambert {
                albedo: a,
                one_sided,
            } => {
                let (albedo, texture) = reflectance(src, &key.clone().key("albedo"), a)?;
                textured = Textured::reflectance(texture);
                Bsdf::Lambert(Lambert {
                    albedo,
                    one_sided: *one_sided,
                })
            }
            MaterialDesc::Mirror {
                reflectance,
                one_sided,
            } => Bsdf::Mirror(Mirror {
                reflectance: albedo(src, &key.clone().key("reflectance"), *reflectance)?,
                one_sided: *one_sided,
            }),
            MaterialDesc::Dielectric {
                ior,
                specular_reflectance: r,
                specular_transmittance: t,
            } => {
                if !(ior.is_finite() && *ior > 0.0) {
                    return Err(src.error(
                        &key.clone().key("ior"),
                        format!("ior = {ior} must be positive"),
                    ));
                }
                let specular = specular_factors(src, &key, r, t, &mut textured)?;
                Bsdf::Dielectric(Dielectric {
                    ior: *ior,
                    specular,
                })
            }
            MaterialDesc::ThinDielectric {
                ior,
                specular_reflectance: r,
                specular_transmittance: t,
            } => {
                if !(ior.is_finite() && *ior > 0.0) {
                    return Err(src.error(
                        &key.clone().key("ior"),
                        format!("ior = {ior} must be positive"),
                    ));
                }
                let specular = specular_factors(src, &key, r, t, &mut textured)?;
                Bsdf::ThinDielectric(ThinDielectric {
                    ior: *ior,
                    specular,
                })
            }
            MaterialDesc::Conductor {
                material,
                eta,
                k,
                specular,
                one_sided,
            } => {
                let (specular, texture) = reflectance(src, &key.clone().key("specular"), specular)?;
                textured.specular = texture.map(Arc::new);
                let index = Index {
                    material: material.as_deref(),
                    eta: eta.as_ref(),
                    k: k.as_ref(),
                };
                let index = complex_index(src, &key, index, &mut textured)?;
                let (eta, k) = index.unwrap_or((Rgb::ZERO, Rgb::ONE));
                Bsdf::Conductor(Conductor {
                    eta,
                    k,
                    specular,
                    one_sided: *one_sided,
                })
            }
            MaterialDesc::RoughConductor {
                alpha,
                alpha_u,
                alpha_v,
                distribution,
                reflectance,
                material,
                eta,
                k,
                specular,
                one_sided,
            } => {
                let r = material_roughness(src, &key, [alpha, alpha_u, alpha_v], "conductor")?;
                let (alpha, anisotropy) = (r.alpha, r.anisotropy);
                textured = Textured::roughness(r);
                let specular_key = key.clone().key("specular");
                let (specular, texture) =
                    super::textures::reflectance(src, &specular_key, specular)?;
                textured.specular = texture.map(Arc::new);
                Bsdf::RoughConductor(RoughConductor {
                    distribution: distribution_of(*distribution),
                    alpha,
                    fresnel: conductor_fresnel(
                        src,
                        &key,
                        *reflectance,
                        Index {
                            material: material.as_deref(),
                            eta: eta.as_ref(),
                            k: k.as_ref(),
                        },
                        &mut textured,
                    )?,
                    specular,
                    one_sided: *one_sided,
                    anisotropy,
                })
            }
            MaterialDesc::RoughDielectric {
                ior,
                alpha,
                alpha_u,
                alpha_v,
                distribution,
                specular_reflectance: r,
                specular_transmittance: t,
            } => {
                let rough = material_roughness(src, &key, [alpha, alpha_u, alpha_v], "dielectric")?;
                let (alpha, anisotropy) = (rough.alpha, rough.anisotropy);
                textured = Textured::roughness(rough);
                let specular = specular_factors(src, &key, r, t, &mut textured)?;
                Bsdf::RoughDielectric(RoughDielectric {
                    ior: rough_ior(src, &key, *ior)?,
                    distribution: distribution_of(*distribution),
                    alpha,
                    specular,
                    anisotropy,
                })
            }
            MaterialDesc::Plastic {
                diffuse,
                specular,
                ior,
                nonlinear,
                one_sided,
            } => {
                let (diffuse, texture) = reflectance(src, &key.clone().key("diffuse"), diffuse)?;
                textured = Textured::reflectance(texture);
                let (specular, texture) = reflectance(src, &key.clone().key("specular"), specular)?;
                textured.specular = texture.map(Arc::new);
                Bsdf::Plastic(Plastic {
                    diffuse,
                    specular,
                    eta: plastic_ior(src, &key, *ior)?,
                    nonlinear: *nonlinear,
                    one_sided: *one_sided,
                })
            }
            MaterialDesc::RoughPlastic {
                diffuse,
                specular,
                alpha,
                distribution,
                ior,
                nonlinear,
                one_sided,
            } => {
                // textured diffuse and specular: the textures' means set the sampling weight,
                // as Mitsuba's (`m_specular_sampling_weight`, computed once at load)
                let (diffuse, texture) = reflectance(src, &key.clone().key("diffuse"), diffuse)?;
                textured = Textured::reflectance(texture);
                let (specular, texture) = reflectance(src, &key.clone().key("specular"), specular)?;
                textured.specular = texture.map(Arc::new);
                Bsdf::RoughPlastic(RoughPlastic::new(
                    Microfacet::new(
                        distribution_of(*distribution),
                        roughness(src, &key, *alpha, "plastic")?,
                    ),
                    rough_plastic_ior(src, &key, *ior)?,
                    diffuse,
                    specular,
                    *nonlinear,
                    *one_sided,
                ))
            }
            MaterialDesc::Null {} => Bsdf::Null(Null),
        };
        materials.insert(name.clone(), bsdf);
        if textured.is_some() {
            textures.insert(name.clone(), textured);
        }
    }
    Ok(Materials {
        bsdfs: materials,
        textures,
    })
}

/// A dielectric's `specular_reflectance` and `specular_transmittance` (each a colour in
/// [0, 1] or a texture, whose mean stands in where no point is known); their textures go to
/// `textured` (`specular` and `transmittance`).
fn specular_factors(
    src: &SceneSource,
    key: &KeyPath,
    r: &ReflectanceValue,
    t: &ReflectanceValue,
    textured: &mut Textured,
) -> Result<Specular, SceneError> {
    let (r, rt) = reflectance(src, &key.clone().key("specular_reflectance"), r)?;
    let (t, tt) = reflectance(src, &key.clone().key("specular_transmittance"), t)?;
    textured.specular = rt.map(Arc::new);
    textured.transmittance = tt.map(Arc::new);
    Ok(Specular {
        reflectance: r,
        transmittance: t,
    })
}

fn distribution_of(d: DistributionDesc) -> Distribution {
    match d {
        DistributionDesc::Ggx => Distribution::Ggx,
        DistributionDesc::Beckmann => Distribution::Beckmann,
    }
}

/// A rough plastic coating's index: positive and not 1 (Mitsuba's `roughplastic` refuses equal
/// indices: there would be no coating).
fn rough_plastic_ior(src: &SceneSource, key: &KeyPath, ior: f32) -> Result<f32, SceneError> {
    let key = key.clone().key("ior");
    if !(ior.is_finite() && ior > 0.0) || ior == 1.0 {
        return Err(src.error(
            &key,
            format!(
                "ior = {ior} must be positive and not 1 (the coating's index inside over outside)"
            ),
        ));
    }
    Ok(ior)
}

/// A microfacet roughness in [ALPHA_MIN, ALPHA_MAX]: a smoother surface is the smooth material
/// (`smooth`), which samples its Dirac exactly, a rougher one leaves the range where the
/// single-scattering model is a fair description (see `bsdf::microfacet`).
fn roughness(
    src: &SceneSource,
    key: &KeyPath,
    alpha: f32,
    smooth: &str,
) -> Result<f32, SceneError> {
    roughness_at(src, key, "alpha", alpha, smooth)
}

/// [`roughness`] of the key `name` (`alpha`, `alpha_u`, `alpha_v`).
fn roughness_at(
    src: &SceneSource,
    key: &KeyPath,
    name: &str,
    alpha: f32,
    smooth: &str,
) -> Result<f32, SceneError> {
    let key = key.clone().key(name);
    if !alpha.is_finite() || alpha < ALPHA_MIN {
        return Err(src.error(
            &key,
            format!(
                "{name} = {alpha} is below {ALPHA_MIN}: a lobe that narrow is lost in f32 \
                 rounding; use type = \"{smooth}\" for a smooth surface"
            ),
        ));
    }
    if alpha > ALPHA_MAX {
        return Err(src.error(
            &key,
            format!(
                "{name} = {alpha} is above {ALPHA_MAX}: the microfacet model without multiple \
                 scattering loses too much energy beyond it; use lambert for a matte surface"
            ),
        ));
    }
    Ok(alpha)
}

/// A roughness that may be a texture: a number as [`roughness`], or a texture whose
/// one-channel values all lie in [`roughness`]'s range (the texture's mean luminance stands in
/// where no point is known).
fn textured_roughness(
    src: &SceneSource,
    key: &KeyPath,
    alpha: &RoughnessValue,
    smooth: &str,
) -> Result<(f32, Option<Texture>), SceneError> {
    textured_roughness_at(src, key, "alpha", alpha, smooth)
}

/// [`textured_roughness`] of the key `name` (`alpha`, `alpha_u`, `alpha_v`).
fn textured_roughness_at(
    src: &SceneSource,
    key: &KeyPath,
    name: &str,
    alpha: &RoughnessValue,
    smooth: &str,
) -> Result<(f32, Option<Texture>), SceneError> {
    let t = match alpha {
        RoughnessValue::Value(a) => return Ok((roughness_at(src, key, name, *a, smooth)?, None)),
        RoughnessValue::Texture(t) => texture(src, &key.clone().key(name), t)?,
    };
    let (lo, hi) = t.range_1();
    roughness_at(src, key, name, lo, smooth)?;
    roughness_at(src, key, name, hi, smooth)?;
    Ok((mean(&t).dot(MITSUBA_LUMINANCE), Some(t)))
}

/// A rough material's roughness: `alpha` (the roughness along the tangent when anisotropic),
/// the anisotropy, and the textures of `alpha` (or `alpha_u`) and `alpha_v`.
struct Roughness {
    alpha: f32,
    anisotropy: Option<Anisotropy>,
    texture: Option<Texture>,
    texture_v: Option<Texture>,
}

/// A rough material's roughness: `alpha`, or `alpha_u` along the shape's dp/du and `alpha_v`
/// across it (Mitsuba 3 documentation, plugins `roughconductor` and `roughdielectric`: both or
/// neither, never with `alpha`), each a number or a texture as [`textured_roughness`]. Equal
/// numbers are the isotropic `alpha` (the same BSDF and code).
fn material_roughness(
    src: &SceneSource,
    key: &KeyPath,
    alphas: [&Option<RoughnessValue>; 3],
    smooth: &str,
) -> Result<Roughness, SceneError> {
    let missing = |name: &str, other: &str| {
        src.error(
            &key.clone().key(other),
            format!("{other} needs {name}: give both alpha_u and alpha_v, or one `alpha`"),
        )
    };
    match alphas {
        [Some(a), None, None] => {
            let (alpha, texture) = textured_roughness(src, key, a, smooth)?;
            Ok(Roughness {
                alpha,
                anisotropy: None,
                texture,
                texture_v: None,
            })
        }
        [Some(_), _, _] => Err(src.error(
            &key.clone().key("alpha"),
            "give either `alpha` or `alpha_u` and `alpha_v`, not both",
        )),
        [None, Some(u), Some(v)] => {
            let (alpha, texture) = textured_roughness_at(src, key, "alpha_u", u, smooth)?;
            let (alpha_v, texture_v) = textured_roughness_at(src, key, "alpha_v", v, smooth)?;
            let textured = texture.is_some() || texture_v.is_some();
            let anisotropy = (alpha != alpha_v || textured).then_some(Anisotropy {
                alpha_v,
                tangent: Vec3::ZERO,
            });
            Ok(Roughness {
                alpha,
                anisotropy,
                texture,
                texture_v,
            })
        }
        [None, Some(_), None] => Err(missing("alpha_u", "alpha_v")),
        [None, None, Some(_)] => Err(missing("alpha_v", "alpha_u")),
        [None, None, None] => Err(src.error(
            &key.clone().key("alpha"),
            "missing the roughness: give `alpha`, or `alpha_u` and `alpha_v`",
        )),
    }
}

/// A rough dielectric's index: positive and not within 1% of 1, where every refracted
/// direction collapses onto -wo whatever the facet (an index-matched boundary is `null`).
fn rough_ior(src: &SceneSource, key: &KeyPath, ior: f32) -> Result<f32, SceneError> {
    let key = key.clone().key("ior");
    if !(ior.is_finite() && ior > 0.0) {
        return Err(src.error(&key, format!("ior = {ior} must be positive")));
    }
    if (ior - 1.0).abs() < 0.01 {
        return Err(src.error(
            &key,
            format!(
                "ior = {ior} is within 1% of 1: the rough refraction lobe degenerates to a \
                 straight line; use the `null` material for an index-matched boundary"
            ),
        ));
    }
    Ok(ior)
}

/// A plastic coat's index inside over outside (default Mitsuba's 1.49 / 1.000277): positive
/// (Mitsuba accepts any, 1 included: a coat that reflects nothing).
fn plastic_ior(src: &SceneSource, key: &KeyPath, ior: Option<f32>) -> Result<f32, SceneError> {
    let Some(ior) = ior else {
        return Ok(default_eta());
    };
    let key = key.clone().key("ior");
    if !(ior.is_finite() && ior > 0.0) {
        return Err(src.error(&key, format!("ior = {ior} must be positive")));
    }
    Ok(ior)
}

/// A conductor's complex index as the file gives it: a named conductor, or `eta` and `k`
/// (each a colour or a texture).
#[derive(Clone, Copy)]
struct Index<'a> {
    material: Option<&'a str>,
    eta: Option<&'a ReflectanceValue>,
    k: Option<&'a ReflectanceValue>,
}

/// Schlick's Fresnel about `reflectance` (default 1), or a complex index (`material` or `eta`
/// and `k`, [`complex_index`]), never both.
fn conductor_fresnel(
    src: &SceneSource,
    key: &KeyPath,
    reflectance: Option<RgbValue>,
    index: Index,
    textured: &mut Textured,
) -> Result<ConductorFresnel, SceneError> {
    let (material, eta) = (index.material, index.eta);
    let index = complex_index(src, key, index, textured)?;
    match (reflectance, index) {
        (r, None) => Ok(ConductorFresnel::Schlick(albedo(
            src,
            &key.clone().key("reflectance"),
            r.unwrap_or(RgbValue::Scalar(1.0)),
        )?)),
        (Some(_), Some(_)) => Err(src.error(
            &key.clone().key(match (material, eta) {
                (Some(_), _) => "material",
                (_, Some(_)) => "eta",
                _ => "k",
            }),
            "give either `reflectance` (Schlick's Fresnel) or a complex index (`material`, or \
             `eta` and `k`), not both",
        )),
        (None, Some((eta, k))) => Ok(ConductorFresnel::Complex { eta, k }),
    }
}

/// A conductor's complex index eta + i k per channel: one of Mitsuba 3's named conductors
/// (`material`; `none` is no index), or `eta` and `k` (both needed, >= 0, not both 0 in a
/// channel, where the Fresnel term is 0 / 0); `None` when none is given. A textured `eta` or
/// `k` (Mitsuba 3 documentation, plugin `conductor`: "float or texture") goes to `textured`,
/// its mean standing in where no point is known; it may be 0 in a channel only where the
/// other is positive everywhere.
fn complex_index(
    src: &SceneSource,
    key: &KeyPath,
    index: Index,
    textured: &mut Textured,
) -> Result<Option<(Rgb, Rgb)>, SceneError> {
    let Index { material, eta, k } = index;
    let least;
    let index = match (material, eta, k) {
        (Some(_), Some(_), _) | (Some(_), _, Some(_)) => {
            return Err(src.error(
                &key.clone().key("material"),
                "give either `material` or `eta` and `k`, not both",
            ))
        }
        (Some("none"), None, None) | (None, None, None) => return Ok(None),
        (Some(name), None, None) => {
            let index = named_conductor(name).ok_or_else(|| {
                let names: Vec<&str> = NAMED_CONDUCTORS.iter().map(|c| c.0).collect();
                src.error(
                    &key.clone().key("material"),
                    format!(
                        "material = \"{name}\" is not one of Mitsuba 3's named conductors ({}, none)",
                        names.join(", ")
                    ),
                )
            })?;
            least = index;
            index
        }
        (None, Some(eta), Some(k)) => {
            let (e, te) = colour(src, &key.clone().key("eta"), eta, Texels::Index("eta"))?;
            let (kk, tk) = colour(src, &key.clone().key("k"), k, Texels::Index("k"))?;
            least = (
                te.as_ref().map_or(e, Texture::least),
                tk.as_ref().map_or(kk, Texture::least),
            );
            textured.eta = te.map(Arc::new);
            textured.k = tk.map(Arc::new);
            (e, kk)
        }
        (None, eta, _) => {
            return Err(src.error(
                &key.clone().key(if eta.is_some() { "eta" } else { "k" }),
                "a complex index needs both `eta` and `k`",
            ))
        }
    };
    let (e, kk) = least;
    if (0..3).any(|c| e[c] == 0.0 && kk[c] == 0.0) {
        let at = if material.is_some() {
            "material"
        } else {
            "eta"
        };
        return Err(src.error(
            &key.clone().key(at),
            format!(
                "eta {} and k {} are both 0 in a channel (their least values): the Fresnel term \
                 is undefined there",
                crate::spectrum::show(e),
                crate::spectrum::show(kk)
            ),
        ));
    }
    Ok(Some(index))
}
