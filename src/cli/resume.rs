//! `--resume FILE` alone: a checkpoint keeps how its render was asked for (a
//! [`Recipe`]: the scene file, the flags, the sample target, the resolution, the shard), and a
//! resumed command takes all of it from there. A flag given again must say the same; only
//! `--spp` may change (a new target, announced), with the session's own options (threads,
//! checkpoint interval, memory limit, outputs and their layers), which do not change the image.

use std::path::{Path, PathBuf};

use super::render_args::RenderArgs;
use super::CliError;
use crate::integrator::settings::RenderOptions;
use crate::render::checkpoint::{Checkpoint, Recipe};

/// The recipe of the render `args` ask for, as its checkpoints keep it.
pub fn recipe(args: &RenderArgs) -> Recipe {
    let mut flags = RenderOptions::clone(&args.options);
    flags.spp = args.mutations_per_pixel.or(flags.spp);
    let s = &args.session;
    Recipe {
        scene: args.scene.as_ref().map(|p| p.display().to_string()),
        scene_absolute: args
            .scene
            .as_ref()
            .and_then(|p| std::fs::canonicalize(p).ok())
            .map(|p| p.display().to_string()),
        flags: serde_json::to_string(&flags).expect("options serialize"),
        resolution: s.film.resolution,
        time: s.time,
        shard: s.shard.map(|x| x.to_string()),
        png: args.png.as_ref().map(|p| p.display().to_string()),
        reproducible: s.reproducible,
        checkpoint: s.checkpoint,
        aovs: s.aovs.as_ref().map(|l| {
            let names: Vec<&str> = l.0.iter().map(|a| a.name()).collect();
            names.join(",")
        }),
    }
}

/// Fills what the command line leaves out from the recipe of the checkpoint at `path`, and
/// refuses a flag that contradicts it (naming both values).
pub fn complete(args: &mut RenderArgs, path: &Path) -> Result<(), CliError> {
    let c = Checkpoint::read(path).map_err(crate::render::RenderError::from)?;
    let Some(recipe) = c.recipe else {
        return Ok(());
    };
    let name = path.display().to_string();
    if args.scene.is_none() {
        args.scene = scene_of(&recipe);
    }
    let saved: RenderOptions = serde_json::from_str(&recipe.flags).map_err(|e| {
        CliError::Usage(format!(
            "{name}: its recorded options do not read back: {e}"
        ))
    })?;
    let mut given = RenderOptions::clone(&args.options);
    given.spp = args.mutations_per_pixel.take().or(given.spp);
    let target = target_spp(&given, &saved, &recipe, &name)?;
    refuse_contradiction(&given, &saved, &name)?;
    let mut merged = given.over(&saved);
    merged.spp = target;
    *args.options = merged;
    let s = &mut args.session;
    let size = |&(w, h): &(u32, u32)| format!("{w}x{h}");
    s.film.resolution = same(
        "--resolution",
        (s.film.resolution, recipe.resolution),
        size,
        &name,
    )?;
    s.time = same("--time", (s.time, recipe.time), f64::to_string, &name)?;
    let shard = (s.shard.map(|x| x.to_string()), recipe.shard.clone());
    let shard = same("--shard", shard, String::clone, &name)?;
    s.shard = shard
        .map(|t| crate::render::shard::Shard::parse(&t))
        .transpose()?;
    s.reproducible |= recipe.reproducible;
    s.checkpoint = s.checkpoint.or(recipe.checkpoint);
    // outputs beside the image: the recipe's unless given anew
    if s.aovs.is_none() {
        s.aovs = recipe.aovs.as_deref().map(str::parse).transpose()?;
    }
    if s.output.is_none() {
        s.output = Some(path.with_extension("exr"));
    }
    if args.png.is_none() {
        args.png = recipe.png.map(PathBuf::from);
    }
    Ok(())
}

/// The scene file of the recipe: as it was given if it is there, else its absolute path
/// (a resume started from another directory); None for the embedded fog box.
fn scene_of(recipe: &Recipe) -> Option<PathBuf> {
    let given = recipe.scene.as_ref().map(PathBuf::from)?;
    if given.exists() {
        return Some(given);
    }
    Some(recipe.scene_absolute.as_ref().map_or(given, PathBuf::from))
}

/// The sample target of the resumed render: the recipe's, or a new `--spp` (announced).
fn target_spp(
    given: &RenderOptions,
    saved: &RenderOptions,
    recipe: &Recipe,
    name: &str,
) -> Result<Option<u32>, CliError> {
    match (given.spp, recipe.time) {
        (Some(_), Some(t)) => Err(CliError::Usage(format!(
            "--spp: the render of {name} is timed (--time {}), so it has no sample target",
            super::number(t)
        ))),
        (Some(n), None) if Some(n) != saved.spp => {
            let was = saved
                .spp
                .map_or("the scene's".to_string(), |s| s.to_string());
            eprintln!("resume: the target is now {n} spp ({name} was rendering toward {was})");
            Ok(Some(n))
        }
        _ => Ok(saved.spp),
    }
}

/// Refuses a render option given now with another value than the checkpoint's render had.
fn refuse_contradiction(
    given: &RenderOptions,
    saved: &RenderOptions,
    name: &str,
) -> Result<(), CliError> {
    let mut now = given.to_json();
    if let Some(o) = now.as_object_mut() {
        o.remove("spp");
    }
    let before = saved.to_json();
    for (key, value) in leaves(&now, "") {
        let old = lookup(&before, &key);
        if old.as_ref() != Some(&value) {
            return Err(contradiction(&key, &value.to_string(), old, name));
        }
    }
    Ok(())
}

fn contradiction(key: &str, now: &str, old: Option<serde_json::Value>, name: &str) -> CliError {
    let old = old.map_or("not given (the scene's value)".to_string(), |v| {
        v.to_string()
    });
    CliError::Usage(format!(
        "--resume {name}: the render option `{key}` is {now} now but {old} in the checkpoint's \
         render; leave it out to continue that render, or start a new one"
    ))
}

/// Every leaf of a JSON object as (`a.b` key, value).
fn leaves(v: &serde_json::Value, prefix: &str) -> Vec<(String, serde_json::Value)> {
    match v.as_object() {
        Some(o) => o
            .iter()
            .flat_map(|(k, v)| {
                let key = if prefix.is_empty() {
                    k.clone()
                } else {
                    format!("{prefix}.{k}")
                };
                leaves(v, &key)
            })
            .collect(),
        None => vec![(prefix.to_string(), v.clone())],
    }
}

/// The value at an `a.b` key of a JSON object.
fn lookup(v: &serde_json::Value, key: &str) -> Option<serde_json::Value> {
    key.split('.').try_fold(v, |v, k| v.get(k)).cloned()
}

/// A session value of the recipe (`pair`: the command line's, the recipe's), unless the
/// command line says another.
fn same<T: PartialEq>(
    flag: &str,
    pair: (Option<T>, Option<T>),
    show: impl Fn(&T) -> String,
    name: &str,
) -> Result<Option<T>, CliError> {
    match pair {
        (Some(n), s) if Some(&n) != s.as_ref() => Err(CliError::Usage(format!(
            "--resume {name}: {flag} is {} now but {} in the checkpoint's render; leave it out \
             to continue that render, or start a new one",
            show(&n),
            s.as_ref().map_or("not given".to_string(), show)
        ))),
        (n, s) => Ok(n.or(s)),
    }
}
