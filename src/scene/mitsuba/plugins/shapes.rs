//! The shapes `rectangle`, `disk`, `cube`, `sphere`, `cylinder`, `obj`, `ply` and `serialized`, with their media, BSDF
//! and area emitter, and the default material of a shape without either.

use glam::{DMat3, DMat4, DVec3};
use roxmltree::Node;

use super::{f3, linear, show, similarity, Importer, Props};
use crate::scene::file::{
    EmissionValue, MaterialDesc, MeshFormat, ReflectanceValue, RgbValue, ShapeDesc,
};
use crate::scene::SceneError;

impl<'a, 'd> Importer<'a, 'd> {
    /// The media of a shape (`interior`, `exterior`).
    pub(super) fn shape_media(
        &mut self,
        p: &mut Props<'a, 'd>,
    ) -> Result<[Option<String>; 2], SceneError> {
        let mut out = [None, None];
        for (k, side) in ["interior", "exterior"].into_iter().enumerate() {
            if let Some(m) = p.object("medium", Some(side))? {
                out[k] = Some(self.medium(m)?);
            }
        }
        Ok(out)
    }

    pub(super) fn shape(&mut self, node: Node<'a, 'a>) -> Result<(), SceneError> {
        let mut p = Props::new(self.doc, node)?;
        let m = p.transform("to_world")?.unwrap_or(DMat4::IDENTITY);
        let flip = p.boolean("flip_normals")? == Some(true);
        let flippable = ["rectangle", "disk", "cylinder", "obj", "ply", "serialized"];
        if flip && !flippable.contains(&p.plugin.as_str()) {
            return Err(p.err(
                "flip_normals is supported on rectangles, disks, cylinders and meshes (obj, ply, serialized) only",
            ));
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
    pub(super) fn surface(
        &mut self,
        bsdf: Option<Node<'a, 'a>>,
        emitter: Option<Node<'a, 'a>>,
    ) -> Result<(Option<String>, Option<EmissionValue>), SceneError> {
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
        let black = matches!(self.out.materials.get(&material), Some(MaterialDesc::Lambert { albedo: ReflectanceValue::Value(albedo), .. }) if albedo.to_rgb() == glam::Vec3::ZERO);
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
    pub(super) fn push_shape(
        &mut self,
        node: Node<'a, 'a>,
        geometry: ShapeDesc,
        how: String,
        material: Option<String>,
        emission: Option<EmissionValue>,
        interior: Option<String>,
        exterior: Option<String>,
    ) -> Result<(), SceneError> {
        let i = self.out.shapes.len();
        let how = format!(
            "{how}, material {}{}{}{}",
            material.as_deref().unwrap_or("none (black emitter)"),
            emission
                .as_ref()
                .map_or(String::new(), |e| format!(", emission {e}")),
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
    pub(super) fn default_material(&mut self) -> String {
        let name = "default diffuse".to_string();
        self.out
            .materials
            .entry(name.clone())
            .or_insert(MaterialDesc::Lambert {
                albedo: RgbValue::Scalar(0.5).into(),
                one_sided: true,
            });
        name
    }
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
        "obj" | "ply" | "serialized" => mesh(p, m, flip),
        "cylinder" => cylinder(p, m, flip),
        k => Err(p.err(format!(
            "the shape `{k}` is not supported (rectangle, disk, cube, sphere, cylinder, obj, ply, serialized are)"
        ))),
    }
}

/// A planar shape's origin and edge vectors: the local point `o` and the local axes x and y
/// scaled by `edge`, mapped by `m`, and the note. Mitsuba 3's `flip_normals` mirrors the local
/// z only, so the axes (and the shape's (u, v)) stay and the normal is `-(u x v)`.
fn planar(m: &DMat4, flip: bool, o: DVec3, edge: f64, what: &str) -> ([[f32; 3]; 3], String) {
    let l = linear(m);
    let o = m.transform_point3(o);
    let (u, v) = (l * (edge * DVec3::X), l * (edge * DVec3::Y));
    let how = format!(
        "at {}, u {}, v {} ({what} at z = 0 mapped, normal {}u x v)",
        show(o),
        show(u),
        show(v),
        if flip { "-" } else { "" }
    );
    ([f3(o), f3(u), f3(v)], how)
}

/// `rectangle`: [-1,1]^2 at z = 0 with normal +z, mapped.
fn rectangle(m: &DMat4, flip: bool) -> (ShapeDesc, String) {
    let ([origin, u, v], how) = planar(m, flip, DVec3::new(-1.0, -1.0, 0.0), 2.0, "[-1,1]^2");
    let (material, emission, interior, exterior) = (None, None, None, None);
    let quad = ShapeDesc::Quad {
        origin,
        u,
        v,
        flip_normals: flip,
        material,
        emission,
        interior,
        exterior,
    };
    (quad, format!("quad {how}"))
}

/// `disk`: the unit disk at z = 0 with normal +z, mapped.
fn disk(m: &DMat4, flip: bool) -> (ShapeDesc, String) {
    let ([center, u, v], how) = planar(m, flip, DVec3::ZERO, 1.0, "unit disk");
    let (material, emission, interior, exterior) = (None, None, None, None);
    let disk = ShapeDesc::Disk {
        center,
        u,
        v,
        flip_normals: flip,
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
    // the rotation's images of x and z: Mitsuba measures (u, v) in the sphere's own frame
    let l = linear(m) / s;
    let (x, z) = (l.x_axis, l.z_axis);
    let rotated =
        (x - DVec3::X).abs().max_element() > 1e-9 || (z - DVec3::Z).abs().max_element() > 1e-9;
    let how = format!(
        "sphere at {}, radius {r}{}",
        show(c),
        if rotated {
            format!(", axes x {} and z {}", show(x), show(z))
        } else {
            String::new()
        }
    );
    let (center, radius) = (f3(c), r as f32);
    let (x_axis, z_axis) = if rotated {
        (Some(f3(x + DVec3::ZERO)), Some(f3(z + DVec3::ZERO)))
    } else {
        (None, None)
    };
    let (material, emission, interior, exterior) = (None, None, None, None);
    Ok((
        ShapeDesc::Sphere {
            center,
            radius,
            x_axis,
            z_axis,
            material,
            emission,
            interior,
            exterior,
        },
        how,
    ))
}

/// `cylinder`: `p0` (0,0,0), `p1` (0,0,1), `radius` (1) under `to_world`, which must map the
/// circle about the axis to a circle (a uniform scale across the axis, any scale along it, no
/// shear): Mitsuba warns and keeps only a part of other maps.
fn cylinder(p: &mut Props, m: &DMat4, flip: bool) -> Geometry {
    let a = p.point("p0")?.unwrap_or(DVec3::ZERO);
    let b = p.point("p1")?.unwrap_or(DVec3::Z);
    let r = p.float("radius")?.unwrap_or(1.0);
    let d = b - a;
    if !(r > 0.0 && d.length() > 0.0) {
        return Err(p.err("a cylinder needs a positive radius and p1 apart from p0"));
    }
    let l = linear(m);
    // Mitsuba's frame about the axis (`Frame3f(d)`), whose image under `to_world` is where the
    // cylinder's phi starts
    let (e0, e1) = coordinate_system(d.normalize());
    let (c0, c1, c2) = (l * e0, l * e1, l * d);
    let s2 = c0.length_squared();
    let tol = 1e-6 * s2;
    let round = (c1.length_squared() - s2).abs() <= tol
        && c0.dot(c1).abs() <= tol
        && c2.dot(c0).abs() <= 1e-6 * (s2 * c2.length_squared()).sqrt()
        && c2.dot(c1).abs() <= 1e-6 * (s2 * c2.length_squared()).sqrt();
    if !round {
        return Err(p.err(
            "a cylinder's to_world must keep it round: a uniform scale across its axis, no shear",
        ));
    }
    let (a, b, r) = (m.transform_point3(a), m.transform_point3(b), r * s2.sqrt());
    let how = format!(
        "cylinder from {} to {}, radius {r}, open ends, normals {}",
        show(a),
        show(b),
        if flip { "inwards" } else { "outwards" }
    );
    let (material, emission, interior, exterior) = (None, None, None, None);
    Ok((
        ShapeDesc::Cylinder {
            p0: f3(a),
            p1: f3(b),
            radius: r as f32,
            flip_normals: flip,
            // (+ 0 writes a negative zero as 0)
            x_axis: Some(f3(c0.normalize() + DVec3::ZERO)),
            material,
            emission,
            interior,
            exterior,
        },
        how,
    ))
}

/// Mitsuba 3's `coordinate_system(n)` (`include/mitsuba/core/vector.h`; Duff et al. 2017,
/// "Building an orthonormal basis, revisited"): the s and t of its `Frame3f(n)`.
fn coordinate_system(n: DVec3) -> (DVec3, DVec3) {
    let sign = 1f64.copysign(n.z);
    let a = -1.0 / (sign + n.z);
    let b = n.x * n.y * a;
    (
        DVec3::new(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x),
        DVec3::new(b, sign + n.y * n.y * a, -n.y),
    )
}

/// `obj`, `ply` and `serialized`: the file under `to_world`, read by the plugin whatever the
/// file's name, shaded with interpolated vertex normals unless `face_normals` is true, both
/// normals negated with `flip_normals` (Mitsuba 3 documentation, plugins `obj`, `ply` and
/// `serialized`); a serialized file's shape `shape_index` (0), its texture coordinates as
/// stored (the plugin has no `flip_tex_coords`).
fn mesh(p: &mut Props, m: &DMat4, flip_normals: bool) -> Geometry {
    let obj = p
        .string("filename")?
        .ok_or_else(|| p.err("`filename` is missing"))?;
    let smooth_normals = p.boolean("face_normals")? != Some(true);
    let serialized = p.plugin == "serialized";
    let (flip_tex_coords, shape_index) = if serialized {
        let k = p.integer("shape_index")?.unwrap_or(0);
        let k = u32::try_from(k)
            .map_err(|_| p.err(format!("shape_index {k} must be a non-negative index")))?;
        (None, Some(k))
    } else {
        (p.boolean("flip_tex_coords")?, None)
    };
    let ext = std::path::Path::new(&obj)
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    let by_name = match ext.as_deref() {
        Some("ply") => MeshFormat::Ply,
        Some("serialized") => MeshFormat::Serialized,
        _ => MeshFormat::Obj,
    };
    let plugin = match p.plugin.as_str() {
        "ply" => MeshFormat::Ply,
        "serialized" => MeshFormat::Serialized,
        _ => MeshFormat::Obj,
    };
    // Mitsuba reads the file as its plugin says: the format is written only where the name
    // would say otherwise
    let format = (by_name != plugin).then_some(plugin);
    let rows = [0, 1, 2].map(|i| m.row(i).to_array().map(|x| x as f32));
    let to_world = (*m != DMat4::IDENTITY).then_some(rows);
    let which = shape_index.map_or(String::new(), |k| format!(" shape {k}"));
    let read = format.map_or(String::new(), |_| format!(" read as {}", p.plugin));
    let how = if smooth_normals {
        format!("mesh `{obj}`{read}{which}, smooth (interpolated vertex normals)")
    } else {
        format!("mesh `{obj}`{read}{which}, flat (face normals)")
    };
    let how = if flip_normals {
        format!("{how}, normals flipped")
    } else {
        how
    };
    let (material, emission, interior, exterior) = (None, None, None, None);
    Ok((
        ShapeDesc::Mesh {
            obj,
            format,
            to_world,
            smooth_normals,
            flip_tex_coords,
            shape_index,
            flip_normals,
            material,
            emission,
            interior,
            exterior,
        },
        how,
    ))
}

/// `geometry` with the keys every shape shares.
fn with_common(
    geometry: ShapeDesc,
    material: Option<String>,
    emission: Option<EmissionValue>,
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
        | ShapeDesc::Cylinder {
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
