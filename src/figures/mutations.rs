//! The five mutations of MLT (Pauly et al. Figs. 4-7), each as an old path x and the proposal
//! y its own `Mutation::sample` made from x, with MLT's default parameters and a fixed seed.
//! x is Fig. 2's path in the fog box; the multi-chain perturbation, which needs a specular
//! chain after the lens chain, starts from a pre-pass path of the glass scene `mlt-sds.toml`.

use crate::integrator::bdpt::{Bdpt, Strategies};
use crate::integrator::mlt::contribution::image_contribution;
use crate::integrator::mlt::init::Bootstrap;
use crate::integrator::mlt::mutation::{MutationKind, Workspace};
use crate::integrator::mlt::{Mlt, MltSettings};
use crate::math::Sampler;
use crate::measure::chart::ChartError;
use crate::path::{Vertex, PLAIN};
use crate::scene::Scene;

use super::side::{self, NEW, OLD};
use super::{path::figure_2_path, svg, Scenes, SEED};

/// Proposals drawn per figure; the figure shows the one that moves a vertex farthest.
const PROPOSALS: u64 = 64;
/// Pre-pass samples searched for the multi-chain perturbation's path.
const PREPASS: u64 = 4096;

/// The largest distance a vertex moved (paths of equal length; infinite otherwise).
fn moved(x: &[Vertex], y: &[Vertex]) -> f32 {
    if x.len() != y.len() {
        return f32::INFINITY;
    }
    x.iter()
        .zip(y)
        .map(|(a, b)| a.p.distance(b.p))
        .fold(0.0, f32::max)
}

/// The proposal of mutation `kind` from x that its figure shows: of the first `PROPOSALS`
/// proposals (fixed seed) whose contribution f(y) is positive (those the chain may accept),
/// the first that changes x's length (bidirectional), else the one that moves a vertex
/// farthest, so that the move is visible at the figure's scale.
pub fn mutation_proposal(scene: &Scene, kind: MutationKind, x: &[Vertex]) -> Option<Vec<Vertex>> {
    let mlt = Mlt::new(scene, &PLAIN, MltSettings::default(), SEED, None).ok()?;
    let m = mlt.mutations.get(kind);
    let mut work = Workspace::default();
    let mut best: Option<(f32, Vec<Vertex>)> = None;
    for k in 0..PROPOSALS {
        let mut sampler = Sampler::new(SEED, k, 4);
        let mut y = Vec::new();
        let proposed = m.sample(scene, &PLAIN, x, &mut sampler, &mut work, &mut y);
        if proposed.is_none() || image_contribution(scene, &y).is_none() {
            continue;
        }
        let d = moved(x, &y);
        if d > best.as_ref().map_or(0.0, |b| b.0) {
            best = Some((d, y));
        }
    }
    best.map(|b| b.1)
}

/// The shortest pre-pass path of `scene` (MLT's bootstrap, fixed seed; the first of equal
/// length) with at least three specular vertices, from which the multi-chain perturbation
/// proposes a path: a chain through both spheres, and nothing else to draw.
pub fn multichain_seed(scene: &Scene) -> Option<Vec<Vertex>> {
    let bdpt = Bdpt::new(&PLAIN, None, Strategies::All);
    let boot = Bootstrap::run(scene, &bdpt, PREPASS, SEED);
    boot.candidates
        .iter()
        .filter_map(|c| Bootstrap::path_of(scene, &bdpt, SEED, c))
        .filter(|x| x.iter().filter(|v| v.delta).count() >= 3)
        .filter(|x| mutation_proposal(scene, MutationKind::MultiChain, x).is_some())
        .min_by_key(Vec::len)
}

/// The file name and the title of a mutation's figure.
fn names(kind: MutationKind) -> (&'static str, &'static str) {
    match kind {
        MutationKind::Bidirectional => ("mutation-bidirectional.svg", "Bidirectional mutation"),
        MutationKind::Sensor => ("mutation-sensor.svg", "Sensor (lens) perturbation"),
        MutationKind::Light => ("mutation-light.svg", "Light (caustic) perturbation"),
        MutationKind::Propagation => ("mutation-propagation.svg", "Propagation perturbation"),
        MutationKind::MultiChain => ("mutation-multichain.svg", "Multi-chain perturbation"),
    }
}

/// The figure of mutation `kind`: x in grey, y in red, y's vertices that moved labelled.
pub(super) fn figure(s: &Scenes, kind: MutationKind) -> (&'static str, Result<String, ChartError>) {
    let (name, title) = names(kind);
    let scene = match kind {
        MutationKind::MultiChain => &s.sds,
        _ => &s.fog_box,
    };
    let x = match kind {
        MutationKind::MultiChain => multichain_seed(scene),
        _ => figure_2_path(scene),
    };
    let pair = x.and_then(|x| Some((mutation_proposal(scene, kind, &x)?, x)));
    let Some((y, x)) = pair else {
        let e = ChartError::Drawing("mutation", format!("{title}: no proposal"));
        return (name, Err(e));
    };
    let v = side::view(scene);
    let svg = svg("mutation", side::size(&v, 760), |root| {
        let caption = format!("{title}: x (grey) and the proposal y (red)");
        let mut c = side::chart(root, &caption, v)?;
        side::draw_scene(&mut c, scene)?;
        // label the vertices that moved (or, for a new length, all but the camera)
        let kept = |a: &[Vertex], b: &[Vertex], i: usize| {
            a.len() == b.len() && a[i].p.distance(b[i].p) < 1e-4 || a[i].is_sensor()
        };
        side::draw_path(&mut c, &x, (OLD, side::LEFT), Some("x"), |i| {
            !kept(&x, &y, i)
        })?;
        side::draw_path(&mut c, &y, (NEW, side::RIGHT), Some("y"), |i| {
            !kept(&y, &x, i)
        })
    });
    (name, svg)
}
