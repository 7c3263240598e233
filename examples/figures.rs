//! The book's diagrams (`pathspace::figures`), drawn from the code they illustrate in the fog
//! box, the cloud and the glass scene. Run with
//! `cargo run --release --example figures -- book/src/figures/diagrams` from the repository's
//! root (it reads `scenes/fog-box.toml`, `scenes/cloud.toml` and `scenes/mlt-sds.toml`).

use std::path::{Path, PathBuf};

use pathspace::figures::{self, Scenes};
use pathspace::image_io::{io_err, write_replacing};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let out = PathBuf::from(std::env::args().nth(1).ok_or("usage: figures OUT_DIR")?);
    let all = figures::all(&Scenes::load(Path::new("."))?)?;
    std::fs::create_dir_all(&out)?;
    for f in all {
        let path = out.join(f.name);
        write_replacing(&path, |tmp| {
            std::fs::write(tmp, f.svg.as_bytes()).map_err(|e| io_err(tmp, e))
        })?;
        println!("wrote {} ({} bytes)", path.display(), f.svg.len());
    }
    Ok(())
}
