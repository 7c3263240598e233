//! `pathspace render [SCENE] [--integrator I] [--spp N | --time S] [--seed S] [--threads N]
//! [--max-depth D] [-o OUT.exr] [--png OUT.png] [--json]`, and for `--integrator smc`
//! `[--smc-variant is1_cv2] [--smc-threshold T] [--smc-cache-budget BYTES] [--smc-estimator
//! distance|march] [--smc-step MFP]`. Every option overrides its key of the scene file's
//! `[render]` table; the passes and the preprocessing run in an
//! [`crate::render::session`].

use std::path::PathBuf;

use super::display::{Live, Preview, Tev};
use super::CliError;
use crate::image_io::{self, ImageMeta};
use crate::integrator::settings::{GuideOptions, RenderOptions, Spelling};
use crate::integrator::smc::SmcOptions;
use crate::integrator::{IntegratorKind, OwnOption, RenderSettings, Setup};
use crate::render::checkpoint::Recipe;
use crate::render::memory;
use crate::render::provenance::TIMING_KEYS;
use crate::render::run::LiveView;
use crate::render::session::Preprocessed;
use crate::render::{Frontend, Outputs, Render, Rendered};
use std::sync::atomic::AtomicUsize;

pub use crate::render::session::RenderResult;

use super::render_args::RenderArgs;

/// The options of guided local sampling, shared by `render` and `converge`: the
/// `[render.guide]` schema, each flag overriding its key.
pub type GuideArgs = GuideOptions;

pub use crate::render::run::guides;

/// The options of `--integrator smc`: the `[render.smc]` schema.
pub type SmcArgs = SmcOptions;

/// Parses a byte count: `1073741824`, `512MiB`, `1GiB`, `64KiB` (shared with the scene key
/// `[render.smc] cache_budget`).
pub use crate::integrator::smc::parse_bytes;

/// Parses `WxH`.
pub use crate::integrator::settings::parse_size as parse_resolution;

/// The relMSE a render expects from its own per-pixel variance (no reference needed); `None`
/// without a camera or for MLT. See `measure::stats::estimated_relmse`.
pub fn estimated_relmse(result: &RenderResult) -> Option<f64> {
    let (image, variance) = (result.image.as_ref()?, result.variance_of_mean.as_ref()?);
    crate::measure::stats::estimated_relmse(image, variance).ok()
}

/// Applies the options to the scene file's settings, checking them in the order the user
/// meets them (the refusals name the option): the integrator and the settings with every
/// option applied, which [`Render::new`] checks against the scene.
fn configure(
    args: &RenderArgs,
    mut settings: RenderSettings,
) -> Result<(IntegratorKind, RenderSettings), CliError> {
    let flags = &args.options;
    let kind = flags.integrator.unwrap_or(settings.integrator);
    args.refuse_foreign(kind, &settings)?;
    let mut flags = RenderOptions::clone(flags);
    flags.spp = args.mutations_per_pixel.or(flags.spp);
    settings
        .apply(&flags, Spelling::Flag)
        .map_err(|e| CliError::Usage(e.message))?;
    Ok((kind, settings))
}

/// The `render` subcommand's worker threads.
fn thread_pool(threads: Option<usize>) -> Result<rayon::ThreadPool, CliError> {
    super::thread_pool(threads)
}

/// Reports the adjoint image (stderr unless `--json`) and writes it with `--adjoint-output`.
fn show_adjoint(args: &RenderArgs, pre: &Preprocessed, render: &Render) -> Result<(), CliError> {
    if render.adjoint.is_none() {
        return Ok(());
    }
    let image = pre
        .technique
        .adjoint
        .as_ref()
        .ok_or_else(|| CliError::Usage("the adjoint image was not installed".into()))?;
    if !args.json {
        eprintln!(
            "adjoint image: {}x{} cells over {} area lights, {} pre-pass samples in {:.2} s, {} empty cells (floor eps = {:.3e})",
            image.cols,
            image.rows,
            image.map.len(),
            image.stats.samples,
            image.stats.seconds,
            image.stats.zero_cells,
            image.epsilon
        );
    }
    if let Some(out) = &args.adjoint_output {
        let img = image.to_image();
        let mut meta = ImageMeta::default();
        meta.set(
            "adjoint_image",
            "cells: I* + eps, columns along u1 (light strips)",
        )
        .set("seed", render.settings.seed)
        .set("scene_hash", format!("{:016x}", render.source.hash()));
        image_io::write_exr(out, &img, &meta).map_err(|e| e.to_string())?;
        image_io::write_png(&out.with_extension("png"), &img).map_err(|e| e.to_string())?;
    }
    Ok(())
}

/// `--strategy-images DIR`: BDPT's strategies one by one, as EXR and PNG.
fn write_strategy_images(
    args: &RenderArgs,
    dir: &std::path::Path,
    setup: &Setup,
    render: &Render,
) -> Result<(), CliError> {
    let images = OwnOption::StrategyImages;
    if !render.kind.facts().takes(images) {
        return Err(CliError::Usage(format!(
            "--strategy-images needs --integrator {}",
            IntegratorKind::names_where(|f| f.takes(images))
        )));
    }
    let renderer = crate::integrator::Renderer::prepared(render.kind, setup)?;
    let films = renderer.strategy_images(render.settings.spp, args.strategy_depth);
    for ((s, t), film) in &films {
        let img = film.image();
        let base = dir.join(format!("s{s}-t{t}"));
        let mut meta = ImageMeta::default();
        meta.set(
            "integrator",
            format!("bdpt strategy s={s} t={t} (MIS-weighted)"),
        )
        .set("spp", render.settings.spp)
        .set("seed", render.settings.seed)
        .set("scene_hash", format!("{:016x}", render.source.hash()));
        image_io::write_exr(&base.with_extension("exr"), &img, &meta).map_err(|e| e.to_string())?;
        image_io::write_png(&base.with_extension("png"), &img).map_err(|e| e.to_string())?;
    }
    if !args.json {
        eprintln!("wrote {} strategy images to {}", films.len(), dir.display());
    }
    Ok(())
}

/// Where the image goes: `-o` (default: the scene's name with .exr, a reference's with
/// -ref.exr, in the current directory) and `--png` (default: next to the EXR).
pub(super) fn output_paths(args: &RenderArgs) -> (PathBuf, PathBuf) {
    let stem = args
        .scene
        .as_ref()
        .and_then(|p| p.file_stem())
        .map(|s| s.to_string_lossy().to_string())
        .unwrap_or_else(|| "fog-box".into());
    let suffix = if args.reference { "-ref" } else { "" };
    let exr = args
        .session
        .output
        .clone()
        .unwrap_or_else(|| PathBuf::from(format!("{stem}{suffix}.exr")));
    let png = args
        .png
        .clone()
        .unwrap_or_else(|| exr.with_extension("png"));
    (exr, png)
}

/// The checkpoint beside the EXR: `OUT.checkpoint`.
pub fn checkpoint_path(exr: &std::path::Path) -> PathBuf {
    exr.with_extension("checkpoint")
}

/// The checkpoint `--resume` names: the file itself, or the checkpoint beside an EXR.
pub(super) fn resume_path(file: &std::path::Path) -> PathBuf {
    let is_exr = file
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("exr"));
    if is_exr {
        checkpoint_path(file)
    } else {
        file.to_path_buf()
    }
}

/// Where `render` writes, checked before any work: the image, the adjoint image, the strategy
/// images, the checkpoint beside the image and the one to resume from, the memory limit.
fn outputs(args: &RenderArgs, has_camera: bool) -> Outputs {
    let (exr, png) = output_paths(args);
    let mut files = Vec::new();
    if has_camera {
        files.extend([(exr.clone(), "exr"), (png, "png")]);
    }
    if let Some(out) = &args.adjoint_output {
        files.extend([(out.clone(), "exr"), (out.with_extension("png"), "png")]);
    }
    Outputs {
        files,
        dirs: args.strategy_images.iter().cloned().collect(),
        checkpoint: checkpoint_path(&exr),
        every: args.session.checkpoint,
        resume: args.session.resume.as_deref().map(resume_path),
        max_memory: memory::Limit {
            max_gib: args.session.memory.max_memory,
        },
    }
}

/// Writes the image as EXR (with the render's record, a reference's marks, the `--aovs`
/// layers) and PNG; the paths written.
fn write_image(
    args: &RenderArgs,
    result: &RenderResult,
    render: &Render,
    pre: &Preprocessed,
    features: Option<&crate::aov::Features>,
) -> Result<Vec<String>, CliError> {
    let Some(image) = &result.image else {
        return Ok(Vec::new());
    };
    let (exr, png) = output_paths(args);
    let mut meta = render.record(result, pre);
    if args.reference {
        meta.set("reference", "true");
        if let Some(e) = estimated_relmse(result) {
            meta.set("estimated_relmse", format!("{e:.6e}"));
        }
    }
    if args.session.reproducible {
        for key in TIMING_KEYS {
            meta.attributes.remove(key);
        }
    }
    let layers = match &args.session.aovs {
        Some(list) => {
            let names: Vec<&str> = list.0.iter().map(|a| a.name()).collect();
            meta.set("aovs", names.join(","));
            let sources = crate::aov::Sources {
                image,
                variance: result.variance_of_mean.as_ref(),
                spp: result.spp,
                features,
            };
            crate::aov::channels(&list.0, &sources).map_err(CliError::Usage)?
        }
        None => Vec::new(),
    };
    image_io::write_exr_channels(&exr, image, &layers, &meta).map_err(|e| e.to_string())?;
    image_io::write_png(&png, image).map_err(|e| e.to_string())?;
    Ok(vec![exr.display().to_string(), png.display().to_string()])
}

fn rgb_json(c: glam::Vec3) -> serde_json::Value {
    serde_json::json!([c.x, c.y, c.z])
}

/// The emitting media (L_e,V0 of eq. 1): name, emission coefficient and the emitted power
/// next-event estimation samples them by (`None` when no medium glows).
fn emitting_media_json(scene: &crate::scene::Scene) -> Option<serde_json::Value> {
    let list: Vec<serde_json::Value> = (0..scene.media.len() as u32)
        .filter(|&m| scene.media[m as usize].emits())
        .map(|m| {
            let power = scene.emitters.of_medium(m).map(|e| rgb_json(e.power));
            serde_json::json!({
                "name": scene.medium_names[m as usize],
                "emission": rgb_json(scene.media[m as usize].emission_coefficient()),
                "power": power,
            })
        })
        .collect();
    (!list.is_empty()).then_some(serde_json::Value::Array(list))
}

/// The one JSON object of `--json`.
fn result_json(
    result: &RenderResult,
    render: &Render,
    pre: &Preprocessed,
    written: &[String],
) -> serde_json::Value {
    let sensors: Vec<serde_json::Value> = result
        .meters
        .iter()
        .map(|m| serde_json::json!({"name": m.name, "value": rgb_json(m.value), "stderr": rgb_json(m.stderr), "samples": m.samples}))
        .collect();
    let mut out = serde_json::json!({
        "integrator": result.integrator,
        "spp": result.spp,
        "seconds": result.seconds,
        "paths_per_second": result.paths_per_second(),
        "mean": result.image.as_ref().map(|i| rgb_json(i.mean())),
        "nan_count": result.nan_count,
        "negative_pixels": result.negative_pixels,
        "estimated_relmse": estimated_relmse(result),
        "sensors": sensors,
        "outputs": written,
        "guide": pre.guide.as_ref().map(|g| serde_json::json!({
            "vertices": crate::conventions::OptionValue::name(render.settings.guide.kind),
            "map": [g.map.0, g.map.1],
            "photons": g.photons,
            "importons": g.importons,
            "regions_radiance": [g.regions_radiance.0, g.regions_radiance.1],
            "regions_importance": [g.regions_importance.0, g.regions_importance.1],
            "bytes_radiance": g.bytes_radiance,
            "bytes_importance": g.bytes_importance,
            "seconds_particles": g.seconds_particles,
            "seconds_build": g.seconds_build,
        })),
        "options": render.settings.given.to_json(),
        "adjoint": pre.adjoint.map(|a| serde_json::json!({
            "samples": a.samples,
            "seconds": a.seconds,
            "zero_cells": a.zero_cells,
        })),
    });
    // only a scene with an emitting medium has the key (other scenes' records are unchanged)
    if let Some(list) = emitting_media_json(render.scene) {
        out["emitting_media"] = list;
    }
    // every integrator's statistics key, null but for this one's
    let own = render.kind.facts().statistics_key();
    for kind in IntegratorKind::ALL {
        if let Some(key) = kind.facts().statistics_key() {
            let value = result.statistics.json.clone().filter(|_| own == Some(key));
            out[key] = value.unwrap_or(serde_json::Value::Null);
        }
    }
    out
}

/// The summary lines printed without `--json`.
fn print_summary(result: &RenderResult, written: &[String]) {
    let mean = result.image.as_ref().map_or("no camera".to_string(), |i| {
        let m = i.mean();
        format!("mean pixel ({:.4}, {:.4}, {:.4})", m.x, m.y, m.z)
    });
    println!(
        "{}: {} spp in {:.2} s, {:.3e} paths/s, {}, {} NaN/inf{}",
        result.integrator,
        result.spp,
        result.seconds,
        result.paths_per_second(),
        mean,
        result.nan_count,
        if written.is_empty() {
            String::new()
        } else {
            format!(" -> {}", written.join(", "))
        }
    );
    for line in &result.statistics.lines {
        println!("{line}");
    }
    for m in &result.meters {
        println!(
            "  sensor {}: ({:.5}, {:.5}, {:.5}) +- ({:.5}, {:.5}, {:.5}) [{} samples]",
            m.name, m.value.x, m.value.y, m.value.z, m.stderr.x, m.stderr.y, m.stderr.z, m.samples
        );
    }
    for line in &result.statistics.closing {
        println!("{line}");
    }
}

pub fn run(mut args: RenderArgs) -> Result<(), CliError> {
    if let Some(file) = args.session.resume.clone() {
        super::resume::complete(&mut args, &resume_path(&file))?;
    }
    let (mut scene, settings, source) =
        super::load_scene_at(args.scene.as_deref(), &args.session.film)?;
    run_scene(&args, &mut scene, settings, &source)
}

/// Renders a loaded scene: the options applied and checked, then the render's steps
/// ([`Render::run`]) with `render`'s outputs and reports; `reference` runs it too.
pub(super) fn run_scene(
    args: &RenderArgs,
    scene: &mut crate::scene::Scene,
    settings: RenderSettings,
    source: &crate::scene::SceneSource,
) -> Result<(), CliError> {
    let (kind, settings) = configure(args, settings)?;
    settings.prepare(scene);
    let scene = &*scene;
    let mut render = Render::new(scene, source, kind, settings, args.session.shard)?;
    render.time = args.session.time;
    render.show = !args.json;
    let mut cli = Cli {
        args,
        features: None,
    };
    let rendered = render.run(&outputs(args, scene.camera.is_some()), &mut cli)?;
    finish(args, &render, &rendered)
}

/// `render`'s part of a render: its threads, the feature layers, the adjoint image's and the
/// guide's reports, the strategy images, the image, the live views, the signals, the recipe.
struct Cli<'a> {
    args: &'a RenderArgs,
    /// The feature layers of `--aovs` (computed once, before the passes).
    features: Option<crate::aov::Features>,
}

impl Frontend for Cli<'_> {
    type Error = CliError;

    fn pool(&mut self) -> Result<rayon::ThreadPool, CliError> {
        thread_pool(self.args.session.threads)
    }

    fn before(&mut self, render: &Render, pool: &rayon::ThreadPool) -> Result<(), CliError> {
        let aovs = self
            .args
            .session
            .aovs
            .as_ref()
            .map_or(&[][..], |l| &l.0[..]);
        if aovs.iter().any(|a| a.is_feature()) {
            let seed = render.settings.seed;
            self.features = pool.install(|| crate::aov::features(render.scene, seed));
        }
        Ok(())
    }

    fn preprocessed(
        &mut self,
        render: &Render,
        pre: &Preprocessed,
        seconds: f64,
        pool: &rayon::ThreadPool,
    ) -> Result<(), CliError> {
        let args = self.args;
        if let Some(t) = args.session.time.filter(|&t| seconds > t) {
            eprintln!(
                "warning: the preprocessing took {seconds:.2} s of the {} s of --time: one pass follows",
                super::number(t)
            );
        }
        show_adjoint(args, pre, render)?;
        if let (Some(g), false) = (&pre.guide, args.json) {
            eprint!("{}", g.table());
        }
        if let Some(dir) = &args.strategy_images {
            let setup = render.setup(pre);
            pool.install(|| write_strategy_images(args, dir, &setup, render))?;
        }
        Ok(())
    }

    fn write(
        &self,
        render: &Render,
        result: &RenderResult,
        pre: &Preprocessed,
    ) -> Result<Vec<String>, CliError> {
        write_image(self.args, result, render, pre, self.features.as_ref())
    }

    fn live(&self, size: Option<(u32, u32)>) -> Option<LiveView<'_>> {
        let mut live = live_views(self.args, size);
        live.active().then(|| {
            Box::new(move |pass: &crate::render::session::PassView| live.pass(pass.image)) as _
        })
    }

    fn stop(&self) -> Result<Option<&'static AtomicUsize>, CliError> {
        Ok(Some(
            super::interrupt::install().map_err(CliError::Signals)?,
        ))
    }

    fn recipe(&self) -> Option<Recipe> {
        Some(super::resume::recipe(self.args))
    }
}

/// The one JSON object of `--json` for a finished (or stopped) render, with its memory: what
/// the command prints and a binding's statistics.
pub fn json_report(render: &Render, done: &Rendered) -> serde_json::Value {
    let mut j = result_json(&done.ended.result, render, &done.pre, &done.written);
    j["memory"] = serde_json::json!({
        "estimate": done.memory.total(),
        "parts": done.memory.parts.iter().map(|(n, b)| (n.to_string(), serde_json::json!(b))).collect::<serde_json::Map<_, _>>(),
        "peak_resident": memory::peak_resident(),
    });
    j
}

/// Reports a finished (or stopped) render and turns a stop by a signal into its error (exit
/// 128 + signal).
fn finish(args: &RenderArgs, render: &Render, done: &Rendered) -> Result<(), CliError> {
    let (result, written) = (&done.ended.result, &done.written);
    warn_negative(result, render.kind);
    for w in &result.statistics.warnings {
        eprintln!("warning: {w}");
    }
    if args.json {
        println!("{}", json_report(render, done));
    } else if args.reference {
        print_reference(result, render.source, written);
    } else {
        print_summary(result, written);
    }
    match done.ended.stopped_by {
        Some(signal) => Err(CliError::Interrupted {
            signal,
            what: format!(
                "stopped by {} after {} of {} spp: wrote {} (continue with --resume {})",
                super::interrupt::name(signal),
                result.spp,
                render.settings.spp,
                written.join(", "),
                checkpoint_path(&output_paths(args).0).display()
            ),
        }),
        None => Ok(()),
    }
}

/// Warns of pixels with a negative estimate (an estimator that has not converged there).
fn warn_negative(result: &RenderResult, kind: IntegratorKind) {
    if result.negative_pixels > 0 {
        eprintln!(
            "warning: {} pixels have a negative estimate (radiance is never negative): the \
             estimator has not converged there{}",
            result.negative_pixels,
            kind.facts()
                .negative_pixels_hint()
                .map_or(String::new(), |h| format!(" ({h})"))
        );
    }
}

/// The summary line of `reference`.
fn print_reference(result: &RenderResult, source: &crate::scene::SceneSource, written: &[String]) {
    println!(
        "reference of {} with {}: {} spp in {:.1} s, estimated relMSE {} -> {}",
        source.name,
        result.integrator,
        result.spp,
        result.seconds,
        estimated_relmse(result).map_or("n/a".to_string(), |e| format!("{e:.3e}")),
        written.join(", ")
    );
}

/// The live views `--display` and `--preview` ask for (none without a camera), tev's
/// connected before the first pass and named by the EXR's path.
fn live_views(args: &RenderArgs, size: Option<(u32, u32)>) -> Live {
    let (exr, png) = output_paths(args);
    let s = &args.session;
    let Some((w, h)) = size else {
        return Live {
            tev: None,
            preview: None,
        };
    };
    let tev = s.display.clone().map(|a| {
        let mut t = Tev::new(a, &exr.display().to_string());
        t.start(w, h);
        t
    });
    Live {
        tev,
        preview: s.preview.map(|t| Preview::new(png, t)),
    }
}
