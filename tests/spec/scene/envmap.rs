//! The image-based environment light (`pathspace::scene::envmap`): its direction sampler
//! against its solid-angle density by chi-square, the density's integral and the power it
//! implies, Mitsuba 3's mapping from the image to directions pinned on single texels, the
//! consistency of the light's sampling records (`sample_li`, `pdf_li`, `sample_le`,
//! `emission_pdf_dir`), and the scene file's errors at their key. The integrators' agreement
//! on maps (a constant map in the furnace, the sample sky over haze) is in
//! `tests/oracles/agreement.rs`. Book: "Environment maps".

use crate::common;

use common::sampler;
use common::stats::Family;
use glam::{Mat3, Vec3};
use pathspace::image_io::{write_exr, Image, ImageMeta};
use pathspace::math::Distribution2D;
use pathspace::path::{Vertex, VertexKind, PLAIN};
use pathspace::scene::envmap::EnvMap;
use pathspace::scene::light::emission_pdf_dir;
use pathspace::scene::{Environment, Light, Scene, SceneSource};
use pathspace::spectrum::{luminance, Rgb};
use std::f64::consts::PI;

/// A 16 x 8 map: a smooth, coloured background and one texel 400 times brighter.
fn texel_map(to_world: Mat3) -> EnvMap {
    let (w, h) = (16, 8);
    let mut texels = Vec::new();
    for y in 0..h {
        for x in 0..w {
            let t = 0.2 + 0.1 * (x as f32 * 0.7).sin() + 0.05 * y as f32;
            texels.push(Rgb::new(t, 0.5 * t, 0.3));
        }
    }
    texels[2 * w + 5] = Rgb::new(120.0, 100.0, 80.0);
    EnvMap::new(w, h, texels, to_world, false)
}

/// A 5 x 2 map (pole rows only), mirrored.
fn pole_map() -> EnvMap {
    let texels = (0..10)
        .map(|i| Rgb::splat(0.1 + (i * 7 % 10) as f32))
        .collect();
    EnvMap::new(
        5,
        2,
        texels,
        Mat3::from_diagonal(Vec3::new(-1.0, 1.0, 1.0)),
        false,
    )
}

/// A rotation about an oblique axis.
fn turn() -> Mat3 {
    Mat3::from_axis_angle(Vec3::new(1.0, 2.0, 3.0).normalize(), 0.7)
}

/// The shipped sample sky through the scene file, turned.
fn sky_map() -> EnvMap {
    let text = r#"
[[lights]]
type = "environment"
map = "envmap-sky.exr"
to_world = [[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]]
"#;
    let text = format!("{CAMERA}{text}");
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes");
    let scene = load(&text, &dir).unwrap_or_else(|e| panic!("{e}"));
    match &scene.lights[0] {
        Light::Environment(Environment::Map(m)) => (**m).clone(),
        _ => panic!("not a map"),
    }
}

fn maps() -> Vec<(&'static str, EnvMap)> {
    vec![
        ("texel map, turned", texel_map(turn())),
        ("pole map, mirrored", pole_map()),
        ("sample sky, turned", sky_map()),
    ]
}

/// A camera, so that a scene of lights alone measures something.
const CAMERA: &str = "[camera]\ntype = \"pinhole\"\neye = [0.0, 0.0, 3.0]\nlook_at = [0.0, 0.0, 0.0]\nfov_deg = 40.0\nresolution = [4, 4]\n\n";

fn load(text: &str, dir: &std::path::Path) -> Result<Scene, pathspace::scene::SceneError> {
    let source = SceneSource {
        name: "envmap.toml".into(),
        text: text.into(),
        base_dir: dir.to_path_buf(),
        origin: None,
        inputs: Default::default(),
    };
    Scene::load(&source)
}

/// Mitsuba 3's `direction_to_uv`, written again here in f64 (the binning must not share the
/// code it tests): phi = atan2(x, -z), theta = acos(y) of the local direction.
fn mitsuba_angles(d: Vec3) -> (f64, f64) {
    let phi = (d.x as f64).atan2(-d.z as f64);
    let phi = if phi < 0.0 { phi + 2.0 * PI } else { phi };
    (phi, (d.y as f64).clamp(-1.0, 1.0).acos())
}

/// Mitsuba 3's `uv_to_direction` in f64.
fn mitsuba_direction(phi: f64, theta: f64) -> Vec3 {
    Vec3::new(
        (phi.sin() * theta.sin()) as f32,
        theta.cos() as f32,
        (-phi.cos() * theta.sin()) as f32,
    )
}

#[test]
fn sampling_agrees_with_the_solid_angle_pdf_by_chi_square() {
    const N: u64 = 300_000;
    let mut fam = Family::new("envmap: sampling vs pdf");
    for (case, (name, map)) in maps().into_iter().enumerate() {
        // bins: the map's half-row cells, W in phi by 2 (H - 1) in theta, where the density
        // times sin theta is constant if the pdf is right (so the quadrature is exact)
        let (w, h) = map.size();
        let (nb_phi, nb_theta) = (w, 2 * (h - 1));
        let (dphi, dtheta) = (2.0 * PI / nb_phi as f64, PI / nb_theta as f64);
        let inv = map.to_world().transpose();
        let bin = |d: Vec3| {
            let (phi, theta) = mitsuba_angles(inv * d);
            let i = ((phi / dphi) as usize).min(nb_phi - 1);
            let j = ((theta / dtheta) as usize).min(nb_theta - 1);
            j * nb_phi + i
        };
        let mut observed = vec![0u64; nb_phi * nb_theta];
        let mut s = sampler(0xe4a, case as u64);
        for _ in 0..N {
            if let Some((d, _, _)) = map.sample(s.next_2d()) {
                observed[bin(d)] += 1;
            }
        }
        // expected: N times the integral of pdf(omega) sin theta over the bin (midpoint rule)
        let (q_phi, q_theta) = (4, 16);
        let mut expected = Vec::with_capacity(observed.len());
        for j in 0..nb_theta {
            for i in 0..nb_phi {
                let mut mass = 0.0;
                for a in 0..q_phi {
                    for b in 0..q_theta {
                        let phi = (i as f64 + (a as f64 + 0.5) / q_phi as f64) * dphi;
                        let theta = (j as f64 + (b as f64 + 0.5) / q_theta as f64) * dtheta;
                        let d = map.to_world() * mitsuba_direction(phi, theta);
                        mass += map.pdf(d) as f64 * theta.sin();
                    }
                }
                expected.push(N as f64 * mass * dphi * dtheta / (q_phi * q_theta) as f64);
            }
        }
        fam.chi_square(name, &observed, &expected);
    }
    fam.finish();
}

#[test]
fn pdf_integrates_to_one_and_the_estimator_to_the_power() {
    const N: u64 = 200_000;
    let mut fam = Family::new("envmap: pdf integral and power");
    for (case, (name, map)) in maps().into_iter().enumerate() {
        let mut s = sampler(0xe4b, case as u64);
        // 4 pi pdf(w) over uniform directions: mean 1
        let (mut m, mut m2) = (0.0f64, 0.0f64);
        for _ in 0..N {
            let w = pathspace::math::warp::uniform_sphere(s.next_2d());
            let x = 4.0 * PI * map.pdf(w) as f64;
            m += x;
            m2 += x * x;
        }
        let mean = m / N as f64;
        fam.samples_are(
            &format!("{name}: integral of pdf"),
            mean,
            m2 / N as f64 - mean * mean,
            N,
            1.0,
        );
        // luminance(L) / pdf over sampled directions: 4 pi times the mean luminance
        let (mut m, mut m2) = (0.0f64, 0.0f64);
        for _ in 0..N {
            let (w, value, pdf) = map.sample(s.next_2d()).expect("off the poles");
            assert_eq!(value, map.radiance(w), "{name}: sampled value at {w}");
            // pdf() takes sin theta from the turned f32 direction, whose components are off by
            // a few ulps: a relative error of that over sin theta
            let d = map.to_world().transpose() * w;
            let sin_theta = (d.x * d.x + d.z * d.z).sqrt();
            let rel = (pdf - map.pdf(w)).abs() / pdf;
            assert!(
                rel <= 8.0 * f32::EPSILON / sin_theta,
                "{name}: sampled pdf {pdf} vs pdf() {} at sin theta {sin_theta}",
                map.pdf(w)
            );
            let x = (luminance(value) / pdf) as f64;
            m += x;
            m2 += x * x;
        }
        let mean = m / N as f64;
        let truth = 4.0 * PI * luminance(map.mean_radiance()) as f64;
        fam.samples_are(
            &format!("{name}: L / pdf"),
            mean,
            m2 / N as f64 - mean * mean,
            N,
            truth,
        );
    }
    fam.finish();
}

/// `Distribution2D` returns points inside the cells it reports, with the cells' density, also
/// on a wide grid where (i + r) / n rounds up into the next cell in f32 (r near 1, i large).
#[test]
fn distribution2d_points_lie_in_their_cells() {
    let (nu, nv) = (5000, 3);
    let weights: Vec<f32> = (0..nu * nv).map(|i| 1.0 + (i % 7) as f32).collect();
    let d = Distribution2D::new(&weights, nu, nv);
    let total: f32 = weights.iter().sum();
    let mut s = sampler(0xe50, 0);
    for _ in 0..300_000 {
        let (p, cell, pdf) = d.sample(s.next_2d());
        assert_eq!(d.cell(p), cell, "point {p} outside cell {cell:?}");
        assert_eq!(d.pdf(p), pdf);
        let (i, j) = cell;
        let want = weights[j * nu + i] / total * (nu * nv) as f32;
        assert!(
            (pdf - want).abs() <= 1e-4 * want,
            "cell {cell:?}: {pdf} vs {want}"
        );
    }
}

/// A map of zeros with texel (x, y) = 1.
fn one_texel(w: usize, h: usize, x: usize, y: usize, to_world: Mat3) -> EnvMap {
    let mut texels = vec![Rgb::ZERO; w * h];
    texels[y * w + x] = Rgb::ONE;
    EnvMap::new(w, h, texels, to_world, false)
}

#[test]
fn the_mapping_is_mitsubas() {
    let (w, h) = (8, 5);
    // texel (2, 1): centred on u = 2.5 / 8, theta = pi 1 / (H - 1), covering u in [2/8, 3/8)
    // and theta within half a row of pi / 4
    let map = one_texel(w, h, 2, 1, Mat3::IDENTITY);
    let centre = mitsuba_direction(2.0 * PI * 2.5 / 8.0, PI / 4.0);
    assert_eq!(map.radiance(centre), Rgb::ONE);
    let mut s = sampler(0xe4c, 0);
    for _ in 0..1000 {
        let (d, value, _) = map.sample(s.next_2d()).unwrap();
        let (phi, theta) = mitsuba_angles(d);
        assert_eq!(value, Rgb::ONE);
        assert!((2.0..=3.0).contains(&(phi / (2.0 * PI) * 8.0)), "phi {phi}");
        assert!((0.5..=1.5).contains(&(theta / PI * 4.0)), "theta {theta}");
    }
    // to_world turns the map: the texel is seen at to_world * centre
    let r = turn();
    let turned = one_texel(w, h, 2, 1, r);
    assert_eq!(turned.radiance(r * centre), Rgb::ONE);
    assert_eq!(turned.radiance(centre), Rgb::ZERO);
    // the top row is the zenith (+y), the bottom row the nadir (a little off the poles, where
    // every column meets, in column 3)
    let near_zenith = mitsuba_direction(2.0 * PI * 3.5 / 8.0, 0.02);
    assert!(near_zenith.y > 0.999);
    assert_eq!(
        one_texel(w, h, 3, 0, Mat3::IDENTITY).radiance(near_zenith),
        Rgb::ONE
    );
    let near_nadir = mitsuba_direction(2.0 * PI * 3.5 / 8.0, PI - 0.02);
    assert_eq!(
        one_texel(w, h, 3, h - 1, Mat3::IDENTITY).radiance(near_nadir),
        Rgb::ONE
    );
    // u = 0 looks along -z, u = 1/4 along +x: column 0 just right of -z, column W - 1 left
    let just = |x: f32| Vec3::new(x, 0.0, -1.0).normalize();
    assert_eq!(
        one_texel(w, h, 0, 2, Mat3::IDENTITY).radiance(just(0.01)),
        Rgb::ONE
    );
    assert_eq!(
        one_texel(w, h, w - 1, 2, Mat3::IDENTITY).radiance(just(-0.01)),
        Rgb::ONE
    );
    let x_side = Vec3::new(1.0, 0.0, 0.05).normalize();
    assert_eq!(
        one_texel(w, h, 2, 2, Mat3::IDENTITY).radiance(x_side),
        Rgb::ONE
    );
}

#[test]
fn the_lights_records_agree_with_its_densities() {
    let light = Light::Environment(Environment::Map(Box::new(texel_map(turn()))));
    let mut s = sampler(0xe4d, 0);
    for _ in 0..10_000 {
        let ls = light
            .sample_li(&[], Vec3::ZERO, s.next_2d(), 0.5)
            .expect("off the poles");
        // (pdf() takes sin theta from the turned direction, the sampler from theta: f32
        // rounding apart)
        let pdf = light.pdf_li(&[], Vec3::ZERO, ls.p, ls.n, 0);
        assert!((ls.pdf - pdf).abs() <= 1e-4 * pdf, "{} vs {pdf}", ls.pdf);
        let es = light
            .sample_le(&[], s.next_2d(), s.next_2d(), 0.5, Vec3::ZERO, 2.0)
            .expect("off the poles");
        let pdf = emission_pdf_dir(&light, es.n, es.d);
        assert!(
            (es.pdf_dir - pdf).abs() <= 1e-4 * pdf,
            "{} vs {pdf}",
            es.pdf_dir
        );
        assert_eq!(
            es.value,
            pathspace::scene::light::emitted_by(&light, es.n, es.d)
        );
    }
}

/// BDPT's environment vertices take the map's density and radiance at their own direction:
/// the density of starting a light path there (eye paths that escape, next-event samples) is
/// the selection probability times the map's pdf, not the uniform sphere's, and the emitted
/// radiance is the map's.
#[test]
fn bdpt_environment_vertices_carry_the_maps_density() {
    let text = format!(
        "{CAMERA}[[shapes]]\ntype = \"sphere\"\ncenter = [0.0, 0.0, 0.0]\nradius = 0.5\n\
         material = \"white\"\n[materials.white]\ntype = \"lambert\"\nalbedo = 0.5\n\
         [[lights]]\ntype = \"environment\"\nmap = \"envmap-sky.exr\"\n"
    );
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes");
    let scene = load(&text, &dir).unwrap_or_else(|e| panic!("{e}"));
    let e = scene.environment.expect("an environment");
    let Light::Environment(env) = &scene.lights[e as usize] else {
        panic!("not an environment")
    };
    let mut s = sampler(0xe4f, 0);
    let mut peak = 0.0f32;
    for _ in 0..1000 {
        let (w, value, pdf) = env.sample(s.next_2d()).expect("off the poles");
        let v = Vertex::new(
            VertexKind::InfiniteLight { light: e, w },
            w * 100.0,
            Vec3::ZERO,
            None,
            None,
        );
        let origin = v.light_origin_pdf(&scene, &PLAIN);
        let want = scene.light_pmf(e) * env.pdf(w);
        assert_eq!(origin, want, "light-start density at {w}");
        assert_eq!(v.emitted(&scene, Vec3::ZERO), value, "radiance at {w}");
        peak = peak.max(pdf);
    }
    // the sun's texels are drawn far above the uniform density
    assert!(
        peak > 100.0 * pathspace::math::warp::INV_FOUR_PI,
        "peak pdf {peak}"
    );
}

/// Writes `image` as an EXR in a fresh directory and returns the directory.
fn map_dir(tag: &str, image: &Image) -> std::path::PathBuf {
    let dir = std::env::temp_dir().join(format!("pathspace-envmap-{tag}-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    write_exr(&dir.join("map.exr"), image, &ImageMeta::default()).unwrap();
    dir
}

fn env_error(dir: &std::path::Path, keys: &str) -> String {
    let text = format!("{CAMERA}[[lights]]\ntype = \"environment\"\n{keys}\n");
    match load(&text, dir) {
        Ok(_) => panic!("loaded: {text}"),
        Err(e) => e.to_string(),
    }
}

#[test]
fn bad_maps_are_refused_at_their_key() {
    let mut image = Image::new(4, 3);
    image.pixels.fill(Rgb::ONE);
    let good = map_dir("good", &image);
    let e = env_error(&good, "map = \"missing.exr\"");
    assert!(
        e.contains("key `lights[0].map`") && e.contains("missing.exr"),
        "{e}"
    );
    let e = env_error(
        &good,
        "map = \"map.exr\"\nto_world = [[1.0, 0.0, 0.0], [0.0, 2.0, 0.0], [0.0, 0.0, 1.0]]",
    );
    assert!(
        e.contains("key `lights[0].to_world`") && e.contains("orthogonal"),
        "{e}"
    );
    let e = env_error(&good, "map = \"map.exr\"\nscale = -1.0");
    assert!(e.contains("key `lights[0].scale`"), "{e}");
    let e = env_error(&good, "radiance = 1.0\nscale = 2.0");
    assert!(
        e.contains("key `lights[0].scale`") && e.contains("map"),
        "{e}"
    );
    let e = env_error(&good, "radiance = 1.0\nmap = \"map.exr\"");
    assert!(e.contains("key `lights[0]`"), "{e}");
    for (tag, value) in [
        ("nan", Rgb::new(1.0, f32::NAN, 1.0)),
        ("inf", Rgb::new(f32::INFINITY, 1.0, 1.0)),
        ("negative", Rgb::new(1.0, 1.0, -0.5)),
    ] {
        let mut bad = image.clone();
        bad.pixels[5] = value;
        let dir = map_dir(tag, &bad);
        let e = env_error(&dir, "map = \"map.exr\"");
        assert!(
            e.contains("key `lights[0].map`") && e.contains("map.exr: texel (1, 1)"),
            "{tag}: {e}"
        );
        let _ = std::fs::remove_dir_all(dir);
    }
    let dir = map_dir("thin", &Image::new(1, 4));
    let e = env_error(&dir, "map = \"map.exr\"");
    assert!(e.contains("1 x 4 map"), "{e}");
    let _ = std::fs::remove_dir_all(dir);
    // not an EXR
    std::fs::write(good.join("text.exr"), "not an image").unwrap();
    let e = env_error(&good, "map = \"text.exr\"");
    assert!(
        e.contains("key `lights[0].map`") && e.contains("text.exr"),
        "{e}"
    );
    let _ = std::fs::remove_dir_all(good);
}

#[test]
fn the_uniform_sampling_option_samples_uniformly() {
    let mut texels = vec![Rgb::splat(0.5); 8 * 4];
    texels[9] = Rgb::splat(50.0);
    let map = EnvMap::new(8, 4, texels, Mat3::IDENTITY, true);
    let mut s = sampler(0xe4e, 0);
    for _ in 0..100 {
        let (w, value, pdf) = map.sample(s.next_2d()).unwrap();
        assert_eq!(pdf, pathspace::math::warp::INV_FOUR_PI);
        assert_eq!(map.pdf(w), pdf);
        assert_eq!(value, map.radiance(w));
    }
}
