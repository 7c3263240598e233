//! Density grids: values on the vertices of a regular lattice spanning the medium's bounding box,
//! trilinearly interpolated in between (Pauly, Kollig, Keller 2000, footnote 5: "We store
//! inhomogeneous media on a three-dimensional grid with intermediate values being computed
//! through tri-linear interpolation"), read from a file or baked from a procedural field.
//!
//! Along a ray, trilinear interpolation inside one cell is a product of three affine functions
//! of t, a cubic; two-point Gauss-Legendre quadrature integrates cubics exactly, so
//! [`Grid::integrate`] computes the optical depth of the interpolated density exactly (to float
//! rounding) by visiting every cell the ray crosses (a 3-D DDA, [`cell_segments`]).
//!
//! File formats (both put the value of vertex (x, y, z) at index x + nx (y + ny z)):
//! * text (any extension but `.vol`): `#` starts a comment; the first three numbers are
//!   nx ny nz (each >= 2), then nx ny nz density values, whitespace-separated;
//! * Mitsuba's binary `.vol`: bytes `VOL`, version 3, i32 encoding (1 = float32, the only one
//!   read), i32 nx, ny, nz, i32 channels (1), six f32 for the bounding box (min xyz, max xyz),
//!   then the float32 values, all little-endian. DEVIATION: Mitsuba 3 places values at cell
//!   centres; pathspace, like Mitsuba 0.6, at the lattice vertices spanning the box.
//!
//! Limits: every side in 2..=[`MAX_GRID_SIDE`], at most [`MAX_GRID_VERTICES`] vertices, and a
//! header is checked against the file's size (the values it can hold at all) before the values
//! are reserved, so a 15-byte file cannot claim a 4 GiB grid.
//!
//! Book: "Table 1: inhomogeneous media" (`book/src/table1-inhomogeneous.md`); executable spec:
//! `tests/spec/medium/heterogeneous.rs`.

use glam::{Vec3, Vec4};
use std::path::Path;

/// Largest accepted lattice side (vertices per axis): keeps a malformed header from allocating.
pub const MAX_GRID_SIDE: usize = 1024;
/// Largest accepted number of vertices (512^3, 512 MiB of f32): a grid's memory is bounded
/// whatever its sides.
pub const MAX_GRID_VERTICES: usize = 1 << 27;

/// The largest grid file read: a `.vol` at [`MAX_GRID_VERTICES`] takes 512 MiB and its header,
/// a text grid about 8 bytes a value, so 1 GiB holds either at the vertex limit.
pub const MAX_GRID_FILE_BYTES: u64 = 1 << 30;

/// Size of the `.vol` header in bytes: 3 magic + 1 version + 5 i32 + 6 f32.
const VOL_HEADER_BYTES: usize = 48;
/// The `.vol` version byte pathspace reads.
const VOL_VERSION: u8 = 3;
/// The `.vol` encoding code of float32 data.
const VOL_FLOAT32: i32 = 1;

/// Gauss-Legendre 2-point abscissae on [0, 1]: (1 -+ 1/sqrt(3)) / 2; exact for cubics.
pub const GAUSS2: [f32; 2] = [0.211_324_87, 0.788_675_1];

/// A lattice of density values on the unit cube of the medium's local coordinates.
#[derive(Clone, Debug, PartialEq)]
pub struct Grid {
    /// Vertices per axis (each >= 2).
    pub res: [usize; 3],
    /// `res[0] * res[1] * res[2]` values, x fastest.
    pub values: Vec<f32>,
}

/// Why a grid was rejected: the message names the file and the line or byte offset.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{file}: {}{message}", if location.is_empty() { String::new() } else { format!("{location}: ") })]
pub struct GridError {
    pub file: String,
    /// `line N` (text) or `byte offset N` (binary), `header`, or empty for the whole file.
    pub location: String,
    pub message: String,
}

/// Why [`Grid::new`] rejected a lattice.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum LatticeError {
    /// A side outside 2..=MAX_GRID_SIDE, or more than MAX_GRID_VERTICES vertices.
    #[error("grid resolution {0:?}: every side must be in 2..={max} and the vertices at most {total}", max = MAX_GRID_SIDE, total = MAX_GRID_VERTICES)]
    Resolution([usize; 3]),
    /// The number of values is not the product of the sides.
    #[error("grid {res:?} needs {n} values, got {got}")]
    Count {
        res: [usize; 3],
        n: usize,
        got: usize,
    },
    /// A density that is negative or not finite.
    #[error("value #{0} = {1} is not a finite density >= 0")]
    Value(usize, f32),
}

/// A grid file's content: the lattice and, for `.vol`, the bounding box it declares.
pub struct GridFile {
    pub grid: Grid,
    pub bounds: Option<(Vec3, Vec3)>,
}

impl Grid {
    /// Validated constructor: every side >= 2, the right number of values, each finite and >= 0.
    pub fn new(res: [usize; 3], values: Vec<f32>) -> Result<Self, LatticeError> {
        if res.iter().any(|&n| !(2..=MAX_GRID_SIDE).contains(&n)) || vertices(res).is_none() {
            return Err(LatticeError::Resolution(res));
        }
        let n = res[0] * res[1] * res[2];
        if values.len() != n {
            return Err(LatticeError::Count {
                res,
                n,
                got: values.len(),
            });
        }
        if let Some((i, v)) = values
            .iter()
            .enumerate()
            .find(|(_, v)| !v.is_finite() || **v < 0.0)
        {
            return Err(LatticeError::Value(i, *v));
        }
        Ok(Grid { res, values })
    }

    /// Bakes `f` (on local coordinates in [0,1]^3) onto an `n`^3 lattice.
    pub fn bake(n: usize, f: impl Fn(Vec3) -> f32) -> Self {
        let mut values = Vec::with_capacity(n * n * n);
        let scale = 1.0 / (n - 1) as f32;
        for z in 0..n {
            for y in 0..n {
                for x in 0..n {
                    values.push(f(Vec3::new(x as f32, y as f32, z as f32) * scale));
                }
            }
        }
        Grid {
            res: [n, n, n],
            values,
        }
    }

    #[inline]
    fn at(&self, x: usize, y: usize, z: usize) -> f32 {
        self.values[x + self.res[0] * (y + self.res[1] * z)]
    }

    /// Lattice coordinates of local point `u`: u * (res - 1).
    #[inline]
    pub fn lattice(&self) -> Vec3 {
        Vec3::new(
            (self.res[0] - 1) as f32,
            (self.res[1] - 1) as f32,
            (self.res[2] - 1) as f32,
        )
    }

    // ANCHOR: trilinear
    /// Trilinear interpolation at local point `u` in [0,1]^3 (clamped to the box).
    #[inline]
    pub fn eval(&self, u: Vec3) -> f32 {
        let (base, f) = self.locate(u);
        trilinear(&self.cell(base), f)
    }

    /// The cell holding local point `u` (clamped to the box): the index of its first vertex,
    /// and `u`'s position in it.
    #[inline]
    fn locate(&self, u: Vec3) -> (usize, Vec3) {
        let g = (u.clamp(Vec3::ZERO, Vec3::ONE)) * self.lattice();
        // g >= 0, so truncation is the floor (without a libm call); g = res - 1 on the far
        // face belongs to the last cell
        let cell = |k: usize| (g[k] as usize).min(self.res[k] - 2);
        let (x, y, z) = (cell(0), cell(1), cell(2));
        let f = g - Vec3::new(x as f32, y as f32, z as f32);
        let (dy, dz) = (self.res[0], self.res[0] * self.res[1]);
        (x + dy * y + dz * z, f)
    }

    /// The eight vertex values of the cell whose first vertex is `base`, as the corner pairs
    /// along x: (000, 100), (010, 110), (001, 101), (011, 111), lower ends first.
    #[inline(always)]
    fn cell(&self, base: usize) -> [Vec4; 2] {
        // the cell's eight vertices from one bounds-checked slice
        let (dy, dz) = (self.res[0], self.res[0] * self.res[1]);
        let v = &self.values[base..=base + 1 + dy + dz];
        [
            Vec4::new(v[0], v[dy], v[dz], v[dy + dz]),
            Vec4::new(v[1], v[dy + 1], v[dz + 1], v[dy + dz + 1]),
        ]
    }

    /// [`Grid::eval`] at two points, the cell read once when both lie in it (as the two
    /// Gauss points of a span in [`Grid::integrate`] do): the same values as two calls.
    #[inline]
    pub fn eval_pair(&self, a: Vec3, b: Vec3) -> (f32, f32) {
        let ((base_a, fa), (base_b, fb)) = (self.locate(a), self.locate(b));
        let ca = self.cell(base_a);
        let cb = if base_b == base_a {
            ca
        } else {
            self.cell(base_b)
        };
        (trilinear(&ca, fa), trilinear(&cb, fb))
    }
    // ANCHOR_END: trilinear

    /// The largest vertex value in the local box [lo, hi]: an upper bound of the trilinear
    /// interpolant there (it is a convex combination of the surrounding vertices).
    pub fn max_in(&self, lo: Vec3, hi: Vec3) -> f32 {
        let l = self.lattice();
        let a = (lo.clamp(Vec3::ZERO, Vec3::ONE) * l).floor();
        let b = (hi.clamp(Vec3::ZERO, Vec3::ONE) * l).ceil();
        let mut m = 0.0f32;
        for z in a.z as usize..=b.z as usize {
            for y in a.y as usize..=b.y as usize {
                for x in a.x as usize..=b.x as usize {
                    m = m.max(self.at(x, y, z));
                }
            }
        }
        m
    }

    // ANCHOR: grid_integrate
    /// The exact integral of the interpolated density over t in [ta, tb] along the local line
    /// u(t) = u0 + t du: cell by cell, two-point Gauss-Legendre (exact for the cubic that
    /// trilinear interpolation is along a line).
    pub fn integrate(&self, u0: Vec3, du: Vec3, ta: f32, tb: f32) -> f32 {
        let l = self.lattice();
        let mut sum = 0.0f32;
        for (a, b) in cell_spans(u0 * l, du * l, ta, tb) {
            let h = b - a;
            let (f0, f1) =
                self.eval_pair(u0 + du * (a + GAUSS2[0] * h), u0 + du * (a + GAUSS2[1] * h));
            sum += 0.5 * h * (f0 + f1);
        }
        sum
    }
    // ANCHOR_END: grid_integrate

    /// [`Grid::integrate`] bit for bit, without reading the cells `empty` marks: a span whose
    /// two Gauss points lie in empty cells adds 0.5 h (0 + 0) = +0, which leaves the sum as it
    /// is, so only the lookups are saved (in the cloud's box, most of a ray's cells).
    pub fn integrate_skipping(
        &self,
        empty: &EmptyCells,
        u0: Vec3,
        du: Vec3,
        ta: f32,
        tb: f32,
    ) -> f32 {
        let l = self.lattice();
        let mut sum = 0.0f32;
        for (a, b) in cell_spans(u0 * l, du * l, ta, tb) {
            let h = b - a;
            let (pa, pb) = (u0 + du * (a + GAUSS2[0] * h), u0 + du * (a + GAUSS2[1] * h));
            let ((base_a, fa), (base_b, fb)) = (self.locate(pa), self.locate(pb));
            if empty.contains(base_a) && empty.contains(base_b) {
                continue;
            }
            // the operations of `eval_pair`
            let ca = self.cell(base_a);
            let cb = if base_b == base_a {
                ca
            } else {
                self.cell(base_b)
            };
            sum += 0.5 * h * (trilinear(&ca, fa) + trilinear(&cb, fb));
        }
        sum
    }
}

/// The cells of a grid whose eight vertices are all zero, one bit per cell, indexed by the
/// cell's first vertex (as `Grid::locate` names it): the interpolated density is exactly zero
/// there, whatever the position in the cell.
#[derive(Clone, Debug, PartialEq)]
pub struct EmptyCells {
    bits: Vec<u64>,
}

impl EmptyCells {
    pub fn new(g: &Grid) -> Self {
        let mut bits = vec![0u64; g.values.len().div_ceil(64)];
        let [nx, ny, nz] = g.res;
        for z in 0..nz - 1 {
            for y in 0..ny - 1 {
                for x in 0..nx - 1 {
                    let base = x + nx * (y + ny * z);
                    if g.cell(base) == [Vec4::ZERO; 2] {
                        bits[base / 64] |= 1 << (base % 64);
                    }
                }
            }
        }
        EmptyCells { bits }
    }

    /// True if the cell whose first vertex is `base` is empty.
    #[inline]
    pub fn contains(&self, base: usize) -> bool {
        (self.bits[base / 64] >> (base % 64)) & 1 != 0
    }
}

/// Trilinear interpolation in one cell (`Grid::cell`'s corner pairs) at position `f` in it:
/// along x in the four lanes at once (lane by lane the scalar `a + (b - a) t`), then y, then z.
#[inline]
fn trilinear(c: &[Vec4; 2], f: Vec3) -> f32 {
    let lerp = |a: f32, b: f32, t: f32| a + (b - a) * t;
    let x = c[0] + (c[1] - c[0]) * f.x;
    lerp(lerp(x.x, x.y, f.y), lerp(x.z, x.w, f.y), f.z)
}

// ANCHOR: dda
/// The pieces of t in [ta, tb] during which the line g(t) = g0 + t gd (in lattice units, cells
/// of side 1, `cells` per axis) stays in one cell: (t_start, t_end, cell index, x fastest). A 3-D
/// DDA (Amanatides and Woo 1987): the next crossing along each axis is tracked, the nearest
/// taken, and the cell index stepped along that axis. The first cell is the one holding the
/// first piece's midpoint (a line starting on a face belongs to the cell it enters); a step
/// that would leave the lattice, which only rounding at the far end allows, keeps the last
/// cell, as the midpoint would clamped to the lattice.
pub fn cell_segments(
    g0: Vec3,
    gd: Vec3,
    ta: f32,
    tb: f32,
    cells: [usize; 3],
) -> impl Iterator<Item = (f32, f32, usize)> {
    let (next, _) = crossings(g0, gd, ta);
    let stride = [1, cells[0], cells[0] * cells[1]];
    let first_end = next[0].min(next[1]).min(next[2]).min(tb);
    let mid = g0 + gd * (0.5 * (ta + first_end));
    let mut cell = [0, 1, 2].map(|k| (mid[k].max(0.0) as usize).min(cells[k] - 1));
    let mut index = cell[0] + stride[1] * cell[1] + stride[2] * cell[2];
    dda(g0, gd, ta, tb).map(move |(t, end, a)| {
        let piece = (t, end, index);
        if gd[a] > 0.0 && cell[a] + 1 < cells[a] {
            cell[a] += 1;
            index += stride[a];
        } else if gd[a] < 0.0 && cell[a] > 0 {
            cell[a] -= 1;
            index -= stride[a];
        }
        piece
    })
}

/// The first crossing of a cell face after `ta` along each axis of g0 + t gd, and the t
/// between crossings (infinite along an axis the line does not move on).
#[inline]
fn crossings(g0: Vec3, gd: Vec3, ta: f32) -> ([f32; 3], [f32; 3]) {
    let start = g0 + gd * ta;
    let mut next = [f32::INFINITY; 3];
    let mut step = [f32::INFINITY; 3];
    for a in 0..3 {
        if gd[a] > 0.0 {
            next[a] = ta + (start[a].floor() + 1.0 - start[a]) / gd[a];
            step[a] = 1.0 / gd[a];
        } else if gd[a] < 0.0 {
            next[a] = ta + (start[a].ceil() - 1.0 - start[a]) / gd[a];
            step[a] = -1.0 / gd[a];
        }
    }
    (next, step)
}

/// The axis of the nearest crossing (the first of equals).
#[inline]
fn nearest_axis(next: &[f32; 3]) -> usize {
    if next[0] <= next[1] && next[0] <= next[2] {
        0
    } else if next[1] <= next[2] {
        1
    } else {
        2
    }
}

/// [`cell_segments`] without the cell index, for callers that need only the pieces.
pub fn cell_spans(g0: Vec3, gd: Vec3, ta: f32, tb: f32) -> impl Iterator<Item = (f32, f32)> {
    dda(g0, gd, ta, tb).map(|(t, end, _)| (t, end))
}

/// The walk both share: (t_start, t_end, the axis whose face ends the piece; at `tb` the axis
/// of the next crossing).
#[inline]
fn dda(g0: Vec3, gd: Vec3, ta: f32, tb: f32) -> impl Iterator<Item = (f32, f32, usize)> {
    let (mut next, step) = crossings(g0, gd, ta);
    let mut t = ta;
    std::iter::from_fn(move || {
        if t >= tb {
            return None;
        }
        let a = nearest_axis(&next);
        let end = next[a].min(tb);
        let piece = (t, end, a);
        t = end;
        next[a] += step[a];
        Some(piece)
    })
}
// ANCHOR_END: dda

/// The number of vertices of a lattice with sides `res`, if within [`MAX_GRID_VERTICES`].
fn vertices(res: [usize; 3]) -> Option<usize> {
    let n = res[0].checked_mul(res[1])?.checked_mul(res[2])?;
    (n <= MAX_GRID_VERTICES).then_some(n)
}

/// [`vertices`] for a file's header; errors as (location, message).
fn checked_vertices(res: [usize; 3]) -> Result<usize, (String, String)> {
    vertices(res).ok_or_else(|| {
        (
            "header".to_string(),
            format!(
                "a {res:?} grid has more than the {MAX_GRID_VERTICES} vertices a grid may have"
            ),
        )
    })
}

/// Reads a grid file: Mitsuba `.vol` by extension, the text format otherwise.
pub fn read_grid_file(path: &Path) -> Result<GridFile, GridError> {
    read_grid_file_hashed(path).map(|(g, _)| g)
}

/// [`read_grid_file`] with the FNV-1a hash of the bytes it parsed (a render's identity).
pub fn read_grid_file_hashed(path: &Path) -> Result<(GridFile, u64), GridError> {
    let name = path.display().to_string();
    let err = |location: String, message: String| GridError {
        file: name.clone(),
        location,
        message,
    };
    let bytes = crate::conventions::read_at_most(path, MAX_GRID_FILE_BYTES)
        .map_err(|e| err(String::new(), format!("cannot read: {e}")))?;
    let hash = crate::conventions::fnv1a(&bytes);
    let grid = if path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("vol"))
    {
        parse_vol(&bytes).map_err(|(loc, msg)| err(loc, msg))
    } else {
        let text = String::from_utf8(bytes)
            .map_err(|e| err(String::new(), format!("not UTF-8 text: {e}")))?;
        parse_text(&text)
            .map(|grid| GridFile { grid, bounds: None })
            .map_err(|(loc, msg)| err(loc, msg))
    };
    grid.map(|g| (g, hash))
}

/// The text format: `nx ny nz` then the values; errors as (location, message).
pub fn parse_text(text: &str) -> Result<Grid, (String, String)> {
    let mut tokens = text.lines().enumerate().flat_map(|(i, l)| {
        l.split('#')
            .next()
            .unwrap_or("")
            .split_whitespace()
            .map(move |t| (i + 1, t))
    });
    let mut res = [0usize; 3];
    for (k, axis) in ["nx", "ny", "nz"].iter().enumerate() {
        let (line, tok) = tokens
            .next()
            .ok_or_else(|| ("header".to_string(), format!("missing {axis}")))?;
        res[k] = tok
            .parse::<usize>()
            .ok()
            .filter(|n| (2..=MAX_GRID_SIDE).contains(n))
            .ok_or_else(|| {
                (
                    format!("line {line}"),
                    format!("{axis} = `{tok}` is not an integer in 2..={MAX_GRID_SIDE}"),
                )
            })?;
    }
    let n = checked_vertices(res)?;
    // every value is at least one character and a separator: refuse a header the file
    // cannot satisfy before reserving its values
    let room = text.len().div_ceil(2);
    if n > room {
        return Err((
            "header".to_string(),
            format!(
                "the header claims a {res:?} grid ({n} values), but the file's {} bytes hold at most {room}",
                text.len()
            ),
        ));
    }
    let mut values = Vec::with_capacity(n);
    let mut last_line = 1;
    for (line, tok) in tokens {
        last_line = line;
        if values.len() == n {
            return Err((
                format!("line {line}"),
                format!("more than the {n} values a {res:?} grid holds (`{tok}`)"),
            ));
        }
        let v = tok.parse::<f32>().map_err(|_| {
            (
                format!("line {line}"),
                format!("`{tok}` (value #{}) is not a number", values.len()),
            )
        })?;
        if !v.is_finite() || v < 0.0 {
            return Err((
                format!("line {line}"),
                format!(
                    "value #{} = {tok} is not a finite density >= 0",
                    values.len()
                ),
            ));
        }
        values.push(v);
    }
    if values.len() != n {
        return Err((
            format!("line {last_line}"),
            format!(
                "a {res:?} grid needs {n} values, the file ends after {}",
                values.len()
            ),
        ));
    }
    Ok(Grid { res, values })
}

/// Mitsuba's `.vol`; errors as (location, message).
pub fn parse_vol(b: &[u8]) -> Result<GridFile, (String, String)> {
    let at = |o: usize| format!("byte offset {o}");
    if b.len() < VOL_HEADER_BYTES {
        return Err((
            "header".into(),
            format!(
                "{} bytes, shorter than the {VOL_HEADER_BYTES}-byte .vol header",
                b.len()
            ),
        ));
    }
    if &b[0..3] != b"VOL" {
        return Err((at(0), "does not start with `VOL`".into()));
    }
    if b[3] != VOL_VERSION {
        return Err((
            at(3),
            format!("version {} (only {VOL_VERSION} is read)", b[3]),
        ));
    }
    let i32_at = |o: usize| i32::from_le_bytes([b[o], b[o + 1], b[o + 2], b[o + 3]]);
    let f32_at = |o: usize| f32::from_le_bytes([b[o], b[o + 1], b[o + 2], b[o + 3]]);
    let encoding = i32_at(4);
    if encoding != VOL_FLOAT32 {
        return Err((
            at(4),
            format!("encoding {encoding} (only {VOL_FLOAT32} = float32 is read)"),
        ));
    }
    let mut res = [0usize; 3];
    for (k, axis) in ["xres", "yres", "zres"].iter().enumerate() {
        let v = i32_at(8 + 4 * k);
        res[k] = usize::try_from(v)
            .ok()
            .filter(|n| (2..=MAX_GRID_SIDE).contains(n))
            .ok_or_else(|| {
                (
                    at(8 + 4 * k),
                    format!("{axis} = {v} is not in 2..={MAX_GRID_SIDE}"),
                )
            })?;
    }
    let channels = i32_at(20);
    if channels != 1 {
        return Err((
            at(20),
            format!("{channels} channels (a density grid has 1)"),
        ));
    }
    let lo = Vec3::new(f32_at(24), f32_at(28), f32_at(32));
    let hi = Vec3::new(f32_at(36), f32_at(40), f32_at(44));
    if !(lo.is_finite() && hi.is_finite() && lo.cmplt(hi).all()) {
        return Err((
            at(24),
            format!("bounding box {lo} .. {hi} is not a finite box with min < max"),
        ));
    }
    let n = checked_vertices(res)?;
    let want = VOL_HEADER_BYTES + 4 * n;
    if b.len() != want {
        return Err((
            at(VOL_HEADER_BYTES),
            format!(
                "a {res:?} float32 grid needs {want} bytes, the file has {}",
                b.len()
            ),
        ));
    }
    let mut values = Vec::with_capacity(n);
    for i in 0..n {
        let o = VOL_HEADER_BYTES + 4 * i;
        let v = f32_at(o);
        if !v.is_finite() || v < 0.0 {
            return Err((
                at(o),
                format!("value #{i} = {v} is not a finite density >= 0"),
            ));
        }
        values.push(v);
    }
    Ok(GridFile {
        grid: Grid { res, values },
        bounds: Some((lo, hi)),
    })
}

/// Encodes a grid as a Mitsuba float32 `.vol` (for tests and tools).
pub fn encode_vol(grid: &Grid, lo: Vec3, hi: Vec3) -> Vec<u8> {
    let mut b = Vec::with_capacity(VOL_HEADER_BYTES + 4 * grid.values.len());
    b.extend_from_slice(b"VOL");
    b.push(VOL_VERSION);
    b.extend_from_slice(&VOL_FLOAT32.to_le_bytes());
    for n in grid.res {
        b.extend_from_slice(&(n as i32).to_le_bytes());
    }
    b.extend_from_slice(&1i32.to_le_bytes());
    for v in lo.to_array().into_iter().chain(hi.to_array()) {
        b.extend_from_slice(&v.to_le_bytes());
    }
    for v in &grid.values {
        b.extend_from_slice(&v.to_le_bytes());
    }
    b
}
