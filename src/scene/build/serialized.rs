//! A reader of Mitsuba's `serialized` meshes (Mitsuba 3 documentation, plugin `serialized`;
//! the versions 3 and 4 Mitsuba 3.9 reads): a little-endian header (0x041C and the version),
//! then per shape a zlib stream of flags, the name (version 4), the vertex and triangle counts,
//! positions, normals, texture coordinates and colours (single or double precision) and
//! `uint32` triangle indices; shapes after the first are found through the dictionary of
//! offsets at the end of the file. The counts are checked against a limit before anything is
//! inflated, and the inflated bytes are read only as far as the counts need.

use std::io::Read;

use glam::{Vec2, Vec3};

use super::ply::MeshPart;

/// The format identifier every shape's header starts with.
const MAGIC: u16 = 0x041C;

/// The flag word's bits (Mitsuba 3's `TriMeshFlags`).
const HAS_NORMALS: u32 = 0x0001;
const HAS_TEXCOORDS: u32 = 0x0002;
/// Declared and never read by Mitsuba 3 (no data follows for it).
const HAS_TANGENTS: u32 = 0x0004;
const HAS_COLORS: u32 = 0x0008;
/// Ignored by Mitsuba 3.9 for versions 3 and 4: the shape's `face_normals` decides.
const FACE_NORMALS: u32 = 0x0010;
const SINGLE_PRECISION: u32 = 0x1000;
const DOUBLE_PRECISION: u32 = 0x2000;
const KNOWN_FLAGS: u32 = HAS_NORMALS
    | HAS_TEXCOORDS
    | HAS_TANGENTS
    | HAS_COLORS
    | FACE_NORMALS
    | SINGLE_PRECISION
    | DOUBLE_PRECISION;

/// The most bytes one shape's stream may inflate to (its arrays; about 20 million triangles
/// with normals), as `MAX_OBJ_BYTES` bounds an OBJ file.
pub const MAX_INFLATED_BYTES: u64 = 1 << 30;

/// The longest shape name read (version 4 names are null-terminated).
const MAX_NAME_BYTES: usize = 1 << 16;

/// A little-endian integer at `at`, or `None` past the end.
fn le<const N: usize>(bytes: &[u8], at: usize) -> Option<[u8; N]> {
    bytes.get(at..at.checked_add(N)?)?.try_into().ok()
}

/// The version of the header at `at` (3 or 4).
fn header(bytes: &[u8], at: usize) -> Result<u16, String> {
    let (Some(m), Some(v)) = (le::<2>(bytes, at), le::<2>(bytes, at + 2)) else {
        return Err(format!("the file ends in the header at byte {at}"));
    };
    let (m, v) = (u16::from_le_bytes(m), u16::from_le_bytes(v));
    if m != MAGIC {
        return Err(format!(
            "byte {at} holds 0x{m:04X}, not the identifier 0x041C of Mitsuba's serialized meshes"
        ));
    }
    if v != 3 && v != 4 {
        return Err(format!(
            "format version {v} is not read (Mitsuba 3.9 reads versions 3 and 4)"
        ));
    }
    Ok(v)
}

/// Where shape `k`'s stream starts: after the header for the first, else at the offset the
/// dictionary at the end of the file gives (`uint64` entries in version 4, `uint32` in
/// version 3, then the `uint32` shape count), whose own header must match the file's.
fn stream_start(bytes: &[u8], version: u16, k: u32) -> Result<usize, String> {
    if k == 0 {
        return Ok(4); // Mitsuba reads the first shape without the dictionary
    }
    let n = bytes.len();
    let count = n
        .checked_sub(4)
        .and_then(|at| le::<4>(bytes, at))
        .map(u32::from_le_bytes)
        .ok_or("the file is too short to end with a dictionary of shapes")?;
    if k >= count {
        return Err(format!(
            "shape_index {k} is out of range: the dictionary lists {count} shapes (0 to {})",
            count.saturating_sub(1)
        ));
    }
    let entry = if version == 4 { 8 } else { 4 };
    let from_end = entry * (count - k) as usize + 4;
    let at = n
        .checked_sub(from_end)
        .filter(|&at| at >= 4)
        .ok_or_else(|| format!("a dictionary of {count} shapes does not fit in the file"))?;
    let offset = if version == 4 {
        le::<8>(bytes, at).map(u64::from_le_bytes)
    } else {
        le::<4>(bytes, at).map(|b| u32::from_le_bytes(b) as u64)
    }
    .and_then(|o| usize::try_from(o).ok())
    .filter(|&o| o < at)
    .ok_or_else(|| format!("the dictionary's offset of shape {k} lies beyond the shapes"))?;
    if header(bytes, offset)? != version {
        return Err(format!(
            "shape {k}'s header at byte {offset} has another version than the file's"
        ));
    }
    Ok(offset + 4)
}

/// `N` bytes of the inflated stream.
fn take<const N: usize>(z: &mut impl Read, what: &str) -> Result<[u8; N], String> {
    let mut b = [0u8; N];
    z.read_exact(&mut b)
        .map_err(|e| format!("the compressed stream ends or breaks in {what}: {e}"))?;
    Ok(b)
}

/// The arrays of one shape's stream, as the header's flags and counts lay them out.
struct Layout {
    vertices: usize,
    triangles: usize,
    normals: bool,
    uvs: bool,
    colors: bool,
    /// 8 for double precision, else 4.
    width: usize,
}

impl Layout {
    /// The bytes the arrays take, `None` above `MAX_INFLATED_BYTES`.
    fn bytes(&self) -> Option<usize> {
        let per_vertex = 3 + 3 * (self.normals as usize) + 2 * (self.uvs as usize);
        let per_vertex = per_vertex + 3 * (self.colors as usize);
        let v = self.vertices.checked_mul(per_vertex * self.width)?;
        let f = self.triangles.checked_mul(12)?;
        v.checked_add(f).filter(|&b| b as u64 <= MAX_INFLATED_BYTES)
    }
}

/// The flags, the name (version 4) and the counts at the start of a shape's stream.
fn layout(z: &mut impl Read, version: u16) -> Result<Layout, String> {
    let flags = u32::from_le_bytes(take(z, "the flags")?);
    if flags & !KNOWN_FLAGS != 0 {
        return Err(format!(
            "the flags 0x{flags:08X} hold bits Mitsuba's format does not define (0x{:08X})",
            flags & !KNOWN_FLAGS
        ));
    }
    if version == 4 {
        let mut len = 0;
        while take::<1>(z, "the name")?[0] != 0 {
            len += 1;
            if len > MAX_NAME_BYTES {
                return Err(format!("the shape's name runs past {MAX_NAME_BYTES} bytes"));
            }
        }
    }
    let vertices = u64::from_le_bytes(take(z, "the vertex count")?);
    let triangles = u64::from_le_bytes(take(z, "the triangle count")?);
    let too_many = || {
        format!(
            "{vertices} vertices and {triangles} triangles: more than the {} MiB a shape may inflate to",
            MAX_INFLATED_BYTES >> 20
        )
    };
    let (Ok(v), Ok(f)) = (usize::try_from(vertices), usize::try_from(triangles)) else {
        return Err(too_many());
    };
    let layout = Layout {
        vertices: v,
        triangles: f,
        normals: flags & HAS_NORMALS != 0,
        uvs: flags & HAS_TEXCOORDS != 0,
        colors: flags & HAS_COLORS != 0,
        width: if flags & DOUBLE_PRECISION != 0 { 8 } else { 4 },
    };
    layout.bytes().ok_or_else(too_many)?;
    Ok(layout)
}

/// `count` values of `dim` components from `body` at `*at`, rounded to f32 as Mitsuba does.
fn floats(body: &[u8], at: &mut usize, count: usize, dim: usize, width: usize) -> Vec<f32> {
    let n = count * dim;
    let values = body[*at..*at + n * width].chunks_exact(width).map(|c| {
        if width == 8 {
            f64::from_le_bytes(c.try_into().unwrap()) as f32
        } else {
            f32::from_le_bytes(c.try_into().unwrap())
        }
    });
    let out = values.collect();
    *at += n * width;
    out
}

/// Positions, triangle indices, and, when the shape stores them, the normal and the texture
/// coordinates at each triangle corner of shape `shape_index` of a `serialized` file.
pub fn read_serialized(bytes: &[u8], shape_index: u32) -> Result<MeshPart, String> {
    let at = |e: String| format!("shape {shape_index}: {e}");
    let version = header(bytes, 0).map_err(at)?;
    let start = stream_start(bytes, version, shape_index).map_err(at)?;
    let mut z = flate2::read::ZlibDecoder::new(&bytes[start..]);
    let l = layout(&mut z, version).map_err(at)?;
    let need = l.bytes().expect("checked by `layout`");
    let mut body = Vec::new();
    let got = z.take(need as u64).read_to_end(&mut body);
    if let Err(e) = got {
        return Err(at(format!("the compressed stream breaks: {e}")));
    }
    if body.len() != need {
        return Err(at(format!(
            "the compressed stream ends after {} of the {need} bytes of {} vertices and {} triangles",
            body.len(),
            l.vertices,
            l.triangles
        )));
    }
    let mut k = 0;
    let vec3s = |v: Vec<f32>| -> Vec<Vec3> { v.chunks_exact(3).map(Vec3::from_slice).collect() };
    let pos = vec3s(floats(&body, &mut k, l.vertices, 3, l.width));
    let nrm = l
        .normals
        .then(|| vec3s(floats(&body, &mut k, l.vertices, 3, l.width)));
    let tex = l.uvs.then(|| {
        let t = floats(&body, &mut k, l.vertices, 2, l.width);
        t.chunks_exact(2).map(Vec2::from_slice).collect::<Vec<_>>()
    });
    k += l.colors as usize * l.vertices * 3 * l.width; // colours are not rendered by Mitsuba 3
    let idx: Vec<u32> = body[k..]
        .chunks_exact(4)
        .map(|c| u32::from_le_bytes(c.try_into().unwrap()))
        .collect();
    if let Some((i, &v)) = idx
        .iter()
        .enumerate()
        .find(|(_, &v)| v as usize >= l.vertices)
    {
        return Err(at(format!(
            "triangle {} names vertex {v}, but the shape has {} vertices",
            i / 3,
            l.vertices
        )));
    }
    let corners = |per_vertex: Vec<_>| idx.iter().map(|&v| per_vertex[v as usize]).collect();
    let normals = nrm.map(corners);
    let uvs = tex.map(|t: Vec<Vec2>| idx.iter().map(|&v| t[v as usize]).collect());
    Ok((pos, idx, normals, uvs))
}
