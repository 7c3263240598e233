//! The BSDFs: `diffuse`, `conductor`, `roughconductor`, `dielectric`, `roughdielectric`,
//! `thindielectric`, `plastic`, `roughplastic`, `twosided` and `null`, with Mitsuba's named
//! indices of refraction and conductors.

use glam::DVec3;
use roxmltree::Node;

use super::{rgb, show, Importer, Props, Response};
use crate::bsdf::named_conductor::named_conductor;
use crate::scene::file::{
    DistributionDesc, FilterTypeDesc, MaterialDesc, ReflectanceValue, RgbValue, RoughnessValue,
    TextureDesc, WrapModeDesc,
};
use crate::scene::mitsuba::props::Doc;
use crate::scene::SceneError;

/// Mitsuba's named indices of refraction (the whole table of its `ior.h`).
const NAMED_IOR: [(&str, f64); 23] = [
    ("vacuum", 1.0),
    ("helium", 1.000036),
    ("hydrogen", 1.000132),
    ("air", 1.000277),
    ("carbon dioxide", 1.00045),
    ("water", 1.3330),
    ("acetone", 1.36),
    ("ethanol", 1.361),
    ("carbon tetrachloride", 1.461),
    ("glycerol", 1.4729),
    ("benzene", 1.501),
    ("silicone oil", 1.52045),
    ("bromine", 1.661),
    ("water ice", 1.31),
    ("fused quartz", 1.458),
    ("pyrex", 1.470),
    ("acrylic glass", 1.49),
    ("polypropylene", 1.49),
    ("bk7", 1.5046),
    ("sodium chloride", 1.544),
    ("amber", 1.55),
    ("pet", 1.5750),
    ("diamond", 2.419),
];

impl<'a, 'd> Importer<'a, 'd> {
    /// The material a `<bsdf>` becomes (memoized by element), `two_sided` when inside a
    /// `twosided`.
    pub(super) fn material(
        &mut self,
        node: Node<'a, 'a>,
        two_sided: Option<&str>,
    ) -> Result<String, SceneError> {
        if let Some(name) = self.materials.get(&node.id()) {
            return Ok(name.clone());
        }
        let mut p = Props::new(self.doc, node)?;
        // the material takes the id of its `twosided` wrapper, if any
        let id = two_sided.or(node.attribute("id"));
        let one_sided = two_sided.is_none();
        let side = if one_sided {
            ", one-sided (black behind its normal, as Mitsuba's)"
        } else {
            ""
        };
        match p.plugin.as_str() {
            "null" => {
                p.finish()?;
                return Ok("null".into());
            }
            "twosided" => return self.two_sided(node, p),
            _ => {}
        }
        let (desc, how) = bsdf(&mut p, one_sided, side)?;
        p.finish()?;
        Ok(self.add_material(node, id, desc, how))
    }

    /// A `twosided` around one of the BSDFs that have a back side: its inner BSDF made
    /// two-sided, under the wrapper's id.
    fn two_sided(
        &mut self,
        node: Node<'a, 'a>,
        mut p: Props<'a, 'd>,
    ) -> Result<String, SceneError> {
        let inner = p
            .object("bsdf", None)?
            .ok_or_else(|| p.err("a twosided needs one <bsdf>"))?;
        p.finish()?;
        let kind = self.doc.plugin(inner)?;
        if ![
            "diffuse",
            "conductor",
            "roughconductor",
            "plastic",
            "roughplastic",
        ]
        .contains(&kind.as_str())
        {
            return Err(self.doc.err(inner, format!("twosided `{kind}` is not supported (diffuse, conductor, roughconductor, plastic, roughplastic are)")));
        }
        let name = self.material(inner, Some(node.attribute("id").unwrap_or("")))?;
        self.materials.insert(node.id(), name.clone());
        Ok(name)
    }

    /// Adds the material of `node` under its `id` (or `bsdf@LINE` when it has none, or one
    /// already taken) and returns its name.
    fn add_material(
        &mut self,
        node: Node<'a, 'a>,
        id: Option<&str>,
        desc: MaterialDesc,
        how: String,
    ) -> String {
        let name = match id {
            Some(id) if !["", "null"].contains(&id) && !self.out.materials.contains_key(id) => {
                id.to_string()
            }
            _ => format!("bsdf@{}", self.doc.line(node)),
        };
        let key = format!("materials.{name}");
        self.note(node, &key, how);
        self.out.materials.insert(name.clone(), desc);
        self.materials.insert(node.id(), name.clone());
        name
    }
}

/// The material of a BSDF plugin other than `twosided` and `null`, and its note; `side` is what
/// the note says of a one-sided material.
fn bsdf(p: &mut Props, one_sided: bool, side: &str) -> Result<(MaterialDesc, String), SceneError> {
    match p.plugin.as_str() {
        "diffuse" => {
            let albedo = reflectance(p, "reflectance")?;
            let how = format!("lambert, albedo {albedo}{side}");
            Ok((MaterialDesc::Lambert { albedo, one_sided }, how))
        }
        "conductor" => {
            let (index, how) = conductor_index(p)?;
            let (specular, shown) = specular_reflectance(p)?;
            let (material, eta, k) = index;
            Ok((
                MaterialDesc::Conductor { material, eta, k, specular, one_sided },
                format!("conductor, {how}, specular {shown}{side}"),
            ))
        }
        "roughconductor" => rough_conductor(p, one_sided, side),
        "dielectric" | "roughdielectric" => dielectric(p),
        "thindielectric" => thin_dielectric(p),
        "plastic" => plastic(p, one_sided, side),
        "roughplastic" => rough_plastic(p, one_sided, side),
        k => Err(p.err(format!(
            "the BSDF `{k}` is not supported (diffuse, conductor, roughconductor, dielectric, roughdielectric, thindielectric, plastic, roughplastic, twosided, null are)"
        ))),
    }
}

/// A colour parameter that may be a texture (Mitsuba's `diffuse` `reflectance`, a plastic's
/// `diffuse_reflectance`), 0.5 when absent as in every plugin that has one.
fn reflectance(p: &mut Props, key: &str) -> Result<ReflectanceValue, SceneError> {
    Ok(match p.texture(key) {
        Some(t) => ReflectanceValue::Texture(texture(p.doc, t)?),
        None => rgb(p
            .color(key, Response::Bounded)?
            .unwrap_or(DVec3::splat(0.5)))
        .into(),
    })
}

/// A `specular_reflectance` (Mitsuba 3 documentation, plugins `conductor`, `roughconductor`,
/// `plastic`, `roughplastic`: a colour or a texture, default 1, scaling the Fresnel term), and
/// how the note shows it.
fn specular_reflectance(p: &mut Props) -> Result<(ReflectanceValue, String), SceneError> {
    let key = "specular_reflectance";
    if let Some(t) = p.texture(key) {
        let t = ReflectanceValue::Texture(texture(p.doc, t)?);
        let shown = t.to_string();
        return Ok((t, shown));
    }
    let s = p.color(key, Response::Bounded)?.unwrap_or(DVec3::ONE);
    Ok((rgb(s).into(), show(s)))
}

/// A `<texture>`: Mitsuba 3's `bitmap` (`filename`, `filter_type`, `wrap_mode`, `raw`,
/// `to_uv`) or `checkerboard` (`color0`, `color1`, `to_uv`), with their defaults.
pub(super) fn texture(doc: &Doc, node: Node) -> Result<TextureDesc, SceneError> {
    let mut p = Props::new(doc, node)?;
    let to_uv = match p.transform("to_uv")? {
        // Mitsuba's 4x4 to 3x3 (`AffineTransform::extract`): the z row and column dropped
        Some(m) => {
            let r = |i: usize| [m.row(i).x, m.row(i).y, m.row(i).w].map(|x| x as f32);
            Some([r(0), r(1)])
        }
        None => None,
    };
    let t = match p.plugin.as_str() {
        "checkerboard" => {
            let c = |p: &mut Props, k: &str, d: f32| -> Result<RgbValue, SceneError> {
                if p.tag_of(k) == Some("texture") {
                    return Err(p.err(format!(
                        "a texture as `{k}` of a checkerboard is not supported"
                    )));
                }
                Ok(p.color(k, Response::Bounded)?
                    .map_or(RgbValue::Scalar(d), rgb))
            };
            use crate::texture::checkerboard::{COLOR0, COLOR1};
            let (color0, color1) = (c(&mut p, "color0", COLOR0)?, c(&mut p, "color1", COLOR1)?);
            TextureDesc::Checkerboard {
                color0,
                color1,
                to_uv,
            }
        }
        "bitmap" => {
            let file = p
                .string("filename")?
                .ok_or_else(|| p.err("`filename` is missing"))?;
            let filter_type = match p.string("filter_type")?.as_deref() {
                None | Some("bilinear") => FilterTypeDesc::Bilinear,
                Some("nearest") => FilterTypeDesc::Nearest,
                Some(f) => {
                    return Err(p.err(format!(
                        "filter_type = {f}: Mitsuba knows bilinear and nearest"
                    )))
                }
            };
            let wrap_mode = match p.string("wrap_mode")?.as_deref() {
                None | Some("repeat") => WrapModeDesc::Repeat,
                Some("mirror") => WrapModeDesc::Mirror,
                Some("clamp") => WrapModeDesc::Clamp,
                Some(w) => {
                    return Err(p.err(format!(
                        "wrap_mode = {w}: Mitsuba knows repeat, mirror and clamp"
                    )))
                }
            };
            let raw = p.boolean("raw")?.unwrap_or(false);
            if p.string("format")?.is_some_and(|f| f != "variant") {
                return Err(
                    p.err("a `format` other than variant is not supported (it rounds texels)")
                );
            }
            TextureDesc::Bitmap {
                file,
                filter_type,
                wrap_mode,
                raw,
                to_uv,
            }
        }
        k => {
            return Err(p.err(format!(
                "the texture `{k}` is not supported (bitmap, checkerboard are)"
            )))
        }
    };
    p.finish()?;
    Ok(t)
}

/// `roughconductor`: Beckmann or GGX with the complex index of [`conductor_index`] and
/// `specular_reflectance` (1) scaling the Fresnel term, as Mitsuba's.
fn rough_conductor(
    p: &mut Props,
    one_sided: bool,
    side: &str,
) -> Result<(MaterialDesc, String), SceneError> {
    let (distribution, alphas) = microfacet(p)?;
    let ((material, eta, k), how) = conductor_index(p)?;
    let (specular, shown) = specular_reflectance(p)?;
    let [alpha, alpha_u, alpha_v] = alphas.keys();
    Ok((
        MaterialDesc::RoughConductor {
            alpha,
            alpha_u,
            alpha_v,
            distribution,
            reflectance: None,
            material,
            eta,
            k,
            specular,
            one_sided,
        },
        format!(
            "rough conductor ({}), {alphas}, {how}, specular {shown}{side}",
            dist_name(distribution),
        ),
    ))
}

/// A conductor's index as Mitsuba 3 reads it (plugins `conductor`, `roughconductor`):
/// `material` (default `none`) names tabulated spectra, turned into RGB as its RGB variants do
/// (`bsdf::named_conductor`); with `none`, `eta` (default 0) and `k` (default 1), each a colour
/// or a texture (unbounded: Mitsuba reads both with `get_unbounded_texture`), so that no index
/// at all is a Fresnel term of 1. A name with `eta` is Mitsuba's error, with `k` alone an
/// ambiguity it ignores: both refused.
#[allow(clippy::type_complexity)]
fn conductor_index(
    p: &mut Props,
) -> Result<
    (
        (
            Option<String>,
            Option<ReflectanceValue>,
            Option<ReflectanceValue>,
        ),
        String,
    ),
    SceneError,
> {
    let material = p.string("material")?.unwrap_or_else(|| "none".into());
    let index_part = |p: &mut Props, key: &str| -> Result<Option<ReflectanceValue>, SceneError> {
        if let Some(t) = p.texture(key) {
            return Ok(Some(ReflectanceValue::Texture(texture(p.doc, t)?)));
        }
        Ok(p.color(key, Response::Unbounded)?.map(|c| rgb(c).into()))
    };
    let (eta, k) = (index_part(p, "eta")?, index_part(p, "k")?);
    if material != "none" {
        if eta.is_some() || k.is_some() {
            return Err(p.err(format!(
                "material = \"{material}\" with eta or k: give either the material or eta and k"
            )));
        }
        if named_conductor(&material).is_none() {
            return Err(p.err(format!(
                "material = \"{material}\" is not one of Mitsuba 3's named conductors"
            )));
        }
        let how = format!("material {material}");
        return Ok(((Some(material), None, None), how));
    }
    if eta.is_none() && k.is_none() {
        // pathspace's default index is Mitsuba's (eta 0, k 1: a Fresnel term of 1)
        return Ok(((None, None, None), "reflectance 1 (material none)".into()));
    }
    let eta = eta.unwrap_or_else(|| rgb(DVec3::ZERO).into());
    let k = k.unwrap_or_else(|| rgb(DVec3::ONE).into());
    let how = format!("eta {eta}, k {k}");
    Ok(((None, Some(eta), Some(k)), how))
}

/// `dielectric` and `roughdielectric`: pathspace's `ior` is `int_ior / ext_ior`, with the two
/// factors of [`specular_factors`].
fn dielectric(p: &mut Props) -> Result<(MaterialDesc, String), SceneError> {
    let rough = p.plugin == "roughdielectric";
    let alpha = if rough { Some(microfacet(p)?) } else { None };
    let ior = ior(p, "int_ior", 1.5046)? / ior(p, "ext_ior", 1.000277)?;
    let ((specular_reflectance, specular_transmittance), shown) = specular_factors(p)?;
    Ok(match alpha {
        None => (
            MaterialDesc::Dielectric {
                ior: ior as f32,
                specular_reflectance,
                specular_transmittance,
            },
            format!("dielectric, ior {ior} (int_ior / ext_ior){shown}"),
        ),
        Some((d, a)) => (
            MaterialDesc::RoughDielectric {
                ior: ior as f32,
                alpha: a.keys()[0].clone(),
                alpha_u: a.keys()[1].clone(),
                alpha_v: a.keys()[2].clone(),
                distribution: d,
                specular_reflectance,
                specular_transmittance,
            },
            format!(
                "rough dielectric ({}), ior {ior} (int_ior / ext_ior), {a}{shown}",
                dist_name(d)
            ),
        ),
    })
}

/// `thindielectric`: `ior` = int_ior / ext_ior (defaults bk7 and air), and the two factors,
/// as `dielectric`.
fn thin_dielectric(p: &mut Props) -> Result<(MaterialDesc, String), SceneError> {
    let ior = ior(p, "int_ior", 1.5046)? / ior(p, "ext_ior", 1.000277)?;
    let ((specular_reflectance, specular_transmittance), shown) = specular_factors(p)?;
    Ok((
        MaterialDesc::ThinDielectric {
            ior: ior as f32,
            specular_reflectance,
            specular_transmittance,
        },
        format!("thin dielectric, ior {ior} (int_ior / ext_ior){shown}"),
    ))
}

/// A dielectric's `specular_reflectance` and `specular_transmittance` (Mitsuba 3
/// documentation, plugins `dielectric`, `roughdielectric`, `thindielectric`: a colour or a
/// texture, default 1, scaling reflection and transmission), and what the note adds.
fn specular_factors(
    p: &mut Props,
) -> Result<((ReflectanceValue, ReflectanceValue), String), SceneError> {
    let mut shown = String::new();
    let mut factor = |p: &mut Props, key: &str| -> Result<ReflectanceValue, SceneError> {
        if let Some(t) = p.texture(key) {
            let t = ReflectanceValue::Texture(texture(p.doc, t)?);
            shown += &format!(", {key} {t}");
            return Ok(t);
        }
        let c = p.color(key, Response::Bounded)?.unwrap_or(DVec3::ONE);
        if c != DVec3::ONE {
            shown += &format!(", {key} {}", show(c));
        }
        Ok(rgb(c).into())
    };
    let r = factor(p, "specular_reflectance")?;
    let t = factor(p, "specular_transmittance")?;
    Ok(((r, t), shown))
}

/// `plastic`: pathspace's `ior` is `int_ior / ext_ior` (defaults "polypropylene" and "air"),
/// `diffuse_reflectance` (0.5), `specular_reflectance` (1), `nonlinear` (false).
fn plastic(
    p: &mut Props,
    one_sided: bool,
    side: &str,
) -> Result<(MaterialDesc, String), SceneError> {
    use crate::bsdf::plastic::{DEFAULT_EXT_IOR, DEFAULT_INT_IOR};
    let ior = ior(p, "int_ior", DEFAULT_INT_IOR)? / ior(p, "ext_ior", DEFAULT_EXT_IOR)?;
    if !(ior.is_finite() && ior > 0.0) {
        return Err(p.err("int_ior and ext_ior must be positive"));
    }
    let d = reflectance(p, "diffuse_reflectance")?;
    let (specular, shown) = specular_reflectance(p)?;
    let nonlinear = p.boolean("nonlinear")?.unwrap_or(false);
    Ok((
        MaterialDesc::Plastic {
            diffuse: d.clone(),
            specular,
            ior: Some(ior as f32),
            nonlinear,
            one_sided,
        },
        format!(
            "plastic, diffuse {d}, specular {shown}, ior {ior} (int_ior / ext_ior){}{side}",
            if nonlinear { ", nonlinear" } else { "" }
        ),
    ))
}

/// An index of refraction given as a number or one of Mitsuba's names.
fn ior(p: &mut Props, key: &str, dflt: f64) -> Result<f64, SceneError> {
    if p.tag_of(key) != Some("string") {
        return Ok(p.float(key)?.unwrap_or(dflt));
    }
    match p.string(key)? {
        None => Ok(dflt),
        Some(s) => match NAMED_IOR.iter().find(|(n, _)| *n == s.as_str()) {
            Some(&(_, v)) => Ok(v),
            None => match s.parse::<f64>() {
                Ok(v) => Ok(v),
                Err(_) => Err(p.err(format!("{key} = \"{s}\" is not a known material name"))),
            },
        },
    }
}

/// A rough plugin's roughness: one `alpha`, or `alpha_u` along the shape's dp/du and `alpha_v`
/// across it, each a number or a texture.
#[derive(Clone)]
enum Alphas {
    Isotropic(RoughnessValue),
    Anisotropic(RoughnessValue, RoughnessValue),
}

impl Alphas {
    /// The scene file's `alpha`, `alpha_u` and `alpha_v`.
    fn keys(&self) -> [Option<RoughnessValue>; 3] {
        match self {
            Alphas::Isotropic(a) => [Some(a.clone()), None, None],
            Alphas::Anisotropic(u, v) => [None, Some(u.clone()), Some(v.clone())],
        }
    }
}

impl std::fmt::Display for Alphas {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Alphas::Isotropic(a) => write!(f, "alpha {a}"),
            Alphas::Anisotropic(u, v) => write!(f, "alpha_u {u}, alpha_v {v}"),
        }
    }
}

/// The microfacet model of a rough plugin: `distribution` (Mitsuba's default beckmann, or
/// ggx) and the roughness: one isotropic `alpha` (default 0.1), a number or a texture
/// (roughconductor and roughdielectric read it with `eval_1`; Mitsuba's roughplastic takes a
/// number only), or `alpha_u` and `alpha_v` (Mitsuba 3 documentation, plugins
/// `roughconductor`, `roughdielectric`: both or neither, not with `alpha`), each the same.
fn microfacet(p: &mut Props) -> Result<(DistributionDesc, Alphas), SceneError> {
    // Mitsuba lowercases the name
    let d = match p
        .string("distribution")?
        .map(|d| d.to_lowercase())
        .as_deref()
    {
        None | Some("beckmann") => DistributionDesc::Beckmann,
        Some("ggx") => DistributionDesc::Ggx,
        Some(d) => {
            return Err(p.err(format!(
                "distribution = {d}: Mitsuba knows beckmann and ggx"
            )))
        }
    };
    // only the sampler depends on it, not the BSDF
    p.ignore(&["sample_visible"]);
    let (u, v) = (
        roughness_value(p, "alpha_u")?,
        roughness_value(p, "alpha_v")?,
    );
    if u.is_some() || v.is_some() {
        let (Some(u), Some(v)) = (u, v) else {
            return Err(
                p.err("both alpha_u and alpha_v must be given (Mitsuba 3's microfacet model)")
            );
        };
        if p.tag_of("alpha").is_some() {
            return Err(p.err(
                "give either alpha or alpha_u and alpha_v, not both (Mitsuba 3's microfacet model)",
            ));
        }
        return Ok((d, Alphas::Anisotropic(u, v)));
    }
    let alpha = roughness_value(p, "alpha")?.unwrap_or(RoughnessValue::Value(0.1));
    Ok((d, Alphas::Isotropic(alpha)))
}

/// A roughness property `name`: a number or a texture (Mitsuba's `get_unbounded_texture`, read
/// with `eval_1`); `None` when absent.
fn roughness_value(p: &mut Props, name: &str) -> Result<Option<RoughnessValue>, SceneError> {
    if let Some(t) = p.texture(name) {
        return Ok(Some(RoughnessValue::Texture(texture(p.doc, t)?)));
    }
    Ok(p.float(name)?.map(|v| RoughnessValue::Value(v as f32)))
}

fn dist_name(d: DistributionDesc) -> &'static str {
    match d {
        DistributionDesc::Ggx => "GGX",
        DistributionDesc::Beckmann => "Beckmann",
    }
}

/// `roughplastic`: pathspace's `ior` is `int_ior / ext_ior` (defaults polypropylene and air),
/// `diffuse_reflectance` (0.5), `specular_reflectance` (1), `nonlinear` (false).
fn rough_plastic(
    p: &mut Props,
    one_sided: bool,
    side: &str,
) -> Result<(MaterialDesc, String), SceneError> {
    let (distribution, alpha) = microfacet(p)?;
    let alpha = match alpha {
        Alphas::Isotropic(RoughnessValue::Value(alpha)) => alpha,
        Alphas::Isotropic(RoughnessValue::Texture(_)) => {
            return Err(p.err("a texture as `alpha` of a roughplastic: Mitsuba 3's roughplastic takes a number (its tables are computed for one alpha)"))
        }
        Alphas::Anisotropic(..) => {
            return Err(p.err("alpha_u and alpha_v of a roughplastic: Mitsuba 3's roughplastic refuses anisotropic roughness"))
        }
    };
    let (int_ior, ext_ior) = (ior(p, "int_ior", 1.49)?, ior(p, "ext_ior", 1.000277)?);
    if !(int_ior > 0.0 && ext_ior > 0.0) || int_ior == ext_ior {
        return Err(p.err("int_ior and ext_ior must be positive and differ"));
    }
    let ior = int_ior / ext_ior;
    let diffuse = reflectance(p, "diffuse_reflectance")?;
    let (specular, shown) = specular_reflectance(p)?;
    let nonlinear = p.boolean("nonlinear")?.unwrap_or(false);
    Ok((
        MaterialDesc::RoughPlastic {
            diffuse: diffuse.clone(),
            specular,
            alpha,
            distribution,
            ior: ior as f32,
            nonlinear,
            one_sided,
        },
        format!(
            "rough plastic ({}), alpha {alpha}, ior {ior} (int_ior / ext_ior), diffuse {diffuse}, specular {shown}{}{side}",
            dist_name(distribution),
            if nonlinear { ", nonlinear" } else { "" }
        ),
    ))
}
