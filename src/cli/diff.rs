//! `pathspace diff A.exr B.exr [--json]`: error metrics of A against B (B is the reference).

use clap::Args;
use std::path::PathBuf;

use crate::image_io;
use crate::measure::metrics;

#[derive(Args, Debug)]
pub struct DiffArgs {
    /// The image to assess.
    pub a: PathBuf,
    /// The reference.
    pub b: PathBuf,
    /// Print one JSON object.
    #[arg(long)]
    pub json: bool,
}

pub fn run(args: DiffArgs) -> Result<(), String> {
    let (a, _) = image_io::read_exr(&args.a).map_err(|e| e.to_string())?;
    let (b, _) = image_io::read_exr(&args.b).map_err(|e| e.to_string())?;
    let m = metrics::compare(&a, &b)?;
    let (ma, mb) = (a.mean(), b.mean());
    if args.json {
        println!(
            "{}",
            serde_json::json!({
                "rmse": m.rmse, "relmse": m.relmse, "max_abs": m.max_abs,
                "mean_a": [ma.x, ma.y, ma.z], "mean_b": [mb.x, mb.y, mb.z],
            })
        );
    } else {
        println!("RMSE     {:.6e}", m.rmse);
        println!("relMSE   {:.6e}", m.relmse);
        println!("max |a-b| {:.6e}", m.max_abs);
        println!("mean A   ({:.5}, {:.5}, {:.5})", ma.x, ma.y, ma.z);
        println!("mean B   ({:.5}, {:.5}, {:.5})", mb.x, mb.y, mb.z);
    }
    Ok(())
}
