//! Emitting media as lights: the volume emittance L_e,V0 of eq. (1) (Pauly, Kollig, Keller
//! 2000), which eq. (5) lets a light path start from (x0 a volume vertex). A point of the
//! emitting media is sampled by (an estimate of) its emitted power: a medium by its power, a
//! cell of a lattice over its box by the emission there, a point uniform in the cell. The
//! density is per unit volume, so an estimator that reaches the same point another way
//! (a direction, then a free-flight distance r) converts with dV = r^2 dw dr.
//!
//! The lattice only shapes the density, which is positive over the whole box: a cell whose
//! centre lies outside the medium gets a small share of samples (the medium may reach into
//! it), every cell a floor, so an estimator that finds emission only where light subpaths
//! start (light tracing) sees all of it. A point drawn outside the medium is rejected by the
//! caller (`Scene::medium_at`).
//! Book: "The transport equations", section "Emitting media".

use glam::Vec3;

use super::Scene;
use crate::geometry::Aabb;
use crate::math::Distribution1D;
use crate::spectrum::{average, Rgb};

/// Cells per axis of the lattice an emitting medium's points are drawn from.
pub const LATTICE_RES: usize = 12;
/// The weight of a cell whose centre lies outside the medium, relative to its emission.
const OUTSIDE_SHARE: f32 = 1.0 / 16.0;
/// The weight every cell gets, relative to the mean cell weight.
const FLOOR_SHARE: f32 = 1e-3;
/// Sub-points per axis at which a cell's emission is averaged for its weight.
const SUB: usize = 2;

/// One emitting medium seen as a light.
#[derive(Clone, Debug)]
pub struct VolumeEmitter {
    /// Its index in `Scene::media`.
    pub medium: u32,
    /// The box its points are drawn from: the boundaries of the medium (shapes with it inside
    /// or outside), clipped to an inhomogeneous medium's box.
    pub bounds: Aabb,
    /// Emitted power 4 pi (integral of L_e,V0 dV) over the cells whose centre lies in the
    /// medium, per channel: the lattice's estimate (exact for a homogeneous box).
    pub power: Rgb,
    cells: Distribution1D,
}

/// A point drawn from the emitting media.
#[derive(Clone, Copy, Debug)]
pub struct VolumeSample {
    pub p: Vec3,
    pub medium: u32,
    /// L_e,V0(p) (eq. 1), radiance per unit length.
    pub emission: Rgb,
    /// Density per unit volume, the medium's selection probability included.
    pub pdf: f32,
}

/// Every emitting medium of a scene, selected by power.
#[derive(Clone, Debug, Default)]
pub struct VolumeEmitters {
    pub emitters: Vec<VolumeEmitter>,
    /// Selection of an emitter by its average power.
    select: Distribution1D,
    /// The emitter of each medium, if it is one.
    of_medium: Vec<Option<u32>>,
}

impl VolumeEmitters {
    /// The emitting media of `scene` with a lattice each (empty when no medium glows: a scene
    /// without emission builds nothing).
    pub fn build(scene: &Scene) -> Self {
        let mut out = VolumeEmitters {
            of_medium: vec![None; scene.media.len()],
            ..Default::default()
        };
        for m in 0..scene.media.len() as u32 {
            if !scene.media[m as usize].emits() {
                continue;
            }
            if let Some(e) = VolumeEmitter::build(scene, m) {
                out.of_medium[m as usize] = Some(out.emitters.len() as u32);
                out.emitters.push(e);
            }
        }
        let weights: Vec<f32> = out.emitters.iter().map(|e| average(e.power)).collect();
        out.select = Distribution1D::new(&weights);
        out
    }

    /// True when no medium can be sampled as a light.
    #[inline]
    pub fn is_empty(&self) -> bool {
        self.emitters.is_empty()
    }

    /// The total emitted power of the sampled media, per channel.
    pub fn power(&self) -> Rgb {
        self.emitters.iter().map(|e| e.power).sum()
    }

    /// The emitter of medium `m`, if it glows and can be sampled.
    pub fn of_medium(&self, m: u32) -> Option<&VolumeEmitter> {
        let i = (*self.of_medium.get(m as usize)?)?;
        Some(&self.emitters[i as usize])
    }

    /// Draws a point of the emitting media: an emitter by power with `u_select`, a point of it
    /// with `u` (see [`VolumeEmitter::sample`]). `emission` is that of `scene`'s medium there.
    pub fn sample(&self, scene: &Scene, u_select: f32, u: Vec3) -> Option<VolumeSample> {
        if self.is_empty() {
            return None;
        }
        let (i, pmf, _) = self.select.sample(u_select);
        let e = &self.emitters[i];
        let (p, pdf) = e.sample(u)?;
        Some(VolumeSample {
            p,
            medium: e.medium,
            emission: scene.media[e.medium as usize].emission(p),
            pdf: pmf * pdf,
        })
    }

    /// The density per unit volume with which [`VolumeEmitters::sample`] draws `p` as a point
    /// of medium `m` (selection included; 0 if `m` is not sampled or `p` outside its cells).
    pub fn pdf(&self, m: u32, p: Vec3) -> f32 {
        let Some(Some(i)) = self.of_medium.get(m as usize).copied() else {
            return 0.0;
        };
        self.select.pmf(i as usize) * self.emitters[i as usize].pdf(p)
    }

    /// The probability of selecting the emitter of medium `m`.
    pub fn pmf(&self, m: u32) -> f32 {
        match self.of_medium.get(m as usize).copied().flatten() {
            Some(i) => self.select.pmf(i as usize),
            None => 0.0,
        }
    }
}

impl VolumeEmitter {
    /// Medium `m` of `scene` as a light, `None` when it has no bounded box or no cell of it
    /// glows.
    fn build(scene: &Scene, m: u32) -> Option<Self> {
        let bounds = medium_bounds(scene, m)?;
        let medium = &scene.media[m as usize];
        let (n, cell) = (LATTICE_RES, bounds.extent() / LATTICE_RES as f32);
        let mut weights = Vec::with_capacity(n * n * n);
        let mut power = Rgb::ZERO;
        for k in 0..n * n * n {
            let lo = bounds.min + cell * lattice_cell(k).as_vec3();
            let inside = scene.medium_at(lo + 0.5 * cell) == Some(m);
            let e = cell_emission(medium, lo, cell);
            if inside {
                power += e;
                weights.push(average(e));
            } else {
                // the medium may still reach into the cell: a small share of samples, so the
                // density is positive wherever the medium can glow (light subpaths start only
                // here); a point drawn outside the medium is rejected by its user
                weights.push(average(e) * OUTSIDE_SHARE);
            }
        }
        // a floor under every cell: a grid's emission may vanish at the sub-points and not
        // between them
        let floor = FLOOR_SHARE * weights.iter().sum::<f32>() / weights.len() as f32;
        for w in &mut weights {
            *w += floor;
        }
        let volume = cell.x * cell.y * cell.z;
        let power = power * (4.0 * std::f32::consts::PI * volume);
        if !(average(power) > 0.0 && average(power).is_finite()) {
            return None;
        }
        Some(VolumeEmitter {
            medium: m,
            bounds,
            power,
            cells: Distribution1D::new(&weights),
        })
    }

    /// A point drawn from the lattice (a cell by its emission with `u.x`, then uniform in it,
    /// `u.x` remapped in its bin, `u.y`, `u.z`)
    /// and its density per unit volume.
    pub fn sample(&self, u: Vec3) -> Option<(Vec3, f32)> {
        // u.x picks the cell and, remapped inside its bin, is the first coordinate in it
        let (k, pmf, rem) = self.cells.sample(u.x);
        if pmf <= 0.0 {
            return None;
        }
        let cell = self.bounds.extent() / LATTICE_RES as f32;
        let lo = self.bounds.min + cell * lattice_cell(k).as_vec3();
        let f = Vec3::new(rem, u.y, u.z);
        Some((lo + cell * f, pmf / (cell.x * cell.y * cell.z)))
    }

    /// The density per unit volume of `p` under [`VolumeEmitter::sample`].
    pub fn pdf(&self, p: Vec3) -> f32 {
        let b = &self.bounds;
        if p.cmplt(b.min).any() || p.cmpgt(b.max).any() {
            return 0.0;
        }
        let cell = b.extent() / LATTICE_RES as f32;
        let c = ((p - b.min) / cell)
            .as_uvec3()
            .min(glam::UVec3::splat(LATTICE_RES as u32 - 1));
        let k = c.x as usize + LATTICE_RES * (c.y as usize + LATTICE_RES * c.z as usize);
        self.cells.pmf(k) / (cell.x * cell.y * cell.z)
    }
}

/// The lattice coordinates of cell `k` (x fastest).
fn lattice_cell(k: usize) -> glam::UVec3 {
    let n = LATTICE_RES;
    glam::UVec3::new((k % n) as u32, ((k / n) % n) as u32, (k / (n * n)) as u32)
}

/// The mean emission of the cell [lo, lo + size] at SUB^3 sub-cell centres.
fn cell_emission(medium: &crate::medium::Medium, lo: Vec3, size: Vec3) -> Rgb {
    let mut sum = Rgb::ZERO;
    for j in 0..SUB * SUB * SUB {
        let s = Vec3::new(
            (j % SUB) as f32,
            ((j / SUB) % SUB) as f32,
            (j / (SUB * SUB)) as f32,
        );
        sum += medium.emission(lo + size * (s + 0.5) / SUB as f32);
    }
    sum / (SUB * SUB * SUB) as f32
}

/// The box of medium `m`: the primitives of the shapes it fills or surrounds, clipped to an
/// inhomogeneous medium's box; `None` if empty or degenerate.
fn medium_bounds(scene: &Scene, m: u32) -> Option<Aabb> {
    let mut b = Aabb::EMPTY;
    for (prim, &s) in scene.prims.iter().zip(&scene.prim_shape) {
        let shape = &scene.shapes[s as usize];
        if shape.interior == Some(m) || shape.exterior == Some(m) {
            b = b.union(prim.bounds());
        }
    }
    if let Some(own) = scene.media[m as usize].bounds() {
        b = Aabb {
            min: b.min.max(own.min),
            max: b.max.min(own.max),
        };
    }
    let ok = !b.is_empty() && b.min.is_finite() && b.max.is_finite() && b.min.cmplt(b.max).all();
    ok.then_some(b)
}

/// The probability that a light subpath (or next-event estimation's light vertex) starts in
/// the emitting media rather than on a light: their share of the emitted power (power
/// selection across the lights and the emitting media); 0 without emitting media.
pub fn volume_share(scene: &Scene) -> f32 {
    if scene.emitters.is_empty() {
        return 0.0;
    }
    if scene.lights.is_empty() {
        return 1.0;
    }
    let v = average(scene.emitters.power());
    let l = scene.light_distr.total();
    if v + l > 0.0 {
        v / (v + l)
    } else {
        0.5
    }
}

/// The factor of every light's selection probability: 1 - [`volume_share`], exactly 1 in a
/// scene without emitting media (so the densities keep their bits there).
#[inline]
pub fn light_share(scene: &Scene) -> f32 {
    1.0 - volume_share(scene)
}
