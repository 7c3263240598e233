//! Regions: where the piecewise-constant estimates of L_i and W_i change (Kristensen 2010,
//! sec. 5.2.3).
//!
//! Particles are split into surface and volume sets, and each set is clustered by k-means into
//! region centres. On surfaces the distance of eq. (5.16),
//!   dist(x_s, x_c) = alpha |x_s - x_c| + (1 - n(x_s) . n(x_c)),
//! keeps walls of different orientation apart; in the medium the distance is Euclidean and a
//! region never holds points of two media. A point's region is found with a kd-tree: on
//! surfaces the `candidates` nearest centres in Euclidean distance, then the smallest eq.
//! (5.16) distance among them (the thesis describes a nearest-centre query; the candidate
//! refinement is this crate's choice); in a medium the nearest centre of the same medium.
//!
//! Everything is deterministic: the initial centres are particles drawn by a seeded stream,
//! the iteration count is fixed, ties break by index.
//! Book: "Enlightened local path sampling: guiding".

use glam::Vec3;
use rayon::prelude::*;

use crate::math::Sampler;

/// A point to cluster or to look up: position, unit normal (zero in a medium), medium id
/// (for volume points).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RegionPoint {
    pub p: Vec3,
    pub n: Vec3,
    pub medium: Option<u32>,
}

/// The parameters of the clustering (the thesis gives none but K; these are this crate's
/// choices, see the book's DEVIATION list).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RegionParams {
    /// Centres K for the whole set (split between surface and volume points in proportion to
    /// their counts, at least one for a non-empty set).
    pub regions: usize,
    /// alpha of eq. (5.16), per unit length (default [`DEFAULT_ALPHA_SCALE`] / scene radius).
    pub alpha: f32,
    /// Lloyd iterations (fixed, so the result does not depend on a convergence test).
    pub iterations: u32,
    /// Euclidean candidates refined by eq. (5.16) on surfaces (1..=[`MAX_CANDIDATES`]).
    pub candidates: usize,
    /// Seed of the initial centres.
    pub seed: u64,
    /// At most this many points are clustered (an even stride through the set); all of them
    /// are projected into the maps afterwards.
    pub cluster_sample: usize,
}

/// alpha = this / scene radius: a normal turned by 90 degrees costs as much as a twentieth of
/// the scene's radius.
pub const DEFAULT_ALPHA_SCALE: f32 = 20.0;
/// The thesis's K for the door scene was 16384; ours defaults to fewer particles and regions.
pub const DEFAULT_REGIONS: usize = 512;
/// Lloyd iterations by default.
pub const DEFAULT_ITERATIONS: u32 = 8;
/// Surface lookups refine this many Euclidean neighbours by eq. (5.16).
pub const DEFAULT_CANDIDATES: usize = 4;
/// Points clustered at most by default (the thesis clustered about 10^6).
pub const DEFAULT_CLUSTER_SAMPLE: usize = 65_536;
/// Upper bound of `candidates` (a fixed-size buffer: lookups do not allocate).
pub const MAX_CANDIDATES: usize = 16;

impl RegionParams {
    /// The defaults for a scene of bounding radius `radius`.
    pub fn for_radius(radius: f32) -> Self {
        RegionParams {
            regions: DEFAULT_REGIONS,
            alpha: DEFAULT_ALPHA_SCALE / radius.max(1e-6),
            iterations: DEFAULT_ITERATIONS,
            candidates: DEFAULT_CANDIDATES,
            seed: 0x5245_4749_4f4e,
            cluster_sample: DEFAULT_CLUSTER_SAMPLE,
        }
    }
}

/// Eq. (5.16): the surface distance between a point and a centre.
// ANCHOR: surface_distance
#[inline]
pub fn surface_distance(alpha: f32, xs: Vec3, ns: Vec3, xc: Vec3, nc: Vec3) -> f32 {
    alpha * (xs - xc).length() + (1.0 - ns.dot(nc))
}
// ANCHOR_END: surface_distance

/// A static 3-d tree over points (implicit layout: the median of each range is its node).
#[derive(Clone, Debug, Default)]
pub struct KdTree {
    pts: Vec<Vec3>,
    ids: Vec<u32>,
    axis: Vec<u8>,
}

impl KdTree {
    /// Builds over `points`; node ids are the indices into `points`.
    pub fn build(points: &[Vec3]) -> Self {
        let mut items: Vec<(Vec3, u32)> = points
            .iter()
            .enumerate()
            .map(|(i, &p)| (p, i as u32))
            .collect();
        let mut axis = vec![0u8; items.len()];
        Self::build_range(&mut items, &mut axis);
        KdTree {
            pts: items.iter().map(|x| x.0).collect(),
            ids: items.iter().map(|x| x.1).collect(),
            axis,
        }
    }

    fn build_range(items: &mut [(Vec3, u32)], axis: &mut [u8]) {
        if items.len() <= 1 {
            return;
        }
        let (lo, hi) = items.iter().fold(
            (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY)),
            |(lo, hi), x| (lo.min(x.0), hi.max(x.0)),
        );
        let ext = hi - lo;
        let a = if ext.x >= ext.y && ext.x >= ext.z {
            0
        } else if ext.y >= ext.z {
            1
        } else {
            2
        };
        let mid = items.len() / 2;
        items.select_nth_unstable_by(mid, |p, q| {
            p.0[a]
                .partial_cmp(&q.0[a])
                .unwrap_or(std::cmp::Ordering::Equal)
                .then(p.1.cmp(&q.1))
        });
        axis[mid] = a as u8;
        let (left, right) = items.split_at_mut(mid);
        let (al, ar) = axis.split_at_mut(mid);
        Self::build_range(left, al);
        Self::build_range(&mut right[1..], &mut ar[1..]);
    }

    pub fn len(&self) -> usize {
        self.pts.len()
    }

    pub fn is_empty(&self) -> bool {
        self.pts.is_empty()
    }

    pub fn bytes(&self) -> usize {
        self.pts.len() * (std::mem::size_of::<Vec3>() + 5)
    }

    /// The `k` nearest points to `q` (Euclidean), sorted by distance, into `out`; returns how
    /// many were found. Ties break by id, so the result is deterministic.
    pub fn nearest(&self, q: Vec3, out: &mut [(f32, u32)]) -> usize {
        let k = out.len();
        let mut count = 0;
        if k > 0 {
            self.knn(0, self.pts.len(), q, out, &mut count);
        }
        count
    }

    fn knn(&self, lo: usize, hi: usize, q: Vec3, out: &mut [(f32, u32)], count: &mut usize) {
        if lo >= hi {
            return;
        }
        let mid = lo + (hi - lo) / 2;
        let p = self.pts[mid];
        let d2 = (p - q).length_squared();
        let id = self.ids[mid];
        let k = out.len();
        if *count < k || (d2, id) < out[k - 1] {
            // insertion into the sorted buffer
            let mut i = (*count).min(k - 1);
            while i > 0 && (d2, id) < out[i - 1] {
                out[i] = out[i - 1];
                i -= 1;
            }
            out[i] = (d2, id);
            *count = (*count + 1).min(k);
        }
        if hi - lo == 1 {
            return;
        }
        let a = self.axis[mid] as usize;
        let diff = q[a] - p[a];
        let (first, second) = if diff < 0.0 {
            ((lo, mid), (mid + 1, hi))
        } else {
            ((mid + 1, hi), (lo, mid))
        };
        self.knn(first.0, first.1, q, out, count);
        if *count < k || diff * diff <= out[k - 1].0 {
            self.knn(second.0, second.1, q, out, count);
        }
    }
}

/// Surface regions: centres with normals and their tree.
#[derive(Clone, Debug, Default)]
struct SurfaceSet {
    p: Vec<Vec3>,
    n: Vec<Vec3>,
    tree: KdTree,
}

/// The volume regions of one medium.
#[derive(Clone, Debug)]
struct VolumeSet {
    medium: u32,
    /// Id of this set's first region.
    first: u32,
    tree: KdTree,
}

/// The regions of one quantity: surface regions are ids 0 .. surface_count, volume regions
/// follow.
#[derive(Clone, Debug, Default)]
pub struct Regions {
    params: Option<RegionParams>,
    surface: SurfaceSet,
    volume: Vec<VolumeSet>,
    count: usize,
}

impl Regions {
    /// Clusters `points` (surface points have a non-zero normal; volume points a medium).
    pub fn build(points: &[RegionPoint], params: RegionParams) -> Self {
        let stride = points.len().div_ceil(params.cluster_sample.max(1)).max(1);
        let (surf, vol): (Vec<RegionPoint>, Vec<RegionPoint>) = points
            .iter()
            .step_by(stride)
            .copied()
            .filter(|x| x.p.is_finite())
            .partition(|x| x.n != Vec3::ZERO || x.medium.is_none());
        let total = (surf.len() + vol.len()).max(1);
        let share = |n: usize| -> usize {
            if n == 0 {
                0
            } else {
                ((params.regions as f64 * n as f64 / total as f64).round() as usize).clamp(1, n)
            }
        };
        let mut sampler = Sampler::new(params.seed, 0, 0);
        // surfaces: normals default to +z for a point that came without one (not expected)
        let surf: Vec<RegionPoint> = surf
            .into_iter()
            .map(|mut x| {
                x.n = x.n.normalize_or(Vec3::Z);
                x
            })
            .collect();
        let surface = kmeans_surface(&surf, share(surf.len()), &params, &mut sampler);
        let mut count = surface.p.len();
        let mut media: Vec<u32> = vol.iter().filter_map(|x| x.medium).collect();
        media.sort_unstable();
        media.dedup();
        let mut volume = Vec::new();
        for m in media {
            let pts: Vec<Vec3> = vol
                .iter()
                .filter(|x| x.medium == Some(m))
                .map(|x| x.p)
                .collect();
            let k = share(pts.len());
            let centres = kmeans_euclidean(&pts, k, params.iterations, &mut sampler);
            volume.push(VolumeSet {
                medium: m,
                first: count as u32,
                tree: KdTree::build(&centres),
            });
            count += centres.len();
        }
        Regions {
            params: Some(params),
            surface,
            volume,
            count,
        }
    }

    /// Number of regions.
    pub fn len(&self) -> usize {
        self.count
    }

    pub fn is_empty(&self) -> bool {
        self.count == 0
    }

    /// Surface regions (ids 0 .. this).
    pub fn surface_len(&self) -> usize {
        self.surface.p.len()
    }

    /// Bytes of the centres and trees.
    pub fn bytes(&self) -> usize {
        self.surface.p.len() * 24
            + self.surface.tree.bytes()
            + self.volume.iter().map(|v| v.tree.bytes()).sum::<usize>()
    }

    /// The region of a surface point with unit normal `n`: the smallest eq. (5.16) distance
    /// among the Euclidean candidates.
    // ANCHOR: region_lookup
    pub fn surface_region(&self, p: Vec3, n: Vec3) -> Option<u32> {
        let params = self.params?;
        if self.surface.tree.is_empty() {
            return None;
        }
        let mut buf = [(0.0f32, 0u32); MAX_CANDIDATES];
        let k = params.candidates.clamp(1, MAX_CANDIDATES);
        let found = self.surface.tree.nearest(p, &mut buf[..k]);
        let mut best: Option<(f32, u32)> = None;
        for &(_, id) in &buf[..found] {
            let c = id as usize;
            let d = surface_distance(params.alpha, p, n, self.surface.p[c], self.surface.n[c]);
            if best.is_none_or(|b| (d, id) < b) {
                best = Some((d, id));
            }
        }
        best.map(|b| b.1)
    }

    /// The region of a point in medium `medium`: the nearest centre of that medium.
    pub fn volume_region(&self, p: Vec3, medium: u32) -> Option<u32> {
        let set = self.volume.iter().find(|v| v.medium == medium)?;
        let mut buf = [(0.0f32, 0u32); 1];
        (set.tree.nearest(p, &mut buf) == 1).then(|| set.first + buf[0].1)
    }
    // ANCHOR_END: region_lookup

    /// The region of a point: surface when `n` is non-zero, else volume.
    pub fn region_of(&self, x: &RegionPoint) -> Option<u32> {
        match (x.n != Vec3::ZERO, x.medium) {
            (true, _) => self.surface_region(x.p, x.n.normalize_or(Vec3::Z)),
            (false, Some(m)) => self.volume_region(x.p, m),
            (false, None) => None,
        }
    }
}

/// K distinct indices of `n` drawn by a partial Fisher-Yates shuffle (deterministic).
fn initial_indices(n: usize, k: usize, sampler: &mut Sampler) -> Vec<usize> {
    let mut idx: Vec<usize> = (0..n).collect();
    for i in 0..k.min(n) {
        let j = i + sampler.next_index(n - i);
        idx.swap(i, j);
    }
    idx.truncate(k.min(n));
    idx
}

/// Lloyd's k-means with eq. (5.16) assignments (Euclidean candidates from a tree over the
/// current centres, refined by eq. 5.16, as in the lookup) and centres updated to the mean
/// position and the renormalized mean normal. Empty clusters keep their centre.
// ANCHOR: kmeans
fn kmeans_surface(
    pts: &[RegionPoint],
    k: usize,
    params: &RegionParams,
    sampler: &mut Sampler,
) -> SurfaceSet {
    if k == 0 || pts.is_empty() {
        return SurfaceSet::default();
    }
    let init = initial_indices(pts.len(), k, sampler);
    let mut set = SurfaceSet {
        p: init.iter().map(|&i| pts[i].p).collect(),
        n: init.iter().map(|&i| pts[i].n).collect(),
        tree: KdTree::default(),
    };
    for it in 0..=params.iterations {
        set.tree = KdTree::build(&set.p);
        if it == params.iterations {
            break;
        }
        let regions = Regions {
            params: Some(*params),
            surface: set.clone(),
            volume: Vec::new(),
            count: set.p.len(),
        };
        let assign: Vec<Option<u32>> = pts
            .par_iter()
            .map(|x| regions.surface_region(x.p, x.n))
            .collect();
        let mut sum_p = vec![glam::DVec3::ZERO; k];
        let mut sum_n = vec![glam::DVec3::ZERO; k];
        let mut cnt = vec![0usize; k];
        for (x, a) in pts.iter().zip(&assign) {
            if let Some(c) = a {
                let c = *c as usize;
                sum_p[c] += x.p.as_dvec3();
                sum_n[c] += x.n.as_dvec3();
                cnt[c] += 1;
            }
        }
        for c in 0..k {
            if cnt[c] > 0 {
                set.p[c] = (sum_p[c] / cnt[c] as f64).as_vec3();
                let n = sum_n[c].as_vec3();
                if n.length_squared() > 1e-12 {
                    set.n[c] = n.normalize();
                }
            }
        }
    }
    set
}
// ANCHOR_END: kmeans

/// Lloyd's k-means with Euclidean distance (the volume points of one medium).
fn kmeans_euclidean(pts: &[Vec3], k: usize, iterations: u32, sampler: &mut Sampler) -> Vec<Vec3> {
    if k == 0 || pts.is_empty() {
        return Vec::new();
    }
    let mut centres: Vec<Vec3> = initial_indices(pts.len(), k, sampler)
        .into_iter()
        .map(|i| pts[i])
        .collect();
    for _ in 0..iterations {
        let tree = KdTree::build(&centres);
        let assign: Vec<u32> = pts
            .par_iter()
            .map(|&p| {
                let mut b = [(0.0f32, 0u32); 1];
                tree.nearest(p, &mut b);
                b[0].1
            })
            .collect();
        let mut sum = vec![glam::DVec3::ZERO; k];
        let mut cnt = vec![0usize; k];
        for (p, &a) in pts.iter().zip(&assign) {
            sum[a as usize] += p.as_dvec3();
            cnt[a as usize] += 1;
        }
        for c in 0..k {
            if cnt[c] > 0 {
                centres[c] = (sum[c] / cnt[c] as f64).as_vec3();
            }
        }
    }
    centres
}
