//! `Path::verify`: every factor a sampler cached on a path, recomputed from the vertices alone.
//!
//! A bidirectional sampler stores on each vertex what later stages reuse without re-tracing:
//! the forward and reverse densities (`pdf_fwd`, `pdf_rev`, in the vertex's measure, with
//! Table 1's propagation pdf), the propagation pdfs of the edges back to the predecessor
//! (`prop_rev`) and from it (`prop_fwd`) and the throughput `beta`. MIS weights (BDPT),
//! transition densities (MLT) and the particles' weights (Kristensen 2010, ch. 5) are only
//! right when these caches equal the densities and contributions of eq. (6) and sec. 4 of
//! Pauly, Kollig, Keller 2000 evaluated on the finished path. The idea is Mitsuba 0.6's `Path::verify` (libbidir): recompute, compare
//! factor by factor, report the first disagreement.
//!
//! Recomputed with public functions only: `path::pdf::densities` (both ends' densities and the
//! edges' propagation pdfs, through `Scene::edge`), `Scene::edge` for transmittance and
//! `path::contribution` (eq. 6) for the whole path.

use super::geometry_term::geometry_term_exact;
use super::pdf::{densities, strategy_pdf};
use super::{geometry_term, measurement_contribution, LocalSampling, Path, VertexKind};
use crate::math::Sampler;
use crate::medium::Medium;
use crate::scene::Scene;
use crate::spectrum::Rgb;

/// Relative tolerance of every comparison, before the geometry's own slack. The caches and
/// their recomputation evaluate the same formulas in f32 on slightly different inputs: the
/// sampler uses the direction it drew and the distance along its lifted ray, the check the
/// direction and distance between the stored (rounded, reprojected) positions. Rounding alone
/// (2^-24 relative per operation, a few dozen operations per density or throughput, and an
/// exponential of a segment length) stays far below 1e-3. The lift of ray origins off
/// surfaces (`geometry::RAY_EPSILON`) is not small at grazing angles or on short edges, so
/// each comparison adds the bound `lift_slack` computes from the edges the factor depends on
/// (lift / (d |cos|) per surface end), and `emission_slack` for a spot light's falloff band.
/// A dropped or doubled factor (a cosine, a pdf, sigma_s, a transmittance) is wrong by far
/// more on almost any path (`tests/invariants/path_verify.rs` breaks three and sees each turn it red).
pub const REL_TOLERANCE: f64 = 1e-3;

/// The first cached factor that its recomputation does not reproduce.
#[derive(Clone, Debug, PartialEq)]
pub struct Mismatch {
    /// Index of the vertex in the path (light end first).
    pub vertex: usize,
    /// Which factor: `pdf_fwd`, `pdf_rev`, `prop_rev`, `prop_fwd`, `beta`, `edge G`, `edge tau`,
    /// `contribution`.
    pub factor: &'static str,
    pub cached: f64,
    pub recomputed: f64,
}

impl std::fmt::Display for Mismatch {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "vertex {}: {} cached {:e}, recomputed {:e}",
            self.vertex, self.factor, self.cached, self.recomputed
        )
    }
}

/// True when `a` and `b` agree within `tol` of the larger (both zero agrees).
fn close(a: f64, b: f64, tol: f64) -> bool {
    a == b || (a - b).abs() <= tol * a.abs().max(b.abs())
}

/// The relative error the lifts put on the factors of edges `edges` (x_e x_{e+1} for e in
/// it): a surface end's ray origin is lifted by `RAY_EPSILON (1 + |p|)` along its normal, which
/// moves the far vertex off the stored one's sampled direction by that much, a relative error
/// of lift / (d |cos|) in each cosine at the surface end (and lift / d in the distance). Three
/// times the sum bounds the (at most three) places a factor meets the same cosine.
fn lift_slack(v: &[super::Vertex], edges: std::ops::Range<usize>) -> f64 {
    let mut slack = 0.0f64;
    for e in edges.start..edges.end.min(v.len().saturating_sub(1)) {
        let (a, b) = (&v[e], &v[e + 1]);
        let w = b.p - a.p;
        let d = w.length() as f64;
        if d <= 0.0 {
            continue;
        }
        let w = w / d as f32;
        for x in [a, b] {
            if x.n != glam::Vec3::ZERO && !x.is_sensor() {
                let lift =
                    crate::geometry::RAY_EPSILON as f64 * (1.0 + x.p.abs().max_element() as f64);
                let cos = (x.n.dot(w).abs() as f64).max(1e-6);
                slack += lift / (d * cos) + lift / d;
            }
        }
    }
    3.0 * slack
}

/// The relative error of a spot light's emission towards `to` from `light` when the direction
/// is off by the angle a lift makes at the far end (see [`lift_slack`]): within the falloff
/// band the smoothstep I(x) = x^2 (3 - 2x) has d ln I / dx = 6 (1 - x) / (x (3 - 2x)), steep at
/// the cone's edge (x -> 0). Zero for every other light and outside the band.
fn emission_slack(scene: &Scene, light: &super::Vertex, to: glam::Vec3) -> f64 {
    let VertexKind::Light { light: l, .. } = light.kind else {
        return 0.0;
    };
    let crate::scene::Light::Spot {
        frame,
        cos_total,
        cos_falloff,
        ..
    } = &scene.lights[l as usize]
    else {
        return 0.0;
    };
    let w = to - light.p;
    let d = w.length() as f64;
    let c = (w.normalize_or_zero().dot(frame.n)) as f64;
    let (c0, c1) = (*cos_total as f64, *cos_falloff as f64);
    if d <= 0.0 || c < c0 || c >= c1 {
        return 0.0;
    }
    let x = ((c - c0) / (c1 - c0)).max(1e-6);
    let angle = crate::geometry::RAY_EPSILON as f64 * (1.0 + to.abs().max_element() as f64) / d;
    let sin = (1.0 - c * c).max(0.0).sqrt();
    3.0 * 6.0 * (1.0 - x) / (x * (3.0 - 2.0 * x)) * sin * angle / (c1 - c0)
}

fn check(vertex: usize, factor: &'static str, cached: f64, recomputed: f64) -> Verdict {
    check_within(vertex, factor, cached, recomputed, 0.0)
}

/// [`check`] with `slack` added to [`REL_TOLERANCE`] (see `lift_slack`).
fn check_within(
    vertex: usize,
    factor: &'static str,
    cached: f64,
    recomputed: f64,
    slack: f64,
) -> Verdict {
    if close(cached, recomputed, REL_TOLERANCE + slack) {
        Ok(())
    } else {
        Err(Mismatch {
            vertex,
            factor,
            cached,
            recomputed,
        })
    }
}

fn check_rgb(
    vertex: usize,
    factor: &'static str,
    cached: Rgb,
    recomputed: Rgb,
    slack: f64,
) -> Verdict {
    for c in 0..3 {
        check_within(
            vertex,
            factor,
            cached[c] as f64,
            recomputed[c] as f64,
            slack,
        )?;
    }
    Ok(())
}

/// The outcome of a check: nothing, or the first mismatch.
pub type Verdict = Result<(), Mismatch>;

/// True when `Scene::edge`'s transmittance is a function of the end points: homogeneous media
/// only (heterogeneous ones estimate it by ratio tracking, an unbiased random number, so the
/// throughput cannot be recomputed; their densities can, `free_flight_pdf` being exact).
pub fn deterministic_transmittance(scene: &Scene) -> bool {
    scene.media.iter().all(Medium::closed_form)
}

/// The part of the sensor an eye subpath samples its first direction in: one pixel of the
/// pinhole's film (the camera subpath is traced per pixel, so its direction density is the
/// film's `pdf_dir` divided by this), the whole meter otherwise.
fn pixel_fraction(scene: &Scene, sensor: &super::Vertex) -> f32 {
    match (sensor.kind, scene.camera.as_ref()) {
        (VertexKind::Camera, Some(c)) => 1.0 / (c.width * c.height) as f32,
        _ => 1.0,
    }
}

impl Path {
    /// Checks the caches of a path x_0 (light end) ... x_k (sensor end) whose vertices
    /// x_0 .. x_{s-1} are as a light subpath left them (`pdf_fwd` = p_L, `pdf_rev` = p_E,
    /// `prop_rev` towards x_{i-1}) and x_s .. x_k as an eye subpath left them, reversed
    /// (`pdf_fwd` = p_E, `pdf_rev` = p_L, `prop_rev` towards x_{i+1}): strategy (s, t) of BDPT
    /// before its connection, a whole light subpath (s = k + 1) or a whole eye subpath
    /// reversed (s = 0). Entries only a connection could set (the reverse densities of the two
    /// vertices on each side of it) are not checked. `beta` also checks each subpath's
    /// throughput step by step (f-hat G tau / pdf_fwd) and, for s, t > 0, that f_j / p_(s,t)
    /// (eq. 6 over the strategy's density) equals the throughputs joined by the connection:
    /// only for paths sampled without Russian roulette (its survival probability divides beta
    /// and is not a function of the vertices) in scenes whose transmittance is deterministic
    /// ([`deterministic_transmittance`]).
    pub fn verify(
        &self,
        scene: &Scene,
        tech: &dyn LocalSampling,
        s: usize,
        beta: bool,
        sampler: &mut Sampler,
    ) -> Verdict {
        let v = &self.vertices;
        let n = v.len();
        if n < 2 {
            return Ok(()); // no edge: nothing was cached
        }
        let s = s.min(n);
        let d = densities(scene, tech, self, sampler);
        for i in 0..s {
            let x = &v[i];
            let fwd = lift_slack(v, i.saturating_sub(2)..i);
            check_within(i, "pdf_fwd", x.pdf_fwd as f64, d.light[i] as f64, fwd)?;
            if i > 0 {
                let e = lift_slack(v, i - 1..i);
                check_within(
                    i,
                    "prop_rev",
                    x.prop_rev as f64,
                    d.prop_down[i - 1] as f64,
                    e,
                )?;
                check_within(i, "prop_fwd", x.prop_fwd as f64, d.prop_up[i - 1] as f64, e)?;
            }
            if i + 2 < s {
                let rev = lift_slack(v, i..i + 2);
                check_within(i, "pdf_rev", x.pdf_rev as f64, d.eye[i] as f64, rev)?;
            }
        }
        for j in s..n {
            let x = &v[j];
            let fwd = lift_slack(v, j..j + 2);
            check_within(j, "pdf_fwd", x.pdf_fwd as f64, d.eye[j] as f64, fwd)?;
            if j + 1 < n {
                let e = lift_slack(v, j..j + 1);
                check_within(j, "prop_rev", x.prop_rev as f64, d.prop_up[j] as f64, e)?;
                check_within(j, "prop_fwd", x.prop_fwd as f64, d.prop_down[j] as f64, e)?;
            }
            if j >= s + 2 {
                let rev = lift_slack(v, j - 2..j);
                check_within(j, "pdf_rev", x.pdf_rev as f64, d.light[j] as f64, rev)?;
            }
        }
        if beta {
            self.verify_beta(scene, tech, s, sampler)?;
        }
        Ok(())
    }

    /// The throughputs of both subpaths, step by step, and f_j / p_(s,t) against them.
    fn verify_beta(
        &self,
        scene: &Scene,
        tech: &dyn LocalSampling,
        s: usize,
        sampler: &mut Sampler,
    ) -> Verdict {
        let v = &self.vertices;
        let n = v.len();
        let edge =
            |sampler: &mut Sampler, i: usize| geometry_term(scene, &v[i], &v[i + 1], sampler);
        // the light subpath: beta(x_1) = L_e G tau / (p(x_0) p(x_1)), then f-hat G tau / p
        for i in 1..s {
            let (g, tau) = edge(sampler, i - 1);
            let expected = if i == 1 {
                if !matches!(v[0].kind, VertexKind::Light { .. }) {
                    continue;
                }
                v[0].emitted(scene, v[1].p) * (tau * g / (v[0].pdf_fwd * v[1].pdf_fwd))
            } else {
                if v[i - 1].delta {
                    continue;
                }
                let f = v[i - 1].f_hat(scene, v[i - 2].p, v[i].p);
                v[i - 1].beta * f * (tau * g / v[i].pdf_fwd)
            };
            let mut slack = lift_slack(v, i.saturating_sub(2)..i);
            if i == 1 {
                slack += emission_slack(scene, &v[0], v[1].p);
            }
            check_rgb(i, "beta", v[i].beta, expected, slack)?;
        }
        // the eye subpath, from the sensor: beta(x_{k-1}) = W_e G tau / (p(x_k) p(x_{k-1}))
        for j in (s..n.saturating_sub(1)).rev() {
            let (g, tau) = edge(sampler, j);
            let expected = if j + 2 == n {
                if !v[n - 1].is_sensor() {
                    continue;
                }
                let we = v[n - 1].importance(scene, v[j].p) * pixel_fraction(scene, &v[n - 1]);
                we * (tau * g / (v[n - 1].pdf_fwd * v[j].pdf_fwd))
            } else {
                if v[j + 1].delta {
                    continue;
                }
                let f = v[j + 1].f_hat(scene, v[j].p, v[j + 2].p);
                v[j + 1].beta * f * (tau * g / v[j].pdf_fwd)
            };
            check_rgb(j, "beta", v[j].beta, expected, lift_slack(v, j..j + 2))?;
        }
        self.verify_contribution(scene, tech, s, sampler)
    }

    /// f_j / p_(s,t) (eq. 6 over the strategy's density) against the two subpaths'
    /// throughputs joined by the connection's f-hat G tau f-hat, for 0 < s < n.
    fn verify_contribution(
        &self,
        scene: &Scene,
        tech: &dyn LocalSampling,
        s: usize,
        sampler: &mut Sampler,
    ) -> Verdict {
        let v = &self.vertices;
        let n = v.len();
        if s == 0 || s >= n || v.iter().any(|x| x.delta) {
            return Ok(());
        }
        let f = measurement_contribution(scene, self, sampler);
        if f == Rgb::ZERO {
            return Ok(());
        }
        let d = densities(scene, tech, self, sampler);
        let mut p = strategy_pdf(&d, s) as f32;
        if s + 1 < n {
            // the eye subpath sampled its direction within one pixel
            p /= pixel_fraction(scene, &v[n - 1]);
        }
        let (g, tau) = geometry_term(scene, &v[s - 1], &v[s], sampler);
        // the light side up to and including x_{s-1}'s f-hat (L_e / p(x_0) for s = 1)
        let light = if s >= 2 {
            v[s - 1].beta * v[s - 1].f_hat(scene, v[s - 2].p, v[s].p)
        } else {
            v[0].emitted(scene, v[1].p) / v[0].pdf_fwd
        };
        // the eye side from x_s's f-hat on (W_e / p(x_k) for t = 1)
        let eye = if s + 1 < n {
            v[s].f_hat(scene, v[s - 1].p, v[s + 1].p) * v[s].beta
        } else {
            v[s].importance(scene, v[s - 1].p) / v[s].pdf_fwd
        };
        let joined = light * (tau * g) * eye;
        let slack = lift_slack(v, 0..n) + emission_slack(scene, &v[0], v[1].p);
        check_rgb(s, "contribution", f / p, joined, slack)
    }
}

/// Checks a path's cached edge factors (G V and tau per edge x_i x_{i+1}, what MLT's chains
/// keep and reuse) against `geometry_term_exact` evaluated on the vertices: MLT's f uses the
/// exact transmittance in every medium, so both factors must match to the bit.
pub fn verify_edges(scene: &Scene, path: &Path, edges: &[(f32, Rgb)]) -> Verdict {
    let v = &path.vertices;
    for (i, &(g, tau)) in edges.iter().enumerate().take(v.len().saturating_sub(1)) {
        let (g2, tau2) = geometry_term_exact(scene, &v[i], &v[i + 1]);
        check(i, "edge G", g as f64, g2 as f64)?;
        check_rgb(i, "edge tau", tau, tau2, 0.0)?;
    }
    Ok(())
}
