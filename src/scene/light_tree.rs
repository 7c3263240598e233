//! Light selection for next-event estimation: by power alone (`power`), or by a light
//! hierarchy that weighs each cluster of lights by what it can deliver to the shading point
//! (`tree`; Conty Estevez and Kulla 2018, "Importance sampling of many lights with adaptive
//! tree splitting"). Both give the exact probability of any light at any point
//! ([`LightSelection::pmf`]), which MIS needs when a scattered ray finds an emitter.
//!
//! The tree is a binary hierarchy over the finite lights with power, bounds and an orientation
//! cone per node. At a shading point the descent picks a child with probability proportional
//! to its importance (eq. 3 of the paper, below), rescaling one random number on the way; the
//! probability of a given light is the product of those choices along its root-to-leaf trail,
//! which [`LightTree::pmf`] recomputes by following the light's bit trail. Lights at infinity
//! (directional, environment) have no position to weigh: one choice by power first decides
//! between them and the tree.

use glam::{Vec3, Vec4};
use std::f32::consts::{FRAC_PI_2, PI};

use super::{Light, Scene};
use crate::geometry::{Aabb, Primitive};
use crate::math::distribution::ONE_MINUS_EPSILON;
use crate::math::Distribution1D;

/// Which light selection next-event estimation uses (`[render] light_selection`,
/// `--light-selection`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum LightSelectionKind {
    /// Proportional to power, the same everywhere.
    Power,
    /// By the light tree's importance at the shading point.
    Tree,
}

crate::option_value!(LightSelectionKind, "light selection");

/// A light selection ready to sample: the scene's power distribution, or a light tree.
#[derive(Clone, Debug)]
pub enum LightSelection {
    Power,
    Tree(Box<LightTree>),
}

impl LightSelection {
    /// The selection `kind` for `scene` (a scene whose lights all have zero power keeps the
    /// power distribution's uniform choice: it has nothing to weigh).
    pub fn build(kind: LightSelectionKind, scene: &Scene) -> Self {
        match kind {
            LightSelectionKind::Power => LightSelection::Power,
            LightSelectionKind::Tree => LightTree::build(&scene.lights, &scene.prims, scene.radius)
                .map_or(LightSelection::Power, |t| LightSelection::Tree(Box::new(t))),
        }
    }

    /// A light for the shading point `p` (surface normal `n`, `None` in a medium) from `u`:
    /// its index, its probability and `u` rescaled for the light's own choices; `None` when no
    /// light exists (where no light's bound reaches `p`, the choice is by power: the
    /// probabilities always sum to one).
    #[inline]
    pub fn sample(
        &self,
        scene: &Scene,
        p: Vec3,
        n: Option<Vec3>,
        u: f32,
    ) -> Option<(usize, f32, f32)> {
        if scene.lights.is_empty() {
            return None;
        }
        match self {
            LightSelection::Power => Some(scene.light_distr.sample(u)),
            LightSelection::Tree(t) => t.sample(p, n, u),
        }
    }

    /// The probability that [`LightSelection::sample`] picks `light` at `p` (normal `n`).
    #[inline]
    pub fn pmf(&self, scene: &Scene, p: Vec3, n: Option<Vec3>, light: u32) -> f32 {
        match self {
            LightSelection::Power => scene.light_pmf(light),
            LightSelection::Tree(t) => t.pmf(p, n, light),
        }
    }
}

/// What a node knows of the lights below it: their summed power, a box around them and a cone
/// around their emission directions (axis, spread of the normals `theta_o`, spread of the
/// emission about a normal `theta_e`), as in Conty Estevez and Kulla 2018, sec. 4.1.
#[derive(Clone, Copy, Debug)]
pub struct LightBounds {
    pub bounds: Aabb,
    pub power: f32,
    pub axis: Vec3,
    pub theta_o: f32,
    pub theta_e: f32,
    /// cos and sin of `theta_o`, cos of `theta_e` (at least 0: no bound here exceeds pi/2).
    cos_o: f32,
    sin_o: f32,
    cos_e: f32,
    /// The box's centre and its half diagonal squared (the bounding sphere).
    centre: Vec3,
    r2: f32,
}

impl LightBounds {
    fn new(bounds: Aabb, power: f32, axis: Vec3, theta_o: f32, theta_e: f32) -> Self {
        LightBounds {
            bounds,
            power,
            axis,
            theta_o,
            theta_e,
            cos_o: theta_o.cos(),
            sin_o: theta_o.sin().max(0.0),
            cos_e: theta_e.cos().max(0.0),
            centre: bounds.centroid(),
            r2: 0.25 * bounds.extent().length_squared(),
        }
    }

    /// The bounds of one finite light with power `power`; `None` for lights at infinity.
    pub fn of(light: &Light, prims: &[Primitive], power: f32) -> Option<Self> {
        let point = |p: Vec3| Aabb { min: p, max: p };
        Some(match light {
            Light::Area { prims: ids, .. } => {
                let (mut bounds, mut axis, mut theta_o) = (Aabb::EMPTY, Vec3::Y, -1.0);
                for &i in ids {
                    let prim = &prims[i as usize];
                    let cone = match prim {
                        Primitive::Quad(q) => (q.n, 0.0),
                        Primitive::Triangle(t) => (t.n, 0.0),
                        Primitive::Disk(d) => (d.n, 0.0),
                        Primitive::Sphere(_) => (Vec3::Y, PI),
                        // normals perpendicular to the axis: the great circle about it
                        Primitive::Cylinder(c) => (c.axis, FRAC_PI_2),
                    };
                    bounds = bounds.union(prim.bounds());
                    (axis, theta_o) = if theta_o < 0.0 {
                        cone
                    } else {
                        cone_union((axis, theta_o), cone)
                    };
                }
                LightBounds::new(bounds, power, axis, theta_o.max(0.0), FRAC_PI_2)
            }
            // a point light emits in every direction: normals spread over the whole sphere
            Light::Point { position, .. } => {
                LightBounds::new(point(*position), power, Vec3::Y, PI, FRAC_PI_2)
            }
            // conservative: the cone of the spot's total angle, no falloff inside it
            Light::Spot {
                position,
                frame,
                cos_total,
                ..
            } => {
                let theta_o = cos_total.clamp(-1.0, 1.0).acos();
                LightBounds::new(point(*position), power, frame.n, theta_o, FRAC_PI_2)
            }
            Light::Directional { .. } | Light::Environment(_) => return None,
        })
    }

    /// The bounds of two nodes together.
    fn union(a: &LightBounds, b: &LightBounds) -> LightBounds {
        let (axis, theta_o) = cone_union((a.axis, a.theta_o), (b.axis, b.theta_o));
        let theta_e = a.theta_e.max(b.theta_e);
        LightBounds::new(
            a.bounds.union(b.bounds),
            a.power + b.power,
            axis,
            theta_o,
            theta_e,
        )
    }

    /// The node's importance at `p` (surface normal `n`): Conty Estevez and Kulla 2018,
    /// eq. (3), power times the bounded cosines at emitter and receiver over a squared
    /// distance. The paper divides by the squared distance to the box's centre, at least the
    /// box's half diagonal squared; here it is the squared distance to the box itself (no
    /// light below is nearer), at least [`BOX_DISTANCE_FLOOR`] times the half diagonal
    /// squared: on the 100 rooms of `pathspace rooms` the light of the room a point is in gets
    /// 0.21 on the floor and 0.32 in the fog on average instead of 0.12 and 0.11, because
    /// the large clusters near the root no longer look alike from inside them (each a point
    /// inside its bounding sphere). Every angle is widened by the angle
    /// theta_u the box's bounding sphere subtends, so the bound holds for every light inside:
    /// zero only where no light below the node can send light to `p`. The angle differences
    /// are taken on cosines and sines (cos(a - b) = cos a cos b + sin a sin b), without
    /// inverse trigonometric functions: the descent evaluates this twice per level, in vector
    /// lanes with the same arithmetic (`Bounds4::importance`); this scalar form is its spec.
    #[inline]
    pub fn importance(&self, p: Vec3, n: Option<Vec3>) -> f32 {
        if self.power <= 0.0 {
            return 0.0;
        }
        let r2 = self.r2;
        let to_p = p - self.centre;
        let d2 = to_p.length_squared();
        // inside the bounding sphere every direction is possible
        // the squared distance to the box itself, at least a hundredth of r^2
        let d2_box = (p - p.clamp(self.bounds.min, self.bounds.max))
            .length_squared()
            .max(BOX_DISTANCE_FLOOR * r2)
            .max(f32::MIN_POSITIVE);
        if d2 <= r2 || d2 <= 0.0 {
            return self.power / d2_box;
        }
        let wi = to_p / d2.sqrt();
        let sin_u2 = (r2 / d2).min(1.0);
        let (sin_u, cos_u) = (sin_u2.sqrt(), (1.0 - sin_u2).sqrt());
        // emitter: the angle theta between axis and p, less the normals' spread theta_o and
        // the sphere's theta_u, clamped at zero
        let cos_w = self.axis.dot(wi).clamp(-1.0, 1.0);
        let (cos_o, sin_o) = (self.cos_o, self.sin_o);
        let cos_emit = if cos_w >= cos_o {
            1.0
        } else {
            let sin_w = (1.0 - cos_w * cos_w).max(0.0).sqrt();
            let cos_x = cos_w * cos_o + sin_w * sin_o;
            let sin_x = (sin_w * cos_o - cos_w * sin_o).max(0.0);
            if cos_x >= cos_u {
                1.0
            } else {
                cos_x * cos_u + sin_x * sin_u
            }
        };
        if cos_emit <= self.cos_e {
            return 0.0;
        }
        // receiver: the cosine at p, two-sided (transmission sees light from behind too)
        let cos_recv = match n {
            Some(n) => {
                let cos_i = n.dot(wi).abs().min(1.0);
                if cos_i >= cos_u {
                    1.0
                } else {
                    let sin_i = (1.0 - cos_i * cos_i).max(0.0).sqrt();
                    (cos_i * cos_u + sin_i * sin_u).max(0.0)
                }
            }
            None => 1.0,
        };
        self.power * cos_emit * cos_recv / d2_box
    }
}

/// The smallest cone this construction gives around two cones (axis, half-angle): the
/// half-angle covering both from an axis between them (Conty Estevez and Kulla 2018, sec. 4.1).
fn cone_union(a: (Vec3, f32), b: (Vec3, f32)) -> (Vec3, f32) {
    if b.1 > a.1 {
        return cone_union(b, a);
    }
    let between = a.0.dot(b.0).clamp(-1.0, 1.0).acos();
    if (between + b.1).min(PI) <= a.1 {
        return a;
    }
    let theta = 0.5 * (a.1 + between + b.1);
    if theta >= PI {
        return (a.0, PI);
    }
    // turn a's axis towards b's by theta - a's half-angle
    let ortho = b.0 - a.0 * a.0.dot(b.0);
    let Some(ortho) = ortho.try_normalize() else {
        return (a.0, PI);
    };
    let turn = theta - a.1;
    (a.0 * turn.cos() + ortho * turn.sin(), theta)
}

/// The least squared distance to a box, as a fraction of its half diagonal squared, in
/// [`LightBounds::importance`]: from inside a box its importance is large but finite.
pub const BOX_DISTANCE_FLOOR: f32 = 0.01;

#[derive(Clone, Copy, Debug)]
enum Node {
    /// Children at these indices; their bounds, and their children's, at this index of
    /// [`LightTree::sides`].
    Inner(u32, u32, u32),
    /// The light with this scene index.
    Leaf(u32),
}

/// The light hierarchy (Conty Estevez and Kulla 2018) over the scene's finite lights of
/// nonzero power, with a choice by power between it and the lights at infinity.
#[derive(Clone, Debug)]
pub struct LightTree {
    nodes: Vec<Node>,
    bounds: Vec<LightBounds>,
    /// For each inner node, the bounds of its two children and of one child's two children in
    /// vector lanes: (left, right, left's left, left's right) and (left, right, right's left,
    /// right's right); a child that is a leaf fills its lanes with its own bounds, which the
    /// descent does not read. The choice below a node and the one below the chosen child take
    /// one set of vector operations where the child is known (`pmf`), two where it is not.
    sides: Vec<[Bounds4; 2]>,
    /// For each scene light: its root-to-leaf trail (bit k: right child at depth k) and
    /// depth, or `None` when the tree does not hold it.
    trail: Vec<Option<(u64, u32)>>,
    /// The probability of choosing the tree rather than a light at infinity.
    p_tree: f32,
    /// The lights at infinity (scene indices) and their choice by power.
    infinite: Vec<u32>,
    infinite_distr: Option<Distribution1D>,
}

/// Below this depth the splits are at the median, so that a trail fits 64 bits for any
/// number of lights below 2^32 (middle splits alone could go as deep as there are lights, on
/// centres that halve in spacing at every split).
const MIDDLE_SPLIT_DEPTH: u32 = 32;

impl LightTree {
    /// The tree over `lights` (their powers as [`Light::power`] gives them for a scene of
    /// radius `radius`, the same as the power selection's); `None` when no light has power.
    pub fn build(lights: &[Light], prims: &[Primitive], radius: f32) -> Option<Self> {
        let powers: Vec<f32> = lights.iter().map(|l| l.power(radius).max(0.0)).collect();
        let mut leaves: Vec<(u32, LightBounds)> = Vec::new();
        let mut infinite = Vec::new();
        for (i, l) in lights.iter().enumerate() {
            if powers[i] <= 0.0 {
                continue;
            }
            match LightBounds::of(l, prims, powers[i]) {
                Some(b) => leaves.push((i as u32, b)),
                None => infinite.push(i as u32),
            }
        }
        let finite: f64 = leaves.iter().map(|(_, b)| b.power as f64).sum();
        let at_infinity: f64 = infinite.iter().map(|&i| powers[i as usize] as f64).sum();
        if finite + at_infinity <= 0.0 {
            return None;
        }
        let mut tree = LightTree {
            nodes: Vec::with_capacity(2 * leaves.len()),
            bounds: Vec::with_capacity(2 * leaves.len()),
            sides: Vec::with_capacity(leaves.len()),
            trail: vec![None; lights.len()],
            p_tree: (finite / (finite + at_infinity)) as f32,
            infinite_distr: (!infinite.is_empty()).then(|| {
                Distribution1D::new(
                    &infinite
                        .iter()
                        .map(|&i| powers[i as usize])
                        .collect::<Vec<_>>(),
                )
            }),
            infinite,
        };
        if !leaves.is_empty() {
            tree.split(&mut leaves, 0, 0);
        }
        Some(tree)
    }

    /// Builds the subtree over `leaves` (at `depth`, reached by `trail`); returns its index.
    /// Split at the middle of the widest axis of the lights' centres (at the median where
    /// that leaves a side empty), ties by light index, so that the tree depends on nothing
    /// but the scene. The middle keeps a regular grid of lights in compact halves, where the
    /// median cut a row of three rooms' lights across (the light of a room then lost to its
    /// neighbour's in `tests/spec/scene/light_tree.rs`).
    fn split(&mut self, leaves: &mut [(u32, LightBounds)], depth: u32, trail: u64) -> u32 {
        let at = self.nodes.len() as u32;
        if leaves.len() == 1 {
            let (light, b) = leaves[0];
            self.nodes.push(Node::Leaf(light));
            self.bounds.push(b);
            self.trail[light as usize] = Some((trail, depth));
            return at;
        }
        let centres = leaves
            .iter()
            .fold(Aabb::EMPTY, |a, (_, b)| a.grow(b.bounds.centroid()));
        let axis = centres.extent().max_position();
        leaves.sort_by(|(ia, a), (ib, b)| {
            a.bounds.centroid()[axis]
                .total_cmp(&b.bounds.centroid()[axis])
                .then(ia.cmp(ib))
        });
        self.nodes.push(Node::Leaf(u32::MAX));
        self.bounds.push(leaves[0].1);
        let middle = centres.centroid()[axis];
        let below = leaves.partition_point(|(_, b)| b.bounds.centroid()[axis] < middle);
        let mid = if below == 0 || below == leaves.len() || depth >= MIDDLE_SPLIT_DEPTH {
            leaves.len() / 2
        } else {
            below
        };
        let (left, right) = leaves.split_at_mut(mid);
        let l = self.split(left, depth + 1, trail);
        let r = self.split(right, depth + 1, trail | (1 << depth));
        let (bl, br) = (&self.bounds[l as usize], &self.bounds[r as usize]);
        self.nodes[at as usize] = Node::Inner(l, r, self.sides.len() as u32);
        let children = |c: u32| match self.nodes[c as usize] {
            Node::Inner(cl, cr, _) => [&self.bounds[cl as usize], &self.bounds[cr as usize]],
            Node::Leaf(_) => [&self.bounds[c as usize]; 2],
        };
        let ([ll, lr], [rl, rr]) = (children(l), children(r));
        self.sides.push([
            Bounds4::new([bl, br, ll, lr]),
            Bounds4::new([bl, br, rl, rr]),
        ]);
        self.bounds[at as usize] = LightBounds::union(bl, br);
        at
    }

    /// The probability of the left child of inner node (`l`, `r`) whose children have
    /// importances `il` and `ir` at the shading point: by importance, or by power where neither
    /// child's bound reaches the point (a looser bound above may have led here), so that every
    /// descent ends at a light and the probabilities sum to one.
    #[inline]
    fn p_left(&self, l: u32, r: u32, il: f32, ir: f32) -> f32 {
        let sum = il + ir;
        if sum > 0.0 && sum.is_finite() {
            il / sum
        } else {
            let (bl, br) = (&self.bounds[l as usize], &self.bounds[r as usize]);
            bl.power / (bl.power + br.power)
        }
    }

    /// For tests: whether at `p` (normal `n`) every inner node's importances in lanes
    /// (`Bounds4::importance`, of its children and of its grandchildren) are bit for bit
    /// [`LightBounds::importance`] of those nodes.
    #[doc(hidden)]
    pub fn lanes_match_scalar(&self, p: Vec3, n: Option<Vec3>) -> bool {
        let (pl, nl) = (splat3(p), n.map(splat3));
        self.nodes.iter().all(|node| {
            let Node::Inner(l, r, pair) = *node else {
                return true;
            };
            let scalar = |c: u32| self.bounds[c as usize].importance(p, n).to_bits();
            let below = |c: u32| match self.nodes[c as usize] {
                Node::Inner(cl, cr, _) => Some([scalar(cl), scalar(cr)]),
                Node::Leaf(_) => None,
            };
            [l, r].iter().enumerate().all(|(side, &c)| {
                let v = self.sides[pair as usize][side].importance(&pl, nl.as_ref());
                let v = v.to_array().map(f32::to_bits);
                v[..2] == [scalar(l), scalar(r)] && below(c).is_none_or(|g| v[2..] == g)
            })
        })
    }

    /// A light for `p` (normal `n`) from `u`, its probability and `u` rescaled.
    pub fn sample(&self, p: Vec3, n: Option<Vec3>, mut u: f32) -> Option<(usize, f32, f32)> {
        let mut pmf = 1.0;
        if let Some(d) = &self.infinite_distr {
            if u >= self.p_tree {
                let v = ((u - self.p_tree) / (1.0 - self.p_tree)).min(ONE_MINUS_EPSILON);
                let (k, q, rem) = d.sample(v);
                return Some((self.infinite[k] as usize, (1.0 - self.p_tree) * q, rem));
            }
            pmf = self.p_tree;
            u = (u / self.p_tree).min(ONE_MINUS_EPSILON);
        }
        let (p, n) = (splat3(p), n.map(splat3));
        let mut node = 0u32;
        // two levels per step: the grandchildren's importances do not depend on the choice
        // between the children, so both sets are computed side by side
        while let Node::Inner(l, r, pair) = *self.nodes.get(node as usize)? {
            let [to_l, to_r] = &self.sides[pair as usize];
            let a = to_l.importance(&p, n.as_ref());
            // below a leaf there is nothing to compute
            let b = match self.nodes[r as usize] {
                Node::Inner(..) => to_r.importance(&p, n.as_ref()),
                Node::Leaf(_) => a,
            };
            let left = choose(&mut u, &mut pmf, self.p_left(l, r, a.x, a.y));
            node = if left { l } else { r };
            let Node::Inner(cl, cr, _) = self.nodes[node as usize] else {
                break;
            };
            let g = if left { a } else { b };
            node = if choose(&mut u, &mut pmf, self.p_left(cl, cr, g.z, g.w)) {
                cl
            } else {
                cr
            };
        }
        match self.nodes[node as usize] {
            Node::Leaf(light) => Some((light as usize, pmf, u)),
            Node::Inner(..) => None,
        }
    }

    /// The probability that [`LightTree::sample`] picks scene light `light` at `p` (normal
    /// `n`): the same choices, followed down the light's trail.
    pub fn pmf(&self, p: Vec3, n: Option<Vec3>, light: u32) -> f32 {
        if let Some(k) = self.infinite.iter().position(|&i| i == light) {
            let d = self
                .infinite_distr
                .as_ref()
                .expect("lights at infinity have a distribution");
            return (1.0 - self.p_tree) * d.pmf(k);
        }
        let Some((trail, depth)) = self.trail[light as usize] else {
            return 0.0;
        };
        let mut pmf = if self.infinite_distr.is_some() {
            self.p_tree
        } else {
            1.0
        };
        let (p, n) = (splat3(p), n.map(splat3));
        let mut node = 0u32;
        // two levels per set of vector operations: the trail names the child in advance
        let mut v = Vec4::ZERO;
        for k in 0..depth {
            let Node::Inner(l, r, pair) = self.nodes[node as usize] else {
                return 0.0;
            };
            let right = trail & (1 << k) != 0;
            let (il, ir) = if k % 2 == 0 {
                v = self.sides[pair as usize][right as usize].importance(&p, n.as_ref());
                (v.x, v.y)
            } else {
                (v.z, v.w)
            };
            let pl = self.p_left(l, r, il, ir);
            if right {
                pmf *= 1.0 - pl;
                node = r;
            } else {
                pmf *= pl;
                node = l;
            }
        }
        pmf
    }

    /// The number of nodes (for `info` and tests).
    pub fn node_count(&self) -> usize {
        self.nodes.len()
    }
}

/// One choice of the descent with left probability `pl`: whether left, with `u` rescaled and
/// the choice's probability multiplied into `pmf`.
#[inline]
fn choose(u: &mut f32, pmf: &mut f32, pl: f32) -> bool {
    if *u < pl {
        *pmf *= pl;
        *u = (*u / pl).min(ONE_MINUS_EPSILON);
        true
    } else {
        *pmf *= 1.0 - pl;
        *u = ((*u - pl) / (1.0 - pl)).min(ONE_MINUS_EPSILON);
        false
    }
}

/// A point or direction with each coordinate in all four lanes.
type Lanes = [Vec4; 3];

fn splat3(v: Vec3) -> Lanes {
    [Vec4::splat(v.x), Vec4::splat(v.y), Vec4::splat(v.z)]
}

/// The bounds of four nodes of the tree, field by field in vector lanes, so that the descent
/// computes four importances with one set of four-lane operations: [`LightBounds::importance`]'s
/// arithmetic lane for lane, its branches as selects, so the values are bit for bit the same.
#[derive(Clone, Copy, Debug)]
struct Bounds4 {
    min: Lanes,
    max: Lanes,
    centre: Lanes,
    axis: Lanes,
    power: Vec4,
    cos_o: Vec4,
    sin_o: Vec4,
    cos_e: Vec4,
    r2: Vec4,
    /// [`BOX_DISTANCE_FLOOR`] times `r2`, the same product the scalar form takes.
    floor: Vec4,
}

impl Bounds4 {
    fn new(b: [&LightBounds; 4]) -> Self {
        let f = |g: fn(&LightBounds) -> f32| Vec4::from_array(b.map(g));
        Bounds4 {
            min: [
                f(|b| b.bounds.min.x),
                f(|b| b.bounds.min.y),
                f(|b| b.bounds.min.z),
            ],
            max: [
                f(|b| b.bounds.max.x),
                f(|b| b.bounds.max.y),
                f(|b| b.bounds.max.z),
            ],
            centre: [f(|b| b.centre.x), f(|b| b.centre.y), f(|b| b.centre.z)],
            axis: [f(|b| b.axis.x), f(|b| b.axis.y), f(|b| b.axis.z)],
            power: f(|b| b.power),
            cos_o: f(|b| b.cos_o),
            sin_o: f(|b| b.sin_o),
            cos_e: f(|b| b.cos_e),
            r2: f(|b| b.r2),
            floor: f(|b| BOX_DISTANCE_FLOOR * b.r2),
        }
    }

    /// The four nodes' [`LightBounds::importance`] at `p` (normal `n`), lane by lane. Each `max`/`min` with a constant takes the constant as its second
    /// operand, which a NaN in the first gives back as `f32::max`/`f32::min` do; the cosine's
    /// clamp keeps a NaN as `f32::clamp` does.
    #[inline]
    fn importance(&self, p: &Lanes, n: Option<&Lanes>) -> Vec4 {
        let (zero, one) = (Vec4::ZERO, Vec4::ONE);
        let to_p = sub3(p, &self.centre);
        let d2 = dot3(&to_p, &to_p);
        let clamped = [0, 1, 2].map(|k| p[k].max(self.min[k]).min(self.max[k]));
        let off = sub3(p, &clamped);
        let d2_box = dot3(&off, &off)
            .max(self.floor)
            .max(Vec4::splat(f32::MIN_POSITIVE));
        let inside = d2.cmple(self.r2) | d2.cmple(zero);
        let len = sqrt4(d2);
        let wi = [to_p[0] / len, to_p[1] / len, to_p[2] / len];
        let sin_u2 = (self.r2 / d2).min(one);
        let (sin_u, cos_u) = (sqrt4(sin_u2), sqrt4(one - sin_u2));
        let cos_w = one.min(Vec4::NEG_ONE.max(dot3(&self.axis, &wi)));
        let (cos_o, sin_o) = (self.cos_o, self.sin_o);
        let sin_w = sqrt4((one - cos_w * cos_w).max(zero));
        let cos_x = cos_w * cos_o + sin_w * sin_o;
        let sin_x = (sin_w * cos_o - cos_w * sin_o).max(zero);
        let cos_emit = Vec4::select(
            cos_w.cmpge(cos_o) | cos_x.cmpge(cos_u),
            one,
            cos_x * cos_u + sin_x * sin_u,
        );
        let cos_recv = match n {
            Some(n) => {
                let cos_i = dot3(n, &wi).abs().min(one);
                let sin_i = sqrt4((one - cos_i * cos_i).max(zero));
                let cone = (cos_i * cos_u + sin_i * sin_u).max(zero);
                Vec4::select(cos_i.cmpge(cos_u), one, cone)
            }
            None => one,
        };
        // inside the bounding sphere: power / d2_box, the same value times two exact ones
        let cos_emit = Vec4::select(inside, one, cos_emit);
        let cos_recv = Vec4::select(inside, one, cos_recv);
        let value = self.power * cos_emit * cos_recv / d2_box;
        let none = self.power.cmple(zero) | (!inside & cos_emit.cmple(self.cos_e));
        Vec4::select(none, zero, value)
    }
}

fn sub3(a: &Lanes, b: &Lanes) -> Lanes {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

/// `Vec3::dot`'s order: (x x' + y y') + z z'.
fn dot3(a: &Lanes, b: &Lanes) -> Vec4 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// The square root of each lane, correctly rounded as `f32::sqrt` is.
#[inline]
fn sqrt4(v: Vec4) -> Vec4 {
    #[cfg(target_arch = "x86_64")]
    {
        // SAFETY: SSE is part of every x86_64 target
        Vec4::from(unsafe { std::arch::x86_64::_mm_sqrt_ps(v.into()) })
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        Vec4::new(v.x.sqrt(), v.y.sqrt(), v.z.sqrt(), v.w.sqrt())
    }
}
