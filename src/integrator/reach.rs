//! Which light paths an integrator cannot sample at all, read off the scene before rendering.
//!
//! Every estimator of the path integral (Pauly, Kollig, Keller 2000, eq. 7) samples paths with
//! some local techniques; a path none of its techniques can produce is missing from its image,
//! with no noise to show it. Two classes matter here (Veach 1997 sec. 8.2, in his heckbert
//! notation with M for a medium vertex):
//!
//! * **Dirac lights behind specular surfaces**: the path tracer (and SMC, which shares its
//!   surface vertices) reaches light only by next-event estimation from a non-specular vertex
//!   or by hitting an emitter by chance. A point, spot or directional light cannot be hit, and a
//!   shadow ray cannot pass a mirror or glass, so paths `L S+ (D|M) ... E` from a Dirac light
//!   are lost (the volume caustic of a spot light focused by glass).
//! * **Specular surfaces seen by the sensor**: light tracing connects the end of a light
//!   subpath to the sensor, which needs a non-specular end vertex, so paths `... (D|M) S+ E`
//!   (whatever the sensor sees in a mirror or through glass) are lost.
//!
//! BDPT and MLT reach both classes (light tracing's connections and the path tracer's hits are
//! among their strategies). The tests are conservative: a specular shape counts as lit or seen
//! unless its bounding box lies wholly outside a spot light's cone or the sensor's view, so a
//! warning can be given where occlusion would hide the problem, never withheld where it occurs.
//! Book: "Measuring a renderer", section "The agreement matrix".

use glam::Vec3;

use super::IntegratorKind;
use crate::geometry::Aabb;
use crate::scene::{Light, Scene};

/// The class of light paths an integrator's techniques cannot sample, declared by its
/// [`Facts::unreachable`](super::Facts::unreachable).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Unreachable {
    /// Every path is reachable (BDPT, MLT).
    Nothing,
    /// `L S+ (D|M) ... E` from a Dirac light: next-event estimation cannot pass a specular
    /// surface (the path tracer, SMC).
    DiracLightsBehindSpecular,
    /// `... (D|M) S+ E`: a light subpath joins the sensor only from a non-specular vertex
    /// (light tracing).
    SpecularSeenBySensor,
}

// ANCHOR: unreachable
/// The warning for `kind` on `scene`, if the integrator cannot reach some of its light paths.
pub fn unreachable_paths(scene: &Scene, kind: IntegratorKind) -> Option<String> {
    let specular = specular_shapes(scene);
    if specular.is_empty() {
        return None;
    }
    match kind.facts().unreachable() {
        Unreachable::DiracLightsBehindSpecular => {
            let lit: Vec<&str> = specular
                .iter()
                .filter(|(_, b)| {
                    scene
                        .lights
                        .iter()
                        .any(|l| l.is_delta() && delta_light_reaches(l, b))
                })
                .map(|(label, _)| label.as_str())
                .collect();
            (!lit.is_empty()).then(|| {
                format!(
                    "{}: light from point, spot or directional lights that reaches {} (mirror or \
                     glass) cannot be sampled: next-event estimation cannot pass a specular \
                     surface and a Dirac light cannot be hit; those paths are missing from the \
                     image (bdpt, light or mlt reach them)",
                    kind.name(),
                    lit.join(", ")
                )
            })
        }
        Unreachable::SpecularSeenBySensor => {
            let seen: Vec<&str> = specular
                .iter()
                .filter(|(_, b)| sensor_sees(scene, b))
                .map(|(label, _)| label.as_str())
                .collect();
            (!seen.is_empty()).then(|| {
                format!(
                    "{}: what the sensors see in or through {} (mirror or glass) cannot be \
                     sampled: a light subpath can only be connected to the sensor from a \
                     non-specular vertex; those paths are missing (bdpt, path or mlt reach them)",
                    kind.name(),
                    seen.join(", ")
                )
            })
        }
        Unreachable::Nothing => None,
    }
}
// ANCHOR_END: unreachable

/// Labels and bounds of the shapes with a specular (mirror or dielectric) BSDF.
fn specular_shapes(scene: &Scene) -> Vec<(String, Aabb)> {
    let mut bounds: Vec<Option<Aabb>> = vec![None; scene.shapes.len()];
    for (prim, &shape) in scene.prims.iter().zip(&scene.prim_shape) {
        let b = bounds[shape as usize].get_or_insert(Aabb::EMPTY);
        *b = b.union(prim.bounds());
    }
    scene
        .shapes
        .iter()
        .zip(bounds)
        .filter(|(s, _)| {
            s.bsdf
                .as_ref()
                .is_some_and(|b| b.has_dirac_lobe() && !s.is_null())
        })
        .filter_map(|(s, b)| b.map(|b| (s.label.clone(), b)))
        .collect()
}

fn contains(b: &Aabb, p: Vec3) -> bool {
    p.cmpge(b.min).all() && p.cmple(b.max).all()
}

/// The eight corners of a box.
fn corners(b: &Aabb) -> [Vec3; 8] {
    let (lo, hi) = (b.min, b.max);
    std::array::from_fn(|i| {
        Vec3::new(
            if i & 1 == 0 { lo.x } else { hi.x },
            if i & 2 == 0 { lo.y } else { hi.y },
            if i & 4 == 0 { lo.z } else { hi.z },
        )
    })
}

/// True unless the box lies wholly on the negative side of one of the half-spaces
/// (n, d): n . x > d.
fn may_meet(b: &Aabb, planes: &[(Vec3, f32)]) -> bool {
    let c = corners(b);
    planes.iter().all(|(n, d)| c.iter().any(|x| n.dot(*x) > *d))
}

/// Whether a Dirac light may illuminate the box (a spot light: its cone's bounding planes).
fn delta_light_reaches(light: &Light, b: &Aabb) -> bool {
    match light {
        Light::Spot {
            position,
            frame,
            cos_total,
            ..
        } => {
            if *cos_total <= 0.0 || contains(b, *position) {
                return true; // a cone of a hemisphere or more, or the apex inside the box
            }
            // the cone's bounding pyramid: four planes through the apex
            let tan = (1.0 - cos_total * cos_total).max(0.0).sqrt() / cos_total;
            let planes: Vec<(Vec3, f32)> = [frame.s, -frame.s, frame.t, -frame.t]
                .into_iter()
                .map(|a| {
                    let n = frame.n * tan + a;
                    (n, n.dot(*position))
                })
                .collect();
            may_meet(b, &planes)
        }
        _ => true,
    }
}

/// Whether the camera or a meter may see the box.
fn sensor_sees(scene: &Scene, b: &Aabb) -> bool {
    if let Some(cam) = scene.camera.as_ref() {
        // a thin lens's rays cross beyond the focus plane: its view is no pinhole frustum
        if !cam.is_pinhole() || contains(b, cam.eye) {
            return true;
        }
        let f = cam.forward;
        let side = |axis: Vec3, tan: f32| [(f * tan - axis), (f * tan + axis)];
        let mut planes: Vec<(Vec3, f32)> = Vec::with_capacity(5);
        for n in side(cam.right, cam.tan_half_x)
            .into_iter()
            .chain(side(cam.up, cam.tan_half_y))
        {
            planes.push((n, n.dot(cam.eye)));
        }
        planes.push((f, f.dot(cam.eye)));
        if may_meet(b, &planes) {
            return true;
        }
    }
    scene.sensors.iter().any(|m| {
        let n = m.normal();
        may_meet(b, &[(n, n.dot(m.quad.origin))])
    })
}
