//! The one transport kernel every method shares: a ray followed through media and index-matched
//! null boundaries (`Bsdf::Null`), cut into the medium segments between crossings and ended by
//! the first non-null surface, escape, or the end of the query range. Propagation (Table 1's
//! free flights per segment), `Scene::transmittance` (tau of eq. 3 times V), `Scene::edge`,
//! MLT's retracing and SMC's ray marching all iterate it, so the crossing rule (the ray is
//! continued past each boundary with a `t_min`, never re-spawned) exists once.
//! Book: "The transport equations", section "Why the ray is continued, not re-spawned, at a null
//! boundary".

use crate::geometry::bvh::tie_reach;
use crate::geometry::{Bvh, Hit, Ray};

use super::Scene;

/// Relative step past a crossed null boundary before the next intersection query, so the same
/// face is not found again (its t carries a few ulps of error). Coplanar opaque faces are not
/// skipped: the BVH's tie-break returns them instead of the null face.
const NULL_CROSSING_EPSILON: f32 = 1e-6;

#[inline]
fn past(t: f32, ray: &Ray) -> f32 {
    t + NULL_CROSSING_EPSILON * (1.0 + t + ray.o.abs().max_element())
}

/// What [`Segments::next_before`] found.
#[derive(Clone, Copy, Debug)]
pub enum Before {
    /// The segment [`Iterator::next`] gives (`None`: the walk is over or trapped).
    Segment(Option<Segment>),
    /// No hit before the limit: the next segment ends past it.
    Beyond,
}

/// Crossing more null boundaries than this along one ray means the geometry traps the ray.
pub const MAX_NULL_CROSSINGS: usize = 256;

/// What ends a medium segment.
#[derive(Clone, Copy, Debug)]
pub enum SegmentEnd {
    /// Nothing within the query range: the ray escapes (or reaches the end of the range).
    Open,
    /// A null boundary, crossed: the next segment starts here, in the medium behind it.
    Null(Hit),
    /// A non-null surface: the ray ends here.
    Surface(Hit),
}

/// One stretch of the ray in one medium, from `t0` to `t1` (ray parameters; `t0` of the first
/// segment is `-lead`, the vertex itself, and `t1` of an open segment is the range's end).
#[derive(Clone, Copy, Debug)]
pub struct Segment {
    pub t0: f32,
    pub t1: f32,
    /// The medium of the stretch (`None`: vacuum).
    pub medium: Option<u32>,
    /// True for the segment that starts at the ray's origin.
    pub first: bool,
    pub end: SegmentEnd,
}

/// The medium segments of a ray through null boundaries, in order along the ray. The iteration
/// ends after a segment ending `Open` or at a `Surface`; it also ends (without such a segment)
/// after [`MAX_NULL_CROSSINGS`] crossings, which every caller treats as a trapped ray.
pub struct Segments<'a> {
    scene: &'a Scene,
    /// The tree the queries run in: the scene's, or its null boundaries alone.
    bvh: &'a Bvh,
    ray: Ray,
    medium: Option<u32>,
    t_start: f32,
    t_min: f32,
    /// The intersection queries' range end.
    t_max: f32,
    /// Where an open segment ends (`t_max`, or beyond it for an edge measured to its true end).
    t_open: f32,
    queries: usize,
    done: bool,
    /// Known to meet nothing up to `t_max` ([`Segments::clear_ahead`]): no query is asked.
    clear: bool,
}

impl<'a> Segments<'a> {
    /// The segments of `ray` starting in `medium`, intersection queries up to `t_max`.
    #[inline]
    pub fn new(scene: &'a Scene, ray: Ray, medium: Option<u32>, t_max: f32) -> Self {
        Segments {
            scene,
            bvh: &scene.bvh,
            ray,
            medium,
            t_start: 0.0,
            t_min: 0.0,
            t_max,
            t_open: t_max,
            queries: 0,
            done: false,
            clear: false,
        }
    }

    /// The first segment starts `lead` before the (lifted) origin, at the vertex itself, so
    /// medium segments are measured between true end points.
    #[inline]
    pub fn lead(mut self, lead: f32) -> Self {
        self.t_start = -lead;
        self
    }

    /// An open last segment ends at `t_open` instead of `t_max` (the edge's true end point
    /// behind its lifted one).
    #[inline]
    pub fn open_end(mut self, t_open: f32) -> Self {
        self.t_open = t_open;
        self
    }

    /// Queries only the null boundaries ([`Scene::boundary_bvh`]), for a ray an any-hit query
    /// has shown to meet no opaque surface within `t_max`: the closest hit among boundaries is
    /// then the closest hit of all (no opaque face is near enough to win a tie), so the
    /// segments are the ones the whole tree gives, for a fraction of the queries' cost.
    #[inline]
    pub fn boundaries_only(mut self) -> Self {
        self.bvh = &self.scene.boundary_bvh;
        self
    }

    /// For a ray an any-hit query has shown to meet nothing within `t_max`, opaque or null
    /// ([`crate::geometry::bvh::Passage::Clear`]): one open segment, found without a query
    /// (the one [`Segments::boundaries_only`] would find after a query that hits nothing).
    #[inline]
    pub fn clear_ahead(mut self) -> Self {
        self.clear = true;
        self
    }

    /// With `from_camera`, queries the scene as the camera sees it before its first scattering
    /// vertex ([`Scene::camera_bvh`]): with `hide_emitters`, emitter shapes are transparent,
    /// index-matched and no medium boundary (Mitsuba 3.9.1's `skip_area_emitters`, used by
    /// `path`, `volpath` and `volpathmis` while the depth is 0). A no-op otherwise.
    #[inline]
    pub fn from_camera(mut self, from_camera: bool) -> Self {
        if let (true, Some(b)) = (from_camera, &self.scene.camera_bvh) {
            self.bvh = b;
        }
        self
    }

    /// The ray the queries run along.
    #[inline]
    pub fn ray(&self) -> &Ray {
        &self.ray
    }

    /// Where the next segment starts (a ray parameter).
    #[inline]
    pub fn start(&self) -> f32 {
        self.t_start
    }

    /// Whether the next segment starts at the ray's origin.
    #[inline]
    pub fn first(&self) -> bool {
        self.queries == 0
    }

    /// The medium of the next segment (`None`: vacuum).
    #[inline]
    pub fn medium(&self) -> Option<u32> {
        self.medium
    }

    /// [`Iterator::next`] for a caller that has drawn a collision at distance `t` from the
    /// next segment's start (a free flight) and needs the surfaces only if one comes first:
    /// the query stops a little past the collision, so the tree is not searched beyond it.
    /// `Beyond` when nothing lies before that point, and then the segment `next` would give
    /// is longer than `t` in f32 (`t < t1 - t0`); otherwise the segment `next` gives. A hit
    /// whose tie-break could involve a primitive past the query's end (within two tie windows
    /// of it) is looked up again without the limit.
    #[inline]
    pub fn next_before(&mut self, t: f32) -> Before {
        // past the collision by more than rounding: a hit at or beyond `limit` ends a segment
        // whose f32 length exceeds t
        let limit = self.t_start + t + 1e-5 * (1.0 + self.t_start.abs() + t);
        if self.done || self.queries >= MAX_NULL_CROSSINGS || limit.is_nan() || limit >= self.t_max
        {
            return Before::Segment(self.next());
        }
        match self.query(limit) {
            None => Before::Beyond,
            Some(hit) if tie_reach(tie_reach(hit.t)) < limit => {
                Before::Segment(Some(self.segment_to(Some(hit))))
            }
            Some(_) => Before::Segment(self.next()),
        }
    }
}

// ANCHOR: segments
impl Iterator for Segments<'_> {
    type Item = Segment;

    #[inline]
    fn next(&mut self) -> Option<Segment> {
        if self.done || self.queries >= MAX_NULL_CROSSINGS {
            return None;
        }
        let hit = self.query(self.t_max);
        Some(self.segment_to(hit))
    }
}

impl Segments<'_> {
    /// The closest hit in (t_min, `t_max`).
    #[inline]
    fn query(&self, t_max: f32) -> Option<Hit> {
        if self.clear {
            return None;
        }
        let scene = self.scene;
        self.bvh.intersect_range(
            &scene.prims,
            &scene.prim_opaque,
            &self.ray,
            self.t_min,
            t_max,
        )
    }

    /// The next segment, ended by `hit` (the closest hit past it), crossing a null boundary.
    #[inline]
    fn segment_to(&mut self, hit: Option<Hit>) -> Segment {
        let first = self.queries == 0;
        self.queries += 1;
        let medium = self.medium;
        let t0 = self.t_start;
        let Some(hit) = hit else {
            self.done = true;
            return Segment {
                t0,
                t1: self.t_open,
                medium,
                first,
                end: SegmentEnd::Open,
            };
        };
        let shape = self.scene.shape_of(&hit);
        let end = if shape.is_null() {
            // the ray is continued (not re-spawned) past the boundary: segments stay contiguous
            self.medium = shape.medium_after(self.ray.d, hit.ng, medium);
            self.t_start = hit.t;
            self.t_min = past(hit.t, &self.ray);
            SegmentEnd::Null(hit)
        } else {
            self.done = true;
            SegmentEnd::Surface(hit)
        };
        Segment {
            t0,
            t1: hit.t,
            medium,
            first,
            end,
        }
    }
}
// ANCHOR_END: segments

impl Segment {
    /// The hit that ends the segment, null or not (`None` for an open one).
    #[inline]
    pub fn hit(&self) -> Option<Hit> {
        match self.end {
            SegmentEnd::Open => None,
            SegmentEnd::Null(h) | SegmentEnd::Surface(h) => Some(h),
        }
    }
}
