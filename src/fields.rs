//! The fields of a state, for ParaView: what one evaluation gives at every node and element,
//! generic over the scalar.
//!
//! One extraction serves the primal fields and their design derivatives by every method: with
//! `f64` it gives a state's fields (and a difference of two states' fields, SDM's and FDM's
//! derivatives); with `Dual64` at a state carrying `dz/db`, `dh/db` and a seeded design, the
//! dual parts are DDM's exact derivatives of the same fields.
//!
//! | field | where | components |
//! |---|---|---|
//! | `displacement` | point | 3 |
//! | `normal_force` (with contact) | point | 1 |
//! | `contact_pressure_nominal`, `contact_pressure_current` (with contact) | point | 1 |
//! | `friction_force` (with contact) | point | 3 |
//! | `cauchy_stress` (volume average: xx, yy, zz, xy, yz, xz) | cell | 6 |
//! | `von_mises` | cell | 1 |
//! | `equivalent_plastic_strain` (Gauss-point average) | cell | 1 |
//!
//! The contact fields are the sums over a node's hitting entries, as in
//! [`crate::output::contact_fields`]; the pressures are the normal force over the node's
//! reference and current tributary areas.

use crate::assembly::{Assembler, Evaluation};
use crate::model::{node_dof, Model};
use crate::scalar::Scalar;
use nalgebra::Matrix3;

/// Where a field lives.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Location {
    /// One value (of `components` scalars) per mesh node.
    Point,
    /// One value per element.
    Cell,
}

/// One field of a state.
#[derive(Clone, Debug, PartialEq)]
pub struct Field<S> {
    /// Its name in the VTK file.
    pub name: &'static str,
    /// Per node or per element.
    pub location: Location,
    /// Scalars per node or element.
    pub components: u32,
    /// `components` scalars per node or element, node- (element-) major.
    pub values: Vec<S>,
}

/// The name of the history scalar a material law keeps as its equivalent plastic strain
/// ([`crate::material::j2::J2Plasticity::HISTORY_NAMES`]); a law without one has none (0).
pub const EQUIVALENT_PLASTIC_STRAIN: &str = "alpha";

/// The fields of the state `z` of the evaluation `ev` (its updated history, stresses and
/// contact). `asm` must keep the stress of every element in the evaluation's scalar
/// ([`Assembler::reading_every_stress`]) for the stress fields to carry derivatives; elsewhere
/// an `f64` evaluation's are its stresses, a differentiating one's zero
/// ([`crate::assembly::Evaluation::cauchy`]).
pub fn state_fields<S: Scalar>(
    model: &Model,
    asm: &Assembler,
    ev: &Evaluation<S>,
    z: &[S],
) -> Vec<Field<S>> {
    let n = model.mesh.n_nodes();
    let ne = model.mesh.n_elements();
    let point = |name, components, values| Field {
        name,
        location: Location::Point,
        components,
        values,
    };
    let cell = |name, components, values| Field {
        name,
        location: Location::Cell,
        components,
        values,
    };
    let mut out = Vec::new();
    let disp: Vec<S> = (0..n)
        .flat_map(|i| (0..3).map(move |c| node_dof(i, c)))
        .map(|d| z[d])
        .collect();
    out.push(point("displacement", 3, disp));
    if !model.contacts.is_empty() {
        let c = &ev.contact;
        let mut normal = vec![S::zero(); n];
        let mut nominal = vec![S::zero(); n];
        let mut current = vec![S::zero(); n];
        let mut friction = vec![S::zero(); 3 * n];
        for (p, pair) in model.contacts.iter().enumerate() {
            let first = asm.contact_flat(p);
            let Some((p_nominal, p_current)) = c.pressures(pair, first) else {
                continue;
            };
            for (i, &node) in pair.hitting.iter().enumerate() {
                let f = first + i;
                if f >= c.normal_force.len() {
                    continue;
                }
                normal[node] += c.normal_force[f];
                nominal[node] += p_nominal[i];
                current[node] += p_current[i];
                for j in 0..3 {
                    friction[node_dof(node, j)] += c.traction[f][j];
                }
            }
        }
        out.push(point("normal_force", 1, normal));
        out.push(point("contact_pressure_nominal", 1, nominal));
        out.push(point("contact_pressure_current", 1, current));
        out.push(point("friction_force", 3, friction));
    }
    let dofs = &asm.dofs;
    let mut sig = Vec::with_capacity(6 * ne);
    let mut mises = Vec::with_capacity(ne);
    let mut eqps = Vec::with_capacity(ne);
    for e in 0..ne {
        let s: Matrix3<S> = match asm.stress_slot(e) {
            Some(slot) => ev.stress[slot],
            None => ev.cauchy[e].map(S::lift),
        };
        sig.extend_from_slice(&stress_components(&s));
        mises.push(von_mises(&s));
        eqps.push(equivalent_plastic_strain(model, dofs, &ev.hist_new, e));
    }
    out.push(cell("cauchy_stress", 6, sig));
    out.push(cell("von_mises", 1, mises));
    out.push(cell("equivalent_plastic_strain", 1, eqps));
    out
}

/// The six components of a symmetric stress in the VTK files' order (xx, yy, zz, xy, yz,
/// xz: the Voigt order of [`crate::material::stress_to_voigt`]).
pub fn stress_components<S: Scalar>(s: &Matrix3<S>) -> [S; 6] {
    crate::material::stress_to_voigt(s).into()
}

/// The von Mises stress of a stress: the stress response's measure
/// ([`crate::response::StressMeasure::VonMises`]), so that a field and a response read the
/// same number.
pub fn von_mises<S: Scalar>(s: &Matrix3<S>) -> S {
    crate::response::StressMeasure::VonMises.of(s)
}

/// The equivalent plastic strain of element `e` in history `hist`: the mean over its Gauss
/// points of its law's [`EQUIVALENT_PLASTIC_STRAIN`] (0 for a law without one, a spring or an
/// element without history).
pub fn equivalent_plastic_strain<S: Scalar>(
    model: &Model,
    dofs: &crate::model::DofMap,
    hist: &[S],
    e: usize,
) -> S {
    let Some(body) = model.bodies.get(dofs.element_body[e]) else {
        return S::zero();
    };
    let names = body.material.history_names();
    let Some(slot) = names.iter().position(|n| *n == EQUIVALENT_PLASTIC_STRAIN) else {
        return S::zero();
    };
    let h = dofs.history(e);
    let per_point = names.len();
    let ng = dofs.gauss(e).len();
    if ng == 0 || h.len() < ng * per_point || h.end > hist.len() {
        return S::zero();
    }
    let mut sum = S::zero();
    for g in 0..ng {
        sum += hist[h.start + g * per_point + slot];
    }
    sum / S::lift(ng as f64)
}
