//! `pathspace merge A.exr B.exr ... -o OUT.exr [--force]` (or `merge DIR... -o DIR`, the
//! shards of a convergence study, [`crate::measure::study`]): the average of independent renders
//! of one scene, each weighted by its sample count (the EXR attribute `spp`: samples or
//! mutations per pixel). Independent MLT runs (other seeds, other machines) merge into one
//! estimate this way, as Pauly et al. sec. 7 suggest for parallel rendering. The inputs'
//! provenance ([`crate::render::provenance`]) is checked first: another scene, integrator
//! or settings, a file given twice and inputs holding the same samples are refused unless
//! `--force`, and the merged file records its sources. The layers of `--aovs` are merged too
//! ([`crate::aov::merge_channels`]).

use clap::Args;
use std::path::PathBuf;

use super::CliError;
use crate::image_io::{self, Image, ImageMeta};
use crate::render::provenance::{self, Conflict, Provenance, ProvenanceError};

#[derive(Args, Debug, Clone)]
pub struct MergeArgs {
    /// The renders to average (at least one), or the directories of a convergence study's
    /// shards (`converge --shard I/N`).
    #[arg(required = true)]
    pub inputs: Vec<PathBuf>,
    /// The merged EXR (for shards of a study: the study's directory).
    #[arg(short = 'o', long = "output")]
    pub output: PathBuf,
    /// Merge inputs that are not independent renders of one image (another scene, integrator or
    /// settings, the same samples twice, no record), each named in a warning on stderr and in
    /// the merged file's `merge_forced`.
    #[arg(long)]
    pub force: bool,
}

/// The sample-count-weighted mean of images with their `spp` attributes; errors name the file.
// ANCHOR: merge
pub fn merge(inputs: &[(String, Image, ImageMeta)]) -> Result<(Image, u64), CliError> {
    let Some((_, first, _)) = inputs.first() else {
        return Err(CliError::NothingToMerge);
    };
    let (w, h) = (first.width, first.height);
    let mut sum = vec![[0.0f64; 3]; (w * h) as usize];
    let mut total = 0u64;
    for (name, img, meta) in inputs {
        if (img.width, img.height) != (w, h) {
            return Err(CliError::MergeSize(
                name.clone(),
                img.width,
                img.height,
                w,
                h,
            ));
        }
        let spp: u64 = meta
            .get("spp")
            .and_then(|v| v.parse().ok())
            .filter(|&n| n > 0)
            .ok_or_else(|| CliError::NoSpp(name.clone()))?;
        check_spp(name, spp, meta)?;
        total = total.checked_add(spp).ok_or_else(|| {
            CliError::Usage(format!(
                "{name}: the inputs' spp add up beyond 2^64 (a forged or damaged `spp`)"
            ))
        })?;
        if let Some(i) = img.pixels.iter().position(|p| !p.is_finite()) {
            let (x, y) = (i as u32 % w, i as u32 / w);
            return Err(CliError::Usage(format!(
                "{name}: the pixel ({x}, {y}) is not finite: a damaged file cannot be merged"
            )));
        }
        for (acc, p) in sum.iter_mut().zip(&img.pixels) {
            for c in 0..3 {
                acc[c] += spp as f64 * p[c] as f64;
            }
        }
    }
    let pixels = sum
        .iter()
        .map(|s| {
            glam::Vec3::new(
                (s[0] / total as f64) as f32,
                (s[1] / total as f64) as f32,
                (s[2] / total as f64) as f32,
            )
        })
        .collect();
    Ok((
        Image {
            width: w,
            height: h,
            pixels,
        },
        total,
    ))
}
// ANCHOR_END: merge

/// Refuses a sample count that the input's passes (its `streams`) cannot have drawn.
fn check_spp(name: &str, spp: u64, meta: &ImageMeta) -> Result<(), CliError> {
    let Some(runs) = meta.get("streams").and_then(provenance::parse_streams) else {
        return Ok(()); // no record to check it against: `merge` refuses that unless --force
    };
    if provenance::spp_fits_streams(spp, &runs) {
        return Ok(());
    }
    let passes = provenance::pass_count(&runs);
    Err(CliError::Usage(format!(
        "{name}: `spp` = {spp} cannot come from the {passes} passes its `streams` record \
         (each adds 1 to {} samples): a forged or damaged count",
        crate::render::plan::PASS_SPP
    )))
}

/// The layers beside the images ([`crate::aov::merge_channels`]: variances by the squared
/// weights, features by the weights, spp summed), with the merged file's `aovs` attribute; a
/// channel that not every input holds is left out with a warning.
fn merge_layers(
    inputs: &[(String, Image, ImageMeta)],
    layers: &[Vec<image_io::Channel>],
    image: &Image,
    meta: &mut ImageMeta,
) -> Vec<image_io::Channel> {
    use crate::aov::{merge_channels, Aov, MergeInput};
    let parts: Vec<MergeInput> = inputs
        .iter()
        .zip(layers)
        .map(|((_, _, m), channels)| MergeInput {
            // `merge` has checked every input's spp
            spp: m.get("spp").and_then(|v| v.parse().ok()).unwrap_or(0),
            channels,
        })
        .collect();
    let (channels, left_out) = merge_channels(&parts, image);
    for c in &left_out {
        eprintln!(
            "warning: merge: channel {} is not in every input (or cannot be combined): left out",
            super::printable(c)
        );
    }
    let mut kept: Vec<Aov> = channels
        .iter()
        .filter_map(|c| Aov::of_channel(&c.name))
        .collect();
    kept.sort();
    kept.dedup();
    meta.attributes.remove("aovs");
    if !kept.is_empty() {
        let names: Vec<&str> = kept.iter().map(|a| a.name()).collect();
        meta.set("aovs", names.join(","));
    }
    channels
}

/// The files given again (the same file under two names counts), and whether each input is
/// the first of its file.
fn same_files(args: &MergeArgs) -> (Vec<Conflict>, Vec<bool>) {
    let key = |p: &PathBuf| std::fs::canonicalize(p).unwrap_or_else(|_| p.clone());
    let keys: Vec<PathBuf> = args.inputs.iter().map(key).collect();
    let mut out = Vec::new();
    let mut first = Vec::with_capacity(keys.len());
    for (i, k) in keys.iter().enumerate() {
        first.push(!keys[..i].contains(k));
        if !first[i] {
            out.push(Conflict::SameFile(args.inputs[i].display().to_string()));
        }
    }
    (out, first)
}

pub fn run(args: MergeArgs) -> Result<(), CliError> {
    if args.inputs.iter().all(|p| p.is_dir()) {
        return merge_studies(&args);
    }
    // a typo in -o must not cost reading (and checking) every input
    image_io::check_output(&args.output, "exr")?;
    let mut inputs = Vec::with_capacity(args.inputs.len());
    let mut records = Vec::with_capacity(args.inputs.len());
    let mut layers = Vec::with_capacity(args.inputs.len());
    for p in &args.inputs {
        let (img, meta) = image_io::read_exr(p)?;
        let name = p.display().to_string();
        records.push(Provenance::read(&name, &meta).map_err(ProvenanceError::from)?);
        layers.push(image_io::read_exr_channels(p)?);
        inputs.push((name, img, meta));
    }
    let (mut conflicts, first) = same_files(&args);
    // a file given again is said once, not again as samples it shares with itself
    let once: Vec<Provenance> = records
        .iter()
        .zip(&first)
        .filter(|(_, &f)| f)
        .map(|(r, _)| r.clone())
        .collect();
    conflicts.extend(provenance::conflicts(&once));
    if !conflicts.is_empty() && !args.force {
        return Err(ProvenanceError::Refused(conflicts).into());
    }
    for c in &conflicts {
        eprintln!(
            "warning: merge --force: {}",
            super::printable(&c.to_string())
        );
    }
    let (image, total) = merge(&inputs)?;
    let mut meta = provenance::merged_record(&records, &inputs[0].2, &conflicts);
    let channels = merge_layers(&inputs, &layers, &image, &mut meta);
    image_io::write_exr_channels(&args.output, &image, &channels, &meta)?;
    println!(
        "merged {} renders ({} samples per pixel) -> {}",
        inputs.len(),
        total,
        args.output.display()
    );
    Ok(())
}

/// `merge DIR... -o DIR`: the shards of one convergence study (`converge --shard I/N`) as the
/// study one process would have written: its rows, record, charts and summary.
fn merge_studies(args: &MergeArgs) -> Result<(), CliError> {
    super::converge::check_study_outputs(&args.output)?;
    let dirs: Vec<&std::path::Path> = args.inputs.iter().map(PathBuf::as_path).collect();
    let (study, rows) = crate::measure::study::merge_shards(&dirs)?;
    super::converge::write_study(&args.output, &study, &rows)
}
