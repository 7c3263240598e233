//! Two ways of sampling a distance along one ray, with the exact density of each: free flight
//! (Table 1, span by span through null boundaries) and equiangular sampling toward a light
//! point (Kulla and Fajardo 2012) over the union of the ray's scattering spans.
//!
//! A technique that combines them by multiple importance sampling needs both densities at any
//! point of the ray, whichever strategy drew it: [`RayMedia`] holds the ray's medium spans once
//! (from the shared [`Segments`] iterator, so its spans are the ones propagation walks) and
//! evaluates [`RayMedia::free_flight_pdf`] and [`RayMedia::equiangular_pdf`] there. The path
//! tracer uses them on every ray of its walk (`distance = "equiangular-mis"`); BDPT and MLT
//! sample by free flight only and do not need them.
//!
//! Inhomogeneous media: delta tracking draws a collision with exactly Table 1's density
//! sigma_t(x) exp(-tau(t)) (Woodcock tracking's classical result; Pauly, Kollig, Keller 2000,
//! Table 1, right column), and the optical depth tau is a deterministic function of the ray
//! (`Medium::optical_depth`: exact for grids and closed-form fields), so the free-flight density
//! is known at any point, as BDPT's weights use it too. Where tau is the fixed quadrature of an
//! fBm field, the weights take the quadrature's density: balance-heuristic weights built from
//! any deterministic densities still sum to one at every point, so the estimate stays unbiased
//! (Veach 1997, sec. 9.2: only that sum and the support matter), and the equiangular estimate
//! takes the tracked (unbiased) transmittance there instead of the approximate closed form.
//!
//! Book: "Sampling toward lights", section "Equiangular distances"; tests:
//! `tests/spec/medium/equiangular.rs`.

use glam::Vec3;

use crate::geometry::Ray;
use crate::math::Sampler;
use crate::medium::Equiangular;
use crate::scene::{Scene, Segment, SegmentEnd, Segments};
use crate::spectrum::Rgb;

/// The most medium spans of one ray that equiangular sampling covers: spans beyond them are
/// outside its domain (its density is 0 there, for the sampler and the MIS weights alike).
pub const MAX_SPANS: usize = 16;

/// The most segments of one ray that [`RayMedia`] keeps for propagation to walk again
/// (a ray crossing more null boundaries is walked by new queries).
const MAX_SEGMENTS: usize = 8;

/// A placeholder for the unused entries of [`RayMedia`]'s segments.
const NO_SEGMENT: Segment = Segment {
    t0: 0.0,
    t1: 0.0,
    medium: None,
    first: false,
    end: SegmentEnd::Open,
};

/// One stretch of the ray inside one medium, between ray parameters `t0` and `t1`.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Span {
    pub t0: f32,
    pub t1: f32,
    pub medium: u32,
    /// True for a medium that scatters in some channel and is not marched
    /// (`Medium::scatters_equiangular`): equiangular sampling's domain is the union of these
    /// spans' stretches `lo..hi`.
    pub scatters: bool,
    /// The part of `t0..t1` where the medium can scatter: the whole span, or its clip to an
    /// inhomogeneous medium's box (its density is zero outside).
    pub lo: f32,
    pub hi: f32,
}

/// The medium spans of a ray up to its first non-null surface (at most [`MAX_SPANS`]), held
/// in place (no allocation per sample).
#[derive(Clone, Copy, Debug)]
pub struct RayMedia {
    pub ray: Ray,
    spans: [Span; MAX_SPANS],
    n: usize,
    /// The ray's segments as [`Segments`] gave them, all of them up to the one that ends the
    /// ray when `complete` (then `n_segments` of them).
    segments: [Segment; MAX_SEGMENTS],
    n_segments: usize,
    complete: bool,
}

impl RayMedia {
    /// The spans of `ray` starting in `medium` (vacuum stretches are left out: they add
    /// nothing to optical depth, and no collision happens in them).
    pub fn collect(scene: &Scene, ray: Ray, medium: Option<u32>) -> Self {
        Self::collect_from(scene, ray, 0.0, medium)
    }

    /// [`RayMedia::collect`] for a ray lifted `lead` past its vertex: the first span starts at
    /// t = -lead, as `Scene::propagate` measures it, so that both agree on every parameter.
    pub fn collect_from(scene: &Scene, ray: Ray, lead: f32, medium: Option<u32>) -> Self {
        Self::collect_seen(scene, ray, (lead, medium), false)
    }

    /// [`RayMedia::collect_from`] along the segments the camera sees before its first
    /// scattering vertex when `from_camera` ([`Segments::from_camera`]).
    pub fn collect_seen(
        scene: &Scene,
        ray: Ray,
        (lead, medium): (f32, Option<u32>),
        from_camera: bool,
    ) -> Self {
        let mut out = RayMedia {
            ray,
            spans: [Span::default(); MAX_SPANS],
            n: 0,
            segments: [NO_SEGMENT; MAX_SEGMENTS],
            n_segments: 0,
            complete: false,
        };
        let segments = Segments::new(scene, ray, medium, f32::INFINITY)
            .lead(lead)
            .from_camera(from_camera);
        for seg in segments {
            if out.n == MAX_SPANS {
                break;
            }
            let kept = out.n_segments < MAX_SEGMENTS;
            if kept {
                out.segments[out.n_segments] = seg;
                out.n_segments += 1;
            }
            if let Some(m) = seg.medium {
                out.spans[out.n] = Self::span(scene, ray, (seg.t0, seg.t1), m);
                out.n += 1;
            }
            if !matches!(seg.end, SegmentEnd::Null(_)) {
                // kept, so were all before it
                out.complete = kept;
                break;
            }
        }
        out
    }

    /// Every segment of the ray up to the one that ends it, as [`Segments`] gives them from
    /// the ray, lead and medium this was collected from; `None` when more than were kept.
    #[inline]
    pub fn segments(&self) -> Option<&[Segment]> {
        self.complete.then(|| &self.segments[..self.n_segments])
    }

    /// The span `t0..t1` of `ray` in medium `m`, its scattering stretch clipped to the
    /// medium's box.
    fn span(scene: &Scene, ray: Ray, (t0, t1): (f32, f32), m: u32) -> Span {
        let med = &scene.media[m as usize];
        let clip = match med.bounds() {
            None => Some((t0, t1)),
            Some(b) if t1.is_finite() => {
                let sr = Ray::new(ray.at(t0), ray.d);
                b.intersect(&sr, sr.d.recip(), t1 - t0)
                    .map(|(a, e)| (t0 + a, (t0 + e).min(t1)))
            }
            // an unbounded span never holds a box: an inhomogeneous medium fills a shape
            Some(_) => None,
        };
        let (lo, hi) = clip.filter(|(a, e)| e > a).unwrap_or((t0, t0));
        Span {
            t0,
            t1,
            medium: m,
            scatters: med.scatters_equiangular() && hi > lo,
            lo,
            hi,
        }
    }

    /// The spans, in order along the ray.
    #[inline]
    pub fn spans(&self) -> &[Span] {
        &self.spans[..self.n]
    }

    /// The span of medium `m` that holds ray parameter `t` (ends included), the first if two
    /// adjacent ones share an end.
    pub fn locate(&self, t: f32, m: u32) -> Option<usize> {
        self.spans()
            .iter()
            .position(|s| s.medium == m && s.t0 <= t && t <= s.t1)
    }

    /// The total angle Theta under which `eq`'s light point sees the scattering spans.
    fn angle_total(&self, eq: &Equiangular) -> f32 {
        self.spans()
            .iter()
            .filter(|s| s.scatters)
            .map(|s| eq.angle(s.hi) - eq.angle(s.lo))
            .sum()
    }

    /// The angles theta(lo) and theta(hi) of each span's scattering stretch seen from `eq`'s
    /// light point (zeros for a span that does not scatter), and their total as
    /// [`RayMedia::angle_total`] sums it: the arc tangents of one sample, taken once.
    fn angles(&self, eq: &Equiangular) -> ([(f32, f32); MAX_SPANS], f32) {
        let mut ends = [(0.0, 0.0); MAX_SPANS];
        for (e, s) in ends.iter_mut().zip(self.spans()) {
            if s.scatters {
                *e = (eq.angle(s.lo), eq.angle(s.hi));
            }
        }
        let total = self
            .spans()
            .iter()
            .zip(&ends)
            .filter(|(s, _)| s.scatters)
            .map(|(_, &(lo, hi))| hi - lo)
            .sum();
        (ends, total)
    }

    /// The density (per unit length) with which [`RayMedia::sample_equiangular`] toward `y`
    /// draws ray parameter `t` in span `i`: h / (Theta (h^2 + (t - delta)^2)), 0 outside the
    /// scattering stretches (Kulla and Fajardo 2012, restricted to a union of intervals).
    pub fn equiangular_pdf(&self, y: Vec3, i: usize, t: f32) -> f32 {
        let Some(s) = self.spans().get(i) else {
            return 0.0;
        };
        if !s.scatters || !(s.lo..=s.hi).contains(&t) {
            return 0.0;
        }
        let Some(eq) = Equiangular::new(self.ray.o, self.ray.d, y) else {
            return 0.0;
        };
        let total = self.angle_total(&eq);
        if total > 0.0 && total.is_finite() {
            eq.angular_rate(t) / total
        } else {
            0.0
        }
    }

    /// Draws a ray parameter equiangularly toward `y` over the scattering spans: a span with
    /// probability proportional to the angle it subtends, then the angle uniform within it.
    /// Returns (span, t, density), or `None` when `y` lies on the ray's line or sees no span.
    pub fn sample_equiangular(&self, y: Vec3, u: f32) -> Option<(usize, f32, f32)> {
        let eq = Equiangular::new(self.ray.o, self.ray.d, y)?;
        let (ends, total) = self.angles(&eq);
        if !(total > 0.0 && total.is_finite()) {
            return None;
        }
        let target = u * total;
        let mut acc = 0.0;
        let mut chosen = None;
        for (i, s) in self.spans().iter().enumerate() {
            let a = ends[i].1 - ends[i].0;
            if !s.scatters || a <= 0.0 {
                continue;
            }
            // the last span takes what rounding leaves of the sum
            chosen = Some((i, ((target - acc) / a).clamp(0.0, 1.0)));
            if target < acc + a {
                break;
            }
            acc += a;
        }
        let (i, v) = chosen?;
        let s = self.spans[i];
        let t = eq.sample_between((s.lo, ends[i].0), (s.hi, ends[i].1), v);
        let pdf = eq.angular_rate(t) / total;
        (pdf > 0.0 && pdf.is_finite() && t.is_finite()).then_some((i, t, pdf))
    }

    /// The density of a free-flight collision at ray parameter `t` in span `i`: the passage
    /// probabilities of the spans before it times the collision density in it (Table 1, as
    /// `Scene::propagate` draws it; one-sample MIS over channels included).
    pub fn free_flight_pdf(&self, scene: &Scene, i: usize, t: f32) -> f32 {
        let mut pdf = 1.0;
        for (k, s) in self.spans().iter().enumerate().take(i + 1) {
            let med = &scene.media[s.medium as usize];
            let sr = Ray::new(self.ray.at(s.t0), self.ray.d);
            if k == i {
                return pdf * med.free_flight_pdf(&sr, t - s.t0, true);
            }
            pdf *= med.free_flight_pdf(&sr, s.t1 - s.t0, false);
        }
        0.0
    }

    /// The deterministic exp(-tau) from the start of the first span to ray parameter `t` in
    /// span `i` (eq. 3), by `Medium::transmittance_exact` (fBm fields: the quadrature's).
    pub fn transmittance_exact(&self, scene: &Scene, i: usize, t: f32) -> Rgb {
        let mut tr = Rgb::ONE;
        for (k, s) in self.spans().iter().enumerate().take(i + 1) {
            let med = &scene.media[s.medium as usize];
            let sr = Ray::new(self.ray.at(s.t0), self.ray.d);
            let end = if k == i { t } else { s.t1 };
            tr *= med.transmittance_exact(&sr, end - s.t0);
        }
        tr
    }

    /// The transmittance from the start of the first span to ray parameter `t` in span `i`
    /// (eq. 3): exact where the optical depth is (`Medium::exact_optical_depth`), else the
    /// medium's unbiased tracking estimate drawn from `sampler`.
    pub fn transmittance(&self, scene: &Scene, i: usize, t: f32, sampler: &mut Sampler) -> Rgb {
        let mut tr = Rgb::ONE;
        for (k, s) in self.spans().iter().enumerate().take(i + 1) {
            let med = &scene.media[s.medium as usize];
            let sr = Ray::new(self.ray.at(s.t0), self.ray.d);
            let end = if k == i { t } else { s.t1 };
            tr *= if med.exact_optical_depth() {
                med.transmittance_exact(&sr, end - s.t0)
            } else {
                med.transmittance(&sr, end - s.t0, sampler)
            };
            if tr == Rgb::ZERO {
                break;
            }
        }
        tr
    }
}
