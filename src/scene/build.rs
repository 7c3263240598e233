//! From a parsed scene file to a [`Scene`]: semantic validation (physics and references) and
//! construction of primitives, lights and the BVH. One file per part of the scene file:
//! `materials` (eq. 2's BSDFs), `media` (Table 1), `shapes` (primitives and area lights),
//! `lights` (delta and infinite lights, selection by power), `sensors` (camera and meters);
//! `values` checks the numbers they share. Every error names its line and key.

mod hidden;
mod lights;
mod materials;
mod media;
mod normals;
mod ply;
mod sensors;
mod serialized;
mod shapes;
mod textures;
mod values;

use glam::Vec3;

pub use media::{
    DEFAULT_FREQUENCY, DEFAULT_OCTAVES, DEFAULT_RELATIVE_STEP, MAX_BAKE_RESOLUTION, MAX_OCTAVES,
};
pub use shapes::MAX_OBJ_BYTES;

use super::file::{self, path};
use super::{Scene, SceneError, SceneSource};
use crate::geometry::{Aabb, Bvh};
use crate::medium::Medium;

/// Builds the scene described by `src`.
pub fn build(src: &SceneSource) -> Result<Scene, SceneError> {
    let desc = file::parse(&src.text, &src.name).map_err(|e| src.relocate(e))?;
    build_parsed(src, &desc)
}

/// Builds the scene `desc` already parsed from `src` (whose text names the lines of errors):
/// a program that changes a value of the description (a binding's parameter update) builds the
/// changed copy without parsing the file again.
pub fn build_parsed(src: &SceneSource, desc: &file::SceneFile) -> Result<Scene, SceneError> {
    let materials = materials::materials(src, desc)?;
    let media = media::Media::build(src, desc)?;
    let shapes::Surfaces {
        prims,
        prim_shape,
        shapes,
        lights,
    } = shapes::shapes(src, desc, &materials, &media)?;
    let media::Media {
        media,
        names: medium_names,
        ..
    } = media;

    let bounds = prims.iter().fold(Aabb::EMPTY, |b, p| b.union(p.bounds()));
    let (center, radius) = if bounds.is_empty() {
        (Vec3::ZERO, 1.0)
    } else {
        (
            bounds.centroid(),
            (0.5 * bounds.extent().length()).max(1e-3),
        )
    };

    // delta and infinite lights
    let lights::Lights {
        lights,
        environment,
        light_distr,
    } = lights::build(src, desc, lights, radius)?;

    let prim_opaque: Vec<bool> = prim_shape
        .iter()
        .map(|&s| !shapes[s as usize].is_null())
        .collect();
    let has_null = prim_opaque.iter().any(|o| !o);
    let crossable = hidden::crossable(&prims, &prim_shape, &shapes, true);
    let bvh = Bvh::build_over(&prims, |i| crossable[i]);
    let boundary_bvh = Bvh::build_over(&prims, |i| crossable[i] && !prim_opaque[i]);
    let emitter = |i: usize| shapes[prim_shape[i] as usize].light.is_some();
    let camera_bvh = (desc.hide_emitters && (0..prims.len()).any(emitter)).then(|| {
        // the null faces hidden by walls other than the emitters the camera sees through
        let seen = hidden::crossable(&prims, &prim_shape, &shapes, false);
        Bvh::build_over(&prims, |i| !emitter(i) && seen[i])
    });
    let closed_form_tau = media.iter().all(Medium::closed_form);
    let hidden_faces = crossable.iter().filter(|&&c| !c).count();

    let mut scene = Scene {
        prims,
        prim_shape,
        prim_opaque,
        bvh,
        boundary_bvh,
        camera_bvh,
        closed_form_tau,
        shapes,
        media,
        medium_names,
        lights,
        light_distr,
        environment,
        light_media: Vec::new(),
        light_prim_media: Vec::new(),
        camera: None,
        camera_medium: None,
        emitters: Default::default(),
        sensors: Vec::new(),
        bounds,
        center,
        radius,
        has_null,
        hidden_faces,
        hide_emitters: desc.hide_emitters,
        hash: src.hash(),
        source_name: src.name.clone(),
    };

    scene.light_media = lights::media_around(&scene);
    scene.light_prim_media = lights::media_per_primitive(src, &scene)?;
    if scene.media.iter().any(Medium::emits) {
        scene.emitters = super::emitters::VolumeEmitters::build(&scene);
    }
    sensors::camera(src, desc, &mut scene)?;
    camera_medium_as_declared(src, &scene)?;
    sensors::meters(src, desc, &mut scene)?;
    if scene.camera.is_none() && scene.sensors.is_empty() {
        return Err(src.error(&path("camera"), "the scene has neither a camera nor a sensor, so nothing would be measured: add a [camera] table or a [[sensors]] entry"));
    }
    hide_emitters_supported(src, &scene)?;
    Ok(scene)
}

/// `hide_emitters` removes the paths whose sensor and emitter are adjacent; it is defined for
/// the camera alone (Mitsuba's is), and emitting media are left out for now: the path tracer
/// collects their emission along the camera's first ray apart from its vertices. Emitter
/// shapes are transparent to the camera's first rays, so none may bound a medium.
fn hide_emitters_supported(src: &SceneSource, scene: &Scene) -> Result<(), SceneError> {
    if !scene.hide_emitters {
        return Ok(());
    }
    let why = if !scene.sensors.is_empty() {
        "hide_emitters with [[sensors]] is not supported: it hides emitters from the camera only"
    } else if !scene.emitters.is_empty() {
        "hide_emitters with an emitting medium is not supported"
    } else if scene
        .shapes
        .iter()
        .any(|s| s.light.is_some() && s.interface)
    {
        "hide_emitters with an area light on a medium boundary is not supported: the camera sees through hidden emitters, which would leave the medium it is in unknown"
    } else {
        return Ok(());
    };
    Err(src.error(&path("hide_emitters"), why))
}

/// A translated scene declares the camera's medium (Mitsuba's sensor names it, or is in
/// vacuum); pathspace finds it from the eye, so the two must agree, or the images would differ.
fn camera_medium_as_declared(src: &SceneSource, scene: &Scene) -> Result<(), SceneError> {
    let Some(origin) = &src.origin else {
        return Ok(());
    };
    if scene.camera.is_none() {
        return Ok(());
    }
    let found = scene
        .camera_medium
        .map(|m| scene.medium_names[m as usize].as_str());
    if found == origin.camera_medium.as_deref() {
        return Ok(());
    }
    let name = |m: Option<&str>| m.map_or("vacuum".to_string(), |m| format!("medium `{m}`"));
    Err(src.error(
        &path("camera"),
        format!(
            "the file places the camera in {}, but its eye is in {}",
            name(origin.camera_medium.as_deref()),
            name(found)
        ),
    ))
}
