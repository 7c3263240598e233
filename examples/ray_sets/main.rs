//! Ray sets for comparing pathspace's BVH with Embree on the same rays (`benches/embree/`,
//! book: "Measuring a renderer: the tools").
//!
//!     cargo run --release --example ray_sets -- write DIR [--res N]
//!     cargo run --release --example ray_sets -- trace DIR [--passes P] [SCENE...]
//!
//! `write` writes, for the fog box, the 100 rooms and a displaced sphere of about a million
//! triangles, the scene's opaque surfaces as triangles (quads split in two; null boundaries
//! left out: they bound media and block no shadow ray) and three ray sets in the format of
//! `format.rs`: camera rays (N x N pixel centres, closest hit), diffuse bounces (from each
//! camera hit, cosine-distributed about the normal on the side the camera sees, closest hit)
//! and shadow rays (from each camera hit to a point on a light, any hit). `trace` builds
//! pathspace's BVH over the triangles and traces every set on one thread, printing per set
//! `RESULT pathspace SCENE SET KIND 1 RAYS CPU_SECONDS HITS SUM_T MRAYS_PER_S` (after each tree's
//! build time, memory and SAH cost in Embree's units, `Bvh::sah_cost`); where the
//! processor has AVX2 the four- and eight-wide trees follow as `pathspace4` and `pathspace8`.

mod format;

use std::path::{Path, PathBuf};
use std::time::Instant;

use glam::{Vec2, Vec3};
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64Mcg;

use format::{Kind, RaySet};
use pathspace::geometry::bvh::Width;
use pathspace::geometry::{offset_origin, shadow_distance, Bvh, Primitive, Ray};
use pathspace::math::frame::Frame;
use pathspace::math::warp;
use pathspace::scene::camera::Camera;
use pathspace::scene::{Scene, SceneSource};

/// The scenes in the order they are written and traced.
const SCENES: [&str; 3] = ["fog-box", "rooms100", "sphere1m"];
/// The ray sets of each scene.
const SETS: [&str; 3] = ["camera", "bounce", "shadow"];

type Result<T> = std::result::Result<T, String>;

fn main() {
    if let Err(e) = run(std::env::args().skip(1).collect()) {
        eprintln!("ray_sets: {e}");
        std::process::exit(1);
    }
}

fn run(args: Vec<String>) -> Result<()> {
    let usage = "usage: ray_sets write DIR [--res N] | trace DIR [--passes P] [SCENE...]";
    let (cmd, dir) = match args.as_slice() {
        [c, d, ..] => (c.as_str(), PathBuf::from(d)),
        _ => return Err(usage.into()),
    };
    let mut res = 512u32;
    let mut passes = 3u32;
    let mut scenes = Vec::new();
    let mut rest = args[2..].iter();
    while let Some(a) = rest.next() {
        let mut value = || rest.next().and_then(|v| v.parse().ok()).ok_or(usage);
        match a.as_str() {
            "--res" => res = value()?,
            "--passes" => passes = value()?,
            s => scenes.push(s.to_string()),
        }
    }
    if scenes.is_empty() {
        scenes = SCENES.map(String::from).to_vec();
    }
    match cmd {
        "write" => write_all(&dir, res),
        "trace" => scenes
            .iter()
            .try_for_each(|s| trace_scene(&dir, s, passes.max(1) as usize)),
        _ => Err(usage.into()),
    }
}

/// What a scene contributes: its triangles, camera and a sampler of points on its lights.
struct Source {
    tris: Vec<[Vec3; 3]>,
    camera: Camera,
    light_point: Box<dyn Fn(&mut Pcg64Mcg) -> Vec3>,
}

fn write_all(dir: &Path, res: u32) -> Result<()> {
    std::fs::create_dir_all(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    for name in SCENES {
        let source = match name {
            "fog-box" => {
                let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/fog-box.toml");
                let src = SceneSource::read(&path).map_err(|e| e.to_string())?;
                from_scene(Scene::load(&src).map_err(|e| e.to_string())?, res)?
            }
            "rooms100" => {
                let text = pathspace::cli::rooms::rooms_scene(10);
                let src = SceneSource::embedded("rooms100", &text);
                from_scene(Scene::load(&src).map_err(|e| e.to_string())?, res)?
            }
            _ => displaced_sphere(res),
        };
        let start = Instant::now();
        let counts = write_scene(dir, name, &source)?;
        println!(
            "{name}: {} triangles, {counts:?} rays ({:.1} s)",
            source.tris.len(),
            start.elapsed().as_secs_f64()
        );
    }
    Ok(())
}

/// A loaded scene's opaque surfaces as triangles, its camera at `res` x `res`, its lights.
fn from_scene(scene: Scene, res: u32) -> Result<Source> {
    let mut tris = Vec::new();
    for (prim, _) in scene.prims.iter().zip(&scene.prim_opaque).filter(|p| *p.1) {
        match prim {
            Primitive::Quad(q) => {
                let [a, b, c, d] = q.corners();
                tris.extend([[a, b, c], [a, c, d]]);
            }
            Primitive::Triangle(t) => tris.push([t.p0, t.p1, t.p2]),
            _ => return Err(format!("{}: only quads and triangles", scene.source_name)),
        }
    }
    let camera = scene.camera.as_ref().ok_or("a camera")?;
    let camera = camera.with_resolution(res, res).ok_or("resolution")?;
    let (prims, lights) = (scene.prims, scene.lights);
    let light_point = Box::new(move |r: &mut Pcg64Mcg| loop {
        let light = &lights[r.random_range(0..lights.len())];
        let u = Vec2::new(r.random(), r.random());
        if let Some(at) = light.sample_point(&prims, u, r.random()) {
            return at.p;
        }
    });
    Ok(Source {
        tris,
        camera,
        light_point,
    })
}

/// A unit sphere of about a million triangles (1000 x 500 longitude-latitude cells, the pole
/// cells' degenerate halves left out) displaced by sines along its normal, seen from z = 3.5 and
/// lit by a 1 x 1 square at y = 3 (no geometry: shadow rays end there).
fn displaced_sphere(res: u32) -> Source {
    let (nu, nv) = (1000usize, 500usize);
    let point = |i: usize, j: usize| {
        let phi = std::f32::consts::TAU * (i % nu) as f32 / nu as f32;
        let theta = std::f32::consts::PI * j as f32 / nv as f32;
        let n = Vec3::new(
            theta.sin() * phi.cos(),
            theta.cos(),
            theta.sin() * phi.sin(),
        );
        let r = 1.0
            + 0.08 * (7.0 * phi).sin() * (9.0 * theta).sin()
            + 0.02 * (53.0 * phi).sin() * (41.0 * theta).cos();
        n * r
    };
    let mut tris = Vec::with_capacity(2 * nu * nv);
    for j in 0..nv {
        for i in 0..nu {
            let (a, b) = (point(i, j), point(i + 1, j));
            let (c, d) = (point(i + 1, j + 1), point(i, j + 1));
            for t in [[a, c, b], [a, d, c]] {
                if pathspace::geometry::shape::Triangle::new(t[0], t[1], t[2]).is_some() {
                    tris.push(t);
                }
            }
        }
    }
    let camera = Camera::new(
        Vec3::new(0.0, 0.0, 3.5),
        Vec3::ZERO,
        Vec3::Y,
        40.0,
        res,
        res,
    )
    .expect("a valid camera");
    let light_point = Box::new(|r: &mut Pcg64Mcg| {
        Vec3::new(r.random_range(-0.5..0.5), 3.0, r.random_range(-0.5..0.5))
    });
    Source {
        tris,
        camera,
        light_point,
    }
}

/// The scene's triangles and its three ray sets; returns the sets' sizes.
fn write_scene(dir: &Path, name: &str, s: &Source) -> Result<[usize; 3]> {
    let io = |e: std::io::Error| e.to_string();
    format::write_triangles(&dir.join(format!("{name}.tri")), &s.tris).map_err(io)?;
    let prims = format::primitives(&s.tris)?;
    let opaque = vec![true; prims.len()];
    let bvh = Bvh::build(&prims);
    let mut r = Pcg64Mcg::seed_from_u64(41);
    let (w, h) = (s.camera.width, s.camera.height);
    let mut sets = [Kind::Closest, Kind::Closest, Kind::Any].map(|kind| RaySet {
        kind,
        rays: Vec::new(),
    });
    for y in 0..h {
        for x in 0..w {
            let ray = s
                .camera
                .generate_ray(Vec2::new(x as f32 + 0.5, y as f32 + 0.5));
            sets[0].rays.push((ray, f32::INFINITY));
            let Some(hit) = bvh.intersect(&prims, &opaque, &ray, f32::INFINITY) else {
                continue;
            };
            // the side of the surface the camera sees
            let n = if hit.ng.dot(ray.d) < 0.0 {
                hit.ng
            } else {
                -hit.ng
            };
            let local = warp::cosine_hemisphere(Vec2::new(r.random(), r.random()));
            let d = Frame::from_normal(n).to_world(local).normalize();
            sets[1]
                .rays
                .push((Ray::new(offset_origin(hit.p, hit.ng, d), d), f32::INFINITY));
            let q = (s.light_point)(&mut r);
            let o = offset_origin(hit.p, hit.ng, q - hit.p);
            if let Some(d) = (q - o).try_normalize() {
                sets[2].rays.push((Ray::new(o, d), shadow_distance(o, q)));
            }
        }
    }
    for (set, label) in sets.iter().zip(SETS) {
        let path = dir.join(format!("{name}.{label}.rays"));
        format::write_rays(&path, set).map_err(io)?;
    }
    Ok(sets.map(|s| s.rays.len()))
}

/// Thread CPU seconds (the machine may be shared: time the thread, not the wall).
fn cpu_seconds() -> f64 {
    let mut ts = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: clock_gettime writes the timespec it is given
    unsafe { libc::clock_gettime(libc::CLOCK_THREAD_CPUTIME_ID, &mut ts) };
    ts.tv_sec as f64 + ts.tv_nsec as f64 * 1e-9
}

fn trace_scene(dir: &Path, name: &str, passes: usize) -> Result<()> {
    let io = |e: std::io::Error| e.to_string();
    let tris = format::read_triangles(&dir.join(format!("{name}.tri"))).map_err(io)?;
    let prims = format::primitives(&tris)?;
    let opaque = vec![true; prims.len()];
    // the renderer's tree (`Bvh::build`: eight-wide nodes for large trees where the processor
    // has AVX2) and, where it has, the four-wide and eight-wide trees whatever the size
    let mut sides = vec![("pathspace", None)];
    if Width::native() != Width::Four {
        sides.push(("pathspace4", Some(Width::Four)));
        sides.push(("pathspace8", Some(Width::Eight)));
    }
    let mut trees = Vec::new();
    for &(side, width) in &sides {
        let start = cpu_seconds();
        let bvh = match width {
            Some(w) => Bvh::build_with(&prims, |_| true, w),
            None => Bvh::build(&prims),
        };
        println!(
            "BUILD {side} {name} {} {:.4}",
            prims.len(),
            cpu_seconds() - start
        );
        // what the hierarchy holds, and what the binary tree of its build held (dropped)
        println!(
            "MEMORY {side} {name} {} bytes; binary tree {} nodes, {} references",
            bvh.memory_bytes(),
            bvh.node_count(),
            bvh.reference_count()
        );
        // in Embree's units, to set beside `embree_trace DIR --verbose SCENE`
        let sah = bvh.sah_cost();
        println!(
            "SAH {side} {name} {:.3}: nodes {:.3}, leaves {:.3} ({} leaves, {} blocks)",
            sah.nodes + sah.leaves,
            sah.nodes,
            sah.leaves,
            sah.leaf_count,
            sah.block_count
        );
        trees.push((side, bvh));
    }
    for label in SETS {
        let set = format::read_rays(&dir.join(format!("{name}.{label}.rays"))).map_err(io)?;
        for (side, bvh) in &trees {
            let start = cpu_seconds();
            let mut sum = format::Checksum::default();
            for _ in 0..passes {
                // black boxes on both ends: every pass is traced, none hoisted or dropped
                sum = std::hint::black_box(format::trace(
                    bvh,
                    &prims,
                    &opaque,
                    std::hint::black_box(&set),
                ));
            }
            let seconds = cpu_seconds() - start;
            let rays = set.rays.len() * passes;
            println!(
                "RESULT {side} {name} {label} {} 1 {rays} {seconds:.6} {} {:.6} {:.3}",
                set.kind.name(),
                sum.hits,
                sum.sum_t,
                rays as f64 / seconds * 1e-6
            );
        }
    }
    Ok(())
}
