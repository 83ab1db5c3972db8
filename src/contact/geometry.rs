//! Contact geometry: closest-point projection of a hitting point onto a target surface.
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
//!   `H_αβ = t_α · t_β − (x − x̄) · x̄_{,αβ}` (a bilinear quad has `x̄_{,12} ≠ 0`);
//! * (10), (11) the variation of (9) at fixed `ξ`-dependence,
//!   `H_αβ dξ^β = t_α · (dx − dx̄|_ξ) + (x − x̄) · dt_α|_ξ`:
//!   this is exactly what the derivative parts of the final Newton correction solve (see below).
//!
//! # Sign conventions
//!
//! * `normal` is the unit outward normal of the *target* body (for a rigid body: pointing towards
//!   the deformable body). For a quad segment it is `t_1 × t_2 / |t_1 × t_2|`, so segments must
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
//! 3. the `hint` segment (previous contact segment, for stability);
//! 4. the lowest segment index.
//!
//! A boundary result reports `inside = false`; its normal is that segment's normal `t_1 × t_2`
//! at the boundary point (the corner's own normal at a node), and `ξ` has one (edge) or two
//! (corner) components at `±1`.
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

use crate::scalar::{lift_vec, re_vec, safe_norm, Scalar};

/// `ξ` tolerance of the "inside" test: `|ξ^α| ≤ 1 + QUAD_INSIDE_TOLERANCE`.
pub const QUAD_INSIDE_TOLERANCE: f64 = 1e-10;

/// Maximum number of closest-point Newton iterations (real parts).
pub const MAX_NEWTON_ITERATIONS: usize = 60;

/// Largest Newton step in `ξ` (half an element).
const MAX_STEP: f64 = 1.0;
/// Converged when a full Newton step is below this (in `ξ`).
const STEP_TOLERANCE: f64 = 1e-13;
/// Converged when the dimensionless residual `|r_α| / ((|x − x̄| + h) h)` is below this.
const RESIDUAL_TOLERANCE: f64 = 1e-15;
/// Relative tolerance of area-type degeneracy checks (relative to `h²`).
const AREA_TOLERANCE: f64 = 1e-10;
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
    pub fn to_real(&self) -> Projection<f64> {
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
    for (node, [a1, a2]) in nodes.iter().zip(XI_NODES) {
        let p1 = xi[0] * a1 + 1.0;
        let p2 = xi[1] * a2 + 1.0;
        x += node * (p1 * p2 * 0.25);
        t1 += node * (p2 * (a1 * 0.25));
        t2 += node * (p1 * (a2 * 0.25));
    }
    QuadPoint { x, t1, t2 }
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

fn real_nodes<S: Scalar>(nodes: &[Vector3<S>; 4]) -> [Vector3<f64>; 4] {
    [
        re_vec(&nodes[0]),
        re_vec(&nodes[1]),
        re_vec(&nodes[2]),
        re_vec(&nodes[3]),
    ]
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

/// Closest-point Newton on the real parts, unconstrained in `ξ` (the bilinear extension).
/// Returns the converged `ξ`.
fn newton_real(
    x: &Vector3<f64>,
    nodes: &[Vector3<f64>; 4],
    h: f64,
    xi_start: [f64; 2],
) -> Result<[f64; 2], GeometryError> {
    let twist = quad_twist(nodes);
    // magnitude of the coordinates: sets the rounding noise of r = x − x̄ (~ ε L)
    let l = nodes.iter().fold(x.amax(), |m, n| m.max(n.amax()));
    let mut xi = xi_start;
    let mut ev = quad_eval(nodes, &xi);
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
        let m11 = ev.t1.dot(&ev.t1);
        let m22 = ev.t2.dot(&ev.t2);
        let m12 = ev.t1.dot(&ev.t2);
        let h12 = m12 - r.dot(&twist);
        let det_h = m11 * m22 - h12 * h12;
        let det_m = m11 * m22 - m12 * m12;
        let mut dir = if det_h > 1e-12 * m11 * m22 {
            // full Newton (H positive definite)
            [
                (m22 * g[0] - h12 * g[1]) / det_h,
                (m11 * g[1] - h12 * g[0]) / det_h,
            ]
        } else if det_m > 1e-14 * m11 * m22 {
            // H indefinite (beyond a focal distance): Levenberg-Marquardt shift H + μM, with
            // μ = 2|λ_min| + 1e-3 from the generalised eigenvalues of (H, M),
            // det(H − λM) = det_m λ² − b λ + det_h = 0
            let b = m11 * m22 + m22 * m11 - 2.0 * h12 * m12;
            let lambda_min = (b - (b * b - 4.0 * det_m * det_h).max(0.0).sqrt()) / (2.0 * det_m);
            let mu = 2.0 * (-lambda_min).max(0.0) + 1e-3;
            let (a11, a22, a12) = (m11 * (1.0 + mu), m22 * (1.0 + mu), h12 + mu * m12);
            let det = a11 * a22 - a12 * a12;
            [
                (a22 * g[0] - a12 * g[1]) / det,
                (a11 * g[1] - a12 * g[0]) / det,
            ]
        } else {
            // fold of the bilinear extension: steepest descent
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
            let ev_t = quad_eval(nodes, &trial);
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

/// Builds the projection at `ξ` (in `S`) on a quad.
fn quad_projection<S: Scalar>(
    x: &Vector3<S>,
    nodes: &[Vector3<S>; 4],
    xi: [S; 2],
    h: f64,
    inside: bool,
) -> Result<Projection<S>, GeometryError> {
    let ev = quad_eval(nodes, &xi);
    let jn = ev.t1.cross(&ev.t2);
    if !greater(safe_norm(&jn).value(), AREA_TOLERANCE * h * h) {
        return Err(GeometryError::DegenerateSegment {
            reason: "the bilinear map folds at the projection point",
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
    nodes: &[Vector3<S>; 4],
    xi0: [f64; 2],
    h: f64,
) -> Result<Projection<S>, GeometryError> {
    let xi_c = [S::lift(xi0[0]), S::lift(xi0[1])];
    let ev = quad_eval(nodes, &xi_c);
    let r = x - ev.x;
    let g1 = r.dot(&ev.t1);
    let g2 = r.dot(&ev.t2);
    let h11 = ev.t1.dot(&ev.t1);
    let h22 = ev.t2.dot(&ev.t2);
    let h12 = ev.t1.dot(&ev.t2) - r.dot(&quad_twist(nodes));
    let det = h11 * h22 - h12 * h12;
    if !greater(det.value(), 1e-12 * h11.value() * h22.value()) {
        return Err(GeometryError::AmbiguousProjection {
            reason: "singular closest-point matrix (point at a focal point of the segment)",
        });
    }
    let xi = [
        xi_c[0] + (h22 * g1 - h12 * g2) / det,
        xi_c[1] + (h11 * g2 - h12 * g1) / det,
    ];
    let lim = 1.0 + QUAD_INSIDE_TOLERANCE;
    let inside = xi[0].value().abs() <= lim && xi[1].value().abs() <= lim;
    quad_projection(x, nodes, xi, h, inside)
}

/// Closest-point projection of `x` onto the bilinear quad `nodes` (counter-clockwise seen from
/// outside), by Newton in convected coordinates from `xi_start`.
///
/// The projection is onto the bilinear extension of the segment (`ξ` unconstrained); `inside`
/// tells whether `|ξ^α| ≤ 1 + 1e-10`. See the module docs for the derivative scheme.
///
/// # Errors
/// [`GeometryError::NonFinite`] (NaN/inf input), [`GeometryError::DegenerateSegment`]
/// (coincident/collinear nodes, zero area, re-entrant corner, fold at the projection point),
/// [`GeometryError::NoConvergence`], [`GeometryError::AmbiguousProjection`] (singular Newton
/// matrix at the solution).
pub fn project_on_quad<S: Scalar>(
    x: &Vector3<S>,
    nodes: &[Vector3<S>; 4],
    xi_start: [f64; 2],
) -> Result<Projection<S>, GeometryError> {
    let xr = re_vec(x);
    if !finite_vec(&xr) {
        return Err(GeometryError::NonFinite {
            what: "hitting point",
        });
    }
    if !(xi_start[0].is_finite() && xi_start[1].is_finite()) {
        return Err(GeometryError::NonFinite { what: "xi_start" });
    }
    let h = check_segment(&real_nodes(nodes))?;
    let (xl, nl, c) = localized(x, nodes);
    let xi0 = newton_real(&re_vec(&xl), &real_nodes(&nl), h, xi_start)?;
    let mut p = finish_interior(&xl, &nl, xi0, h)?;
    p.point += c;
    Ok(p)
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
    if !c.interior() && (c.align - best.align).abs() > 1e-12 {
        return c.align > best.align;
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
pub const SEGMENT_KEEP: f64 = 0.1;

/// [`closest_on_quads`], except that segment `keep` is kept while `x` projects onto its
/// interior or within [`SEGMENT_KEEP`] outside it (in `ξ`): hysteresis of the segment choice
/// against the last converged state.
///
/// # Errors
/// Those of [`closest_on_quads`].
pub fn closest_on_quads_keeping<S: Scalar>(
    x: &Vector3<S>,
    quads: &[[Vector3<S>; 4]],
    keep: Option<usize>,
) -> Result<(usize, Projection<S>), GeometryError> {
    if let Some(k) = keep.filter(|&k| k < quads.len()) {
        let xr = re_vec(x);
        let quad = real_nodes(&quads[k]);
        if let (true, Ok(h)) = (finite_vec(&xr), check_segment(&quad)) {
            let (xl, nl, _) = localized(&xr, &quad);
            if let Ok(xi) = newton_real(&xl, &nl, h, [0.0, 0.0]) {
                let lim = 1.0 + SEGMENT_KEEP;
                if xi[0].abs() <= lim && xi[1].abs() <= lim {
                    let (xs, ns, c) = localized(x, &quads[k]);
                    let mut p = finish_interior(&xs, &ns, xi, h)?;
                    p.point += c;
                    return Ok((k, p));
                }
            }
        }
    }
    closest_on_quads(x, quads, keep)
}

/// Closest point of `x` on a set of quad segments, with segment switching for large sliding.
///
/// Returns the index of the chosen segment and the projection onto it. The rule (closest point
/// on the union of the closed segments, interior before boundary, best-aligned normal at shared
/// edges, then `hint`, then lowest index) is given in the module docs. For a boundary result
/// `inside = false` and the normal is the segment normal at the boundary point.
///
/// # Errors
/// [`GeometryError::NoSegments`], [`GeometryError::NonFinite`] for a non-finite `x`,
/// [`GeometryError::Segment`] when a segment is invalid (non-finite, degenerate), and the errors
/// of the final evaluation of the chosen candidate.
pub fn closest_on_quads<S: Scalar>(
    x: &Vector3<S>,
    quads: &[[Vector3<S>; 4]],
    hint: Option<usize>,
) -> Result<(usize, Projection<S>), GeometryError> {
    if quads.is_empty() {
        return Err(GeometryError::NoSegments);
    }
    let xr = re_vec(x);
    if !finite_vec(&xr) {
        return Err(GeometryError::NonFinite {
            what: "hitting point",
        });
    }
    let lim = 1.0 + QUAD_INSIDE_TOLERANCE;
    let mut best: Option<Candidate> = None;
    let mut offer = |c: Candidate| match &best {
        Some(b) if !prefer(&c, b, hint) => {}
        _ => best = Some(c),
    };
    for (index, quad) in quads.iter().enumerate() {
        let h = check_segment(&real_nodes(quad)).map_err(|e| GeometryError::Segment {
            index,
            source: Box::new(e),
        })?;
        let (xr, nr, _) = localized(&xr, &real_nodes(quad));
        // interior stationary point (a failed or outside unconstrained projection only means
        // that this segment offers its boundary point)
        if let Ok(xi) = newton_real(&xr, &nr, h, [0.0, 0.0]) {
            if xi[0].abs() <= lim && xi[1].abs() <= lim {
                let dist = (xr - quad_eval(&nr, &xi).x).norm();
                offer(Candidate {
                    index,
                    h,
                    dist,
                    align: 1.0,
                    kind: CandidateKind::Interior(xi),
                });
            }
        }
        let (edge, u, dist) = boundary_real(&xr, &nr);
        let xi = boundary_xi(&xr, &nr, edge, u);
        let ev = quad_eval(&nr, &xi);
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
    let (xl, nl, c) = localized(x, &quads[best.index]);
    let mut projection = match best.kind {
        CandidateKind::Interior(xi0) => {
            let mut p = finish_interior(&xl, &nl, xi0, best.h)?;
            p.inside = true;
            p
        }
        CandidateKind::Boundary { edge, u } => {
            let xi = boundary_xi(&xl, &nl, edge, u);
            quad_projection(&xl, &nl, xi, best.h, false)?
        }
    };
    projection.point += c;
    Ok((best.index, projection))
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
pub fn project_on_plane<S: Scalar>(
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
pub fn project_on_cylinder<S: Scalar>(
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
pub fn project_on_rounded_box<S: Scalar>(
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
    pub fn project<S: Scalar>(
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
mod tests {
    use super::*;
    use nalgebra::Rotation3;
    use num_dual::{Dual64, DualSVec64};
    use proptest::prelude::*;

    type V3 = Vector3<f64>;

    /// Central finite-difference step (quantities of order one).
    const FD_STEP: f64 = 1e-6;

    /// Independent bilinear interpolation for the oracles.
    fn bilinear(q: &[V3; 4], a: f64, b: f64) -> V3 {
        (q[0] * ((1.0 - a) * (1.0 - b))
            + q[1] * ((1.0 + a) * (1.0 - b))
            + q[2] * ((1.0 + a) * (1.0 + b))
            + q[3] * ((1.0 - a) * (1.0 + b)))
            * 0.25
    }

    /// Brute force: distance from `x` to the closed quad by a dense grid over `[-1, 1]²` then a
    /// compass search (step halved down to 1e-14), clamped to the square.
    fn brute_force_distance(x: &V3, q: &[V3; 4], n: usize) -> f64 {
        let d = |a: f64, b: f64| (x - bilinear(q, a, b)).norm();
        let mut best = (0.0, 0.0, f64::INFINITY);
        for i in 0..=n {
            for j in 0..=n {
                let a = -1.0 + 2.0 * i as f64 / n as f64;
                let b = -1.0 + 2.0 * j as f64 / n as f64;
                let v = d(a, b);
                if v < best.2 {
                    best = (a, b, v);
                }
            }
        }
        let mut step = 2.0 / n as f64;
        let dirs = [
            (1.0, 0.0),
            (-1.0, 0.0),
            (0.0, 1.0),
            (0.0, -1.0),
            (1.0, 1.0),
            (-1.0, -1.0),
            (1.0, -1.0),
            (-1.0, 1.0),
        ];
        while step > 1e-14 {
            let mut improved = true;
            while improved {
                improved = false;
                for (da, db) in dirs {
                    let a = (best.0 + step * da).clamp(-1.0, 1.0);
                    let b = (best.1 + step * db).clamp(-1.0, 1.0);
                    let v = d(a, b);
                    if v < best.2 {
                        best = (a, b, v);
                        improved = true;
                    }
                }
            }
            step *= 0.5;
        }
        best.2
    }

    fn lift_quad<S: Scalar>(q: &[V3; 4]) -> [Vector3<S>; 4] {
        [
            lift_vec(&q[0]),
            lift_vec(&q[1]),
            lift_vec(&q[2]),
            lift_vec(&q[3]),
        ]
    }

    /// All real outputs of a projection, in a fixed order.
    fn values(p: &Projection<f64>) -> Vec<f64> {
        let mut v = vec![p.xi[0], p.xi[1], p.gap];
        for w in [&p.point, &p.normal, &p.t1, &p.t2] {
            v.extend(w.iter().copied());
        }
        v
    }

    /// Derivative part `k` of all outputs, same order as [`values`].
    fn parts<S: Scalar>(p: &Projection<S>, k: usize) -> Vec<f64> {
        let mut v = vec![p.xi[0].part(k), p.xi[1].part(k), p.gap.part(k)];
        for w in [&p.point, &p.normal, &p.t1, &p.t2] {
            v.extend(w.iter().map(|c| c.part(k)));
        }
        v
    }

    /// Central differences of `f` (f64 outputs) for a scalar perturbation.
    fn central_fd(f: impl Fn(f64) -> Projection<f64>) -> Vec<f64> {
        let plus = values(&f(FD_STEP));
        let minus = values(&f(-FD_STEP));
        plus.iter()
            .zip(&minus)
            .map(|(p, m)| (p - m) / (2.0 * FD_STEP))
            .collect()
    }

    /// Dual vs finite difference: 1e-7 relative; the 1e-9 absolute floor covers derivatives
    /// that are exactly zero, where the FD quotient is rounding noise (~1e-16/1e-6).
    fn assert_derivatives(ad: &[f64], fd: &[f64], what: &str) {
        for (i, (a, f)) in ad.iter().zip(fd).enumerate() {
            assert!(
                (a - f).abs() <= 1e-7 * a.abs().max(f.abs()) + 1e-9,
                "{what}: output {i}: dual {a:e} vs fd {f:e}"
            );
        }
    }

    /// Real part of a dual evaluation equals the f64 evaluation (1e-14 relative). Not bit-equal:
    /// num-dual divides as `re * recip(other.re)`, one rounding away from f64 `/`; the 1e-16
    /// absolute floor covers components that are zero in exact arithmetic (outputs are O(1)).
    fn assert_same_real(a: &Projection<f64>, b: &Projection<f64>, what: &str) {
        for (i, (x, y)) in values(a).iter().zip(values(b)).enumerate() {
            assert!(
                (x - y).abs() <= 1e-14 * x.abs().max(y.abs()) + 1e-16,
                "{what}: output {i}: {x:e} vs {y:e}"
            );
        }
        assert_eq!(a.inside, b.inside, "{what}: inside flag");
    }

    /// Residual of eq. (9), `(x − x̄)·t_α`, and the distance.
    fn residual_and_distance(x: &V3, p: &Projection<f64>) -> ([f64; 2], f64) {
        let r = x - p.point;
        ([r.dot(&p.t1), r.dot(&p.t2)], r.norm())
    }

    fn flat_quad() -> [V3; 4] {
        // irregular convex quad in a tilted plane
        let rot = Rotation3::from_euler_angles(0.3, -0.2, 0.7);
        [
            rot * V3::new(-1.1, -0.9, 0.0) + V3::new(0.2, 0.1, 0.3),
            rot * V3::new(1.0, -1.2, 0.0) + V3::new(0.2, 0.1, 0.3),
            rot * V3::new(1.3, 0.8, 0.0) + V3::new(0.2, 0.1, 0.3),
            rot * V3::new(-0.8, 1.1, 0.0) + V3::new(0.2, 0.1, 0.3),
        ]
    }

    fn warped_quad() -> [V3; 4] {
        [
            V3::new(-1.0, -1.1, 0.15),
            V3::new(1.2, -0.9, -0.2),
            V3::new(0.9, 1.0, 0.25),
            V3::new(-1.1, 0.8, -0.1),
        ]
    }

    #[test]
    fn flat_and_warped_quad_satisfy_orthogonality_and_match_brute_force() {
        let points = [
            V3::new(0.3, -0.2, 0.8),
            V3::new(-0.5, 0.4, -0.6),
            V3::new(0.1, 0.7, 0.05),
            V3::new(0.6, -0.6, 1.5),
        ];
        for (name, q) in [("flat", flat_quad()), ("warped", warped_quad())] {
            for x in &points {
                let p = project_on_quad(x, &q, [0.0, 0.0]).unwrap();
                assert!(p.inside, "{name}: test points project inside");
                let (res, dist) = residual_and_distance(x, &p);
                assert!(
                    res[0].abs() < 1e-12 && res[1].abs() < 1e-12,
                    "{name}: {res:?}"
                );
                let bf = brute_force_distance(x, &q, 200);
                assert!(
                    (dist - bf).abs() <= 1e-10 * bf,
                    "{name}: newton {dist} vs brute force {bf}"
                );
                // interior closest point: the gap is the signed distance
                assert!((p.gap.abs() - dist).abs() <= 1e-12);
                // the point is on the bilinear surface at xi, and the normal is unit
                assert!((bilinear(&q, p.xi[0], p.xi[1]) - p.point).norm() < 1e-14);
                assert!((p.normal.norm() - 1.0).abs() < 1e-14);
                // t_α are ∂x̄/∂ξ^α (central differences of the independent interpolation)
                let h = 1e-6;
                let d1 = (bilinear(&q, p.xi[0] + h, p.xi[1]) - bilinear(&q, p.xi[0] - h, p.xi[1]))
                    / (2.0 * h);
                let d2 = (bilinear(&q, p.xi[0], p.xi[1] + h) - bilinear(&q, p.xi[0], p.xi[1] - h))
                    / (2.0 * h);
                assert!((d1 - p.t1).norm() < 1e-9 && (d2 - p.t2).norm() < 1e-9);
            }
        }
        // a flat quad: gap is the signed height over the plane
        let q = flat_quad();
        let n = (q[1] - q[0]).cross(&(q[3] - q[0])).normalize();
        let x = bilinear(&q, 0.2, -0.3) + n * 0.7;
        let p = project_on_quad(&x, &q, [0.9, 0.9]).unwrap();
        assert!((p.gap - 0.7).abs() < 1e-13);
        assert!((p.xi[0] - 0.2).abs() < 1e-13 && (p.xi[1] + 0.3).abs() < 1e-13);
        assert!((p.normal - n).norm() < 1e-13);
    }

    #[test]
    fn projection_outside_the_element_reports_outside() {
        let q = warped_quad();
        let p = project_on_quad(&V3::new(2.5, 0.2, 0.4), &q, [0.0, 0.0]).unwrap();
        assert!(!p.inside && p.xi[0] > 1.0);
        let (res, _) = residual_and_distance(&V3::new(2.5, 0.2, 0.4), &p);
        assert!(res[0].abs() < 1e-12 && res[1].abs() < 1e-12);
        // the search clamps to the boundary and agrees with the brute force
        let x = V3::new(2.5, 0.2, 0.4);
        let (i, p) = closest_on_quads(&x, &[q], None).unwrap();
        assert_eq!(i, 0);
        assert!(!p.inside && p.xi[0] == 1.0);
        let bf = brute_force_distance(&x, &q, 200);
        assert!(((x - p.point).norm() - bf).abs() <= 1e-10 * bf);
    }

    /// Random convex quad: jittered square, optionally warped, scaled, rotated, translated.
    fn random_quad(
        jitter: &[f64; 8],
        warp: &[f64; 4],
        planar: bool,
        angles: &[f64; 3],
        scale: f64,
        shift: &[f64; 3],
    ) -> [V3; 4] {
        let rot = Rotation3::from_euler_angles(angles[0], angles[1], angles[2]);
        let t = V3::new(shift[0], shift[1], shift[2]);
        let mut q = [V3::zeros(); 4];
        for (a, node) in q.iter_mut().enumerate() {
            let [s1, s2] = XI_NODES[a];
            let w = if planar { 0.0 } else { warp[a] };
            let local = V3::new(s1 + jitter[2 * a], s2 + jitter[2 * a + 1], w);
            *node = rot * local * scale + t;
        }
        q
    }

    fn arr8() -> impl Strategy<Value = [f64; 8]> {
        prop::array::uniform8(-0.3f64..0.3)
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(256))]

        #[test]
        fn random_quads_closest_point_matches_brute_force(
            jitter in arr8(),
            warp in prop::array::uniform4(-0.2f64..0.2),
            planar in any::<bool>(),
            angles in prop::array::uniform3(-3.1f64..3.1),
            scale in 0.5f64..2.0,
            shift in prop::array::uniform3(-2.0f64..2.0),
            xi in prop::array::uniform2(-1.6f64..1.6),
            offset in 0.02f64..0.6,
            below in any::<bool>(),
        ) {
            let q = random_quad(&jitter, &warp, planar, &angles, scale, &shift);
            let foot = bilinear(&q, xi[0], xi[1]);
            let t1 = (bilinear(&q, xi[0] + 1e-5, xi[1]) - bilinear(&q, xi[0] - 1e-5, xi[1])) / 2e-5;
            let t2 = (bilinear(&q, xi[0], xi[1] + 1e-5) - bilinear(&q, xi[0], xi[1] - 1e-5)) / 2e-5;
            let n = t1.cross(&t2).normalize();
            let sign = if below { -1.0 } else { 1.0 };
            let x = foot + n * (sign * offset * scale);
            let (i, p) = closest_on_quads(&x, &[q], None).unwrap();
            prop_assert_eq!(i, 0);
            let dist = (x - p.point).norm();
            let bf = brute_force_distance(&x, &q, 100);
            prop_assert!((dist - bf).abs() <= 1e-10 * bf, "search {} vs brute force {}", dist, bf);
            if p.inside {
                let (res, _) = residual_and_distance(&x, &p);
                prop_assert!(res[0].abs().max(res[1].abs()) <= 1e-12 * scale * scale);
            } else {
                prop_assert!(p.xi[0].abs() == 1.0 || p.xi[1].abs() == 1.0);
            }
            // the unconstrained projection, when inside, is the same closest point
            let u = project_on_quad(&x, &q, [0.0, 0.0]).unwrap();
            if u.inside {
                prop_assert!(((x - u.point).norm() - bf).abs() <= 1e-10 * bf);
            }
        }

        #[test]
        fn degenerate_input_never_panics(
            jitter in arr8(),
            angles in prop::array::uniform3(-3.1f64..3.1),
            which in 0usize..6,
            i in 0usize..4,
            j in 0usize..4,
            c in 0usize..3,
            line in prop::array::uniform4(-2.0f64..2.0),
            xv in prop::array::uniform3(-2.0f64..2.0),
        ) {
            let mut q = random_quad(&jitter, &[0.0; 4], true, &angles, 1.0, &[0.0; 3]);
            let mut x = V3::new(xv[0], xv[1], xv[2]);
            let dir = V3::new(0.3, -0.5, 0.8);
            let expect_err = match which {
                0 => { if i != j { q[j] = q[i]; } i != j }            // coincident nodes
                1 => { for (a, node) in q.iter_mut().enumerate() { *node = dir * line[a]; } true } // collinear
                2 => { q[i][c] = f64::NAN; true }                    // NaN node
                3 => { x[c] = f64::NAN; true }                       // NaN point
                4 => { q = [q[0]; 4]; true }                          // all coincide
                _ => { q.swap(i, j); i != j && (i + j) % 2 == 1 } // adjacent swap: bow-tie; diagonal swap: reversed but valid
            };
            let r64 = project_on_quad(&x, &q, [0.0, 0.0]);
            let s64 = closest_on_quads(&x, &[q, q], Some(1));
            let qd = lift_quad::<Dual64>(&q);
            let xd: Vector3<Dual64> = lift_vec(&x);
            let rd = project_on_quad(&xd, &qd, [0.0, 0.0]);
            let sd = closest_on_quads(&xd, &[qd], None);
            if expect_err {
                prop_assert!(r64.is_err() && s64.is_err() && rd.is_err() && sd.is_err());
            }
            // rigid surfaces with bad parameters: errors, no panic
            let bad = [
                RigidSurface::Plane { point: V3::zeros(), normal: V3::zeros() },
                RigidSurface::Cylinder { axis_point: V3::zeros(), axis: V3::z(), radius: -1.0 },
                RigidSurface::Cylinder { axis_point: V3::zeros(), axis: V3::zeros(), radius: 1.0 },
                RigidSurface::RoundedBox { center: V3::zeros(), half_extents: V3::new(1.0, 0.1, 1.0), radius: 0.5 },
                RigidSurface::RoundedBox { center: V3::zeros(), half_extents: V3::repeat(1.0), radius: f64::NAN },
            ];
            for s in &bad {
                prop_assert!(s.project(&x, &V3::zeros()).is_err());
            }
        }
    }

    #[test]
    fn degenerate_segments_are_typed_errors() {
        let q = flat_quad();
        let x = V3::new(0.1, 0.2, 0.5);
        let mut coincident = q;
        coincident[2] = coincident[1];
        assert!(matches!(
            project_on_quad(&x, &coincident, [0.0, 0.0]),
            Err(GeometryError::DegenerateSegment { .. })
        ));
        let collinear = [V3::zeros(), V3::x(), V3::x() * 2.0, V3::x() * 3.0];
        assert!(matches!(
            project_on_quad(&x, &collinear, [0.0, 0.0]),
            Err(GeometryError::DegenerateSegment { .. })
        ));
        let mut bow_tie = q;
        bow_tie.swap(2, 3);
        assert!(matches!(
            project_on_quad(&x, &bow_tie, [0.0, 0.0]),
            Err(GeometryError::DegenerateSegment { .. })
        ));
        let mut nan = q;
        nan[3].y = f64::NAN;
        assert!(matches!(
            project_on_quad(&x, &nan, [0.0, 0.0]),
            Err(GeometryError::NonFinite { .. })
        ));
        assert!(matches!(
            closest_on_quads(&x, &[q, nan], None),
            Err(GeometryError::Segment { index: 1, .. })
        ));
        assert!(matches!(
            closest_on_quads::<f64>(&x, &[], None),
            Err(GeometryError::NoSegments)
        ));
        let cyl = RigidSurface::Cylinder {
            axis_point: V3::zeros(),
            axis: V3::z(),
            radius: 1.0,
        };
        assert!(matches!(
            cyl.project(&V3::new(0.0, 0.0, 3.0), &V3::zeros()),
            Err(GeometryError::AmbiguousProjection { .. })
        ));
    }

    #[test]
    fn quad_derivatives_wrt_point_match_finite_differences() {
        for q in [flat_quad(), warped_quad()] {
            let x0 = V3::new(0.3, -0.2, 0.8);
            let xs = Vector3::from_fn(|k, _| DualSVec64::<3>::seeded(x0[k], k));
            let qs = lift_quad::<DualSVec64<3>>(&q);
            let pd = project_on_quad(&xs, &qs, [0.0, 0.0]).unwrap();
            let p64 = project_on_quad(&x0, &q, [0.0, 0.0]).unwrap();
            assert_same_real(&pd.to_real(), &p64, "DualSVec64 real part");
            for k in 0..3 {
                let fd = central_fd(|h| {
                    let mut x = x0;
                    x[k] += h;
                    project_on_quad(&x, &q, [0.0, 0.0]).unwrap()
                });
                assert_derivatives(&parts(&pd, k), &fd, "d/dx");
            }
        }
    }

    #[test]
    fn quad_derivatives_wrt_node_coordinates_match_finite_differences() {
        let q = warped_quad();
        let x0 = V3::new(-0.4, 0.5, -0.7);
        for (node, comp) in [(2, 2), (1, 0), (3, 1)] {
            let mut qd = lift_quad::<Dual64>(&q);
            qd[node][comp] = Dual64::new(q[node][comp], 1.0);
            let pd = project_on_quad(&lift_vec(&x0), &qd, [0.0, 0.0]).unwrap();
            let p64 = project_on_quad(&x0, &q, [0.0, 0.0]).unwrap();
            assert_same_real(&pd.to_real(), &p64, "Dual64 real part");
            let fd = central_fd(|h| {
                let mut qq = q;
                qq[node][comp] += h;
                project_on_quad(&x0, &qq, [0.0, 0.0]).unwrap()
            });
            assert_derivatives(&parts(&pd, 0), &fd, "d/dnode");
        }
    }

    #[test]
    fn boundary_projection_derivatives_match_finite_differences() {
        let q = warped_quad();
        // over an edge (xi2 clamped) and over a corner (both clamped)
        for x0 in [V3::new(0.2, -2.0, 0.5), V3::new(2.0, 1.7, 0.6)] {
            let p64 = closest_on_quads(&x0, &[q], None).unwrap().1;
            assert!(!p64.inside);
            // seed the point (3 parts) and one node coordinate (part 3)
            let xs = Vector3::from_fn(|k, _| DualSVec64::<4>::seeded(x0[k], k));
            let mut qs = lift_quad::<DualSVec64<4>>(&q);
            qs[1][0] = DualSVec64::<4>::seeded(q[1][0], 3);
            let pd = closest_on_quads(&xs, &[qs], None).unwrap().1;
            assert_same_real(&pd.to_real(), &p64, "boundary real part");
            for k in 0..4 {
                let fd = central_fd(|h| {
                    let (mut x, mut qq) = (x0, q);
                    if k < 3 {
                        x[k] += h;
                    } else {
                        qq[1][0] += h;
                    }
                    closest_on_quads(&x, &[qq], None).unwrap().1
                });
                assert_derivatives(&parts(&pd, k), &fd, "boundary d/dp");
            }
        }
    }

    #[test]
    fn tangents_are_derivatives_of_the_point_wrt_xi() {
        // point = X(ξ(x)) ⇒ d point/dx_k = t_1 dξ^1/dx_k + t_2 dξ^2/dx_k on every surface
        let x0 = V3::new(1.9, 0.95, 1.2);
        let xs = Vector3::from_fn(|k, _| DualSVec64::<3>::seeded(x0[k], k));
        let d = lift_vec::<DualSVec64<3>>(&V3::new(0.05, -0.02, 0.1));
        let surfaces = [
            RigidSurface::Plane {
                point: V3::new(0.0, 0.0, 0.3),
                normal: V3::new(0.2, -0.4, 1.0),
            },
            RigidSurface::Cylinder {
                axis_point: V3::new(0.1, 0.0, 0.0),
                axis: V3::new(0.1, 1.0, 0.2),
                radius: 0.7,
            },
            RigidSurface::RoundedBox {
                center: V3::zeros(),
                half_extents: V3::new(2.0, 1.0, 1.0),
                radius: 0.25,
            },
        ];
        let mut projections: Vec<Projection<DualSVec64<3>>> = surfaces
            .iter()
            .map(|s| s.project(&xs, &d).unwrap())
            .collect();
        let qs = lift_quad::<DualSVec64<3>>(&warped_quad());
        projections.push(
            project_on_quad(&(xs - lift_vec(&V3::new(1.5, 0.5, 0.0))), &qs, [0.0; 2]).unwrap(),
        );
        for p in &projections {
            for k in 0..3 {
                let dp = p.point.map(|c| c.part(k));
                let chain = re_vec(&p.t1) * p.xi[0].part(k) + re_vec(&p.t2) * p.xi[1].part(k);
                assert!((dp - chain).norm() < 1e-12, "{dp} vs {chain}");
            }
            let n = re_vec(&p.t1).cross(&re_vec(&p.t2)).normalize();
            assert!(
                (n - re_vec(&p.normal)).norm() < 1e-12,
                "t1 x t2 along the normal"
            );
        }
    }

    #[test]
    fn plane_gap_and_normal_closed_form() {
        let plane = RigidSurface::Plane {
            point: V3::new(0.0, 0.0, 1.0),
            normal: V3::new(0.0, 0.0, 2.0),
        };
        let d = V3::new(0.1, 0.2, 0.3);
        let p = plane.project(&V3::new(1.0, 2.0, 5.0), &d).unwrap();
        assert!((p.gap - 3.7).abs() < 1e-14);
        assert!((p.normal - V3::z()).norm() < 1e-15);
        assert!((p.point - V3::new(1.0, 2.0, 1.3)).norm() < 1e-14);
        // material coordinates: e1 = x axis, e2 = y axis, relative to the moved point
        assert!((p.xi[0] - 0.9).abs() < 1e-14 && (p.xi[1] - 1.8).abs() < 1e-14);
        // tilted plane, penetration
        let n = V3::new(1.0, 1.0, 1.0) / 3f64.sqrt();
        let tilted = RigidSurface::Plane {
            point: V3::new(1.0, 0.0, 0.0),
            normal: n * 5.0,
        };
        let x = V3::new(0.2, 0.1, -0.3);
        let p = tilted.project(&x, &V3::zeros()).unwrap();
        assert!((p.gap - (0.2 + 0.1 - 0.3 - 1.0) / 3f64.sqrt()).abs() < 1e-14);
        assert!((p.normal - n).norm() < 1e-15);
    }

    #[test]
    fn cylinder_gap_and_normal_closed_form() {
        let cyl = RigidSurface::Cylinder {
            axis_point: V3::zeros(),
            axis: V3::new(0.0, 0.0, 3.0),
            radius: 2.0,
        };
        let p = cyl.project(&V3::new(3.0, 4.0, 7.0), &V3::zeros()).unwrap();
        assert!((p.gap - 3.0).abs() < 1e-14);
        assert!((p.normal - V3::new(0.6, 0.8, 0.0)).norm() < 1e-15);
        assert!((p.point - V3::new(1.2, 1.6, 7.0)).norm() < 1e-14);
        // ξ = (R θ, s): θ from the x axis towards y for the z axis
        assert!((p.xi[0] - 2.0 * 0.8f64.atan2(0.6)).abs() < 1e-14);
        assert!((p.xi[1] - 7.0).abs() < 1e-14);
        assert!((p.t1 - V3::new(-0.8, 0.6, 0.0)).norm() < 1e-15 && p.t2 == V3::z());
        // moved by d, penetrating
        let d = V3::new(1.0, -1.0, 0.5);
        let p = cyl.project(&V3::new(1.0 + 1.5, -1.0, 0.0), &d).unwrap();
        assert!((p.gap + 0.5).abs() < 1e-14 && (p.normal - V3::x()).norm() < 1e-15);
        assert!((p.xi[1] + 0.5).abs() < 1e-14);
    }

    #[test]
    fn rounded_box_gap_and_normal_closed_form() {
        let bx = RigidSurface::RoundedBox {
            center: V3::zeros(),
            half_extents: V3::new(2.0, 1.0, 1.0),
            radius: 0.25,
        };
        let z = V3::zeros();
        // flat face
        let p = bx.project(&V3::new(0.3, 0.2, 1.5), &z).unwrap();
        assert!((p.gap - 0.5).abs() < 1e-14 && (p.normal - V3::z()).norm() < 1e-15);
        assert!((p.point - V3::new(0.3, 0.2, 1.0)).norm() < 1e-15);
        assert!((p.xi[0] - 0.3).abs() < 1e-15 && (p.xi[1] - 0.2).abs() < 1e-15);
        // near the rounded corner: inner corner (1.75, 0.75, 0.75)
        let x = V3::new(2.0, 1.0, 1.2);
        let v = V3::new(0.25, 0.25, 0.45);
        let p = bx.project(&x, &z).unwrap();
        assert!((p.gap - (v.norm() - 0.25)).abs() < 1e-14);
        assert!((p.normal - v.normalize()).norm() < 1e-15);
        assert!((p.point - (V3::new(1.75, 0.75, 0.75) + v.normalize() * 0.25)).norm() < 1e-14);
        // rounded edge, penetrating but outside the inner box
        let p = bx.project(&V3::new(1.9, 0.2, 0.9), &z).unwrap();
        assert!((p.gap - (0.15 * 2f64.sqrt() - 0.25)).abs() < 1e-14);
        assert!((p.normal - V3::new(1.0, 0.0, 1.0).normalize()).norm() < 1e-15);
        // deep penetration (inside the inner box): nearest face x = +2, moved by d
        let d = V3::new(0.05, -0.02, 0.1);
        let p = bx.project(&(V3::new(1.6, 0.1, 0.2) + d), &d).unwrap();
        assert!((p.gap + 0.4).abs() < 1e-14 && (p.normal - V3::x()).norm() < 1e-15);
        assert!((p.point - (V3::new(2.0, 0.1, 0.2) + d)).norm() < 1e-14);
        // continuity of the gap across the inner-box boundary (face z = 0.75)
        let a = bx.project(&V3::new(0.1, 0.1, 0.75 + 1e-12), &z).unwrap();
        let b = bx.project(&V3::new(0.1, 0.1, 0.75 - 1e-12), &z).unwrap();
        assert!((a.gap - b.gap).abs() < 1e-11 && (a.gap + 0.25).abs() < 1e-11);
    }

    #[test]
    fn rigid_derivatives_wrt_translation_and_point_match_finite_differences() {
        let surfaces = [
            RigidSurface::Plane {
                point: V3::new(0.0, 0.0, 0.3),
                normal: V3::new(0.2, -0.4, 1.0),
            },
            RigidSurface::Cylinder {
                axis_point: V3::new(0.1, 0.0, 0.0),
                axis: V3::new(0.1, 1.0, 0.2),
                radius: 0.7,
            },
            RigidSurface::RoundedBox {
                center: V3::zeros(),
                half_extents: V3::new(2.0, 1.0, 1.0),
                radius: 0.25,
            },
        ];
        let points = [
            V3::new(1.9, 0.95, 1.2),  // rounded corner
            V3::new(1.95, 0.3, 0.95), // rounded edge (y_z − d_z = 0.85 > 0.75)
            V3::new(1.6, 0.1, 0.2),   // deep
            V3::new(0.4, -0.2, 1.3),  // face
        ];
        let d0 = V3::new(0.05, -0.02, 0.1);
        for s in &surfaces {
            for x0 in &points {
                // parts 0..3: x; parts 3..6: d
                let xs = Vector3::from_fn(|k, _| DualSVec64::<6>::seeded(x0[k], k));
                let ds = Vector3::from_fn(|k, _| DualSVec64::<6>::seeded(d0[k], k + 3));
                let pd = s.project(&xs, &ds).unwrap();
                let p64 = s.project(x0, &d0).unwrap();
                assert_same_real(&pd.to_real(), &p64, "rigid real part");
                let pd1 = s
                    .project(&lift_vec::<Dual64>(x0), &d0.map(|c| Dual64::new(c, 1.0)))
                    .unwrap();
                assert_same_real(&pd1.to_real(), &p64, "rigid Dual64 real part");
                for k in 0..6 {
                    let fd = central_fd(|h| {
                        let (mut x, mut d) = (*x0, d0);
                        if k < 3 {
                            x[k] += h;
                        } else {
                            d[k - 3] += h;
                        }
                        s.project(&x, &d).unwrap()
                    });
                    assert_derivatives(&parts(&pd, k), &fd, "rigid d/dp");
                }
                // Dual64 seeding d along (1,1,1) is the sum of the three directional parts
                let sum: Vec<f64> = (3..6).map(|k| parts(&pd, k)).fold(vec![0.0; 15], |a, b| {
                    a.iter().zip(&b).map(|(u, v)| u + v).collect()
                });
                assert_derivatives(&parts(&pd1, 0), &sum, "Dual64 vs DualSVec64");
            }
        }
    }

    #[test]
    fn rounded_box_derivatives_wrt_shape_parameters() {
        // optional generic parameters: radius and half extents seeded
        let x0 = V3::new(1.9, 0.95, 1.2);
        let he = V3::new(2.0, 1.0, 1.0);
        let pd = project_on_rounded_box(
            &lift_vec::<DualSVec64<2>>(&x0),
            &Vector3::zeros(),
            &Vector3::new(
                DualSVec64::<2>::seeded(he.x, 1),
                DualSVec64::from(he.y),
                DualSVec64::from(he.z),
            ),
            DualSVec64::<2>::seeded(0.25, 0),
        )
        .unwrap();
        for k in 0..2 {
            let fd = central_fd(|h| {
                let (mut he, mut r) = (he, 0.25);
                if k == 0 {
                    r += h;
                } else {
                    he.x += h;
                }
                project_on_rounded_box(&x0, &V3::zeros(), &he, r).unwrap()
            });
            assert_derivatives(&parts(&pd, k), &fd, "shape d/dp");
        }
    }

    /// Slides `x(s)` over `quads`, passing the previous segment as hint; returns the
    /// projections and the segment indices.
    fn slide(
        quads: &[[V3; 4]],
        path: impl Fn(f64) -> V3,
        n: usize,
    ) -> Vec<(usize, Projection<f64>, V3)> {
        let mut hint = None;
        (0..=n)
            .map(|i| {
                let x = path(i as f64 / n as f64);
                let (seg, p) = closest_on_quads(&x, quads, hint).unwrap();
                hint = Some(seg);
                (seg, p, x)
            })
            .collect()
    }

    #[test]
    fn sliding_over_a_flat_strip_is_continuous() {
        let bottom = [0.0, 1.1, 1.9, 3.2, 4.0, 5.0];
        let top = [0.1, 1.0, 2.1, 3.0, 4.2, 5.0];
        let quads: Vec<[V3; 4]> = (0..5)
            .map(|k| {
                [
                    V3::new(bottom[k], 0.0, 0.0),
                    V3::new(bottom[k + 1], 0.0, 0.0),
                    V3::new(top[k + 1], 1.0, 0.0),
                    V3::new(top[k], 1.0, 0.0),
                ]
            })
            .collect();
        for height in [0.25, -0.1] {
            let samples = slide(&quads, |s| V3::new(0.3 + 4.4 * s, 0.5, height), 2000);
            let mut visited = std::collections::BTreeSet::new();
            for (seg, p, x) in &samples {
                visited.insert(*seg);
                assert!(p.inside);
                assert!((p.gap - height).abs() < 1e-13, "gap {} at {x}", p.gap);
                assert!((p.point - V3::new(x.x, 0.5, 0.0)).norm() < 1e-13);
                assert!((p.normal - V3::z()).norm() < 1e-14);
            }
            assert_eq!(visited.len(), 5, "all five segments visited");
        }
    }

    /// 2D distance from `(x, z)` to the polyline through `pts` (oracle for the curved strip).
    fn polyline_distance(p: (f64, f64), pts: &[(f64, f64)]) -> f64 {
        pts.windows(2)
            .map(|w| {
                let (a, b) = (w[0], w[1]);
                let ab = (b.0 - a.0, b.1 - a.1);
                let ap = (p.0 - a.0, p.1 - a.1);
                let t = ((ap.0 * ab.0 + ap.1 * ab.1) / (ab.0 * ab.0 + ab.1 * ab.1)).clamp(0.0, 1.0);
                ((ap.0 - t * ab.0).powi(2) + (ap.1 - t * ab.1).powi(2)).sqrt()
            })
            .fold(f64::INFINITY, f64::min)
    }

    #[test]
    fn sliding_over_a_curved_strip_is_continuous() {
        let r = 5.0;
        let phis: Vec<f64> = (0..6).map(|k| -0.5 + 0.2 * k as f64).collect();
        let at = |phi: f64, y: f64| V3::new(r * phi.sin(), y, r * phi.cos());
        let poly: Vec<(f64, f64)> = phis.iter().map(|&f| (r * f.sin(), r * f.cos())).collect();
        // convex (normal outward, point outside) and concave (normal inward, point behind)
        for (outward, radius, sign) in [(true, r + 0.3, 1.0), (false, r + 0.2, -1.0)] {
            let quads: Vec<[V3; 4]> = phis
                .windows(2)
                .map(|w| {
                    if outward {
                        [at(w[0], 0.0), at(w[1], 0.0), at(w[1], 1.0), at(w[0], 1.0)]
                    } else {
                        [at(w[0], 0.0), at(w[0], 1.0), at(w[1], 1.0), at(w[1], 0.0)]
                    }
                })
                .collect();
            let n = 3000;
            let path = |s: f64| {
                let psi = -0.45 + 0.9 * s;
                V3::new(radius * psi.sin(), 0.5, radius * psi.cos())
            };
            let ds = radius * 0.9 / n as f64;
            let samples = slide(&quads, path, n);
            let mut visited = std::collections::BTreeSet::new();
            let mut boundary = 0;
            for (k, (seg, p, x)) in samples.iter().enumerate() {
                visited.insert(*seg);
                boundary += usize::from(!p.inside);
                let dist = (x - p.point).norm();
                let oracle = polyline_distance((x.x, x.z), &poly);
                assert!((dist - oracle).abs() < 1e-12, "distance {dist} vs {oracle}");
                assert!(sign * p.gap > 0.0 && p.gap.abs() <= dist + 1e-14);
                assert!((p.point.y - 0.5).abs() < 1e-13);
                if k > 0 {
                    let prev = &samples[k - 1].1;
                    assert!((p.gap - prev.gap).abs() <= 2.0 * ds, "gap jump at {k}");
                    assert!(
                        (p.point - prev.point).norm() <= 2.0 * ds,
                        "point jump at {k}"
                    );
                }
            }
            assert_eq!(visited.len(), 5);
            assert!(boundary > 0, "the path crosses the edge wedges");
        }
    }

    #[test]
    fn convex_ridge_picks_best_aligned_normal_then_hint() {
        // two-quad roof with the ridge along y at x = 0
        let a = [
            V3::new(-1.0, 0.0, -0.2),
            V3::new(0.0, 0.0, 0.0),
            V3::new(0.0, 1.0, 0.0),
            V3::new(-1.0, 1.0, -0.2),
        ];
        let b = [
            V3::new(0.0, 0.0, 0.0),
            V3::new(1.0, 0.0, -0.2),
            V3::new(1.0, 1.0, -0.2),
            V3::new(0.0, 1.0, 0.0),
        ];
        let quads = [a, b];
        // over the ridge, slightly towards b: boundary point on the ridge, b's normal
        let x = V3::new(0.02, 0.5, 0.5);
        let (seg, p) = closest_on_quads(&x, &quads, Some(0)).unwrap();
        assert_eq!(seg, 1);
        assert!(!p.inside && (p.point - V3::new(0.0, 0.5, 0.0)).norm() < 1e-14);
        let nb = V3::new(0.2, 0.0, 1.0).normalize();
        assert!((p.normal - nb).norm() < 1e-14 && (p.gap - x.dot(&nb) + 0.0).abs() < 1e-14);
        // exactly on the bisector: the hint decides, else the lowest index
        let x = V3::new(0.0, 0.5, 0.5);
        assert_eq!(closest_on_quads(&x, &quads, Some(1)).unwrap().0, 1);
        assert_eq!(closest_on_quads(&x, &quads, Some(0)).unwrap().0, 0);
        assert_eq!(closest_on_quads(&x, &quads, None).unwrap().0, 0);
    }

    #[test]
    fn projection_far_from_the_origin_matches_the_translated_one() {
        // translation invariance at coordinates 1e4 times the segment size: ξ and gap agree
        // to what the input rounding allows (ε·1e4 ≈ 2e-12)
        let q = warped_quad();
        let x = V3::new(0.3, -0.4, 0.6);
        let shift = V3::new(1.0e4, -2.0e4, 5.0e3);
        let a = project_on_quad(&x, &q, [0.0, 0.0]).unwrap();
        let b = project_on_quad(&(x + shift), &q.map(|n| n + shift), [0.0, 0.0]).unwrap();
        assert!((a.xi[0] - b.xi[0]).abs() < 1e-11 && (a.xi[1] - b.xi[1]).abs() < 1e-11);
        assert!((a.gap - b.gap).abs() < 1e-11);
        assert!((a.point + shift - b.point).norm() < 1e-11);
        let (_, c) = closest_on_quads(&(x + shift), &[q.map(|n| n + shift)], None).unwrap();
        assert!((a.gap - c.gap).abs() < 1e-11);
    }
}
