//! Mitsuba 3 plugins, one function each, translated into pathspace's scene-file descriptions
//! with Mitsuba's conventions and defaults; anything without an exact counterpart is refused.

use glam::{DMat3, DMat4, DVec3};
use roxmltree::{Node, NodeId};
use std::collections::HashMap;
use std::path::PathBuf;

use super::props::{Doc, Props};
use super::FORMAT;
use crate::scene::file::{
    CameraDesc, DistributionDesc, LightDesc, MaterialDesc, MediumDesc, Origin, PhaseDesc,
    PropagationDesc, RgbValue, SceneFile, ShapeDesc,
};
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

/// The translation in progress.
pub(super) struct Importer<'a, 'd> {
    doc: &'d Doc<'a>,
    base_dir: PathBuf,
    out: SceneFile,
    origin: Origin,
    materials: HashMap<NodeId, String>,
    media: HashMap<NodeId, String>,
    render: toml::Table,
    integrator: Option<(String, Node<'a, 'a>)>,
    sensor_seen: bool,
}

fn rgb(v: DVec3) -> RgbValue {
    if v.x == v.y && v.y == v.z {
        RgbValue::Scalar(v.x as f32)
    } else {
        RgbValue::Triple([v.x as f32, v.y as f32, v.z as f32])
    }
}

/// A vector for `info`: six significant decimals, one number when the three agree.
fn show(v: DVec3) -> String {
    let n = |x: f64| {
        let t = format!("{x:.6}");
        let t = t.trim_end_matches('0').trim_end_matches('.');
        if t == "-0" {
            "0".to_string()
        } else {
            t.to_string()
        }
    };
    if v.x == v.y && v.y == v.z {
        n(v.x)
    } else {
        format!("[{}, {}, {}]", n(v.x), n(v.y), n(v.z))
    }
}

fn f3(v: DVec3) -> [f32; 3] {
    [v.x as f32, v.y as f32, v.z as f32]
}

/// The linear part of an affine map.
fn linear(m: &DMat4) -> DMat3 {
    DMat3::from_mat4(*m)
}

/// Whether `l` is `s` times a rotation (s > 0), to a relative 1e-6.
fn similarity(l: &DMat3) -> Option<f64> {
    let s2 = (l.transpose() * *l).col(0).x;
    let e = l.transpose() * *l - DMat3::IDENTITY * s2;
    let ok = s2 > 0.0 && e.to_cols_array().iter().all(|x| x.abs() <= 1e-6 * s2);
    (ok && l.determinant() > 0.0).then(|| s2.sqrt())
}

impl<'a, 'd> Importer<'a, 'd> {
    pub fn new(doc: &'d Doc<'a>, base_dir: PathBuf) -> Self {
        Importer {
            doc,
            base_dir,
            out: SceneFile::default(),
            origin: Origin {
                format: FORMAT.into(),
                ..Origin::default()
            },
            materials: HashMap::new(),
            media: HashMap::new(),
            render: toml::Table::new(),
            integrator: None,
            sensor_seen: false,
        }
    }

    fn note(&mut self, node: Node, key: &str, how: String) {
        self.origin
            .lines
            .push((key.to_string(), self.doc.line(node)));
        self.origin.notes.push(format!(
            "line {}: <{} type=\"{}\"> -> {key}: {how}",
            self.doc.line(node),
            node.tag_name().name(),
            node.attribute("type").unwrap_or("")
        ));
    }

    /// The scene's top-level elements, in order.
    pub fn scene(&mut self, root: Node<'a, 'a>) -> Result<(), SceneError> {
        for c in root.children().filter(Node::is_element) {
            match c.tag_name().name() {
                "default" => {}
                // referenced by id where used; an unused one does not change the image
                "bsdf" | "medium" | "texture" | "phase" | "volume" | "rfilter" => {
                    if c.attribute("id").is_none() {
                        return Err(self.doc.err(c, "a top-level element needs an `id`"));
                    }
                }
                "integrator" => self.integrator(c)?,
                "sensor" => self.sensor(c)?,
                "shape" => self.shape(c)?,
                "emitter" => self.emitter(c)?,
                "include" => {
                    return Err(self
                        .doc
                        .err(c, "<include> is not supported: paste the file in"))
                }
                t => return Err(self.doc.err(c, format!("<{t}> is not supported"))),
            }
        }
        Ok(())
    }

    /// The render settings and the checks that need the whole scene.
    pub fn finish(mut self, root: Node) -> Result<(SceneFile, Origin), SceneError> {
        if !self.sensor_seen {
            return Err(self.doc.err(root, "the scene has no <sensor>"));
        }
        let (kind, node) = self.integrator.clone().unwrap_or(("path".into(), root));
        if kind == "path" && !self.out.media.is_empty() {
            return Err(self.doc.err(
                node,
                "Mitsuba's `path` integrator ignores media, but the scene has some: use `volpath`",
            ));
        }
        self.render.insert("integrator".into(), "path".into());
        self.origin
            .lines
            .push(("render".into(), self.doc.line(node)));
        self.out.render = Some(self.render);
        Ok((self.out, self.origin))
    }

    fn integrator(&mut self, node: Node<'a, 'a>) -> Result<(), SceneError> {
        let mut p = Props::new(self.doc, node)?;
        let kind = p.plugin.clone();
        if !["path", "volpath", "volpathmis"].contains(&kind.as_str()) {
            return Err(p.err(format!(
                "the integrator `{kind}` is not supported (path, volpath, volpathmis are)"
            )));
        }
        let max_depth = p.integer("max_depth")?.unwrap_or(-1);
        let rr = p.integer("rr_depth")?.unwrap_or(5);
        if p.boolean("hide_emitters")? == Some(true) {
            return Err(p.err("hide_emitters = true is not supported"));
        }
        p.finish()?;
        // Mitsuba counts path segments (1: emitters seen directly), pathspace scattering vertices
        let depth = match max_depth {
            -1 => None,
            d if d >= 1 => Some(d - 1),
            d => {
                return Err(self.doc.err(
                    node,
                    format!("max_depth = {d}: Mitsuba renders nothing below 1 (-1 is unlimited)"),
                ))
            }
        };
        if let Some(d) = depth {
            self.render
                .insert("max_depth".into(), toml::Value::Integer(d));
        }
        self.integrator = Some((kind.clone(), node));
        self.note(
            node,
            "render",
            format!(
                "pathspace's volumetric path tracer, max_depth {} (Mitsuba's {max_depth} counts segments); rr_depth {rr} not used (pathspace's own roulette, unbiased either way)",
                depth.map_or("unlimited".into(), |d| d.to_string())
            ),
        );
        Ok(())
    }

    fn sensor(&mut self, node: Node<'a, 'a>) -> Result<(), SceneError> {
        if self.sensor_seen {
            return Err(self.doc.err(node, "only one <sensor> is supported"));
        }
        self.sensor_seen = true;
        let mut p = Props::new(self.doc, node)?;
        if p.plugin != "perspective" {
            return Err(p.err(format!(
                "the sensor `{}` is not supported (perspective is)",
                p.plugin
            )));
        }
        let fov = p.float("fov")?.ok_or_else(|| p.err("`fov` is missing"))?;
        let axis = p.string("fov_axis")?.unwrap_or_else(|| "x".into());
        let m = p.transform("to_world")?.unwrap_or(DMat4::IDENTITY);
        for k in ["principal_point_offset_x", "principal_point_offset_y"] {
            if p.float(k)?.is_some_and(|x| x != 0.0) {
                return Err(p.err(format!("a nonzero {k} is not supported")));
            }
        }
        // pathspace does not clip: only Mitsuba's defaults (or wider) give the same image
        if p.float("near_clip")?.is_some_and(|x| x > 0.01) {
            return Err(p.err("a near_clip above Mitsuba's default 0.01 is not supported (pathspace does not clip)"));
        }
        // a far clip matters only inside the scene's extent, which the sensor cannot see here:
        // accepted, and `info` says it is not applied
        p.ignore(&["far_clip"]);
        let medium = match p.object("medium", None)? {
            Some(m) => Some(self.medium(m)?),
            None => None,
        };
        let film = p
            .object("film", None)?
            .ok_or_else(|| p.err("<film> is missing"))?;
        let sampler = p.object("sampler", None)?;
        p.finish()?;
        let (w, h) = self.film(film)?;
        let (spp, seed) = match sampler {
            Some(s) => self.sampler(s)?,
            None => (4, 0),
        };
        let tan = (0.5 * fov.to_radians()).tan();
        let (w64, h64) = (w as f64, h as f64);
        let tan_y = match axis.as_str() {
            "x" => tan * h64 / w64,
            "y" => tan,
            "diagonal" => tan * h64 / (w64 * w64 + h64 * h64).sqrt(),
            "smaller" if w <= h => tan * h64 / w64,
            "smaller" => tan,
            "larger" if w >= h => tan * h64 / w64,
            "larger" => tan,
            a => return Err(self.doc.err(node, format!("fov_axis = \"{a}\" is unknown"))),
        };
        let l = linear(&m);
        if similarity(&l).is_none_or(|s| (s - 1.0).abs() > 1e-6) {
            return Err(self.doc.err(
                node,
                "the sensor's to_world must be a rotation and a translation (no scale, no mirror)",
            ));
        }
        let eye = m.w_axis.truncate();
        let forward = l * DVec3::Z;
        self.out.camera = Some(CameraDesc::Pinhole {
            eye: f3(eye),
            look_at: f3(eye + forward),
            up: f3(l * DVec3::Y),
            fov_deg: (2.0 * tan_y.atan()).to_degrees() as f32,
            resolution: [w, h],
        });
        self.render.insert("spp".into(), toml::Value::Integer(spp));
        self.render
            .insert("seed".into(), toml::Value::Integer(seed));
        self.origin.camera_medium = medium.clone();
        self.note(
            node,
            "camera",
            format!(
                "pinhole, fov {fov} deg along {axis} = {:.4} deg vertical, {w}x{h}, box filter, {spp} spp, seed {seed}, in {}; no clipping (geometry nearer than Mitsuba's default near clip, 1 cm, or beyond a far_clip is rendered)",
                (2.0 * tan_y.atan()).to_degrees(),
                medium.as_deref().unwrap_or("vacuum")
            ),
        );
        Ok(())
    }

    fn film(&mut self, node: Node<'a, 'a>) -> Result<(u32, u32), SceneError> {
        let mut p = Props::new(self.doc, node)?;
        if p.plugin != "hdrfilm" {
            return Err(p.err(format!(
                "the film `{}` is not supported (hdrfilm is)",
                p.plugin
            )));
        }
        let w = p.integer("width")?.unwrap_or(768);
        let h = p.integer("height")?.unwrap_or(576);
        let filter = p.object("rfilter", None)?;
        if let Some(f) = p.string("pixel_format")? {
            if f != "rgb" && f != "rgba" {
                return Err(p.err(format!(
                    "pixel_format = \"{f}\": only rgb (or rgba) images are the same"
                )));
            }
        }
        p.ignore(&["component_format", "file_format", "sample_border"]);
        p.finish()?;
        match filter {
            Some(f) if self.doc.plugin(f)? == "box" => Props::new(self.doc, f)?.finish()?,
            Some(f) => {
                return Err(self.doc.err(
                    f,
                    "only the box filter is supported (pathspace's pixels are boxes)",
                ))
            }
            None => {
                return Err(self.doc.err(
                    node,
                    "no <rfilter>: Mitsuba's default is gaussian, pathspace's pixels are boxes; add <rfilter type=\"box\"/>",
                ))
            }
        }
        let ok = |v: i64| (1..=16384).contains(&v);
        if !(ok(w) && ok(h)) {
            return Err(self.doc.err(
                node,
                format!("{w}x{h} pixels: each side must be in 1..=16384"),
            ));
        }
        Ok((w as u32, h as u32))
    }

    fn sampler(&mut self, node: Node<'a, 'a>) -> Result<(i64, i64), SceneError> {
        let mut p = Props::new(self.doc, node)?;
        let spp = p.integer("sample_count")?.unwrap_or(4);
        let seed = p.integer("seed")?.unwrap_or(0);
        // the pattern changes the noise, not the expectation
        p.ignore(&["jitter", "scramble_seed", "dimension"]);
        p.finish()?;
        if !(1..=1 << 30).contains(&spp) || seed < 0 {
            return Err(self
                .doc
                .err(node, "sample_count must be positive and seed non-negative"));
        }
        Ok((spp, seed))
    }

    /// The material a `<bsdf>` becomes (memoized by element), `two_sided` when inside a
    /// `twosided`.
    fn material(
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
        let (desc, how) = match p.plugin.as_str() {
            "null" => {
                p.finish()?;
                return Ok("null".into());
            }
            "twosided" => {
                let inner = p.object("bsdf", None)?.ok_or_else(|| p.err("a twosided needs one <bsdf>"))?;
                p.finish()?;
                let kind = self.doc.plugin(inner)?;
                if !["diffuse", "conductor", "roughconductor", "plastic", "roughplastic"].contains(&kind.as_str()) {
                    return Err(self.doc.err(inner, format!("twosided `{kind}` is not supported (diffuse, conductor, roughconductor, plastic, roughplastic are)")));
                }
                let name = self.material(inner, Some(node.attribute("id").unwrap_or("")))?;
                self.materials.insert(node.id(), name.clone());
                return Ok(name);
            }
            "diffuse" => {
                let a = p.color("reflectance")?.unwrap_or(DVec3::splat(0.5));
                p.finish()?;
                (
                    MaterialDesc::Lambert { albedo: rgb(a), one_sided },
                    format!("lambert, albedo {}{side}", show(a)),
                )
            }
            "conductor" => {
                let r = no_named_conductor(&mut p)?;
                p.finish()?;
                (
                    MaterialDesc::Mirror { reflectance: rgb(r), one_sided },
                    format!("mirror, reflectance {}{side}", show(r)),
                )
            }
            "roughconductor" => {
                let r = rough_conductor(&mut p, one_sided, side)?;
                p.finish()?;
                r
            }
            "dielectric" | "roughdielectric" => {
                let r = dielectric(&mut p)?;
                p.finish()?;
                r
            }
            "thindielectric" => {
                let r = thin_dielectric(&mut p)?;
                p.finish()?;
                r
            }
            "plastic" => {
                let r = plastic(&mut p, one_sided, side)?;
                p.finish()?;
                r
            }
            "roughplastic" => {
                let r = rough_plastic(&mut p, one_sided, side)?;
                p.finish()?;
                r
            }
            k => {
                return Err(p.err(format!(
                    "the BSDF `{k}` is not supported (diffuse, conductor, roughconductor, dielectric, roughdielectric, thindielectric, plastic, roughplastic, twosided, null are)"
                )))
            }
        };
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
        Ok(name)
    }

    /// The medium a `<medium>` becomes (memoized by element).
    fn medium(&mut self, node: Node<'a, 'a>) -> Result<String, SceneError> {
        if let Some(name) = self.media.get(&node.id()) {
            return Ok(name.clone());
        }
        let mut p = Props::new(self.doc, node)?;
        let scale = p.float("scale")?.unwrap_or(1.0);
        let phase = match p.object("phase", None)? {
            Some(ph) => phase(self.doc, ph)?,
            None => PhaseDesc::Isotropic {},
        };
        p.ignore(&["sample_emitters", "has_spectral_extinction"]);
        let (desc, how) = match p.plugin.as_str() {
            "homogeneous" => {
                let st = p.color("sigma_t")?.unwrap_or(DVec3::ONE) * scale;
                let albedo = p.color("albedo")?.unwrap_or(DVec3::splat(0.75));
                p.finish()?;
                let (ss, sa) = (st * albedo, st * (DVec3::ONE - albedo));
                (
                    MediumDesc::Homogeneous { sigma_a: rgb(sa), sigma_s: rgb(ss), phase },
                    format!("homogeneous, sigma_s = scale sigma_t albedo = {}, sigma_a = scale sigma_t (1 - albedo) = {}", show(ss), show(sa)),
                )
            }
            "heterogeneous" => {
                let albedo = p.color("albedo")?.unwrap_or(DVec3::splat(0.75));
                let grid = p
                    .object("volume", Some("sigma_t"))?
                    .ok_or_else(|| p.err("`sigma_t` must be a <volume type=\"gridvolume\">"))?;
                p.finish()?;
                let (file, min, max) = self.gridvolume(grid)?;
                let (ss, sa) = (albedo * scale, (DVec3::ONE - albedo) * scale);
                (
                    MediumDesc::Grid {
                        sigma_a: rgb(sa),
                        sigma_s: rgb(ss),
                        phase,
                        file: file.clone(),
                        min: Some(f3(min)),
                        max: Some(f3(max)),
                        propagation: PropagationDesc::DeltaTracking,
                        step: None,
                    },
                    format!("grid `{file}` (values at cell centres: lattice {} .. {}), sigma_s = scale albedo = {}, sigma_a = {} per unit density", show(min), show(max), show(ss), show(sa)),
                )
            }
            k => {
                return Err(p.err(format!(
                    "the medium `{k}` is not supported (homogeneous, heterogeneous are)"
                )))
            }
        };
        let name = match node.attribute("id") {
            Some(id) if !self.out.media.contains_key(id) => id.to_string(),
            _ => format!("medium@{}", self.doc.line(node)),
        };
        let key = format!("media.{name}");
        self.note(node, &key, how);
        self.out.media.insert(name.clone(), desc);
        self.media.insert(node.id(), name.clone());
        Ok(name)
    }

    /// A `gridvolume`: its file and the lattice box of pathspace's grid. Mitsuba 3 puts the
    /// values at the cell centres of the unit cube mapped by `to_world` (ignoring the file's
    /// box) and clamps beyond the outer centres; pathspace's lattice spans its box, so the box
    /// is the outer centres and the grid's faces must be zero (the clamped shell then is too).
    fn gridvolume(&self, node: Node<'a, 'a>) -> Result<(String, DVec3, DVec3), SceneError> {
        let mut p = Props::new(self.doc, node)?;
        if p.plugin != "gridvolume" {
            return Err(p.err(format!(
                "the volume `{}` is not supported (gridvolume is)",
                p.plugin
            )));
        }
        let file = p
            .string("filename")?
            .ok_or_else(|| p.err("`filename` is missing"))?;
        let m = p.transform("to_world")?.unwrap_or(DMat4::IDENTITY);
        if p.string("filter_type")?.is_some_and(|f| f != "trilinear") {
            return Err(p.err("only filter_type = \"trilinear\" is supported"));
        }
        if p.string("wrap_mode")?.is_some_and(|f| f != "clamp") {
            return Err(p.err("only wrap_mode = \"clamp\" is supported"));
        }
        if p.boolean("use_grid_bbox")? == Some(true) {
            return Err(p.err("use_grid_bbox = true is not supported"));
        }
        p.ignore(&["raw", "accel"]);
        p.finish()?;
        let l = linear(&m);
        let diag = DVec3::new(l.x_axis.x, l.y_axis.y, l.z_axis.z);
        if l != DMat3::from_diagonal(diag) || diag.min_element() <= 0.0 {
            return Err(self.doc.err(node, "the grid's to_world must be a positive scale and a translation (pathspace's grids are axis-aligned)"));
        }
        let path = self.base_dir.join(&file);
        let g = crate::medium::grid::read_grid_file(&path)
            .map_err(|e| self.doc.err(node, e.to_string()))?
            .grid;
        if !faces_are_zero(&g) {
            return Err(self.doc.err(node, format!("`{file}` is not zero on its faces: Mitsuba 3 holds the outer values over the last half cell, pathspace's lattice ends there; pad the grid with zeros")));
        }
        let res = DVec3::new(g.res[0] as f64, g.res[1] as f64, g.res[2] as f64);
        let lo = (DVec3::splat(0.5) / res) * diag + m.w_axis.truncate();
        let hi = (DVec3::ONE - DVec3::splat(0.5) / res) * diag + m.w_axis.truncate();
        Ok((file, lo, hi))
    }

    /// The media of a shape (`interior`, `exterior`).
    fn shape_media(&mut self, p: &mut Props<'a, 'd>) -> Result<[Option<String>; 2], SceneError> {
        let mut out = [None, None];
        for (k, side) in ["interior", "exterior"].into_iter().enumerate() {
            if let Some(m) = p.object("medium", Some(side))? {
                out[k] = Some(self.medium(m)?);
            }
        }
        Ok(out)
    }

    fn shape(&mut self, node: Node<'a, 'a>) -> Result<(), SceneError> {
        let mut p = Props::new(self.doc, node)?;
        let m = p.transform("to_world")?.unwrap_or(DMat4::IDENTITY);
        let flip = p.boolean("flip_normals")? == Some(true);
        if flip && !matches!(p.plugin.as_str(), "rectangle" | "disk") {
            return Err(p.err("flip_normals is supported on rectangles and disks only"));
        }
        let [interior, exterior] = self.shape_media(&mut p)?;
        let bsdf = p.object("bsdf", None)?;
        let emitter = p.object("emitter", None)?;
        if linear(&m).determinant() <= 0.0 {
            return Err(p.err("a to_world with a mirror or a zero scale is not supported"));
        }
        let (geometry, how) = geometry(&mut p, &m, flip)?;
        p.finish()?;
        let (material, emission) = self.surface(bsdf, emitter)?;
        self.push_shape(node, geometry, how, material, emission, interior, exterior)
    }

    /// A shape's material and emission, as Mitsuba makes them: an emitter without a BSDF (or
    /// with a black diffuse) is black, a shape without either a one-sided diffuse of 0.5.
    fn surface(
        &mut self,
        bsdf: Option<Node<'a, 'a>>,
        emitter: Option<Node<'a, 'a>>,
    ) -> Result<(Option<String>, Option<RgbValue>), SceneError> {
        let emission = match emitter {
            Some(e) => Some(self.area(e)?),
            None => None,
        };
        let known = self.materials.len();
        let material = match bsdf {
            Some(b) => self.material(b, None)?,
            // Mitsuba's emitter without a BSDF is black (a black diffuse), as pathspace's
            None if emission.is_some() => return Ok((None, emission)),
            None => self.default_material(),
        };
        // a black diffuse emitter is an emitter without a material
        let black = matches!(self.out.materials.get(&material), Some(MaterialDesc::Lambert { albedo, .. }) if albedo.to_rgb() == glam::Vec3::ZERO);
        let material = if emission.is_some() && black {
            if self.materials.len() > known {
                // made for this shape alone: not part of the scene
                self.out.materials.remove(&material);
                self.materials.retain(|_, m| *m != material);
            }
            None
        } else {
            Some(material)
        };
        Ok((material, emission))
    }

    /// Adds a translated shape with the keys every shape shares.
    #[allow(clippy::too_many_arguments)]
    fn push_shape(
        &mut self,
        node: Node<'a, 'a>,
        geometry: ShapeDesc,
        how: String,
        material: Option<String>,
        emission: Option<RgbValue>,
        interior: Option<String>,
        exterior: Option<String>,
    ) -> Result<(), SceneError> {
        let i = self.out.shapes.len();
        let how = format!(
            "{how}, material {}{}{}{}",
            material.as_deref().unwrap_or("none (black emitter)"),
            emission.map_or(String::new(), |e| format!(", emission {e}")),
            interior
                .as_ref()
                .map_or(String::new(), |m| format!(", interior {m}")),
            exterior
                .as_ref()
                .map_or(String::new(), |m| format!(", exterior {m}")),
        );
        self.out.shapes.push(with_common(
            geometry, material, emission, interior, exterior,
        ));
        self.note(node, &format!("shapes[{i}]"), how);
        Ok(())
    }

    /// Mitsuba gives a shape without a BSDF (and without an emitter) a one-sided diffuse of
    /// reflectance 0.5.
    fn default_material(&mut self) -> String {
        let name = "default diffuse".to_string();
        self.out
            .materials
            .entry(name.clone())
            .or_insert(MaterialDesc::Lambert {
                albedo: RgbValue::Scalar(0.5),
                one_sided: true,
            });
        name
    }

    /// An `area` emitter's radiance.
    fn area(&mut self, node: Node<'a, 'a>) -> Result<RgbValue, SceneError> {
        let mut p = Props::new(self.doc, node)?;
        if p.plugin != "area" {
            return Err(p.err(format!(
                "the emitter `{}` on a shape is not supported (area is)",
                p.plugin
            )));
        }
        let r = p.color("radiance")?.unwrap_or(DVec3::ONE);
        p.finish()?;
        Ok(rgb(r))
    }

    /// A top-level emitter.
    fn emitter(&mut self, node: Node<'a, 'a>) -> Result<(), SceneError> {
        let mut p = Props::new(self.doc, node)?;
        let m = p.transform("to_world")?;
        let (light, how) = match p.plugin.as_str() {
            "point" => point(&mut p, m)?,
            "spot" => spot(&mut p, m.unwrap_or(DMat4::IDENTITY))?,
            "directional" => directional(&mut p, m)?,
            "constant" if m.is_none() => {
                let r = p.color("radiance")?.unwrap_or(DVec3::ONE);
                let (zenith, horizon, nadir) = (None, None, None);
                let radiance = Some(rgb(r));
                let env = LightDesc::Environment {
                    radiance,
                    zenith,
                    horizon,
                    nadir,
                    map: None,
                    scale: None,
                    to_world: None,
                    sampling: None,
                };
                (env, format!("constant environment, radiance {}", show(r)))
            }
            "constant" => return Err(p.err("a constant emitter takes no to_world")),
            "envmap" => envmap(&mut p, m)?,
            "area" => return Err(p.err("an `area` emitter belongs inside a <shape>")),
            k => {
                return Err(p.err(format!(
                "the emitter `{k}` is not supported (area, point, spot, directional, constant are)"
            )))
            }
        };
        p.finish()?;
        let i = self.out.lights.len();
        self.out.lights.push(light);
        self.note(node, &format!("lights[{i}]"), how);
        Ok(())
    }
}

/// A light and its note.
type Lighting = Result<(LightDesc, String), SceneError>;

/// `envmap`: a lat-long EXR (`filename`, relative to the XML file) times `scale`, turned by
/// the rotation `to_world` (the mapping is Mitsuba's; pathspace looks texels up without
/// Mitsuba's bilinear interpolation).
fn envmap(p: &mut Props, m: Option<DMat4>) -> Lighting {
    let map = p
        .string("filename")?
        .ok_or_else(|| p.err("`filename` is missing"))?;
    let scale = p.float("scale")?.map(|x| x as f32);
    let to_world = match m {
        None => None,
        Some(m) if m.w_axis.truncate() != DVec3::ZERO => return Err(p.err(
            "an envmap's to_world must be a rotation (a translation has no meaning at infinity)",
        )),
        Some(m) => Some([0, 1, 2].map(|i| m.row(i).truncate().to_array().map(|x| x as f32))),
    };
    let how = format!(
        "environment map `{map}`, scale {}, sampled by luminance, texels looked up without interpolation",
        scale.unwrap_or(1.0)
    );
    let light = LightDesc::Environment {
        radiance: None,
        zenith: None,
        horizon: None,
        nadir: None,
        map: Some(map),
        scale,
        to_world,
        sampling: None,
    };
    Ok((light, how))
}

/// `point`: at `position` or the origin of `to_world`, `intensity` in W/sr.
fn point(p: &mut Props, m: Option<DMat4>) -> Lighting {
    let pos = match (p.point("position")?, m) {
        (Some(x), None) => x,
        (None, Some(m)) => m.w_axis.truncate(),
        (None, None) => DVec3::ZERO,
        (Some(_), Some(_)) => return Err(p.err("give `position` or `to_world`, not both")),
    };
    let i = p.color("intensity")?.unwrap_or(DVec3::ONE);
    let how = format!("point light at {}, intensity {} W/sr", show(pos), show(i));
    let (position, intensity) = (f3(pos), rgb(i));
    Ok((
        LightDesc::Point {
            position,
            intensity,
        },
        how,
    ))
}

/// `spot`: along local +z of `to_world`; only the hard cone (`beam_width` = `cutoff_angle`)
/// is the same light in both renderers.
fn spot(p: &mut Props, m: DMat4) -> Lighting {
    let i = p.color("intensity")?.unwrap_or(DVec3::ONE);
    let cutoff = p.float("cutoff_angle")?.unwrap_or(20.0);
    let beam = p.float("beam_width")?.unwrap_or(0.75 * cutoff);
    if beam != cutoff {
        return Err(p.err(format!("beam_width {beam} differs from cutoff_angle {cutoff}: Mitsuba's falloff is linear in the angle, pathspace's a smoothstep in the cosine; set beam_width = cutoff_angle for a hard cone")));
    }
    let (pos, dir) = (m.w_axis.truncate(), linear(&m) * DVec3::Z);
    let how = format!(
        "spot light at {} along {}, intensity {} W/sr, hard cone {cutoff} deg",
        show(pos),
        show(dir),
        show(i)
    );
    let (position, direction, intensity) = (f3(pos), f3(dir), rgb(i));
    let (cone_deg, falloff_deg) = (cutoff as f32, 0.0);
    let light = LightDesc::Spot {
        position,
        direction,
        intensity,
        cone_deg,
        falloff_deg,
    };
    Ok((light, how))
}

/// `directional`: light travelling along `direction` (or local +z of `to_world`).
fn directional(p: &mut Props, m: Option<DMat4>) -> Lighting {
    let dir = match (p.point("direction")?, m) {
        (Some(d), None) => d,
        (None, Some(m)) => linear(&m) * DVec3::Z,
        (None, None) => DVec3::Z,
        (Some(_), Some(_)) => return Err(p.err("give `direction` or `to_world`, not both")),
    };
    let e = p.color("irradiance")?.unwrap_or(DVec3::ONE);
    let how = format!(
        "directional light along {}, irradiance {}",
        show(dir),
        show(e)
    );
    let (direction, irradiance) = (f3(dir), rgb(e));
    Ok((
        LightDesc::Directional {
            direction,
            irradiance,
        },
        how,
    ))
}

/// A shape's geometry and its note.
type Geometry = Result<(ShapeDesc, String), SceneError>;

/// The geometry of a shape plugin under `m` (already checked not to mirror); the keys every
/// shape shares are filled in later (`with_common`).
fn geometry(p: &mut Props, m: &DMat4, flip: bool) -> Geometry {
    match p.plugin.as_str() {
        "rectangle" => Ok(rectangle(m, flip)),
        "disk" => Ok(disk(m, flip)),
        "cube" => cube(p, m),
        "sphere" => sphere(p, m),
        "obj" | "ply" => mesh(p, m),
        k => Err(p.err(format!(
            "the shape `{k}` is not supported (rectangle, disk, cube, sphere, obj, ply are)"
        ))),
    }
}

/// A planar shape's origin and edge vectors: the local point `o` and the local axes x and y
/// scaled by `edge`, mapped by `m` (u and v swapped to flip the normal u x v), and the note.
fn planar(m: &DMat4, flip: bool, o: DVec3, edge: f64, what: &str) -> ([[f32; 3]; 3], String) {
    let l = linear(m);
    let o = m.transform_point3(o);
    let (u, v) = (l * (edge * DVec3::X), l * (edge * DVec3::Y));
    let (u, v) = if flip { (v, u) } else { (u, v) };
    let how = format!(
        "at {}, u {}, v {} ({what} at z = 0 mapped, normal u x v{})",
        show(o),
        show(u),
        show(v),
        if flip { ", flipped" } else { "" }
    );
    ([f3(o), f3(u), f3(v)], how)
}

/// `rectangle`: [-1,1]^2 at z = 0 with normal +z, mapped (u and v swapped to flip the normal).
fn rectangle(m: &DMat4, flip: bool) -> (ShapeDesc, String) {
    let ([origin, u, v], how) = planar(m, flip, DVec3::new(-1.0, -1.0, 0.0), 2.0, "[-1,1]^2");
    let (material, emission, interior, exterior) = (None, None, None, None);
    let quad = ShapeDesc::Quad {
        origin,
        u,
        v,
        material,
        emission,
        interior,
        exterior,
    };
    (quad, format!("quad {how}"))
}

/// `disk`: the unit disk at z = 0 with normal +z, mapped (u and v swapped to flip the normal).
fn disk(m: &DMat4, flip: bool) -> (ShapeDesc, String) {
    let ([center, u, v], how) = planar(m, flip, DVec3::ZERO, 1.0, "unit disk");
    let (material, emission, interior, exterior) = (None, None, None, None);
    let disk = ShapeDesc::Disk {
        center,
        u,
        v,
        material,
        emission,
        interior,
        exterior,
    };
    (disk, format!("disk {how}"))
}

/// `cube`: [-1,1]^3 under a scale and a translation (pathspace's boxes are axis-aligned).
fn cube(p: &mut Props, m: &DMat4) -> Geometry {
    let l = linear(m);
    let diag = DVec3::new(l.x_axis.x, l.y_axis.y, l.z_axis.z);
    if l != DMat3::from_diagonal(diag) {
        return Err(p.err("a rotated cube is not supported (pathspace's boxes are axis-aligned)"));
    }
    let t = m.w_axis.truncate();
    let (lo, hi) = (t - diag, t + diag);
    let how = format!(
        "box {} .. {} ([-1,1]^3 mapped, normals outwards)",
        show(lo),
        show(hi)
    );
    let (min, max) = (f3(lo), f3(hi));
    let (material, emission, interior, exterior) = (None, None, None, None);
    Ok((
        ShapeDesc::Box {
            min,
            max,
            material,
            emission,
            interior,
            exterior,
        },
        how,
    ))
}

/// `sphere`: `center` and `radius` under a uniform scale, a rotation and a translation.
fn sphere(p: &mut Props, m: &DMat4) -> Geometry {
    let c = p.point("center")?.unwrap_or(DVec3::ZERO);
    let r = p.float("radius")?.unwrap_or(1.0);
    let s = similarity(&linear(m)).ok_or_else(|| {
        p.err("a sphere's to_world must be a uniform scale, a rotation and a translation")
    })?;
    let (c, r) = (m.transform_point3(c), r * s);
    let how = format!("sphere at {}, radius {r}", show(c));
    let (center, radius) = (f3(c), r as f32);
    let (material, emission, interior, exterior) = (None, None, None, None);
    Ok((
        ShapeDesc::Sphere {
            center,
            radius,
            material,
            emission,
            interior,
            exterior,
        },
        how,
    ))
}

/// `obj` and `ply`: the file under `to_world`, with face normals only.
fn mesh(p: &mut Props, m: &DMat4) -> Geometry {
    let obj = p
        .string("filename")?
        .ok_or_else(|| p.err("`filename` is missing"))?;
    if p.boolean("face_normals")? != Some(true) {
        return Err(p.err("Mitsuba interpolates vertex normals unless face_normals = true, pathspace has geometric normals only: add <boolean name=\"face_normals\" value=\"true\"/>"));
    }
    p.ignore(&["flip_tex_coords"]);
    let rows = [0, 1, 2].map(|i| m.row(i).to_array().map(|x| x as f32));
    let to_world = (*m != DMat4::IDENTITY).then_some(rows);
    let how = format!("mesh `{obj}`, flat (face normals)");
    let (material, emission, interior, exterior) = (None, None, None, None);
    Ok((
        ShapeDesc::Mesh {
            obj,
            to_world,
            material,
            emission,
            interior,
            exterior,
        },
        how,
    ))
}

/// `roughconductor`: GGX with a complex index (`eta`, `k`) or Mitsuba's `none` (a Fresnel term
/// of 1, exactly pathspace's reflectance 1).
fn rough_conductor(
    p: &mut Props,
    one_sided: bool,
    side: &str,
) -> Result<(MaterialDesc, String), SceneError> {
    let (distribution, alpha) = microfacet(p)?;
    let eta = p.color("eta")?;
    let k = p.color("k")?;
    let r = no_named_conductor(p)?;
    let (eta, k, how) = match (eta, k) {
        (Some(e), Some(k)) if r == DVec3::ONE => (Some(rgb(e)), Some(rgb(k)), format!("eta {}, k {}", show(e), show(k))),
        (None, None) if r == DVec3::ONE => (None, None, "reflectance 1 (material none)".into()),
        (None, None) => return Err(p.err("specular_reflectance other than 1 with material none: Mitsuba scales a Fresnel term of 1, pathspace's `reflectance` is Schlick's F0; give eta and k instead")),
        (Some(_), Some(_)) => return Err(p.err("specular_reflectance other than 1 with eta and k is not supported")),
        _ => return Err(p.err("give both eta and k")),
    };
    Ok((
        MaterialDesc::RoughConductor {
            alpha: alpha as f32,
            distribution,
            reflectance: None,
            eta,
            k,
            one_sided,
        },
        format!(
            "rough conductor ({}), alpha {alpha}, {how}{side}",
            dist_name(distribution)
        ),
    ))
}

/// `dielectric` and `roughdielectric`: pathspace's `ior` is `int_ior / ext_ior`.
fn dielectric(p: &mut Props) -> Result<(MaterialDesc, String), SceneError> {
    let rough = p.plugin == "roughdielectric";
    let alpha = if rough { Some(microfacet(p)?) } else { None };
    let ior = ior(p, "int_ior", 1.5046)? / ior(p, "ext_ior", 1.000277)?;
    for k in ["specular_reflectance", "specular_transmittance"] {
        if p.color(k)?.is_some_and(|c| c != DVec3::ONE) {
            return Err(p.err(format!("{k} other than 1 is not supported")));
        }
    }
    Ok(match alpha {
        None => (
            MaterialDesc::Dielectric { ior: ior as f32 },
            format!("dielectric, ior {ior} (int_ior / ext_ior)"),
        ),
        Some((d, a)) => (
            MaterialDesc::RoughDielectric {
                ior: ior as f32,
                alpha: a as f32,
                distribution: d,
            },
            format!(
                "rough dielectric ({}), ior {ior} (int_ior / ext_ior), alpha {a}",
                dist_name(d)
            ),
        ),
    })
}

/// `thindielectric`: `ior` = int_ior / ext_ior (defaults bk7 and air), as `dielectric`.
fn thin_dielectric(p: &mut Props) -> Result<(MaterialDesc, String), SceneError> {
    let ior = ior(p, "int_ior", 1.5046)? / ior(p, "ext_ior", 1.000277)?;
    for k in ["specular_reflectance", "specular_transmittance"] {
        if p.color(k)?.is_some_and(|c| c != DVec3::ONE) {
            return Err(p.err(format!("{k} other than 1 is not supported")));
        }
    }
    Ok((
        MaterialDesc::ThinDielectric { ior: ior as f32 },
        format!("thin dielectric, ior {ior} (int_ior / ext_ior)"),
    ))
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
    let d = p.color("diffuse_reflectance")?.unwrap_or(DVec3::splat(0.5));
    let s = p.color("specular_reflectance")?.unwrap_or(DVec3::ONE);
    let nonlinear = p.boolean("nonlinear")?.unwrap_or(false);
    Ok((
        MaterialDesc::Plastic {
            diffuse: rgb(d),
            specular: rgb(s),
            ior: Some(ior as f32),
            nonlinear,
            one_sided,
        },
        format!(
            "plastic, diffuse {}, specular {}, ior {ior} (int_ior / ext_ior){}{side}",
            show(d),
            show(s),
            if nonlinear { ", nonlinear" } else { "" }
        ),
    ))
}

/// A conductor's `material` must be `none` (no tabulated spectra); its reflectance.
fn no_named_conductor(p: &mut Props) -> Result<DVec3, SceneError> {
    if let Some(m) = p.string("material")? {
        if m != "none" {
            return Err(p.err(format!(
                "material = \"{m}\": tabulated conductor spectra are not imported; give eta and k as <rgb>"
            )));
        }
    }
    if p.plugin == "conductor" && (p.color("eta")?.is_some() || p.color("k")?.is_some()) {
        return Err(p.err("a smooth conductor with eta and k is not supported: pathspace's mirror has a constant reflectance"));
    }
    Ok(p.color("specular_reflectance")?.unwrap_or(DVec3::ONE))
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

/// The microfacet model of a rough plugin: `distribution` (Mitsuba's default beckmann, or
/// ggx) and one isotropic `alpha` (default 0.1).
fn microfacet(p: &mut Props) -> Result<(DistributionDesc, f64), SceneError> {
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
    if p.float("alpha_u")?.is_some() || p.float("alpha_v")?.is_some() {
        return Err(p.err("anisotropic roughness (alpha_u, alpha_v) is not supported"));
    }
    // only the sampler depends on it, not the BSDF
    p.ignore(&["sample_visible"]);
    Ok((d, p.float("alpha")?.unwrap_or(0.1)))
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
    let (int_ior, ext_ior) = (ior(p, "int_ior", 1.49)?, ior(p, "ext_ior", 1.000277)?);
    if !(int_ior > 0.0 && ext_ior > 0.0) || int_ior == ext_ior {
        return Err(p.err("int_ior and ext_ior must be positive and differ"));
    }
    let ior = int_ior / ext_ior;
    let diffuse = p.color("diffuse_reflectance")?.unwrap_or(DVec3::splat(0.5));
    let specular = p.color("specular_reflectance")?.unwrap_or(DVec3::ONE);
    let nonlinear = p.boolean("nonlinear")?.unwrap_or(false);
    Ok((
        MaterialDesc::RoughPlastic {
            diffuse: rgb(diffuse),
            specular: rgb(specular),
            alpha: alpha as f32,
            distribution,
            ior: ior as f32,
            nonlinear,
            one_sided,
        },
        format!(
            "rough plastic ({}), alpha {alpha}, ior {ior} (int_ior / ext_ior), diffuse {}, specular {}{}{side}",
            dist_name(distribution),
            show(diffuse),
            show(specular),
            if nonlinear { ", nonlinear" } else { "" }
        ),
    ))
}

fn phase(doc: &Doc, node: Node) -> Result<PhaseDesc, SceneError> {
    let mut p = Props::new(doc, node)?;
    let ph = match p.plugin.as_str() {
        "isotropic" => PhaseDesc::Isotropic {},
        // Mitsuba's g > 0 scatters forwards, as pathspace's
        "hg" => PhaseDesc::Hg {
            g: p.float("g")?.unwrap_or(0.8) as f32,
        },
        k => {
            return Err(p.err(format!(
                "the phase function `{k}` is not supported (isotropic, hg are)"
            )))
        }
    };
    p.finish()?;
    Ok(ph)
}

/// Whether every value on the six faces of the lattice is zero.
fn faces_are_zero(g: &crate::medium::grid::Grid) -> bool {
    let [nx, ny, nz] = g.res;
    (0..nz).all(|z| {
        (0..ny).all(|y| {
            (0..nx).all(|x| {
                let face = x == 0 || y == 0 || z == 0 || x == nx - 1 || y == ny - 1 || z == nz - 1;
                !face || g.values[x + nx * (y + ny * z)] == 0.0
            })
        })
    })
}

/// `geometry` with the keys every shape shares.
fn with_common(
    geometry: ShapeDesc,
    material: Option<String>,
    emission: Option<RgbValue>,
    interior: Option<String>,
    exterior: Option<String>,
) -> ShapeDesc {
    let mut s = geometry;
    match &mut s {
        ShapeDesc::Quad {
            material: m,
            emission: e,
            interior: i,
            exterior: x,
            ..
        }
        | ShapeDesc::Box {
            material: m,
            emission: e,
            interior: i,
            exterior: x,
            ..
        }
        | ShapeDesc::Sphere {
            material: m,
            emission: e,
            interior: i,
            exterior: x,
            ..
        }
        | ShapeDesc::Disk {
            material: m,
            emission: e,
            interior: i,
            exterior: x,
            ..
        }
        | ShapeDesc::Mesh {
            material: m,
            emission: e,
            interior: i,
            exterior: x,
            ..
        } => {
            (*m, *e, *i, *x) = (material, emission, interior, exterior);
        }
    }
    s
}
