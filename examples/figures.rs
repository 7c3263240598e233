//! The book's diagrams (`pathspace::figures`): a path of Pauly et al. Fig. 2 sampled in the fog
//! box, and the transmittance of eq. (3) along a ray through the fog box and the cloud.
//! Run with `cargo run --release --example figures -- book/src/figures/diagrams` from the
//! repository's root (it reads `scenes/fog-box.toml` and `scenes/cloud.toml`).

use std::path::{Path, PathBuf};

use pathspace::figures;
use pathspace::image_io::{io_err, write_replacing};
use pathspace::scene::{Scene, SceneSource};

fn load(path: &str) -> Result<Scene, Box<dyn std::error::Error>> {
    Ok(Scene::load(&SceneSource::read(Path::new(path))?)?)
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let out = PathBuf::from(std::env::args().nth(1).ok_or("usage: figures OUT_DIR")?);
    let all = figures::all(&load("scenes/fog-box.toml")?, &load("scenes/cloud.toml")?)?;
    std::fs::create_dir_all(&out)?;
    for f in all {
        let path = out.join(f.name);
        write_replacing(&path, |tmp| {
            std::fs::write(tmp, f.svg.as_bytes()).map_err(|e| io_err(tmp, e))
        })?;
        println!("wrote {}", path.display());
    }
    Ok(())
}
