//! The image-based environment light (`pathspace::scene::envmap`): its direction sampler
//! against its solid-angle density by chi-square, the density's integral and the power it
//! implies, Mitsuba 3's mapping from the image to directions and its bilinear lookup against a
//! reimplementation in f64, pinned on single texels, the piecewise-bilinear sampler, the
//! consistency of the light's sampling records (`sample_li`, `pdf_li`, `sample_le`,
//! `emission_pdf_dir`), and the scene file's errors at their key. The integrators' agreement
//! on maps (a constant map in the furnace, the sample sky over haze) is in
//! `tests/oracles/agreement.rs`. Book: "Environment maps".

use crate::common;

use common::sampler;
use common::stats::Family;
use glam::{Mat3, Vec3};
use pathspace::image_io::{write_exr, Image, ImageMeta};
use pathspace::math::{Bilinear2D, Distribution2D};
use pathspace::path::{Vertex, VertexKind, PLAIN};
use pathspace::scene::envmap::EnvMap;
use pathspace::scene::light::{emission_pdf_dir, LightPointDraw};
use pathspace::scene::{Environment, Light, Scene, SceneSource};
use pathspace::spectrum::{luminance, Rgb};
use std::f64::consts::PI;

/// A 16 x 8 map: a smooth, coloured background and one texel 400 times brighter.
fn texel_map(to_world: Mat3) -> EnvMap {
    EnvMap::new(16, 8, texel_values(), to_world, false)
}

/// The texels of [`texel_map`].
fn texel_values() -> Vec<Rgb> {
    let (w, h) = (16, 8);
    let mut texels = Vec::new();
    for y in 0..h {
        for x in 0..w {
            let t = 0.2 + 0.1 * (x as f32 * 0.7).sin() + 0.05 * y as f32;
            texels.push(Rgb::new(t, 0.5 * t, 0.3));
        }
    }
    texels[2 * w + 5] = Rgb::new(120.0, 100.0, 80.0);
    texels
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
        // bins: the cells between texel centres, W in s = u - 1/(2W) (wrapped) by H - 1 in
        // theta, halved in theta, where the density times sin theta is bilinear in (s, theta)
        // if the pdf is right (so the midpoint quadrature is exact)
        let (w, h) = map.size();
        let (nb_phi, nb_theta) = (w, 2 * (h - 1));
        let (dphi, dtheta) = (2.0 * PI / nb_phi as f64, PI / nb_theta as f64);
        let shift = PI / w as f64;
        let inv = map.to_world().transpose();
        let bin = |d: Vec3| {
            let (phi, theta) = mitsuba_angles(inv * d);
            let s = (phi - shift).rem_euclid(2.0 * PI);
            let i = ((s / dphi) as usize).min(nb_phi - 1);
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
                        let phi = (i as f64 + (a as f64 + 0.5) / q_phi as f64) * dphi + shift;
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

/// `Bilinear2D` draws points with the density it reports: a chi-square test over 4 x 4 bins per
/// cell of a grid with zero vertices (the midpoint rule is exact for a bilinear function on a
/// bin inside a cell), and its density is the bilinear interpolation of the vertex values over
/// their integral.
#[test]
fn bilinear2d_samples_follow_its_density() {
    const N: u64 = 400_000;
    let (nu, nv) = (5, 3);
    let values: Vec<f32> = (0..(nu + 1) * (nv + 1))
        .map(|k| [0.0, 1.0, 3.0, 0.5, 7.0, 0.0, 2.0][k % 7])
        .collect();
    let d = Bilinear2D::new(&values, nu, nv);
    // the integral: each cell's mean of its corners over nu nv cells
    let at = |i: usize, j: usize| values[j * (nu + 1) + i] as f64;
    let integral: f64 = (0..nv)
        .flat_map(|j| (0..nu).map(move |i| (i, j)))
        .map(|(i, j)| (at(i, j) + at(i + 1, j) + at(i, j + 1) + at(i + 1, j + 1)) / 4.0)
        .sum::<f64>()
        / (nu * nv) as f64;
    for j in 0..=nv {
        for i in 0..=nu {
            let p = glam::Vec2::new(i as f32 / nu as f32, j as f32 / nv as f32);
            let want = at(i, j) / integral;
            assert!(
                (d.pdf(p) as f64 - want).abs() <= 1e-5 * want.max(1.0),
                "vertex ({i}, {j}): {} vs {want}",
                d.pdf(p)
            );
        }
    }
    let (bu, bv) = (4 * nu, 4 * nv);
    let mut observed = vec![0u64; bu * bv];
    let mut s = sampler(0xe51, 0);
    for _ in 0..N {
        let (p, pdf) = d.sample(s.next_2d());
        assert_eq!(pdf, d.pdf(p), "pdf at {p}");
        assert!(pdf > 0.0, "a point of density 0 at {p}");
        let i = ((p.x * bu as f32) as usize).min(bu - 1);
        let j = ((p.y * bv as f32) as usize).min(bv - 1);
        observed[j * bu + i] += 1;
    }
    let mut expected = Vec::new();
    let mut mass = 0.0;
    for j in 0..bv {
        for i in 0..bu {
            let centre =
                glam::Vec2::new((i as f32 + 0.5) / bu as f32, (j as f32 + 0.5) / bv as f32);
            let m = d.pdf(centre) as f64 / (bu * bv) as f64;
            mass += m;
            expected.push(N as f64 * m);
        }
    }
    assert!(
        (mass - 1.0).abs() < 1e-5,
        "the density integrates to {mass}"
    );
    let mut fam = Family::new("bilinear2d: sampling vs pdf");
    fam.chi_square("5 x 3 cells with zeros", &observed, &expected);
    fam.finish();
}

/// Mitsuba 3's bilinear lookup written again in f64 from its definition: texel (x, y) centred
/// on u = (x + 1/2) / W, theta = pi y / (H - 1), interpolated between the four nearest centres,
/// wrapped around in u and clamped in theta.
fn reference_lookup(texels: &[Rgb], (w, h): (usize, usize), phi: f64, theta: f64) -> [f64; 3] {
    let x = phi / (2.0 * PI) * w as f64 - 0.5;
    let x0 = x.floor();
    let fx = x - x0;
    let i0 = (x0 as i64).rem_euclid(w as i64) as usize;
    let i1 = (i0 + 1) % w;
    let y = (theta / PI).clamp(0.0, 1.0) * (h - 1) as f64;
    let j0 = (y.floor() as usize).min(h - 2);
    let fy = y - j0 as f64;
    let t = |i: usize, j: usize, c: usize| texels[j * w + i].to_array()[c] as f64;
    std::array::from_fn(|c| {
        let row = |j: usize| (1.0 - fx) * t(i0, j, c) + fx * t(i1, j, c);
        (1.0 - fy) * row(j0) + fy * row(j0 + 1)
    })
}

/// The radiance is Mitsuba's bilinear lookup and the density Mitsuba's: over random directions,
/// `radiance` against the f64 reference, and `pdf` times 2 pi^2 sin theta against the bilinear
/// interpolation of Y(L) sin theta at the texel centres (shifted by half a texel in u), up to
/// one normalizing constant.
#[test]
fn the_lookup_and_the_density_are_mitsubas_bilinear_ones() {
    let texels = texel_values();
    let size = (16, 8);
    let r = turn();
    let map = EnvMap::new(size.0, size.1, texels.clone(), r, false);
    let weighted: Vec<Rgb> = texels
        .iter()
        .enumerate()
        .map(|(k, &l)| {
            let theta = PI * (k / size.0) as f64 / (size.1 - 1) as f64;
            Rgb::splat(luminance(l) * theta.sin() as f32)
        })
        .collect();
    let mut s = sampler(0xe52, 0);
    let mut ratios = Vec::new();
    for _ in 0..20_000 {
        let w = pathspace::math::warp::uniform_sphere(s.next_2d());
        let (phi, theta) = mitsuba_angles(r.transpose() * w);
        let want = reference_lookup(&texels, size, phi, theta);
        let got = map.radiance(w).to_array();
        for c in 0..3 {
            // f32 angles: a few 1e-7 of a texel times the largest texel
            assert!(
                (got[c] as f64 - want[c]).abs() <= 2e-5 * 120.0,
                "radiance at {w}: {got:?} vs {want:?}"
            );
        }
        let density = reference_lookup(&weighted, size, phi, theta)[0];
        if density > 1e-2 {
            ratios.push(map.pdf(w) as f64 * 2.0 * PI * PI * theta.sin() / density);
        }
    }
    let (lo, hi) = ratios
        .iter()
        .fold((f64::MAX, 0.0f64), |(a, b), &x| (a.min(x), b.max(x)));
    assert!(
        hi / lo - 1.0 < 1e-3,
        "pdf over the reference in [{lo}, {hi}]"
    );
}

#[test]
fn the_mapping_is_mitsubas() {
    let (w, h) = (8, 5);
    let at = |x: usize, y: usize, u: f64, theta: f64| {
        one_texel(w, h, x, y, Mat3::IDENTITY).radiance(mitsuba_direction(2.0 * PI * u, theta))[0]
    };
    let near = |got: f32, want: f32| (got - want).abs() < 1e-4;
    // texel (2, 1): centred on u = 2.5 / 8, theta = pi 1 / (H - 1), blended linearly with its
    // neighbours' centres, in u and in theta
    assert!(near(at(2, 1, 2.5 / 8.0, PI / 4.0), 1.0));
    assert!(near(at(2, 1, 2.75 / 8.0, PI / 4.0), 0.75));
    assert!(near(at(2, 1, 3.5 / 8.0, PI / 4.0), 0.0));
    assert!(near(at(2, 1, 2.5 / 8.0, 1.5 * PI / 4.0), 0.5));
    assert!(near(at(2, 1, 2.25 / 8.0, 0.75 * PI / 4.0), 0.5625));
    // samples of a single texel lie within its neighbours' centres, where it shows
    let map = one_texel(w, h, 2, 1, Mat3::IDENTITY);
    let mut s = sampler(0xe4c, 0);
    for _ in 0..1000 {
        let (d, value, _) = map.sample(s.next_2d()).unwrap();
        let (phi, theta) = mitsuba_angles(d);
        assert!(value[0] > 0.0, "{d}: {value}");
        assert!((1.5..=3.5).contains(&(phi / (2.0 * PI) * 8.0)), "phi {phi}");
        assert!((0.0..=2.0).contains(&(theta / PI * 4.0)), "theta {theta}");
    }
    // to_world turns the map: the texel is seen at to_world * centre
    let r = turn();
    let centre = mitsuba_direction(2.0 * PI * 2.5 / 8.0, PI / 4.0);
    let turned = one_texel(w, h, 2, 1, r);
    assert!(near(turned.radiance(r * centre)[0], 1.0));
    assert!(
        turned.radiance(centre)[0] < 0.5,
        "{}",
        turned.radiance(centre)
    );
    // the top row is the zenith (+y), clamped there (not blended across the pole with the
    // opposite meridian), the bottom row the nadir
    assert!(mitsuba_direction(0.0, 0.02).y > 0.999);
    let fy = 0.02 / PI * 4.0;
    assert!(near(at(3, 0, 3.5 / 8.0, 0.02), (1.0 - fy) as f32));
    assert!(near(at(3, 4, 3.5 / 8.0, PI - 0.02), (1.0 - fy) as f32));
    assert!(near(at(7, 0, 7.5 / 8.0, 0.02), (1.0 - fy) as f32));
    // u = 0 looks along -z, half a texel from the centres of columns W - 1 and 0, which meet
    // there (wrapped around); u = 1/4 along +x, between the centres of columns 1 and 2
    let minus_z = Vec3::new(0.0, 0.0, -1.0);
    let plus_x = Vec3::new(1.0, 0.0, 0.0);
    for (x, d) in [(0, minus_z), (w - 1, minus_z), (1, plus_x), (2, plus_x)] {
        let value = one_texel(w, h, x, 2, Mat3::IDENTITY).radiance(d)[0];
        assert!(near(value, 0.5), "column {x} at {d}: {value}");
    }
}

#[test]
fn the_lights_records_agree_with_its_densities() {
    let light = Light::Environment(Environment::Map(Box::new(texel_map(turn()))));
    let mut s = sampler(0xe4d, 0);
    for _ in 0..10_000 {
        let ls = light
            .sample_li(&[], Vec3::ZERO, (s.next_2d(), 0.5), LightPointDraw::Area)
            .expect("off the poles");
        // (pdf() takes sin theta from the turned direction, the sampler from theta: f32
        // rounding apart)
        let pdf = light.pdf_li(&[], Vec3::ZERO, (ls.p, ls.n, 0), LightPointDraw::Area);
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
            pathspace::scene::light::emitted_by(&light, &[], 0, (es.p, es.n), es.d)
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

/// The pixels of a test RGBE image, `w` x `h`, as (r, g, b, e) bytes: runs of equal pixels,
/// zeros (e = 0) and varied exponents.
fn rgbe_pixels(w: usize, h: usize) -> Vec<[u8; 4]> {
    if w > 128 {
        // no three equal bytes in a row: literals of the full 128
        return (0..w * h)
            .map(|k| {
                [
                    (k * 7 % 256) as u8,
                    (k * 13 % 251) as u8,
                    (k % 2) as u8,
                    130 + (k % 3) as u8,
                ]
            })
            .collect();
    }
    (0..w * h)
        .map(|k| match k % 11 {
            0..=3 => [200, 100, 50, 130],
            4 => [0, 0, 0, 0],
            5 => [255, 1, 128, 140],
            _ => [
                (k * 37 % 256) as u8,
                (k * 11 % 256) as u8,
                7,
                120 + (k % 20) as u8,
            ],
        })
        .collect()
}

/// A Radiance file of `pixels`, its scanlines run-length encoded per channel (`rle`) or flat,
/// written here from the format's description (not by the reader's code).
fn rgbe_file(w: usize, h: usize, pixels: &[[u8; 4]], rle: bool) -> Vec<u8> {
    let mut out = format!(
        "#?RADIANCE\n# written by the envmap spec\nFORMAT=32-bit_rle_rgbe\nEXPOSURE=1.0\n\n-Y {h} +X {w}\n"
    )
    .into_bytes();
    for row in pixels.chunks(w) {
        if !rle {
            out.extend(row.iter().flatten());
            continue;
        }
        out.extend([2, 2, (w >> 8) as u8, (w & 0xff) as u8]);
        for c in 0..4 {
            let v: Vec<u8> = row.iter().map(|p| p[c]).collect();
            let mut x = 0;
            while x < w {
                let run = v[x..].iter().take_while(|&&b| b == v[x]).count().min(127);
                if run >= 3 {
                    out.extend([128 + run as u8, v[x]]);
                    x += run;
                } else {
                    // a literal up to where a run of three begins
                    let runs_at = |i: usize| i + 2 < w && v[i] == v[i + 1] && v[i] == v[i + 2];
                    let mut n = 1;
                    while x + n < w && n < 128 && !runs_at(x + n) {
                        n += 1;
                    }
                    out.push(n as u8);
                    out.extend(&v[x..x + n]);
                    x += n;
                }
            }
        }
    }
    out
}

/// (r, g, b) 2^(e - 136), 0 for e = 0, in f64.
fn rgbe_value(p: [u8; 4]) -> [f64; 3] {
    let f = if p[3] == 0 {
        0.0
    } else {
        2f64.powi(p[3] as i32 - 136)
    };
    [p[0] as f64 * f, p[1] as f64 * f, p[2] as f64 * f]
}

#[test]
fn radiance_rgbe_maps_read_as_mitsuba_reads_them() {
    use pathspace::image_io::rgbe::decode;
    for (w, h) in [(9, 3), (4, 2), (40, 5), (300, 2)] {
        let pixels = rgbe_pixels(w, h);
        for rle in [true, false] {
            // (scanlines narrower than 8 are always flat)
            let rle = rle && w >= 8;
            let file = rgbe_file(w, h, &pixels, rle);
            let image = decode(&file, 1 << 20).unwrap_or_else(|e| panic!("{w} x {h}: {e}"));
            assert_eq!((image.width as usize, image.height as usize), (w, h));
            for (k, (&p, got)) in pixels.iter().zip(&image.pixels).enumerate() {
                let want = rgbe_value(p);
                assert_eq!(
                    got.to_array().map(|x| x as f64),
                    want,
                    "{w} x {h}, rle {rle}: pixel {k}"
                );
            }
            // every truncation is an error, never a panic
            for cut in 0..file.len() {
                assert!(decode(&file[..cut], 1 << 20).is_err(), "cut at {cut}");
            }
        }
    }
    // the light from a .hdr is the light from an EXR of the same texels
    let (w, h) = (9, 3);
    let dir = std::env::temp_dir().join(format!("pathspace-envmap-hdr-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let pixels = rgbe_pixels(w, h);
    std::fs::write(dir.join("map.hdr"), rgbe_file(w, h, &pixels, true)).unwrap();
    let mut image = Image::new(w as u32, h as u32);
    for (px, &p) in image.pixels.iter_mut().zip(&pixels) {
        *px = Rgb::from_array(rgbe_value(p).map(|x| x as f32));
    }
    write_exr(&dir.join("map.exr"), &image, &ImageMeta::default()).unwrap();
    let light = |file: &str| {
        let text = format!("{CAMERA}[[lights]]\ntype = \"environment\"\nmap = \"{file}\"\n");
        let scene = load(&text, &dir).unwrap_or_else(|e| panic!("{e}"));
        match &scene.lights[0] {
            Light::Environment(Environment::Map(m)) => (**m).clone(),
            _ => panic!("not a map"),
        }
    };
    assert_eq!(light("map.hdr"), light("map.exr"));
    let _ = std::fs::remove_dir_all(dir);
}

#[test]
fn bad_rgbe_files_are_refused_with_what_is_wrong() {
    use pathspace::image_io::rgbe::decode;
    let (w, h) = (9, 2);
    let good = rgbe_file(w, h, &rgbe_pixels(w, h), true);
    let text = String::from_utf8_lossy(&good).to_string();
    let resolution = text.find("-Y").unwrap();
    let pixels = resolution + text[resolution..].find('\n').unwrap() + 1;
    let with = |from: &str, to: &str| {
        let mut b = good.clone();
        let head = text[..pixels].replacen(from, to, 1);
        b.splice(..pixels, head.bytes());
        b
    };
    let cases: Vec<(Vec<u8>, &str)> = vec![
        (with("#?RADIANCE", "P6"), "does not start with `#?`"),
        (
            with("32-bit_rle_rgbe", "32-bit_rle_xyze"),
            "only 32-bit_rle_rgbe",
        ),
        (with("FORMAT=32-bit_rle_rgbe\n", ""), "no FORMAT"),
        (with("-Y 2 +X 9", "+Y 2 +X 9"), "other orientations"),
        (with("-Y 2 +X 9", "-Y 0 +X 9"), "not a positive integer"),
        (
            with("-Y 2 +X 9", "-Y 99999 +X 99999"),
            "more than the limit",
        ),
        (with("-Y 2 +X 9", "-Y 2 +X 10"), "encoded 9 pixels wide"),
        (with("\n\n-Y", "\n-Y"), ""),
    ];
    for (bytes, want) in cases {
        let e = decode(&bytes, 1 << 20).expect_err(want);
        assert!(e.contains(want), "{want}: {e}");
    }
    // a run of 0 and a run past the end of the scanline
    for (code, want) in [(0u8, "a run of 0"), (128 + 10, "a run of 10")] {
        let mut b = good.clone();
        b[pixels + 4] = code;
        let e = decode(&b, 1 << 20).expect_err(want);
        assert!(
            e.contains(want) && e.contains("scanline 0, channel 0"),
            "{e}"
        );
    }
    // through the scene file: the key and the file's name
    let dir = std::env::temp_dir().join(format!("pathspace-envmap-badhdr-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(dir.join("sky.hdr"), &good[..good.len() - 3]).unwrap();
    let e = env_error(&dir, "map = \"sky.hdr\"");
    assert!(
        e.contains("key `lights[0].map`") && e.contains("sky.hdr") && e.contains("ends early"),
        "{e}"
    );
    let _ = std::fs::remove_dir_all(dir);
}
