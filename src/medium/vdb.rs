//! OpenVDB files: a float grid of a `.vdb` read into the density lattice of [`super::grid`].
//!
//! An OpenVDB grid stores values at integer voxel coordinates in a sparse tree: a root table of
//! tiles and 32^3 internal nodes, each holding tiles or 16^3 internal nodes, each holding tiles
//! or 8^3 leaves of voxel values; a value mask marks the active voxels and tiles. The grid's
//! transform maps voxel (i, j, k) to world space. pathspace reads the values of the voxels in
//! the active bounding box (the active voxels' and active tiles'), grown by one voxel on every
//! side, as a [`Grid`] whose lattice vertices are the voxels and whose box is their world
//! positions: the medium is then OpenVDB's trilinear field (its `BoxSampler`) everywhere, since
//! beyond the margin every value is the background, which must be 0. The majorant grid of
//! [`super::Heterogeneous`] is built from these values, so an empty region of the VDB (no leaf,
//! an inactive tile) has majorant 0 and a constant tile its value.
//!
//! The file format (version 222 to 224: OpenVDB 3 and later), little-endian: the header (magic
//! `0x56444220` as i64, version, library version, a grid-offsets flag, a 36-byte UUID), the
//! file's metadata, the grid descriptors (name, type `Tree_float_5_4_3` with `_HalfFloat` when
//! the values are stored as half floats, offsets), and per grid its compression flags
//! (zip, active mask, Blosc), metadata, transform, topology (masks, tile values) and buffers
//! (the leaves' values). Value arrays are mask-compressed (only the active values, with the
//! inactive ones restored from one or two stored values and a selection mask), then zlib or
//! Blosc (LZ4 or zlib codec, byte-shuffled) compressed; Blosc's header is parsed here, its LZ4
//! blocks decoded by `lz4_flex`.
//!
//! Read: float grids (and half-float storage), scale-and-translate transforms (uniform or per
//! axis, including an `AffineMap` of that form). Refused, with the reason: other value types,
//! rotations, shears and frustums, instanced grids, a nonzero background, negative or
//! non-finite values. Limits: the lattice of [`super::grid`] ([`MAX_GRID_SIDE`] per side,
//! [`MAX_GRID_VERTICES`] in all), at most [`MAX_VDB_LEAVES`] leaves and [`MAX_VDB_TILES`] tiles
//! that are active or not the background; every length and offset is checked against the
//! file's bytes before it is used, and every decompression is into a buffer of the size the
//! tree implies, so a small file cannot claim a large allocation.
//!
//! Executable spec: `tests/spec/medium/vdb.rs`; fixtures written by OpenVDB:
//! `tests/fixtures/vdb/` (`scripts/make_vdb_fixtures.py`).

use glam::Vec3;
use std::io::Read;
use std::path::Path;

use super::grid::{GridError, GridFile, MAX_GRID_FILE_BYTES, MAX_GRID_SIDE, MAX_GRID_VERTICES};
use super::Grid;

/// Most leaf nodes read (a 1024^3 lattice of active voxels has 128^3 = 2^21).
pub const MAX_VDB_LEAVES: usize = 1 << 21;
/// Most tiles kept (active or not the background), over all levels.
pub const MAX_VDB_TILES: usize = 1 << 22;

/// The magic number, `VDB ` read as a little-endian i64.
const MAGIC: i64 = 0x5644_4220;
/// Oldest file format read: per-grid compression flags and mask-compressed node values.
const FIRST_VERSION: u32 = 222;
/// Newest file format read (OpenVDB 6 to 12).
const LAST_VERSION: u32 = 224;
/// The compression flags of a grid.
const COMPRESS_ZIP: u32 = 0x1;
const COMPRESS_ACTIVE_MASK: u32 = 0x2;
const COMPRESS_BLOSC: u32 = 0x4;
/// The float tree of the three node levels 5, 4, 3 (log2 of a node's side in children).
const FLOAT_TREE: &str = "Tree_float_5_4_3";
const HALF_SUFFIX: &str = "_HalfFloat";
/// Log2 of the voxels along a side of a root child (32 x 16 x 8 = 4096).
const ROOT_CHILD_LOG2: u32 = 12;

/// A failure: (location, message), located as in [`GridError`].
type Fail = (String, String);

fn at(offset: usize) -> String {
    format!("byte offset {offset}")
}

/// A read position in the file's bytes; every read is bounds-checked.
struct Reader<'a> {
    b: &'a [u8],
    pos: usize,
}

impl<'a> Reader<'a> {
    fn take(&mut self, n: usize, what: &str) -> Result<&'a [u8], Fail> {
        let left = self.b.len() - self.pos;
        if n > left {
            return Err((
                at(self.pos),
                format!("{what} needs {n} bytes, the file ends after {left}"),
            ));
        }
        let s = &self.b[self.pos..self.pos + n];
        self.pos += n;
        Ok(s)
    }
    fn array<const N: usize>(&mut self, what: &str) -> Result<[u8; N], Fail> {
        Ok(self.take(N, what)?.try_into().expect("N bytes taken"))
    }
    fn u8(&mut self, what: &str) -> Result<u8, Fail> {
        Ok(self.array::<1>(what)?[0])
    }
    fn u32(&mut self, what: &str) -> Result<u32, Fail> {
        Ok(u32::from_le_bytes(self.array(what)?))
    }
    fn i32(&mut self, what: &str) -> Result<i32, Fail> {
        Ok(i32::from_le_bytes(self.array(what)?))
    }
    fn i64(&mut self, what: &str) -> Result<i64, Fail> {
        Ok(i64::from_le_bytes(self.array(what)?))
    }
    fn f32(&mut self, what: &str) -> Result<f32, Fail> {
        Ok(f32::from_le_bytes(self.array(what)?))
    }
    fn vec3d(&mut self, what: &str) -> Result<[f64; 3], Fail> {
        let mut v = [0.0; 3];
        for c in &mut v {
            *c = f64::from_le_bytes(self.array(what)?);
        }
        Ok(v)
    }
    fn coord(&mut self, what: &str) -> Result<[i64; 3], Fail> {
        Ok([self.i32(what)?, self.i32(what)?, self.i32(what)?].map(i64::from))
    }
    /// A string: u32 length, then its bytes (checked against the file before reading).
    fn string(&mut self, what: &str) -> Result<String, Fail> {
        let start = self.pos;
        let n = self.u32(what)? as usize;
        let bytes = self.take(n, what).map_err(|(_, m)| (at(start), m))?;
        String::from_utf8(bytes.to_vec())
            .map_err(|_| (at(start), format!("{what} is not UTF-8 text")))
    }
    /// A node mask of `words` u64.
    fn mask(&mut self, words: usize, what: &str) -> Result<Vec<u64>, Fail> {
        let b = self.take(8 * words, what)?;
        Ok(b.chunks_exact(8)
            .map(|c| u64::from_le_bytes(c.try_into().expect("8 bytes")))
            .collect())
    }
    /// Moves to `offset` (a descriptor's grid position), which must lie in the file.
    fn seek(&mut self, offset: i64, what: &str) -> Result<(), Fail> {
        match usize::try_from(offset) {
            Ok(o) if o <= self.b.len() => {
                self.pos = o;
                Ok(())
            }
            _ => Err((
                at(self.pos),
                format!(
                    "{what} {offset} is outside the file's {} bytes",
                    self.b.len()
                ),
            )),
        }
    }
}

fn bit(mask: &[u64], i: usize) -> bool {
    mask[i >> 6] >> (i & 63) & 1 == 1
}

/// A metadata table (of the file or a grid): skipped, each value by its stated size.
fn skip_metadata(r: &mut Reader) -> Result<(), Fail> {
    let count = r.u32("the metadata count")?;
    for _ in 0..count {
        r.string("a metadata name")?;
        r.string("a metadata type")?;
        let n = r.u32("a metadata value's size")? as usize;
        r.take(n, "a metadata value")?;
    }
    Ok(())
}

/// The header up to the grid descriptors; errors if it is not a file this reader reads.
fn header(r: &mut Reader) -> Result<(), Fail> {
    if r.b.len() < 8 || r.i64("the magic number")? != MAGIC {
        return Err((at(0), "not an OpenVDB file (no `VDB` magic number)".into()));
    }
    let version = r.u32("the file format version")?;
    if !(FIRST_VERSION..=LAST_VERSION).contains(&version) {
        return Err((
            at(8),
            format!("file format version {version} (read: {FIRST_VERSION} to {LAST_VERSION}, written by OpenVDB 3 and later)"),
        ));
    }
    r.u32("the library version")?;
    r.u32("the library version")?;
    if r.u8("the grid-offsets flag")? == 0 {
        return Err((
            at(r.pos - 1),
            "written as a stream without grid offsets (not read: write it to a file)".into(),
        ));
    }
    r.take(36, "the UUID")?;
    skip_metadata(r)
}

/// A grid descriptor: its name (without OpenVDB's `\x1e` suffix for duplicates), its type,
/// whether it instances another grid, where its data starts and ends.
struct Descriptor {
    name: String,
    tree: String,
    instance_of: String,
    grid_pos: i64,
    end_pos: i64,
}

fn descriptor(r: &mut Reader) -> Result<Descriptor, Fail> {
    let unique = r.string("a grid name")?;
    let name = unique.split('\u{1e}').next().unwrap_or("").to_string();
    let tree = r.string("a grid type")?;
    let instance_of = r.string("an instance parent")?;
    let grid_pos = r.i64("a grid position")?;
    r.i64("a block position")?;
    let end_pos = r.i64("a grid end position")?;
    Ok(Descriptor {
        name,
        tree,
        instance_of,
        grid_pos,
        end_pos,
    })
}

/// Finds the grid `name` among the descriptors and moves to its data; returns whether its
/// values are stored as half floats.
fn find_grid(r: &mut Reader, name: &str) -> Result<bool, Fail> {
    let count = r.i32("the grid count")?;
    let mut names = Vec::new();
    for _ in 0..count.max(0) {
        let start = r.pos;
        let d = descriptor(r)?;
        if d.name == name {
            if !d.instance_of.is_empty() {
                return Err((
                    at(start),
                    format!(
                        "grid {name:?} is an instance of grid {:?} (instanced grids are not read)",
                        d.instance_of
                    ),
                ));
            }
            let half = d.tree.strip_suffix(HALF_SUFFIX);
            if half.unwrap_or(&d.tree) != FLOAT_TREE {
                return Err((
                    at(start),
                    format!(
                        "grid {name:?} has type {:?} (read: float grids, {FLOAT_TREE})",
                        d.tree
                    ),
                ));
            }
            r.seek(d.grid_pos, "the grid position")?;
            return Ok(half.is_some());
        }
        if d.end_pos <= r.pos as i64 {
            return Err((
                at(start),
                format!(
                    "grid {:?} ends at {} before its descriptor does",
                    d.name, d.end_pos
                ),
            ));
        }
        r.seek(d.end_pos, "the grid end position")?;
        names.push(d.name);
    }
    Err((
        String::new(),
        format!("no grid named {name:?} (the file has {names:?}); name one with `grid`"),
    ))
}

/// Voxel (i, j, k) to world: a positive scale per axis, then a translation.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Transform {
    pub scale: [f64; 3],
    pub translate: [f64; 3],
}

impl Transform {
    fn world(&self, ijk: [i64; 3]) -> Vec3 {
        Vec3::from_array(
            [0, 1, 2].map(|k| (ijk[k] as f64 * self.scale[k] + self.translate[k]) as f32),
        )
    }
}

/// The grid's transform: scale and translation maps (and an affine map of that form).
fn transform(r: &mut Reader) -> Result<Transform, Fail> {
    let start = r.pos;
    let kind = r.string("the transform's type")?;
    let (scale, translate) = match kind.as_str() {
        "UniformScaleTranslateMap" | "ScaleTranslateMap" => {
            let t = r.vec3d("the translation")?;
            let s = r.vec3d("the scale")?;
            r.take(4 * 24, "the scale's derived values")?;
            (s, t)
        }
        "UniformScaleMap" | "ScaleMap" => {
            let s = r.vec3d("the scale")?;
            r.take(4 * 24, "the scale's derived values")?;
            (s, [0.0; 3])
        }
        "TranslationMap" => ([1.0; 3], r.vec3d("the translation")?),
        "AffineMap" => {
            let mut m = [[0.0f64; 4]; 4];
            for row in &mut m {
                let a = r.vec3d("the affine matrix")?;
                let w = f64::from_le_bytes(r.array("the affine matrix")?);
                *row = [a[0], a[1], a[2], w];
            }
            let axis_aligned = (0..4).all(|i| (0..4).all(|j| i == j || i == 3 || m[i][j] == 0.0));
            if !axis_aligned || m[3][3] != 1.0 {
                return Err((at(start), format!("an affine transform with rotation, shear or projection ({m:?}): read are scale and translation")));
            }
            ([m[0][0], m[1][1], m[2][2]], [m[3][0], m[3][1], m[3][2]])
        }
        other => {
            return Err((
                at(start),
                format!("transform {other:?} (read: scale and translation maps)"),
            ))
        }
    };
    if !(scale.iter().all(|s| s.is_finite() && *s > 0.0) && translate.iter().all(|t| t.is_finite()))
    {
        return Err((
            at(start),
            format!("transform scale {scale:?}, translation {translate:?}: the scale must be positive and both finite"),
        ));
    }
    Ok(Transform { scale, translate })
}

/// A region of constant value: a tile (of any level) with its first voxel and side.
struct Tile {
    origin: [i64; 3],
    side: i64,
    value: f32,
}

/// The tree's topology: tiles, leaves (first voxel and value mask) and the active bounding box.
struct Topology {
    flags: u32,
    half: bool,
    background: f32,
    tiles: Vec<Tile>,
    leaves: Vec<[i64; 3]>,
    lo: [i64; 3],
    hi: [i64; 3],
}

impl Topology {
    fn include(&mut self, lo: [i64; 3], side: i64) {
        self.lo = [0, 1, 2].map(|k| self.lo[k].min(lo[k]));
        self.hi = [0, 1, 2].map(|k| self.hi[k].max(lo[k] + side - 1));
    }

    fn tile(
        &mut self,
        r: &Reader,
        origin: [i64; 3],
        side: i64,
        value: f32,
        active: bool,
    ) -> Result<(), Fail> {
        if active {
            self.include(origin, side);
        }
        if active || value != self.background {
            if self.tiles.len() == MAX_VDB_TILES {
                return Err((
                    at(r.pos),
                    format!("more than {MAX_VDB_TILES} tiles (the limit of a VDB grid)"),
                ));
            }
            self.tiles.push(Tile {
                origin,
                side,
                value,
            });
        }
        Ok(())
    }
}

/// The position of child `n` of a node of side 2^log2 children (x slowest, z fastest).
fn child_offset(n: usize, log2: u32) -> [i64; 3] {
    let m = (1usize << log2) - 1;
    [n >> (2 * log2), (n >> log2) & m, n & m].map(|c| c as i64)
}

/// An internal node's topology (log2 side 5 or 4): masks, tile values, then its children.
fn internal(r: &mut Reader, t: &mut Topology, origin: [i64; 3], log2: u32) -> Result<(), Fail> {
    let n = 1usize << (3 * log2);
    let child_log2 = if log2 == 5 { 7 } else { 3 };
    let children = r.mask(n / 64, "a node's child mask")?;
    let active = r.mask(n / 64, "a node's value mask")?;
    let values = compressed_values(r, t, n, &active)?;
    let at_child = |i: usize| child_offset(i, log2).map(|c| c << child_log2);
    for i in (0..n).filter(|&i| !bit(&children, i)) {
        let o = at_child(i);
        let origin = [0, 1, 2].map(|k| origin[k] + o[k]);
        t.tile(r, origin, 1 << child_log2, values[i], bit(&active, i))?;
    }
    for i in (0..n).filter(|&i| bit(&children, i)) {
        let o = at_child(i);
        let child = [0, 1, 2].map(|k| origin[k] + o[k]);
        if log2 == 5 {
            internal(r, t, child, 4)?;
        } else {
            let mask = r.mask(8, "a leaf's value mask")?;
            if t.leaves.len() == MAX_VDB_LEAVES {
                return Err((
                    at(r.pos),
                    format!("more than {MAX_VDB_LEAVES} leaves (the limit of a VDB grid)"),
                ));
            }
            for v in (0..512).filter(|&v| bit(&mask, v)) {
                let o = child_offset(v, 3);
                t.include([0, 1, 2].map(|k| child[k] + o[k]), 1);
            }
            t.leaves.push(child);
        }
    }
    Ok(())
}

/// The grid's compression flags, transform and topology (the root's tiles and children).
fn topology(r: &mut Reader, half: bool) -> Result<(Transform, Topology), Fail> {
    let fpos = r.pos;
    let flags = r.u32("the compression flags")?;
    if flags & !(COMPRESS_ZIP | COMPRESS_ACTIVE_MASK | COMPRESS_BLOSC) != 0 {
        return Err((
            at(fpos),
            format!("compression flags {flags:#x} (known: zip 0x1, active mask 0x2, Blosc 0x4)"),
        ));
    }
    skip_metadata(r)?;
    let xf = transform(r)?;
    let bpos = r.pos;
    let buffers = r.i32("the buffer count")?;
    if buffers != 1 {
        return Err((
            at(bpos),
            format!("{buffers} buffers per node (a tree has 1)"),
        ));
    }
    let bpos = r.pos;
    let background = r.f32("the background value")?;
    if background != 0.0 {
        return Err((at(bpos), format!("background value {background}: a density grid's background must be 0 (the medium ends at the grid's box)")));
    }
    let mut t = Topology {
        flags,
        half,
        background,
        tiles: Vec::new(),
        leaves: Vec::new(),
        lo: [i64::MAX; 3],
        hi: [i64::MIN; 3],
    };
    let tiles = r.u32("the root's tile count")?;
    let children = r.u32("the root's child count")?;
    for _ in 0..tiles {
        let origin = r.coord("a root tile")?;
        let value = r.f32("a root tile's value")?;
        let active = r.u8("a root tile's state")? != 0;
        t.tile(r, origin, 1 << ROOT_CHILD_LOG2, value, active)?;
    }
    for _ in 0..children {
        let origin = r.coord("a root child's origin")?;
        internal(r, &mut t, origin, 5)?;
    }
    Ok((xf, t))
}

/// A node's `n` values as OpenVDB's `readCompressedValues` stores them: a metadata byte saying
/// which inactive values are stored, those values and a selection mask, then the active values
/// (all values, without mask compression), zip- or Blosc-compressed, floats or halves.
fn compressed_values(
    r: &mut Reader,
    t: &Topology,
    n: usize,
    active: &[u64],
) -> Result<Vec<f32>, Fail> {
    let mpos = r.pos;
    let meta = r.u8("a value array's metadata byte")?;
    if meta > 6 {
        return Err((
            at(mpos),
            format!("value array metadata {meta} (known: 0 to 6)"),
        ));
    }
    let bg = t.background;
    let mut inactive = [if meta == 0 { bg } else { -bg }, bg];
    if matches!(meta, 2 | 4 | 5) {
        inactive[0] = r.f32("an inactive value")?;
    }
    if meta == 5 {
        inactive[1] = r.f32("an inactive value")?;
    }
    let selection = if matches!(meta, 3..=5) {
        Some(r.mask(n / 64, "a selection mask")?)
    } else {
        None
    };
    let count = if t.flags & COMPRESS_ACTIVE_MASK != 0 && meta != 6 {
        active.iter().map(|w| w.count_ones() as usize).sum()
    } else {
        n
    };
    let size = if t.half { 2 } else { 4 };
    // OpenVDB's half writer writes nothing at all for an empty array (the float one a size)
    let bytes = match t.half && count == 0 {
        true => Vec::new(),
        false => data(r, t.flags, count * size)?,
    };
    let read: Vec<f32> = if t.half {
        bytes
            .chunks_exact(2)
            .map(|c| half::f16::from_le_bytes([c[0], c[1]]).to_f32())
            .collect()
    } else {
        bytes
            .chunks_exact(4)
            .map(|c| f32::from_le_bytes(c.try_into().expect("4 bytes")))
            .collect()
    };
    if count == n {
        return Ok(read);
    }
    let mut next = read.into_iter();
    Ok((0..n)
        .map(|i| match bit(active, i) {
            true => next.next().unwrap_or(bg),
            false => inactive[usize::from(selection.as_ref().is_some_and(|s| bit(s, i)))],
        })
        .collect())
}

/// `nbytes` of data: stored, or zip or Blosc compressed behind an i64 size (negative: stored).
fn data(r: &mut Reader, flags: u32, nbytes: usize) -> Result<Vec<u8>, Fail> {
    if flags & (COMPRESS_ZIP | COMPRESS_BLOSC) == 0 {
        return Ok(r.take(nbytes, "a value array")?.to_vec());
    }
    let start = r.pos;
    let size = r.i64("a compressed size")?;
    if size <= 0 {
        let stored = size.unsigned_abs() as usize;
        if stored != nbytes {
            return Err((
                at(start),
                format!("a stored chunk of {stored} bytes where the node holds {nbytes}"),
            ));
        }
        return Ok(r.take(nbytes, "a value array")?.to_vec());
    }
    let src = r.take(
        usize::try_from(size).unwrap_or(usize::MAX),
        "a compressed value array",
    )?;
    let out = if flags & COMPRESS_BLOSC != 0 {
        blosc(src, nbytes)
    } else {
        inflate(src, nbytes)
    };
    out.map_err(|m| (at(start), m))
}

/// A zlib stream that must inflate to exactly `nbytes`.
fn inflate(src: &[u8], nbytes: usize) -> Result<Vec<u8>, String> {
    let mut out = Vec::with_capacity(nbytes);
    flate2::read::ZlibDecoder::new(src)
        .take(nbytes as u64 + 1)
        .read_to_end(&mut out)
        .map_err(|e| format!("a zip-compressed value array does not inflate: {e}"))?;
    if out.len() != nbytes {
        return Err(format!(
            "a zip-compressed value array inflates to {} bytes where the node holds {nbytes}",
            out.len()
        ));
    }
    Ok(out)
}

/// The Blosc 1 codec of compressor `code` (bits 5-7 of the flags).
fn blosc_codec(code: u8, src: &[u8], out: &mut [u8]) -> Result<(), String> {
    let got = match code {
        1 => lz4_flex::block::decompress_into(src, out)
            .map_err(|e| format!("a Blosc-LZ4 block does not decode: {e}"))?,
        3 => {
            let v = inflate(src, out.len())?;
            out.copy_from_slice(&v);
            v.len()
        }
        _ => {
            let name = ["blosclz", "lz4", "snappy", "zlib", "zstd"]
                .get(code as usize)
                .unwrap_or(&"unknown");
            return Err(format!(
                "Blosc compressor {code} ({name}) is not read (read: lz4 as OpenVDB writes, zlib)"
            ));
        }
    };
    if got != out.len() {
        return Err(format!(
            "a Blosc block decodes to {got} bytes, not {}",
            out.len()
        ));
    }
    Ok(())
}

/// A Blosc 1 chunk that must hold exactly `nbytes`: the 16-byte header (version, codec
/// version, flags, type size, sizes), block starts, each block in one or `typesize` splits of
/// an i32 size and the codec's bytes (stored when the size equals the split's), byte-unshuffled.
fn blosc(src: &[u8], nbytes: usize) -> Result<Vec<u8>, String> {
    let u32_at = |o: usize| {
        src.get(o..o + 4)
            .map(|b| u32::from_le_bytes(b.try_into().expect("4 bytes")) as usize)
    };
    if src.len() < 16 {
        return Err(format!(
            "a Blosc chunk of {} bytes, shorter than its 16-byte header",
            src.len()
        ));
    }
    let (flags, typesize) = (src[2], src[3] as usize);
    let (size, blocksize) = (u32_at(4).unwrap_or(0), u32_at(8).unwrap_or(0));
    if size != nbytes {
        return Err(format!(
            "a Blosc chunk of {size} bytes where the node holds {nbytes}"
        ));
    }
    if flags & 0x4 != 0 || typesize == 0 || blocksize == 0 {
        return Err(format!("a Blosc chunk with flags {flags:#x}, type size {typesize}, block size {blocksize} (read: byte shuffle or none, sizes > 0)"));
    }
    let mut out = vec![0u8; nbytes];
    if flags & 0x2 != 0 {
        let body = src
            .get(16..16 + nbytes)
            .ok_or("a stored Blosc chunk shorter than its data")?;
        out.copy_from_slice(body);
        return Ok(out);
    }
    let nblocks = nbytes.div_ceil(blocksize);
    let dont_split = flags & 0x10 != 0;
    let mut tmp = vec![0u8; blocksize.min(nbytes)];
    for j in 0..nblocks {
        let bsize = blocksize.min(nbytes - j * blocksize);
        let leftover = bsize < blocksize;
        let mut pos = u32_at(16 + 4 * j).ok_or("Blosc block starts past the chunk's end")?;
        let splits = if !dont_split && typesize <= 16 && bsize / typesize >= 128 && !leftover {
            typesize
        } else {
            1
        };
        let neblock = bsize / splits;
        for s in 0..splits {
            let cbytes = u32_at(pos).ok_or("a Blosc split size past the chunk's end")?;
            let body = src
                .get(pos + 4..(pos + 4).saturating_add(cbytes))
                .ok_or("a Blosc split past the chunk's end")?;
            let dst = &mut tmp[s * neblock..(s + 1) * neblock];
            if cbytes == neblock {
                dst.copy_from_slice(body);
            } else {
                blosc_codec(flags >> 5, body, dst)?;
            }
            pos += 4 + cbytes;
        }
        let block = &mut out[j * blocksize..j * blocksize + bsize];
        if flags & 0x1 != 0 && typesize > 1 {
            unshuffle(typesize, &tmp[..bsize], block);
        } else {
            block.copy_from_slice(&tmp[..bsize]);
        }
    }
    Ok(out)
}

/// Blosc's byte unshuffle: byte j of element i was stored at j * elements + i; the bytes past
/// the last whole element are stored as they are.
fn unshuffle(typesize: usize, src: &[u8], dst: &mut [u8]) {
    let elements = src.len() / typesize;
    for i in 0..elements {
        for j in 0..typesize {
            dst[i * typesize + j] = src[j * elements + i];
        }
    }
    let tail = elements * typesize;
    dst[tail..].copy_from_slice(&src[tail..]);
}

/// A dense lattice: its first voxel, its sides and its values (x fastest).
type Lattice = ([i64; 3], [usize; 3], Vec<f32>);

/// The dense lattice over the active box grown by one voxel, its tiles painted, then the
/// leaves' buffers read into it.
fn lattice(r: &mut Reader, t: &Topology) -> Result<Lattice, Fail> {
    if t.lo[0] > t.hi[0] {
        return Err((
            String::new(),
            "the grid has no active voxels or tiles".into(),
        ));
    }
    let lo = t.lo.map(|c| c - 1);
    let span = [0, 1, 2].map(|k| t.hi[k] + 1 - lo[k] + 1);
    let res = span.map(|s| usize::try_from(s).unwrap_or(usize::MAX));
    let n = res[0]
        .checked_mul(res[1])
        .and_then(|n| n.checked_mul(res[2]));
    if res.iter().any(|&s| s > MAX_GRID_SIDE) || n.is_none_or(|n| n > MAX_GRID_VERTICES) {
        return Err((String::new(), format!("the active voxels and a voxel of margin span {span:?} voxels: every side must be at most {MAX_GRID_SIDE} and the voxels at most {MAX_GRID_VERTICES}")));
    }
    let mut values = vec![t.background; n.unwrap_or(0)];
    let index = |p: [i64; 3]| -> Option<usize> {
        let d = [0, 1, 2].map(|k| p[k] - lo[k]);
        (0..3)
            .all(|k| d[k] >= 0 && d[k] < span[k])
            .then(|| (d[0] + span[0] * (d[1] + span[1] * d[2])) as usize)
    };
    for tile in &t.tiles {
        // the tile clipped to the lattice
        let a = [0, 1, 2].map(|k| tile.origin[k].max(lo[k]));
        let b = [0, 1, 2].map(|k| (tile.origin[k] + tile.side - 1).min(lo[k] + span[k] - 1));
        for z in a[2]..=b[2] {
            for y in a[1]..=b[1] {
                for x in a[0]..=b[0] {
                    if let Some(i) = index([x, y, z]) {
                        values[i] = tile.value;
                    }
                }
            }
        }
    }
    for origin in &t.leaves {
        let mask = r.mask(8, "a leaf's value mask")?;
        let leaf = compressed_values(r, t, 512, &mask)?;
        for (v, value) in leaf.into_iter().enumerate() {
            let o = child_offset(v, 3);
            if let Some(i) = index([0, 1, 2].map(|k| origin[k] + o[k])) {
                values[i] = value;
            }
        }
    }
    if let Some(i) = values.iter().position(|v| !v.is_finite() || *v < 0.0) {
        let p = [i % res[0], i / res[0] % res[1], i / (res[0] * res[1])].map(|c| c as i64);
        let voxel = [0, 1, 2].map(|k| lo[k] + p[k]);
        return Err((
            String::new(),
            format!(
                "voxel {voxel:?} = {} is not a finite density >= 0",
                values[i]
            ),
        ));
    }
    Ok((lo, res, values))
}

/// Reads the float grid `name` of an OpenVDB file's bytes: the lattice and its world box.
pub fn parse_vdb(bytes: &[u8], name: &str) -> Result<GridFile, Fail> {
    let mut r = Reader { b: bytes, pos: 0 };
    header(&mut r)?;
    let half = find_grid(&mut r, name)?;
    let (xf, t) = topology(&mut r, half)?;
    let (lo, res, values) = lattice(&mut r, &t)?;
    let hi = [0, 1, 2].map(|k| lo[k] + res[k] as i64 - 1);
    let (wlo, whi) = (xf.world(lo), xf.world(hi));
    if !(wlo.is_finite() && whi.is_finite() && wlo.cmplt(whi).all()) {
        return Err((String::new(), format!("the grid's box {wlo} .. {whi} in world space is not a finite box with min < max (in f32)")));
    }
    let grid = Grid::new(res, values).map_err(|e| (String::new(), e.to_string()))?;
    Ok(GridFile {
        grid,
        bounds: Some((wlo, whi)),
    })
}

/// Reads the float grid `name` of the OpenVDB file at `path`, with the FNV-1a hash of its bytes
/// (a render's identity).
pub fn read_vdb_file_hashed(path: &Path, name: &str) -> Result<(GridFile, u64), GridError> {
    let err = |location: String, message: String| GridError {
        file: path.display().to_string(),
        location,
        message,
    };
    let bytes = crate::conventions::read_at_most(path, MAX_GRID_FILE_BYTES)
        .map_err(|e| err(String::new(), format!("cannot read: {e}")))?;
    let hash = crate::conventions::fnv1a(&bytes);
    parse_vdb(&bytes, name)
        .map(|g| (g, hash))
        .map_err(|(l, m)| err(l, m))
}
