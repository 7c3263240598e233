//! The render as one call (`render::Render::run`) from a front end that is not the command
//! line: the image is the session's bit for bit, a stop keeps the render's state beside the
//! image and a resumed render finishes it (and removes the state), and the checks before the
//! work refuse with the render layer's errors.
//! Book: "Measuring a renderer".

use std::path::PathBuf;
use std::sync::atomic::{AtomicUsize, Ordering};

use pathspace::integrator::{IntegratorKind, RenderSettings};
use pathspace::render::memory::Limit;
use pathspace::render::session::{self, Preprocessed, RenderResult};
use pathspace::render::{Frontend, Outputs, Render, RenderError};
use pathspace::scene::{Scene, SceneSource};

const FOG_BOX: &str = include_str!("../../../scenes/fog-box.toml");

/// A front end that writes nothing and may be stopped by `stop`.
struct Quiet {
    stop: Option<&'static AtomicUsize>,
}

impl Frontend for Quiet {
    type Error = RenderError;

    fn pool(&mut self) -> Result<rayon::ThreadPool, RenderError> {
        Ok(rayon::ThreadPoolBuilder::new()
            .num_threads(2)
            .build()
            .unwrap())
    }

    fn write(
        &self,
        _: &Render,
        _: &RenderResult,
        _: &Preprocessed,
    ) -> Result<Vec<String>, Self::Error> {
        Ok(Vec::new())
    }

    fn stop(&self) -> Result<Option<&'static AtomicUsize>, RenderError> {
        Ok(self.stop)
    }
}

/// The fog box at 12x10 with `spp` samples per pixel.
fn fog_box(spp: u32) -> (Scene, RenderSettings, SceneSource) {
    let src = SceneSource::embedded("fog-box.toml", FOG_BOX);
    let (mut scene, mut settings) = pathspace::integrator::settings::load(&src).unwrap();
    scene.camera = scene
        .camera
        .as_ref()
        .and_then(|c| c.with_resolution(12, 10));
    settings.spp = spp;
    (scene, settings, src)
}

/// A scratch directory of this test.
fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!(
        "pathspace-render-api-{}-{name}",
        std::process::id()
    ));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn quiet(render: &mut Render) {
    render.show = false;
}

#[test]
fn one_call_renders_the_sessions_image() {
    let (scene, settings, src) = fog_box(8);
    let mut render = Render::new(&scene, &src, IntegratorKind::Path, settings, None).unwrap();
    quiet(&mut render);
    let out = Outputs {
        checkpoint: scratch("one").join("fog.checkpoint"),
        ..Outputs::default()
    };
    let done = render.run(&out, &mut Quiet { stop: None }).unwrap();
    assert!(done.ended.result.complete && done.ended.stopped_by.is_none());
    assert!(done.memory.total() > 0 && done.written.is_empty());
    let pre = Preprocessed::default();
    let alone = session::render(&render.job(&pre, 0.0)).unwrap();
    assert_eq!(
        done.ended.result.image.unwrap().pixels,
        alone.image.unwrap().pixels
    );
    std::fs::remove_dir_all(scratch("one")).unwrap();
}

#[test]
fn a_stop_keeps_the_state_and_a_resume_finishes_it() {
    static STOP: AtomicUsize = AtomicUsize::new(0);
    let (scene, settings, src) = fog_box(8);
    let mut render = Render::new(&scene, &src, IntegratorKind::Bdpt, settings, None).unwrap();
    quiet(&mut render);
    let path = scratch("stop").join("fog.checkpoint");
    let mut out = Outputs {
        checkpoint: path.clone(),
        ..Outputs::default()
    };
    STOP.store(15, Ordering::SeqCst);
    let stopped = render.run(&out, &mut Quiet { stop: Some(&STOP) }).unwrap();
    assert_eq!(stopped.ended.stopped_by, Some(15));
    assert_eq!(stopped.written, [path.display().to_string()]);
    assert!(path.is_file(), "the state of a stopped render is kept");
    out.resume = Some(path.clone());
    let resumed = render.run(&out, &mut Quiet { stop: None }).unwrap();
    assert!(resumed.ended.result.complete);
    assert!(
        !path.exists(),
        "a finished render removes the state it resumed from"
    );
    let pre = Preprocessed::default();
    let alone = session::render(&render.job(&pre, 0.0)).unwrap();
    assert_eq!(
        resumed.ended.result.image.unwrap().pixels,
        alone.image.unwrap().pixels
    );
    std::fs::remove_dir_all(scratch("stop")).unwrap();
}

#[test]
fn the_checks_before_the_work_refuse_with_the_render_layers_errors() {
    let (scene, settings, src) = fog_box(4);
    let render = Render::new(&scene, &src, IntegratorKind::Path, settings, None).unwrap();
    let small = Outputs {
        max_memory: Limit {
            max_gib: Some(1e-6),
        },
        ..Outputs::default()
    };
    let e = render.run(&small, &mut Quiet { stop: None }).err().unwrap();
    assert!(matches!(e, RenderError::Memory(_)), "{e}");
    let missing = Outputs {
        files: vec![(scratch("out").join("no-such-dir/fog.exr"), "exr")],
        ..Outputs::default()
    };
    let e = render
        .run(&missing, &mut Quiet { stop: None })
        .err()
        .unwrap();
    assert!(matches!(e, RenderError::Output(_)), "{e}");
    std::fs::remove_dir_all(scratch("out")).unwrap();
    let (scene, settings, src) = fog_box(4);
    let shard = pathspace::render::shard::Shard::parse("1/2").unwrap();
    let e = Render::new(&scene, &src, IntegratorKind::Smc, settings, Some(shard))
        .err()
        .unwrap();
    assert!(matches!(e, RenderError::Shard(_)), "{e}");
}

/// A front end reads the variance of each pixel's mean only where the film holds it: `path`
/// and `smc` keep each sample in its pixel; `light`, `bdpt` (t = 1 splats) and the MCMC
/// integrators do not,
/// and a variance that left their splats out would understate the error.
#[test]
fn the_variance_of_the_mean_is_given_only_where_the_film_holds_it() {
    for kind in IntegratorKind::ALL {
        let (scene, settings, src) = fog_box(4);
        let mut render = Render::new(&scene, &src, *kind, settings, None).unwrap();
        quiet(&mut render);
        let name = kind.name();
        let out = Outputs {
            checkpoint: scratch(name).join("fog.checkpoint"),
            ..Outputs::default()
        };
        let done = render.run(&out, &mut Quiet { stop: None }).unwrap();
        let splats = matches!(
            kind,
            IntegratorKind::Light
                | IntegratorKind::Bdpt
                | IntegratorKind::Mlt
                | IntegratorKind::Pssmlt
                | IntegratorKind::Mmlt
        );
        assert_eq!(
            done.ended.result.variance_of_mean.is_some(),
            !splats,
            "{name}: got a variance {}, expected {}",
            done.ended.result.variance_of_mean.is_some(),
            !splats
        );
        std::fs::remove_dir_all(scratch(name)).unwrap();
    }
}
