//! Every solid family (hex8, hex20, tet4, tet10, wedge6, wedge15, each with its formulations)
//! against independent values: the patch test on a distorted mesh with curved quadratic
//! edges, rigid rotations (proptest), the hand-coded tangent against the dual-number
//! derivative of the internal force, the real part of a dual evaluation against f64, and a
//! homogeneous SVK and J2 state against the material law at a point.

// Index loops over unknowns read like the formulas they check.
#![allow(clippy::needless_range_loop)]

use crate::common::{block, distorted_mesh_of, one_body_model, patch_test, prescribe, solve};
use fricsens::element::{ElementFamily, ElementInput, ElementOutput, Kinematics, Shape};
use fricsens::load::PressureLoad;
use fricsens::material::j2::Hardening;
use fricsens::material::{Branch, J2Plasticity, MaterialLaw, NeoHookean, StVenantKirchhoff};
use fricsens::mesh::Mesh;
use fricsens::model::{Amplitude, Material};
use fricsens::scalar::{tape, Rev, Scalar};
use nalgebra::{Matrix3, Rotation3, SVector, Vector3};
use num_dual::{Derivative, Dual64, DualSVec64};
use proptest::prelude::*;

#[test]
fn patch_test_of_every_family_on_a_distorted_mesh() {
    for family in ElementFamily::solids() {
        let f = family.formulation().unwrap();
        for kinematics in [Kinematics::Small, Kinematics::Large] {
            patch_test(distorted_mesh_of(family.shape(), false), kinematics, f);
        }
    }
}

#[test]
fn curved_edges_pass_the_patch_test_under_the_rules_that_integrate_them() {
    // on curved edges, int grad N_a dV is a polynomial of higher degree than on straight
    // ones; hex20's 3x3x3 rule and tet10's 14 points integrate it exactly on this mesh, so
    // the linear field is reproduced. (Hex20's reduced rule, tet10's 4 points and the
    // wedge15's 3x3 do not: 3e-5 relative at the interior nodes here, a consistency error
    // that vanishes under refinement; measured, not asserted.)
    for family in ElementFamily::solids() {
        if !matches!(family.name(), "hex20" | "hex20-f-bar" | "tet10-high-order") {
            continue;
        }
        let f = family.formulation().unwrap();
        for kinematics in [Kinematics::Small, Kinematics::Large] {
            patch_test(distorted_mesh_of(family.shape(), true), kinematics, f);
        }
    }
}

/// One element of `shape`: its natural node positions, scaled, sheared and with every node
/// moved by a smooth offset (curved edges for the quadratic shapes), positively oriented.
fn distorted_element(shape: Shape) -> Vec<Vector3<f64>> {
    let a = Matrix3::new(1.3, 0.2, -0.1, 0.1, 0.9, 0.15, -0.05, 0.1, 1.1);
    shape
        .natural_nodes()
        .iter()
        .map(|xi| {
            let p = Vector3::new(xi[0], xi[1], xi[2]);
            let bump = Vector3::new(
                0.04 * (2.1 * p[1]).sin(),
                -0.03 * (1.7 * p[2]).cos(),
                0.05 * (1.3 * p[0]).sin(),
            );
            a * p + bump + Vector3::new(2.0, -1.0, 0.5)
        })
        .collect()
}

/// An element's force, tangent, Cauchy stress, branches and updated history.
type Evaluated<S> = (Vec<S>, Vec<S>, Matrix3<S>, Vec<Branch>, Vec<S>);

/// Internal force (and tangent) of one element of `family` at generalised displacements
/// `dofs`, with `material`'s own parameters and a zero history; the Cauchy stress summed
/// only if `want_cauchy`; and the updated history.
fn evaluate<S: Scalar, M: MaterialLaw>(
    family: ElementFamily,
    x: &[Vector3<S>],
    dofs: &[Vector3<S>],
    kinematics: Kinematics,
    material: &M,
    want_tangent: bool,
    want_cauchy: bool,
) -> Evaluated<S> {
    let hist_old = vec![S::zero(); family.n_gauss() * material.history_len()];
    let a = (kinematics, want_tangent, want_cauchy);
    evaluate_from(family, x, dofs, &hist_old, material, a)
}

/// [`evaluate`] from the history `hist_old`.
fn evaluate_from<S: Scalar, M: MaterialLaw>(
    family: ElementFamily,
    x: &[Vector3<S>],
    dofs: &[Vector3<S>],
    hist_old: &[S],
    material: &M,
    (kinematics, want_tangent, want_cauchy): (Kinematics, bool, bool),
) -> Evaluated<S> {
    let nd = 3 * dofs.len();
    let ng = family.n_gauss();
    let params: Vec<S> = material.params().iter().map(|p| S::lift(*p)).collect();
    let mut hist_new = hist_old.to_vec();
    let mut force = vec![S::zero(); nd];
    let mut tangent = vec![S::zero(); if want_tangent { nd * nd } else { 0 }];
    let mut branches = vec![Branch::Elastic; ng];
    let mut yield_ratio = vec![0.0; ng];
    let input = ElementInput {
        x_ref: x,
        dofs,
        kinematics,
        material,
        params: &params,
        hist_old,
        frozen: None,
    };
    let mut out = ElementOutput {
        force: &mut force,
        tangent: want_tangent.then_some(&mut tangent[..]),
        hist_new: &mut hist_new,
        branches: &mut branches,
        yield_ratio: &mut yield_ratio,
        cauchy: Matrix3::zeros(),
        want_cauchy,
        min_det_f: 0.0,
    };
    family.evaluate(&input, &mut out).unwrap();
    let cauchy = out.cauchy;
    (force, tangent, cauchy, branches, hist_new)
}

/// A smooth non-homogeneous displacement of the element's nodes (and small internal modes).
fn displacements(x: &[Vector3<f64>], n_gen: usize, scale: f64) -> Vec<Vector3<f64>> {
    (0..n_gen)
        .map(|a| match x.get(a) {
            Some(p) => {
                Vector3::new(
                    0.05 * p[1] + 0.03 * (p[0] * p[2]).sin(),
                    -0.04 * p[2] + 0.02 * p[0] * p[0],
                    0.06 * p[0] - 0.03 * (p[1] * 1.1).cos(),
                ) * scale
            }
            None => Vector3::new(0.01, -0.02, 0.015) * scale,
        })
        .collect()
}

/// The tangent's column `j` against the derivative of the force along unknown `j`, by a dual
/// evaluation; and the dual evaluation's real part against the f64 one, bit for bit. A dual
/// evaluation without the Cauchy stress (an element whose stress nothing reads: `det F` then
/// a constant of its value) gives the same force and history, real and dual parts, bit for
/// bit.
fn tangent_is_the_force_derivative<M: MaterialLaw>(
    family: ElementFamily,
    kinematics: Kinematics,
    material: &M,
    scale: f64,
    exact_real: bool,
) -> Vec<Branch> {
    let x = distorted_element(family.shape());
    let n_gen = family.n_dofs() / 3;
    let d = displacements(&x, n_gen, scale);
    let (f, k, _, branches, _) = evaluate(family, &x, &d, kinematics, material, true, true);
    let nd = 3 * n_gen;
    let xd: Vec<Vector3<Dual64>> = x.iter().map(|p| p.map(Dual64::from_re)).collect();
    let k_norm = k.iter().map(|v| v * v).sum::<f64>().sqrt();
    for j in 0..nd {
        let dd: Vec<Vector3<Dual64>> = d
            .iter()
            .enumerate()
            .map(|(a, v)| {
                Vector3::from_fn(|c, _| {
                    let seed = if 3 * a + c == j { 1.0 } else { 0.0 };
                    Dual64::new(v[c], seed)
                })
            })
            .collect();
        let (fd, _, _, _, hd) = evaluate(family, &xd, &dd, kinematics, material, false, true);
        let (fs, _, cs, _, hs) = evaluate(family, &xd, &dd, kinematics, material, false, false);
        assert_eq!(cs, Matrix3::zeros(), "{}: no Cauchy stress", family.name());
        for (a, b) in fs.iter().zip(&fd).chain(hs.iter().zip(&hd)) {
            assert_eq!(
                (a.re.to_bits(), a.eps.to_bits()),
                (b.re.to_bits(), b.eps.to_bits()),
                "{} {kinematics:?}: without the Cauchy stress",
                family.name()
            );
        }
        for i in 0..nd {
            if exact_real {
                assert_eq!(
                    fd[i].re,
                    f[i],
                    "{}: real part of the dual force",
                    family.name()
                );
            } else {
                // a quotient in the law (J2's return mapping) is a product by the reciprocal
                // in a dual: its real part is the f64 one up to round-off
                assert!(
                    (fd[i].re - f[i]).abs() < 1e-13 * k_norm,
                    "{}",
                    family.name()
                );
            }
            // the hand-coded tangent and the exact derivative agree to round-off of the
            // element's stiffness scale
            assert!(
                (fd[i].eps - k[i * nd + j]).abs() < 1e-10 * k_norm,
                "{} {kinematics:?}: K[{i}][{j}] = {} vs dF/du = {}",
                family.name(),
                k[i * nd + j],
                fd[i].eps
            );
        }
    }
    branches
}

#[test]
fn tangents_of_every_family_are_the_derivatives_of_their_forces() {
    let svk = StVenantKirchhoff::new(1000.0, 0.3);
    let neo = NeoHookean::new(1000.0, 0.45);
    for family in ElementFamily::solids() {
        for kinematics in [Kinematics::Small, Kinematics::Large] {
            tangent_is_the_force_derivative(family, kinematics, &svk, 1.0, true);
        }
        tangent_is_the_force_derivative(family, Kinematics::Large, &neo, 1.0, true);
    }
}

#[test]
fn plastic_tangents_of_every_family_are_the_derivatives_of_their_forces() {
    // yield stress 1 against a Young's modulus of 1000: strains of a few percent are plastic
    let j2 = J2Plasticity::new(1000.0, 0.3, 1.0, Hardening::Linear { h: 50.0 });
    for family in ElementFamily::solids() {
        let branches = tangent_is_the_force_derivative(family, Kinematics::Large, &j2, 1.0, false);
        assert!(
            branches.contains(&Branch::Plastic),
            "{}: the state is meant to be plastic",
            family.name()
        );
    }
}

/// A reverse-mode recording (which sums the force and the Cauchy stress without the B rows)
/// against the `f64` evaluation with its hand-coded tangent: the same force and stress to
/// round-off (the sums taken in another order), and one sweep weighted by `w` on the force
/// gives `w^T K` to the round-off of the element's stiffness scale, as the dual check above.
/// A recording that wants no Cauchy stress (an element whose stress nothing reads) is a
/// shorter tape with the same force, history and sweep, bit for bit: the skipped sums feed
/// nothing else.
fn recording_is_the_force_and_its_derivative<M: MaterialLaw>(
    family: ElementFamily,
    kinematics: Kinematics,
    material: &M,
) {
    let x = distorted_element(family.shape());
    let n_gen = family.n_dofs() / 3;
    let d = displacements(&x, n_gen, 1.0);
    let (f, k, cauchy, _, _) = evaluate(family, &x, &d, kinematics, material, true, true);
    let nd = 3 * n_gen;
    let scale = |v: &[f64]| v.iter().map(|v| v * v).sum::<f64>().sqrt();
    let (f_norm, k_norm) = (scale(&f), scale(&k));
    tape::clear();
    let xr: Vec<Vector3<Rev>> = x.iter().map(|p| p.map(Rev::constant)).collect();
    let dr: Vec<Vector3<Rev>> = d.iter().map(|v| v.map(Rev::input)).collect();
    let (fr, _, cr, _, hr) = evaluate(family, &xr, &dr, kinematics, material, false, true);
    let name = family.name();
    for (a, b) in fr.iter().zip(&f) {
        assert!(
            (a.value() - b).abs() < 1e-13 * f_norm,
            "{name} {kinematics:?}: force {} vs {b}",
            a.value()
        );
    }
    let c_err = (cr.map(|c| c.value()) - cauchy).norm();
    assert!(
        c_err < 1e-13 * cauchy.norm(),
        "{name} {kinematics:?}: Cauchy stress off by {c_err:.2e}"
    );
    let w: Vec<f64> = (0..nd).map(|i| 1.0 + 0.37 * i as f64).collect();
    let mut adjoint = Vec::new();
    tape::sweep(fr.iter().zip(&w).map(|(f, w)| (*f, *w)), &mut adjoint);
    let w_norm = scale(&w);
    let dr_long: Vec<f64> = (dr.iter().flat_map(|v| v.iter()))
        .map(|x| x.adjoint(&adjoint))
        .collect();
    for (j, dj) in dr.iter().flat_map(|v| v.iter()).enumerate() {
        let want: f64 = (0..nd).map(|i| w[i] * k[i * nd + j]).sum();
        let got = dj.adjoint(&adjoint);
        assert!(
            (got - want).abs() < 1e-10 * k_norm * w_norm,
            "{name} {kinematics:?}: (w^T K)[{j}] = {want} vs the sweep's {got}"
        );
    }
    let long = tape::len();
    tape::clear();
    let dr: Vec<Vector3<Rev>> = d.iter().map(|v| v.map(Rev::input)).collect();
    let (fs, _, cs, _, hs) = evaluate(family, &xr, &dr, kinematics, material, false, false);
    assert!(
        tape::len() < long,
        "{name} {kinematics:?}: without the Cauchy stress the tape is {} entries, with it {long}",
        tape::len()
    );
    assert_eq!(cs.map(|c| c.value()), Matrix3::zeros());
    let mut short = Vec::new();
    tape::sweep(fs.iter().zip(&w).map(|(f, w)| (*f, *w)), &mut short);
    // the same adjoints to the bit: the entries left out fed only the Cauchy stress (and its
    // volume), whose weights are zero, so in the long recording's sweep they held zero
    // adjoints, which the sweep skips (it adds nothing from them, not even a zero)
    for (a, b) in fs.iter().zip(&fr).chain(hs.iter().zip(&hr)) {
        assert_eq!(
            a.value().to_bits(),
            b.value().to_bits(),
            "{name} {kinematics:?}"
        );
    }
    for (a, b) in dr.iter().flat_map(|v| v.iter()).zip(dr_long) {
        let (a, b) = (a.adjoint(&short), b);
        assert_eq!(
            a.to_bits(),
            b.to_bits(),
            "{name} {kinematics:?}: adjoint {a} vs {b}"
        );
    }
    tape::clear();
}

/// Where the reference nodes carry no derivative, an evaluation computes the geometry in
/// `f64` and lifts it; where the displacements carry none either, the kinematics too (F-bar's
/// as well). Neither shortcut may change a value or an adjoint: from a plastic history,
/// every family's J2 evaluation in `Dual64` gives the same force, history and stress real
/// parts to the bit with its history seeded alone (both shortcuts), with a displacement
/// seeded too (the geometry's alone), with a node's coordinate seeded too (neither) and with
/// a node's coordinate seeded alone (neither: a shape parameter's pseudo-load); so
/// does one in `DualSVec64<2>` whose nodes and displacements hold derivative parts that are
/// all zero (constants, both shortcuts); and a recording with the displacements constant
/// (an element whose history alone is an input, as the adjoint records an elastic element
/// that was plastic before) gives the same force, history, stress and history adjoints to
/// the bit as one with them as inputs, and as one with the nodes' coordinates inputs too.
/// Nor may a shortcut drop a derivative: each seeded input's derivative parts (and the
/// recording's adjoints of a displacement and a coordinate) agree with central differences
/// of the `f64` evaluation.
fn constants_in_f64_change_nothing(family: ElementFamily, kinematics: Kinematics, size: f64) {
    let j2 = J2Plasticity::new(1000.0, 0.3, 1.0, Hardening::Linear { h: 50.0 });
    let name = family.name();
    let x: Vec<Vector3<f64>> = (distorted_element(family.shape()).iter())
        .map(|p| p * size)
        .collect();
    let n_gen = family.n_dofs() / 3;
    let d = displacements(&x, n_gen, 1.0);
    let half: Vec<Vector3<f64>> = d.iter().map(|v| v * 0.5).collect();
    let (.., branches, hist) = evaluate(family, &x, &half, kinematics, &j2, false, false);
    assert!(
        branches.contains(&Branch::Plastic) && hist.iter().any(|h| *h != 0.0),
        "{name} {kinematics:?}: the history is meant to be plastic"
    );
    let a = (kinematics, false, true);
    // Dual64: the history's first scalar seeded; then a displacement; then a coordinate
    let lift = |v: &Vector3<f64>| v.map(Dual64::from);
    let h: Vec<Dual64> = (hist.iter().enumerate())
        .map(|(i, v)| Dual64::new(*v, if i == 0 { 1.0 } else { 0.0 }))
        .collect();
    let (xd, dd): (Vec<_>, Vec<_>) = (x.iter().map(lift).collect(), d.iter().map(lift).collect());
    let mut dd_seeded = dd.clone();
    dd_seeded[0][1].eps = 1.0;
    let mut xd_seeded = xd.clone();
    xd_seeded[1][2].eps = 1.0;
    let runs = [
        evaluate_from(family, &xd, &dd, &h, &j2, a),
        evaluate_from(family, &xd, &dd_seeded, &h, &j2, a),
        evaluate_from(family, &xd_seeded, &dd_seeded, &h, &j2, a),
    ];
    let bits = |e: &Evaluated<Dual64>| -> Vec<u64> {
        (e.0.iter().chain(&e.4).chain(e.2.iter()))
            .map(|v| v.re.to_bits())
            .collect()
    };
    for (k, run) in runs.iter().enumerate().skip(1) {
        assert_eq!(bits(run), bits(&runs[0]), "{name} {kinematics:?}: run {k}");
    }
    // and no derivative dropped by a shortcut: each run's derivative parts less the run
    // before's are the derivative in the seed it adds, against central differences of the
    // f64 evaluation
    let fd = FiniteDifferences {
        family,
        x: &x,
        d: &d,
        hist: &hist,
        material: &j2,
        a,
    };
    let parts = |e: &Evaluated<Dual64>| -> Vec<f64> {
        (e.0.iter().chain(&e.4).chain(e.2.iter()))
            .map(|v| v.eps)
            .collect()
    };
    let label = format!("{name} {kinematics:?} size {size}");
    let groups = [3 * n_gen, hist.len(), 9];
    let seeds = [Seed::History, Seed::Dof, Seed::Node];
    for (k, seed) in seeds.into_iter().enumerate() {
        let mut added = parts(&runs[k]);
        if k > 0 {
            for (a, b) in added.iter_mut().zip(parts(&runs[k - 1])) {
                *a -= b;
            }
        }
        let what = format!("{label}: {seed:?}");
        close_to_differences(&added, &fd.central(seed), &groups, &what);
    }
    // the node seeded alone, the displacements and the history constants
    let h_plain: Vec<Dual64> = hist.iter().map(|v| Dual64::from(*v)).collect();
    let node_alone = evaluate_from(family, &xd_seeded, &dd, &h_plain, &j2, a);
    assert_eq!(
        bits(&node_alone),
        bits(&runs[0]),
        "{name} {kinematics:?}: node alone"
    );
    let what = format!("{label}: node alone");
    close_to_differences(&parts(&node_alone), &fd.central(Seed::Node), &groups, &what);
    let zero_parts =
        |v: &Vector3<f64>| v.map(|c| DualSVec64::<2>::new(c, Derivative::some(SVector::zeros())));
    let xs: Vec<_> = x.iter().map(zero_parts).collect();
    let ds: Vec<_> = d.iter().map(zero_parts).collect();
    let hs: Vec<DualSVec64<2>> = (hist.iter().enumerate())
        .map(|(i, v)| DualSVec64::<2>::seeded(*v, if i == 0 { 0 } else { 2 }))
        .collect();
    let wide = evaluate_from(family, &xs, &ds, &hs, &j2, a);
    let wide_bits: Vec<u64> = (wide.0.iter().chain(&wide.4).chain(wide.2.iter()))
        .map(|v| v.re.to_bits())
        .collect();
    assert_eq!(
        wide_bits,
        bits(&runs[0]),
        "{name} {kinematics:?}: DualSVec64"
    );
    // a displacement seeded in the second part: the same values, and that part the
    // displacement's derivative (the first still the history's)
    let mut ds_seeded = ds.clone();
    ds_seeded[0][1] = DualSVec64::<2>::seeded(d[0][1], 1);
    let wide = evaluate_from(family, &xs, &ds_seeded, &hs, &j2, a);
    let wide_values = || wide.0.iter().chain(&wide.4).chain(wide.2.iter());
    let wide_bits: Vec<u64> = wide_values().map(|v| v.re.to_bits()).collect();
    assert_eq!(
        wide_bits,
        bits(&runs[0]),
        "{name} {kinematics:?}: DualSVec64 seeded"
    );
    for (k, seed) in [Seed::History, Seed::Dof].into_iter().enumerate() {
        let part: Vec<f64> = wide_values().map(|v| v.part(k)).collect();
        close_to_differences(
            &part,
            &fd.central(seed),
            &groups,
            &format!("{label}: part {k}"),
        );
    }
    // Rev: the history an input; the displacements constants, then inputs; then the
    // nodes' coordinates inputs too
    let record = |(nodes, dofs): (bool, bool)| -> ((Vec<u64>, Vec<u64>), [f64; 2]) {
        tape::clear();
        let rev = |input: bool| if input { Rev::input } else { Rev::constant };
        let xr: Vec<Vector3<Rev>> = x.iter().map(|p| p.map(rev(nodes))).collect();
        let dr: Vec<Vector3<Rev>> = d.iter().map(|v| v.map(rev(dofs))).collect();
        let hr: Vec<Rev> = hist.iter().map(|v| Rev::input(*v)).collect();
        let (f, _, c, _, hn) = evaluate_from(family, &xr, &dr, &hr, &j2, a);
        let weights = (f.iter().chain(&hn).chain(c.iter()).enumerate())
            .map(|(i, v)| (*v, 1.0 + 0.37 * i as f64));
        let mut adjoint = Vec::new();
        tape::sweep(weights, &mut adjoint);
        let values = (f.iter().chain(&hn).chain(c.iter()))
            .map(|v| v.value().to_bits())
            .collect();
        let adjoints = hr.iter().map(|v| v.adjoint(&adjoint).to_bits()).collect();
        let others = [dr[0][1].adjoint(&adjoint), xr[1][2].adjoint(&adjoint)];
        tape::clear();
        ((values, adjoints), others)
    };
    let (plain, _) = record((false, false));
    for inputs in [(false, true), (true, true)] {
        let (same, _) = record(inputs);
        assert_eq!(same, plain, "{name} {kinematics:?}: recording {inputs:?}");
    }
    // the displacement's and the coordinate's adjoints: the weighted sum's derivatives
    let (_, [dof, node]) = record((true, true));
    let weighted = |seed: Seed| -> f64 {
        (fd.central(seed).iter().enumerate())
            .map(|(i, v)| v * (1.0 + 0.37 * i as f64))
            .sum()
    };
    for (adjoint, seed) in [(dof, Seed::Dof), (node, Seed::Node)] {
        close_to_differences(
            &[adjoint],
            &[weighted(seed)],
            &[],
            &format!("{label}: Rev {seed:?}"),
        );
    }
}

/// The input a derivative is taken in: the history's first scalar, the first node's `y`
/// displacement, the second node's `z` coordinate.
#[derive(Clone, Copy, Debug)]
enum Seed {
    History,
    Dof,
    Node,
}

/// Central differences of an element's `f64` evaluation (force, new history, Cauchy
/// stress) in one input.
struct FiniteDifferences<'a, M: MaterialLaw> {
    family: ElementFamily,
    x: &'a [Vector3<f64>],
    d: &'a [Vector3<f64>],
    hist: &'a [f64],
    material: &'a M,
    a: (Kinematics, bool, bool),
}

impl<M: MaterialLaw> FiniteDifferences<'_, M> {
    fn central(&self, seed: Seed) -> Vec<f64> {
        let at = |step: f64| -> Vec<f64> {
            let (mut x, mut d, mut h) = (self.x.to_vec(), self.d.to_vec(), self.hist.to_vec());
            match seed {
                Seed::History => h[0] += step,
                Seed::Dof => d[0][1] += step,
                Seed::Node => x[1][2] += step,
            }
            let e = evaluate_from(self.family, &x, &d, &h, self.material, self.a);
            e.0.iter().chain(&e.4).chain(e.2.iter()).copied().collect()
        };
        let step = 1e-6;
        let (up, down) = (at(step), at(-step));
        up.iter()
            .zip(&down)
            .map(|(u, w)| (u - w) / (2.0 * step))
            .collect()
    }
}

/// `derivatives` agree with central `differences` to 1e-5 of the largest of them in each
/// group of outputs (the force, the new history and the stress, whose derivatives differ
/// by orders of magnitude: `groups` their lengths in that order; one group where not given):
/// a step of 1e-6 leaves a truncation error of about 1e-12 and a round-off of about 1e-10
/// relative; a derivative a shortcut dropped is off by its own size. A group whose
/// differences are all zero is held to 1e-5 of the largest over all.
fn close_to_differences(derivatives: &[f64], differences: &[f64], groups: &[usize], what: &str) {
    let largest = |v: &[f64]| v.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let overall = largest(differences);
    assert!(overall > 0.0, "{what}: no derivative to compare");
    let whole = [differences.len()];
    let groups = if groups.is_empty() {
        &whole[..]
    } else {
        groups
    };
    assert_eq!(groups.iter().sum::<usize>(), differences.len(), "{what}");
    let mut start = 0;
    for (g, len) in groups.iter().enumerate() {
        let range = start..start + len;
        start += len;
        let scale = match largest(&differences[range.clone()]) {
            0.0 => overall,
            s => s,
        };
        for i in range {
            let (a, b) = (derivatives[i], differences[i]);
            assert!(
                (a - b).abs() <= 1e-5 * scale,
                "{what}: output {i} (group {g}): {a} against the differences' {b} (scale {scale})"
            );
        }
    }
}

#[test]
fn constant_inputs_computed_in_f64_change_no_value_and_no_adjoint() {
    for family in ElementFamily::solids() {
        for kinematics in [Kinematics::Small, Kinematics::Large] {
            // elements of several sizes: a ratio rounded two ways (a true quotient against
            // a product by the reciprocal) agrees on many operands, differs on some
            for size in [1.0, 0.7, 1.3, 2.9] {
                constants_in_f64_change_nothing(family, kinematics, size);
            }
        }
    }
}

#[test]
fn a_recording_gives_the_force_and_the_tangents_vector_jacobian_product() {
    let svk = StVenantKirchhoff::new(1000.0, 0.3);
    let j2 = J2Plasticity::new(1000.0, 0.3, 1.0, Hardening::Linear { h: 50.0 });
    for family in ElementFamily::solids() {
        for kinematics in [Kinematics::Small, Kinematics::Large] {
            recording_is_the_force_and_its_derivative(family, kinematics, &svk);
            recording_is_the_force_and_its_derivative(family, kinematics, &j2);
        }
    }
}

/// The Cauchy stress of the material law at a point under a homogeneous deformation gradient
/// `f` (large kinematics).
fn cauchy_at_a_point<M: MaterialLaw>(material: &M, f: &Matrix3<f64>) -> Matrix3<f64> {
    let e = (f.transpose() * f - Matrix3::identity()) * 0.5;
    let mut h = vec![0.0; material.history_len()];
    let r = material.update(material.params(), &e, &h.clone(), &mut h, None, true);
    f * r.stress * f.transpose() / f.determinant()
}

#[test]
fn a_homogeneous_state_is_the_material_law_at_every_point() {
    // uniaxial stretch of 3 % with lateral contraction, elastic (SVK) and plastic (J2): every
    // family represents the homogeneous state exactly, so its stress is the law's
    let f = Matrix3::from_diagonal(&Vector3::new(1.03, 0.99, 0.992));
    let svk = StVenantKirchhoff::new(1000.0, 0.3);
    let j2 = J2Plasticity::new(1000.0, 0.3, 1.0, Hardening::Linear { h: 50.0 });
    for family in ElementFamily::solids() {
        let x = distorted_element(family.shape());
        let n_gen = family.n_dofs() / 3;
        let d: Vec<Vector3<f64>> = (0..n_gen)
            .map(|a| match x.get(a) {
                Some(p) => (f - Matrix3::identity()) * p,
                None => Vector3::zeros(), // no incompatible mode in a homogeneous state
            })
            .collect();
        let (_, _, c, _, _) = evaluate(family, &x, &d, Kinematics::Large, &svk, false, true);
        let expected = cauchy_at_a_point(&svk, &f);
        assert!(
            (c - expected).norm() < 1e-12 * expected.norm(),
            "{}",
            family.name()
        );
        let (_, _, c, branches, _) = evaluate(family, &x, &d, Kinematics::Large, &j2, false, true);
        let expected = cauchy_at_a_point(&j2, &f);
        assert!(branches.iter().all(|b| *b == Branch::Plastic));
        assert!(
            (c - expected).norm() < 1e-12 * expected.norm(),
            "{}: {c} vs {expected}",
            family.name()
        );
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(16))]

    #[test]
    fn rigid_motions_of_every_family_leave_it_unstressed(
        axis in (-1.0f64..1.0, -1.0f64..1.0, -1.0f64..1.0),
        angle in -3.1f64..3.1,
        shift in (-2.0f64..2.0, -2.0f64..2.0, -2.0f64..2.0),
    ) {
        let axis = Vector3::new(axis.0, axis.1, axis.2 + 1.5); // never zero
        let q = Rotation3::from_axis_angle(&nalgebra::Unit::new_normalize(axis), angle);
        let t = Vector3::new(shift.0, shift.1, shift.2);
        let svk = StVenantKirchhoff::new(1000.0, 0.3);
        for family in ElementFamily::solids() {
            let x = distorted_element(family.shape());
            let n_gen = family.n_dofs() / 3;
            let d: Vec<Vector3<f64>> = (0..n_gen)
                .map(|a| match x.get(a) {
                    Some(p) => q * p + t - p,
                    None => Vector3::zeros(),
                })
                .collect();
            let (f, _, c, _, _) = evaluate(family, &x, &d, Kinematics::Large, &svk, false, true);
            // force scale of a unit strain: E times the element's size (about 1)
            let fmax = f.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            prop_assert!(fmax < 1e-10 * 1000.0, "{}: force {fmax}", family.name());
            prop_assert!(c.norm() < 1e-10 * 1000.0, "{}: stress {}", family.name(), c.norm());
        }
    }
}

/// A block of `shape` elements, 3 x 2 x 2 cells over 3 x 2 x 1.5.
fn block_of(shape: Shape) -> Mesh {
    let mut mesh = Mesh::default();
    let mut spec = block("b", [3, 2, 2], [3.0, 2.0, 1.5]);
    spec.element = shape;
    mesh.add_block(spec).unwrap();
    mesh
}

#[test]
fn generated_blocks_of_every_shape_fill_the_block_and_its_sides() {
    for shape in Shape::SOLIDS {
        let mesh = block_of(shape);
        let x = mesh.coordinates::<f64>(&mesh.block_geometry());
        let family = ElementFamily::standard(shape);
        let volume: f64 = (0..mesh.n_elements())
            .map(|e| {
                let xe: Vec<Vector3<f64>> = mesh.element_nodes(e).iter().map(|&n| x[n]).collect();
                family.reference_volume(&xe).unwrap()
            })
            .sum();
        assert!((volume - 9.0).abs() < 1e-12, "{shape:?}: volume {volume}");
        let lengths = [3.0, 2.0, 1.5];
        for (s, side) in ["xmin", "xmax", "ymin", "ymax", "zmin", "zmax"]
            .iter()
            .enumerate()
        {
            let axis = s / 2;
            let at = if s % 2 == 0 { 0.0 } else { lengths[axis] };
            let faces = &mesh.face_sets[&format!("b.{side}")];
            let mut area = Vector3::<f64>::zeros();
            for f in faces.iter() {
                let xf: Vec<Vector3<f64>> = f.nodes.iter().map(|&n| x[n]).collect();
                area += f.family.normal_weights(&xf).iter().sum::<Vector3<f64>>();
                assert!(f.nodes.iter().all(|&n| x[n][axis] == at));
            }
            // outward: the side's area vector points along -/+ its axis
            let mut expected = Vector3::zeros();
            expected[axis] = if s % 2 == 0 { -1.0 } else { 1.0 } * 9.0 / lengths[axis];
            assert!((area - expected).norm() < 1e-12, "{shape:?} {side}: {area}");
            let nodes = &mesh.node_sets[&format!("b.{side}")];
            let on: Vec<usize> = (0..x.len()).filter(|&n| x[n][axis] == at).collect();
            assert_eq!(nodes, &on, "{shape:?} {side}");
        }
    }
}

#[test]
fn a_pressed_block_of_every_family_is_in_uniaxial_stress() {
    // pressure p on x = 3, symmetry planes x = 0, y = 0, z = 0: u = (-x, nu y, nu z) p / E,
    // a linear field that every family represents; the pressure's consistent nodal forces on
    // quad4, quad8, tri3 and tri6 faces are what make it exact
    let (young, nu, p) = (1000.0, 0.3, 2.0);
    for family in ElementFamily::solids() {
        let mesh = block_of(family.shape());
        let x = mesh.coordinates::<f64>(&mesh.block_geometry());
        let mut model = one_body_model(
            mesh.clone(),
            Material::Svk(StVenantKirchhoff::new(young, nu)),
            Kinematics::Small,
            family.formulation().unwrap(),
        );
        for (c, side) in ["xmin", "ymin", "zmin"].iter().enumerate() {
            prescribe(
                &mut model,
                mesh.node_sets[&format!("b.{side}")].clone(),
                c,
                0.0,
            );
        }
        model.pressures.push(PressureLoad {
            name: "p".into(),
            faces: mesh.face_sets["b.xmax"].clone(),
            value: p,
            amplitude: Amplitude::ramp(),
        });
        let res = solve(&model);
        let z = res.states.last().unwrap();
        for (n, xn) in x.iter().enumerate() {
            let u = Vector3::new(-xn[0], nu * xn[1], nu * xn[2]) * (p / young);
            for c in 0..3 {
                assert!(
                    (z[3 * n + c] - u[c]).abs() < 1e-10 * 3.0 * p / young,
                    "{} node {n} comp {c}: {} vs {}",
                    family.name(),
                    z[3 * n + c],
                    u[c]
                );
            }
        }
    }
}

/// Two blocks 2 x 2 x 1 stacked along z (`lower` of `lower_shape` elements, `upper` of
/// `upper_shape`, 2 x 2 x 1 cells each), the upper one's nodes on its bottom pressed onto the
/// lower one's top faces (frictionless, Lagrange multipliers), the upper top moved down by
/// 0.01, symmetry planes x = 0 and y = 0, the lower bottom held in z: small strains, E = 1000,
/// nu = 0.3.
fn stacked(lower_shape: Shape, upper_shape: Shape) -> fricsens::model::Model {
    let block = |name: &str, shape: Shape, z: f64| {
        format!(
            r#"
[[bodies]]
name = "{name}"
element = "{shape}"
origin = [0.0, 0.0, {z:?}]
kinematics = "small"
x = {{ length = 2.0, zones = [ {{ fraction = 1.0, elements = 2, ratio = 1.0 }} ] }}
y = {{ length = 2.0, zones = [ {{ fraction = 1.0, elements = 2, ratio = 1.0 }} ] }}
z = {{ length = 1.0, zones = [ {{ fraction = 1.0, elements = 1, ratio = 1.0 }} ] }}
material = {{ law = "svk", E = 1000.0, nu = 0.3 }}
"#,
            shape = shape.name()
        )
    };
    let text = format!(
        r#"
name = "stacked"
{}
{}
[[prescribed]]
name = "base"
set = "lower.zmin"
components = ["z"]
[[prescribed]]
name = "press"
set = "upper.zmax"
components = ["z"]
value = -0.01
[[prescribed]]
name = "x-symmetry"
set = "lower.xmin"
components = ["x"]
[[prescribed]]
name = "x-symmetry-upper"
set = "upper.xmin"
components = ["x"]
[[prescribed]]
name = "y-symmetry"
set = "lower.ymin"
components = ["y"]
[[prescribed]]
name = "y-symmetry-upper"
set = "upper.ymin"
components = ["y"]

[[contacts]]
name = "interface"
hitting = "upper.zmin"
target = {{ faces = "lower.zmax" }}

[[steps]]
end = 1.0
increments = 1

[[responses]]
kind = "reaction"
name = "top"
set = "upper.zmax"
component = "z"
[[responses]]
kind = "reaction"
name = "bottom"
set = "lower.zmin"
component = "z"
[[responses]]
kind = "pressure-profile"
name = "p"
pair = "interface"
along = "x"
per = "node"
"#,
        block("lower", lower_shape, 0.0),
        block("upper", upper_shape, 1.0)
    );
    fricsens::scene::Scene::from_toml(&text, "stacked.toml")
        .expect("the scene parses")
        .build()
        .expect("the scene builds")
}

#[test]
fn stacked_blocks_of_every_shape_carry_the_press_through_their_contact() {
    // every target node under a hitting node (matching meshes of one shape; a hex20 under a
    // tet10 or wedge15 block, whose hitting nodes cover the quad8 nodes and the faces'
    // centres): the contact forces can be the target's consistent loads and the state is
    // uniaxial stress, u = (nu x, nu y, -z) e with e = 0.01 / 2, the force E e A = 20. A hex20
    // cannot be the hitting side: its quad8 corners' consistent loads are negative (-1/12 of
    // the face's), a tension no contact carries. Hitting nodes only at the corners of
    // quadratic target faces (a hex8 on a hex20 or tet10, a tet4 on a wedge15) leave the
    // faces' mid-side nodes free to bulge between them: node-to-segment sees nothing there,
    // and this coarse stack carries 0.53-0.62 of the force (measured); the invariant there
    // is equilibrium, top reaction = -bottom reaction. Where the state is uniform, every
    // hitting node reads the stress E e as its contact pressure: its normal force over its
    // pressure area (on tri6 faces the consistent shares, nothing at the corners; a corner
    // reads the mean of its faces' mid-sides).
    let e = 0.005;
    let exact = 1000.0 * e * 4.0;
    for (lower, upper, uniform) in [
        (Shape::Hex8, Shape::Hex8, true),
        (Shape::Tet4, Shape::Tet4, true),
        (Shape::Tet10, Shape::Tet10, true),
        (Shape::Wedge6, Shape::Wedge6, true),
        (Shape::Wedge15, Shape::Wedge15, true),
        (Shape::Hex20, Shape::Tet10, true),
        (Shape::Hex20, Shape::Wedge15, true),
        (Shape::Hex20, Shape::Hex8, false),
        (Shape::Tet10, Shape::Hex8, false),
        (Shape::Wedge15, Shape::Tet4, false),
    ] {
        let model = stacked(lower, upper);
        let res = solve(&model);
        let k = res.times.len() - 1;
        let value = |name: &str| {
            let r = model.responses.iter().position(|r| r.name == name).unwrap();
            res.response_value(&model, r, k)
        };
        let (top, bottom) = (value("top"), value("bottom"));
        // the solver stops at |R| <= 1e-9 of the force scale
        assert!(
            (top + bottom).abs() < 1e-8 * exact,
            "{lower:?} under {upper:?}: top {top}, bottom {bottom}"
        );
        if uniform {
            assert!(
                (top + exact).abs() < 1e-8 * exact,
                "{lower:?} under {upper:?}: top reaction {top}, exact {}",
                -exact
            );
            let stress = 1000.0 * e;
            let mut read = 0;
            for (r, resp) in model.responses.iter().enumerate() {
                if resp.name.starts_with("p[") {
                    let p = res.response_value(&model, r, k);
                    assert!(
                        (p - stress).abs() < 1e-8 * stress,
                        "{lower:?} under {upper:?}: {} = {p}",
                        resp.name
                    );
                    read += 1;
                }
            }
            let pair = &model.contacts[0];
            let c = &res.contact[k];
            let n = pair.hitting.len();
            let p = pair.nodal_pressures(&c.normal_force[..n], &c.area[..n]);
            assert!(read > 0 && read <= n);
            for (i, p) in p.iter().enumerate() {
                assert!(
                    (p - stress).abs() < 1e-8 * stress,
                    "{lower:?} under {upper:?}: node {} reads {p}",
                    pair.hitting[i]
                );
            }
            let x = model.mesh.coordinates::<f64>(&model.mesh.block_geometry());
            let z = res.states.last().unwrap();
            for (n, p) in x.iter().enumerate() {
                let u = Vector3::new(0.3 * e * p.x, 0.3 * e * p.y, -e * p.z);
                assert!(
                    (Vector3::from_column_slice(&z[3 * n..3 * n + 3]) - u).norm() < 1e-9 * e,
                    "{lower:?} node {n}"
                );
            }
        }
    }
}

#[test]
fn every_family_converges_at_its_order_on_lames_cylinder() {
    // the report's study on its three coarser meshes (2, 4, 8 elements through the wall):
    // L2 orders of the displacement and of its DDM derivatives in E and in a shape parameter
    // against the closed forms. Measured: 1.8-1.9 for the linear families, 2.9-3.4 for the
    // quadratic ones; the bands below allow for the coarse meshes' pre-asymptotic slopes
    use fricsens::studies::validate::convergence::{order, study};
    let rows = study(&[2, 4, 8]).unwrap();
    for shape in fricsens::studies::validate::convergence::SHAPES {
        let name = ElementFamily::standard(shape).name();
        let mine: Vec<_> = rows.iter().filter(|r| r.family == name).collect();
        let (low, high) = if shape.is_quadratic() {
            (2.7, 3.6)
        } else {
            (1.7, 2.3)
        };
        for (what, o) in [
            ("u", order(&mine, |r| r.displacement)),
            ("du/dE", order(&mine, |r| r.d_young)),
            ("du/db", order(&mine, |r| r.d_radius)),
        ] {
            assert!(
                (low..=high).contains(&o),
                "{name}: order of {what} {o:.2}, expected in [{low}, {high}]"
            );
        }
    }
}

#[test]
fn a_formulation_the_shape_does_not_take_is_a_typed_error_naming_the_body() {
    // every shape against every formulation: a scene builds exactly when the shape takes it
    for shape in Shape::SOLIDS {
        for f in fricsens::element::Formulation::ALL {
            let text = format!(
                r#"
name = "one-block"
[[bodies]]
name = "b"
element = "{}"
formulation = "{}"
origin = [0.0, 0.0, 0.0]
x = {{ length = 1.0, zones = [ {{ fraction = 1.0, elements = 1, ratio = 1.0 }} ] }}
y = {{ length = 1.0, zones = [ {{ fraction = 1.0, elements = 1, ratio = 1.0 }} ] }}
z = {{ length = 1.0, zones = [ {{ fraction = 1.0, elements = 1, ratio = 1.0 }} ] }}
material = {{ law = "svk", E = 1000.0, nu = 0.3 }}
[[steps]]
end = 1.0
increments = 1
"#,
                shape.name(),
                f.name()
            );
            let built = fricsens::scene::Scene::from_toml(&text, "one-block.toml")
                .expect("the scene parses")
                .build();
            let takes = ElementFamily::new(shape, Some(f)).is_ok();
            match built {
                Ok(_) => assert!(takes, "{shape:?} built with {f:?}"),
                Err(e) => {
                    // the same model made in code reaches the solver, which refuses it too
                    let model = one_body_model(
                        block_of(shape),
                        Material::Svk(StVenantKirchhoff::new(1000.0, 0.3)),
                        Kinematics::Small,
                        f,
                    );
                    match fricsens::solver::Solver::new(&model) {
                        Err(fricsens::solver::AnalysisError::Model(
                            fricsens::solver::ModelError::Formulation { body, .. },
                        )) => assert_eq!(body, "b"),
                        Err(other) => panic!("{shape:?} with {f:?} in code: {other}"),
                        Ok(_) => panic!("{shape:?} with {f:?} in code: the solver took it"),
                    }
                    assert!(!takes, "{shape:?} refused {f:?}: {e}");
                    let message = e.to_string();
                    assert!(
                        message.contains("bodies[0].formulation") && message.contains(f.name()),
                        "{message}"
                    );
                }
            }
        }
    }
}

#[test]
fn hertz_on_hex20_and_tet10_blocks_within_two_percent_with_fewer_unknowns_than_hex8() {
    // the report's study (fricsens validate) on its coarser meshes: a and p0 against Hertz
    // (oracles.md section 4) within the issue's 2 %, with fewer unknowns than the fewest the
    // hex8 block needs for it; DDM's dp0/dE = p0 / (2 E) within 2 % as well
    use fricsens::studies::validate::hertz_families::row;
    let within = |r: &fricsens::studies::validate::hertz_families::HertzRow| {
        r.half_width_error < 0.02 && r.peak_error < 0.02
    };
    let hex8 = [3, 6]
        .into_iter()
        .map(|n| row(Shape::Hex8, n).unwrap())
        .find(within)
        .expect("hex8 within 2 % on 6 elements across a");
    for (shape, n) in [(Shape::Hex20, 6), (Shape::Tet10, 3)] {
        let r = row(shape, n).unwrap();
        println!("{r:?}");
        assert!(within(&r) && r.d_peak_error < 0.02, "{r:?}");
        assert!(
            r.unknowns < hex8.unknowns,
            "{shape:?}: {} unknowns, hex8 {}",
            r.unknowns,
            hex8.unknowns
        );
    }
}

#[test]
fn dp_dmu_along_a_curved_punch_agrees_between_ddm_sdm_and_fdm() {
    // the smoothness study's scene (fricsens validate) on a coarse hex20 punch and slab:
    // central SDM and central FDM, independent of DDM, give its profile of dp/dmu. FDM's
    // reruns converge to a relative force tolerance of 1e-9, so their noise over the step
    // 2 beta mu is about 1e-9 / 1e-4 = 1e-5 of the derivative; central SDM's truncation is of
    // order beta^2 = 1e-8
    use fricsens::studies::validate::smoothness::rows;
    let dir = std::env::temp_dir().join(format!("fricsens-smoothness-{}", std::process::id()));
    let rows = rows((Shape::Hex20, 0.5), (Shape::Hex20, 0.5), &dir).unwrap();
    let _ = std::fs::remove_dir_all(&dir);
    assert_eq!(rows.len(), 3);
    let ddm = &rows[0];
    assert!(ddm.x.len() >= 8, "{} stations in contact", ddm.x.len());
    for (r, tol) in [(&rows[1], 1e-6), (&rows[2], 1e-4)] {
        assert_eq!(r.x, ddm.x);
        assert!(
            r.max_deviation <= tol * ddm.max_abs,
            "{}: {} against max {}",
            r.method,
            r.max_deviation,
            ddm.max_abs
        );
    }
}
