//! Oracles for the thin-lens camera (`scene::camera`): W_e's normalization over the lens and the
//! directions, rays that land where they were aimed, the pinhole limit bit for bit, and the
//! image of a point light in and out of focus, whose circle of confusion the thin-lens
//! geometry gives (Kolb, Mitchell, Hanrahan 1995): a point at depth d seen through a lens of
//! radius r focused at depth f images to a uniform disk of radius r |d - f| / (d f) on the
//! film at distance 1.

use crate::common;

use common::stats::Family;
use glam::{Vec2, Vec3};
use pathspace::integrator::{IntegratorKind, RenderSettings, Renderer, Setup};
use pathspace::scene::{Camera, SceneSource};

const RADIUS: f32 = 0.2;
const FOCUS: f32 = 2.0;

/// A 4 x 3 camera looking down -z through a lens of radius [`RADIUS`] focused at [`FOCUS`].
fn lens_camera() -> Camera {
    Camera::new(Vec3::ZERO, -Vec3::Z, Vec3::Y, 40.0, 4, 3)
        .and_then(|c| c.with_lens(RADIUS, FOCUS))
        .unwrap()
}

/// int_lens int_dirs W_e^(j)(p, w) cos(w, forward) dw dA = 1 for every pixel j: lens points
/// uniform on the disk, directions uniform on the sphere, each run's
/// estimate per pixel compared with 1.
#[test]
fn importance_integrates_to_one_per_pixel_over_lens_and_directions() {
    let cam = lens_camera();
    let npix = (cam.width * cam.height) as usize;
    const RUNS: u64 = 8;
    const N: u64 = 400_000;
    let mut runs = vec![Vec::new(); npix];
    for run in 0..RUNS {
        let mut s = common::sampler(0x1e05, run);
        let mut sum = vec![0.0f64; npix];
        for _ in 0..N {
            let p = cam.sample_lens(&mut s);
            let u = s.next_2d();
            let w = pathspace::math::warp::uniform_sphere(u);
            let Some(imp) = cam.importance(p, w) else {
                continue;
            };
            let px = (imp.raster.x as usize).min(cam.width as usize - 1);
            let py = (imp.raster.y as usize).min(cam.height as usize - 1);
            let cos = w.dot(cam.forward) as f64;
            // the lens disk's own area, not the camera's density: W_e must carry exactly 1 / (pi r^2)
            let lens_area = std::f64::consts::PI * (RADIUS as f64).powi(2);
            let pdf = 1.0 / (lens_area * 4.0 * std::f64::consts::PI);
            sum[py * cam.width as usize + px] += imp.we as f64 * cos / pdf;
        }
        for (r, v) in runs.iter_mut().zip(sum) {
            r.push(v / N as f64);
        }
    }
    let mut fam = Family::new("lens: W_e normalization");
    for (j, r) in runs.iter().enumerate() {
        fam.runs_are(&format!("pixel {j}"), r, 1.0);
    }
    fam.finish();
}

/// A ray sampled through a raster position from any lens point is seen by `importance` at
/// that raster position, with the film's density 1 / (A cos^3) from every lens point.
#[test]
fn rays_through_the_lens_land_on_their_raster_position() {
    let cam = lens_camera();
    let mut s = common::sampler(0x1e06, 0);
    for _ in 0..10_000 {
        let raster = s.next_2d() * Vec2::new(4.0, 3.0);
        let ray = cam.sample_ray(raster, &mut s);
        assert!((ray.o - cam.eye).length() <= RADIUS * (1.0 + 1e-6));
        assert!(
            ray.o.dot(cam.forward).abs() < 1e-6,
            "the lens point is on the lens"
        );
        let imp = cam.importance(ray.o, ray.d).expect("in view");
        assert!(
            (imp.raster - raster).length() < 1e-3,
            "{raster} lands at {}",
            imp.raster
        );
        // the focus plane's image of the film, uniform, seen from the lens point
        let cos = ray.d.dot(cam.forward);
        let expected = 1.0 / (cam.film_area() * cos * cos * cos);
        let rel = (imp.pdf_dir / expected - 1.0).abs();
        assert!(rel < 1e-5, "pdf_dir {} vs {expected}", imp.pdf_dir);
    }
}

/// Aperture 0 is the pinhole: the same rays, bit for bit, from no random numbers, the same W_e.
#[test]
fn zero_aperture_is_the_pinhole_bit_for_bit() {
    let pinhole = Camera::new(Vec3::new(0.1, 0.2, 3.0), Vec3::ZERO, Vec3::Y, 50.0, 7, 5).unwrap();
    let zero = pinhole.clone().with_lens(0.0, 2.5).unwrap();
    let (mut a, mut b) = (common::sampler(0x1e07, 0), common::sampler(0x1e07, 0));
    for _ in 0..1000 {
        let raster = a.next_2d() * Vec2::new(7.0, 5.0);
        let _ = b.next_2d();
        let (r0, r1) = (
            pinhole.generate_ray(raster),
            zero.sample_ray(raster, &mut b),
        );
        assert_eq!((r0.o, r0.d), (r1.o, r1.d));
        let (i0, i1) = (
            pinhole.importance(pinhole.eye, r0.d).unwrap(),
            zero.importance(zero.eye, r1.d).unwrap(),
        );
        assert_eq!(
            (i0.we, i0.pdf_dir, i0.raster),
            (i1.we, i1.pdf_dir, i1.raster)
        );
    }
    assert_eq!(
        a.next_f32(),
        b.next_f32(),
        "the pinhole draws no lens sample"
    );
}

/// A scene file with `aperture_radius = 0` renders the pinhole's image bit for bit, for every
/// integrator that renders through the shared camera code.
#[test]
fn zero_aperture_scene_renders_the_pinhole_image() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/agreement");
    let text = std::fs::read_to_string(dir.join("chromatic.toml")).unwrap();
    let zero = text.replace(
        "resolution = [8, 8]",
        "resolution = [8, 8]\naperture_radius = 0.0\nfocus_distance = 1.7",
    );
    assert_ne!(zero, text);
    let image = |text: &str, kind: IntegratorKind| {
        let source = SceneSource::embedded("chromatic.toml", text);
        let (scene, settings): (_, RenderSettings) =
            pathspace::integrator::settings::load(&source).unwrap();
        let setup = Setup {
            scene: &scene,
            technique: &pathspace::path::PLAIN,
            settings: &settings,
            seed: 5,
            max_depth: None,
        };
        let mut r = Renderer::prepared(kind, &setup).unwrap();
        r.pass(2, &|| {});
        r.film.as_ref().unwrap().image().pixels
    };
    for kind in [
        IntegratorKind::Path,
        IntegratorKind::Light,
        IntegratorKind::Bdpt,
        IntegratorKind::Smc,
    ] {
        assert!(image(&text, kind) == image(&zero, kind), "{}", kind.name());
    }
}

/// The scene of one point light of intensity `intensity` at `position`, seen through a 33 x 33
/// camera at the origin looking down -z, lens radius [`RADIUS`] focused at `focus`.
fn point_light_scene(position: Vec3, focus: f32) -> String {
    format!(
        r#"
[camera]
type = "pinhole"
eye = [0.0, 0.0, 0.0]
look_at = [0.0, 0.0, -1.0]
fov_deg = 30.0
resolution = [33, 33]
aperture_radius = {RADIUS}
focus_distance = {focus}

[[lights]]
type = "point"
position = [{}, {}, {}]
intensity = 2.0
"#,
        position.x, position.y, position.z
    )
}

/// The mean image of `runs` renders of `text` by `kind` (each `passes` passes of `spp`).
fn point_light_runs(text: &str, kind: IntegratorKind, passes: u32, spp: u32) -> Vec<Vec<f64>> {
    let source = SceneSource::embedded("point.toml", text);
    let (scene, settings) = pathspace::integrator::settings::load(&source).unwrap();
    (0..8)
        .map(|seed| {
            let setup = Setup {
                scene: &scene,
                technique: &pathspace::path::PLAIN,
                settings: &settings,
                seed,
                max_depth: None,
            };
            let mut r = Renderer::prepared(kind, &setup).unwrap();
            for _ in 0..passes {
                r.pass(spp, &|| {});
            }
            let img = r.film.as_ref().unwrap().image();
            img.pixels.iter().map(|p| p.x as f64).collect()
        })
        .collect()
}

/// The mean over the film of a point light's image: I / (A_film d^2) E_lens[|x - p| / d], the
/// lens point p uniform on the disk, x at depth d and off the axis by `a` (W_e's 1 / cos^4 and
/// the cosine at the lens against the 1 / |x - p|^2 = cos^2 / d^2 of the distance).
fn point_light_mean(intensity: f64, d: f64, a: f64, film_area: f64) -> f64 {
    let r = RADIUS as f64;
    let mean_dist = common::simpson(
        |rho| {
            common::simpson(
                |phi| (d * d + a * a + rho * rho - 2.0 * a * rho * phi.cos()).sqrt(),
                0.0,
                std::f64::consts::TAU,
                64,
            ) * rho
        },
        0.0,
        r,
        64,
    ) / (std::f64::consts::PI * r * r);
    intensity / (film_area * d * d) * mean_dist / d
}

/// A point light out of focus images to a uniform disk whose radius is the thin-lens
/// geometry's: every pixel wholly outside it stays black in every run, every pixel wholly
/// inside it is lit, and the image's mean is the closed form of [`point_light_mean`]; in
/// focus the same light lands in one pixel. Light tracing (t = 1 through a sampled lens
/// point), BDPT ((1, 1) from the eye subpath's lens point) and the path tracer's direct image
/// of delta lights (one lens point per pass, so its disk is not checked for coverage).
#[test]
fn point_light_images_to_its_circle_of_confusion() {
    let tan = (15.0f64).to_radians().tan();
    let film_area = 4.0 * tan * tan;
    let pixel = 2.0 * tan / 33.0;
    let mut fam = Family::new("lens: circle of confusion");
    // (depth, lateral offset) of the light; the first in focus
    for (d, a) in [(2.0f64, 0.0f64), (5.0, 0.9), (1.2, 0.0)] {
        let position = Vec3::new(a as f32, 0.0, -d as f32);
        let text = point_light_scene(position, FOCUS);
        // the disk on the film (distance 1): centre a / d, radius r |d - f| / (d f)
        let centre = a / d;
        let radius = RADIUS as f64 * (d - FOCUS as f64).abs() / (d * FOCUS as f64);
        let truth = point_light_mean(2.0, d, a, film_area);
        for (kind, passes, spp) in [
            (IntegratorKind::Light, 1, 16),
            (IntegratorKind::Bdpt, 1, 4),
            (IntegratorKind::Path, 64, 1),
        ] {
            let runs = point_light_runs(&text, kind, passes, spp);
            let what = format!("{} d {d} a {a}", kind.name());
            let means: Vec<f64> = runs
                .iter()
                .map(|r| r.iter().sum::<f64>() / 1089.0)
                .collect();
            fam.runs_are(&format!("{what}: mean"), &means, truth);
            for j in 0..1089 {
                let (x, y) = ((j % 33) as f64, (j / 33) as f64);
                // the pixel's square on the film, x to the right, y up
                let (x0, x1) = ((x - 16.5) * pixel, (x - 15.5) * pixel);
                let (y0, y1) = ((15.5 - y) * pixel, (16.5 - y) * pixel);
                let nearest = |lo: f64, hi: f64, c: f64| c.clamp(lo, hi) - c;
                let farthest = |lo: f64, hi: f64, c: f64| (lo - c).abs().max((hi - c).abs());
                let near = nearest(x0, x1, centre).hypot(nearest(y0, y1, 0.0));
                let far = farthest(x0, x1, centre).hypot(farthest(y0, y1, 0.0));
                let lit = runs.iter().filter(|r| r[j] != 0.0).count();
                if near > radius * (1.0 + 1e-3) + 1e-6 {
                    assert_eq!(lit, 0, "{what}: pixel ({x}, {y}) outside the disk is lit");
                }
                if far < radius * (1.0 - 1e-3) && kind != IntegratorKind::Path {
                    assert_eq!(lit, runs.len(), "{what}: pixel ({x}, {y}) inside is dark");
                }
            }
        }
    }
    fam.finish();
}

/// A small diffuse ball out of focus, lit by a point light beside the camera: every connection
/// to the camera leaves from a scattering vertex (light tracing's t = 1 through a sampled lens
/// point, BDPT's camera walks), and the ball's image is the union of its points' circles of
/// confusion. Pixels wholly outside the largest one (plus the ball's own image) stay black;
/// pixels wholly inside the circle of the ball's nearest point, which the light sees, are lit.
#[test]
fn ball_out_of_focus_images_to_its_circles_of_confusion() {
    let (d, rho) = (5.0f64, 0.1f64);
    let text = format!(
        r#"
[camera]
type = "pinhole"
eye = [0.0, 0.0, 0.0]
look_at = [0.0, 0.0, -1.0]
fov_deg = 30.0
resolution = [33, 33]
aperture_radius = {RADIUS}
focus_distance = {FOCUS}

[materials.white]
type = "lambert"
albedo = 0.8

[[shapes]]
type = "sphere"
center = [0.0, 0.0, -{d}]
radius = {rho}
material = "white"

[[lights]]
type = "point"
position = [0.0, 0.3, -0.5]
intensity = 5.0
"#
    );
    let (r, f) = (RADIUS as f64, FOCUS as f64);
    let pixel = 2.0 * (15.0f64).to_radians().tan() / 33.0;
    let outer = rho / (d - rho) + r * (d + rho - f) / ((d + rho) * f);
    let inner = r * (d - rho - f) / ((d - rho) * f);
    for (kind, spp) in [
        (IntegratorKind::Light, 256),
        (IntegratorKind::Bdpt, 64),
        (IntegratorKind::Path, 64),
    ] {
        let runs = point_light_runs(&text, kind, 1, spp);
        for j in 0..1089 {
            let (x, y) = ((j % 33) as f64, (j / 33) as f64);
            let (x0, x1) = ((x - 16.5) * pixel, (x - 15.5) * pixel);
            let (y0, y1) = ((15.5 - y) * pixel, (16.5 - y) * pixel);
            let near = x0.max(0.0).min(x1).hypot(y0.max(0.0).min(y1));
            let far = x0.abs().max(x1.abs()).hypot(y0.abs().max(y1.abs()));
            let lit = runs.iter().filter(|r| r[j] != 0.0).count();
            let what = kind.name();
            if near > outer * (1.0 + 1e-3) {
                assert_eq!(lit, 0, "{what}: pixel ({x}, {y}) outside the image is lit");
            }
            if far < inner * (1.0 - 1e-3) {
                assert!(lit > 0, "{what}: pixel ({x}, {y}) inside the image is dark");
            }
        }
    }
}
