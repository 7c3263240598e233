//! The book's diagrams, drawn from the implementation itself: each figure samples with the
//! crate's own code (BDPT's walks, the media's free-flight sampling and exact transmittance,
//! the MLT mutations, an SMC run, the particle tracers) at a fixed seed and draws what it got
//! as SVG with plotters, so a figure cannot disagree with the code it illustrates.
//! `cargo run --release --example figures -- book/src/figures/diagrams` writes them;
//! `tests/repository/figures.rs` checks that the committed files are byte for byte what this module draws
//! and that every diagram a chapter names is one of them.
//!
//! One file per family: `side` (the scene seen from the side, shared), `path` (Pauly et al.
//! Figs. 1 and 2, transmittance), `free_flight` (Table 1's outcome space), `mutations` (Figs.
//! 4-7), `walks` (BDPT's strategies, the Neumann series' walk), `chain` (a Dirac chain's
//! weights), `light_point` (a quad light's point drawn by area or by solid angle), `halo` (a lamp's halo and a vertex's cone), `film_points` (stratified film positions), `smc` (Pegoraro et al. Fig. 1, the joint domain), `particles` (enlightened
//! sampling: particles, a guide's map).

mod chain;
mod film_points;
mod free_flight;
mod halo;
mod light_point;
mod mutations;
mod particles;
mod path;
mod side;
mod smc;
mod walks;

use std::path::Path;

use plotters::coord::Shift;
use plotters::prelude::*;

use crate::measure::chart::{register_font, ChartError};
use crate::scene::{Scene, SceneSource};

pub use chain::{mirror_chain, mirror_chain_weights, MIRROR_OVER_LIGHT};
pub use film_points::film_points;
pub use mutations::{multichain_seed, mutation_proposal};
pub use path::figure_2_path;
pub use smc::smc_run;

/// The seed of every figure's sampler.
pub const SEED: u64 = 2000;
/// The most sample indices a figure tries before it gives up looking for its path.
const TRIES: u64 = 100_000;

/// One figure: its file name and its SVG text.
pub struct Figure {
    pub name: &'static str,
    pub svg: String,
}

/// The scenes the figures are drawn in, as the repository ships them.
pub struct Scenes {
    /// `scenes/fog-box.toml`: most figures.
    pub fog_box: Scene,
    /// `scenes/cloud.toml`: the inhomogeneous medium.
    pub cloud: Scene,
    /// `scenes/mlt-sds.toml`: glass, for the multi-chain perturbation's specular chains.
    pub sds: Scene,
}

impl Scenes {
    /// Reads the three scenes from `root/scenes/`.
    pub fn load(root: &Path) -> Result<Scenes, String> {
        let load = |name: &str| -> Result<Scene, String> {
            let path = root.join("scenes").join(name);
            let err = |e: &dyn std::fmt::Display| format!("{}: {e}", path.display());
            let source = SceneSource::read(&path).map_err(|e| err(&e))?;
            Scene::load(&source).map_err(|e| err(&e))
        };
        Ok(Scenes {
            fog_box: load("fog-box.toml")?,
            cloud: load("cloud.toml")?,
            sds: load("mlt-sds.toml")?,
        })
    }
}

/// Every diagram, in the order of the book's chapters.
pub fn all(s: &Scenes) -> Result<Vec<Figure>, ChartError> {
    register_font()?;
    let fog = &s.fog_box;
    let run = smc_run(fog);
    let mut out = vec![
        figure("fog-box.svg", side::fog_box_figure(fog))?,
        figure("ray-fig1.svg", path::ray_figure(fog))?,
        figure(
            "transmittance.svg",
            path::transmittance_figure(fog, &s.cloud),
        )?,
        figure("free-flight-homogeneous.svg", free_flight::figure(fog))?,
        figure("free-flight-cloud.svg", free_flight::figure(&s.cloud))?,
        figure("neumann-walk.svg", walks::neumann_figure(fog))?,
        figure("path-fig2.svg", path::path_figure(fog))?,
        figure("bdpt-strategies.svg", walks::strategies_figure(fog))?,
        figure("mirror-chain.svg", chain::figure())?,
        figure("light-point.svg", light_point::figure(fog))?,
        figure("halo.svg", halo::figure(fog))?,
    ];
    for kind in crate::integrator::mlt::mutation::MutationKind::ALL {
        let (name, svg) = mutations::figure(s, kind);
        out.push(figure(name, svg)?);
    }
    out.push(figure("particles.svg", particles::figure(fog))?);
    out.push(figure("guide-map.svg", particles::guide_figure(fog))?);
    out.push(figure("smc-octree.svg", smc::octree_figure(&run))?);
    out.push(figure(
        "joint-domain.svg",
        smc::joint_domain_figure(fog, &run),
    )?);
    out.push(figure("film-points.svg", film_points::figure())?);
    Ok(out)
}

fn figure(name: &'static str, svg: Result<String, ChartError>) -> Result<Figure, ChartError> {
    Ok(Figure { name, svg: svg? })
}

/// A figure's drawing area.
pub(crate) type Area<'s> = DrawingArea<SVGBackend<'s>, Shift>;
/// What drawing on it returns.
pub(crate) type Drawn = Result<(), Box<dyn std::error::Error>>;

/// The SVG text of a `size` drawing on white by `draw`; `stem` names the figure in errors.
pub(crate) fn svg(
    stem: &'static str,
    size: (u32, u32),
    draw: impl FnOnce(&Area<'_>) -> Drawn,
) -> Result<String, ChartError> {
    let fail = |e: &dyn std::fmt::Display| ChartError::Drawing(stem, e.to_string());
    let mut text = String::new();
    {
        let root = SVGBackend::with_string(&mut text, size).into_drawing_area();
        root.fill(&WHITE).map_err(|e| fail(&e))?;
        draw(&root).map_err(|e| fail(&e))?;
        root.present().map_err(|e| fail(&e))?;
    }
    Ok(text)
}

/// The subscript digits of `i` (vertex names x₀, x₁, ...).
pub(crate) fn subscript(i: usize) -> String {
    i.to_string()
        .chars()
        .map(|c| char::from_u32(0x2080 + c.to_digit(10).unwrap_or(0)).unwrap_or(c))
        .collect()
}
