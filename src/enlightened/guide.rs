//! Guided local sampling (Kristensen 2010, sec. 5.3), extended to medium vertices.
//!
//! At a surface vertex of an eye subpath the direction is drawn from the one-sample mixture
//!   p(w) = c1 p_fs(w) + c2 p_Li(w)                 [Kristensen 2010, eq. (5.18)]
//! and at a surface vertex of a light subpath from
//!   p(w) = c1 p_f*s(w) + c2 p_Wi(w)                [Kristensen 2010, eq. (5.19)]
//! where p_Li and p_Wi are the equal-area maps of the vertex's region built from photons and
//! importons. At a medium vertex the phase function takes the BSDF's place,
//!   p(w) = c1 p_fp(w) + c2 p_{Li|Wi}(w),
//! with the maps of the volume regions: the thesis proposes this (sec. 5.3.3) but never ran it.
//! A light subpath leaving an area light samples its direction from
//!   p(w) = c1 p_Le(w) + c2 p_Wi(w)                 [Kristensen 2010, eq. (5.17)]
//! with the importance map of the light point's surface region.
//!
//! The mixture is exact: its density is a function of the vertex (position, normal, medium),
//! the incoming direction, the outgoing direction and the transport mode only, so the density
//! of any given path can be evaluated again from its vertices ([`Vertex::pdf_dir`] calls
//! [`scatter_pdf`]), which BDPT's MIS weights, `path::pdf::densities` and MLT's transition
//! densities all do. The component with c1 keeps the support of the BSDF or phase function, so
//! the estimator stays unbiased however poor the maps are. Dirac BSDFs are not guided.
//!
//! Guided Russian roulette (sec. 5.3.4) continues a path with probability
//!   q = min(q_max, alpha * |beta'| / |beta_0| * Lhat(w'))
//! where w' is the direction already sampled, beta' the throughput after it, and
//! Lhat(w') = level(region) * 4 pi p_map(w') the map's incident quantity in w' relative to the
//! mean over all regions and directions; alpha ([`GuideSettings::roulette`]) is the
//! normalization the thesis leaves open.
//! Book: "Enlightened local path sampling: guiding".

use glam::{Vec2, Vec3};

use super::direction_map::{DirectionMap, DEFAULT_COLS, DEFAULT_ROWS};
use super::regions::{RegionParams, RegionPoint, Regions};
use crate::bsdf::{Bsdf, Lobe, TransportMode};
use crate::math::distribution::ONE_MINUS_EPSILON;
use crate::math::Sampler;
pub use crate::path::technique::ScatterSample;
use crate::path::technique::{local_scatter_pdf, LobeChoice, LocalSampling};
use crate::path::{Vertex, VertexKind};
use crate::scene::Scene;
use crate::spectrum::Rgb;

/// Which vertices are guided.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum GuideKind {
    Off,
    /// Surface vertices (the thesis's method).
    Surface,
    /// Medium vertices only (the thesis's proposal).
    Volume,
    /// Both.
    Both,
}

crate::option_value!(GuideKind, "guide");

impl GuideKind {
    pub fn surface(self) -> bool {
        matches!(self, GuideKind::Surface | GuideKind::Both)
    }

    pub fn volume(self) -> bool {
        matches!(self, GuideKind::Volume | GuideKind::Both)
    }
}

/// The particle samplers of Kristensen 2010, sec. 5.2.2.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum ParticleSampler {
    /// Photons from light subpaths, importons from eye subpaths (eqs. (5.11)-(5.12)): `particles`
    /// subpaths of each kind.
    Classical,
    /// The bidirectional particle sampler: `particles` full paths, photons and importons from
    /// each.
    Bidirectional,
    /// The Metropolis particle sampler (eq. (5.15)): `particles` chain steps over the
    /// bidirectional sampler, after a bootstrap of a quarter as many (between 1024 and the
    /// thesis's 65536) and a pilot: particles crowd where light reaches the camera.
    Metropolis,
}

crate::option_value!(ParticleSampler, "particle sampler");

/// c2 of eqs. (5.17)-(5.19): the thesis uses c1 = c2 = 1/2.
pub const DEFAULT_GUIDE_WEIGHT: f32 = 0.5;
/// Particles of each quantity traced for the maps by default.
pub const DEFAULT_PARTICLES: usize = 200_000;

/// Everything that shapes the guide.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GuideSettings {
    pub kind: GuideKind,
    /// Map columns (phi) and rows (cos theta).
    pub cols: u32,
    pub rows: u32,
    /// Region count and clustering parameters (alpha of eq. 5.16 in scene units).
    pub regions: RegionParams,
    /// Particles per quantity (photons and importons each).
    pub particles: usize,
    /// Only particles at this depth or deeper go into the maps (1: all; 2: indirect only, so
    /// the maps leave to BDPT's connections what they already sample well: the direct light
    /// and the direct view of the camera). A choice of this crate, not the thesis's.
    pub min_depth: u32,
    /// Which particle sampler traces the photons and importons (Kristensen 2010, sec. 5.2.2).
    pub sampler: ParticleSampler,
    /// The Metropolis particle sampler's chain parameters (its bootstrap is set from
    /// `particles`: a quarter of the chain steps, 1024 to 65536).
    pub metropolis: crate::enlightened::metropolis::MetropolisParticleSettings,
    /// c2: probability of sampling the map (c1 = 1 - c2 for the BSDF or phase function).
    pub c_guide: f32,
    /// Guided Russian roulette with this normalization alpha (None: the renderer's own roulette).
    pub roulette: Option<f32>,
    /// Seed of the particle tracing and the clustering.
    pub seed: u64,
}

impl GuideSettings {
    /// The defaults for a scene of bounding radius `radius` (guiding off).
    pub fn for_radius(radius: f32) -> Self {
        GuideSettings {
            kind: GuideKind::Off,
            cols: DEFAULT_COLS,
            rows: DEFAULT_ROWS,
            regions: RegionParams::for_radius(radius),
            particles: DEFAULT_PARTICLES,
            min_depth: 1,
            sampler: ParticleSampler::Classical,
            metropolis: Default::default(),
            c_guide: DEFAULT_GUIDE_WEIGHT,
            roulette: None,
            seed: 0x454c_5053,
        }
    }

    /// A region count must be in 1..=2^20.
    pub fn check_regions(&self, k: Option<usize>) -> Result<(), GuideError> {
        match k {
            Some(k) if !(1..=1 << 20).contains(&k) => Err(GuideError::BadRegions(k)),
            _ => Ok(()),
        }
    }

    /// A particle path count must be in 1..=10^9.
    pub fn check_particles(&self, n: Option<usize>) -> Result<(), GuideError> {
        match n {
            Some(n) if !(1..=1_000_000_000).contains(&n) => Err(GuideError::BadParticles(n)),
            _ => Ok(()),
        }
    }

    /// c2 must be in (0, 1): c1 = 1 - c2 > 0 keeps the BSDF's support (unbiasedness).
    pub fn check_weight(w: f32) -> Result<f32, GuideError> {
        if w > 0.0 && w < 1.0 {
            Ok(w)
        } else {
            Err(GuideError::BadWeight(w))
        }
    }

    /// alpha of eq. (5.16) must be positive and finite.
    pub fn check_alpha(a: f32) -> Result<f32, GuideError> {
        if a > 0.0 && a.is_finite() {
            Ok(a)
        } else {
            Err(GuideError::BadAlpha(a))
        }
    }

    /// The roulette normalization must be positive and finite.
    pub fn check_roulette(r: f32) -> Result<f32, GuideError> {
        if r > 0.0 && r.is_finite() {
            Ok(r)
        } else {
            Err(GuideError::BadRoulette(r))
        }
    }

    /// Parses `COLSxROWS`.
    pub fn parse_map(s: &str) -> Result<(u32, u32), GuideError> {
        let bad = || GuideError::BadMap(s.into());
        let (a, b) = s.split_once('x').ok_or_else(bad)?;
        let c: u32 = a.trim().parse().map_err(|_| bad())?;
        let r: u32 = b.trim().parse().map_err(|_| bad())?;
        if !(1..=1024).contains(&c) || !(1..=1024).contains(&r) {
            return Err(bad());
        }
        Ok((c, r))
    }
}

/// Why a guide setting is refused (the value, as given); the messages name the setting as the
/// `[render.guide]` keys do, and the callers add the key's place or the flag.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum GuideError {
    /// A region count outside 1..=2^20.
    #[error("regions = {0} must be in 1..=1048576")]
    BadRegions(usize),
    /// A particle path count outside 1..=10^9.
    #[error("particles = {0} must be in 1..=1000000000")]
    BadParticles(usize),
    /// A map weight c2 outside (0, 1): c1 = 1 - c2 must stay positive (unbiasedness).
    #[error("weight = {0} must be in (0, 1): the BSDF or phase function keeps 1 - weight > 0")]
    BadWeight(f32),
    /// An alpha of eq. (5.16) that is not positive and finite.
    #[error("alpha = {0} must be a positive number per unit length")]
    BadAlpha(f32),
    /// A roulette normalization that is not positive and finite.
    #[error("roulette = {0} must be a positive number")]
    BadRoulette(f32),
    /// A map size that is not `COLSxROWS` with both in 1..=1024 (the text given).
    #[error("map size `{0}` is not COLSxROWS with both in 1..=1024 (e.g. 32x16)")]
    BadMap(String),
}

/// One deposit: a particle's position (with normal on surfaces, medium in volumes), its
/// incident direction (pointing back towards the source) and its scalar weight.
#[derive(Clone, Copy, Debug)]
pub struct Deposit {
    pub point: RegionPoint,
    pub direction: Vec3,
    pub weight: f32,
}

/// The regions and maps of one quantity.
#[derive(Clone, Debug, Default)]
pub struct GuideField {
    pub regions: Regions,
    pub maps: Vec<DirectionMap>,
    /// Each region's total weight over the mean total of the non-empty regions.
    pub level: Vec<f32>,
    /// Deposits that went into the maps.
    pub particles: usize,
}

impl GuideField {
    /// Clusters the deposits into regions, then splats each into its region's map.
    // ANCHOR: field_build
    pub fn build(deposits: &[Deposit], settings: &GuideSettings) -> Self {
        let points: Vec<RegionPoint> = deposits.iter().map(|d| d.point).collect();
        let regions = Regions::build(&points, settings.regions);
        let mut maps = vec![DirectionMap::new(settings.cols, settings.rows); regions.len()];
        let mut particles = 0;
        for d in deposits {
            if let Some(r) = regions.region_of(&d.point) {
                maps[r as usize].splat(d.direction, d.weight);
                particles += 1;
            }
        }
        for m in &mut maps {
            m.build();
        }
        let nonempty: Vec<f64> = maps
            .iter()
            .filter(|m| !m.is_empty())
            .map(|m| m.total())
            .collect();
        let mean = nonempty.iter().sum::<f64>() / nonempty.len().max(1) as f64;
        let level = maps
            .iter()
            .map(|m| {
                if mean > 0.0 {
                    (m.total() / mean) as f32
                } else {
                    0.0
                }
            })
            .collect();
        GuideField {
            regions,
            maps,
            level,
            particles,
        }
    }
    // ANCHOR_END: field_build

    pub fn bytes(&self) -> usize {
        self.regions.bytes()
            + self.maps.iter().map(DirectionMap::bytes).sum::<usize>()
            + self.level.len() * 4
    }
}

/// Preprocessing statistics (the columns of the thesis's Table 5.1, plus time).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct GuideStats {
    /// Photons and importons deposited.
    pub photons: usize,
    pub importons: usize,
    /// Regions (surface + volume) for radiance and importance.
    pub regions_radiance: (usize, usize),
    pub regions_importance: (usize, usize),
    pub map: (u32, u32),
    /// Bytes of regions, trees and maps, per quantity.
    pub bytes_radiance: usize,
    pub bytes_importance: usize,
    pub seconds_particles: f64,
    pub seconds_build: f64,
    /// The Metropolis particle sampler's run, when it traced the particles.
    pub metropolis: Option<crate::enlightened::metropolis::MetropolisParticleStats>,
}

impl GuideStats {
    pub fn seconds(&self) -> f64 {
        self.seconds_particles + self.seconds_build
    }

    /// One line per quantity, Table 5.1's columns.
    pub fn table(&self) -> String {
        let row = |q: &str, n: usize, r: (usize, usize), b: usize| {
            format!(
                "  {q:<10} particles {n:>9}  regions {:>6} ({} surface, {} volume)  map {}x{}  {:.2} MiB\n",
                r.0 + r.1,
                r.0,
                r.1,
                self.map.0,
                self.map.1,
                b as f64 / (1024.0 * 1024.0)
            )
        };
        format!(
            "guide preprocessing: {:.2} s (particles {:.2} s, regions and maps {:.2} s)\n{}{}",
            self.seconds(),
            self.seconds_particles,
            self.seconds_build,
            row(
                "radiance",
                self.photons,
                self.regions_radiance,
                self.bytes_radiance
            ),
            row(
                "importance",
                self.importons,
                self.regions_importance,
                self.bytes_importance
            ),
        ) + &self.metropolis.map_or(String::new(), |m| {
            format!(
                "  metropolis {} steps, acceptance {:.3}; bootstrap: {:.4} of samples carry light to the sensor, {:.4} carry particles\n",
                m.steps,
                m.accepted as f64 / m.steps.max(1) as f64,
                m.connected,
                m.with_particles
            )
        })
    }
}

/// The guide: L_i and W_i per region, and the settings that say where they are used.
#[derive(Clone, Debug)]
pub struct Guide {
    pub settings: GuideSettings,
    /// Built from photons: guides eye subpaths (mode Radiance).
    pub radiance: GuideField,
    /// Built from importons: guides light subpaths (mode Importance).
    pub importance: GuideField,
    pub stats: GuideStats,
    /// A process-unique id, the key of the per-thread region memo ([`RegionMemo`]).
    id: u64,
}

/// Ids of guides, so that a memo entry of a dropped guide can never be taken for a new one's.
static NEXT_GUIDE_ID: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(1);

/// Slots of the per-thread region memo (direct-mapped).
const MEMO_SLOTS: usize = 512;

/// A per-thread memo of region lookups. A path's vertices are looked up again and again (the
/// walk's forward and reverse densities, then every MIS weight and transition density that
/// involves them), and each lookup is a k-nearest query with eq. (5.16) refinement. The memo
/// only caches a pure function of (guide, mode, position, normal, medium), compared bit for
/// bit, so results, and images, do not depend on it or on the thread; it is allocated once per
/// thread.
struct RegionMemo {
    keys: Vec<[u32; 9]>,
    regions: Vec<Option<u32>>,
}

thread_local! {
    static MEMO: std::cell::RefCell<RegionMemo> = std::cell::RefCell::new(RegionMemo {
        keys: vec![[0; 9]; MEMO_SLOTS],
        regions: vec![None; MEMO_SLOTS],
    });
}

impl Guide {
    /// Builds both fields from deposits (`seconds_particles` is the caller's tracing time).
    pub fn build(
        photons: &[Deposit],
        importons: &[Deposit],
        settings: GuideSettings,
        seconds_particles: f64,
    ) -> Self {
        let t0 = std::time::Instant::now();
        let radiance = GuideField::build(photons, &settings);
        let importance = GuideField::build(importons, &settings);
        let split = |f: &GuideField| {
            let s = f.regions.surface_len();
            (s, f.regions.len() - s)
        };
        let stats = GuideStats {
            photons: radiance.particles,
            importons: importance.particles,
            regions_radiance: split(&radiance),
            regions_importance: split(&importance),
            map: (settings.cols, settings.rows),
            bytes_radiance: radiance.bytes(),
            bytes_importance: importance.bytes(),
            seconds_particles,
            seconds_build: t0.elapsed().as_secs_f64(),
            metropolis: None,
        };
        Guide {
            settings,
            radiance,
            importance,
            stats,
            id: NEXT_GUIDE_ID.fetch_add(1, std::sync::atomic::Ordering::Relaxed),
        }
    }

    /// The field that guides a subpath carrying `mode`: photons (L_i) for eye subpaths,
    /// importons (W_i) for light subpaths.
    #[inline]
    pub fn field(&self, mode: TransportMode) -> &GuideField {
        match mode {
            TransportMode::Radiance => &self.radiance,
            TransportMode::Importance => &self.importance,
        }
    }

    /// The map and region level guiding vertex `v` in `mode`, if any: surface vertices with a
    /// regular BSDF when surface guiding is on, medium vertices when volume guiding is on,
    /// and only where the region's map holds weight.
    // ANCHOR: map_at
    #[inline]
    pub fn map_at(
        &self,
        scene: &Scene,
        v: &Vertex,
        mode: TransportMode,
    ) -> Option<(&DirectionMap, f32)> {
        let field = self.field(mode);
        let medium = match v.kind {
            VertexKind::Surface { .. } if self.settings.kind.surface() => {
                // a mixture with a Dirac lobe is not guided: the guided density is over solid
                // angle, and the BSDF's own sampling (with its discrete lobe choice) stays exact
                if !v
                    .bsdf(scene)
                    .is_some_and(|b| b.has_regular_lobe() && !b.has_dirac_lobe())
                {
                    return None;
                }
                None
            }
            VertexKind::Medium { medium } if self.settings.kind.volume() => Some(medium),
            _ => return None,
        };
        let region = self.region_memoized(field, mode, v.p, v.n, medium)?;
        let map = &field.maps[region as usize];
        (!map.is_empty()).then(|| (map, field.level[region as usize]))
    }
    // ANCHOR_END: map_at

    /// The region of a surface point (`medium` None) or a medium point, through the memo.
    fn region_memoized(
        &self,
        field: &GuideField,
        mode: TransportMode,
        p: Vec3,
        n: Vec3,
        medium: Option<u32>,
    ) -> Option<u32> {
        let key = [
            self.id as u32,
            (self.id >> 32) as u32 ^ ((mode == TransportMode::Importance) as u32) << 31,
            p.x.to_bits(),
            p.y.to_bits(),
            p.z.to_bits(),
            n.x.to_bits(),
            n.y.to_bits(),
            n.z.to_bits(),
            medium.map_or(u32::MAX, |m| m),
        ];
        let mut h = 0u64;
        for k in key {
            h = crate::math::sampler::mix64(h ^ k as u64);
        }
        let slot = (h as usize) % MEMO_SLOTS;
        let lookup = || match medium {
            None => field.regions.surface_region(p, n),
            Some(m) => field.regions.volume_region(p, m),
        };
        MEMO.with(|memo| {
            let Ok(mut memo) = memo.try_borrow_mut() else {
                return lookup();
            };
            if memo.keys[slot] == key && key[0] | key[1] != 0 {
                return memo.regions[slot];
            }
            let r = lookup();
            memo.keys[slot] = key;
            memo.regions[slot] = r;
            r
        })
    }
}

/// The mixture density c1 p_local + c2 p_map of eqs. (5.18), (5.19) and their medium
/// extension, given the local model's density `p_local` of `wi`.
#[inline]
pub fn mixture(c_guide: f32, p_local: f32, map: &DirectionMap, wi: Vec3) -> f32 {
    (1.0 - c_guide) * p_local + c_guide * map.pdf(wi)
}

/// Solid-angle density with which a `mode` subpath at surface or medium vertex `v`, reached
/// from direction `wo` (pointing away from `v`), samples `wi`: the BSDF's or phase function's
/// own density, or the guided mixture where a map guides `v`.
// ANCHOR: scatter_pdf
pub fn scatter_pdf(
    g: &Guide,
    scene: &Scene,
    v: &Vertex,
    wo: Vec3,
    wi: Vec3,
    mode: TransportMode,
) -> f32 {
    let Some(local) = local_scatter_pdf(scene, v, wo, wi) else {
        return 0.0;
    };
    match g.map_at(scene, v, mode) {
        Some((map, _)) => mixture(g.settings.c_guide, local, map, wi),
        None => local,
    }
}
// ANCHOR_END: scatter_pdf

/// The guided choice between a glass vertex's two lobes (Kristensen 2010, sec. 5.3: Fresnel
/// times the map's value in each candidate direction), mixed with the plain Fresnel choice by
/// the guide weight c so that it stays positive wherever the BSDF's is:
///
/// P(reflect) = (1 - c) F + c F L(w_r) / (F L(w_r) + (1 - F) L(w_t)),
///
/// with L the `mode` map of the vertex's region (L_i on eye subpaths, W_i on light subpaths);
/// plain F where the map sees neither direction. Returns P(reflect) with the reflection sample
/// and the transmission sample (`None` under total internal reflection, where P = 1), or `None`
/// where no map guides the vertex (surface guiding off, no dielectric, empty region).
// ANCHOR: guided_fresnel
pub fn guided_fresnel(
    g: &Guide,
    scene: &Scene,
    v: &Vertex,
    wo: Vec3,
    mode: TransportMode,
) -> Option<LobeChoice> {
    let bsdf = v.bsdf(scene)?;
    if !g.settings.kind.surface() || !matches!(*bsdf, Bsdf::Dielectric(_)) {
        return None;
    }
    let field = g.field(mode);
    let region = g.region_memoized(field, mode, v.p, v.n, None)?;
    let map = &field.maps[region as usize];
    if map.is_empty() {
        return None;
    }
    // uc = 0 always reflects, uc -> 1 transmits unless the light is totally reflected
    // in the shading frame; the chosen sample's value gets its correction afterwards
    let r = bsdf.sample(wo, v.ns, Vec2::ZERO, 0.0, mode)?;
    let t = bsdf
        .sample(wo, v.ns, Vec2::ZERO, ONE_MINUS_EPSILON, mode)
        .filter(|t| t.lobe == Lobe::SingularTransmission);
    let Some(t) = t else {
        return Some((1.0, r, None));
    };
    let f = r.pdf;
    let (lr, lt) = (f * map.relative(r.wi), (1.0 - f) * map.relative(t.wi));
    let c = g.settings.c_guide;
    let p = if lr + lt > 0.0 {
        (1.0 - c) * f + c * lr / (lr + lt)
    } else {
        f
    };
    Some((p, r, Some(t)))
}
// ANCHOR_END: guided_fresnel

/// Samples a scattering direction at surface or medium vertex `v` for a `mode` subpath, from
/// the guided mixture where a map guides `v` (one extra random number picks the component),
/// else exactly as the plain technique does (same random numbers). `u` are the first two
/// numbers, already drawn (`LocalSampling::sample_scatter` draws them).
// ANCHOR: sample_scatter
pub fn sample_scatter_with(
    g: &Guide,
    scene: &Scene,
    v: &Vertex,
    wo: Vec3,
    mode: TransportMode,
    u: Vec2,
    sampler: &mut Sampler,
) -> Option<ScatterSample> {
    let guided = g
        .map_at(scene, v, mode)
        .map(|(m, l)| (g.settings.c_guide, m, l));
    match v.kind {
        VertexKind::Surface { .. } => {
            let uc = sampler.next_f32();
            let bsdf = v.bsdf(scene)?;
            if let Some((p_r, r, t)) = guided_fresnel(g, scene, v, wo, mode) {
                // glass: reflection or transmission with the guided choice probability
                let (bs, pdf) = match t {
                    Some(t) if uc >= p_r => (t, 1.0 - p_r),
                    _ => (r, p_r),
                };
                let nn = v.normals();
                let c = if nn.ns == nn.ng {
                    1.0
                } else {
                    nn.correction(wo, bs.wi, mode)
                };
                if c == 0.0 {
                    return None;
                }
                return Some(ScatterSample {
                    wi: bs.wi,
                    value: bs.value * c,
                    pdf,
                    lobe: bs.lobe,
                    lhat: None,
                });
            }
            let Some((c, map, level)) = guided else {
                return bsdf
                    .sample_shaded(wo, v.normals(), u, uc, mode)
                    .map(ScatterSample::from_bsdf);
            };
            let wi = if sampler.next_f32() < c {
                map.sample(u)?.0
            } else {
                bsdf.sample(wo, v.ns, u, uc, mode)?.wi
            };
            let pdf = mixture(c, bsdf.pdf_shaded(wo, wi, v.normals()), map, wi);
            Some(ScatterSample {
                wi,
                value: bsdf.eval_shaded(wo, wi, v.normals(), mode),
                pdf,
                lobe: Lobe::Regular,
                lhat: Some(level * map.relative(wi)),
            })
        }
        VertexKind::Medium { medium } => {
            let phase = scene.media[medium as usize].phase();
            let Some((c, map, level)) = guided else {
                return Some(ScatterSample::from_phase(phase.sample(wo, u)));
            };
            let wi = if sampler.next_f32() < c {
                map.sample(u)?.0
            } else {
                phase.sample(wo, u).wi
            };
            let pdf = mixture(c, phase.pdf(wo, wi), map, wi);
            Some(ScatterSample {
                wi,
                value: Rgb::splat(phase.eval(wo, wi)),
                pdf,
                lobe: Lobe::Regular,
                lhat: Some(level * map.relative(wi)),
            })
        }
        _ => None,
    }
}
// ANCHOR_END: sample_scatter

/// The guided roulette's survival probability (sec. 5.3.4), within [`ROULETTE_MIN_SURVIVAL`,
/// `q_max`]; `None` where the vertex is not guided or guided roulette is off.
// ANCHOR: roulette
#[inline]
pub fn roulette_survival(
    g: &Guide,
    lhat: Option<f32>,
    throughput_ratio: f32,
    q_max: f32,
) -> Option<f32> {
    let alpha = g.settings.roulette?;
    let l = lhat?;
    let q = alpha * throughput_ratio * l;
    // the floor keeps a survivor's throughput within ROULETTE_MAX_WEIGHT times the start
    let floor = (throughput_ratio / ROULETTE_MAX_WEIGHT).clamp(ROULETTE_MIN_SURVIVAL, q_max);
    Some(if q.is_nan() {
        q_max
    } else {
        q.clamp(floor, q_max)
    })
}
// ANCHOR_END: roulette

/// The least survival probability of guided roulette. Roulette is unbiased only where q > 0
/// for every path that can still contribute; a map that saw no particle in a direction says
/// Lhat = 0 there, which is an estimate, not a fact (DEVIATION: the thesis's formula has no
/// floor; without one the fog box loses 5% of its light, see `tests/spec/enlightened/guide.rs`).
pub const ROULETTE_MIN_SURVIVAL: f32 = 0.05;

/// The weight window of guided roulette: a survivor's throughput is at most this many times the
/// walk's starting throughput (q >= (beta'/beta_0) / 4). Without it the survivors of directions
/// a map underrates are 20 times heavier at every vertex, an estimator so heavy-tailed that its
/// mean over finite runs sits below the truth (DEVIATION, a choice of this crate).
pub const ROULETTE_MAX_WEIGHT: f32 = 4.0;

impl From<&crate::enlightened::Particle> for Deposit {
    /// A particle's position, normal (surfaces) or medium (volumes), incident direction and
    /// luminance weight.
    fn from(p: &crate::enlightened::Particle) -> Self {
        Deposit {
            point: RegionPoint {
                p: p.position,
                n: p.normal.unwrap_or(Vec3::ZERO),
                medium: if p.normal.is_some() { None } else { p.medium },
            },
            direction: p.direction,
            weight: crate::spectrum::luminance(p.weight),
        }
    }
}

/// The preprocessing pass (Kristensen 2010, sec. 5.1, steps 1-5): traces `settings.particles`
/// light subpaths (photons) and as many eye subpaths (importons) with the classical tracer,
/// then clusters and projects them, the particles traced with technique `tech` (unguided: the
/// plain one, or the adjoint image's light starts).
// ANCHOR: build_guide
pub fn build_guide(scene: &Scene, tech: &dyn LocalSampling, settings: GuideSettings) -> Guide {
    use crate::enlightened::metropolis::{trace_metropolis, MetropolisParticleSettings};
    use crate::enlightened::particles::{
        trace_bidirectional, trace_classical, ImportonSource, Quantity,
    };
    let t0 = std::time::Instant::now();
    let paths = settings.particles as u64;
    let deep = |p: &&crate::enlightened::Particle| p.depth >= settings.min_depth;
    let mut metropolis = None;
    let (photons, importons) = match settings.sampler {
        ParticleSampler::Classical => (
            trace_classical(scene, tech, Quantity::Radiance, paths, settings.seed),
            trace_classical(
                scene,
                tech,
                Quantity::Importance,
                paths,
                settings.seed ^ 0x1,
            ),
        ),
        ParticleSampler::Bidirectional => {
            let sets = match ImportonSource::default_for(scene) {
                Some(src) => trace_bidirectional(scene, tech, src, paths, settings.seed),
                None => Default::default(),
            };
            (sets.photons, sets.importons)
        }
        ParticleSampler::Metropolis => {
            let mp = MetropolisParticleSettings {
                bootstrap: (paths / 4).clamp(1024, 65_536),
                ..settings.metropolis
            };
            let (sets, stats) = match ImportonSource::default_for(scene) {
                Some(src) => trace_metropolis(scene, tech, src, paths, settings.seed, &mp),
                None => Default::default(),
            };
            metropolis = Some(stats);
            (sets.photons, sets.importons)
        }
    };
    let photons: Vec<Deposit> = photons.iter().filter(deep).map(Deposit::from).collect();
    let importons: Vec<Deposit> = importons.iter().filter(deep).map(Deposit::from).collect();
    let seconds_particles = t0.elapsed().as_secs_f64();
    let mut guide = Guide::build(&photons, &importons, settings, seconds_particles);
    guide.stats.metropolis = metropolis;
    guide
}
// ANCHOR_END: build_guide

/// The importance map guiding emission from area-light point (p, n), with c2: surface
/// guiding on and the point's importance region non-empty.
#[inline]
fn emission_map(g: &Guide, p: Vec3, n: Vec3) -> Option<(f32, &DirectionMap)> {
    if !g.settings.kind.surface() || n == Vec3::ZERO {
        return None;
    }
    let field = &g.importance;
    let region = g.region_memoized(field, TransportMode::Importance, p, n, None)?;
    let map = &field.maps[region as usize];
    (!map.is_empty()).then_some((g.settings.c_guide, map))
}

/// Eq. (5.17): the density of emission direction `w` at area-light point (p, n) whose own
/// emission density is `p_le`: c1 p_Le + c2 p_Wi where an importance map guides the point.
// ANCHOR: emission_pdf
#[inline]
pub fn emission_pdf(g: &Guide, p: Vec3, n: Vec3, w: Vec3, p_le: f32) -> f32 {
    match emission_map(g, p, n) {
        Some((c, map)) => mixture(c, p_le, map, w),
        None => p_le,
    }
}
// ANCHOR_END: emission_pdf

/// Eq. (5.17), sampling: the emission direction `d_le` the light drew from its own density
/// (with numbers `u`), or, with probability c2, a direction from the importance map drawn with
/// the same `u` (one extra number picks the component, only where a map guides the point).
/// Returns the direction and its mixture density (`p_le_of` gives the light's own density).
pub fn sample_emission(
    g: &Guide,
    (p, n): (Vec3, Vec3),
    d_le: Vec3,
    u: Vec2,
    p_le_of: impl Fn(Vec3) -> f32,
    sampler: &mut Sampler,
) -> Option<(Vec3, f32)> {
    let Some((c, map)) = emission_map(g, p, n) else {
        return Some((d_le, p_le_of(d_le)));
    };
    let d = if sampler.next_f32() < c {
        map.sample(u)?.0
    } else {
        d_le
    };
    Some((d, mixture(c, p_le_of(d), map, d)))
}
