//! `[[shapes]]`: quads, boxes, spheres and OBJ meshes with their material, emission and media;
//! emitting shapes become area lights. A shape that holds a medium must be closed.

use glam::{Vec2, Vec3};
use std::collections::{BTreeMap, HashMap};

use super::materials::Materials;
use super::media::Media;
use super::normals;
use super::ply::MeshPart;
use super::textures::{colour, Texels};
use super::values::finite3;
use crate::bsdf::Bsdf;
use crate::geometry::shape::{Cylinder, Disk, Quad, Sphere, Triangle};
use crate::geometry::Primitive;
use crate::math::{Distribution1D, Frame};
use crate::scene::file::{path, KeyPath, MeshFormat, SceneFile, ShapeCommon, ShapeDesc};
use crate::scene::{AreaRadiance, Light, SceneError, SceneSource, ShapeInfo, ShapeTexture, UvMap};
use crate::texture::Texture;

/// A shape's emission: the constant radiance (a texture's mean), and the texture if any.
type Emission = (Vec3, Option<Texture>);

/// A closed, consistently oriented triangle mesh: every edge is shared by exactly two
/// triangles that traverse it in opposite directions. Vertices are welded by position first, so
/// an OBJ that splits vertices along seams (for normals or texture coordinates) still counts.
fn mesh_is_closed(positions: &[Vec3], indices: &[u32]) -> bool {
    let mut weld: HashMap<[u32; 3], u32> = HashMap::new();
    let ids: Vec<u32> = positions
        .iter()
        .map(|p| {
            let n = weld.len() as u32;
            *weld.entry(p.to_array().map(f32::to_bits)).or_insert(n)
        })
        .collect();
    let mut edges: HashMap<(u32, u32), i32> = HashMap::new();
    for t in indices.chunks_exact(3) {
        let t = [ids[t[0] as usize], ids[t[1] as usize], ids[t[2] as usize]];
        for (a, b) in [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])] {
            *edges.entry((a, b)).or_insert(0) += 1;
        }
    }
    !edges.is_empty()
        && edges
            .iter()
            .all(|(&(a, b), &c)| c == 1 && edges.get(&(b, a)) == Some(&1))
}

/// Signed volume enclosed by a closed triangle mesh: positive when its normals point outwards
/// (a flipped triangle's counts negated: its normal is -(e1 x e2)).
fn signed_volume(tris: &[Triangle]) -> f32 {
    tris.iter()
        .map(|t| {
            let c = t.e1().cross(t.e2());
            let v = t.p0.dot(c) / 6.0;
            if t.n.dot(c) < 0.0 {
                -v
            } else {
                v
            }
        })
        .sum()
}

/// Why an OBJ file's face indices were refused, with the OBJ line.
#[derive(Debug, thiserror::Error)]
enum ObjIndexError {
    /// A face word that does not start with an integer.
    #[error("line {line}: `{word}` is not a vertex index")]
    NotAnIndex { line: usize, word: String },
    /// An index past the vertices read so far.
    #[error(
        "line {line}: face index {k} is out of range (the file has {vertices} vertices so far)"
    )]
    OutOfRange { line: usize, k: i64, vertices: i64 },
}

/// Checks every face index of an OBJ file before tobj sees it, so the error names the OBJ line.
fn check_obj_indices(text: &str) -> Result<(), ObjIndexError> {
    let mut vertices = 0i64;
    for (n, line) in text.lines().enumerate() {
        let mut words = line.split_whitespace();
        match words.next() {
            Some("v") => vertices += 1,
            Some("f") | Some("l") => {
                for w in words {
                    let Some(Ok(k)) = w.split('/').next().map(str::parse::<i64>) else {
                        return Err(ObjIndexError::NotAnIndex {
                            line: n + 1,
                            word: w.to_string(),
                        });
                    };
                    // OBJ indices are 1-based; negative ones count back from the last vertex
                    let ok = if k > 0 {
                        k <= vertices
                    } else {
                        k < 0 && -k <= vertices
                    };
                    if !ok {
                        return Err(ObjIndexError::OutOfRange {
                            line: n + 1,
                            k,
                            vertices,
                        });
                    }
                }
            }
            _ => {}
        }
    }
    Ok(())
}

fn box_quads(min: Vec3, max: Vec3) -> Vec<Quad> {
    let d = max - min;
    let (dx, dy, dz) = (Vec3::X * d.x, Vec3::Y * d.y, Vec3::Z * d.z);
    // each face's u x v points out of the box
    [
        (min, dz, dy),
        (Vec3::new(max.x, min.y, min.z), dy, dz),
        (min, dx, dz),
        (Vec3::new(min.x, max.y, min.z), dz, dx),
        (min, dy, dx),
        (Vec3::new(min.x, min.y, max.z), dx, dy),
    ]
    .into_iter()
    .filter_map(|(o, u, v)| Quad::new(o, u, v))
    .collect()
}

/// What the shapes of a file become: primitives with the shape each belongs to, the shapes,
/// and the area lights (the first lights of the scene, in the order of the shapes).
pub(super) struct Surfaces {
    /// Every primitive, shape by shape.
    pub(super) prims: Vec<Primitive>,
    /// The shape of each primitive.
    pub(super) prim_shape: Vec<u32>,
    /// The shapes.
    pub(super) shapes: Vec<ShapeInfo>,
    /// The area lights, one per emitting shape.
    pub(super) lights: Vec<Light>,
}

/// Builds every `[[shapes]]` entry in order.
pub(super) fn shapes(
    src: &SceneSource,
    desc: &SceneFile,
    materials: &Materials,
    media: &Media,
) -> Result<Surfaces, SceneError> {
    let mut prims = Vec::new();
    let mut prim_shape = Vec::new();
    let mut shapes = Vec::new();
    let mut lights = Vec::new();
    for (i, s) in desc.shapes.iter().enumerate() {
        let key = path("shapes").index(i);
        let common = s.common();
        let (emission, bsdf) = surface(src, &key, &common, &materials.bsdfs)?;
        let textured = common
            .material
            .as_ref()
            .and_then(|m| materials.textures.get(m));
        let interior = media.find(src, desc, &key.clone().key("interior"), &common.interior)?;
        let exterior = media.find(src, desc, &key.clone().key("exterior"), &common.exterior)?;
        let interface = common.interior.is_some() || common.exterior.is_some();
        let emission_texture = emission.as_ref().is_some_and(|e| e.1.is_some());
        let (new, closed, mut corners, uvs) = primitives(
            src,
            &key,
            s,
            &common,
            textured.is_some() || emission_texture,
        )?;
        if common.emission.is_some() {
            if corners.as_ref().is_some_and(|c| !shaded_flat(&new, c)) {
                return Err(src.error(
                    &key.clone().key("smooth_normals"),
                    "an emitting mesh is shaded by its face normals only, and this one's vertex normals are not its face normals (a curved mesh): remove smooth_normals (in Mitsuba XML: add <boolean name=\"face_normals\" value=\"true\"/>)",
                ));
            }
            corners = None;
        }
        if common.interior.is_some() && !closed {
            return Err(src.error(
                &key.clone().key("interior"),
                format!(
                    "{} is not a closed shape (a mesh is closed when every edge joins exactly two consistently wound triangles), so it has no inside to hold a medium",
                    match s {
                        ShapeDesc::Mesh { obj, .. } => format!("the mesh `{obj}`"),
                        _ => format!("a {}", s.kind()),
                    }
                ),
            ));
        }
        let shape_id = shapes.len() as u32;
        let normals = corners.map(|corners| crate::scene::CornerNormals {
            first_prim: prims.len() as u32,
            corners,
        });
        let uv = uv_map(s, prims.len() as u32, uvs);
        let texture = textured.map(|t| ShapeTexture {
            reflectance: t.reflectance.clone(),
            alpha: t.alpha.clone(),
            alpha_v: t.alpha_v.clone(),
            specular: t.specular.clone(),
            transmittance: t.transmittance.clone(),
            eta: t.eta.clone(),
            k: t.k.clone(),
            tangent: t.tangent,
            uv: uv.clone(),
        });
        let light = emission.map(|(mean, texture)| {
            let radiance = match texture {
                None => AreaRadiance::Constant(mean),
                Some(t) => AreaRadiance::Textured {
                    texture: std::sync::Arc::new(t),
                    uv,
                    mean,
                },
            };
            let first = prims.len() as u32;
            let ids: Vec<u32> = (first..first + new.len() as u32).collect();
            let areas: Vec<f32> = new.iter().map(Primitive::area).collect();
            lights.push(Light::Area {
                shape: shape_id,
                prims: ids,
                distr: Distribution1D::new(&areas),
                area: areas.iter().sum(),
                radiance,
            });
            (lights.len() - 1) as u32
        });
        for p in new {
            prims.push(p);
            prim_shape.push(shape_id);
        }
        shapes.push(ShapeInfo {
            bsdf,
            light,
            interior,
            exterior,
            interface,
            label: format!("shapes[{i}] ({})", s.kind()),
            normals,
            texture,
        });
    }
    Ok(Surfaces {
        prims,
        prim_shape,
        shapes,
        lights,
    })
}

/// A sphere's own axes from `x_axis` and `z_axis` (either defaulting to the world's): unit,
/// perpendicular within 1e-3 (then made exactly so, x against z), y = z x x.
fn sphere_frame(
    src: &SceneSource,
    key: &KeyPath,
    x: Option<[f32; 3]>,
    z: Option<[f32; 3]>,
) -> Result<Frame, SceneError> {
    let axis = |name: &str, v: Option<[f32; 3]>, default: Vec3| -> Result<Vec3, SceneError> {
        let k = key.clone().key(name);
        let v = v.map_or(Ok(default), |v| finite3(src, &k, v))?;
        v.try_normalize()
            .ok_or_else(|| src.error(&k, format!("{name} must be a direction, not zero")))
    };
    let (x, z) = (axis("x_axis", x, Vec3::X)?, axis("z_axis", z, Vec3::Z)?);
    if x.dot(z).abs() > 1e-3 {
        return Err(src.error(
            &key.clone().key("x_axis"),
            "x_axis must be perpendicular to z_axis",
        ));
    }
    let x = (x - x.dot(z) * z).normalize();
    Ok(Frame {
        s: x,
        t: z.cross(x),
        n: z,
    })
}

/// How a textured shape maps its points to (u, v), with Mitsuba 3's conventions: the quad
/// (`rectangle`), disk, sphere and cylinder by their own coordinates, the box as `cube`, a mesh
/// by its texture coordinates `uvs` (its first primitive `first_prim`), else its barycentrics.
fn uv_map(s: &ShapeDesc, first_prim: u32, uvs: Option<Vec<[Vec2; 3]>>) -> UvMap {
    match (s, uvs) {
        (ShapeDesc::Box { min, max, .. }, _) => {
            let (lo, hi) = (Vec3::from_array(*min), Vec3::from_array(*max));
            UvMap::Cube {
                center: 0.5 * (lo + hi),
                half: 0.5 * (hi - lo),
            }
        }
        (_, Some(corners)) => UvMap::Mesh {
            first_prim,
            corners: corners.into(),
        },
        _ => UvMap::Primitive,
    }
}

/// A shape's emission (black counts as none) and material: one of them is required, and a null
/// boundary cannot emit.
fn surface(
    src: &SceneSource,
    key: &KeyPath,
    common: &ShapeCommon,
    materials: &BTreeMap<String, Bsdf>,
) -> Result<(Option<Emission>, Option<Bsdf>), SceneError> {
    let emission = match &common.emission {
        Some(e) => Some(colour(
            src,
            &key.clone().key("emission"),
            e,
            Texels::Emission,
        )?),
        None => None,
    }
    .filter(|(mean, t)| t.as_ref().map_or(mean.max_element(), Texture::max_value) > 0.0);
    let bsdf = match &common.material {
        Some(m) => Some(materials.get(m).cloned().ok_or_else(|| {
            let known: Vec<&str> = materials.keys().map(String::as_str).collect();
            src.error(
                &key.clone().key("material"),
                format!("unknown material `{m}` (defined: {known:?})"),
            )
        })?),
        None if emission.is_some() => None,
        None => {
            return Err(src.error(
                key,
                "a shape needs a `material` (or `emission`, for a black emitter)",
            ))
        }
    };
    if emission.is_some() && matches!(bsdf, Some(Bsdf::Null(_))) {
        return Err(src.error(&key.clone().key("emission"), "a null boundary cannot emit"));
    }
    Ok((emission, bsdf))
}

/// A shape's primitives, whether they enclose a volume (a quad does not; a mesh does when it is
/// closed), a smooth mesh's corner normals, and with `want_uv` a mesh's corner texture
/// coordinates when its file has them.
fn primitives(
    src: &SceneSource,
    key: &KeyPath,
    s: &ShapeDesc,
    common: &ShapeCommon,
    want_uv: bool,
) -> Result<(Vec<Primitive>, bool, Corners, CornerUvs), SceneError> {
    let mut new: Vec<Primitive> = Vec::new();
    let mut closed = true;
    match s {
        ShapeDesc::Quad {
            origin,
            u,
            v,
            flip_normals,
            ..
        } => {
            let o = finite3(src, &key.clone().key("origin"), *origin)?;
            let u = finite3(src, &key.clone().key("u"), *u)?;
            let v = finite3(src, &key.clone().key("v"), *v)?;
            let q = Quad::new(o, u, v).ok_or_else(|| {
                src.error(
                    &key.clone().key("u"),
                    "u and v are parallel: the quad has no area",
                )
            })?;
            new.push(Primitive::Quad(if *flip_normals { q.flipped() } else { q }));
            closed = false;
        }
        ShapeDesc::Box { min, max, .. } => {
            let lo = finite3(src, &key.clone().key("min"), *min)?;
            let hi = finite3(src, &key.clone().key("max"), *max)?;
            if !(hi.cmpgt(lo).all()) {
                return Err(src.error(
                    &key.clone().key("max"),
                    format!("max {max:?} must exceed min {min:?} on every axis"),
                ));
            }
            new.extend(box_quads(lo, hi).into_iter().map(Primitive::Quad));
        }
        ShapeDesc::Sphere {
            center,
            radius,
            x_axis,
            z_axis,
            ..
        } => {
            let c = finite3(src, &key.clone().key("center"), *center)?;
            if !(radius.is_finite() && *radius > 0.0) {
                return Err(src.error(
                    &key.clone().key("radius"),
                    format!("radius = {radius} must be positive"),
                ));
            }
            let mut sphere = Sphere::new(c, *radius);
            if x_axis.is_some() || z_axis.is_some() {
                sphere.frame = sphere_frame(src, key, *x_axis, *z_axis)?;
            }
            new.push(Primitive::Sphere(sphere));
        }
        ShapeDesc::Disk {
            center,
            u,
            v,
            flip_normals,
            ..
        } => {
            let c = finite3(src, &key.clone().key("center"), *center)?;
            let u = finite3(src, &key.clone().key("u"), *u)?;
            let v = finite3(src, &key.clone().key("v"), *v)?;
            let d = Disk::new(c, u, v).ok_or_else(|| {
                src.error(
                    &key.clone().key("u"),
                    "u and v are parallel: the disk has no area",
                )
            })?;
            new.push(Primitive::Disk(if *flip_normals { d.flipped() } else { d }));
            closed = false;
        }
        ShapeDesc::Cylinder {
            p0,
            p1,
            radius,
            flip_normals,
            x_axis,
            ..
        } => {
            let a = finite3(src, &key.clone().key("p0"), *p0)?;
            let b = finite3(src, &key.clone().key("p1"), *p1)?;
            if !(radius.is_finite() && *radius > 0.0) {
                return Err(src.error(
                    &key.clone().key("radius"),
                    format!("radius = {radius} must be positive"),
                ));
            }
            let c = Cylinder::new(a, b, *radius, *flip_normals).ok_or_else(|| {
                src.error(
                    &key.clone().key("p1"),
                    "p1 equals p0: the cylinder has no length",
                )
            })?;
            let c = match x_axis {
                Some(x) => {
                    let k = key.clone().key("x_axis");
                    c.with_x_axis(finite3(src, &k, *x)?).ok_or_else(|| {
                        src.error(&k, "x_axis must be a direction perpendicular to p1 - p0")
                    })?
                }
                None => c,
            };
            new.push(Primitive::Cylinder(c));
            closed = false;
        }
        ShapeDesc::Mesh {
            obj,
            format,
            to_world,
            smooth_normals,
            flip_tex_coords,
            shape_index,
            flip_normals,
            ..
        } => {
            let place = placement(src, key, to_world)?;
            let form = MeshForm {
                format: *format,
                smooth: *smooth_normals,
                uv: want_uv.then_some(*flip_tex_coords),
                shape_index: *shape_index,
                flip_normals: *flip_normals,
            };
            let (tris, all_closed, corners, uvs) = mesh(src, key, obj, place, common, form)?;
            closed = all_closed;
            new.extend(tris.into_iter().map(Primitive::Triangle));
            return Ok((new, closed, corners, uvs));
        }
    }
    Ok((new, closed, None, None))
}

/// The most a unit vertex normal may differ from its triangle's face normal, per component, and
/// still be the same normal: the two are computed from the same corners in different orders,
/// a few f32 roundings apart on a planar mesh.
const SAME_NORMAL: f32 = 1e-6;

/// Whether every corner normal of a smooth mesh is its triangle's face normal (a planar mesh, as
/// a light's quad usually is): then interpolated shading is flat shading, and an emitting mesh
/// is the same light either way (Mitsuba 3 tests an area emitter's side and samples it by the
/// interpolated normal).
fn shaded_flat(prims: &[Primitive], corners: &[[Vec3; 3]]) -> bool {
    prims.iter().zip(corners).all(|(p, c)| match p {
        Primitive::Triangle(t) => c
            .iter()
            .all(|n| (*n - t.n).abs().max_element() <= SAME_NORMAL),
        _ => false,
    })
}

/// A mesh's `to_world` rows as an affine map (identity without them), every entry finite and
/// the linear part invertible.
fn placement(
    src: &SceneSource,
    key: &KeyPath,
    to_world: &Option<[[f32; 4]; 3]>,
) -> Result<glam::Affine3A, SceneError> {
    let Some(r) = to_world else {
        return Ok(glam::Affine3A::IDENTITY);
    };
    let col = |j: usize| Vec3::new(r[0][j], r[1][j], r[2][j]);
    let m = glam::Affine3A::from_cols(col(0).into(), col(1).into(), col(2).into(), col(3).into());
    let det = m.matrix3.determinant();
    if !(r.iter().flatten().all(|x| x.is_finite()) && det.is_normal()) {
        return Err(src.error(
            &key.clone().key("to_world"),
            "to_world must be finite with an invertible linear part",
        ));
    }
    Ok(m)
}

/// The models of an OBJ file as (positions, triangle indices, corner normals), every face
/// index checked first so that an error names the OBJ line. A smooth mesh keeps the file's
/// position indices (its computed normals are per position, as Mitsuba's) and its `vn`.
fn obj_parts(
    src: &SceneSource,
    obj_key: &KeyPath,
    file: &std::path::Path,
    bytes: Vec<u8>,
    smooth: bool,
) -> Result<Vec<MeshPart>, SceneError> {
    let cannot = |e: &dyn std::fmt::Display| {
        src.error(obj_key, format!("cannot read `{}`: {e}", file.display()))
    };
    let text = String::from_utf8(bytes).map_err(|e| cannot(&e))?;
    check_obj_indices(&text)
        .map_err(|e| src.error(obj_key, format!("`{}` {e}", file.display())))?;
    let options = tobj::LoadOptions {
        triangulate: true,
        single_index: !smooth,
        ..Default::default()
    };
    let (models, _) = tobj::load_obj_buf(&mut text.as_bytes(), &options, |_| {
        Err(tobj::LoadError::OpenFileFailed) // materials are not used
    })
    .map_err(|e| src.error(obj_key, format!("cannot load `{}`: {e}", file.display())))?;
    let vec3s = |v: &[f32]| -> Vec<Vec3> {
        v.chunks_exact(3)
            .map(|c| Vec3::new(c[0], c[1], c[2]))
            .collect()
    };
    models
        .into_iter()
        .map(|m| {
            let m = m.mesh;
            let normals = vec3s(&m.normals);
            let corners = (smooth && !m.normal_indices.is_empty())
                .then(|| {
                    if m.normal_indices.len() != m.indices.len() {
                        return Err("some faces have vertex normals (`vn`) and some have none");
                    }
                    m.normal_indices
                        .iter()
                        .map(|&k| normals.get(k as usize).copied())
                        .collect::<Option<Vec<Vec3>>>()
                        .ok_or("a vertex normal index is out of range")
                })
                .transpose()
                .map_err(|e| src.error(obj_key, format!("`{}`: {e}", file.display())))?;
            let uvs = obj_uvs(&m, smooth)
                .map_err(|e| src.error(obj_key, format!("`{}`: {e}", file.display())))?;
            Ok((vec3s(&m.positions), m.indices, corners, uvs))
        })
        .collect()
}

/// An OBJ model's texture coordinates (`vt`) at each triangle corner, aligned with its
/// indices; `None` without `vt`. tobj keeps them per vertex when it made one index (`!smooth`),
/// else per corner by their own indices.
fn obj_uvs(m: &tobj::Mesh, smooth: bool) -> Result<Option<Vec<Vec2>>, &'static str> {
    if m.texcoords.is_empty() {
        return Ok(None);
    }
    let uv = |k: u32| {
        let k = 2 * k as usize;
        m.texcoords.get(k..k + 2).map(|t| Vec2::new(t[0], t[1]))
    };
    let mixed = "some faces have texture coordinates (`vt`) and some have none";
    let ids = if smooth {
        if m.texcoord_indices.len() != m.indices.len() {
            return Err(mixed);
        }
        &m.texcoord_indices
    } else {
        if m.texcoords.len() != 2 * (m.positions.len() / 3) {
            return Err(mixed);
        }
        &m.indices
    };
    ids.iter()
        .map(|&k| uv(k))
        .collect::<Option<Vec<Vec2>>>()
        .map(Some)
        .ok_or("a texture coordinate index is out of range")
}

/// The largest OBJ file read (about 10 million triangles).
pub const MAX_OBJ_BYTES: u64 = 1 << 30;

/// How a mesh file is read (`format`, else by its extension) and what it keeps beside its
/// triangles: corner normals when `smooth`, and with `uv` (the shape's `flip_tex_coords`) the
/// file's texture coordinates, if any; `flip_normals` turns every normal around.
struct MeshForm {
    format: Option<MeshFormat>,
    smooth: bool,
    uv: Option<Option<bool>>,
    shape_index: Option<u32>,
    flip_normals: bool,
}

/// A mesh file's format by its extension: `.ply`, `.serialized`, else OBJ.
fn format_of(file: &std::path::Path) -> MeshFormat {
    let ext = file.extension().and_then(|e| e.to_str()).unwrap_or("");
    if ext.eq_ignore_ascii_case("ply") {
        MeshFormat::Ply
    } else if ext.eq_ignore_ascii_case("serialized") {
        MeshFormat::Serialized
    } else {
        MeshFormat::Obj
    }
}

/// The triangles of an OBJ, PLY or serialized file, every index and vertex checked, whether the mesh is
/// closed (a closed mesh holding a medium must be wound outwards), and the corner normals and
/// texture coordinates of each triangle that `form` asks for.
fn mesh(
    src: &SceneSource,
    key: &KeyPath,
    obj: &str,
    place: glam::Affine3A,
    common: &ShapeCommon,
    form: MeshForm,
) -> Result<MeshTriangles, SceneError> {
    let smooth = form.smooth;
    let file = src.base_dir.join(obj);
    let obj_key = key.clone().key("obj");
    let fail =
        |e: &dyn std::fmt::Display| src.error(&obj_key, format!("`{}`: {e}", file.display()));
    let bytes = crate::conventions::read_at_most(&file, MAX_OBJ_BYTES)
        .map_err(|e| src.error(&obj_key, format!("cannot read `{}`: {e}", file.display())))?;
    src.record_input(obj, crate::conventions::fnv1a(&bytes));
    let format = form.format.unwrap_or_else(|| format_of(&file));
    if form.shape_index.is_some() && format != MeshFormat::Serialized {
        return Err(src.error(
            &key.clone().key("shape_index"),
            format!(
                "shape_index selects a shape of a serialized file, and `{}` is not read as one (format)",
                file.display()
            ),
        ));
    }
    let parts = match format {
        MeshFormat::Ply => vec![super::ply::read_ply(&bytes).map_err(|e| fail(&e))?],
        MeshFormat::Serialized => {
            let k = form.shape_index.unwrap_or(0);
            vec![super::serialized::read_serialized(&bytes, k).map_err(|e| fail(&e))?]
        }
        MeshFormat::Obj => obj_parts(src, &obj_key, &file, bytes, smooth)?,
    };
    let mut all_closed = true;
    let mut tris = Vec::new();
    let mut corners = Vec::new();
    // Mitsuba 3's `obj` flips v by default, its `ply` and `serialized` do not
    let flip = form.uv.map(|f| f.unwrap_or(format == MeshFormat::Obj));
    let mut uvs = Vec::new();
    let mut parts_with_uv = 0;
    for (pos, idx, normals, tex) in &parts {
        let pos: Vec<Vec3> = pos.iter().map(|&p| place.transform_point3(p)).collect();
        if idx.iter().any(|&k| k as usize >= pos.len()) {
            return Err(fail(&"a face index is out of range"));
        }
        if pos.iter().any(|p| !p.is_finite()) {
            return Err(fail(&"a vertex is not finite"));
        }
        all_closed &= mesh_is_closed(&pos, idx);
        let smooth_part = if !smooth {
            None
        } else if let Some(ns) = normals {
            let placed: Option<Vec<Vec3>> =
                ns.iter().map(|&n| normals::placed(&place, n)).collect();
            Some(placed.ok_or_else(|| fail(&"a vertex normal is not finite or has zero length"))?)
        } else {
            let per_position = normals::angle_weighted(&pos, idx);
            Some(idx.iter().map(|&k| per_position[k as usize]).collect())
        };
        // Mitsuba negates the interpolated normal: negating the corners is the same
        let smooth_part = smooth_part.map(|n: Vec<Vec3>| {
            if form.flip_normals {
                n.into_iter().map(|n| -n).collect()
            } else {
                n
            }
        });
        for (c, t) in idx.chunks_exact(3).enumerate() {
            let Some(tri) =
                Triangle::new(pos[t[0] as usize], pos[t[1] as usize], pos[t[2] as usize])
            else {
                continue;
            };
            tris.push(if form.flip_normals {
                tri.flipped()
            } else {
                tri
            });
            if let Some(n) = &smooth_part {
                corners.push([n[3 * c], n[3 * c + 1], n[3 * c + 2]]);
            }
            if let (Some(flip), Some(t)) = (flip, tex) {
                let f = |t: Vec2| if flip { Vec2::new(t.x, 1.0 - t.y) } else { t };
                uvs.push([f(t[3 * c]), f(t[3 * c + 1]), f(t[3 * c + 2])]);
            }
        }
        parts_with_uv += usize::from(tex.is_some());
    }
    if flip.is_some() && parts_with_uv != 0 && parts_with_uv != parts.len() {
        return Err(fail(
            &"some of its objects have texture coordinates and some have none",
        ));
    }
    if uvs.iter().flatten().any(|t| !t.is_finite()) {
        return Err(fail(&"a texture coordinate is not finite"));
    }
    if tris.is_empty() {
        return Err(src.error(&obj_key, format!("`{}` has no triangles", file.display())));
    }
    let closed = all_closed;
    if closed && common.interior.is_some() && signed_volume(&tris) < 0.0 {
        let why = if form.flip_normals {
            "flip_normals turns its normals inwards, so `interior` would be outside; remove flip_normals"
        } else {
            "`interior` would be outside; reverse the faces' vertex order"
        };
        return Err(src.error(
            &obj_key,
            format!(
                "`{}` is wound inside out (its normals point inwards): {why}",
                file.display()
            ),
        ));
    }
    let uvs = (flip.is_some() && parts_with_uv != 0).then_some(uvs);
    Ok((tris, closed, smooth.then_some(corners), uvs))
}

/// A smooth mesh's normals at the corners of each triangle (`None`: flat).
type Corners = Option<Vec<[Vec3; 3]>>;

/// A textured mesh's texture coordinates at the corners of each triangle (`None`: the file
/// has none, or the shape is not textured).
type CornerUvs = Option<Vec<[Vec2; 3]>>;

/// A mesh's triangles, whether it is closed, its corner normals when smooth, and its corner
/// texture coordinates when textured.
type MeshTriangles = (Vec<Triangle>, bool, Corners, CornerUvs);
