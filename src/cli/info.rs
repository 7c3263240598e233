//! `pathspace info SCENE`: validates a scene and prints what it contains.

use clap::Args;
use std::path::PathBuf;

#[derive(Args, Debug)]
pub struct InfoArgs {
    /// Scene file (TOML).
    pub scene: PathBuf,
}

pub fn run(args: InfoArgs) -> Result<(), String> {
    let (scene, source) = super::load_scene(Some(&args.scene))?;
    println!("{}: valid (hash {:016x})", source.name, source.hash());
    println!(
        "  render: integrator {}, {} spp, seed {}, max_depth {}",
        scene.render.integrator,
        scene.render.spp,
        scene.render.seed,
        scene
            .render
            .max_depth
            .map_or("unlimited".to_string(), |d| d.to_string())
    );
    match &scene.camera {
        Some(c) => println!(
            "  camera: pinhole at {:?}, {}x{}, in {}",
            c.eye.to_array(),
            c.width,
            c.height,
            scene
                .camera_medium
                .map_or("vacuum".to_string(), |m| scene.medium_names[m as usize]
                    .clone())
        ),
        None => println!("  camera: none"),
    }
    println!(
        "  shapes: {} ({} primitives, BVH of {} nodes)",
        scene.shapes.len(),
        scene.prims.len(),
        scene.bvh.node_count()
    );
    for s in &scene.shapes {
        let mat = match &s.bsdf {
            Some(b) => format!("{b:?}"),
            None => "black emitter".into(),
        };
        let med = |m: Option<u32>| {
            m.map_or("vacuum".to_string(), |i| {
                scene.medium_names[i as usize].clone()
            })
        };
        let iface = if s.interface {
            format!(
                ", interior {}, exterior {}",
                med(s.interior),
                med(s.exterior)
            )
        } else {
            String::new()
        };
        println!(
            "    {}: {}{}{}",
            s.label,
            mat,
            if s.light.is_some() { ", emits" } else { "" },
            iface
        );
    }
    println!("  media: {}", scene.media.len());
    for (n, m) in scene.medium_names.iter().zip(&scene.media) {
        println!("    {n}: {m:?}");
    }
    println!("  lights: {}", scene.lights.len());
    for (i, l) in scene.lights.iter().enumerate() {
        let kind = match l {
            crate::scene::Light::Area {
                shape,
                area,
                radiance,
                ..
            } => format!(
                "area (shape {shape}, area {area:.4}, radiance {:?})",
                radiance.to_array()
            ),
            crate::scene::Light::Point { .. } => "point".into(),
            crate::scene::Light::Spot { .. } => "spot".into(),
            crate::scene::Light::Directional {
                direction,
                irradiance,
            } => format!(
                "directional {:?}, irradiance {:?}",
                direction.to_array(),
                irradiance.to_array()
            ),
            crate::scene::Light::Environment(e) => format!("environment {e:?}"),
        };
        println!(
            "    [{i}] {kind}, selection probability {:.4}",
            scene.light_pmf(i as u32)
        );
    }
    println!("  sensors: {}", scene.sensors.len());
    for s in &scene.sensors {
        println!(
            "    {}: irradiance meter, area {:.4}, normal {:?}",
            s.name,
            crate::geometry::Primitive::Quad(s.quad).area(),
            s.normal().to_array()
        );
    }
    Ok(())
}
