//! `pathspace merge A.exr B.exr ... -o OUT.exr`: the average of independent renders of one
//! scene, each weighted by its sample count (the EXR attribute `spp`: samples or mutations per
//! pixel). Independent MLT runs (other seeds, other machines) merge into one estimate this way,
//! as Pauly et al. sec. 7 suggest for parallel rendering.

use clap::Args;
use std::path::PathBuf;

use super::CliError;
use crate::image_io::{self, Image, ImageMeta};

#[derive(Args, Debug, Clone)]
pub struct MergeArgs {
    /// The renders to average (at least one).
    #[arg(required = true)]
    pub inputs: Vec<PathBuf>,
    /// The merged EXR.
    #[arg(short = 'o', long = "output")]
    pub output: PathBuf,
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
        total += spp;
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

pub fn run(args: MergeArgs) -> Result<(), CliError> {
    let mut inputs = Vec::with_capacity(args.inputs.len());
    for p in &args.inputs {
        let (img, meta) = image_io::read_exr(p)?;
        inputs.push((p.display().to_string(), img, meta));
    }
    let scenes: Vec<&str> = inputs
        .iter()
        .filter_map(|(_, _, m)| m.get("scene_hash"))
        .collect();
    if scenes.windows(2).any(|w| w[0] != w[1]) {
        return Err(CliError::MixedScenes);
    }
    let (image, total) = merge(&inputs)?;
    let mut meta = inputs[0].2.clone();
    meta.set("spp", total).set("merged_from", inputs.len());
    image_io::write_exr(&args.output, &image, &meta)?;
    println!(
        "merged {} renders ({} samples per pixel) -> {}",
        inputs.len(),
        total,
        args.output.display()
    );
    Ok(())
}
