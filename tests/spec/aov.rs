//! The layers of `--aovs` (`pathspace::aov`): the variance layer is the variance of each
//! pixel's mean, calibrated against the spread of 16 independent renders; the feature layers
//! hold what the first event of a camera ray is (a diffuse wall's reflectance, its normal facing
//! the camera, its distance; in a dense medium the single-scattering albedo and a zero normal);
//! `merge` combines the layers of shards by the variance of a weighted mean; without `--aovs`
//! the EXR holds R, G, B only.
//! Book: "Measuring a renderer" (layers beside the image).

use std::path::{Path, PathBuf};

use pathspace::aov::{self, Aov, Sources};
use pathspace::image_io::{self, Channel};
use pathspace::integrator::{IntegratorKind, PixelSamples, Renderer};
use pathspace::scene::{Scene, SceneSource, FOG_BOX};

use crate::common;
use common::cli::{pathspace, scratch, stderr};
use common::stats::Family;

const GROUP: &str = "aovs";

/// Independent renders of the calibration.
const RUNS: u64 = 16;
/// Samples per pixel of each.
const SPP: u32 = 16;

/// One render: per pixel, its means and its variance layer, each per channel.
type Run = (Vec<[f64; 3]>, Vec<[f64; 3]>);

/// The fog box at 32 x 32 pixels.
fn fog_box_32() -> Scene {
    let text = FOG_BOX.replace("resolution = [256, 256]", "resolution = [32, 32]");
    Scene::load(&SceneSource::embedded("fog-box.toml", &text)).unwrap()
}

/// The fog box at 32 x 32 pixels through Mitsuba's default gaussian filter.
fn fog_box_32_gaussian() -> Scene {
    let text = FOG_BOX.replace(
        "resolution = [256, 256]",
        "resolution = [32, 32]\nfilter = { type = \"gaussian\" }",
    );
    Scene::load(&SceneSource::embedded("fog-box.toml", &text)).unwrap()
}

/// One render of `scene` with `seed`: its image, as (pixel, channel) means, and its variance
/// layer as `--aovs variance` writes it. With the box, one pass of `SPP` samples; with another
/// filter, passes of 4 as the command line renders (its variance comes from the passes).
fn render_with_variance(scene: &Scene, seed: u64) -> Run {
    let mut r = Renderer::new(scene, IntegratorKind::Path, seed, None);
    // the layer estimates the variance of independent samples' mean: stratified film
    // positions would make it overstate the spread across the fog box's edges
    r.pixel_samples = PixelSamples::Independent;
    if scene.camera.as_ref().unwrap().filter.is_box() {
        r.pass(SPP, &|| {});
    } else {
        for _ in 0..SPP / 4 {
            r.pass(4, &|| {});
        }
    }
    let film = r.film.unwrap();
    let (image, variance) = (film.image(), film.variance_of_mean());
    let sources = Sources {
        image: &image,
        variance: Some(&variance),
        spp: film.spp,
        features: None,
    };
    let layer = aov::channels(&[Aov::Variance], &sources).unwrap();
    let names: Vec<&str> = layer.iter().map(|c| c.name.as_str()).collect();
    assert_eq!(names, ["Variance.R", "Variance.G", "Variance.B"]);
    let means = image.pixels.iter().map(|p| p.to_array().map(f64::from));
    let vars = (0..image.pixels.len()).map(|i| [0, 1, 2].map(|c| layer[c].values[i] as f64));
    (means.collect(), vars.collect())
}

/// The mean over `runs` of the variance layers, summed over channels, per pixel.
fn mean_layer(runs: &[Run], p: usize) -> f64 {
    let k = runs.len() as f64;
    (0..3)
        .map(|c| runs.iter().map(|r| r.1[p][c]).sum::<f64>() / k)
        .sum()
}

/// The variance layer agrees with the spread of 16 independent renders. Per pixel and
/// channel, the sample variance s^2 of the 16 means and the mean of the 16 variance layers
/// both estimate Var[mean] without bias, whatever the distribution of the samples, so their
/// difference has mean 0. Summed over channels and divided by a scale v_p taken from 16 other
/// renders (independent of the difference, so the mean stays 0; without it the few brightest
/// pixels' noise hides everything else), the differences of the 1024 pixels, which draw
/// independent streams, are judged by Student's t. A layer holding the variance of one sample
/// (spp times too large), or twice or half Var[mean], fails by more than 12 standard errors.
#[test]
fn variance_layer_matches_the_spread_of_16_independent_renders() {
    calibrate(&fog_box_32(), "box");
}

/// With a filter, neighbouring pixels share samples and a pixel is the ratio sum(w f) / sum(w):
/// its layer is the delta-method variance of the ratio over the render's independent passes,
/// calibrated like the box's. A layer from the per-sample spread of the weighted values, or one
/// without the K / (K - 1) of K passes, fails.
#[test]
fn filtered_variance_layer_matches_the_spread_of_16_independent_renders() {
    calibrate(&fog_box_32_gaussian(), "gaussian");
}

/// The calibration of the variance layer of `scene` against 16 independent renders.
fn calibrate(scene: &Scene, filter: &str) {
    let render = |seeds: std::ops::RangeInclusive<u64>| -> Vec<_> {
        seeds
            .map(|seed| render_with_variance(scene, seed))
            .collect()
    };
    let (runs, scale_runs) = (render(1..=RUNS), render(1001..=1000 + RUNS));
    let pixels = runs[0].0.len();
    let scale: Vec<f64> = (0..pixels).map(|p| mean_layer(&scale_runs, p)).collect();
    // a floor for pixels whose scale runs saw no noise
    let floor = 0.01 * scale.iter().sum::<f64>() / pixels as f64;
    let k = RUNS as f64;
    let (mut spread_total, mut layer_total) = (0.0, 0.0);
    let d: Vec<f64> = (0..pixels)
        .map(|p| {
            let spread: f64 = (0..3)
                .map(|c| {
                    let mean = runs.iter().map(|r| r.0[p][c]).sum::<f64>() / k;
                    runs.iter().map(|r| (r.0[p][c] - mean).powi(2)).sum::<f64>() / (k - 1.0)
                })
                .sum();
            let layer = mean_layer(&runs, p);
            spread_total += spread;
            layer_total += layer;
            (spread - layer) / (scale[p] + floor)
        })
        .collect();
    eprintln!(
        "sum over pixels: spread of the renders {spread_total:.6e}, variance layers {layer_total:.6e}, ratio {:.4}",
        spread_total / layer_total
    );
    assert!(layer_total > 0.0, "the fog box has noise to measure");
    let mut fam = Family::new(&format!(
        "variance layer against the spread of independent renders, {filter} filter"
    ));
    fam.runs_are(
        "per pixel, (spread of the means - mean variance layer) / independent scale",
        &d,
        0.0,
    );
    fam.finish();
}

/// Writes `text` as `dir/name` and returns the path.
fn scene_file(dir: &Path, name: &str, text: &str) -> PathBuf {
    let path = dir.join(name);
    std::fs::write(&path, text).unwrap();
    path
}

/// A diffuse wall of reflectance (0.2, 0.5, 0.8) filling the view at z = -2, seen from the
/// origin along -z; its normal u x v points away from the camera (the layer faces it).
const WALL: &str = r#"
[camera]
type = "pinhole"
eye = [0.0, 0.0, 0.0]
look_at = [0.0, 0.0, -1.0]
up = [0.0, 1.0, 0.0]
fov_deg = 40.0
resolution = [7, 5]

[materials.wall]
type = "lambert"
albedo = [0.2, 0.5, 0.8]

[[shapes]]
type = "quad"
origin = [-10.0, -10.0, -2.0]
u = [0.0, 20.0, 0.0]
v = [20.0, 0.0, 0.0]
material = "wall"

[[lights]]
type = "environment"
radiance = 1.0
"#;

/// The camera inside a box of a dense medium: sigma_t = 1000 in every channel, albedo
/// (0.2, 0.5, 0.8); every camera ray collides within a few thousandths.
const DENSE: &str = r#"
[camera]
type = "pinhole"
eye = [0.0, 0.0, 0.0]
look_at = [0.0, 0.0, -1.0]
up = [0.0, 1.0, 0.0]
fov_deg = 40.0
resolution = [9, 9]

[media.dense]
type = "homogeneous"
sigma_a = [800.0, 500.0, 200.0]
sigma_s = [200.0, 500.0, 800.0]
phase = { type = "isotropic" }

[[shapes]]
type = "box"
min = [-1.0, -1.0, -1.0]
max = [1.0, 1.0, 1.0]
material = "null"
interior = "dense"

[[lights]]
type = "environment"
radiance = 1.0
"#;

/// Renders `scene` with `args` into `dir/out`, which must succeed; the EXR.
fn render(dir: &Path, scene: &Path, out: &str, args: &[&str]) -> PathBuf {
    let exr = dir.join(out);
    let mut all = vec!["render", scene.to_str().unwrap()];
    all.extend_from_slice(args);
    all.extend_from_slice(&["--reproducible", "-o", exr.to_str().unwrap()]);
    let done = pathspace(&all);
    assert!(done.status.success(), "{all:?}: {}", stderr(&done));
    exr
}

/// The channel `name` of `channels`.
fn channel<'a>(channels: &'a [Channel], name: &str) -> &'a [f32] {
    &channels
        .iter()
        .find(|c| c.name == name)
        .unwrap_or_else(|| panic!("no channel {name}"))
        .values
}

/// The three channels of a vector layer, per pixel.
fn vectors(channels: &[Channel], names: [&str; 3]) -> Vec<glam::Vec3> {
    let [x, y, z] = names.map(|n| channel(channels, n));
    (0..x.len())
        .map(|i| glam::Vec3::new(x[i], y[i], z[i]))
        .collect()
}

/// `a` and `b` equal up to a few f32 rounding steps of their size.
fn close(a: f32, b: f32) -> bool {
    (a - b).abs() <= 8.0 * f32::EPSILON * a.abs().max(b.abs()).max(1e-30)
}

#[test]
fn every_layer_is_written_under_its_channel_names() {
    let dir = scratch(GROUP, "names");
    let wall = scene_file(&dir, "wall.toml", WALL);
    let exr = render(&dir, &wall, "all.exr", &["--spp", "4", "--aovs", "all"]);
    let channels = image_io::read_exr_channels(&exr).unwrap();
    let mut got: Vec<&str> = channels.iter().map(|c| c.name.as_str()).collect();
    let mut want: Vec<&str> = Aov::ALL
        .iter()
        .flat_map(|a| a.channels().to_vec())
        .collect();
    got.sort();
    want.sort();
    assert_eq!(got, want);
    assert!(channels.iter().all(|c| c.values.len() == 7 * 5));
    assert!(channel(&channels, "spp").iter().all(|&n| n == 4.0));
    let (_, meta) = image_io::read_exr(&exr).unwrap();
    assert_eq!(
        meta.get("aovs"),
        Some("variance,relative-variance,albedo,normal,depth,position,spp")
    );
    // `diff` compares R, G, B as before and names the layers
    let plain = render(&dir, &wall, "plain.exr", &["--spp", "4"]);
    let done = pathspace(&["diff", exr.to_str().unwrap(), plain.to_str().unwrap()]);
    assert!(done.status.success(), "{}", stderr(&done));
    let out = String::from_utf8_lossy(&done.stdout);
    assert!(out.contains("relMSE   0.000000e0"), "{out}");
    assert!(
        out.contains("layers A variance, relative-variance, albedo"),
        "{out}"
    );
    // so does `reference`
    let r = dir.join("ref.exr");
    let done = pathspace(&[
        "reference",
        wall.to_str().unwrap(),
        "--spp",
        "4",
        "--aovs",
        "depth",
        "-o",
        r.to_str().unwrap(),
    ]);
    assert!(done.status.success(), "{}", stderr(&done));
    let names: Vec<String> = image_io::read_exr_channels(&r)
        .unwrap()
        .into_iter()
        .map(|c| c.name)
        .collect();
    assert_eq!(names, ["Z"]);
}

#[test]
fn without_aovs_the_exr_holds_rgb_only() {
    let dir = scratch(GROUP, "plain");
    let wall = scene_file(&dir, "wall.toml", WALL);
    let exr = render(&dir, &wall, "plain.exr", &["--spp", "2"]);
    assert!(image_io::read_exr_channels(&exr).unwrap().is_empty());
    let (_, meta) = image_io::read_exr(&exr).unwrap();
    assert_eq!(meta.get("aovs"), None);
}

#[test]
fn a_diffuse_wall_writes_its_reflectance_normal_and_distance() {
    let dir = scratch(GROUP, "wall");
    let wall = scene_file(&dir, "wall.toml", WALL);
    let exr = render(
        &dir,
        &wall,
        "wall.exr",
        &["--spp", "1", "--aovs", "albedo,normal,depth,position"],
    );
    let ch = image_io::read_exr_channels(&exr).unwrap();
    let albedo = vectors(&ch, ["Albedo.R", "Albedo.G", "Albedo.B"]);
    let normal = vectors(&ch, ["Ns.X", "Ns.Y", "Ns.Z"]);
    let p = vectors(&ch, ["P.X", "P.Y", "P.Z"]);
    let depth = channel(&ch, "Z");
    let scene = Scene::load(&SceneSource::embedded("wall.toml", WALL)).unwrap();
    let cam = scene.camera.as_ref().unwrap();
    let (w, h) = (cam.width, cam.height);
    // the distance to the wall at film point (rx, ry)
    let dist = |rx: f32, ry: f32| 2.0 / cam.generate_ray(glam::Vec2::new(rx, ry)).d.z.abs();
    for i in 0..(w * h) as usize {
        let (x, y) = ((i as u32 % w) as f32, (i as u32 / w) as f32);
        assert!(
            close(albedo[i].x, 0.2) && close(albedo[i].y, 0.5) && close(albedo[i].z, 0.8),
            "pixel {i}: albedo {}",
            albedo[i]
        );
        assert!(
            (normal[i] - glam::Vec3::Z).length() < 1e-6,
            "pixel {i}: normal {}",
            normal[i]
        );
        assert!(close(p[i].z, -2.0), "pixel {i}: P.Z {}", p[i].z);
        // the mean distance over the pixel lies between the distance at the pixel's point
        // nearest the optical axis and at its farthest corner
        let near = dist(
            (w as f32 / 2.0).clamp(x, x + 1.0),
            (h as f32 / 2.0).clamp(y, y + 1.0),
        );
        let far = [(0., 0.), (1., 0.), (0., 1.), (1., 1.)]
            .iter()
            .map(|(a, b)| dist(x + a, y + b))
            .fold(0.0f32, f32::max);
        let slack = 1e-5 * far;
        assert!(
            depth[i] >= near - slack && depth[i] <= far + slack,
            "pixel {i}: depth {} not in [{near}, {far}]",
            depth[i]
        );
    }
    // the centre pixel of an odd resolution holds the axis: a distance just above 2
    let centre = ((h / 2) * w + w / 2) as usize;
    assert!(depth[centre] >= 2.0 - 1e-5 && depth[centre] < 2.01);
}

/// In a dense medium every first event is a medium vertex: the albedo layer is
/// sigma_s / sigma_t, the normal is the zero vector, and the depth is the mean of 16 free
/// flights (Exp(sigma_t): mean 1 / 1000), judged over the 81 independent pixels by Student's t.
#[test]
fn a_dense_medium_writes_its_single_scattering_albedo_and_no_normal() {
    let dir = scratch(GROUP, "dense");
    let dense = scene_file(&dir, "dense.toml", DENSE);
    let exr = render(
        &dir,
        &dense,
        "dense.exr",
        &["--spp", "1", "--aovs", "albedo,normal,depth"],
    );
    let ch = image_io::read_exr_channels(&exr).unwrap();
    let albedo = vectors(&ch, ["Albedo.R", "Albedo.G", "Albedo.B"]);
    let normal = vectors(&ch, ["Ns.X", "Ns.Y", "Ns.Z"]);
    for (i, (a, n)) in albedo.iter().zip(&normal).enumerate() {
        assert!(
            close(a.x, 0.2) && close(a.y, 0.5) && close(a.z, 0.8),
            "pixel {i}: albedo {a}"
        );
        assert_eq!(*n, glam::Vec3::ZERO, "pixel {i}");
    }
    let depth: Vec<f64> = channel(&ch, "Z").iter().map(|&z| z as f64).collect();
    let mut fam = Family::new("depth in a dense medium");
    fam.runs_are("mean depth of the pixels, 1 / sigma_t", &depth, 1e-3);
    fam.finish();
}

#[test]
fn the_variance_layer_is_refused_where_the_film_has_no_pixel_variance() {
    let dir = scratch(GROUP, "refused");
    let wall = scene_file(&dir, "wall.toml", WALL);
    let out = dir.join("x.exr");
    for integrator in ["mlt", "bdpt", "light"] {
        let done = pathspace(&[
            "render",
            wall.to_str().unwrap(),
            "--integrator",
            integrator,
            "--aovs",
            "albedo,variance",
            "-o",
            out.to_str().unwrap(),
        ]);
        assert!(!done.status.success());
        let e = stderr(&done);
        assert!(
            e.contains("--aovs variance needs --integrator path or smc"),
            "{e}"
        );
        assert!(!out.exists());
    }
    let done = pathspace(&["render", wall.to_str().unwrap(), "--aovs", "albedo,colour"]);
    assert!(!done.status.success());
    assert!(
        stderr(&done).contains("unknown layer `colour`"),
        "{}",
        stderr(&done)
    );
}

/// Shards merged: the variance layer is sum w_i^2 Var_i with w_i = spp_i / sum spp, the
/// relative variance is recomputed from it and the merged image, the features are the
/// weighted mean, spp is summed; an input without the layers leaves them out, with a warning.
#[test]
fn merge_combines_the_layers_of_shards() {
    let dir = scratch(GROUP, "merge");
    let fog = scene_file(&dir, "fog.toml", FOG_BOX);
    let shards: Vec<PathBuf> = (1..=3)
        .map(|i| {
            let shard = format!("{i}/3");
            let args = ["--spp", "12", "--resolution", "8x8", "--aovs", "all"];
            let mut all = args.to_vec();
            all.extend_from_slice(&["--shard", &shard]);
            render(&dir, &fog, &format!("s{i}.exr"), &all)
        })
        .collect();
    let merged = dir.join("merged.exr");
    let mut args = vec!["merge"];
    args.extend(shards.iter().map(|p| p.to_str().unwrap()));
    args.extend(["-o", merged.to_str().unwrap()]);
    let done = pathspace(&args);
    assert!(done.status.success(), "{}", stderr(&done));
    let spp: Vec<f64> = shards
        .iter()
        .map(|s| {
            image_io::read_exr(s)
                .unwrap()
                .1
                .get("spp")
                .unwrap()
                .parse()
                .unwrap()
        })
        .collect();
    let total: f64 = spp.iter().sum();
    let layers: Vec<Vec<Channel>> = shards
        .iter()
        .map(|s| image_io::read_exr_channels(s).unwrap())
        .collect();
    let (image, meta) = image_io::read_exr(&merged).unwrap();
    let m = image_io::read_exr_channels(&merged).unwrap();
    assert_eq!(m.len(), layers[0].len(), "every layer kept");
    assert_eq!(
        meta.get("aovs"),
        Some("variance,relative-variance,albedo,normal,depth,position,spp")
    );
    let weighted = |name: &str, power: i32, i: usize| -> f32 {
        let sum: f64 = (0..3)
            .map(|s| (spp[s] / total).powi(power) * channel(&layers[s], name)[i] as f64)
            .sum();
        sum as f32
    };
    for i in 0..64 {
        for (c, rgb) in ["R", "G", "B"].iter().enumerate() {
            let var = weighted(&format!("Variance.{rgb}"), 2, i);
            assert!(close(channel(&m, &format!("Variance.{rgb}"))[i], var));
            let mean = image.pixels[i][c] as f64;
            let rel = (var as f64 / (mean * mean + 1e-2)) as f32;
            assert!(close(
                channel(&m, &format!("RelativeVariance.{rgb}"))[i],
                rel
            ));
        }
        for name in ["Albedo.G", "Ns.Y", "P.X", "Z"] {
            assert!(close(channel(&m, name)[i], weighted(name, 1, i)), "{name}");
        }
        assert_eq!(channel(&m, "spp")[i], total as f32);
    }
    // an input without layers: merged without them, said on stderr
    let plain = render(
        &dir,
        &fog,
        "plain3.exr",
        &["--spp", "12", "--resolution", "8x8", "--shard", "3/3"],
    );
    let out = dir.join("merged2.exr");
    let done = pathspace(&[
        "merge",
        shards[0].to_str().unwrap(),
        shards[1].to_str().unwrap(),
        plain.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
    ]);
    assert!(done.status.success(), "{}", stderr(&done));
    assert!(stderr(&done).contains("channel Variance.R is not in every input"));
    assert!(image_io::read_exr_channels(&out).unwrap().is_empty());
    assert_eq!(image_io::read_exr(&out).unwrap().1.get("aovs"), None);
}
