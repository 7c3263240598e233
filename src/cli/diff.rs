//! `pathspace diff A.exr B.exr [--json] [--heatmap OUT.png]`: error metrics of A against B (B is
//! the reference), and optionally a false-colour map of the per-pixel relative error.

use clap::Args;
use std::path::PathBuf;

use super::CliError;
use crate::image_io;
use crate::measure::{heatmap, metrics};

#[derive(Args, Debug)]
pub struct DiffArgs {
    /// The image to assess.
    pub a: PathBuf,
    /// The reference.
    pub b: PathBuf,
    /// Print one JSON object.
    #[arg(long)]
    pub json: bool,
    /// Write a false-colour PNG of the per-pixel relative error (viridis on a log scale from
    /// 0.1 % to 100 %; the mapping is printed).
    #[arg(long, value_name = "OUT.png")]
    pub heatmap: Option<PathBuf>,
    /// A second render of A's scene by the same estimator with another seed: also prints the
    /// variance part of A's relMSE, mean (a1 - a2)^2 / 2 / (b^2 + 1e-2), which needs no
    /// noise-free reference.
    #[arg(long, value_name = "A2.exr")]
    pub twin: Option<PathBuf>,
}

/// The layers beside R, G, B in an EXR: `--aovs`' names in their order, then any other
/// channel by its own name.
fn layer_names(path: &std::path::Path) -> Result<Vec<String>, CliError> {
    use crate::aov::Aov;
    let channels = image_io::read_exr_channels(path)?;
    let mut known: Vec<Aov> = channels
        .iter()
        .filter_map(|c| Aov::of_channel(&c.name))
        .collect();
    known.sort();
    known.dedup();
    let others = channels
        .iter()
        .filter(|c| Aov::of_channel(&c.name).is_none())
        .map(|c| c.name.clone());
    Ok(known
        .iter()
        .map(|a| a.name().to_string())
        .chain(others)
        .collect())
}

pub fn run(args: DiffArgs) -> Result<(), CliError> {
    // a heatmap that cannot be written must not cost reading (and comparing) the images
    if let Some(out) = &args.heatmap {
        image_io::check_output_file(out)?;
    }
    let (a, _) = image_io::read_exr(&args.a)?;
    let (b, _) = image_io::read_exr(&args.b)?;
    let m = metrics::compare(&a, &b)?;
    let (ma, mb) = (a.mean(), b.mean());
    if let Some(out) = &args.heatmap {
        heatmap::write_heatmap(out, &a, &b)?;
    }
    let twin = match &args.twin {
        Some(p) => {
            let (a2, _) = image_io::read_exr(p)?;
            Some(metrics::twin_variance(&a, &a2, &b)?)
        }
        None => None,
    };
    let legend = heatmap::legend_lines();
    let layers = [layer_names(&args.a)?, layer_names(&args.b)?];
    if args.json {
        let mut obj = serde_json::json!({
            "rmse": m.rmse, "relmse": m.relmse, "max_abs": m.max_abs, "max_f32_steps": m.max_steps,
            "mean_a": [ma.x, ma.y, ma.z], "mean_b": [mb.x, mb.y, mb.z],
        });
        if let Some(v) = twin {
            obj["relmse_variance"] = serde_json::json!(v);
        }
        if layers.iter().any(|l| !l.is_empty()) {
            obj["layers_a"] = serde_json::json!(layers[0]);
            obj["layers_b"] = serde_json::json!(layers[1]);
        }
        if let Some(out) = &args.heatmap {
            let stops: Vec<serde_json::Value> = legend
                .iter()
                .map(|(c, e)| serde_json::json!({"colour": c, "relative_error": e}))
                .collect();
            obj["heatmap"] = serde_json::json!({
                "path": out.display().to_string(),
                "colour_map": "viridis, log10 of the relative error, clamped",
                "stops": stops,
            });
        }
        println!("{obj}");
    } else {
        println!("RMSE     {:.6e}", m.rmse);
        println!("relMSE   {:.6e}", m.relmse);
        println!("max |a-b| {:.6e}", m.max_abs);
        println!("max f32 steps {}", m.max_steps);
        println!("mean A   ({:.5}, {:.5}, {:.5})", ma.x, ma.y, ma.z);
        println!("mean B   ({:.5}, {:.5}, {:.5})", mb.x, mb.y, mb.z);
        if let Some(v) = twin {
            println!("relMSE variance part (from the twin) {v:.6e}");
        }
        if layers.iter().any(|l| !l.is_empty()) {
            let list = |l: &[String]| match l.is_empty() {
                true => "none".to_string(),
                // channel names come from the files: escaped for the terminal
                false => super::printable(&l.join(", ")),
            };
            println!(
                "layers A {} (the metrics compare R, G, B)",
                list(&layers[0])
            );
            println!("layers B {}", list(&layers[1]));
        }
        if let Some(out) = &args.heatmap {
            println!(
                "heatmap  {}: per-pixel relative error sqrt(mean_c (a-b)^2/(b^2+{})), viridis on log10, clamped:",
                out.display(),
                metrics::RELMSE_EPSILON
            );
            for (i, (colour, e)) in legend.iter().enumerate() {
                let edge = match i {
                    0 => " or less",
                    i if i + 1 == legend.len() => " or more (and NaN)",
                    _ => "",
                };
                println!("  {colour}  {:>8}{edge}", format!("{:.3}%", e * 100.0));
            }
        }
    }
    Ok(())
}
