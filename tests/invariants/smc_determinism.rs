//! SMC is parallel and deterministic: during a pass every thread reads the same snapshot of the
//! structure, and the records are merged (and refinements made) between passes in tile order,
//! so a render is bit-identical for a seed whatever the thread count, structure included.
//! Book: "Sequential Monte Carlo adaptation", section "Parallel and deterministic".

use pathspace::integrator::smc::{EstimatorForm, OctreeStats, Smc, SmcSettings};
use pathspace::integrator::{IntegratorKind, RenderSettings, Renderer};
use pathspace::scene::{Scene, SceneSource};

const TESTBED: &str = include_str!("../../scenes/smc-testbed-albedo-0.8.toml");

fn render(threads: usize, seed: u64, form: EstimatorForm) -> (Vec<[f64; 3]>, OctreeStats) {
    let text = TESTBED.replace("resolution = [32, 32]", "resolution = [24, 20]");
    let scene = Scene::load(&SceneSource::embedded("smc-testbed.toml", &text)).unwrap();
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap();
    pool.install(|| {
        let settings = SmcSettings {
            threshold: 4.0,
            form,
            ..Default::default()
        };
        let mut r = Renderer::new(&scene, IntegratorKind::Smc, seed, None)
            .with_settings(&RenderSettings {
                smc: settings,
                ..RenderSettings::for_scene(&scene)
            })
            .unwrap();
        for _ in 0..4 {
            r.pass(2, &|| {});
        }
        let stats = r.engine::<Smc>().unwrap().stats();
        (r.film.unwrap().sum, stats)
    })
}

#[test]
fn one_and_two_threads_give_bit_identical_images_and_structures() {
    for form in [
        EstimatorForm::Distance,
        EstimatorForm::RayMarching { step: 1.0 },
    ] {
        let (a, sa) = render(1, 42, form);
        let (b, sb) = render(2, 42, form);
        assert!(sa.max_depth >= 2, "the structure did not refine: {sa}");
        assert!(
            a == b,
            "the image depends on the thread count ({})",
            form.name()
        );
        assert_eq!(sa, sb, "the structure depends on the thread count");
        let (c, _) = render(2, 43, form);
        assert!(a != c, "the seed has no effect");
    }
}
