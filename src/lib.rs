//! # pathspace
//!
//! An executable reference for light transport in participating media. Each module implements
//! one concept of the papers and is paired with one chapter of the book (`book/`); the tests in
//! `tests/` are the executable specification.
//!
//! | paper section | module |
//! |---|---|
//! | Pauly, Kollig, Keller 2000, eq. (1), (3), Table 1 | [`medium`] |
//! | eq. (1) phase functions | [`medium::phase`] |
//! | eq. (2) local scattering | [`bsdf`] |
//! | eq. (4) Neumann series | [`integrator::path`] |
//! | eq. (5) measurement equation, sensors | [`scene::camera`], [`scene::sensor`], [`film`] |
//! | sec. 3-4: path space, characteristic, G, f_j, densities | [`path`] |
//! | BDPT with MIS (Lafortune and Willems 1996, Veach ch. 10): walks, connections, weights; the integrators | [`bidir`], [`integrator::bdpt`] |
//! | sec. 5, eq. (8): Metropolis light transport, mutations (and Veach ch. 11) | [`integrator::mlt`] |
//! | Table 1, right column: inhomogeneous media, ray marching, tracking | [`medium::heterogeneous`] |
//! | Pegoraro, Wald, Parker 2008, eq. (1)-(9): sequential Monte Carlo | [`integrator::smc`] |
//! | Kristensen 2010 ch. 5: adjoint image, photons and importons | [`enlightened`] |
//! | a render: its passes, checkpoints, provenance, shards, memory, as one API | [`render`] |
//! | measuring: relMSE, efficiency, convergence order | [`measure`] |
//! | variance and feature layers (AOVs) beside the image | [`aov`] |
//! | conventions and measures | [`conventions`] |
//! | the book's diagrams, drawn from the code they illustrate | [`figures`] |

pub mod aov;
pub mod bidir;
pub mod bsdf;
pub mod cli;
pub mod conventions;
pub mod enlightened;
pub mod figures;
pub mod film;
pub mod geometry;
pub mod image_io;
pub mod integrator;
pub mod math;
pub mod measure;
pub mod medium;
pub mod path;
pub mod render;
pub mod scene;
pub mod spectrum;
pub mod texture;
