//! Determinism: the same scene and seed give a bit-identical image whatever the thread count,
//! because every random stream is derived from the seed and the pixel (or meter chunk) and pass
//! index, and parallel results are merged in a fixed order.

use pathspace::integrator::{IntegratorKind, Renderer};
use pathspace::scene::{Scene, SceneSource, FOG_BOX};

fn render(threads: usize, seed: u64) -> (Vec<[f64; 3]>, Vec<f64>) {
    render_with(IntegratorKind::Path, threads, seed)
}

fn render_with(kind: IntegratorKind, threads: usize, seed: u64) -> (Vec<[f64; 3]>, Vec<f64>) {
    render_filtered(kind, "", threads, seed)
}

/// A render at 40 x 24 pixels (tiles of 16 cut both axes) with the camera key `filter` (or none).
fn render_filtered(
    kind: IntegratorKind,
    filter: &str,
    threads: usize,
    seed: u64,
) -> (Vec<[f64; 3]>, Vec<f64>) {
    let text = FOG_BOX.replace(
        "resolution = [256, 256]",
        &format!("resolution = [40, 24]\n{filter}"),
    );
    let mut text = text;
    text.push_str(
        "\n[[sensors]]\ntype = \"irradiance_meter\"\nname = \"floor\"\norigin = [-0.5, -0.99, -0.5]\nu = [0.0, 0.0, 1.0]\nv = [1.0, 0.0, 0.0]\n",
    );
    let scene = Scene::load(&SceneSource::embedded("fog-box.toml", &text)).unwrap();
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap();
    pool.install(|| {
        let mut r = Renderer::new(&scene, kind, seed, None);
        r.meter_samples = 256;
        r.pass(3, &|| {});
        r.pass(2, &|| {});
        let meters = r.meters.iter().flat_map(|m| m.sum).collect();
        let film = r.film.unwrap();
        let mut pixels = film.sum;
        // a filtered film's weights and batch sums, which sum over neighbouring tiles
        pixels.extend(film.sum_sq);
        for f in &film.filtered {
            pixels.push([f.weight, f.weight_sq, f.batches as f64]);
            pixels.push(f.cross);
        }
        // splatted contributions (light tracing, BDPT's t = 1) must be just as reproducible
        pixels.extend(film.splat);
        (pixels, meters)
    })
}

#[test]
fn one_and_two_threads_give_bit_identical_images() {
    let (a, ma) = render(1, 42);
    let (b, mb) = render(2, 42);
    assert!(a == b, "the image depends on the thread count");
    assert!(ma == mb, "the meters depend on the thread count");
}

#[test]
fn different_seeds_give_different_images() {
    let (a, _) = render(2, 1);
    let (b, _) = render(2, 2);
    assert!(a != b, "the seed has no effect");
}

#[test]
fn bidirectional_integrators_are_deterministic_with_splats() {
    for kind in [IntegratorKind::Bdpt, IntegratorKind::Light] {
        let (a, ma) = render_with(kind, 1, 5);
        let (b, mb) = render_with(kind, 2, 5);
        assert!(a == b, "{kind:?}: the image depends on the thread count");
        assert!(ma == mb, "{kind:?}: the meters depend on the thread count");
    }
}

/// With a filter, a camera sample adds to pixels of the neighbouring tiles and a splat to up to
/// 25 pixels: the tiles' blocks and the splats are summed in tile order, so the image is the
/// same bit for bit with 1 or 3 threads.
#[test]
fn filtered_images_with_splats_are_deterministic() {
    let gaussian = "filter = { type = \"gaussian\" }";
    for kind in [
        IntegratorKind::Path,
        IntegratorKind::Light,
        IntegratorKind::Bdpt,
    ] {
        let (a, ma) = render_filtered(kind, gaussian, 1, 5);
        let (b, mb) = render_filtered(kind, gaussian, 3, 5);
        assert!(
            a == b,
            "{kind:?}: the filtered image depends on the thread count"
        );
        assert!(ma == mb, "{kind:?}: the meters depend on the thread count");
        let (boxed, _) = render_with(kind, 1, 5);
        assert!(
            a[..boxed.len()] != boxed[..],
            "{kind:?}: the filter has no effect"
        );
    }
}

/// MLT: chains are independent streams derived from the seed and the chain index, the pre-pass
/// is deterministic, and chain results are merged in chain order, so the image depends on the
/// seed and the chain count only.
#[test]
fn mlt_is_deterministic_for_a_seed_and_chain_count() {
    let text = FOG_BOX.replace("resolution = [256, 256]", "resolution = [24, 16]");
    let scene = Scene::load(&SceneSource::embedded("fog-box.toml", &text)).unwrap();
    let run = |threads: usize, seed: u64| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| {
            let mut r = Renderer::new(&scene, IntegratorKind::Mlt, seed, None);
            r.pass(2, &|| {});
            r.pass(2, &|| {});
            r.film.unwrap().splat
        })
    };
    assert!(run(1, 7) == run(2, 7), "MLT depends on the thread count");
    assert!(run(2, 7) != run(2, 8), "MLT ignores the seed");
}

/// The path tracer with `distance = "equiangular-mis"`: its equiangular estimate draws from the
/// pixel's own stream, so its image is bit-identical on one and two threads too (and differs
/// from free flight's).
#[test]
fn the_equiangular_path_tracer_is_deterministic() {
    use pathspace::integrator::path::DistanceSampling;
    use pathspace::integrator::Setup;
    let text = FOG_BOX.replace("resolution = [256, 256]", "resolution = [40, 24]");
    let source = SceneSource::embedded("fog-box.toml", &text);
    let (scene, mut settings) = pathspace::integrator::settings::load(&source).unwrap();
    let mut image = |threads: usize, distance: DistanceSampling| {
        settings.distance = distance;
        let setup = Setup {
            scene: &scene,
            technique: &pathspace::path::PLAIN,
            settings: &settings,
            seed: 42,
            max_depth: None,
        };
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| {
            let mut r = Renderer::prepared(IntegratorKind::Path, &setup).unwrap();
            r.pass(3, &|| {});
            r.film.unwrap().sum
        })
    };
    let a = image(1, DistanceSampling::EquiangularMis);
    let b = image(2, DistanceSampling::EquiangularMis);
    assert!(a == b, "the equiangular image depends on the thread count");
    assert!(
        a != image(2, DistanceSampling::FreeFlight),
        "the option has no effect"
    );
}
