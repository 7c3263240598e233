//! The image contribution f of Metropolis light transport (Pauly, Kollig, Keller 2000, sec. 5:
//! f_j(x) = h_j(x) f(x)) for an explicit path x_0 (light) ... x_k (camera: the pinhole or a
//! point of a thin lens, with the lens's W_e in the area measure there), and the densities
//! of its vertices under local sampling, both with the Dirac factors of singular scattering
//! removed in the same way.
//!
//! A mirror or glass vertex has f_s = R delta(w - w_s) / |cos| (Veach 1997 ch. 5, the specular
//! BSDFs). Every sampler that produces such a vertex produces the same delta (the
//! direction is forced), so the delta cancels in every ratio MLT forms: f(y) / T(x -> y) and
//! f(x) / T(y -> x). Here f keeps R / |cos| (the "Dirac-free" value `BsdfSample::value`) and a
//! density keeps the probability of the lobe (`BsdfSample::pdf`), converted to area by the same
//! g / d^2 as any direction: the convention BDPT's throughputs already use.

use std::ops::Range;

use glam::{Vec2, Vec3};

use crate::bsdf::{Bsdf, Lobe, Normals, TransportMode};
use crate::math::distribution::ONE_MINUS_EPSILON;
use crate::math::Sampler;
use crate::path::geometry_term::geometry_term_exact;
use crate::path::geometry_term::to_area;
use crate::path::pdf::{densities_into, Densities};
use crate::path::{LocalSampling, Vertex, VertexKind};
use crate::scene::{Light, Scene};
use crate::spectrum::{luminance, Rgb};

/// 1 - cos of the largest angle between a vertex's specular direction and the direction to its
/// neighbour that still counts as the same direction. Vertices come from traced rays whose
/// origins are lifted by `RAY_EPSILON`; this admits ~4.5e-3 rad, far above that error and far
/// below any perturbation that would change a path.
pub const SPECULAR_COS_TOLERANCE: f32 = 1e-5;

/// The BSDF at a surface vertex if all its lobes are Dirac (mirror, glass). A material with a
/// Dirac and a regular lobe (plastic) is refused by MLT (`check_scene`).
pub fn singular_bsdf<'a>(scene: &'a Scene, v: &Vertex) -> Option<&'a Bsdf> {
    v.material(scene).filter(|b| b.only_dirac_lobes())
}

/// True when vertex `v` scatters only through Dirac lobes (mirror, glass).
pub fn is_specular(scene: &Scene, v: &Vertex) -> bool {
    singular_bsdf(scene, v).is_some()
}

/// The singular lobe `bsdf` uses to turn direction `wo` into `lobe`'s direction at a point
/// with normals `nn`, with the sample record (Dirac-free value, shading correction included,
/// and lobe probability). `None` if the lobe cannot occur.
pub fn specular_sample(
    bsdf: &Bsdf,
    wo: Vec3,
    nn: Normals,
    lobe: Lobe,
    mode: TransportMode,
) -> Option<crate::bsdf::BsdfSample> {
    // the dielectric picks reflection when uc < F: uc = 0 forces reflection, uc -> 1 forces
    // transmission (and falls back to reflection under total internal reflection)
    let uc = match lobe {
        Lobe::SingularTransmission => ONE_MINUS_EPSILON,
        _ => 0.0,
    };
    let s = bsdf.sample_shaded(wo, nn, Vec2::ZERO, uc, mode)?;
    (s.lobe == lobe && s.pdf > 0.0).then_some(s)
}

/// The lobe of the scattering at surface vertex `v` between neighbours `a` and `b`:
/// reflection when both lie on the same side of the surface.
pub fn lobe_between(scene: &Scene, v: &Vertex, a: Vec3, b: Vec3) -> Lobe {
    if !is_specular(scene, v) {
        return Lobe::Regular;
    }
    if (a - v.p).dot(v.n) * (b - v.p).dot(v.n) > 0.0 {
        Lobe::SingularReflection
    } else {
        Lobe::SingularTransmission
    }
}

/// The lobe at vertex i of a path (Regular for anything but a specular surface vertex).
pub fn lobe_at(scene: &Scene, path: &[Vertex], i: usize) -> Lobe {
    if i == 0 || i + 1 >= path.len() {
        return Lobe::Regular;
    }
    lobe_between(scene, &path[i], path[i - 1].p, path[i + 1].p)
}

/// Dirac-free f-hat(from -> v -> to) in radiance mode: f_s or sigma_s f_p for regular vertices,
/// R / |cos| of the lobe for a specular vertex whose neighbours satisfy the specular relation
/// (zero otherwise). The value is the BSDF at the vertex's point (a textured glass's tint).
pub fn f_hat_singular(scene: &Scene, v: &Vertex, from: Vec3, to: Vec3) -> Rgb {
    if !is_specular(scene, v) {
        return v.f_hat(scene, from, to);
    }
    let Some(bsdf) = v.bsdf(scene) else {
        return Rgb::ZERO;
    };
    let wo = (to - v.p).normalize_or_zero();
    let wi = (from - v.p).normalize_or_zero();
    let lobe = lobe_between(scene, v, from, to);
    match specular_sample(&bsdf, wo, v.normals(), lobe, TransportMode::Radiance) {
        Some(s) if s.wi.dot(wi) >= 1.0 - SPECULAR_COS_TOLERANCE => s.value,
        _ => Rgb::ZERO,
    }
}

/// Probability of the lobe that carries `from -> v -> to` when `v` samples from `from`'s side
/// (the Dirac-free direction density of a specular vertex; zero if the relation fails).
///
/// A guided glass vertex chooses its lobe with the guided probability of `mode`'s map
/// (the technique's [`LocalSampling::lobe_choice`], `guide::guided_fresnel`): light subpaths (`Importance`) with W_i,
/// eye subpaths (`Radiance`) with L_i.
pub fn lobe_probability(
    scene: &Scene,
    tech: &dyn LocalSampling,
    v: &Vertex,
    from: Vec3,
    to: Vec3,
    mode: TransportMode,
) -> f32 {
    let Some(bsdf) = singular_bsdf(scene, v) else {
        return 0.0;
    };
    let wo = (from - v.p).normalize_or_zero();
    let wi = (to - v.p).normalize_or_zero();
    let lobe = lobe_between(scene, v, from, to);
    let Some(s) = specular_sample(bsdf, wo, v.normals(), lobe, TransportMode::Radiance) else {
        return 0.0;
    };
    if s.wi.dot(wi) < 1.0 - SPECULAR_COS_TOLERANCE {
        return 0.0;
    }
    match tech.lobe_choice(scene, v, wo, mode) {
        Some((p_r, _, _)) => match lobe {
            Lobe::SingularTransmission => 1.0 - p_r,
            _ => p_r,
        },
        None => s.pdf,
    }
}

/// The image contribution of a path: f (RGB, Dirac-free, eq. 6 with W_e of the pixel the path
/// lands in) and that pixel's continuous raster position. `None` when f = 0 or the path is not
/// light ... camera.
pub fn image_contribution(scene: &Scene, v: &[Vertex]) -> Option<(Rgb, Vec2)> {
    image_contribution_reusing(scene, v, None, &mut Vec::new())
}

/// The edge factors G V and tau of a path, one per edge x_i x_{i+1} (what `image_contribution`
/// spends its ray casts on).
pub type EdgeFactors = Vec<(f32, Rgb)>;

/// A path with its edge factors, for reuse.
pub type PathEdges<'a> = (&'a [Vertex], &'a [(f32, Rgb)]);

/// `image_contribution`, reusing the edge factors of a previous path `old` (with its factors)
/// for every edge whose two vertices it shares, aligned from the light end or from the eye end:
/// a perturbation changes a few edges of a long path, and each edge costs a ray cast through
/// the media. The factors are a function of the two vertices only, so the result is the same to
/// the bit. `edges` receives this path's factors (complete only when f > 0).
// ANCHOR: image_contribution
pub fn image_contribution_reusing(
    scene: &Scene,
    v: &[Vertex],
    old: Option<PathEdges>,
    edges: &mut EdgeFactors,
) -> Option<(Rgb, Vec2)> {
    edges.clear();
    let n = v.len();
    // x0 on a light (at infinity too), or a volume vertex of a glowing medium (eq. 5)
    // n - 2 scattering vertices, at least the scene's min_depth (`hide_emitters`)
    if n < 2 + scene.min_depth() as usize || !(is_light_vertex(&v[0]) || v[0].is_medium()) {
        return None;
    }
    if v[n - 1].kind != VertexKind::Camera || v[1..n - 1].iter().any(|x| !is_scatterer(x)) {
        return None;
    }
    let cam = scene.camera.as_ref()?;
    let imp = cam.importance(v[n - 1].p, (v[n - 2].p - v[n - 1].p).normalize_or_zero())?;
    // tau is the exact one, not ratio tracking's estimate: the target must be a function of the
    // path alone, for the acceptance and for reusing an edge's factors across mutations
    let mut f = start_emission(scene, &v[0], v[1].p);
    for i in 0..n - 1 {
        if f == Rgb::ZERO {
            return None;
        }
        if i > 0 {
            f *= f_hat_singular(scene, &v[i], v[i - 1].p, v[i + 1].p);
        }
        let (g, tau) =
            reused_edge(v, i, old).unwrap_or_else(|| geometry_term_exact(scene, &v[i], &v[i + 1]));
        edges.push((g, tau));
        f *= tau * g;
    }
    f *= imp.we;
    (f.is_finite() && luminance(f) > 0.0).then_some((f, imp.raster))
}
// ANCHOR_END: image_contribution

/// L_e(x0 -> x1) of eq. (6): the light's emission, or at a volume vertex x0 the volume
/// emittance L_e,V0(x0) of eq. (1), isotropic and scaled by the density there (radiance per
/// unit length: with x0's volume measure dV = r^2 dw dr it is the emission of a free flight's
/// collision, and G(x0, x1) has no cosine at x0).
pub fn start_emission(scene: &Scene, v0: &Vertex, towards: Vec3) -> Rgb {
    match v0.kind {
        VertexKind::Medium { .. } => v0.surface_emission(scene, towards),
        _ => v0.emitted(scene, towards),
    }
}

/// The factors of edge i of `v` if `old` has the same two vertices at the same place counted
/// from the light end, or from the eye end.
fn reused_edge(v: &[Vertex], i: usize, old: Option<PathEdges>) -> Option<(f32, Rgb)> {
    let (x, e) = old?;
    if e.len() + 1 != x.len() {
        return None;
    }
    if i + 1 < x.len() && same_vertex(&v[i], &x[i]) && same_vertex(&v[i + 1], &x[i + 1]) {
        return Some(e[i]);
    }
    let from_end = v.len() - 1 - i; // edge i joins v[i] and v[i + 1]; from the eye end
    if from_end < x.len() {
        let j = x.len() - 1 - from_end;
        if same_vertex(&v[i], &x[j]) && same_vertex(&v[i + 1], &x[j + 1]) {
            return Some(e[j]);
        }
    }
    None
}

/// p_L and p_E of every vertex (`path::pdf::densities`) with specular vertices' directions
/// given the probability of their lobe instead of a Dirac (see the module note).
// ANCHOR: singular_densities
pub fn singular_densities(scene: &Scene, tech: &dyn LocalSampling, v: &[Vertex]) -> Densities {
    singular_densities_in(scene, tech, v, 0..v.len())
}

/// `singular_densities` of the vertices `range` only (the others stay 0).
pub fn singular_densities_in(
    scene: &Scene,
    tech: &dyn LocalSampling,
    v: &[Vertex],
    range: Range<usize>,
) -> Densities {
    let mut d = Densities::default();
    singular_densities_into(scene, tech, v, range, &mut d);
    d
}

/// `singular_densities_in` written into `d`, whose buffers are reused.
pub fn singular_densities_into(
    scene: &Scene,
    tech: &dyn LocalSampling,
    v: &[Vertex],
    range: Range<usize>,
    d: &mut Densities,
) {
    let mut unused = Sampler::new(0, 0, 0);
    densities_into(scene, tech, v, range.clone(), &mut unused, d);
    let n = v.len();
    for i in range.start.max(2)..range.end.min(n) {
        if is_specular(scene, &v[i - 1]) {
            let p = lobe_probability(
                scene,
                tech,
                &v[i - 1],
                v[i - 2].p,
                v[i].p,
                TransportMode::Importance,
            );
            d.light[i] = to_area(p, &v[i - 1], &v[i]) * d.prop_up[i - 1];
        }
    }
    for i in range.start..range.end.min(n.saturating_sub(2)) {
        if is_specular(scene, &v[i + 1]) {
            let p = lobe_probability(
                scene,
                tech,
                &v[i + 1],
                v[i + 2].p,
                v[i].p,
                TransportMode::Radiance,
            );
            d.eye[i] = to_area(p, &v[i + 1], &v[i]) * d.prop_down[i];
        }
    }
    if range.start == 0 && n > 0 && is_directional(scene, &v[0]) {
        directional_origin(scene, &v[0], d);
    }
}
// ANCHOR_END: singular_densities

/// A directional light's vertex in the directional measure (book: "Metropolis light
/// transport", lights at infinity): its one direction is a point mass, so a light subpath
/// chooses it with the light's selection probability alone (BDPT's walk keeps the Dirac and
/// caches 0), and no eye subpath can sample it: p_E(x_0) = 0.
fn directional_origin(scene: &Scene, v: &Vertex, d: &mut Densities) {
    if let VertexKind::InfiniteLight { light, .. } = v.kind {
        d.light[0] = scene.light_pmf(light) * crate::scene::emitters::light_share(scene);
        d.eye[0] = 0.0;
    }
}

/// True for a directional light's vertex.
pub fn is_directional(scene: &Scene, v: &Vertex) -> bool {
    match v.kind {
        VertexKind::InfiniteLight { light, .. } => {
            matches!(scene.lights[light as usize], Light::Directional { .. })
        }
        _ => false,
    }
}

/// True for the vertices a path may start with: a point on a light, or a light at infinity.
#[inline]
pub fn is_light_vertex(v: &Vertex) -> bool {
    matches!(
        v.kind,
        VertexKind::Light { .. } | VertexKind::InfiniteLight { .. }
    )
}

/// Distance from a vertex at `p` to where its infinite light's vertex is placed: beyond the
/// scene's bounding sphere whatever `p` (as BDPT places the vertex it reaches or connects to).
pub fn infinite_distance(scene: &Scene, p: Vec3) -> f32 {
    4.0 * scene.radius + (p - scene.center).length()
}

/// Places the vertex x_0 of a light at infinity, if `path` starts with one, along its direction
/// w from x_1: x_0 = x_1 + w (4R + |x_1 - c|). In the directional measure x_0 is the direction
/// w alone; its position is only where the edge's rays and cosines are computed from, so every
/// path a chain holds keeps it on the line through x_1 (a mutation that moves x_1 and keeps w
/// moves it along).
pub fn anchor_infinite(scene: &Scene, path: &mut [Vertex]) {
    if path.len() < 2 {
        return;
    }
    if let VertexKind::InfiniteLight { w, .. } = path[0].kind {
        let p1 = path[1].p;
        path[0].p = p1 + w * infinite_distance(scene, p1);
    }
}

/// True for the vertices a path may have between its ends: surfaces and medium points.
#[inline]
pub fn is_scatterer(v: &Vertex) -> bool {
    matches!(
        v.kind,
        VertexKind::Surface { .. } | VertexKind::Medium { .. }
    )
}

/// True when a light vertex sits at a Dirac position (point and spot lights) or is a
/// directional light's one direction: resampling it can land exactly on the old vertex.
pub fn is_delta_position_light(scene: &Scene, v: &Vertex) -> bool {
    match v.kind {
        VertexKind::Light { light, .. } => matches!(
            scene.lights[light as usize],
            Light::Point { .. } | Light::Spot { .. }
        ),
        VertexKind::InfiniteLight { .. } => is_directional(scene, v),
        _ => false,
    }
}

/// Same vertex (copied, not recomputed): kind and position bit-equal. A light at infinity is
/// its direction alone (its kind holds it; the position follows x_1, see `anchor_infinite`).
#[inline]
pub fn same_vertex(a: &Vertex, b: &Vertex) -> bool {
    a.kind == b.kind && (a.p == b.p || a.is_infinite_light())
}

/// The scalar target f* of the chain: the luminance of f (Pauly et al. sec. 5 leave the
/// choice open; Veach 1997 sec. 11.3 uses luminance for colour images).
#[inline]
pub fn scalar_contribution(f: Rgb) -> f32 {
    luminance(f)
}
