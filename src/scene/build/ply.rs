//! A small reader of PLY meshes (Turk 1994; the format Mitsuba's `ply` shape reads): ASCII
//! and binary (either byte order), the vertices' `x`, `y`, `z` (with normals and texture
//! coordinates when present) and the faces' `vertex_indices` (or `vertex_index`) as triangle
//! fans; every other element and property is
//! read past. Counts are checked against the bytes left before anything is reserved.

use glam::{Vec2, Vec3};

/// The most vertices one face may list (a polygon is split into a fan of triangles).
pub const MAX_FACE_VERTICES: usize = 1024;

#[derive(Clone, Copy, PartialEq)]
enum Format {
    Ascii,
    Little,
    Big,
}

#[derive(Clone, Copy)]
enum Scalar {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl Scalar {
    fn parse(name: &str) -> Option<Scalar> {
        Some(match name {
            "char" | "int8" => Scalar::I8,
            "uchar" | "uint8" => Scalar::U8,
            "short" | "int16" => Scalar::I16,
            "ushort" | "uint16" => Scalar::U16,
            "int" | "int32" => Scalar::I32,
            "uint" | "uint32" => Scalar::U32,
            "float" | "float32" => Scalar::F32,
            "double" | "float64" => Scalar::F64,
            _ => return None,
        })
    }

    fn size(self) -> usize {
        match self {
            Scalar::I8 | Scalar::U8 => 1,
            Scalar::I16 | Scalar::U16 => 2,
            Scalar::I32 | Scalar::U32 | Scalar::F32 => 4,
            Scalar::F64 => 8,
        }
    }
}

struct Property {
    name: String,
    /// `Some(count type)` for a list.
    list: Option<Scalar>,
    ty: Scalar,
}

struct Element {
    name: String,
    count: usize,
    props: Vec<Property>,
}

/// The values of the body, read one at a time in either encoding.
struct Body<'a> {
    bytes: &'a [u8],
    at: usize,
    format: Format,
}

impl Body<'_> {
    fn value(&mut self, ty: Scalar) -> Result<f64, String> {
        if self.format == Format::Ascii {
            let rest = &self.bytes[self.at..];
            let start = rest
                .iter()
                .position(|b| !b.is_ascii_whitespace())
                .ok_or("the file ends early")?;
            let len = rest[start..]
                .iter()
                .position(|b| b.is_ascii_whitespace())
                .unwrap_or(rest.len() - start);
            let word = &rest[start..start + len];
            self.at += start + len;
            return std::str::from_utf8(word)
                .ok()
                .and_then(|w| w.parse::<f64>().ok())
                .ok_or_else(|| {
                    format!(
                        "byte {}: `{}` is not a number",
                        self.at - len,
                        String::from_utf8_lossy(word)
                    )
                });
        }
        let n = ty.size();
        let b = self
            .bytes
            .get(self.at..self.at + n)
            .ok_or("the file ends early")?;
        self.at += n;
        let mut a = [0u8; 8];
        a[..n].copy_from_slice(b);
        if self.format == Format::Big {
            a[..n].reverse();
        }
        Ok(match ty {
            Scalar::I8 => a[0] as i8 as f64,
            Scalar::U8 => a[0] as f64,
            Scalar::I16 => i16::from_le_bytes([a[0], a[1]]) as f64,
            Scalar::U16 => u16::from_le_bytes([a[0], a[1]]) as f64,
            Scalar::I32 => i32::from_le_bytes([a[0], a[1], a[2], a[3]]) as f64,
            Scalar::U32 => u32::from_le_bytes([a[0], a[1], a[2], a[3]]) as f64,
            Scalar::F32 => f32::from_le_bytes([a[0], a[1], a[2], a[3]]) as f64,
            Scalar::F64 => f64::from_le_bytes(a),
        })
    }
}

/// The header: format, elements, and where the body starts.
fn header(bytes: &[u8]) -> Result<(Format, Vec<Element>, usize), String> {
    const END: &[u8] = b"end_header";
    let end = bytes
        .windows(END.len())
        .position(|w| w == END)
        .ok_or("no `end_header`: not a PLY file")?;
    let body = end
        + END.len()
        + bytes[end + END.len()..]
            .iter()
            .position(|&b| b == b'\n')
            .ok_or("the file ends in its header")?
        + 1;
    let text = std::str::from_utf8(&bytes[..end]).map_err(|_| "the header is not text")?;
    let mut lines = text.lines().enumerate();
    if lines.next().map(|(_, l)| l.trim()) != Some("ply") {
        return Err("the first line is not `ply`".into());
    }
    let mut format = None;
    let mut elements: Vec<Element> = Vec::new();
    for (n, line) in lines {
        let w: Vec<&str> = line.split_whitespace().collect();
        let bad = || format!("header line {}: `{}` is not understood", n + 1, line.trim());
        match w.as_slice() {
            [] | ["comment", ..] | ["obj_info", ..] => {}
            ["format", f, "1.0"] => {
                format = Some(match *f {
                    "ascii" => Format::Ascii,
                    "binary_little_endian" => Format::Little,
                    "binary_big_endian" => Format::Big,
                    _ => return Err(bad()),
                })
            }
            ["element", name, count] => elements.push(Element {
                name: name.to_string(),
                count: count.parse().map_err(|_| bad())?,
                props: Vec::new(),
            }),
            ["property", "list", c, t, name] => {
                let p = Property {
                    name: name.to_string(),
                    list: Some(Scalar::parse(c).ok_or_else(bad)?),
                    ty: Scalar::parse(t).ok_or_else(bad)?,
                };
                elements.last_mut().ok_or_else(bad)?.props.push(p);
            }
            ["property", t, name] => {
                let p = Property {
                    name: name.to_string(),
                    list: None,
                    ty: Scalar::parse(t).ok_or_else(bad)?,
                };
                elements.last_mut().ok_or_else(bad)?.props.push(p);
            }
            _ => return Err(bad()),
        }
    }
    let format = format.ok_or("the header has no `format` line")?;
    Ok((format, elements, body))
}

/// One part of a mesh file: positions, triangle indices and, when the file gives them, the
/// normal and the texture coordinates of each triangle corner (aligned with the indices).
pub type MeshPart = (Vec<Vec3>, Vec<u32>, Option<Vec<Vec3>>, Option<Vec<Vec2>>);

/// The names of a vertex's texture coordinates Mitsuba 3's `ply` reads.
const UV_NAMES: [[&str; 2]; 3] = [["u", "v"], ["s", "t"], ["texture_u", "texture_v"]];

/// Positions, triangle indices, vertex normals (`nx`, `ny`, `nz`) and texture coordinates
/// (`u`, `v` or `s`, `t` or `texture_u`, `texture_v`) of a PLY file.
pub fn read_ply(bytes: &[u8]) -> Result<MeshPart, String> {
    let (format, elements, start) = header(bytes)?;
    let mut body = Body {
        bytes,
        at: start,
        format,
    };
    let (mut pos, mut idx, mut nrm, mut tex) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    for e in &elements {
        // every instance takes at least one byte per property (two in ASCII, with a separator)
        let least = e.props.len().max(1) * if format == Format::Ascii { 2 } else { 1 };
        if e.count.saturating_mul(least) > bytes.len() - body.at.min(bytes.len()) {
            return Err(format!(
                "element `{}`: {} of them cannot fit in the {} bytes left",
                e.name,
                e.count,
                bytes.len() - body.at
            ));
        }
        let xyz = ["x", "y", "z"].map(|a| e.props.iter().position(|p| p.name == a));
        // vertex normals: all three of nx, ny, nz or none (Mitsuba 3 documentation, plugin `ply`)
        let nxyz = ["nx", "ny", "nz"].map(|a| e.props.iter().position(|p| p.name == a));
        let has_normals = e.name == "vertex" && nxyz.iter().all(Option::is_some);
        let uv = UV_NAMES
            .iter()
            .map(|n| n.map(|a| e.props.iter().position(|p| p.name == a)))
            .find(|uv| uv.iter().all(Option::is_some))
            .filter(|_| e.name == "vertex");
        if e.name == "vertex" {
            if xyz.iter().any(Option::is_none) {
                return Err("the vertices have no x, y, z".into());
            }
            pos.reserve(e.count);
        }
        for _ in 0..e.count {
            let (mut v, mut n, mut t) = ([0f64; 3], [0f64; 3], [0f64; 2]);
            for (k, p) in e.props.iter().enumerate() {
                let Some(ct) = p.list else {
                    let x = body.value(p.ty)?;
                    if let Some(a) = xyz.iter().position(|&i| i == Some(k)) {
                        v[a] = x;
                    }
                    if let Some(a) = nxyz.iter().position(|&i| i == Some(k)) {
                        n[a] = x;
                    }
                    if let Some(a) = uv.and_then(|uv| uv.iter().position(|&i| i == Some(k))) {
                        t[a] = x;
                    }
                    continue;
                };
                let n = body.value(ct)?;
                if !(0.0..=MAX_FACE_VERTICES as f64).contains(&n) || n.fract() != 0.0 {
                    return Err(format!(
                        "a list of {n} entries (at most {MAX_FACE_VERTICES})"
                    ));
                }
                let face =
                    e.name == "face" && (p.name == "vertex_indices" || p.name == "vertex_index");
                let mut ids = Vec::with_capacity(if face { n as usize } else { 0 });
                for _ in 0..n as usize {
                    let i = body.value(p.ty)?;
                    if face {
                        if !(i >= 0.0 && i < u32::MAX as f64 && i.fract() == 0.0) {
                            return Err(format!("face index {i} is not a vertex index"));
                        }
                        ids.push(i as u32);
                    }
                }
                for t in 1..ids.len().saturating_sub(1) {
                    idx.extend([ids[0], ids[t], ids[t + 1]]);
                }
            }
            if e.name == "vertex" {
                pos.push(Vec3::new(v[0] as f32, v[1] as f32, v[2] as f32));
                if has_normals {
                    nrm.push(Vec3::new(n[0] as f32, n[1] as f32, n[2] as f32));
                }
                if uv.is_some() {
                    tex.push(Vec2::new(t[0] as f32, t[1] as f32));
                }
            }
        }
    }
    if let Some(&k) = idx.iter().find(|&&k| k as usize >= pos.len()) {
        return Err(format!(
            "face index {k} is out of range (the file has {} vertices)",
            pos.len()
        ));
    }
    // normals only when every vertex has one
    let normals = (!nrm.is_empty() && nrm.len() == pos.len())
        .then(|| idx.iter().map(|&k| nrm[k as usize]).collect());
    let uvs = (!tex.is_empty() && tex.len() == pos.len())
        .then(|| idx.iter().map(|&k| tex[k as usize]).collect());
    Ok((pos, idx, normals, uvs))
}
