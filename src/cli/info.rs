//! `pathspace info SCENE`: validates a scene and prints what it contains, in the file's own
//! terms (coefficients, albedos, light powers), so a scene can be checked by reading.
//! Book: "Scenes and geometry".

use clap::Args;
use glam::Vec3;
use std::path::PathBuf;

use crate::bsdf::Bsdf;
use crate::geometry::Primitive;
use crate::medium::Medium;
use crate::scene::file::escape_controls as esc;
use crate::scene::{AreaRadiance, Environment, Light, Scene};
use crate::spectrum::{round3 as round, show as v3};

#[derive(Args, Debug)]
pub struct InfoArgs {
    /// Scene file (TOML, or Mitsuba 3 XML by its `.xml` extension).
    pub scene: PathBuf,
    /// Write each grid medium's density lattice (read or baked from a procedural field) to
    /// DIR/NAME.vol, boxed by the medium's box (for the peers' converters, benches/peers).
    #[arg(long, value_name = "DIR")]
    pub write_grids: Option<PathBuf>,
}

/// A point or direction, always as a triple.
fn p3(v: Vec3) -> String {
    format!("[{}, {}, {}]", round(v.x), round(v.y), round(v.z))
}

fn bsdf(b: &Option<Bsdf>) -> String {
    let sides = match b {
        Some(b) if b.black_behind(Vec3::NEG_Z, Vec3::Z) => ", one-sided",
        _ => "",
    };
    let model = match b {
        None => "black (emission only)".into(),
        Some(b) => b.describe(),
    };
    format!("{model}{sides}")
}

fn medium(m: &Medium) -> String {
    m.describe()
}

/// The media that glow (L_e,V0 of eq. 1) and the power next-event estimation samples them by.
fn emitting_media(scene: &Scene) {
    for (m, (n, med)) in scene.medium_names.iter().zip(&scene.media).enumerate() {
        if !med.emits() {
            continue;
        }
        let how = match scene.emitters.of_medium(m as u32) {
            Some(e) => format!(
                "power {} (4 pi L_e,V0 over its box {} .. {}), sampled as a light with probability {:.4}",
                v3(e.power),
                p3(e.bounds.min),
                p3(e.bounds.max),
                scene.emitters.pmf(m as u32)
            ),
            None => "no bounded box: its emission is collected along free flights only".into(),
        };
        let per = if med.closed_form() {
            ""
        } else {
            " per unit density"
        };
        println!(
            "    {} emits: L_e,V0 {}{per}, {how}",
            esc(n),
            v3(med.emission_coefficient())
        );
    }
}

fn light(l: &Light) -> String {
    match l {
        Light::Area {
            shape,
            prims,
            area,
            radiance,
            ..
        } => format!(
            "area light on shapes[{shape}] ({} primitives), area {}, radiance {}",
            prims.len(),
            round(*area),
            match radiance {
                AreaRadiance::Constant(r) => v3(*r),
                AreaRadiance::Textured { texture, mean, .. } =>
                    format!("{} (mean {})", texture.describe(), v3(*mean)),
            }
        ),
        Light::Point {
            position,
            intensity,
        } => {
            format!(
                "point at {}, intensity {} W/sr",
                p3(*position),
                v3(*intensity)
            )
        }
        Light::Spot {
            position,
            frame,
            intensity,
            cos_total,
            cos_falloff,
        } => format!(
            "spot at {} towards {}, intensity {} W/sr, cone {} deg, falloff from {} deg",
            p3(*position),
            p3(frame.n),
            v3(*intensity),
            round(cos_total.acos().to_degrees()),
            round(cos_falloff.acos().to_degrees())
        ),
        Light::Directional {
            direction,
            irradiance,
        } => {
            format!(
                "directional, travelling along {}, irradiance {}",
                p3(*direction),
                v3(*irradiance)
            )
        }
        Light::Environment(Environment::Constant(r)) => {
            format!("environment, constant radiance {}", v3(*r))
        }
        Light::Environment(Environment::Gradient {
            zenith,
            horizon,
            nadir,
        }) => format!(
            "environment, gradient: zenith {}, horizon {}, nadir {}",
            v3(*zenith),
            v3(*horizon),
            v3(*nadir)
        ),
        Light::Environment(Environment::Map(map)) => {
            let (w, h) = map.size();
            format!(
                "environment, {w} x {h} map sampled {}, mean radiance {}",
                if map.is_uniform() {
                    "uniformly"
                } else {
                    "by luminance"
                },
                v3(map.mean_radiance())
            )
        }
    }
}

/// The name of a medium index (`vacuum` for none). Names from the file are printed with
/// their control characters escaped ([`esc`]), as in error messages.
fn medium_name(scene: &Scene, m: Option<u32>) -> String {
    m.map_or("vacuum".to_string(), |i| {
        esc(&scene.medium_names[i as usize]).into_owned()
    })
}

/// The estimated memory of a render with the file's `[render]` settings on all cores, and the
/// default `--max-memory` it is checked against.
fn memory_line(scene: &Scene, r: &crate::integrator::RenderSettings) -> String {
    use crate::render::memory;
    let kind = r.integrator;
    format!(
        "{} for a {} render on {} threads (default --max-memory {})",
        memory::estimate(scene, kind, r, rayon::current_num_threads()).describe(),
        kind.name(),
        rayon::current_num_threads(),
        memory::gib(memory::default_max_memory())
    )
}

pub fn run(args: InfoArgs) -> Result<(), super::CliError> {
    let (scene, r, source) = super::load_scene(Some(&args.scene))?;
    println!("{}: valid (hash {:016x})", esc(&source.name), source.hash());
    if let Some(o) = &source.origin {
        println!("  imported from {}, element by element:", o.format);
        for n in &o.notes {
            println!("    {}", esc(n));
        }
    }
    println!(
        "  render: integrator {}, {} spp, seed {}, max_depth {}, {} meter samples per pass",
        r.integrator.name(),
        r.spp,
        r.seed,
        r.max_depth
            .map_or("unlimited (Russian roulette)".to_string(), |d| d
                .to_string()),
        r.meter_samples
    );
    if scene.bounds.is_empty() {
        println!("  bounds: empty (no geometry)");
    } else {
        println!(
            "  bounds: {} to {}",
            p3(scene.bounds.min),
            p3(scene.bounds.max)
        );
    }
    match &scene.camera {
        Some(c) => println!(
            "  camera: {} at {} looking along {}, vertical fov {} deg, {}x{}{}, in {}",
            lens_note(c),
            p3(c.eye),
            p3(c.forward),
            round(2.0 * c.tan_half_y.atan().to_degrees()),
            c.width,
            c.height,
            filter_note(c.filter),
            medium_name(&scene, scene.camera_medium)
        ),
        None => println!("  camera: none"),
    }
    if scene.hide_emitters {
        println!("  hide_emitters: paths with no scattering vertex between camera and emitter are not measured");
    }
    println!(
        "  shapes: {} ({} primitives, BVH of {} nodes)",
        scene.shapes.len(),
        scene.prims.len(),
        scene.bvh.node_count()
    );
    if scene.hidden_faces > 0 {
        println!(
            "  {} null face(s) lie on walls that transmit nothing: no ray can cross them, so the BVH leaves them out",
            scene.hidden_faces
        );
    }
    for s in &scene.shapes {
        let emits = s
            .light
            .map_or(String::new(), |l| format!(", emits (lights[{l}])"));
        let iface = if s.interface {
            format!(
                ", interior {}, exterior {}",
                medium_name(&scene, s.interior),
                medium_name(&scene, s.exterior)
            )
        } else {
            String::new()
        };
        let texture = s.texture.as_ref().map_or(String::new(), |t| {
            let part = |what: &str, t: &Option<std::sync::Arc<crate::texture::Texture>>| {
                t.as_ref()
                    .map(|t| format!(" ({what} textured: {}; its mean shown)", t.describe()))
                    .unwrap_or_default()
            };
            format!(
                "{}{}{}{}",
                part("reflectance", &t.reflectance),
                part("alpha", &t.alpha),
                part("specular", &t.specular),
                part("transmittance", &t.transmittance)
            )
        });
        println!(
            "    {}: {}{}{}{}",
            s.label,
            bsdf(&s.bsdf),
            texture,
            emits,
            iface
        );
    }
    println!("  media: {}", scene.media.len());
    for (n, m) in scene.medium_names.iter().zip(&scene.media) {
        println!("    {}: {}", esc(n), medium(m));
    }
    emitting_media(&scene);
    println!(
        "  lights: {} (selected in proportion to power; the path tracer's next-event estimation picks by the light tree unless light_selection = \"power\")",
        scene.lights.len()
    );
    for (i, l) in scene.lights.iter().enumerate() {
        println!(
            "    [{i}] {}, power {}, selection probability {:.4}",
            light(l),
            round(l.power(scene.radius)),
            scene.light_pmf(i as u32)
        );
    }
    println!("  memory: {}", memory_line(&scene, &r));
    println!("  sensors: {}", scene.sensors.len());
    for s in &scene.sensors {
        let q = &s.quad;
        println!(
            "    {}: irradiance meter, centre {}, area {}, normal {}, in {}",
            esc(&s.name),
            p3(q.origin + 0.5 * (q.u + q.v)),
            round(Primitive::Quad(*q).area()),
            p3(s.normal()),
            medium_name(&scene, s.medium)
        );
    }
    match &args.write_grids {
        Some(dir) => write_grids(&scene, dir),
        None => Ok(()),
    }
}

/// `--write-grids DIR`: every grid medium's lattice as DIR/NAME.vol over its box.
fn write_grids(scene: &Scene, dir: &std::path::Path) -> Result<(), super::CliError> {
    use crate::medium::{grid::encode_vol, Density};
    let io = |p: &std::path::Path, e: std::io::Error| {
        super::CliError::Usage(format!("--write-grids: {}: {e}", p.display()))
    };
    std::fs::create_dir_all(dir).map_err(|e| io(dir, e))?;
    for (name, m) in scene.medium_names.iter().zip(&scene.media) {
        if let Medium::Heterogeneous(h) = m {
            if let Density::Grid(g) = &h.density {
                let plain = |c: char| c.is_ascii_alphanumeric() || "-_".contains(c);
                if !name.chars().all(plain) {
                    return Err(super::CliError::Usage(format!("--write-grids: the medium name `{}` is not a plain file name (letters, digits, - and _)", esc(name))));
                }
                let path = dir.join(format!("{name}.vol"));
                std::fs::write(&path, encode_vol(g, h.bounds.min, h.bounds.max))
                    .map_err(|e| io(&path, e))?;
                println!("  wrote {}: {} grid of {}", path.display(), esc(name), {
                    let [x, y, z] = g.res;
                    format!("{x}x{y}x{z}")
                });
            }
        }
    }
    Ok(())
}

/// The camera's kind: a pinhole, or a thin lens with its radius and focus distance.
fn lens_note(c: &crate::scene::camera::Camera) -> String {
    if c.lens_radius > 0.0 {
        format!(
            "thin lens of radius {} focused at {}",
            round(c.lens_radius),
            round(c.focus_distance)
        )
    } else {
        "pinhole".to_string()
    }
}

/// The camera's reconstruction filter as `info` names it (nothing for the box, the default).
fn filter_note(f: crate::film::PixelFilter) -> String {
    use crate::film::PixelFilter;
    match f {
        PixelFilter::Box => String::new(),
        PixelFilter::Tent { radius } => format!(", tent filter (radius {radius})"),
        PixelFilter::Gaussian { stddev } => format!(", gaussian filter (stddev {stddev})"),
    }
}
