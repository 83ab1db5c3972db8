//! Checks of a model before its first increment, for what would otherwise show up as a failed
//! or silently wrong analysis many increments later:
//!
//! * **overlap**: hitting nodes that start inside their target (which nodes, how deep) — an
//!   error: the first increment would load them with the whole overlap at once;
//! * **rigid-body modes**: a body whose supports (prescribed components and springs to the
//!   ground) leave it free to translate or rotate — an error when nothing else holds it (the
//!   tangent is singular), a warning when it is in a contact pair (it is then held only by
//!   contact, which must be closed from the first increment on, or the tangent is singular);
//! * **pairs that cannot touch**: a rigid target that stays further from every hitting node
//!   than the hitting body's size along its whole path — a warning;
//! * **a hitting surface coarser than its target** (deformable pairs): the target's nodes
//!   between the hitting ones pass into the hitting body — a warning.
//!
//! [`crate::solver::Solver::new`] runs them; its errors are [`PrecheckError`]s inside
//! [`crate::solver::AnalysisError::Precheck`], its warnings [`crate::solver::Solver::warnings`].

use crate::assembly::{Assembler, Evaluation};
use crate::contact::Target;
use crate::element::Shape;
use crate::model::{Lifted, Model};
use nalgebra::{Matrix6, Vector3, Vector6};

/// A model that cannot be run as it is.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum PrecheckError {
    /// Hitting nodes start inside their target.
    #[error("pre-check: contact pair '{pair}': {} hitting node(s) start inside the target, the deepest by {:.3e} ({:.2} of its element size): {}; move the bodies apart (or start the target where it touches) so that the first increment closes the contact", nodes.len(), nodes[0].1, nodes[0].1 / element_size.max(f64::MIN_POSITIVE), list_nodes(nodes))]
    Overlap {
        /// The pair.
        pair: String,
        /// `(mesh node, penetration depth)`, deepest first.
        nodes: Vec<(usize, f64)>,
        /// Element size at the deepest node (square root of its tributary area).
        element_size: f64,
    },
    /// A rigid target pushed by a force does not touch the hitting nodes at the start.
    #[error("pre-check: contact pair '{pair}': its rigid target is pushed by a force but touches no hitting node at t = 0 (the closest, node {node}, is {closest:.3e} away): nothing holds the target before contact; translate it by {closest:.3e} towards the hitting nodes so that it touches, or drive the approach by a prescribed translation")]
    PushedTargetApart {
        /// The pair.
        pair: String,
        /// The closest hitting node (mesh node number).
        node: usize,
        /// Its gap at t = 0.
        closest: f64,
    },
    /// A body can move as a rigid body and nothing holds it.
    #[error("pre-check: body '{body}' is free to move as a rigid body ({}) and is in no contact pair: the tangent is singular; prescribe those components on some of its nodes (or tie it with springs)", modes.join("; "))]
    RigidBody {
        /// The body.
        body: String,
        /// The free rigid motions, described.
        modes: Vec<String>,
    },
}

fn list_nodes(nodes: &[(usize, f64)]) -> String {
    let shown: Vec<String> = nodes
        .iter()
        .take(8)
        .map(|(n, d)| format!("node {n} ({d:.3e})"))
        .collect();
    if nodes.len() > 8 {
        format!("{}, ... ({} more)", shown.join(", "), nodes.len() - 8)
    } else {
        shown.join(", ")
    }
}

/// Something a user should know before the run, which does not stop it.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum PrecheckWarning {
    /// A body is held only by contact in some rigid-body directions.
    #[error("body '{body}' is held only by contact (pairs {}) against moving as a rigid body ({}): the contact must be closed and pressed from the first increment on, or the tangent is singular", pairs.join(", "), modes.join("; "))]
    HeldByContact {
        /// The body.
        body: String,
        /// Its free rigid motions, described.
        modes: Vec<String>,
        /// The pairs it is in.
        pairs: Vec<String>,
    },
    /// A rigid target never comes near the hitting nodes.
    #[error("contact pair '{pair}': the target stays at least {closest:.3e} away from every hitting node along its whole path (the hitting body is {size:.3e} across): it cannot touch unless the body deforms that far")]
    NeverTouches {
        /// The pair.
        pair: String,
        /// Smallest gap of any hitting node (reference position) at any breakpoint of the
        /// target's path.
        closest: f64,
        /// Bounding-box diagonal of the hitting nodes.
        size: f64,
    },
    /// A deformable pair whose hitting surface is coarser than its target.
    #[error("contact pair '{pair}': its hitting surface is coarser than its target (node spacing {hitting:.3e} against {target:.3e} along the same direction, {:.1} times, at the median hitting face): the pair holds only the hitting nodes, so the target's nodes between them can pass into the hitting body unresisted; hitting with the finer surface (swap `hitting` and `target`) is the usual choice", hitting / target)]
    CoarseHitting {
        /// The pair.
        pair: String,
        /// Node spacing of the median hitting face along its coarsest direction against the
        /// target (reference geometry).
        hitting: f64,
        /// Node spacing of the target face nearest it along the same direction.
        target: f64,
    },
}

/// The centroid of a face's corners.
fn corner_centroid(f: crate::mesh::Face<'_>, x: &[Vector3<f64>]) -> Vector3<f64> {
    let nc = f.family.n_corners();
    (0..nc).map(|a| x[f.nodes[a]]).sum::<Vector3<f64>>() / nc as f64
}

/// A face's edges as (vector, node spacing along it): a quadratic face's edge holds a
/// mid-side node, so its spacing is half its length.
fn face_edges(f: crate::mesh::Face<'_>, x: &[Vector3<f64>]) -> Vec<(Vector3<f64>, f64)> {
    let per = if f.family.is_quadratic() { 2.0 } else { 1.0 };
    (f.family.edges().iter())
        .map(|[a, b]| {
            let v = x[f.nodes[*b]] - x[f.nodes[*a]];
            (v, v.norm() / per)
        })
        .collect()
}

/// Deformable pairs whose hitting surface is [`COARSE_HITTING`] times or more as coarse as
/// the target faces under it. For each hitting face, the target face nearest it (of its
/// first node's candidates) is compared edge by edge: each hitting edge's node spacing against
/// that of the target edge most nearly parallel to it, the face's ratio the largest (so a
/// plane-strain layer, one element through the thickness on both sides, compares its
/// in-plane spacings); the warning gives the median face's spacings. A node-to-surface pair
/// constrains only its hitting nodes: where they are the sparser, the target's nodes between
/// them pass into the hitting body, and each hitting node presses a dimple of its own into the
/// finer target. The physics fuzzer's seed 537 (a slider of elements 0.225 wide hitting a
/// base of 0.12, an augmented-Lagrangian penalty of 1,000 E, mu = 0.62) took 124
/// sub-increments and 1,414 Newton iterations; with hitting and target swapped, 45 and 502.
pub fn coarse_hitting(model: &Model, lifted: &Lifted<f64>) -> Vec<PrecheckWarning> {
    let mut out = Vec::new();
    let x = &lifted.coords;
    for pair in &model.contacts {
        let (Target::Faces { faces }, Some(own)) = (&pair.target, &pair.hitting_faces) else {
            continue;
        };
        let index: std::collections::HashMap<usize, usize> = pair
            .hitting
            .iter()
            .enumerate()
            .map(|(i, &n)| (n, i))
            .collect();
        let mut ratios: Vec<(f64, f64, f64)> = Vec::new();
        for h in own.iter() {
            let Some(&i) = h.nodes.first().and_then(|n| index.get(n)) else {
                continue;
            };
            let ch = corner_centroid(h, x);
            let distance = |k: usize| (corner_centroid(faces.face(k), x) - ch).norm();
            let nearest = (pair.candidates[i].iter())
                .copied()
                .min_by(|&a, &b| distance(a).total_cmp(&distance(b)));
            let Some(k) = nearest else {
                continue;
            };
            let (eh, et) = (face_edges(h, x), face_edges(faces.face(k), x));
            let worst = (eh.iter())
                .filter_map(|(vh, sh)| {
                    let parallel = et.iter().max_by(|a, b| {
                        let cos = |v: &Vector3<f64>| (v.dot(vh) / (v.norm() * vh.norm())).abs();
                        cos(&a.0).total_cmp(&cos(&b.0))
                    })?;
                    (parallel.1 > 0.0).then(|| (sh / parallel.1, *sh, parallel.1))
                })
                .max_by(|a, b| a.0.total_cmp(&b.0));
            ratios.extend(worst);
        }
        if ratios.is_empty() {
            continue;
        }
        ratios.sort_by(|a, b| a.0.total_cmp(&b.0));
        let (ratio, hitting, target) = ratios[ratios.len() / 2];
        if ratio >= COARSE_HITTING {
            out.push(PrecheckWarning::CoarseHitting {
                pair: pair.name.clone(),
                hitting,
                target,
            });
        }
    }
    out
}

/// How much coarser than its target a hitting surface is before [`coarse_hitting`] warns.
pub const COARSE_HITTING: f64 = 1.5;

/// Overlap of a model's contact pairs at the start (`eval`: the contact evaluated at the
/// reference state and `t = 0`). A node counts when it is deeper than 1e-6 of its element size
/// (the square root of its tributary area; round-off of touching surfaces is far below).
/// A rigid target pushed by a force must touch some hitting node (within the gap that counts
/// as touching, [`crate::contact::KernelParams::touch`]).
pub fn overlap(
    model: &Model,
    assembler: &Assembler,
    eval: &Evaluation<f64>,
) -> Result<(), PrecheckError> {
    for (p, pair) in model.contacts.iter().enumerate() {
        let first = assembler.contact.flat[p];
        if assembler.contact.target[p].iter().any(Option::is_some) {
            let closest = (0..pair.hitting.len())
                .map(|i| (pair.hitting[i], eval.contact.gap[first + i]))
                .min_by(|a, b| a.1.total_cmp(&b.1));
            if let Some((node, closest)) = closest {
                if closest > assembler.contact.touch[p] {
                    return Err(PrecheckError::PushedTargetApart {
                        pair: pair.name.clone(),
                        node,
                        closest,
                    });
                }
            }
        }
        let mut nodes: Vec<(usize, f64, f64)> = Vec::new();
        for (i, &s) in pair.hitting.iter().enumerate() {
            let g = eval.contact.gap[first + i];
            let h = pair.area[i].sqrt();
            if g.is_finite() && -g > 1e-6 * h {
                nodes.push((s, -g, h));
            }
        }
        if nodes.is_empty() {
            continue;
        }
        nodes.sort_by(|a, b| b.1.total_cmp(&a.1));
        return Err(PrecheckError::Overlap {
            pair: pair.name.clone(),
            element_size: nodes[0].2,
            nodes: nodes.into_iter().map(|(n, d, _)| (n, d)).collect(),
        });
    }
    Ok(())
}

/// The rigid-body modes of every body its supports leave free (`constrained`: the prescribed
/// unknowns). Bodies tied by a spring to another node are skipped (the spring may hold them).
pub fn rigid_body_modes(
    model: &Model,
    lifted: &Lifted<f64>,
    constrained: &[bool],
) -> (Vec<PrecheckWarning>, Result<(), PrecheckError>) {
    let mut warnings = Vec::new();
    let node_group = crate::contact::setup::node_groups(&model.mesh);
    let group_of = |n: usize| node_group[n];
    for body in &model.bodies {
        let mut nodes: Vec<usize> = model.mesh.groups[body.group].nodes.clone();
        nodes.sort_unstable();
        nodes.dedup();
        if nodes.is_empty() {
            continue;
        }
        let tied = model.springs.iter().any(|s| {
            let g = &model.mesh.groups[s.group];
            g.shape == Shape::Line2 && g.nodes.iter().any(|&n| group_of(n) == Some(body.group))
        });
        if tied {
            continue;
        }
        let centre = nodes
            .iter()
            .map(|&n| lifted.coords[n])
            .sum::<Vector3<f64>>()
            / nodes.len() as f64;
        let size = nodes
            .iter()
            .map(|&n| (lifted.coords[n] - centre).norm())
            .fold(0.0f64, f64::max)
            .max(f64::MIN_POSITIVE);
        // rows [e_c, (r / L) x e_c]: u_c = a_c + w . (r x e_c) for the rigid motion
        // u = a + w x r, with w scaled by the body's size
        let mut m = Matrix6::<f64>::zeros();
        let mut add = |r: Vector3<f64>, c: usize| {
            let mut e = Vector3::zeros();
            e[c] = 1.0;
            let rot = (r / size).cross(&e);
            let row = Vector6::new(e[0], e[1], e[2], rot[0], rot[1], rot[2]);
            m += row * row.transpose();
        };
        for &n in &nodes {
            let r = lifted.coords[n] - centre;
            for c in 0..3 {
                let grounded = model.springs.iter().any(|s| {
                    let g = &model.mesh.groups[s.group];
                    g.shape == Shape::Point1 && g.nodes.contains(&n) && s.stiffness[c][c] > 0.0
                });
                if constrained[crate::model::node_dof(n, c)] || grounded {
                    add(r, c);
                }
            }
        }
        let eig = m.symmetric_eigen();
        let scale = eig.eigenvalues.max().max(1.0);
        let mut modes = Vec::new();
        for k in 0..6 {
            if eig.eigenvalues[k] <= 1e-9 * scale {
                modes.push(describe(&eig.eigenvectors.column(k).into_owned()));
            }
        }
        if modes.is_empty() {
            continue;
        }
        let pairs: Vec<String> = model
            .contacts
            .iter()
            .filter(|c| {
                c.hitting.iter().any(|&n| group_of(n) == Some(body.group))
                    || match &c.target {
                        Target::Faces { faces } => faces
                            .all_nodes()
                            .iter()
                            .any(|&n| group_of(n) == Some(body.group)),
                        Target::Rigid { .. } => false,
                    }
            })
            .map(|c| c.name.clone())
            .collect();
        if pairs.is_empty() {
            return (
                warnings,
                Err(PrecheckError::RigidBody {
                    body: body.name.clone(),
                    modes,
                }),
            );
        }
        warnings.push(PrecheckWarning::HeldByContact {
            body: body.name.clone(),
            modes,
            pairs,
        });
    }
    (warnings, Ok(()))
}

/// A rigid motion `(a, w L)` in words: its translation and rotation directions.
fn describe(v: &Vector6<f64>) -> String {
    let t = Vector3::new(v[0], v[1], v[2]);
    let w = Vector3::new(v[3], v[4], v[5]);
    let fmt = |d: Vector3<f64>| {
        // unit, its largest component positive
        let k = d.iamax();
        let d = d / d.norm() * d[k].signum();
        format!("({:.2}, {:.2}, {:.2})", d[0], d[1], d[2]).replace("-0.00", "0.00")
    };
    let (tn, wn) = (t.norm(), w.norm());
    if wn <= 1e-6 * tn {
        format!("translation along {}", fmt(t))
    } else if tn <= 1e-6 * wn {
        format!("rotation about {}", fmt(w))
    } else {
        format!(
            "rotation about {} with translation along {}",
            fmt(w),
            fmt(t)
        )
    }
}

/// Rigid targets that stay further from every hitting node than the hitting body's size,
/// at every breakpoint of their path.
pub fn never_touching(model: &Model, lifted: &Lifted<f64>) -> Vec<PrecheckWarning> {
    let mut out = Vec::new();
    for (p, pair) in model.contacts.iter().enumerate() {
        let Target::Rigid { surface, motion } = &pair.target else {
            continue;
        };
        let mut times = vec![0.0];
        for m in motion {
            times.extend(m.amplitude.points.iter().map(|(t, _)| *t));
        }
        times.extend(model.times.last().copied());
        let x: Vec<Vector3<f64>> = pair.hitting.iter().map(|&n| lifted.coords[n]).collect();
        let lo = x.iter().fold(x[0], |a, b| a.inf(b));
        let hi = x.iter().fold(x[0], |a, b| a.sup(b));
        let size = (hi - lo).norm();
        let mut closest = f64::INFINITY;
        for &t in &times {
            // a pushed target where it starts (its motion is not known before the run)
            let d =
                crate::contact::assembly::rigid_translation(pair, &lifted.rigid_motion[p], t, None);
            for xi in &x {
                if let Ok(pr) = surface.project(xi, &d) {
                    closest = closest.min(pr.gap);
                }
            }
        }
        if closest.is_finite() && closest > size.max(f64::MIN_POSITIVE) {
            out.push(PrecheckWarning::NeverTouches {
                pair: pair.name.clone(),
                closest,
                size,
            });
        }
    }
    out
}
