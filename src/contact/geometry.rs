//! Contact geometry: closest-point projection of a hitting point onto a target surface.
//!
//! *Why one file of about 1,000 lines (its tests are in `geometry_tests.rs`):* one
//! responsibility, the closest-point projection onto every kind of target, whose kinds share
//! the candidate search and the keeping of a face.
//!
//! Every function is generic over [`Scalar`] (`f64`, `Dual64`, `DualSVec64<N>`); the derivative
//! parts of the results are the exact derivatives with respect to whatever was seeded (node
//! coordinates, the hitting point, a rigid body's prescribed translation, shape parameters).
//!
//! # Symbols (Chen, Hisada et al., section 2.1)
//!
//! | paper            | here                    | meaning                                               |
//! |------------------|-------------------------|-------------------------------------------------------|
//! | `x^h`            | `x`                     | hitting point (slave node), deformed position          |
//! | `x^t`, `x̄`       | [`Projection::point`]   | target point: the closest point on the target surface |
//! | `ξ^1, ξ^2`       | [`Projection::xi`]      | convected coordinates of the target point             |
//! | `t_1, t_2`       | [`Projection::t1`], `t2`| covariant base vectors `∂x^t/∂ξ^α` (not normalised)   |
//! | `n`              | [`Projection::normal`]  | unit outward normal of the target body                |
//! | `g = -(gap)`     | [`Projection::gap`]     | normal gap, sign convention below                     |
//!
//! Equations:
//!
//! * (1) `t_α = ∂x^t/∂ξ^α`, `n = t_1 × t_2 / |t_1 × t_2|`;
//! * (7) `g = x^t − x^h`; (8) the paper's penetration `g = g · n`;
//! * (9) `t_α · g = 0`: the closest-point condition. Here it is solved as
//!   `r_α(ξ) = (x − x̄(ξ)) · t_α(ξ) = 0` by Newton's method with the full second-order matrix
//!   `H_αβ = t_α · t_β − (x − x̄) · x̄_{,αβ}` (a bilinear quad has `x̄_{,12} ≠ 0`, a quadratic
//!   face every `x̄_{,αβ}`; a tri3 none);
//! * (10), (11) the variation of (9) at fixed `ξ`-dependence,
//!   `H_αβ dξ^β = t_α · (dx − dx̄|_ξ) + (x − x̄) · dt_α|_ξ`:
//!   this is exactly what the derivative parts of the final Newton correction solve (see below).
//!
//! # Sign conventions
//!
//! * `normal` is the unit outward normal of the *target* body (for a rigid body: pointing towards
//!   the deformable body). For a face segment it is `t_1 × t_2 / |t_1 × t_2|`, so segments must
//!   be numbered counter-clockwise seen from outside the target body.
//! * `gap = (x − point) · normal`: positive = separated, negative = penetration. This is the
//!   paper's `g` of eq. (8) with the opposite sign (`gap = −g`).
//!
//! # Derivatives (implicit function theorem)
//!
//! The closest-point Newton iterations run in `f64` on the real parts, in coordinates relative to
//! the segment centroid, with step limiting (`|Δξ| ≤ 1`), an Armijo line search, a
//! Levenberg-Marquardt shift `H + μ M` (`M_αβ = t_α · t_β`) where `H` is indefinite (points
//! beyond a focal distance of a warped segment) and an iteration cap
//! ([`MAX_NEWTON_ITERATIONS`]). Far (≳ 10 segment sizes) from strongly warped segments the
//! minimiser on the bilinear extension can lie at `|ξ| ≫ 1` and [`GeometryError::NoConvergence`]
//! is returned; [`closest_on_quads`] then uses the segment's boundary point.
//! From the converged `ξ₀` one final Newton correction
//! `ξ = ξ₀ + H⁻¹ r(ξ₀)` is evaluated in `S`. Its real part is one more (quadratically convergent)
//! Newton step; its derivative part is `H⁻¹ ∂r/∂p`, i.e. the exact `dξ/dp` of eq. (11), because
//! `r(ξ₀) ≈ 0`. Point, tangents, normal and gap are then evaluated in `S` at that `ξ`.
//! All branch decisions (inside/outside, which edge, which face) are taken on real parts.
//! Where the closest-point map is not differentiable (a point equidistant from two segments, a
//! point on the line where a rounded-box face meets its edge cylinder, the cylinder's `θ = π`
//! cut for `ξ^1`), the derivative parts are the one-sided derivatives of the branch the real part
//! chose.
//!
//! # Segment validity
//!
//! # Faces of every family ([`Segment`])
//!
//! A target face is a quad4, quad8, tri3 or tri6 ([`crate::element::FaceFamily`]); its map
//! `x̄(ξ) = Σ N_a(ξ) x_a` over its natural domain (the square `[−1, 1]²`, or the unit triangle
//! `ξ ≥ 0`, `ξ¹ + ξ² ≤ 1`) is the family's interpolation, curved for the quadratic ones, and the
//! projection is onto that curved surface itself. The quad4 keeps the arithmetic below (bit
//! for bit as before the other families came); every family shares the Newton iterations, the
//! final correction in `S` and the search. The boundary of a face is its edges, straight lines
//! in `ξ`: on a straight edge the closest point is closed-form, on a curved one it is found by
//! a one-dimensional Newton on `|x − x̄(ξ(u))|²` (from the best of five samples, kept in
//! `[0, 1]`, the ends candidates too), and its derivative parts by one Newton step in `S`,
//! `u = u₀ + r · x̄_u / (x̄_u · x̄_u − r · x̄_uu)`, the implicit-function-theorem derivative. A
//! face other than the quad4 is accepted when its Jacobian `t_1 × t_2` is positive along its
//! centre normal at every node and at the centre. The hysteresis of [`SEGMENT_KEEP`] is half as
//! wide in `ξ` on a triangle, whose domain is.
//!
//! A quad segment is accepted when its coordinates are finite and every corner Jacobian
//! `(x_{a+1} − x_a) × (x_{a−1} − x_a)` is positive along the centre normal (beyond
//! `1e-10 h²`, `h` the largest node distance): coincident or collinear nodes, zero area and
//! re-entrant (non-convex, bow-tie) quads are [`GeometryError::DegenerateSegment`].
//!
//! # Segment search and the edge/corner rule ([`closest_on_quads`])
//!
//! For every segment two candidates are formed: the interior stationary point of the distance
//! (unconstrained Newton, accepted when `|ξ^α| ≤ 1 + 1e-10`: "inside"), and the closest point on
//! the segment boundary (its four straight edges, `ξ` clamped to `[-1, 1]`). The closest
//! candidate over all segments wins, i.e. the result is the closest point on the union of the
//! closed segments. For an interior candidate `|gap|` equals the distance, so when the node
//! projects inside several segments this is "the smallest `|gap|`". Ties (distances equal within
//! `1e-10` relative to segment size) are broken in this order:
//!
//! 1. an interior candidate beats a boundary one;
//! 2. among boundary candidates (node over a convex edge or corner, where several segments share
//!    the same boundary point), the segment whose normal is best aligned with `x − point`
//!    (largest `|gap| / distance`): this keeps the gap continuous when sliding over the edge;
//!    the `hint` segment keeps its place against one better aligned by less than
//!    [`ALIGN_KEEP`] (hysteresis: the choice flipping between Newton iterates made Newton
//!    cycle), so with a hint the gap is continuous up to `ALIGN_KEEP` times the distance;
//! 3. the `hint` segment (previous contact segment, for stability);
//! 4. the lowest segment index.
//!
//! A boundary result reports `inside = false`; its normal is that segment's normal `t_1 × t_2`
//! at the boundary point (the corner's own normal at a node), and `ξ` has one (edge) or two
//! (corner) components at `±1`.
//!
//! # Smoothed normals (`project_smoothed`)
//!
//! A pair with `smoothing` gives each face the target's nodal normals `n_a` (the area-weighted
//! mean of the normals of the faces around each node, formed by the contact assembly) and
//! projects a hitting point along `n̂(ξ) = Σ N_a n_a / |Σ N_a n_a|` instead of onto the closest
//! point: `x − x̄(ξ) ∥ n̂(ξ)`, `gap = (x − x̄) · n̂`, `normal = n̂`. Faces sharing an edge share
//! its nodes' normals, so gap and normal are continuous across it; on a flat patch this is the
//! closest point. Its derivatives follow the closest point's scheme (Newton on real parts, one
//! correction in `S`).
//!
//! # Rigid analytic surfaces ([`RigidSurface`])
//!
//! Each is moved by a rigid translation `d`; `ξ` are material surface coordinates (a point fixed
//! on the rigid body keeps its `ξ` when `d` changes); `inside` is always `true`.
//!
//! * Plane: `ξ = ((x^t − p − d) · e_1, (x^t − p − d) · e_2)`, with `e_1` the unit projection onto
//!   the plane of the coordinate axis least aligned with `n`, `e_2 = n × e_1`; `t_α = e_α`.
//! * Cylinder (contact on the outside): `ξ^1 = R θ` (arc length, `θ ∈ (−π, π]` measured from
//!   `b_1`, the unit projection of the coordinate axis least aligned with the axis `a`, towards
//!   `b_2 = a × b_1`), `ξ^2` = position along the axis from `axis_point + d`;
//!   `t_1 = a × n`, `t_2 = a`. A point on the axis is ambiguous and is an error.
//! * Rounded box (Minkowski sum of the inner box `half_extents − radius` with a sphere of
//!   `radius`, axis-aligned): outside the inner box the closest point is the closest point on
//!   the inner box plus `radius` along the unit direction to the node; inside it (deep
//!   penetration) the nearest face (smallest `b_k − |y_k|`, ties: lowest axis, `+` side at
//!   `y_k = 0`). `ξ` is a face chart: with `k` the axis of the largest `|n_k|` (ties: lowest)
//!   and `(i, j)` the cyclic successors of `k` (swapped when `n_k < 0`), `ξ = (y^t_i, y^t_j)`,
//!   the contact point's coordinates relative to the moved centre, and
//!   `t_1 = e_i − (n_i/n_k) e_k`, `t_2 = e_j − (n_j/n_k) e_k` (the surface as a graph over the
//!   `(i, j)` plane). `ξ` jumps where the chart changes (diagonal directions of the normal).

use nalgebra::Vector3;

use crate::element::face::MAX_FACE_NODES;
use crate::element::FaceFamily;
use crate::scalar::{lift_vec, re_vec, safe_norm, Scalar};

/// `ξ` tolerance of the "inside" test: `|ξ^α| ≤ 1 + QUAD_INSIDE_TOLERANCE`.
pub(crate) const QUAD_INSIDE_TOLERANCE: f64 = 1e-10;

/// Maximum number of closest-point Newton iterations (real parts).
pub const MAX_NEWTON_ITERATIONS: usize = 60;

/// Largest Newton step in `ξ` (half an element).
const MAX_STEP: f64 = 1.0;
/// Converged when a full Newton step is below this (in `ξ`).
const STEP_TOLERANCE: f64 = 1e-13;
/// Converged when the dimensionless residual `|r_α| / ((|x − x̄| + h) h)` is below this.
const RESIDUAL_TOLERANCE: f64 = 1e-15;
/// Relative tolerance of area-type degeneracy checks (relative to `h²`).
pub(crate) const AREA_TOLERANCE: f64 = 1e-10;
/// Relative tolerance of distance ties in the segment search (relative to distance + size).
const TIE_TOLERANCE: f64 = 1e-10;

/// Natural coordinates of the quad nodes.
const XI_NODES: [[f64; 2]; 4] = [[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]];

/// Straight edges of a bilinear quad: (node at free coordinate −1, node at +1, index of the fixed
/// coordinate, its value).
const EDGES: [(usize, usize, usize, f64); 4] = [
    (0, 1, 1, -1.0),
    (1, 2, 0, 1.0),
    (3, 2, 1, 1.0),
    (0, 3, 0, -1.0),
];

/// Why a projection failed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum GeometryError {
    /// A NaN or infinite input value.
    #[error("non-finite input: {what}")]
    NonFinite {
        /// Which input.
        what: &'static str,
    },
    /// The segment cannot carry a projection (coincident or collinear nodes, zero area,
    /// re-entrant corner, or a fold of the bilinear map at the projection point).
    #[error("degenerate segment: {reason}")]
    DegenerateSegment {
        /// What is wrong with it.
        reason: &'static str,
    },
    /// The closest-point Newton iterations did not converge.
    #[error("closest-point projection did not converge in {iterations} iterations (scaled residual {residual:e})")]
    NoConvergence {
        /// Iterations done.
        iterations: usize,
        /// Last dimensionless residual `max |r_α| / ((|x − x̄| + h) h)`.
        residual: f64,
    },
    /// The closest point is not unique / not differentiable there (a point on a cylinder axis,
    /// a point at a focal point of the surface where the Newton matrix is singular).
    #[error("ambiguous projection: {reason}")]
    AmbiguousProjection {
        /// Where.
        reason: &'static str,
    },
    /// Invalid rigid-surface parameters (zero normal or axis, non-positive radius, radius larger
    /// than a half extent, ...).
    #[error("invalid surface: {reason}")]
    InvalidSurface {
        /// What is wrong.
        reason: &'static str,
    },
    /// [`closest_on_quads`] was given no segment.
    #[error("no target segment given")]
    NoSegments,
    /// A segment of the search set is invalid.
    #[error("segment {index}: {source}")]
    Segment {
        /// Index of the segment in the slice.
        index: usize,
        /// What failed.
        #[source]
        source: Box<GeometryError>,
    },
}

/// Result of a closest-point projection (see the module docs for the conventions).
#[derive(Debug, Clone, PartialEq)]
pub struct Projection<S> {
    /// Convected (surface) coordinates `ξ^1, ξ^2` of the target point.
    pub xi: [S; 2],
    /// Target point `x^t = x̄(ξ)`.
    pub point: Vector3<S>,
    /// Covariant tangent `t_1 = ∂x̄/∂ξ^1` (not normalised).
    pub t1: Vector3<S>,
    /// Covariant tangent `t_2 = ∂x̄/∂ξ^2` (not normalised).
    pub t2: Vector3<S>,
    /// Unit outward normal of the target, `t_1 × t_2 / |t_1 × t_2|`.
    pub normal: Vector3<S>,
    /// `(x − point) · normal`: positive = separated, negative = penetration.
    pub gap: S,
    /// Quad: `|ξ^α| ≤ 1 + 1e-10` (the point is on the segment proper); rigid surfaces: `true`.
    pub inside: bool,
}

impl<S: Scalar> Projection<S> {
    /// The real parts.
    #[cfg(test)]
    pub(crate) fn to_real(&self) -> Projection<f64> {
        Projection {
            xi: [self.xi[0].value(), self.xi[1].value()],
            point: re_vec(&self.point),
            t1: re_vec(&self.t1),
            t2: re_vec(&self.t2),
            normal: re_vec(&self.normal),
            gap: self.gap.value(),
            inside: self.inside,
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Bilinear quad
// ---------------------------------------------------------------------------------------------

/// Position and covariant tangents of a bilinear quad at `ξ`.
struct QuadPoint<S> {
    x: Vector3<S>,
    t1: Vector3<S>,
    t2: Vector3<S>,
}

/// `x̄(ξ) = Σ N_a x_a`, `t_α = Σ N_{a,α} x_a`, with
/// `N_a = (1 + ξ^1 ξ^1_a)(1 + ξ^2 ξ^2_a)/4`.
fn quad_eval<S: Scalar>(nodes: &[Vector3<S>; 4], xi: &[S; 2]) -> QuadPoint<S> {
    let mut x = Vector3::zeros();
    let mut t1 = Vector3::zeros();
    let mut t2 = Vector3::zeros();
    for (node, [n, d1, d2]) in nodes.iter().zip(quad_weights(xi)) {
        x += node * n;
        t1 += node * d1;
        t2 += node * d2;
    }
    QuadPoint { x, t1, t2 }
}

/// The bilinear quad's shape functions and their derivatives at `xi`, `[N_a, N_{a,1},
/// N_{a,2}]` per node (in `f64` where `ξ` is a constant: [`node_jacobian`]).
fn quad_weights<T: Scalar>(xi: &[T; 2]) -> [[T; 3]; 4] {
    XI_NODES.map(|[a1, a2]| {
        let p1 = xi[0] * a1 + 1.0;
        let p2 = xi[1] * a2 + 1.0;
        [p1 * p2 * 0.25, p2 * (a1 * 0.25), p1 * (a2 * 0.25)]
    })
}

/// `x̄_{,12} = Σ N_{a,12} x_a = (x_1 − x_2 + x_3 − x_4)/4` (constant; `x̄_{,11} = x̄_{,22} = 0`).
fn quad_twist<S: Scalar>(nodes: &[Vector3<S>; 4]) -> Vector3<S> {
    (nodes[0] - nodes[1] + nodes[2] - nodes[3]) * S::lift(0.25)
}

/// `a > b`; false when either is NaN, so `!greater(..)` rejects NaN in degeneracy checks.
#[inline]
fn greater(a: f64, b: f64) -> bool {
    a > b
}

fn finite_vec(v: &Vector3<f64>) -> bool {
    v.iter().all(|c| c.is_finite())
}

/// Coordinates relative to the segment centroid `c` (returns `x − c`, `x_a − c`, `c`). The
/// projection is translation invariant; this removes the cancellation in `t_α = Σ N_{a,α} x_a`
/// and in `x − x̄` when coordinates are large compared with the segment.
fn localized<S: Scalar>(
    x: &Vector3<S>,
    nodes: &[Vector3<S>; 4],
) -> (Vector3<S>, [Vector3<S>; 4], Vector3<S>) {
    let c = (nodes[0] + nodes[1] + nodes[2] + nodes[3]) * S::lift(0.25);
    (x - c, nodes.map(|n| n - c), c)
}

/// Validates a segment (real parts) and returns its size `h` (largest node distance).
///
/// Accepted when all coordinates are finite, the centre Jacobian `|t_1 × t_2|` is positive and
/// every corner Jacobian is positive along the centre normal (a convex, non-collapsed quad; the
/// bilinear map is then one-to-one on the element).
fn check_segment(nodes: &[Vector3<f64>; 4]) -> Result<f64, GeometryError> {
    if !nodes.iter().all(finite_vec) {
        return Err(GeometryError::NonFinite {
            what: "segment node coordinates",
        });
    }
    let mut h: f64 = 0.0;
    for a in 0..4 {
        for b in a + 1..4 {
            h = h.max((nodes[a] - nodes[b]).norm());
        }
    }
    if !(h > 0.0 && h.is_finite()) {
        return Err(GeometryError::DegenerateSegment {
            reason: "all nodes coincide",
        });
    }
    let c = quad_eval(nodes, &[0.0, 0.0]);
    let jn = c.t1.cross(&c.t2);
    let j = jn.norm();
    if !greater(j, AREA_TOLERANCE * h * h) {
        return Err(GeometryError::DegenerateSegment {
            reason: "zero area (collinear or coincident nodes)",
        });
    }
    let n0 = jn / j;
    for a in 0..4 {
        let next = nodes[(a + 1) % 4] - nodes[a];
        let prev = nodes[(a + 3) % 4] - nodes[a];
        if !greater(next.cross(&prev).dot(&n0), AREA_TOLERANCE * h * h) {
            return Err(GeometryError::DegenerateSegment {
                reason: "collapsed or re-entrant corner (coincident nodes or non-convex quad)",
            });
        }
    }
    Ok(h)
}

/// Closest point on the boundary of a quad (real parts): `(edge, u, distance)` with `u ∈ [0, 1]`
/// the position along the straight edge.
fn boundary_real(x: &Vector3<f64>, nodes: &[Vector3<f64>; 4]) -> (usize, f64, f64) {
    let mut best = (0, 0.0, f64::INFINITY);
    for (e, &(a, b, _, _)) in EDGES.iter().enumerate() {
        let ab = nodes[b] - nodes[a];
        let u = ((x - nodes[a]).dot(&ab) / ab.dot(&ab)).clamp(0.0, 1.0);
        let dist = (x - (nodes[a] + ab * u)).norm();
        if dist < best.2 {
            best = (e, u, dist);
        }
    }
    best
}

/// `ξ` (in `S`) of the boundary point on `edge` at the real position `u_re`: the free
/// coordinate is the exact closed-form minimiser along the straight edge when interior, a
/// constant at the end nodes (corners).
fn boundary_xi<S: Scalar>(
    x: &Vector3<S>,
    nodes: &[Vector3<S>; 4],
    edge: usize,
    u_re: f64,
) -> [S; 2] {
    let (a, b, fixed, value) = EDGES[edge];
    let u = if u_re > 0.0 && u_re < 1.0 {
        let ab = nodes[b] - nodes[a];
        (x - nodes[a]).dot(&ab) / ab.dot(&ab)
    } else {
        S::lift(u_re)
    };
    let s = u * 2.0 - 1.0;
    let mut xi = [S::lift(value), S::lift(value)];
    xi[1 - fixed] = s;
    xi
}

/// Candidate closest point of one segment in the search (real parts).
#[derive(Debug, Clone, Copy)]
struct Candidate {
    index: usize,
    h: f64,
    dist: f64,
    /// `|gap| / dist` (1 when `dist = 0` or interior).
    align: f64,
    kind: CandidateKind,
}

#[derive(Debug, Clone, Copy)]
enum CandidateKind {
    Interior([f64; 2]),
    Boundary { edge: usize, u: f64 },
}

impl Candidate {
    fn interior(&self) -> bool {
        matches!(self.kind, CandidateKind::Interior(_))
    }
}

/// How much better aligned (`|gap| / distance`) another face's normal
/// must be at a shared boundary point before the `hint` face (the last Newton iterate's) gives
/// way to it: hysteresis of the edge/corner rule (module docs).
///
/// Why: a node over a shared edge or corner, or beyond a free edge near a corner, whose
/// closest point is on the boundary of two faces at once, takes the face whose normal is best
/// aligned with `x - point`; with the node in contact the distance is small, and from one
/// Newton iterate to the next the best-aligned face changed, turning the constraint's force
/// from one face's normal to the other's. Newton then cycled with the residual's size
/// unchanged and its sign flipping (the physics fuzzer's seed 700: a base node beyond the
/// slider's free edge at a corner of two of its faces, the free residual 9.1e-5 at every
/// iterate against a tolerance of 1.7e-8, flipping on the node's and the slider's `z`
/// components). Where the two faces' alignments differ by less than this, the face of the
/// last iterate is kept, and Newton converges on it. The kept face's `|gap|` is within this
/// fraction of the distance of the best-aligned face's, and `|gap|` jumps by about as much
/// where the face does change (without a hint the gap is continuous there). Measured on the
/// physics fuzzer with default settings (scenes completing their whole path): seeds 0-999, 988
/// without the band (`1e-12`) and 990 with it (700 and 976 converge, none breaks); held-out
/// seeds 1000-1999, 992 and 994 (1008 and 1693 converge). A band of 0.001 converges 700 and
/// 976 as well. Nodes projecting onto a face's interior are not concerned. The smoothed
/// projection's own choice of face is not either (it is concerned only through its start,
/// this rule's face): keeping the last iterate's face there too, while the node projects
/// within [`SEGMENT_KEEP`] outside it, was measured and not kept (seeds 57, 103 and 475 cycle
/// with it, 987 of seeds 0-999).
pub const ALIGN_KEEP: f64 = 0.01;

/// Is `c` preferred over `best` (see the edge/corner rule in the module docs)?
fn prefer(c: &Candidate, best: &Candidate, hint: Option<usize>) -> bool {
    let tol = TIE_TOLERANCE * (c.dist.max(best.dist) + c.h.max(best.h));
    if c.dist < best.dist - tol {
        return true;
    }
    if c.dist > best.dist + tol {
        return false;
    }
    if c.interior() != best.interior() {
        return c.interior();
    }
    if !c.interior() {
        // the hint keeps its face against a normal better aligned by less than ALIGN_KEEP
        let kept = hint == Some(best.index) || hint == Some(c.index);
        let band = if kept { ALIGN_KEEP } else { 1e-12 };
        if (c.align - best.align).abs() > band {
            return c.align > best.align;
        }
    }
    if hint == Some(best.index) {
        return false;
    }
    if hint == Some(c.index) {
        return true;
    }
    c.index < best.index
}

/// How far outside its segment (in `ξ`, whose range over a segment is 2) a hitting point may
/// project and still keep the segment it had at the last Newton iterate (the last converged
/// state at an increment's first; [`closest_on_quads_keeping`]).
///
/// Why: a node at the shared edge of two faceted segments whose normals differ projects onto
/// one segment at one Newton iterate and onto the other at the next; the residual jumps with
/// the normal and Newton cycles between the two with the active set unchanged (found by the
/// physics fuzzer: a frictionless slider on a deformable base, residual 1.9e-6 <-> 2.1e-6 for
/// 30 iterations at every cutback; in 3D a node at a vertex cycling between two faces neither
/// of which it had converged on). With the segment kept across the edge by a twentieth of its
/// width the residual is smooth from iterate to iterate; the gap to the extended segment
/// differs from the gap to its neighbour by the edge's kink times at most that distance, and
/// the node changes segment once it is further out.
///
/// That change is a jump of the gap (the constraint row's residual jumps by the constraint
/// scale times it): the fuzzer's slider on a finer, plastically dented base cycles there
/// (seed 57, `FRICSENS_TRACE=1 fricsens run tests/corpus/robustness/seed-57.toml`: at t = 1.1467,
/// a step of 1/512 of the user's increment, two nodes changed face, their gap jumped by 8.7e-3
/// and the residual from 0.04 to 144). A narrower band trades those cycles for nodes cycling
/// between faces. Measured on the physics fuzzer with
/// default settings (scenes completing their whole path): seeds 0-999, 982 at 0.1 and 0.07, 984
/// at 0.05 and 0.03; held-out seeds 1000-1999, 987 at 0.1, 988 at 0.05 (six scenes fixed,
/// three broken over the 2,000); on the once-failing corpus, net +3 at 0.05 and 0.03, +1 at 0.02,
/// +2 at 0.01. No width reaches 99 %; 0.1 is kept.
pub const SEGMENT_KEEP: f64 = 0.1;

/// [`closest_on_segments`], except that segment `keep` is kept while `x` projects onto its
/// interior or within [`SEGMENT_KEEP`] outside it (in `ξ`; half that on a triangle, whose
/// natural domain is half as wide): hysteresis of the segment choice against the last Newton
/// iterate's (the last converged state's at an increment's first iterate); `keep` is also the
/// hint of [`closest_on_segments`], and of its [`ALIGN_KEEP`] band.
///
/// # Errors
/// Those of [`closest_on_segments`].
pub fn closest_on_segments_keeping<S: Scalar>(
    x: &Vector3<S>,
    segments: &[Segment<S>],
    keep: Option<usize>,
) -> Result<(usize, Projection<S>), GeometryError> {
    if let Some(k) = keep.filter(|&k| k < segments.len()) {
        let xr = re_vec(x);
        let seg = segments[k].real();
        if let (true, Ok(h)) = (finite_vec(&xr), check_face(&seg)) {
            let (xl, sl, _) = seg.localized(&xr);
            if let Ok(xi) = newton_real(&xl, &sl, h, seg.family.centre_st()) {
                let width = if seg.family.is_triangle() { 0.5 } else { 1.0 };
                if seg.family.contains(xi, SEGMENT_KEEP * width) {
                    let (xs, ss, c) = segments[k].localized(x);
                    let mut p = finish_interior(&xs, &ss, xi, h)?;
                    p.point += c;
                    return Ok((k, p));
                }
            }
        }
    }
    closest_on_segments(x, segments, keep)
}

/// [`closest_on_segments_keeping`] over bilinear quads.
///
/// # Errors
/// Those of [`closest_on_segments`].
pub fn closest_on_quads_keeping<S: Scalar>(
    x: &Vector3<S>,
    quads: &[[Vector3<S>; 4]],
    keep: Option<usize>,
) -> Result<(usize, Projection<S>), GeometryError> {
    let segments: Vec<Segment<S>> = quads.iter().map(|q| Segment::quad4(*q)).collect();
    closest_on_segments_keeping(x, &segments, keep)
}

/// Closest point of `x` on a set of target faces, with face switching for large sliding.
///
/// Returns the index of the chosen face and the projection onto it. The rule (closest point
/// on the union of the closed faces, interior before boundary, best-aligned normal at shared
/// edges but for the `hint` face's band [`ALIGN_KEEP`], then `hint`, then lowest index) is
/// given in the module docs. For a boundary result
/// `inside = false` and the normal is the face normal at the boundary point.
///
/// # Errors
/// [`GeometryError::NoSegments`], [`GeometryError::NonFinite`] for a non-finite `x`,
/// [`GeometryError::Segment`] when a face is invalid (non-finite, degenerate), and the errors
/// of the final evaluation of the chosen candidate.
pub fn closest_on_segments<S: Scalar>(
    x: &Vector3<S>,
    segments: &[Segment<S>],
    hint: Option<usize>,
) -> Result<(usize, Projection<S>), GeometryError> {
    if segments.is_empty() {
        return Err(GeometryError::NoSegments);
    }
    let xr = re_vec(x);
    if !finite_vec(&xr) {
        return Err(GeometryError::NonFinite {
            what: "hitting point",
        });
    }
    let mut best: Option<Candidate> = None;
    let mut offer = |c: Candidate| match &best {
        Some(b) if !prefer(&c, b, hint) => {}
        _ => best = Some(c),
    };
    for (index, seg) in segments.iter().enumerate() {
        let seg = seg.real();
        let h = check_face(&seg).map_err(|e| GeometryError::Segment {
            index,
            source: Box::new(e),
        })?;
        let (xr, sr, _) = seg.localized(&xr);
        // interior stationary point (a failed or outside unconstrained projection only means
        // that this segment offers its boundary point)
        if let Ok(xi) = newton_real(&xr, &sr, h, seg.family.centre_st()) {
            if seg.family.contains(xi, QUAD_INSIDE_TOLERANCE) {
                let dist = (xr - surface_point(&sr, &xi).x).norm();
                offer(Candidate {
                    index,
                    h,
                    dist,
                    align: 1.0,
                    kind: CandidateKind::Interior(xi),
                });
            }
        }
        let (edge, u, dist) = face_boundary_real(&xr, &sr);
        let xi = face_boundary_xi(&xr, &sr, edge, u);
        let ev = surface_point(&sr, &xi);
        let n = ev.t1.cross(&ev.t2).normalize();
        let align = if dist > 0.0 {
            ((xr - ev.x).dot(&n) / dist).abs()
        } else {
            1.0
        };
        offer(Candidate {
            index,
            h,
            dist,
            align,
            kind: CandidateKind::Boundary { edge, u },
        });
    }
    let Some(best) = best else {
        return Err(GeometryError::NoSegments);
    };
    let (xl, sl, c) = segments[best.index].localized(x);
    let mut projection = match best.kind {
        CandidateKind::Interior(xi0) => {
            let mut p = finish_interior(&xl, &sl, xi0, best.h)?;
            p.inside = true;
            p
        }
        CandidateKind::Boundary { edge, u } => {
            let xi = face_boundary_xi(&xl, &sl, edge, u);
            face_projection(&xl, &sl, xi, best.h, false)?
        }
    };
    projection.point += c;
    Ok((best.index, projection))
}

/// [`closest_on_segments`] over bilinear quads.
///
/// # Errors
/// Those of [`closest_on_segments`].
pub fn closest_on_quads<S: Scalar>(
    x: &Vector3<S>,
    quads: &[[Vector3<S>; 4]],
    hint: Option<usize>,
) -> Result<(usize, Projection<S>), GeometryError> {
    let segments: Vec<Segment<S>> = quads.iter().map(|q| Segment::quad4(*q)).collect();
    closest_on_segments(x, &segments, hint)
}

// ---------------------------------------------------------------------------------------------
// Target faces of every family
// ---------------------------------------------------------------------------------------------

/// A target face as the projection sees it: its family and the positions of its nodes (the
/// first `family.n_nodes()` entries, in the family's order, counter-clockwise seen from
/// outside the target body).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Segment<S> {
    /// The face's family.
    pub family: FaceFamily,
    /// Node positions.
    pub nodes: [Vector3<S>; MAX_FACE_NODES],
}

impl<S: Scalar> Segment<S> {
    /// A face of `family` with nodes `nodes` (`family.n_nodes()` of them).
    pub fn new(family: FaceFamily, nodes: &[Vector3<S>]) -> Self {
        let mut all = [Vector3::zeros(); MAX_FACE_NODES];
        all[..nodes.len()].copy_from_slice(nodes);
        Segment { family, nodes: all }
    }

    /// A bilinear quad.
    pub fn quad4(nodes: [Vector3<S>; 4]) -> Self {
        Segment::new(FaceFamily::Quad4, &nodes)
    }

    /// The nodes in use.
    fn used(&self) -> &[Vector3<S>] {
        &self.nodes[..self.family.n_nodes()]
    }

    /// The four nodes of a bilinear quad.
    fn quad(&self) -> [Vector3<S>; 4] {
        [self.nodes[0], self.nodes[1], self.nodes[2], self.nodes[3]]
    }

    /// The real parts.
    fn real(&self) -> Segment<f64> {
        Segment {
            family: self.family,
            nodes: self.nodes.map(|n| re_vec(&n)),
        }
    }

    /// Coordinates relative to the face's centre (returns `x − c`, the face moved by `−c`, `c`):
    /// the quad's [`localized`] for a quad4, the mean of the nodes for the others.
    fn localized(&self, x: &Vector3<S>) -> (Vector3<S>, Segment<S>, Vector3<S>) {
        let c = if self.family == FaceFamily::Quad4 {
            localized(x, &self.quad()).2
        } else {
            self.used().iter().fold(Vector3::zeros(), |s, n| s + n)
                * S::lift(1.0 / self.family.n_nodes() as f64)
        };
        let mut moved = *self;
        for n in moved.nodes.iter_mut().take(self.family.n_nodes()) {
            *n -= c;
        }
        (x - c, moved, c)
    }
}

/// Position, covariant tangents and second derivatives of a face at `ξ`.
struct SurfacePoint<S> {
    x: Vector3<S>,
    t1: Vector3<S>,
    t2: Vector3<S>,
    /// `[x̄_{,11}, x̄_{,12}, x̄_{,22}]`.
    curvature: [Vector3<S>; 3],
}

/// The face's map at `ξ`: the bilinear quad's own [`quad_eval`] and [`quad_twist`] for a quad4,
/// the family's interpolation for the others.
fn surface_point<S: Scalar>(seg: &Segment<S>, xi: &[S; 2]) -> SurfacePoint<S> {
    if seg.family == FaceFamily::Quad4 {
        let q = quad_eval(&seg.quad(), xi);
        return SurfacePoint {
            x: q.x,
            t1: q.t1,
            t2: q.t2,
            curvature: [Vector3::zeros(), quad_twist(&seg.quad()), Vector3::zeros()],
        };
    }
    let f = seg.family.interpolation(*xi);
    let mut p = SurfacePoint {
        x: Vector3::zeros(),
        t1: Vector3::zeros(),
        t2: Vector3::zeros(),
        curvature: [Vector3::zeros(); 3],
    };
    for (a, node) in seg.used().iter().enumerate() {
        p.x += node * f.n[a];
        p.t1 += node * f.d[a][0];
        p.t2 += node * f.d[a][1];
        for k in 0..3 {
            p.curvature[k] += node * f.dd[a][k];
        }
    }
    p
}

/// Validates a face (real parts) and returns its size `h` (largest node distance): a quad4
/// by [`check_segment`]; the others when every coordinate is finite and the Jacobian
/// `t_1 × t_2` is positive along the centre normal at every node and at the centre (beyond
/// `1e-10 h²`): no collapsed corner, no fold of the curved map over the face.
fn check_face(seg: &Segment<f64>) -> Result<f64, GeometryError> {
    if seg.family == FaceFamily::Quad4 {
        return check_segment(&seg.quad());
    }
    let nodes = seg.used();
    if !nodes.iter().all(finite_vec) {
        return Err(GeometryError::NonFinite {
            what: "segment node coordinates",
        });
    }
    let mut h: f64 = 0.0;
    for a in 0..nodes.len() {
        for b in a + 1..nodes.len() {
            h = h.max((nodes[a] - nodes[b]).norm());
        }
    }
    if !(h > 0.0 && h.is_finite()) {
        return Err(GeometryError::DegenerateSegment {
            reason: "all nodes coincide",
        });
    }
    let c = surface_point(seg, &seg.family.centre_st());
    let jn = c.t1.cross(&c.t2);
    if !greater(jn.norm(), AREA_TOLERANCE * h * h) {
        return Err(GeometryError::DegenerateSegment {
            reason: "zero area (collinear or coincident nodes)",
        });
    }
    let n0 = jn.normalize();
    for a in 0..nodes.len() {
        let p = surface_point(seg, &seg.family.node_st(a));
        if !greater(p.t1.cross(&p.t2).dot(&n0), AREA_TOLERANCE * h * h) {
            return Err(GeometryError::DegenerateSegment {
                reason: "the face folds or collapses at a node (coincident nodes, a mid-side node off its edge)",
            });
        }
    }
    Ok(h)
}

/// The closest-point matrix `H_αβ = t_α · t_β − r · x̄_{,αβ}` and the metric `M_αβ = t_α · t_β`
/// as `(h11, h12, h22, m11, m12, m22)`.
fn closest_point_matrix<S: Scalar>(p: &SurfacePoint<S>, r: &Vector3<S>) -> [S; 6] {
    let m11 = p.t1.dot(&p.t1);
    let m22 = p.t2.dot(&p.t2);
    let m12 = p.t1.dot(&p.t2);
    [
        m11 - r.dot(&p.curvature[0]),
        m12 - r.dot(&p.curvature[1]),
        m22 - r.dot(&p.curvature[2]),
        m11,
        m12,
        m22,
    ]
}

/// Closest-point Newton on the real parts, unconstrained in `ξ` (the extension of the face's
/// map beyond its domain). Returns the converged `ξ`.
fn newton_real(
    x: &Vector3<f64>,
    seg: &Segment<f64>,
    h: f64,
    xi_start: [f64; 2],
) -> Result<[f64; 2], GeometryError> {
    // magnitude of the coordinates: sets the rounding noise of r = x − x̄ (~ ε L)
    let l = seg.used().iter().fold(x.amax(), |m, n| m.max(n.amax()));
    let mut xi = xi_start;
    let mut ev = surface_point(seg, &xi);
    let mut r = x - ev.x;
    let mut f = 0.5 * r.dot(&r);
    let mut residual = f64::INFINITY;
    let mut iterations = 0;
    while iterations < MAX_NEWTON_ITERATIONS {
        iterations += 1;
        // g = −∇f = (x − x̄)·t_α
        let g = [r.dot(&ev.t1), r.dot(&ev.t2)];
        let scale = (r.norm() + h) * h;
        residual = g[0].abs().max(g[1].abs()) / scale;
        let tmax = ev.t1.norm().max(ev.t2.norm());
        let noise_g = 8.0 * f64::EPSILON * l * tmax / scale;
        if residual <= RESIDUAL_TOLERANCE.max(noise_g) {
            return Ok(xi);
        }
        let [h11, h12, h22, m11, m12, m22] = closest_point_matrix(&ev, &r);
        let det_h = h11 * h22 - h12 * h12;
        let det_m = m11 * m22 - m12 * m12;
        let mut dir = if det_h > 1e-12 * m11 * m22 && h11 > 0.0 {
            // full Newton (H positive definite)
            [
                (h22 * g[0] - h12 * g[1]) / det_h,
                (h11 * g[1] - h12 * g[0]) / det_h,
            ]
        } else if det_m > 1e-14 * m11 * m22 {
            // H indefinite (beyond a focal distance): Levenberg-Marquardt shift H + μM, with
            // μ = 2|λ_min| + 1e-3 from the generalised eigenvalues of (H, M),
            // det(H − λM) = det_m λ² − b λ + det_h = 0
            let b = h11 * m22 + h22 * m11 - 2.0 * h12 * m12;
            let lambda_min = (b - (b * b - 4.0 * det_m * det_h).max(0.0).sqrt()) / (2.0 * det_m);
            let mu = 2.0 * (-lambda_min).max(0.0) + 1e-3;
            let (a11, a22, a12) = (h11 + mu * m11, h22 + mu * m22, h12 + mu * m12);
            let det = a11 * a22 - a12 * a12;
            [
                (a22 * g[0] - a12 * g[1]) / det,
                (a11 * g[1] - a12 * g[0]) / det,
            ]
        } else {
            // fold of the map's extension: steepest descent
            let s = m11 + m22;
            [g[0] / s, g[1] / s]
        };
        let len = dir[0].abs().max(dir[1].abs());
        if !len.is_finite() {
            break;
        }
        if len > MAX_STEP {
            dir = [dir[0] * MAX_STEP / len, dir[1] * MAX_STEP / len];
        }
        let slope = g[0] * dir[0] + g[1] * dir[1];
        let gnorm = (g[0] * g[0] + g[1] * g[1]).sqrt();
        let mut alpha = 1.0;
        let mut accepted = None;
        for _ in 0..40 {
            let trial = [xi[0] + alpha * dir[0], xi[1] + alpha * dir[1]];
            let ev_t = surface_point(seg, &trial);
            let r_t = x - ev_t.x;
            let f_t = 0.5 * r_t.dot(&r_t);
            let armijo = f_t <= f - 1e-4 * alpha * slope;
            // below the resolution of f (rounding of r ~ ε L): accept when the gradient
            // still decreases
            let noise_f = 16.0 * f64::EPSILON * l * (r.norm() + r_t.norm());
            let flat = f_t - f <= noise_f && {
                let gt = [r_t.dot(&ev_t.t1), r_t.dot(&ev_t.t2)];
                (gt[0] * gt[0] + gt[1] * gt[1]).sqrt() < gnorm
            };
            if armijo || flat {
                accepted = Some((trial, ev_t, r_t, f_t));
                break;
            }
            alpha *= 0.5;
        }
        let Some((trial, ev_t, r_t, f_t)) = accepted else {
            // no decrease possible: converged to rounding if the residual is small
            if residual <= 1e-9 {
                return Ok(xi);
            }
            break;
        };
        xi = trial;
        ev = ev_t;
        r = r_t;
        f = f_t;
        if alpha == 1.0 && len <= STEP_TOLERANCE {
            return Ok(xi);
        }
    }
    Err(GeometryError::NoConvergence {
        iterations,
        residual,
    })
}

/// Unit vector `v/|v|`, or the given error when `|v|` is zero (real part).
fn unit_or<S: Scalar>(v: &Vector3<S>, err: GeometryError) -> Result<Vector3<S>, GeometryError> {
    let n = safe_norm(v);
    let nr = n.value();
    if nr > 0.0 && nr.is_finite() {
        Ok(v / n)
    } else {
        Err(err)
    }
}

/// Builds the projection at `ξ` (in `S`) on a face.
fn face_projection<S: Scalar>(
    x: &Vector3<S>,
    seg: &Segment<S>,
    xi: [S; 2],
    h: f64,
    inside: bool,
) -> Result<Projection<S>, GeometryError> {
    let ev = surface_point(seg, &xi);
    let jn = ev.t1.cross(&ev.t2);
    if !greater(safe_norm(&jn).value(), AREA_TOLERANCE * h * h) {
        return Err(GeometryError::DegenerateSegment {
            reason: "the face's map folds at the projection point",
        });
    }
    let normal = unit_or(
        &jn,
        GeometryError::DegenerateSegment {
            reason: "zero normal at the projection point",
        },
    )?;
    let gap = (x - ev.x).dot(&normal);
    Ok(Projection {
        xi,
        point: ev.x,
        t1: ev.t1,
        t2: ev.t2,
        normal,
        gap,
        inside,
    })
}

/// The final Newton correction in `S` from the converged real `ξ₀` (exact first derivatives by
/// the implicit function theorem), then the projection at the corrected `ξ`.
fn finish_interior<S: Scalar>(
    x: &Vector3<S>,
    seg: &Segment<S>,
    xi0: [f64; 2],
    h: f64,
) -> Result<Projection<S>, GeometryError> {
    let xi_c = [S::lift(xi0[0]), S::lift(xi0[1])];
    let ev = surface_point(seg, &xi_c);
    let r = x - ev.x;
    let g1 = r.dot(&ev.t1);
    let g2 = r.dot(&ev.t2);
    let [h11, h12, h22, m11, _, m22] = closest_point_matrix(&ev, &r);
    let det = h11 * h22 - h12 * h12;
    if !greater(det.value(), 1e-12 * m11.value() * m22.value()) {
        return Err(GeometryError::AmbiguousProjection {
            reason: "singular closest-point matrix (point at a focal point of the segment)",
        });
    }
    let xi = [
        xi_c[0] + (h22 * g1 - h12 * g2) / det,
        xi_c[1] + (h11 * g2 - h12 * g1) / det,
    ];
    let inside = seg
        .family
        .contains([xi[0].value(), xi[1].value()], QUAD_INSIDE_TOLERANCE);
    face_projection(x, seg, xi, h, inside)
}

/// Closest-point projection of `x` onto the face `seg` (counter-clockwise seen from outside),
/// by Newton in convected coordinates from `xi_start`.
///
/// The projection is onto the extension of the face's map (`ξ` unconstrained); `inside` tells
/// whether `ξ` lies in the natural domain (within `1e-10`). See the module docs for the
/// derivative scheme.
///
/// # Errors
/// [`GeometryError::NonFinite`] (NaN/inf input), [`GeometryError::DegenerateSegment`]
/// (coincident/collinear nodes, zero area, re-entrant corner, fold at the projection point),
/// [`GeometryError::NoConvergence`], [`GeometryError::AmbiguousProjection`] (singular Newton
/// matrix at the solution).
pub(crate) fn project_on_segment<S: Scalar>(
    x: &Vector3<S>,
    seg: &Segment<S>,
    xi_start: [f64; 2],
) -> Result<Projection<S>, GeometryError> {
    let (h, xl, sl, c) = checked_local(x, seg, xi_start)?;
    let xi0 = newton_real(&re_vec(&xl), &sl.real(), h, xi_start)?;
    let mut p = finish_interior(&xl, &sl, xi0, h)?;
    p.point += c;
    Ok(p)
}

/// The checks every projection makes of its input (a finite hitting point and start, a face
/// [`check_face`] accepts), then the face's size `h` and `x` and `seg` localized
/// ([`Segment::localized`]: relative to the face's first node `c`).
#[allow(clippy::type_complexity)]
fn checked_local<S: Scalar>(
    x: &Vector3<S>,
    seg: &Segment<S>,
    xi_start: [f64; 2],
) -> Result<(f64, Vector3<S>, Segment<S>, Vector3<S>), GeometryError> {
    if !finite_vec(&re_vec(x)) {
        return Err(GeometryError::NonFinite {
            what: "hitting point",
        });
    }
    if !(xi_start[0].is_finite() && xi_start[1].is_finite()) {
        return Err(GeometryError::NonFinite { what: "xi_start" });
    }
    let h = check_face(&seg.real())?;
    let (xl, sl, c) = seg.localized(x);
    Ok((h, xl, sl, c))
}

/// `J⁻¹ r` for a 2 x 2 `J` (by Cramer's rule), `None` where `J` is singular relative to its
/// entries.
fn solve_2x2<S: Scalar>(j: [[f64; 2]; 2], r: [S; 2]) -> Option<[S; 2]> {
    let det = j[0][0] * j[1][1] - j[0][1] * j[1][0];
    let scale = (j[0][0].abs() + j[0][1].abs()) * (j[1][0].abs() + j[1][1].abs());
    (det.abs() > 1e-12 * scale && det.is_finite()).then(|| {
        [
            (r[0] * j[1][1] - r[1] * j[0][1]) / det,
            (r[1] * j[0][0] - r[0] * j[1][0]) / det,
        ]
    })
}

// ---------------------------------------------------------------------------------------------
// Smoothed normals
// ---------------------------------------------------------------------------------------------

/// The normal field of a face smoothed by its nodal normals: `n(ξ) = Σ N_a(ξ) n_a`, and the
/// residual of the projection along it, `r_α = (d − (d · n̂) n̂) · t_α` with `d = x − x̄(ξ)` and
/// `n̂ = n / |n|`: zero where `x − x̄(ξ)` is parallel to `n̂(ξ)`. Returns `r`, the face's point
/// and `n̂`.
fn smoothed_residual<S: Scalar>(
    x: &Vector3<S>,
    seg: &Segment<S>,
    normals: &[Vector3<S>; MAX_FACE_NODES],
    xi: &[S; 2],
) -> ([S; 2], SurfacePoint<S>, Vector3<S>) {
    let p = surface_point(seg, xi);
    let f = seg.family.interpolation(*xi);
    let mut n = Vector3::zeros();
    for (na, w) in normals.iter().zip(f.n).take(seg.family.n_nodes()) {
        n += na * w;
    }
    let n = n / safe_norm(&n);
    let d = x - p.x;
    let dp = d - n * d.dot(&n);
    ([dp.dot(&p.t1), dp.dot(&p.t2)], p, n)
}

/// The Jacobian `∂r_α/∂ξ^β` of [`smoothed_residual`] at `xi` (real parts, by dual numbers in
/// each direction) and `r` there.
fn smoothed_jacobian(
    x: &Vector3<f64>,
    seg: &Segment<f64>,
    normals: &[Vector3<f64>; MAX_FACE_NODES],
    xi: [f64; 2],
) -> ([f64; 2], [[f64; 2]; 2]) {
    use num_dual::Dual64;
    let lift = |v: &Vector3<f64>| v.map(Dual64::from_re);
    let xd = lift(x);
    let sd = Segment {
        family: seg.family,
        nodes: seg.nodes.map(|n| lift(&n)),
    };
    let nd = normals.map(|n| lift(&n));
    let column = |k: usize| {
        let mut at = [Dual64::from_re(xi[0]), Dual64::from_re(xi[1])];
        at[k].eps = 1.0;
        smoothed_residual(&xd, &sd, &nd, &at).0
    };
    let (c0, c1) = (column(0), column(1));
    (
        [c0[0].re, c0[1].re],
        [[c0[0].eps, c1[0].eps], [c0[1].eps, c1[1].eps]],
    )
}

/// Projection of `x` onto the face `seg` along the face's smoothed normal field: the point
/// `x̄(ξ)` whose normal `n̂(ξ) = Σ N_a(ξ) n_a / |Σ N_a(ξ) n_a|`, interpolated from the nodal
/// normals `normals` (unit, outward, the first `family.n_nodes()`), passes through `x`. The
/// gap is `(x − x̄) · n̂` and the normal `n̂`.
///
/// Why: on a faceted target the closest-point normal jumps at every edge, and so does the gap
/// of a node held on a face beyond its edge ([`SEGMENT_KEEP`]); a Lagrange multiplier row then
/// jumps by the constraint scale times that gap when the node changes face, and Newton cycles
/// (the physics fuzzer's slider on a dented base). Two faces sharing an edge share its nodes'
/// normals, so on that edge they give the same `x̄`, `n̂` and gap: the projection, the gap and
/// the normal are continuous across faces (Nagata-free normal smoothing, as the averaged
/// nodal normals of mortar methods). On a flat patch every nodal normal is the face normal and
/// this is the closest-point projection.
///
/// Newton on `r(ξ) = 0` in `f64` (the Jacobian by dual numbers), then one correction in `S`,
/// `ξ = ξ₀ − J⁻¹ r(ξ₀)`: exact first derivatives by the implicit function theorem, as
/// [`project_on_segment`]'s. `ξ` is not confined to the face (`inside` says whether it lies in
/// it).
///
/// # Errors
/// Those of [`project_on_segment`]; [`GeometryError::AmbiguousProjection`] where the smoothed
/// normal vanishes or the Jacobian is singular.
pub(crate) fn project_smoothed<S: Scalar>(
    x: &Vector3<S>,
    seg: &Segment<S>,
    normals: &[Vector3<S>; MAX_FACE_NODES],
    xi_start: [f64; 2],
) -> Result<Projection<S>, GeometryError> {
    let (h, xl, sl, c) = checked_local(x, seg, xi_start)?;
    let nr = normals.map(|n| re_vec(&n));
    if !nr.iter().take(seg.family.n_nodes()).all(finite_vec) {
        return Err(GeometryError::NonFinite {
            what: "nodal normals",
        });
    }
    let (xlr, slr) = (re_vec(&xl), sl.real());
    let singular = GeometryError::AmbiguousProjection {
        reason: "singular smoothed-normal projection (the smoothed normal lies in the face)",
    };
    let mut xi = xi_start;
    let mut converged = false;
    let mut residual = f64::INFINITY;
    let mut iterations = 0;
    while iterations < MAX_NEWTON_ITERATIONS {
        iterations += 1;
        let (r, j) = smoothed_jacobian(&xlr, &slr, &nr, xi);
        residual = r[0].abs().max(r[1].abs()) / ((xlr.norm() + h) * h);
        let Some(mut step) = solve_2x2(j, r) else {
            return Err(singular);
        };
        let size = step[0].abs().max(step[1].abs());
        if size > MAX_STEP {
            step = step.map(|v| v * MAX_STEP / size);
        }
        xi = [xi[0] - step[0], xi[1] - step[1]];
        if !(xi[0].is_finite() && xi[1].is_finite()) {
            break;
        }
        if size < STEP_TOLERANCE || residual < RESIDUAL_TOLERANCE {
            converged = true;
            break;
        }
    }
    if !converged {
        return Err(GeometryError::NoConvergence {
            iterations,
            residual,
        });
    }
    // the correction in S, with the Jacobian at the converged point
    let (_, j) = smoothed_jacobian(&xlr, &slr, &nr, xi);
    let at = [S::lift(xi[0]), S::lift(xi[1])];
    let (r, _, _) = smoothed_residual(&xl, &sl, normals, &at);
    let step = solve_2x2(j, r).ok_or(singular)?;
    let xi_s = [at[0] - step[0], at[1] - step[1]];
    let (_, p, n) = smoothed_residual(&xl, &sl, normals, &xi_s);
    let jn = p.t1.cross(&p.t2);
    if !greater(jn.dot(&n).value(), AREA_TOLERANCE * h * h) {
        return Err(GeometryError::DegenerateSegment {
            reason: "the smoothed normal turns away from the face at the projection point",
        });
    }
    let gap = (xl - p.x).dot(&n);
    let inside = seg
        .family
        .contains([xi_s[0].value(), xi_s[1].value()], QUAD_INSIDE_TOLERANCE);
    Ok(Projection {
        xi: xi_s,
        point: p.x + c,
        t1: p.t1,
        t2: p.t2,
        normal: n,
        gap,
        inside,
    })
}

/// The outward normal `t_1 × t_2` (not normalised: it weighs by area) of face `seg` at its
/// node `a`: the tangents of [`surface_point`] there, whose shape-function weights are
/// constants, summed with `f64` weights (the nodal normals of smoothed faces take a dozen of
/// these per hitting node in the contact kernel's many-direction duals, where a dual weight
/// only copies: the same sums in the same order, so the same bits wherever the coordinates
/// are finite).
pub(crate) fn node_jacobian<S: Scalar>(seg: &Segment<S>, a: usize) -> Vector3<S> {
    let st = seg.family.node_st(a);
    let (mut t1, mut t2) = (Vector3::<S>::zeros(), Vector3::<S>::zeros());
    let mut add = |node: &Vector3<S>, w1: f64, w2: f64| {
        for c in 0..3 {
            t1[c] += node[c] * w1;
            t2[c] += node[c] * w2;
        }
    };
    if seg.family == FaceFamily::Quad4 {
        for (node, [_, d1, d2]) in seg.nodes.iter().zip(quad_weights(&st)) {
            add(node, d1, d2);
        }
    } else {
        let f = seg.family.interpolation(st);
        for (node, d) in seg.used().iter().zip(f.d) {
            add(node, d[0], d[1]);
        }
    }
    t1.cross(&t2)
}

/// [`project_on_segment`] onto a bilinear quad.
#[cfg(test)]
pub(crate) fn project_on_quad<S: Scalar>(
    x: &Vector3<S>,
    nodes: &[Vector3<S>; 4],
    xi_start: [f64; 2],
) -> Result<Projection<S>, GeometryError> {
    project_on_segment(x, &Segment::quad4(*nodes), xi_start)
}

/// `ξ(u)` on edge `edge` of a face, `u ∈ [0, 1]` from the edge's first corner to its second
/// (a straight line in `ξ` for every family).
fn edge_xi<S: Scalar>(family: FaceFamily, edge: usize, u: S) -> [S; 2] {
    let [a, b] = family.edges()[edge];
    let (sa, sb) = (family.node_st(a), family.node_st(b));
    [u * (sb[0] - sa[0]) + sa[0], u * (sb[1] - sa[1]) + sa[1]]
}

/// `x̄_u`, `x̄_uu` along edge `edge` at `p` (the face's point on it).
fn edge_derivatives<S: Scalar>(
    family: FaceFamily,
    edge: usize,
    p: &SurfacePoint<S>,
) -> (Vector3<S>, Vector3<S>) {
    let [a, b] = family.edges()[edge];
    let (sa, sb) = (family.node_st(a), family.node_st(b));
    let (d0, d1) = (sb[0] - sa[0], sb[1] - sa[1]);
    let xu = p.t1 * S::lift(d0) + p.t2 * S::lift(d1);
    let xuu = p.curvature[0] * S::lift(d0 * d0)
        + p.curvature[1] * S::lift(2.0 * d0 * d1)
        + p.curvature[2] * S::lift(d1 * d1);
    (xu, xuu)
}

/// The closest point of `x` on edge `edge` of a curved face (real parts): `u ∈ [0, 1]` and its
/// distance. Newton on `φ(u) = |x − x̄(ξ(u))|² / 2` from the best of five samples, steps kept
/// in `[0, 1]`, a gradient step where `φ'' ≤ 0`; the ends are candidates too.
fn curved_edge_real(x: &Vector3<f64>, seg: &Segment<f64>, edge: usize) -> (f64, f64) {
    let dist = |u: f64| (x - surface_point(seg, &edge_xi(seg.family, edge, u)).x).norm();
    let mut u = [0.0, 0.25, 0.5, 0.75, 1.0]
        .into_iter()
        .min_by(|a, b| dist(*a).total_cmp(&dist(*b)))
        .unwrap_or(0.5);
    for _ in 0..MAX_NEWTON_ITERATIONS {
        let p = surface_point(seg, &edge_xi(seg.family, edge, u));
        let r = x - p.x;
        let (xu, xuu) = edge_derivatives(seg.family, edge, &p);
        let slope = -r.dot(&xu);
        let curvature = xu.dot(&xu) - r.dot(&xuu);
        let step = if curvature > 0.0 {
            -slope / curvature
        } else {
            -slope / xu.dot(&xu).max(f64::MIN_POSITIVE)
        };
        let next = (u + step).clamp(0.0, 1.0);
        let done = (next - u).abs() <= STEP_TOLERANCE;
        u = next;
        if done {
            break;
        }
    }
    [u, 0.0, 1.0]
        .into_iter()
        .map(|v| (v, dist(v)))
        .min_by(|a, b| a.1.total_cmp(&b.1))
        .unwrap_or((u, dist(u)))
}

/// Closest point on the boundary of a face (real parts): `(edge, u, distance)`, `u ∈ [0, 1]`
/// along the edge (a quad4's [`boundary_real`], its own edge table).
fn face_boundary_real(x: &Vector3<f64>, seg: &Segment<f64>) -> (usize, f64, f64) {
    if seg.family == FaceFamily::Quad4 {
        return boundary_real(x, &seg.quad());
    }
    let mut best = (0, 0.0, f64::INFINITY);
    for (e, [a, b]) in seg.family.edges().iter().enumerate() {
        let (u, dist) = if seg.family.is_quadratic() {
            curved_edge_real(x, seg, e)
        } else {
            let ab = seg.nodes[*b] - seg.nodes[*a];
            let u = ((x - seg.nodes[*a]).dot(&ab) / ab.dot(&ab)).clamp(0.0, 1.0);
            (u, (x - (seg.nodes[*a] + ab * u)).norm())
        };
        if dist < best.2 {
            best = (e, u, dist);
        }
    }
    best
}

/// `ξ` (in `S`) of the boundary point on `edge` at the real position `u_re` (a quad4's
/// [`boundary_xi`]): at an end, the corner's constant `ξ`; inside a straight edge, the exact
/// closed-form minimiser; inside a curved one, one Newton step in `S` from `u_re`, whose
/// derivative part is the implicit-function-theorem derivative of the edge's closest point.
fn face_boundary_xi<S: Scalar>(x: &Vector3<S>, seg: &Segment<S>, edge: usize, u_re: f64) -> [S; 2] {
    if seg.family == FaceFamily::Quad4 {
        return boundary_xi(x, &seg.quad(), edge, u_re);
    }
    let u = if !(u_re > 0.0 && u_re < 1.0) {
        S::lift(u_re)
    } else if seg.family.is_quadratic() {
        let u0 = S::lift(u_re);
        let p = surface_point(seg, &edge_xi(seg.family, edge, u0));
        let r = x - p.x;
        let (xu, xuu) = edge_derivatives(seg.family, edge, &p);
        u0 + r.dot(&xu) / (xu.dot(&xu) - r.dot(&xuu))
    } else {
        let [a, b] = seg.family.edges()[edge];
        let ab = seg.nodes[b] - seg.nodes[a];
        (x - seg.nodes[a]).dot(&ab) / ab.dot(&ab)
    };
    edge_xi(seg.family, edge, u)
}

// ---------------------------------------------------------------------------------------------
// Rigid analytic surfaces
// ---------------------------------------------------------------------------------------------

/// Index of the coordinate axis least aligned with `v` (real parts; ties: lowest).
fn least_aligned_axis<S: Scalar>(v: &Vector3<S>) -> usize {
    let mut k = 0;
    for i in 1..3 {
        if v[i].value().abs() < v[k].value().abs() {
            k = i;
        }
    }
    k
}

/// Orthonormal `(e_1, e_2)` with `e_1 × e_2 = n` (`n` unit): `e_1` is the unit projection of the
/// coordinate axis least aligned with `n` onto the plane normal to `n`, `e_2 = n × e_1`.
fn tangent_basis<S: Scalar>(n: &Vector3<S>) -> (Vector3<S>, Vector3<S>) {
    let k = least_aligned_axis(n);
    let mut a = Vector3::<S>::zeros();
    a[k] = S::one();
    let p = a - n * n[k];
    // |p|² = 1 − n_k² ≥ 2/3
    let e1 = p / safe_norm(&p);
    let e2 = n.cross(&e1);
    (e1, e2)
}

fn check_finite_inputs<S: Scalar>(
    x: &Vector3<S>,
    others: &[&Vector3<S>],
) -> Result<(), GeometryError> {
    if !finite_vec(&re_vec(x)) {
        return Err(GeometryError::NonFinite {
            what: "hitting point",
        });
    }
    if !others.iter().all(|v| finite_vec(&re_vec(*v))) {
        return Err(GeometryError::NonFinite {
            what: "surface parameters or translation",
        });
    }
    Ok(())
}

/// Projection onto the plane through `point` with outward normal `normal` (any length; it is
/// normalised). `ξ` and tangents: see the module docs. All arguments may be seeded.
///
/// # Errors
/// [`GeometryError::NonFinite`], [`GeometryError::InvalidSurface`] for a zero normal.
pub(crate) fn project_on_plane<S: Scalar>(
    x: &Vector3<S>,
    point: &Vector3<S>,
    normal: &Vector3<S>,
) -> Result<Projection<S>, GeometryError> {
    check_finite_inputs(x, &[point, normal])?;
    let n = unit_or(
        normal,
        GeometryError::InvalidSurface {
            reason: "zero plane normal",
        },
    )?;
    let (e1, e2) = tangent_basis(&n);
    let r = x - point;
    let gap = r.dot(&n);
    Ok(Projection {
        xi: [r.dot(&e1), r.dot(&e2)],
        point: x - n * gap,
        t1: e1,
        t2: e2,
        normal: n,
        gap,
        inside: true,
    })
}

/// Projection onto the outside of the cylinder of the given `radius` around the line through
/// `axis_point` along `axis` (any length; normalised). `ξ = (R θ, s)`, see the module docs.
/// All arguments may be seeded.
///
/// # Errors
/// [`GeometryError::NonFinite`], [`GeometryError::InvalidSurface`] (zero axis, radius not
/// positive), [`GeometryError::AmbiguousProjection`] for a point on the axis.
pub(crate) fn project_on_cylinder<S: Scalar>(
    x: &Vector3<S>,
    axis_point: &Vector3<S>,
    axis: &Vector3<S>,
    radius: S,
) -> Result<Projection<S>, GeometryError> {
    check_finite_inputs(x, &[axis_point, axis])?;
    let rr = radius.value();
    if !(rr > 0.0 && rr.is_finite()) {
        return Err(GeometryError::InvalidSurface {
            reason: "cylinder radius must be positive and finite",
        });
    }
    let a = unit_or(
        axis,
        GeometryError::InvalidSurface {
            reason: "zero cylinder axis",
        },
    )?;
    let r = x - axis_point;
    let s = r.dot(&a);
    let q = r - a * s;
    let rho = safe_norm(&q);
    if !greater(rho.value(), 1e-12 * rr) {
        return Err(GeometryError::AmbiguousProjection {
            reason: "point on the cylinder axis",
        });
    }
    let n = q / rho;
    let (b1, b2) = tangent_basis(&a);
    let theta = q.dot(&b2).atan2(q.dot(&b1));
    Ok(Projection {
        xi: [radius * theta, s],
        point: axis_point + a * s + n * radius,
        t1: a.cross(&n),
        t2: a,
        normal: n,
        gap: rho - radius,
        inside: true,
    })
}

/// Projection onto the axis-aligned rounded box: the Minkowski sum of the inner box of half
/// extents `half_extents − radius` with a sphere of `radius` (`0 ≤ radius ≤ min half extent`).
/// Deep penetration (inside the inner box) projects onto the nearest face. `ξ` is the face chart
/// of the module docs. All arguments may be seeded.
///
/// # Errors
/// [`GeometryError::NonFinite`], [`GeometryError::InvalidSurface`].
pub(crate) fn project_on_rounded_box<S: Scalar>(
    x: &Vector3<S>,
    center: &Vector3<S>,
    half_extents: &Vector3<S>,
    radius: S,
) -> Result<Projection<S>, GeometryError> {
    check_finite_inputs(x, &[center, half_extents])?;
    let rr = radius.value();
    if !(rr >= 0.0 && rr.is_finite()) {
        return Err(GeometryError::InvalidSurface {
            reason: "rounded box radius must be non-negative and finite",
        });
    }
    let b = half_extents.map(|e| e - radius);
    if !b.iter().all(|bi| bi.value() >= 0.0) {
        return Err(GeometryError::InvalidSurface {
            reason: "rounded box radius larger than a half extent",
        });
    }
    let y = x - center;
    // closest point on the inner box, clamp decided on real parts
    let mut q = y;
    let mut outside = false;
    for i in 0..3 {
        if y[i].value() > b[i].value() {
            q[i] = b[i];
            outside = true;
        } else if y[i].value() < -b[i].value() {
            q[i] = -b[i];
            outside = true;
        }
    }
    let (local, normal, gap) = if outside {
        let v = y - q;
        let dist = safe_norm(&v);
        let n = v / dist;
        (q + n * radius, n, dist - radius)
    } else {
        // deep penetration: nearest face of the inner box
        let mut k = 0;
        for i in 1..3 {
            if b[i].value() - y[i].value().abs() < b[k].value() - y[k].value().abs() {
                k = i;
            }
        }
        let sign = if y[k].value() >= 0.0 { 1.0 } else { -1.0 };
        let mut n = Vector3::<S>::zeros();
        n[k] = S::lift(sign);
        let mut p = y;
        p[k] = (b[k] + radius) * sign;
        (p, n, y[k] * sign - b[k] - radius)
    };
    // face chart on the axis of the dominant normal component
    let mut k = 0;
    for i in 1..3 {
        if normal[i].value().abs() > normal[k].value().abs() {
            k = i;
        }
    }
    let (mut i, mut j) = ((k + 1) % 3, (k + 2) % 3);
    if normal[k].value() < 0.0 {
        std::mem::swap(&mut i, &mut j);
    }
    let mut t1 = Vector3::<S>::zeros();
    let mut t2 = Vector3::<S>::zeros();
    t1[i] = S::one();
    t1[k] = -normal[i] / normal[k];
    t2[j] = S::one();
    t2[k] = -normal[j] / normal[k];
    Ok(Projection {
        xi: [local[i], local[j]],
        point: center + local,
        t1,
        t2,
        normal,
        gap,
        inside: true,
    })
}

/// A rigid analytic target surface (scene data in `f64`), moved by a rigid translation `d`.
#[derive(Debug, Clone, PartialEq)]
pub enum RigidSurface {
    /// Plane through `point`; `normal` (any length) points out of the rigid body, towards the
    /// deformable body.
    Plane {
        /// A point of the plane (undisplaced).
        point: Vector3<f64>,
        /// Outward normal (normalised on use).
        normal: Vector3<f64>,
    },
    /// Cylinder, contact on its outside.
    Cylinder {
        /// A point of the axis (undisplaced).
        axis_point: Vector3<f64>,
        /// Axis direction (normalised on use).
        axis: Vector3<f64>,
        /// Radius `R > 0`.
        radius: f64,
    },
    /// Axis-aligned box with rounded edges and corners (Minkowski sum of the inner box
    /// `half_extents − radius` and a sphere of `radius`).
    RoundedBox {
        /// Centre (undisplaced).
        center: Vector3<f64>,
        /// Half extents of the whole (rounded) box.
        half_extents: Vector3<f64>,
        /// Edge/corner radius, `0 ≤ radius ≤ min(half_extents)`.
        radius: f64,
    },
}

impl RigidSurface {
    /// Closest-point projection of `x` onto the surface translated by `d` (both may be seeded).
    ///
    /// # Errors
    /// See [`project_on_plane`], [`project_on_cylinder`], [`project_on_rounded_box`].
    pub(crate) fn project<S: Scalar>(
        &self,
        x: &Vector3<S>,
        d: &Vector3<S>,
    ) -> Result<Projection<S>, GeometryError> {
        match self {
            RigidSurface::Plane { point, normal } => {
                project_on_plane(x, &(lift_vec::<S>(point) + d), &lift_vec(normal))
            }
            RigidSurface::Cylinder {
                axis_point,
                axis,
                radius,
            } => project_on_cylinder(
                x,
                &(lift_vec::<S>(axis_point) + d),
                &lift_vec(axis),
                S::lift(*radius),
            ),
            RigidSurface::RoundedBox {
                center,
                half_extents,
                radius,
            } => project_on_rounded_box(
                x,
                &(lift_vec::<S>(center) + d),
                &lift_vec(half_extents),
                S::lift(*radius),
            ),
        }
    }
}

#[cfg(test)]
#[path = "geometry_tests.rs"]
mod tests;
