use pathspace::integrator::smc::{SmcSettings, Variant};
use pathspace::integrator::{IntegratorKind, Renderer};
use pathspace::scene::{Scene, SceneSource};
fn main() {
    let args: Vec<String> = std::env::args().collect();
    let scene = Scene::load(&SceneSource::read(std::path::Path::new(&args[1])).unwrap()).unwrap();
    let (reference, _) = pathspace::image_io::read_exr(std::path::Path::new(&args[2])).unwrap();
    let thr: f64 = args[3].parse().unwrap();
    for v in args[6].split(',') {
        let s = SmcSettings {
            variant: Variant::parse(v).unwrap(),
            threshold: thr,
            form: pathspace::integrator::smc::EstimatorForm::parse(
                &args[4],
                args.get(5).map(|x| x.parse().unwrap()),
            )
            .unwrap(),
            ..Default::default()
        };
        let mut r = Renderer::new(&scene, IntegratorKind::Smc, 7, None)
            .with_smc_settings(s)
            .unwrap();
        let mut line = format!("{v}:");
        for pass in 0..1024u32 {
            // one pass of 4 spp in a separate film to measure its error
            let before = r.film.as_ref().unwrap().clone();
            r.pass(4, &|| {});
            if (pass + 1).is_power_of_two() && pass >= 3 {
                let f = r.film.as_ref().unwrap();
                let mut img = f.image();
                for (i, p) in img.pixels.iter_mut().enumerate() {
                    for c in 0..3 {
                        p[c] = ((f.sum[i][c] - before.sum[i][c]) / 4.0) as f32;
                    }
                }
                let m = pathspace::measure::metrics::compare(&img, &reference).unwrap();
                line += &format!(" {:.4}", m.rmse);
            }
        }
        println!("{line}  | {}", r.smc.as_ref().unwrap().stats());
    }
}
