//! Surface scattering f_s of the local scattering equation (Pauly, Kollig, Keller 2000, eq. 2):
//! Lambertian (two-sided), mirror, smooth conductor (complex-index Fresnel), smooth dielectric with Fresnel, a thin dielectric sheet, the
//! rough (GGX or Beckmann microfacet) conductor, dielectric and plastic (`conductor`,
//! `rough_dielectric`, `rough_plastic`, over `microfacet`), smooth plastic (`plastic`: a Dirac
//! coat over a diffuse base, the one model with a Dirac and a regular lobe), and the null
//! (index-matched) boundary that only separates media. Each model is a struct in its own file
//! (`lambert`, `mirror`, `dielectric`, `thin_dielectric`, `null`, and those above) implementing
//! [`BsdfModel`]; [`Bsdf`] holds one and dispatches to it.
//!
//! Convention (see `conventions`): `wo` and `wi` point away from the surface point; `n` is the
//! geometric normal as the shape defines it (either side may be lit). Values are f_s itself,
//! without the cosine. Singular (delta) lobes return `value = weight * pdf / |cos wi|`, so that
//! `value * |cos wi| / pdf` is the path weight, as every regular lobe.
//!
//! Three questions, three helpers: does the material have a regular lobe
//! ([`Bsdf::has_regular_lobe`]: next-event estimation and connections may end there and see
//! `eval`/`pdf`, the regular part only), a Dirac lobe ([`Bsdf::has_dirac_lobe`]: some light
//! reaches it only by its own sampling), and did this sample take a Dirac
//! ([`Lobe::is_singular`]: the vertex is then a Dirac vertex, with a discrete probability, no
//! connection, and full weight for an emitter its ray hits). Plastic answers yes to all three.
//!
//! Book: "Surface scattering (eq. 2)" (`book/src/bsdf.md`); executable spec: `tests/spec/bsdf.rs`, and
//! `tests/spec/bsdf/contract.rs`, the contract every model of [`Bsdf`] meets.

use glam::{Vec2, Vec3};

use crate::spectrum::Rgb;

pub mod conductor;
pub mod dielectric;
pub mod lambert;
pub mod microfacet;
pub mod mirror;
pub mod named_conductor;
pub mod null;
pub mod plastic;
pub mod rough_dielectric;
pub mod rough_plastic;
pub mod thin_dielectric;

pub use conductor::{Conductor, ConductorFresnel, RoughConductor};
pub use dielectric::{Dielectric, Specular};
pub use lambert::Lambert;
pub use microfacet::{
    AnisoBeckmann, AnisoGgx, Anisotropy, Beckmann, Distribution, Ggx, Microfacet,
};
pub use mirror::Mirror;
pub use null::Null;
pub use plastic::Plastic;
pub use rough_dielectric::RoughDielectric;
pub use rough_plastic::RoughPlastic;
pub use thin_dielectric::{thin_dielectric_reflectance, ThinDielectric};

// ANCHOR: transport_mode
/// Which quantity a path carries: radiance (eye paths) or importance (light paths, the adjoint
/// BSDF f*_s). Only refraction differs (the eta^2 factor, Kristensen 2010 eq. 2.9).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TransportMode {
    Radiance,
    Importance,
}
// ANCHOR_END: transport_mode

/// The scattering mode of a sampled direction (Pauly et al. sec. 5.2: perturbations keep modes).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Lobe {
    /// A smooth (regular) lobe with a density over solid angle.
    Regular,
    /// A Dirac reflection.
    SingularReflection,
    /// A Dirac transmission (refraction).
    SingularTransmission,
}

impl Lobe {
    /// True when this sampled lobe is a Dirac: the vertex that took it is a Dirac vertex (no
    /// connection, a discrete probability), whatever other lobes its material has.
    pub fn is_singular(self) -> bool {
        self != Lobe::Regular
    }
}

/// A sampled direction with the BSDF value and the density that produced it.
#[derive(Clone, Copy, Debug)]
pub struct BsdfSample {
    pub wi: Vec3,
    /// f_s(wo, wi) (see the module note on singular lobes).
    pub value: Rgb,
    /// Solid-angle density for regular lobes, discrete probability for singular ones.
    pub pdf: f32,
    pub lobe: Lobe,
}

impl BsdfSample {
    /// value * |cos wi| / pdf: the factor the path throughput is multiplied by.
    #[inline]
    pub fn weight(&self, n: Vec3) -> Rgb {
        self.value * (self.wi.dot(n).abs() / self.pdf)
    }
}

// ANCHOR: normals
/// The two normals of a surface point: the geometric `ng` (the shape's: cosines of the
/// geometry term, sides, media, ray offsets) and the shading `ns` (the frame the model is
/// evaluated in: interpolated on smooth meshes, `ng` everywhere else).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Normals {
    pub ng: Vec3,
    pub ns: Vec3,
}

impl Normals {
    /// A point shaded by its geometric normal.
    #[inline]
    pub fn flat(n: Vec3) -> Self {
        Normals { ng: n, ns: n }
    }

    /// The factor that turns f_s evaluated in the shading frame into the BSDF of the
    /// geometric measure both transport directions share (Veach 1997, sec. 5.3):
    /// `|w_l . ns| / |w_l . ng|` for the direction `w_l` light arrives from (`wi` in radiance
    /// mode, `wo` in importance mode), so that with the cosine `|w_e . ng|` of the other
    /// direction, which the path's geometry term carries, radiance sees `f |wi . ns|` and
    /// importance `f |wo . ns| |wi . ng| / |wo . ng|`, Veach's adjoint (eq. 5.19). Zero when
    /// either direction lies on one side of `ng` and the other of `ns` (Mitsuba 3's particle
    /// tracer refuses these as light leaks; here every mode does).
    // ANCHOR: shading_correction
    #[inline]
    pub fn correction(&self, wo: Vec3, wi: Vec3, mode: TransportMode) -> f32 {
        let (o_g, o_s) = (wo.dot(self.ng), wo.dot(self.ns));
        let (i_g, i_s) = (wi.dot(self.ng), wi.dot(self.ns));
        if o_g * o_s <= 0.0 || i_g * i_s <= 0.0 {
            return 0.0;
        }
        match mode {
            TransportMode::Radiance => (i_s / i_g).abs(),
            TransportMode::Importance => (o_s / o_g).abs(),
        }
    }
    // ANCHOR_END: shading_correction
}
// ANCHOR_END: normals

/// The closed set of surface models, one struct per model (each in its own file, each a
/// [`BsdfModel`]). Adding a model is its file, its variant here (and in `dispatch!`'s one
/// match), and its scene key (`scene::file::MaterialDesc`, built in `scene::build::materials`);
/// the compiler lists every other site (the AOV albedo, `pathspace info`), since no match over
/// the models has a wildcard arm.
#[derive(Clone, Debug, PartialEq)]
pub enum Bsdf {
    /// rho / pi on both sides, or on the normal's side only (`one_sided`).
    Lambert(Lambert),
    /// A perfect mirror with a constant reflectance (black behind the normal if `one_sided`).
    Mirror(Mirror),
    /// A smooth dielectric interface; `ior` is inside (behind the normal) over outside.
    Dielectric(Dielectric),
    /// A thin dielectric sheet (Mitsuba 3's `thindielectric`): `ior` is the sheet's index over
    /// the surrounding one. Light is reflected or passes straight through, with the sheet's
    /// internal reflections summed ([`thin_dielectric_reflectance`]); no refraction, no eta^2.
    ThinDielectric(ThinDielectric),
    /// A smooth conductor: a Dirac reflection with complex-index Fresnel (Mitsuba's
    /// `conductor`; one-sided unless in a `twosided`).
    Conductor(Conductor),
    /// A GGX microfacet conductor (glossy reflection, two-sided unless `one_sided`).
    RoughConductor(RoughConductor),
    /// A GGX microfacet dielectric interface (glossy reflection and refraction).
    RoughDielectric(RoughDielectric),
    /// Smooth plastic: a Dirac coat reflection over a diffuse base (Mitsuba 3's `plastic`).
    Plastic(Plastic),
    /// A diffuse base under a rough dielectric coating (Mitsuba 3's `roughplastic`).
    RoughPlastic(RoughPlastic),
    /// An index-matched boundary: light passes unchanged. Never a scattering vertex.
    Null(Null),
}

/// What every surface model answers. [`Bsdf`] calls these after the checks all models share:
/// `eval`, `pdf` and `sample` are never asked about a `wo` behind a one-sided model (black
/// there), and `sample` never about a grazing `wo` (`wo . n == 0`).
pub trait BsdfModel {
    /// A regular lobe (a density over solid angle): next-event estimation and connections may
    /// end here and see `eval`/`pdf`, the regular part only.
    fn has_regular_lobe(&self) -> bool;
    /// A Dirac lobe: some light reaches it only by its own sampling.
    fn has_dirac_lobe(&self) -> bool;
    /// Some light passes to the other side of the surface.
    fn transmits(&self) -> bool;
    /// Black behind the normal (Mitsuba 3's convention for opaque models without `twosided`).
    fn one_sided(&self) -> bool;
    /// f_s(wo, wi) in `mode`, without the cosine: zero for singular lobes; the regular lobe
    /// alone for a model with both.
    fn eval(&self, wo: Vec3, wi: Vec3, n: Vec3, mode: TransportMode) -> Rgb;
    /// Solid-angle density with which `sample` produces `wi` (zero for singular lobes; for a
    /// model with both, the regular lobe's density times the probability of taking it).
    fn pdf(&self, wo: Vec3, wi: Vec3, n: Vec3) -> f32;
    /// Samples `wi` given `wo` from `u` (the direction) and `uc` (the lobe); `None` when no
    /// direction can be produced.
    fn sample(
        &self,
        wo: Vec3,
        n: Vec3,
        u: Vec2,
        uc: f32,
        mode: TransportMode,
    ) -> Option<BsdfSample>;
    /// Its albedo seen at cosine `cos` to the normal (the albedo layer of `--aovs`, before it
    /// is clamped to [0, 1] as denoisers expect).
    fn albedo(&self, cos: f32) -> Rgb;
    /// What `pathspace info` says of it (`lambert, albedo 0.5`).
    fn describe(&self) -> String;
}

/// A coated model's albedo at cosine `cos`: the coat's specular reflectance and the base's
/// diffuse one mixed by the coat's Fresnel reflectance (index `eta`).
pub fn coated_albedo(diffuse: Rgb, specular: Rgb, eta: f32, cos: f32) -> Rgb {
    let f = fresnel_dielectric(cos, eta);
    specular * f + diffuse * (1.0 - f)
}

/// `dispatch!(bsdf, m => expr)`: `expr` with `m` bound to the model inside `bsdf`. The one
/// exhaustive match over the variants that every method of [`Bsdf`] goes through.
macro_rules! dispatch {
    ($bsdf:expr, $m:ident => $e:expr) => {
        match $bsdf {
            Bsdf::Lambert($m) => $e,
            Bsdf::Mirror($m) => $e,
            Bsdf::Dielectric($m) => $e,
            Bsdf::ThinDielectric($m) => $e,
            Bsdf::Conductor($m) => $e,
            Bsdf::RoughConductor($m) => $e,
            Bsdf::RoughDielectric($m) => $e,
            Bsdf::Plastic($m) => $e,
            Bsdf::RoughPlastic($m) => $e,
            Bsdf::Null($m) => $e,
        }
    };
}

/// Fresnel reflectance of an unpolarized wave for a dielectric interface. `cos_i` is measured on
/// the side the light arrives from, `eta` = eta_transmitted / eta_incident.
// ANCHOR: fresnel
pub fn fresnel_dielectric(cos_i: f32, eta: f32) -> f32 {
    // ASSIGNMENT: fresnel
    let cos_i = cos_i.clamp(0.0, 1.0);
    let sin2_t = (1.0 - cos_i * cos_i) / (eta * eta);
    if sin2_t >= 1.0 {
        return 1.0; // total internal reflection
    }
    let cos_t = (1.0 - sin2_t).sqrt();
    let r_par = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
    let r_perp = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
    0.5 * (r_par * r_par + r_perp * r_perp)
    // END ASSIGNMENT
}
// ANCHOR_END: fresnel

/// Mirror `w` about `n`.
#[inline]
pub fn reflect(w: Vec3, n: Vec3) -> Vec3 {
    2.0 * w.dot(n) * n - w
}

impl Bsdf {
    /// True for the null boundary, which is skipped by tracing rather than scattered at.
    pub fn is_null(&self) -> bool {
        matches!(self, Bsdf::Null(_))
    }

    /// True when the material has a regular lobe (a density over solid angle): next-event
    /// estimation and connections may end at it, and they see that lobe only.
    pub fn has_regular_lobe(&self) -> bool {
        dispatch!(self, m => m.has_regular_lobe())
    }

    /// True when the material has a Dirac lobe: some of its light is scattered into one
    /// direction, which no connection and no light sample can reach (only its own sampling).
    pub fn has_dirac_lobe(&self) -> bool {
        dispatch!(self, m => m.has_dirac_lobe())
    }

    /// True when some light passes to the other side of the surface (the null boundary passes
    /// all of it); reflection-only models keep every path on the side it arrived from.
    pub fn transmits(&self) -> bool {
        dispatch!(self, m => m.transmits())
    }

    /// The factor (eta_o / eta_t)^2 by which radiance crossing from `wi`'s side to `wo`'s is
    /// scaled at a refracting interface (Kristensen 2010, eq. 2.15; `ior` inside, behind `n`,
    /// over 1 outside), 1 where `wi` and `wo` lie on one side or the model does not refract
    /// (a thin sheet, a null boundary). Part of every radiance-mode transmission's value; a
    /// path that enters and leaves the glass gets it back, so Russian roulette leaves it out.
    pub fn radiance_scale(&self, wo: Vec3, wi: Vec3, n: Vec3) -> f32 {
        let ior = match self {
            Bsdf::Dielectric(d) => d.ior,
            Bsdf::RoughDielectric(d) => d.ior,
            _ => return 1.0,
        };
        let (cos_o, cos_i) = (wo.dot(n), wi.dot(n));
        if cos_o * cos_i >= 0.0 {
            return 1.0;
        }
        // eta_o / eta_t: wo outside (cos_o > 0) looks into the glass
        let ratio = if cos_o > 0.0 { 1.0 / ior } else { ior };
        ratio * ratio
    }

    /// True when every lobe is a Dirac (mirror, glass; the null boundary has none): every
    /// vertex on it is a Dirac vertex, whatever was sampled there.
    pub fn only_dirac_lobes(&self) -> bool {
        !self.has_regular_lobe()
    }

    /// True when `wo` sees the back of a one-sided opaque model, which is black there (Mitsuba
    /// 3's convention for `diffuse` and `conductor` without `twosided`): no value, no density,
    /// no sample. Reflection-only models keep `wo` and `wi` on one side, so `wo` decides.
    // ANCHOR: black_behind
    pub fn black_behind(&self, wo: Vec3, n: Vec3) -> bool {
        let one_sided = dispatch!(self, m => m.one_sided());
        one_sided && wo.dot(n) <= 0.0
    }
    // ANCHOR_END: black_behind

    /// f_s(wo, wi): zero for singular lobes (a Dirac cannot be evaluated at a given direction);
    /// the regular lobe alone for a model with both.
    // ANCHOR: bsdf_eval
    pub fn eval(&self, wo: Vec3, wi: Vec3, n: Vec3, mode: TransportMode) -> Rgb {
        if self.black_behind(wo, n) {
            return Rgb::ZERO;
        }
        dispatch!(self, m => m.eval(wo, wi, n, mode))
    }
    // ANCHOR_END: bsdf_eval

    /// Solid-angle density with which [`Bsdf::sample`] produces `wi` (zero for singular lobes;
    /// for a model with both, the regular lobe's density times the probability of taking it).
    pub fn pdf(&self, wo: Vec3, wi: Vec3, n: Vec3) -> f32 {
        if self.black_behind(wo, n) {
            return 0.0;
        }
        dispatch!(self, m => m.pdf(wo, wi, n))
    }

    /// The model's albedo seen at cosine `cos` to the normal ([`BsdfModel::albedo`]).
    pub fn albedo(&self, cos: f32) -> Rgb {
        dispatch!(self, m => m.albedo(cos))
    }

    /// What `pathspace info` says of the model.
    pub fn describe(&self) -> String {
        dispatch!(self, m => m.describe())
    }

    /// f_s(wo, wi) at a point with normals `nn`: evaluated in the shading frame, times
    /// [`Normals::correction`] (the plain [`Bsdf::eval`] where `ns` is `ng`), so that with the
    /// geometric cosine of the outgoing side it is the same path contribution in both modes.
    pub fn eval_shaded(&self, wo: Vec3, wi: Vec3, nn: Normals, mode: TransportMode) -> Rgb {
        if nn.ns == nn.ng {
            return self.eval(wo, wi, nn.ng, mode);
        }
        let c = nn.correction(wo, wi, mode);
        if c == 0.0 {
            return Rgb::ZERO;
        }
        self.eval(wo, wi, nn.ns, mode) * c
    }

    /// The density of [`Bsdf::sample_shaded`]: the model's own, in the shading frame.
    #[inline]
    pub fn pdf_shaded(&self, wo: Vec3, wi: Vec3, nn: Normals) -> f32 {
        self.pdf(wo, wi, nn.ns)
    }

    /// Samples `wi` in the shading frame, its value times [`Normals::correction`], so that
    /// `value |wi . ng| / pdf` ([`BsdfSample::weight`] with `ng`) is the path weight; `None`
    /// where the correction vanishes (a leak across the two normals).
    pub fn sample_shaded(
        &self,
        wo: Vec3,
        nn: Normals,
        u: Vec2,
        uc: f32,
        mode: TransportMode,
    ) -> Option<BsdfSample> {
        let mut s = self.sample(wo, nn.ns, u, uc, mode)?;
        if nn.ns != nn.ng {
            let c = nn.correction(wo, s.wi, mode);
            if c == 0.0 {
                return None;
            }
            s.value *= c;
        }
        Some(s)
    }

    /// Samples `wi` given `wo`. `None` when no direction can be produced.
    pub fn sample(
        &self,
        wo: Vec3,
        n: Vec3,
        u: Vec2,
        uc: f32,
        mode: TransportMode,
    ) -> Option<BsdfSample> {
        if wo.dot(n) == 0.0 || self.black_behind(wo, n) {
            return None;
        }
        dispatch!(self, m => m.sample(wo, n, u, uc, mode))
    }
}
