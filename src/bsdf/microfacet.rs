//! The GGX (Trowbridge-Reitz) and Beckmann microfacet distributions with Smith masking, and
//! their samplers (GGX: its visible normals; Beckmann: D(m) cos theta_m), shared by the rough
//! conductor, the rough dielectric and the rough plastic. [`Microfacet`] is the one a material
//! names (`distribution = "ggx" | "beckmann"`), dispatched by a `match` without allocation.
//! Anisotropic roughness (`alpha_u` along the local x, `alpha_v` along y; [`AnisoGgx`],
//! [`AnisoBeckmann`]) is the isotropic distribution of roughness 1 under the stretch (alpha_u x,
//! alpha_v y, z) (Heitz 2014, "Understanding the masking-shadowing function", sec. 5.3), in the
//! frame of the shape's dp/du ([`shading_frame`]).
//!
//! Every function here works in a local frame whose +z is the macro-surface normal on the side
//! the sampled-from direction `wo` lies (`wo.z > 0`); microfacet normals `m` have `m.z > 0`.
//! Slopes are taken from the tangential components (x^2 + y^2) / z^2 rather than from
//! 1 - cos^2, because at small roughness the lobe is a few milliradians wide and 1 - cos^2 in
//! f32 would have no significant digit left.
//!
//! Masking-shadowing is Smith's separable form G = G1(wo) G1(wi) (Walter et al. 2007, eq. 23),
//! the form their reflection and refraction BSDFs are written with; the height-correlated form
//! is exact only for reflection in closed form (for refraction it needs a Beta function).
//!
//! Book: "Surface scattering (eq. 2)", section "Rough surfaces"; spec: `tests/spec/bsdf/microfacet.rs`.

use glam::{Vec2, Vec3};

use crate::math::Frame;
use std::f32::consts::PI;
use std::f64::consts::PI as PI64;

/// The smallest roughness a scene may ask for: below it the lobe is narrower than the angular
/// resolution of f32 directions after a few dot products (a few 1e-7 rad on a 1e-3 wide lobe is
/// already 1e-4 relative error in the slopes), so a smooth material must be used instead.
pub const ALPHA_MIN: f32 = 1e-3;
/// The largest roughness a scene may ask for: at alpha = 1 half of the facets are steeper than
/// 45 degrees, and the single-scattering model already drops 69% of the light at normal
/// incidence (the white furnace of `tests/spec/bsdf/microfacet.rs`); rougher surfaces would drop more.
pub const ALPHA_MAX: f32 = 1.0;

/// The isotropic GGX distribution with roughness `alpha` (the slope scale).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ggx {
    pub alpha: f32,
}

impl Ggx {
    /// D(m): microfacet normals per unit solid angle and unit macro-surface area, projected
    /// (integral of D(m) m.z over the hemisphere is 1). Walter et al. 2007, eq. (33), written
    /// with the slopes x/z, y/z: D = 1 / (pi a^2 z^4 (1 + (x^2 + y^2) / (a^2 z^2))^2).
    pub fn d(&self, m: Vec3) -> f32 {
        if m.z <= 0.0 {
            return 0.0;
        }
        let a2 = self.alpha * self.alpha;
        // z^4 (1 + t^2/a^2)^2 = (z^2 + (x^2 + y^2)/a^2)^2: no division by a small z
        let k = m.z * m.z + (m.x * m.x + m.y * m.y) / a2;
        1.0 / (PI * a2 * k * k)
    }

    /// Smith's Lambda(w) for GGX: (-1 + sqrt(1 + a^2 tan^2 theta)) / 2 (Heitz 2014, eq. 72; the
    /// G1 of Walter et al. 2007, eq. (34), is 1 / (1 + Lambda)). Infinite at grazing angles.
    pub fn lambda(&self, w: Vec3) -> f32 {
        let z2 = w.z * w.z;
        if z2 == 0.0 {
            return f32::INFINITY;
        }
        let a2_tan2 = self.alpha * self.alpha * (w.x * w.x + w.y * w.y) / z2;
        // (sqrt(1 + x) - 1) / 2 = x / (2 (sqrt(1 + x) + 1)), without cancellation at small x
        a2_tan2 / (2.0 * ((1.0 + a2_tan2).sqrt() + 1.0))
    }

    /// G1(w, m): the fraction of microfacets with normal `m` visible from `w` (Walter et al.
    /// 2007, eq. (34)): zero when `w` sees the back of the facet or lies on the other side of
    /// the macro-surface than the facet faces (the chi+ factor of eq. (34)).
    pub fn g1(&self, w: Vec3, m: Vec3) -> f32 {
        if w.dot(m) * w.z <= 0.0 {
            return 0.0;
        }
        1.0 / (1.0 + self.lambda(w))
    }

    /// G(wo, wi, m) = G1(wo, m) G1(wi, m): Smith's separable masking-shadowing (Walter et al.
    /// 2007, eq. (23)).
    pub fn g(&self, wo: Vec3, wi: Vec3, m: Vec3) -> f32 {
        self.g1(wo, m) * self.g1(wi, m)
    }

    /// The density of visible normals seen from `wo` (wo.z > 0): G1(wo) max(0, wo.m) D(m) /
    /// wo.z (Heitz 2018, eq. 1), the density [`Ggx::sample_visible`] draws `m` with.
    pub fn pdf_visible(&self, wo: Vec3, m: Vec3) -> f32 {
        visible_density(wo, m, self.g1(wo, m), || self.d(m))
    }

    /// A microfacet normal drawn from the visible normals seen from `wo` (wo.z > 0), by Heitz
    /// 2018 (JCGT 7(4), listing of sec. 2): stretch `wo` to the configuration where the
    /// microsurface is a hemisphere (alpha = 1), sample the projected disk of that hemisphere
    /// as seen from the stretched direction (a uniform disk, its far half squeezed by the
    /// projection), lift the point onto the hemisphere and unstretch the normal.
    // ANCHOR: sample_visible
    pub fn sample_visible(&self, wo: Vec3, u: Vec2) -> Vec3 {
        // ASSIGNMENT: ggx_visible_normals
        let a = self.alpha;
        // stretched view direction (Heitz 2018, sec. 2, step 1)
        let vh = Vec3::new(a * wo.x, a * wo.y, wo.z).normalize();
        // an orthonormal basis around it with t1 horizontal (step 2)
        let len2 = vh.x * vh.x + vh.y * vh.y;
        let t1 = if len2 > 0.0 {
            Vec3::new(-vh.y, vh.x, 0.0) / len2.sqrt()
        } else {
            Vec3::X
        };
        let t2 = vh.cross(t1);
        // a point of the unit disk; the half hidden behind the hemisphere's rim is squeezed
        // into the visible part by the factor (1 + vh.z) / 2 (step 3)
        let r = u.x.sqrt();
        let phi = 2.0 * PI * u.y;
        let p1 = r * phi.cos();
        let s = 0.5 * (1.0 + vh.z);
        let p2 = (1.0 - s) * (1.0 - p1 * p1).max(0.0).sqrt() + s * r * phi.sin();
        // onto the hemisphere (step 4), then back to the ellipsoid's normal (step 5)
        let nh = p1 * t1 + p2 * t2 + (1.0 - p1 * p1 - p2 * p2).max(0.0).sqrt() * vh;
        Vec3::new(a * nh.x, a * nh.y, nh.z.max(1e-7)).normalize()
        // END ASSIGNMENT
    }
    // ANCHOR_END: sample_visible
}

/// The isotropic Beckmann distribution with roughness `alpha` (the RMS slope), with Smith's G1
/// as Mitsuba 3 evaluates it: the rational approximation of Walter et al. 2007, eq. (27), not
/// the erf form (which [`Beckmann::lambda`] keeps for the tables that need the exact one).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Beckmann {
    pub alpha: f32,
}

impl Beckmann {
    /// D(m) = exp(-tan^2 theta_m / a^2) / (pi a^2 cos^4 theta_m) (Walter et al. 2007, eq. (25)),
    /// written with the tangential components so that a narrow lobe keeps its digits.
    pub fn d(&self, m: Vec3) -> f32 {
        if m.z <= 0.0 {
            return 0.0;
        }
        let a2 = self.alpha * self.alpha;
        let z2 = m.z * m.z;
        let tan2 = (m.x * m.x + m.y * m.y) / z2;
        let d = (-tan2 / a2).exp() / (PI * a2 * z2 * z2);
        // near the horizon both factors underflow (0 / 0): the Gaussian has long vanished
        if d.is_finite() {
            d
        } else {
            0.0
        }
    }

    /// The argument a = 1 / (alpha tan theta) of eqs. (26), (27); infinite at the normal.
    fn a(&self, w: Vec3) -> f64 {
        let t = ((w.x as f64).powi(2) + (w.y as f64).powi(2)).sqrt();
        (w.z as f64).abs() / (self.alpha as f64 * t)
    }

    /// Smith's exact Lambda(w) = (erf(a) - 1) / 2 + exp(-a^2) / (2 a sqrt(pi)), a = 1 / (alpha
    /// tan theta) (Walter et al. 2007, eq. (26) is 1 / (1 + Lambda)); in f64.
    pub fn lambda(&self, w: Vec3) -> f64 {
        let a = self.a(w);
        if !a.is_finite() {
            return 0.0;
        }
        if a == 0.0 {
            return f64::INFINITY;
        }
        // (erf(a) - 1) / 2 = -erfc(a) / 2, without cancellation at large a
        -statrs::function::erf::erfc(a) / 2.0 + (-a * a).exp() / (2.0 * a * PI64.sqrt())
    }

    /// G1(w, m) by the rational approximation of Walter et al. 2007, eq. (27) (relative error
    /// below 0.35%), exactly 1 for a >= 1.6 and at the normal: Mitsuba 3's `smith_g1`, so that
    /// imported scenes evaluate the same BSDF. Zero when `w` sees the facet's back.
    pub fn g1(&self, w: Vec3, m: Vec3) -> f32 {
        if w.dot(m) * w.z <= 0.0 {
            return 0.0;
        }
        walter_rational(self.a(w))
    }

    /// A facet normal with density D(m) cos theta_m: tan^2 theta_m = -alpha^2 ln(1 - u) inverts
    /// the radial CDF 1 - exp(-tan^2 / alpha^2) exactly (Walter et al. 2007, eq. (28)).
    pub fn sample(&self, u: Vec2) -> Vec3 {
        let a = self.alpha as f64;
        let tan2 = -a * a * (1.0 - u.x as f64).max(f64::MIN_POSITIVE).ln();
        let phi = 2.0 * PI64 * u.y as f64;
        let t = tan2.sqrt();
        let m = glam::DVec3::new(t * phi.cos(), t * phi.sin(), 1.0).normalize();
        m.as_vec3()
    }

    /// The density of [`Beckmann::sample`]: D(m) cos theta_m.
    pub fn pdf(&self, m: Vec3) -> f32 {
        self.d(m) * m.z.max(0.0)
    }
}

/// Walter et al. 2007, eq. (27): Beckmann's Smith G1 as a rational function of a = 1 /
/// (alpha tan theta), exactly 1 from a = 1.6 on (Mitsuba 3's `smith_g1`).
fn walter_rational(a: f64) -> f32 {
    if a >= 1.6 {
        return 1.0;
    }
    ((3.535 * a + 2.181 * a * a) / (1.0 + 2.276 * a + 2.577 * a * a)) as f32
}

/// `w` stretched by the two roughnesses, (alpha_u x, alpha_v y, z): the configuration in which
/// an anisotropic distribution is the isotropic one of roughness 1 (Heitz 2014, sec. 5.3; the
/// projected roughness of eq. (80) is |stretched xy| / |xy|).
fn stretch(w: Vec3, alpha_u: f32, alpha_v: f32) -> Vec3 {
    Vec3::new(alpha_u * w.x, alpha_v * w.y, w.z)
}

/// The anisotropic GGX distribution: roughness `alpha_u` along the local x (the tangent) and
/// `alpha_v` along y. Only the rough models' anisotropic materials use it; an isotropic one
/// (`alpha_u == alpha_v`) goes through [`Ggx`], bit for bit as before.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AnisoGgx {
    pub alpha_u: f32,
    pub alpha_v: f32,
}

impl AnisoGgx {
    /// D(m) = 1 / (pi a_u a_v cos^4 theta_m (1 + tan^2 theta_m (cos^2 phi / a_u^2 + sin^2 phi /
    /// a_v^2))^2) (Heitz 2014, eq. 82), with the tangential components as [`Ggx::d`].
    pub fn d(&self, m: Vec3) -> f32 {
        if m.z <= 0.0 {
            return 0.0;
        }
        let (au, av) = (self.alpha_u, self.alpha_v);
        let k = m.z * m.z + m.x * m.x / (au * au) + m.y * m.y / (av * av);
        1.0 / (PI * au * av * k * k)
    }

    /// Smith's Lambda(w) with the projected roughness alpha(phi_w)^2 = cos^2 phi a_u^2 + sin^2
    /// phi a_v^2 (Heitz 2014, eqs. 72 and 80): the isotropic Lambda of roughness 1 at the
    /// stretched direction.
    pub fn lambda(&self, w: Vec3) -> f32 {
        Ggx { alpha: 1.0 }.lambda(stretch(w, self.alpha_u, self.alpha_v))
    }

    /// G1(w, m) = chi+(w.m / w.z) / (1 + Lambda(w)) (Heitz 2014, eq. 43).
    pub fn g1(&self, w: Vec3, m: Vec3) -> f32 {
        if w.dot(m) * w.z <= 0.0 {
            return 0.0;
        }
        1.0 / (1.0 + self.lambda(w))
    }

    /// The density of visible normals seen from `wo`, G1(wo) max(0, wo.m) D(m) / wo.z (Heitz
    /// 2018, eq. 1), the density of [`AnisoGgx::sample_visible`].
    pub fn pdf_visible(&self, wo: Vec3, m: Vec3) -> f32 {
        visible_density(wo, m, self.g1(wo, m), || self.d(m))
    }

    /// Heitz 2018 (JCGT 7(4), sec. 2) with two roughnesses: stretch `wo` by (a_u, a_v, 1), draw
    /// a visible normal of the hemisphere (roughness 1) seen from it, unstretch the normal by
    /// the same factors (steps 1 and 5 of the listing are the only ones that read alpha).
    pub fn sample_visible(&self, wo: Vec3, u: Vec2) -> Vec3 {
        let (au, av) = (self.alpha_u, self.alpha_v);
        let vh = stretch(wo, au, av).normalize();
        let nh = Ggx { alpha: 1.0 }.sample_visible(vh, u);
        Vec3::new(au * nh.x, av * nh.y, nh.z.max(1e-7)).normalize()
    }
}

/// The anisotropic Beckmann distribution (RMS slopes `alpha_u` along x, `alpha_v` along y),
/// with Walter's rational G1 at the projected roughness, as Mitsuba 3's `MicrofacetDistribution`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AnisoBeckmann {
    pub alpha_u: f32,
    pub alpha_v: f32,
}

impl AnisoBeckmann {
    /// D(m) = exp(-tan^2 theta_m (cos^2 phi / a_u^2 + sin^2 phi / a_v^2)) / (pi a_u a_v cos^4
    /// theta_m) (Heitz 2014, eq. 81).
    pub fn d(&self, m: Vec3) -> f32 {
        if m.z <= 0.0 {
            return 0.0;
        }
        let (au, av) = (self.alpha_u, self.alpha_v);
        let z2 = m.z * m.z;
        let e = (m.x * m.x / (au * au) + m.y * m.y / (av * av)) / z2;
        let d = (-e).exp() / (PI * au * av * z2 * z2);
        if d.is_finite() {
            d
        } else {
            0.0
        }
    }

    /// G1(w, m) by Walter et al. 2007, eq. (27), at a = 1 / (alpha(phi_w) tan theta_w), the
    /// projected roughness of Heitz 2014, eq. 80 (Mitsuba 3's `smith_g1`).
    pub fn g1(&self, w: Vec3, m: Vec3) -> f32 {
        if w.dot(m) * w.z <= 0.0 {
            return 0.0;
        }
        let s = stretch(w, self.alpha_u, self.alpha_v).as_dvec3();
        walter_rational(s.z.abs() / (s.x * s.x + s.y * s.y).sqrt())
    }

    /// A facet normal with density D(m) cos theta_m: its slopes (-m.x / m.z, -m.y / m.z) are a
    /// Gaussian of deviations a_u / sqrt 2, a_v / sqrt 2 (Heitz 2014, eq. 81 as a slope
    /// density), drawn as the unit one (radius^2 = -ln(1 - u), Walter et al. 2007, eq. (28))
    /// scaled per axis.
    pub fn sample(&self, u: Vec2) -> Vec3 {
        let r = (-(1.0 - u.x as f64).max(f64::MIN_POSITIVE).ln()).sqrt();
        let phi = 2.0 * PI64 * u.y as f64;
        let (au, av) = (self.alpha_u as f64, self.alpha_v as f64);
        let m = glam::DVec3::new(au * r * phi.cos(), av * r * phi.sin(), 1.0).normalize();
        m.as_vec3()
    }

    /// The density of [`AnisoBeckmann::sample`]: D(m) cos theta_m.
    pub fn pdf(&self, m: Vec3) -> f32 {
        self.d(m) * m.z.max(0.0)
    }
}

/// Which microfacet distribution a rough material uses (the scene file's `distribution`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Distribution {
    #[default]
    Ggx,
    Beckmann,
}

impl Distribution {
    /// The scene file's spelling.
    pub fn name(self) -> &'static str {
        match self {
            Distribution::Ggx => "ggx",
            Distribution::Beckmann => "beckmann",
        }
    }
}

/// A distribution with its roughness: the one interface the rough models use. `alpha` is the
/// roughness along the local x (Mitsuba's `alpha_u`), `alpha_v` along y; equal, the isotropic
/// [`Ggx`] and [`Beckmann`] evaluate it (so isotropic materials keep their bits), otherwise
/// [`AnisoGgx`] and [`AnisoBeckmann`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Microfacet {
    pub distribution: Distribution,
    pub alpha: f32,
    pub alpha_v: f32,
}

/// One of the four distributions a [`Microfacet`] stands for.
enum Kind {
    Ggx(Ggx),
    Beckmann(Beckmann),
    AnisoGgx(AnisoGgx),
    AnisoBeckmann(AnisoBeckmann),
}

impl Microfacet {
    /// An isotropic distribution.
    pub fn new(distribution: Distribution, alpha: f32) -> Self {
        Self::anisotropic(distribution, alpha, alpha)
    }

    /// Roughness `alpha_u` along the tangent (local x), `alpha_v` along the bitangent.
    pub fn anisotropic(distribution: Distribution, alpha_u: f32, alpha_v: f32) -> Self {
        Microfacet {
            distribution,
            alpha: alpha_u,
            alpha_v,
        }
    }

    fn kind(&self) -> Kind {
        let (alpha_u, alpha_v) = (self.alpha, self.alpha_v);
        match (self.distribution, alpha_u == alpha_v) {
            (Distribution::Ggx, true) => Kind::Ggx(Ggx { alpha: alpha_u }),
            (Distribution::Beckmann, true) => Kind::Beckmann(Beckmann { alpha: alpha_u }),
            (Distribution::Ggx, false) => Kind::AnisoGgx(AnisoGgx { alpha_u, alpha_v }),
            (Distribution::Beckmann, false) => {
                Kind::AnisoBeckmann(AnisoBeckmann { alpha_u, alpha_v })
            }
        }
    }

    /// D(m), normalized so that the projected area is one (integral of D(m) m.z is 1).
    pub fn d(&self, m: Vec3) -> f32 {
        match self.kind() {
            Kind::Ggx(g) => g.d(m),
            Kind::Beckmann(b) => b.d(m),
            Kind::AnisoGgx(g) => g.d(m),
            Kind::AnisoBeckmann(b) => b.d(m),
        }
    }

    /// Smith's G1(w, m) (GGX exactly, Beckmann by Walter's rational approximation).
    pub fn g1(&self, w: Vec3, m: Vec3) -> f32 {
        match self.kind() {
            Kind::Ggx(g) => g.g1(w, m),
            Kind::Beckmann(b) => b.g1(w, m),
            Kind::AnisoGgx(g) => g.g1(w, m),
            Kind::AnisoBeckmann(b) => b.g1(w, m),
        }
    }

    /// Smith's separable G(wo, wi, m) = G1(wo, m) G1(wi, m) (Walter et al. 2007, eq. (23)).
    pub fn g(&self, wo: Vec3, wi: Vec3, m: Vec3) -> f32 {
        self.g1(wo, m) * self.g1(wi, m)
    }

    /// A facet normal for `wo` (wo.z > 0): GGX's visible normals (Heitz 2018), Beckmann's
    /// D(m) cos theta_m (its visible normals have no closed-form inverse, and an iterated one
    /// would leave the density inexact). The normal may face away from `wo`; callers reject it.
    pub fn sample(&self, wo: Vec3, u: Vec2) -> Vec3 {
        match self.kind() {
            Kind::Ggx(g) => g.sample_visible(wo, u),
            Kind::Beckmann(b) => b.sample(u),
            Kind::AnisoGgx(g) => g.sample_visible(wo, u),
            Kind::AnisoBeckmann(b) => b.sample(u),
        }
    }

    /// The density of `m` under [`Microfacet::sample`] from `wo`, zero for a facet `wo` sees
    /// from behind (those samples are rejected, so they carry no density of a direction).
    pub fn pdf(&self, wo: Vec3, m: Vec3) -> f32 {
        match self.kind() {
            Kind::Ggx(g) => g.pdf_visible(wo, m),
            Kind::AnisoGgx(g) => g.pdf_visible(wo, m),
            Kind::Beckmann(b) if wo.dot(m) > 0.0 => b.pdf(m),
            Kind::AnisoBeckmann(b) if wo.dot(m) > 0.0 => b.pdf(m),
            Kind::Beckmann(_) | Kind::AnisoBeckmann(_) => 0.0,
        }
    }
}

/// The anisotropy of a rough material at a point: the roughness `alpha_v` across the tangent
/// (the material's `alpha` is along it) and the tangent, the shape's dp/du there (Mitsuba 3's
/// shading frame: `SurfaceInteraction::initialize_sh_frame`). `tangent` is zero until a point
/// is known (`Scene::bsdf_at` sets it).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Anisotropy {
    pub alpha_v: f32,
    pub tangent: Vec3,
}

/// `alpha 0.3`, or `alpha_u 0.1, alpha_v 0.4` (what `pathspace info` says of a roughness).
pub fn describe_alpha(alpha: f32, anisotropy: Option<&Anisotropy>) -> String {
    match anisotropy {
        None => format!("alpha {alpha}"),
        Some(a) => format!("alpha_u {alpha}, alpha_v {}", a.alpha_v),
    }
}

/// The local frame of a rough model at a point with shading normal `n` (as the shape gives
/// it), whose +z is `nf` (`n` or `-n`, the side of `wo`): Duff et al.'s frame around `nf` for
/// an isotropic material (whose value does not depend on the tangent), else Mitsuba 3's
/// shading frame: x the tangent made perpendicular to `n` (Gram-Schmidt), or Duff et al.'s
/// first axis around `n` where the tangent is zero or along `n` (a sphere's poles).
pub fn shading_frame(anisotropy: Option<&Anisotropy>, n: Vec3, nf: Vec3) -> Frame {
    let Some(a) = anisotropy else {
        return Frame::from_normal(nf);
    };
    let s = (a.tangent - n * n.dot(a.tangent))
        .try_normalize()
        .unwrap_or_else(|| Frame::from_normal(n).s);
    // D is even in x and in y: the orientation of t (which side of nf) does not matter
    Frame {
        s,
        t: nf.cross(s),
        n: nf,
    }
}

/// Mirror reflection of `w` about the (unit) microfacet normal `m`.
#[inline]
pub fn reflect_about(w: Vec3, m: Vec3) -> Vec3 {
    2.0 * w.dot(m) * m - w
}

/// The direction refracted from `w` through a facet with normal `m` on `w`'s side (w.m > 0),
/// for eta = eta_w / eta_other; `None` under total internal reflection.
#[inline]
pub fn refract_about(w: Vec3, m: Vec3, eta: f32) -> Option<Vec3> {
    let cos_w = w.dot(m);
    let sin2_t = eta * eta * (1.0 - cos_w * cos_w).max(0.0);
    if sin2_t >= 1.0 {
        return None;
    }
    let cos_t = (1.0 - sin2_t).sqrt();
    Some((-eta * w + (eta * cos_w - cos_t) * m).normalize())
}

/// G1(wo) max(0, wo.m) D(m) / wo.z (Heitz 2018, eq. 1) from `g1` = G1(wo, m) and D(m) (read
/// only where the density is not 0), for wo.z > 0; 0 elsewhere.
#[inline]
fn visible_density(wo: Vec3, m: Vec3, g1: f32, d: impl FnOnce() -> f32) -> f32 {
    if wo.z <= 0.0 {
        return 0.0;
    }
    let c = wo.dot(m);
    if c <= 0.0 {
        return 0.0;
    }
    g1 * c * d() / wo.z
}
