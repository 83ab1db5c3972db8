//! Hex8 fixtures: blocks and one-body models, a distorted mesh, one element evaluated on its
//! own, prescribed displacements, rigid motions and a deformed cantilever off equilibrium.

use fricsens::element::hex8;
use fricsens::element::hex8::{Hex8Input, Hex8Output};
use fricsens::element::{Formulation, Kinematics};
use fricsens::material::StVenantKirchhoff;
use fricsens::material::{Branch, MaterialLaw};
use fricsens::mesh::{Axis, BlockSpec, Mesh, NodePlace};
use fricsens::model::{Amplitude, Body, Material, Model, Prescribed};
use fricsens::scene::{cantilever, CantileverSpec};
use nalgebra::{Matrix3, Vector3};

use super::solve;

pub fn block(name: &str, n: [usize; 3], l: [f64; 3]) -> BlockSpec {
    BlockSpec {
        element: fricsens::element::Shape::Hex8,
        name: name.into(),
        origin: [0.0; 3],
        x: Axis::uniform(l[0], n[0]),
        y: Axis::uniform(l[1], n[1]),
        z: Axis::uniform(l[2], n[2]),
    }
}

pub fn one_body_model(
    mesh: Mesh,
    material: Material,
    kinematics: Kinematics,
    formulation: Formulation,
) -> Model {
    Model {
        mesh,
        bodies: vec![Body {
            name: "b".into(),
            group: 0,
            material,
            kinematics,
            formulation: Some(formulation),
        }],
        times: vec![1.0],
        ..Model::default()
    }
}

/// A 2x2x2 block whose interior node and some surface nodes are moved off the grid.
pub fn distorted_mesh() -> Mesh {
    distorted_mesh_of(fricsens::element::Shape::Hex8, false)
}

/// A 2x2x2 block of `shape` elements (the generator's hex cells, split for tetrahedra and
/// wedges) whose corner nodes but the cube's are moved off the grid by a smooth, non-affine
/// offset. A quadratic shape's mid-edge nodes stay at the middle of their (moved) corners
/// when `curved` is false: straight edges, the patch test's distorted mesh. With `curved`,
/// they are moved by the same offset as the corners: curved edges.
pub fn distorted_mesh_of(shape: fricsens::element::Shape, curved: bool) -> Mesh {
    let mut mesh = Mesh::default();
    let mut spec = block("b", [2, 2, 2], [2.0, 2.0, 2.0]);
    spec.element = shape;
    mesh.add_block(spec).unwrap();
    let x = mesh.coordinates::<f64>(&mesh.block_geometry());
    for (n, p) in mesh.places.iter_mut().enumerate() {
        let c = x[n];
        // move every node that is not a corner of the cube by a smooth, non-affine offset
        let corner = (0..3).all(|i| c[i] == 0.0 || c[i] == 2.0);
        if !corner {
            let d = Vector3::new(
                0.13 * (c[1] * 1.7).sin() * (c[0] * (2.0 - c[0])).min(1.0),
                -0.11 * (c[2] * 1.3).cos() * (c[1] * (2.0 - c[1])).min(1.0),
                0.09 * (c[0] * 0.9).sin() * (c[2] * (2.0 - c[2])).min(1.0),
            );
            *p = NodePlace::Free([c[0] + d[0], c[1] + d[1], c[2] + d[2]]);
        }
    }
    if shape.is_quadratic() && !curved {
        let x = mesh.coordinates::<f64>(&mesh.block_geometry());
        let n_corners = shape.corners().n_nodes();
        let elements: Vec<Vec<usize>> = mesh.elements().map(|(_, e)| e.to_vec()).collect();
        for e in elements {
            for (k, [a, b]) in shape.edges().iter().enumerate() {
                let m = (x[e[*a]] + x[e[*b]]) * 0.5;
                mesh.places[e[n_corners + k]] = NodePlace::Free([m[0], m[1], m[2]]);
            }
        }
    }
    mesh
}

pub fn boundary_nodes(mesh: &Mesh) -> Vec<usize> {
    let mut v: Vec<usize> = ["xmin", "xmax", "ymin", "ymax", "zmin", "zmax"]
        .iter()
        .flat_map(|s| mesh.node_sets[&format!("b.{s}")].clone())
        .collect();
    v.sort();
    v.dedup();
    v
}

pub fn unit_cube() -> [Vector3<f64>; 8] {
    std::array::from_fn(|a| {
        let xi = hex8::NODE_XI[a];
        Vector3::new(
            0.5 * (xi[0] + 1.0),
            0.5 * (xi[1] + 1.0),
            0.5 * (xi[2] + 1.0),
        )
    })
}

pub struct ElementResult<S> {
    pub force: Vec<S>,
    pub tangent: Vec<S>,
    pub hist_new: Vec<S>,
    pub cauchy: Matrix3<S>,
}

/// One hex8 evaluated with its material's own parameters (no branch imposed).
pub fn element<S: fricsens::scalar::Scalar, M: MaterialLaw>(
    x_ref: &[Vector3<S>; 8],
    dofs: &[Vector3<S>],
    kinematics: Kinematics,
    formulation: Formulation,
    material: &M,
    hist_old: &[S],
    want_tangent: bool,
) -> ElementResult<S> {
    let nd = 3 * dofs.len();
    let params: Vec<S> = material.params().iter().map(|p| S::lift(*p)).collect();
    let mut force = vec![S::zero(); nd];
    let mut tangent = vec![S::zero(); if want_tangent { nd * nd } else { 0 }];
    let mut hist_new = vec![S::zero(); 8 * material.history_len()];
    let input = Hex8Input {
        x_ref,
        dofs,
        kinematics,
        formulation,
        material,
        params: &params,
        hist_old,
        frozen: None,
    };
    let mut out = Hex8Output {
        force: &mut force,
        tangent: if want_tangent {
            Some(&mut tangent[..])
        } else {
            None
        },
        hist_new: &mut hist_new,
        branches: [Branch::Elastic; 8],
        yield_ratio: [0.0; 8],
        cauchy: Matrix3::zeros(),
        min_det_f: 0.0,
    };
    hex8::evaluate(&input, &mut out).unwrap();
    let cauchy = out.cauchy;
    ElementResult {
        force,
        tangent,
        hist_new,
        cauchy,
    }
}

/// Prescribe component `c` of `nodes` to `v` (ramped), named after the first node.
pub fn prescribe(model: &mut Model, nodes: Vec<usize>, c: usize, v: f64) {
    model.prescribed.push(Prescribed {
        name: format!("n{}c{c}", nodes[0]),
        nodes,
        component: c,
        value: v,
        amplitude: Amplitude::ramp(),
    });
}

/// One St. Venant-Kirchhoff hex8 (large kinematics) moved rigidly, `x -> q x + c` (internal
/// unknowns of `formulation` at zero): the largest nodal force and the norm of the Cauchy stress.
pub fn rigid_motion_force(
    formulation: Formulation,
    x_ref: [Vector3<f64>; 8],
    q: Matrix3<f64>,
    c: Vector3<f64>,
) -> (f64, f64) {
    let mat = StVenantKirchhoff::new(2.0e5, 0.3);
    let mut dofs: Vec<Vector3<f64>> = x_ref.iter().map(|x| q * x + c - x).collect();
    dofs.extend(vec![Vector3::zeros(); formulation.internal_dofs() / 3]);
    let r = element(
        &x_ref,
        &dofs,
        Kinematics::Large,
        formulation,
        &mat,
        &[],
        false,
    );
    let fmax = r.force.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    (fmax, r.cauchy.norm())
}

/// The large-deflection cantilever (10 elements, 4 increments) solved, and its last state
/// stepped off equilibrium so that checks there are at a generic state.
pub fn deformed_cantilever(
    kinematics: Kinematics,
    formulation: Formulation,
    nu: f64,
) -> (Model, Vec<f64>) {
    let spec = CantileverSpec {
        nx: 10,
        nu,
        alpha: 2.0,
        increments: 4,
        kinematics,
        formulation,
        ..CantileverSpec::large_deflection()
    };
    let model = cantilever(&spec).build().unwrap();
    let res = solve(&model);
    let mut z = res.states.last().unwrap().clone();
    // step off equilibrium so the check is at a generic state
    for (i, zi) in z.iter_mut().enumerate() {
        *zi += 1e-3 * ((i as f64) * 0.37).sin();
    }
    (model, z)
}

/// The patch test: the boundary nodes of `mesh` follow an affine displacement field; every
/// node must follow it and every element carry its exact, uniform stress (St Venant-Kirchhoff).
pub fn patch_test(mesh: Mesh, kinematics: Kinematics, formulation: Formulation) {
    let x = mesh.coordinates::<f64>(&mesh.block_geometry());
    let grad_u = Matrix3::new(
        0.010, 0.004, -0.002, 0.003, -0.006, 0.005, -0.001, 0.002, 0.008,
    );
    let mut model = one_body_model(
        mesh.clone(),
        Material::Svk(StVenantKirchhoff::new(1000.0, 0.3)),
        kinematics,
        formulation,
    );
    for n in boundary_nodes(&mesh) {
        let u = grad_u * x[n];
        for c in 0..3 {
            prescribe(&mut model, vec![n], c, u[c]);
        }
    }
    let res = solve(&model);
    let z = &res.states[1];
    for (n, xn) in x.iter().enumerate() {
        let u = grad_u * xn;
        for c in 0..3 {
            assert!(
                (z[3 * n + c] - u[c]).abs() < 1e-10 * u.norm().max(1e-3),
                "{kinematics:?} {formulation:?} node {n} comp {c}: {} vs {}",
                z[3 * n + c],
                u[c]
            );
        }
    }
    let f = Matrix3::identity() + grad_u;
    let strain = match kinematics {
        Kinematics::Large => (f.transpose() * f - Matrix3::identity()) * 0.5,
        Kinematics::Small => (grad_u + grad_u.transpose()) * 0.5,
    };
    let (lambda, mu) = fricsens::material::lame(1000.0, 0.3);
    let s = strain * (2.0 * mu) + Matrix3::identity() * (lambda * strain.trace());
    let sigma = match kinematics {
        Kinematics::Large => f * s * f.transpose() / f.determinant(),
        Kinematics::Small => s,
    };
    for c in &res.stresses[1] {
        assert!(
            (c - sigma).norm() <= 1e-10 * sigma.norm(),
            "{kinematics:?} {formulation:?}: element stress {c} vs {sigma}"
        );
    }
}
