//! Bidirectional path tracing with multiple importance sampling, with media (Lafortune and
//! Willems 1996; Veach 1997 ch. 10; in the path-integral framework of Pauly, Kollig, Keller
//! 2000, eq. 7): the engine the `light` and `bdpt` integrators, MLT's bootstrap and the
//! enlightened preprocessing share, one layer above the path-space mathematics it is built on.
//!
//! A light subpath y_0 ... y_{s-1} and an eye subpath z_{t-1} ... z_0 (z_0 on the sensor) are
//! joined by one edge into a path of s + t vertices. Every (s, t) gives an unbiased estimate
//! f_j / (p(y) p(z)); the balance heuristic (or, on request, the power heuristic) weights them
//! with the densities every other split of the same path would have had. All densities are in
//! the vertices' own measures (area on surfaces, volume in the medium) and include the
//! propagation pdfs of Table 1, so the weights see medium vertices exactly as the path integral
//! does.
//!
//! - [`walk`]: the two subpaths' random walks, limited by the caller's [`WalkLimits`];
//! - [`connect`]: one strategy (s, t) of a pair of subpaths, with [`next_event`] (s = 1) and
//!   [`sensor`] (t = 1) for the connections that sample their own endpoint;
//! - [`mis`]: the strategies' weights from the densities the connection changes.
//!
//! The integrators combine the strategies of a sample into the film (`integrator::bdpt`).
//! Book: "Bidirectional path tracing".

pub mod connect;
pub mod mis;
pub mod next_event;
pub mod sensor;
pub mod walk;

pub use mis::{mis_weight_of_path, Join, MisHeuristic};

use glam::Vec2;

use crate::path::subpath::VertexCache;
use crate::path::{LocalSampling, Vertex};
use crate::scene::Scene;

/// Vertices per subpath at most, whatever Russian roulette decides (a safety net only).
pub const MAX_SUBPATH_VERTICES: usize = 256;

/// Which strategies are used.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Strategies {
    /// All (s, t), weighted by the engine's [`MisHeuristic`].
    All,
    /// Light tracing: only t = 1 (light subpaths connected to the sensor), unweighted.
    LightTracing,
    /// One strategy alone, unweighted: an unbiased estimator of the paths it can sample (the
    /// debugging view, and the test that each strategy is unbiased on its own).
    Only(usize, usize),
}

/// How far a walk may go, passed to every walk by its caller: Russian roulette (after
/// `RR_START_DEPTH` vertices) on or off, and the number of vertices it may hold at most, below
/// the depth limit and [`MAX_SUBPATH_VERTICES`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct WalkLimits {
    pub roulette: bool,
    pub max_vertices: usize,
}

impl WalkLimits {
    /// BDPT's own walks: Russian roulette, no cap but the depth limit and the safety net.
    pub const BDPT: WalkLimits = WalkLimits {
        roulette: true,
        max_vertices: MAX_SUBPATH_VERTICES,
    };

    /// At most `n` vertices and no Russian roulette: the walks of samplers that draw the path
    /// length themselves (the bidirectional particle sampler: a walk of exactly n vertices
    /// unless it escapes or is absorbed).
    pub const fn at_most(n: usize) -> Self {
        WalkLimits {
            roulette: false,
            max_vertices: n,
        }
    }
}

impl Default for WalkLimits {
    fn default() -> Self {
        Self::BDPT
    }
}

/// Where a BDPT sample's eye subpath starts: the pinhole through a raster position, or a
/// point on an irradiance meter (the two sensors of the path integral's measurement, eq. 5).
#[derive(Clone, Copy, Debug)]
pub enum SensorStart {
    Camera(Vec2),
    Meter(u32),
}

/// Reusable per-thread storage, so no sample allocates.
#[derive(Default)]
pub struct Scratch {
    pub light: Vec<Vertex>,
    pub eye: Vec<Vertex>,
    /// The per-vertex values of both subpaths that `Bdpt::combine` computes once per sample.
    pub light_cache: Vec<VertexCache>,
    pub eye_cache: Vec<VertexCache>,
}

/// The engine: the local-sampling technique of both walks (their MIS densities and light
/// starts), the depth limit and the strategies whose weights it computes. The medium around
/// each light, where light subpaths start, is the scene's (`Scene::light_media`).
#[derive(Clone, Debug)]
pub struct Bdpt<'t> {
    pub tech: &'t dyn LocalSampling,
    pub max_depth: u32,
    pub strategies: Strategies,
    /// How the strategies of `Strategies::All` share a path.
    pub heuristic: MisHeuristic,
}

impl<'t> Bdpt<'t> {
    /// BDPT sampling with technique `tech`, paths of at most `max_depth` edges (`None`: no
    /// limit) and `strategies`.
    pub fn new(
        tech: &'t dyn LocalSampling,
        max_depth: Option<u32>,
        strategies: Strategies,
    ) -> Self {
        Bdpt {
            tech,
            max_depth: max_depth.unwrap_or(u32::MAX),
            strategies,
            heuristic: MisHeuristic::default(),
        }
    }

    /// This engine weighting its strategies by `heuristic`.
    pub fn with_heuristic(mut self, heuristic: MisHeuristic) -> Self {
        self.heuristic = heuristic;
        self
    }

    /// The largest s to try with a light subpath `light`: its length, but at least 1 when the
    /// scene has lights, because s = 1 samples its own light vertex (next-event estimation)
    /// whatever became of the light subpath: a walk that ended before its first vertex (a
    /// guided emission direction behind the light) must not take that strategy with it.
    pub fn max_light_vertices(scene: &Scene, light: &[Vertex]) -> usize {
        if scene.lights.is_empty() && scene.emitters.is_empty() {
            0
        } else {
            light.len().max(1)
        }
    }
}

pub use crate::scene::emitters::{light_share, volume_share};
