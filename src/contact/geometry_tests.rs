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
    projections
        .push(project_on_quad(&(xs - lift_vec(&V3::new(1.5, 0.5, 0.0))), &qs, [0.0; 2]).unwrap());
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
    hinted: bool,
) -> Vec<(usize, Projection<f64>, V3)> {
    let mut hint = None;
    (0..=n)
        .map(|i| {
            let x = path(i as f64 / n as f64);
            let (seg, p) = closest_on_quads(&x, quads, hint).unwrap();
            hint = Some(seg).filter(|_| hinted);
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
        let samples = slide(&quads, |s| V3::new(0.3 + 4.4 * s, 0.5, height), 2000, true);
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
        // without a hint the gap is continuous; with the last face as the hint it keeps
        // that face until the next is better aligned by ALIGN_KEEP, and the gap jumps there by
        // at most that fraction of the distance
        for hinted in [false, true] {
            let samples = slide(&quads, path, n, hinted);
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
                    let band = if hinted { ALIGN_KEEP * dist } else { 0.0 };
                    assert!(
                        (p.gap - prev.gap).abs() <= 2.0 * ds + band,
                        "gap jump at {k}"
                    );
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
}

/// Two-quad roof with the ridge along y at x = 0, the faces falling by 0.2 over a width of 1.
fn roof() -> [[V3; 4]; 2] {
    [
        [
            V3::new(-1.0, 0.0, -0.2),
            V3::new(0.0, 0.0, 0.0),
            V3::new(0.0, 1.0, 0.0),
            V3::new(-1.0, 1.0, -0.2),
        ],
        [
            V3::new(0.0, 0.0, 0.0),
            V3::new(1.0, 0.0, -0.2),
            V3::new(1.0, 1.0, -0.2),
            V3::new(0.0, 1.0, 0.0),
        ],
    ]
}

#[test]
fn convex_ridge_picks_best_aligned_normal_then_hint() {
    let quads = roof();
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
fn hint_keeps_its_face_against_a_slightly_better_aligned_one() {
    // over the ridge of roof() at x = s along the ridge's perpendicular,
    // height 1/2: |gap| / distance is (1/2 -/+ s/5) / (|n| |d|) for the faces a and b
    let quads = roof();
    let align = |s: f64, sign: f64| {
        let d = V3::new(s, 0.0, 0.5);
        (d.dot(&V3::new(sign * 0.2, 0.0, 1.0).normalize()) / d.norm()).abs()
    };
    // b better aligned by less than ALIGN_KEEP: the hint decides either way
    let s = 0.005;
    let gain = align(s, 1.0) - align(s, -1.0);
    assert!(gain > 0.0 && gain < ALIGN_KEEP, "{gain}");
    let x = V3::new(s, 0.5, 0.5);
    assert_eq!(closest_on_quads(&x, &quads, Some(0)).unwrap().0, 0);
    assert_eq!(closest_on_quads(&x, &quads, Some(1)).unwrap().0, 1);
    // without a hint the better aligned
    assert_eq!(closest_on_quads(&x, &quads, None).unwrap().0, 1);
    // the kept face's projection is the boundary point with its own normal: the gap it
    // reports differs from b's by less than ALIGN_KEEP of the distance
    let (_, pa) = closest_on_quads(&x, &quads, Some(0)).unwrap();
    let (_, pb) = closest_on_quads(&x, &quads, Some(1)).unwrap();
    let dist = (x - pa.point).norm();
    assert!((pa.gap.abs() - pb.gap.abs()).abs() <= ALIGN_KEEP * dist);
    // beyond the band the better aligned wins against the hint
    let s = 0.05;
    assert!(align(s, 1.0) - align(s, -1.0) > ALIGN_KEEP);
    let x = V3::new(s, 0.5, 0.5);
    assert_eq!(closest_on_quads(&x, &quads, Some(0)).unwrap().0, 1);
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

// ---------------------------------------------------------------------------------------------
// Faces of every family (tri3, tri6, quad8; quad4 through the same search)
// ---------------------------------------------------------------------------------------------

/// A face of `family` on the curved surface `z = 0.15 x² − 0.1 x y + 0.05 y²` (its nodes on
/// it, so a quadratic face is curved), the natural domain mapped to about `[0, 2]²`.
fn curved_face(family: FaceFamily) -> Segment<f64> {
    let nodes: Vec<V3> = (0..family.n_nodes())
        .map(|a| {
            let [s, t] = family.node_st(a);
            let (x, y) = if family.is_triangle() {
                (2.0 * s + 0.3 * t, 2.0 * t - 0.2 * s)
            } else {
                (1.0 + s + 0.15 * t, 1.0 + t - 0.1 * s)
            };
            V3::new(x, y, 0.15 * x * x - 0.1 * x * y + 0.05 * y * y)
        })
        .collect();
    Segment::new(family, &nodes)
}

/// Independent point of a face at natural coordinates `st` (the family's shape functions).
fn face_at(seg: &Segment<f64>, st: [f64; 2]) -> V3 {
    let (n, _) = seg.family.shape(st);
    (0..seg.family.n_nodes()).fold(V3::zeros(), |p, a| p + seg.nodes[a] * n[a])
}

/// Brute force: the distance from `x` to the closed face, by a dense grid of its natural
/// domain then a compass search kept in the domain.
fn brute_force_face_distance(x: &V3, seg: &Segment<f64>) -> f64 {
    let family = seg.family;
    let n = 200;
    let to_st = |i: usize, j: usize| {
        let (a, b) = (i as f64 / n as f64, j as f64 / n as f64);
        if family.is_triangle() {
            [a * (1.0 - b), b]
        } else {
            [2.0 * a - 1.0, 2.0 * b - 1.0]
        }
    };
    let d = |st: [f64; 2]| (x - face_at(seg, st)).norm();
    let mut best = ([0.0, 0.0], f64::INFINITY);
    for i in 0..=n {
        for j in 0..=n {
            let st = to_st(i, j);
            let v = d(st);
            if v < best.1 {
                best = (st, v);
            }
        }
    }
    let mut step = 2.0 / n as f64;
    while step > 1e-14 {
        let mut moved = false;
        // the diagonals let it slide along a triangle's hypotenuse
        for (ds, dt) in [
            (1.0, 0.0),
            (-1.0, 0.0),
            (0.0, 1.0),
            (0.0, -1.0),
            (1.0, -1.0),
            (-1.0, 1.0),
        ] {
            let st = [best.0[0] + ds * step, best.0[1] + dt * step];
            if family.contains(st, 0.0) {
                let v = d(st);
                if v < best.1 {
                    best = (st, v);
                    moved = true;
                }
            }
        }
        if !moved {
            step *= 0.5;
        }
    }
    best.1
}

#[test]
fn projections_on_curved_faces_are_the_closest_points() {
    for family in FaceFamily::ALL {
        let seg = curved_face(family);
        for x in [
            V3::new(0.9, 1.1, 1.2),
            V3::new(1.3, 0.4, -0.8),
            V3::new(3.5, 0.5, 0.7),   // beyond an edge
            V3::new(-1.0, -1.0, 0.3), // beyond a corner
            V3::new(0.7, 0.6, 0.05),
        ] {
            let (_, p) = closest_on_segments(&x, &[seg], None).unwrap();
            let brute = brute_force_face_distance(&x, &seg);
            let dist = (x - p.point).norm();
            // the compass search stops at 1e-14 in xi: distances agree to ~1e-12
            assert!(
                (dist - brute).abs() < 1e-10,
                "{family:?} {x}: {dist} vs brute force {brute}"
            );
            // the point is the face's point at the returned xi, in the face
            assert!((face_at(&seg, p.xi) - p.point).norm() < 1e-12);
            assert!(family.contains(p.xi, 1e-10));
            if p.inside {
                // orthogonality (eq. 9) and |gap| = distance
                let r = x - p.point;
                assert!(r.dot(&p.t1).abs() < 1e-12 && r.dot(&p.t2).abs() < 1e-12);
                assert!((p.gap.abs() - dist).abs() < 1e-12);
            }
            // outward normal: counter-clockwise faces seen from +z
            assert!(p.normal.z > 0.0);
        }
    }
}

#[test]
fn curved_projection_derivatives_are_finite_differences() {
    // d(xi, gap)/d(x and every node coordinate) from one dual evaluation per seed, against
    // central differences of the f64 projection: inside points, and points whose closest point
    // is on a curved edge
    for family in FaceFamily::ALL {
        let seg = curved_face(family);
        for x in [V3::new(0.9, 1.1, 1.2), V3::new(3.2, 0.6, 0.7)] {
            let n_nodes = family.n_nodes();
            for k in 0..3 * (n_nodes + 1) {
                let perturbed = |h: f64| {
                    let mut s = seg;
                    let mut y = x;
                    if k < 3 {
                        y[k] += h;
                    } else {
                        s.nodes[(k - 3) / 3][(k - 3) % 3] += h;
                    }
                    closest_on_segments(&y, &[s], None).unwrap().1
                };
                let (pp, pm) = (perturbed(FD_STEP), perturbed(-FD_STEP));
                let lift = |v: &V3| v.map(Dual64::from_re);
                let nodes: Vec<Vector3<Dual64>> = seg.nodes[..n_nodes].iter().map(lift).collect();
                let mut sd = Segment::new(family, &nodes);
                let mut xd = lift(&x);
                if k < 3 {
                    xd[k].eps = 1.0;
                } else {
                    sd.nodes[(k - 3) / 3][(k - 3) % 3].eps = 1.0;
                }
                let (_, pd) = closest_on_segments(&xd, &[sd], None).unwrap();
                let fd_gap = (pp.gap - pm.gap) / (2.0 * FD_STEP);
                // central differences of smooth functions of order one: error ~ FD_STEP²
                assert!(
                    (pd.gap.eps - fd_gap).abs() < 1e-7,
                    "{family:?} seed {k}: gap"
                );
                for a in 0..2 {
                    let fd = (pp.xi[a] - pm.xi[a]) / (2.0 * FD_STEP);
                    assert!(
                        (pd.xi[a].eps - fd).abs() < 1e-7,
                        "{family:?} seed {k}: xi{a}"
                    );
                }
            }
        }
    }
}

#[test]
fn a_node_sliding_over_curved_faces_sees_a_continuous_gap() {
    // two quad8 (and two tri6) faces of one curved surface sharing an edge: the closest point
    // on their union moves continuously, so does the gap
    for family in [FaceFamily::Quad8, FaceFamily::Tri6] {
        let a = curved_face(family);
        // the mirror image across x = 0 (reversed order keeps it counter-clockwise from +z),
        // sharing the edge of a's nodes at x = 0 when there are some; otherwise just a second
        // face of the surface
        let mirrored: Vec<V3> = a.nodes[..family.n_nodes()]
            .iter()
            .map(|v| {
                V3::new(
                    -v.x,
                    v.y,
                    0.15 * v.x * v.x + 0.1 * v.x * v.y + 0.05 * v.y * v.y,
                )
            })
            .collect();
        let mut order: Vec<usize> = (0..family.n_nodes()).collect();
        // reverse the corner cycle and the mid-side nodes with it
        let c = family.n_corners();
        let corners: Vec<usize> = (0..c).rev().collect();
        let mids: Vec<usize> = (0..c).rev().map(|m| c + (m + c - 1) % c).collect();
        if family.is_quadratic() {
            order = corners.iter().chain(mids.iter()).copied().collect();
        }
        let b = Segment::new(
            family,
            &order.iter().map(|&i| mirrored[i]).collect::<Vec<_>>(),
        );
        let mut last: Option<f64> = None;
        for i in 0..=200 {
            let s = -1.5 + 3.0 * i as f64 / 200.0;
            let x = V3::new(s, 1.0, 1.0);
            let (_, p) = closest_on_segments(&x, &[a, b], None).unwrap();
            let dist = (x - p.point).norm();
            if let Some(l) = last {
                // a step of 0.015 moves the distance by at most that much
                assert!(
                    (dist - l).abs() <= 0.0151,
                    "{family:?} at {s}: {l} -> {dist}"
                );
            }
            last = Some(dist);
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Smoothed normals
// ---------------------------------------------------------------------------------------------

fn all_normals(n: V3) -> [V3; MAX_FACE_NODES] {
    [n; MAX_FACE_NODES]
}

/// On a flat face whose nodal normals are all the face normal, the projection along the
/// smoothed normal is the closest-point projection (both invariants of the plane: the foot
/// of the perpendicular), inside and outside the face.
#[test]
fn smoothed_projection_on_a_flat_face_is_the_closest_point() {
    let q = flat_quad();
    let n = (q[1] - q[0]).cross(&(q[3] - q[0])).normalize();
    let seg = Segment::quad4(q);
    for x in [
        V3::new(0.3, -0.2, 0.8),
        V3::new(-0.5, 0.4, -0.6),
        V3::new(2.5, 0.7, 0.05),
    ] {
        let s = project_smoothed(&x, &seg, &all_normals(n), [0.0, 0.0]).unwrap();
        let c = project_on_quad(&x, &q, [0.0, 0.0]).unwrap();
        for (i, (a, b)) in values(&s).iter().zip(values(&c)).enumerate() {
            assert!(
                (a - b).abs() <= 1e-13 * (1.0 + b.abs()),
                "output {i}: {a:e} vs {b:e}"
            );
        }
        assert_eq!(s.inside, c.inside);
        // the foot of the perpendicular: x - point along n, gap its length
        assert!(((x - s.point) - n * s.gap).norm() <= 1e-13);
    }
}

/// Two faces meeting at an edge with a kink of 30 degrees (a roof), the nodal normals at the
/// shared edge the mean of the two face normals. A point on the ray from an edge point along
/// that mean normal projects onto the edge from either face, with the same gap (the distance
/// along the ray), normal and point: the gap and normal do not jump from face to face. A
/// closest-point projection gives the same gap there but the two faces' own normals.
#[test]
fn smoothed_projection_is_continuous_across_a_kinked_edge() {
    let a = 30f64.to_radians();
    // face A: x in [-1, 0] in the plane y = 0; face B: from the edge x = 0 up at angle a
    let (e0, e1) = (V3::new(0.0, 0.0, 0.0), V3::new(0.0, 0.0, 1.0));
    let b_far = V3::new(a.cos(), a.sin(), 0.0);
    let face_a = [V3::new(-1.0, 0.0, 1.0), e1, e0, V3::new(-1.0, 0.0, 0.0)];
    let face_b = [e1, b_far + e1, b_far, e0];
    let na = (face_a[1] - face_a[0])
        .cross(&(face_a[3] - face_a[0]))
        .normalize();
    let nb = (face_b[1] - face_b[0])
        .cross(&(face_b[3] - face_b[0]))
        .normalize();
    assert!(na.y > 0.0 && nb.y > 0.0, "outward normals point up");
    let ne = (na + nb).normalize();
    // nodal normals in each face's node order: the shared edge's nodes get the mean
    let mut normals_a8 = [V3::zeros(); MAX_FACE_NODES];
    let mut normals_b8 = [V3::zeros(); MAX_FACE_NODES];
    normals_a8[..4].copy_from_slice(&[na, ne, ne, na]);
    normals_b8[..4].copy_from_slice(&[ne, nb, nb, ne]);
    for (t, gap) in [(0.3, 0.2), (0.7, -0.05), (0.5, 0.0)] {
        let edge_point = V3::new(0.0, 0.0, t);
        let x = edge_point + ne * gap;
        let pa = project_smoothed(&x, &Segment::quad4(face_a), &normals_a8, [0.0, 0.0]).unwrap();
        let pb = project_smoothed(&x, &Segment::quad4(face_b), &normals_b8, [0.0, 0.0]).unwrap();
        for p in [&pa, &pb] {
            assert!((p.gap - gap).abs() <= 1e-13, "gap {:e} vs {gap:e}", p.gap);
            assert!((p.normal - ne).norm() <= 1e-13);
            assert!((p.point - edge_point).norm() <= 1e-13);
        }
        // the edge is face A's side from node 1 to node 2 (xi^1 = +1), face B's from node 0
        // to node 3 (xi^1 = -1)
        assert!((pa.xi[0] - 1.0).abs() <= 1e-13 && (pb.xi[0] + 1.0).abs() <= 1e-13);
        // the faceted projection: each face's own normal at the edge
        if gap > 0.0 {
            let ca = project_on_quad(&x, &face_a, [0.0, 0.0]).unwrap();
            assert!((ca.normal - na).norm() <= 1e-13);
        }
    }
}

/// The derivative parts of the smoothed projection (dual numbers: one correction from the
/// converged real solution, the implicit function theorem) against central differences of
/// the f64 projection, seeding the hitting point, a node of a warped face and a nodal
/// normal.
#[test]
fn smoothed_projection_derivatives_match_central_differences() {
    let q = warped_quad();
    let mut normals = [V3::zeros(); MAX_FACE_NODES];
    let tilt = [
        V3::new(0.1, -0.05, 1.0),
        V3::new(-0.08, 0.02, 1.0),
        V3::new(0.05, 0.1, 1.0),
        V3::new(-0.02, -0.1, 1.0),
    ];
    for (n, t) in normals.iter_mut().zip(tilt) {
        *n = t.normalize();
    }
    let x = V3::new(0.35, -0.25, 0.6);
    let run = |dx: V3, dnode: V3, dnormal: V3| {
        let mut qq = q;
        qq[2] += dnode;
        let mut nn = normals;
        nn[1] += dnormal;
        project_smoothed(&(x + dx), &Segment::quad4(qq), &nn, [0.0, 0.0]).unwrap()
    };
    let base = run(V3::zeros(), V3::zeros(), V3::zeros());
    assert!(base.inside);
    let seed = |v: V3, c: usize| {
        let mut d = v.map(Dual64::from_re);
        d[c].eps = 1.0;
        d
    };
    let qd = lift_quad::<Dual64>(&q);
    let nd = normals.map(|n| n.map(Dual64::from_re));
    for c in 0..3 {
        let e = V3::ith(c, 1.0);
        // the hitting point
        let p = project_smoothed(&seed(x, c), &Segment::quad4(qd), &nd, [0.0, 0.0]).unwrap();
        assert_same_real(&p.to_real(), &base, "real parts");
        let fd = central_fd(|h| run(e * h, V3::zeros(), V3::zeros()));
        assert_derivatives(&parts(&p, 0), &fd, "hitting point");
        // node 2 of the face
        let mut qs = qd;
        qs[2] = seed(q[2], c);
        let p = project_smoothed(
            &x.map(Dual64::from_re),
            &Segment::quad4(qs),
            &nd,
            [0.0, 0.0],
        )
        .unwrap();
        let fd = central_fd(|h| run(V3::zeros(), e * h, V3::zeros()));
        assert_derivatives(&parts(&p, 0), &fd, "face node");
        // nodal normal 1 (not renormalised: the interpolation normalises)
        let mut ns = nd;
        ns[1] = seed(normals[1], c);
        let p = project_smoothed(
            &x.map(Dual64::from_re),
            &Segment::quad4(qd),
            &ns,
            [0.0, 0.0],
        )
        .unwrap();
        let fd = central_fd(|h| run(V3::zeros(), V3::zeros(), e * h));
        assert_derivatives(&parts(&p, 0), &fd, "nodal normal");
    }
}

/// `node_jacobian` sums the face's tangents at a node with `f64` weights; the face map itself
/// (`surface_point` at the node's lifted `ξ`) gives the same `t_1 × t_2` to the bit, in `f64`
/// and in dual numbers seeded on every node coordinate, for every face family.
#[test]
fn node_jacobian_is_the_face_maps_normal_to_the_bit() {
    for family in FaceFamily::ALL {
        let seg = curved_face(family);
        let n = family.n_nodes();
        let nodes: Vec<Vector3<DualSVec64<24>>> = (0..n)
            .map(|a| Vector3::from_fn(|k, _| DualSVec64::<24>::seeded(seg.nodes[a][k], 3 * a + k)))
            .collect();
        let dual = Segment::new(family, &nodes);
        for a in 0..n {
            let st = family.node_st(a);
            let p = surface_point(&seg, &st);
            assert_eq!(
                node_jacobian(&seg, a),
                p.t1.cross(&p.t2),
                "{family:?} node {a}"
            );
            let lifted = [DualSVec64::<24>::lift(st[0]), DualSVec64::<24>::lift(st[1])];
            let pd = surface_point(&dual, &lifted);
            let (fast, full) = (node_jacobian(&dual, a), pd.t1.cross(&pd.t2));
            for c in 0..3 {
                assert_eq!(fast[c].value(), full[c].value(), "{family:?} node {a}");
                for k in 0..3 * n {
                    assert_eq!(
                        fast[c].part(k).to_bits(),
                        full[c].part(k).to_bits(),
                        "{family:?} node {a} component {c} part {k}"
                    );
                }
            }
        }
    }
}
