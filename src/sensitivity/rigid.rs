//! Refined SDM for shape parameters (`Settings::rigid_modes`): the rigid-body part of each
//! node's motion differentiated exactly, the rest by SDM's finite difference.
//!
//! **Why SDM errs on shape parameters.** SDM differences the residual at the fixed converged
//! unknowns `z` between the reference coordinates `X` and `X + db V` (`V = dX/db`, the design
//! velocity). Where an element has turned through a rigid rotation `Q`, its fixed nodal
//! displacements are a rigid motion on `X` but not on `X + db V`: the perturbed element sees a
//! spurious strain of order `|Q - I| |grad V| db` and answers with the stiffness of the
//! material, so the difference's truncation error is the element's rigid rotation times its
//! relative stretch `db |grad V|` times its stiffness, not the small curvature of its
//! deformation. A velocity confined to the last elements of a beam (the free end moved) makes
//! `|grad V| = 1 / l_e`, and the error grows with every refinement (linearly for forward,
//! quadratically for central differences): the semi-analytical inaccuracy of Barthelemy &
//! Haftka (AIAA J. 28, 1990) and of the Abaqus Benchmarks' cantilever (1.17.1).
//!
//! **The remedy** (the exact differentiation of the rigid-body modes of Parente & Vaz,
//! IJNME 52, 2001, in a form that needs no element code of its own). For any fixed vector `w`
//! of unknowns, the residual of an element along the path `(X + db V, z + db w)` has the
//! derivative
//!
//! ```text
//! d/db R_e(z + db w, X + db V) = dR_e/dX . V + K_e w        (K_e: the element's tangent)
//! ```
//!
//! so `dR_e/dX . V` is the finite difference along that path less `K_e w`, exactly, whatever
//! `w` is: only the truncation changes. Choosing `w_a = (Q_e - I) V_a` at every node `a` of
//! element `e`, with `Q_e` the element's rigid rotation, moves each node's current position by
//! `db Q_e V_a`: the perturbation of the reference turned with the element (for small
//! deformation, `w` is the change of the element's rigid mode `W_e X` along `V`). In the
//! corotated frame the perturbed element is the unperturbed one with its reference and current
//! positions moved together, its deformation unchanged, and the difference sees only the
//! curvature of the deformational part. (A nodal rotation shared by the elements around a
//! node would not do: its change across an element, times the translation part of `V`, is a
//! spurious strain of the size of the one removed.)
//!
//! Each element has a `w` of its own, so the elements are evaluated in colours, no two of a
//! colour sharing a node (eight on a structured hexahedral mesh): per colour one evaluation of
//! the colour's tangent at the converged state (its residual is the forward difference's
//! nominal), and per moving parameter one (forward) or two (central) evaluations of the
//! colour's elements; a colour none of whose elements the parameter reaches is left out. The springs, contact and loads are differenced as plain SDM does. Every
//! evaluation reuses the element kernels and their tangent; no derivative is written by hand.
//! The truncation left is that of the element's deformation under a relative stretch
//! `db |grad V|`: it still grows where a refinement makes the stretched elements smaller at a
//! fixed `db`, but without the rigid rotation's amplification.
//!
//! `Q_e` is the rotation of the deformation gradient fitted by least squares to the element's
//! nodes (`F = H M^-1`, `H = sum (x_a - x_c)(X_a - X_c)^T`, `M = sum (X_a - X_c)(X_a - X_c)^T`
//! about the centroids): its polar rotation for large deformation, `I + skew(F - I)` (the
//! infinitesimal rotation) for small. An element where `M` is singular takes `w = 0`.

use super::*;
use crate::assembly::{Evaluation, Frozen};
use crate::element::Kinematics;
use crate::linalg::SparseMatrix;
use crate::model::Lifted;
use crate::solver::{AnalysisError, Converged};
use crate::terms::Terms;
use nalgebra::{Matrix3, Vector3};

/// The solid elements' rigid rotations `Q_e - I` and their colouring.
struct ElementRotations {
    /// `Q_e - I` per element (`None`: a spring, or no rotation defined).
    rotation: Vec<Option<Matrix3<f64>>>,
    /// The solid elements of each colour.
    colours: Vec<Vec<usize>>,
}

impl ElementRotations {
    /// The rotations of the converged state `c` (module docs).
    fn of(c: &Converged<'_>) -> Self {
        let mesh = &c.model.mesh;
        let dofs = &c.assembler.dofs;
        let current = |n: usize| {
            let u = Vector3::new(c.z[3 * n], c.z[3 * n + 1], c.z[3 * n + 2]);
            c.lifted.coords[n] + u
        };
        let mut solids = Vec::new();
        let rotation = (0..mesh.n_elements())
            .map(|e| {
                let body = c.model.bodies.get(dofs.element_body[e])?;
                if dofs.gauss(e).is_empty() {
                    return None;
                }
                solids.push(e);
                let nodes = mesh.element_nodes(e);
                let k = nodes.len() as f64;
                let xc = nodes
                    .iter()
                    .map(|&n| c.lifted.coords[n])
                    .sum::<Vector3<f64>>()
                    / k;
                let cc = nodes.iter().map(|&n| current(n)).sum::<Vector3<f64>>() / k;
                let (mut h, mut m) = (Matrix3::zeros(), Matrix3::zeros());
                for &n in nodes {
                    let dx = c.lifted.coords[n] - xc;
                    h += (current(n) - cc) * dx.transpose();
                    m += dx * dx.transpose();
                }
                // a fit over fewer than four non-coplanar points has no inverse
                let scale = m.norm();
                if scale.is_nan() || scale <= 0.0 || m.determinant().abs() <= 1e-12 * scale.powi(3)
                {
                    return None;
                }
                let f = h * m.try_inverse()?;
                match body.kinematics {
                    Kinematics::Large => polar_rotation(&f).map(|q| q - Matrix3::identity()),
                    Kinematics::Small => Some(0.5 * (f - f.transpose())),
                }
            })
            .collect();
        let items: Vec<Vec<usize>> = solids
            .iter()
            .map(|&e| mesh.element_nodes(e).to_vec())
            .collect();
        let (colour, count) = super::adjoint::colour(&items, mesh.n_nodes());
        let mut colours = vec![Vec::new(); count];
        for (i, &e) in solids.iter().enumerate() {
            colours[colour[i]].push(e);
        }
        ElementRotations { rotation, colours }
    }
}

/// The rotation of the polar decomposition `F = Q U` (from the singular value decomposition,
/// with a reflection turned back into a rotation); `None` where it does not converge.
fn polar_rotation(f: &Matrix3<f64>) -> Option<Matrix3<f64>> {
    let svd = f.svd(true, true);
    let (mut u, v_t) = (svd.u?, svd.v_t?);
    if (u * v_t).determinant() < 0.0 {
        // the smallest singular value's direction reversed
        let i = svd.singular_values.imin();
        for r in 0..3 {
            u[(r, i)] = -u[(r, i)];
        }
    }
    Some(u * v_t)
}

/// The design velocity `V = dX/db` of every node from the perturbed reference coordinates
/// (`plus - minus` over `span`); `None` where no node moves.
pub(super) fn velocity(
    plus: &Lifted<f64>,
    minus: &Lifted<f64>,
    span: f64,
) -> Option<Vec<Vector3<f64>>> {
    let v: Vec<Vector3<f64>> = (plus.coords.iter().zip(&minus.coords))
        .map(|(p, m)| (p - m) / span)
        .collect();
    v.iter().any(|x| *x != Vector3::zeros()).then_some(v)
}

/// One moving parameter of the refined SDM.
pub(super) struct Moving<'x> {
    /// Its index.
    pub k: usize,
    /// Its step `db`.
    pub db: f64,
    /// The designs at `b + db` and (central) `b - db`.
    pub plus: &'x Lifted<f64>,
    /// `b - db` for central differences.
    pub minus: Option<&'x Lifted<f64>>,
    /// Its design velocity.
    pub velocity: Vec<Vector3<f64>>,
    /// The unknowns' prescribed derivative.
    pub dzc: &'x [f64],
}

impl Engine<'_> {
    /// The solid elements' part of each moving parameter's pseudo-load difference, the rigid
    /// rotations differentiated exactly (module docs): `D_k = sum over colours of [the
    /// colour's difference along (X + db V, z + db (dzc + w))] - K_c w`, on every row.
    pub(super) fn solid_differences(
        &mut self,
        c: &Converged<'_>,
        frozen: &Frozen<'_>,
        moving: &[Moving<'_>],
    ) -> Result<Vec<Vec<f64>>, AnalysisError> {
        let n = c.z.len();
        let ne = c.model.mesh.n_elements();
        let rot = ElementRotations::of(c);
        let mut out = vec![vec![0.0; n]; moving.len()];
        let mut tangent = SparseMatrix::new(c.assembler.pattern.clone());
        let no_node = vec![true; c.assembler.contact.n_hitting];
        let mut ev_0 = Evaluation::<f64>::new(c.assembler, ne);
        let mut ev_p = Evaluation::<f64>::new(c.assembler, ne);
        let mut ev_m = Evaluation::<f64>::new(c.assembler, ne);
        let mut w = vec![0.0; n];
        let mut kw = vec![0.0; n];
        let mut shift = vec![0.0; n];
        // the elements each parameter leaves unreached (`None`: none, or no restriction): a
        // colour none of whose elements a parameter reaches adds exactly nothing to its
        // difference (no node of it moves, so `w` is zero there too) and is left out
        let unreached: Vec<Option<Vec<bool>>> = moving
            .iter()
            .map(|m| {
                let reach = super::engine::Reach::between(m.plus, c.lifted);
                (frozen.gauss).and_then(|g| self.unreached(c, m.k, &reach, m.dzc, g, false))
            })
            .collect();
        for members in &rot.colours {
            let reached: Vec<bool> = (unreached.iter())
                .map(|u| u.as_ref().is_none_or(|u| members.iter().any(|&e| !u[e])))
                .collect();
            if !reached.contains(&true) {
                continue;
            }
            let mut skip = vec![true; ne];
            for &e in members {
                skip[e] = false;
            }
            let pass = Frozen {
                skip: Some(&skip),
                skip_contact: Some(&no_node),
                members_only: true,
                terms: Terms {
                    solids: true,
                    ..Terms::NONE
                },
                ..*frozen
            };
            // the colour's tangent, and its residual at the converged state
            let (lifted, z, hist) = (c.lifted, c.z, c.hist_prev);
            self.evaluate(
                c,
                lifted,
                z,
                hist,
                Some(&pass),
                Some(&mut tangent),
                &mut ev_0,
            )?;
            for ((m, d), _) in (moving.iter().zip(out.iter_mut()))
                .zip(&reached)
                .filter(|(_, r)| **r)
            {
                w.iter_mut().for_each(|x| *x = 0.0);
                for &e in members {
                    let Some(q) = &rot.rotation[e] else { continue };
                    for &a in c.model.mesh.element_nodes(e) {
                        let wa = q * m.velocity[a];
                        for i in 0..3 {
                            w[3 * a + i] = wa[i];
                        }
                    }
                }
                for ((s, a), b) in shift.iter_mut().zip(m.dzc).zip(&w) {
                    *s = a + b;
                }
                self.perturbed(c, m.k, m.db, m.plus, &shift, Some(&pass), &mut ev_p)?;
                let (base, span) = match m.minus {
                    Some(minus) => {
                        self.perturbed(c, m.k, -m.db, minus, &shift, Some(&pass), &mut ev_m)?;
                        (&ev_m, 2.0 * m.db)
                    }
                    None => (&ev_0, m.db),
                };
                tangent.mul_vec(&w, &mut kw)?;
                for i in 0..n {
                    d[i] += (ev_p.residual[i] - base.residual[i]) / span - kw[i];
                }
            }
            let evaluated = (moving.iter().zip(&reached))
                .filter(|(_, r)| **r)
                .map(|(m, _)| if m.minus.is_some() { 2 } else { 1 })
                .sum::<usize>();
            self.results.cost.partial_evaluations += 1 + evaluated;
        }
        Ok(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Rotation3;

    #[test]
    fn polar_rotation_of_a_turned_stretch_is_the_turn() {
        let q = *Rotation3::from_axis_angle(&Vector3::z_axis(), 1.2).matrix();
        let u = Matrix3::new(1.3, 0.1, 0.0, 0.1, 0.9, 0.05, 0.0, 0.05, 1.1);
        let got = polar_rotation(&(q * u)).unwrap();
        assert!((got - q).norm() < 1e-12, "{got}");
        // an inverted gradient still gives a rotation (det +1)
        let f = q * Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, -0.01));
        let got = polar_rotation(&f).unwrap();
        assert!((got.determinant() - 1.0).abs() < 1e-12);
        assert!((got.transpose() * got - Matrix3::identity()).norm() < 1e-12);
    }
}
