//! The measurement contribution function (Pauly, Kollig, Keller 2000, eq. 6):
//! f_j(x) = L_e(x_0 -> x_1) G(x_0 <-> x_1) tau(x_0 <-> x_1)
//!          prod_{i=1}^{k-1} f-hat(x_{i-1} -> x_i -> x_{i+1}) G(x_i <-> x_{i+1}) tau(x_i <-> x_{i+1})
//!          W_e^(j)(x_{k-1} -> x_k),
//! with f-hat = f_s on surfaces and sigma_s f_p in the medium. It is evaluated for any explicit
//! path, independently of how the path was sampled: BDPT and MLT rest on that.

use super::geometry_term::geometry_term;
use super::{Path, VertexKind};
use crate::math::Sampler;
use crate::scene::Scene;
use crate::spectrum::Rgb;

/// f_j of eq. (6) for the pixel (or meter) the sensor vertex x_k stands for; zero when any
/// factor vanishes. Singular scattering (mirror, glass) has no finite value and gives zero here:
/// paths through such vertices are weighted by their samplers instead.
// ANCHOR: measurement_contribution
pub fn measurement_contribution(scene: &Scene, path: &Path, sampler: &mut Sampler) -> Rgb {
    let v = &path.vertices;
    let k = path.length();
    if k == 0 || !v[k].is_sensor() {
        return Rgb::ZERO;
    }
    let mut f = match v[0].kind {
        VertexKind::Light { .. } => v[0].emitted(scene, v[1].p),
        // a volume vertex x0: the volume emittance L_e,V0 (isotropic)
        VertexKind::Medium { medium } => match scene.media[medium as usize].emission(v[0].p) {
            e if e == Rgb::ZERO => return e,
            e => e,
        },
        _ => return Rgb::ZERO,
    };
    for i in 0..k {
        let (g, tau) = geometry_term(scene, &v[i], &v[i + 1], sampler);
        f *= tau * g;
        if i + 1 < k {
            f *= v[i + 1].f_hat(scene, v[i].p, v[i + 2].p);
        }
        if f == Rgb::ZERO {
            return f;
        }
    }
    f * v[k].importance(scene, v[k - 1].p)
}
// ANCHOR_END: measurement_contribution
