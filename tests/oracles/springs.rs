//! Springs are elements: a model built in code adds them with `Model::add_spring` as element
//! groups of the discrete shapes (`point1` to the ground, `line2` between two nodes), and the
//! dof map, the assembly and every sensitivity method take them through the element families.
//!
//! Oracle: two springs in series with full (coupled) stiffness matrices, `K1` from node `a` to
//! the ground and `K2` from `a` to `b`, with a force `F` on `b`: `K1 u_a = F` and
//! `K2 (u_b - u_a) = F`, so `u_a = K1^-1 F`, `u_b = u_a + K2^-1 F`, and `du_b/dF_x` is the first
//! column of `K1^-1 + K2^-1`.

use fricsens::element::{ElementFamily, Shape};
use fricsens::model::{node_dof, Amplitude, Model, NodalLoad};
use fricsens::prelude::*;
use fricsens::response::{Response, ResponseKind};
use fricsens::solver::NoObserver;
use nalgebra::{Matrix3, Vector3};

const K1: [[f64; 3]; 3] = [[4.0, 1.0, 0.0], [1.0, 3.0, 0.5], [0.0, 0.5, 2.0]];
const K2: [[f64; 3]; 3] = [[2.0, -0.5, 0.25], [-0.5, 5.0, 0.0], [0.25, 0.0, 1.5]];
const F: [f64; 3] = [1.0, -2.0, 0.5];

fn series() -> Model {
    let mut model = Model::default();
    let a = model.mesh.add_node([0.0, 0.0, 0.0]);
    let b = model.mesh.add_node([1.0, 0.0, 0.0]);
    model.add_spring("ground", a, None, K1).unwrap();
    model.add_spring("link", a, Some(b), K2).unwrap();
    for (c, f) in F.iter().enumerate() {
        model.loads.push(NodalLoad {
            name: format!("F{c}"),
            nodes: vec![b],
            weights: vec![1.0],
            component: c,
            value: *f,
            amplitude: Amplitude::ramp(),
        });
    }
    for c in 0..3 {
        model.responses.push(Response {
            name: format!("ub{c}"),
            kind: ResponseKind::Displacement {
                nodes: vec![b],
                component: c,
            },
        });
    }
    model.times = vec![0.5, 1.0];
    model
}

fn matrix(k: [[f64; 3]; 3]) -> Matrix3<f64> {
    Matrix3::from_fn(|i, j| k[i][j])
}

#[test]
fn springs_are_discrete_element_groups_with_their_own_unknowns() {
    let model = series();
    assert_eq!(model.mesh.groups[0].shape, Shape::Point1);
    assert_eq!(model.mesh.groups[1].shape, Shape::Line2);
    let dofs = model.dof_map();
    assert_eq!(dofs.element_family[0], Some(ElementFamily::Spring1));
    assert_eq!(dofs.element_family[1], Some(ElementFamily::Spring2));
    assert_eq!(dofs.element_dofs(0), &[0, 1, 2]);
    assert_eq!(dofs.element_dofs(1), &[0, 1, 2, 3, 4, 5]);
    // no Gauss point, no history
    assert_eq!(dofs.n_gauss(), 0);
    assert_eq!(dofs.n_history, 0);
    // a spring is no part of the geometry: no faces, no edges
    assert!(model.mesh.boundary_faces(1).is_empty());
    assert!(model
        .mesh
        .smallest_edge(&[Vector3::zeros(), Vector3::x()])
        .is_infinite());
}

#[test]
fn springs_in_series_solve_to_the_closed_form_and_ddm_and_sdm_give_its_derivative() {
    let model = series();
    let res = Solver::new(&model)
        .unwrap()
        .run(&RunOptions::default(), &mut NoObserver)
        .unwrap();
    let z = res.states.last().unwrap();
    let f = Vector3::from(F);
    let (c1, c2) = (
        matrix(K1).try_inverse().unwrap(),
        matrix(K2).try_inverse().unwrap(),
    );
    let ua = c1 * f;
    let ub = ua + c2 * f;
    for c in 0..3 {
        // a linear problem: one Newton step, exact to round-off of a 6x6 solve
        assert!((z[node_dof(0, c)] - ua[c]).abs() < 1e-12, "u_a[{c}]");
        assert!((z[node_dof(1, c)] - ub[c]).abs() < 1e-12, "u_b[{c}]");
    }
    // d u_b / d F_x: the first column of K1^-1 + K2^-1
    let want = (c1 + c2).column(0).into_owned();
    let fx = Parameter::by_name(&model, "load.F0").unwrap();
    for method in [Method::Ddm, Method::Sdm] {
        let settings = Settings {
            method,
            ..Settings::default()
        };
        let (_, sens) = run_sensitivity(&model, std::slice::from_ref(&fx), &settings).unwrap();
        let last = sens.increments.len() - 1;
        for c in 0..3 {
            let d = sens.derivative(&format!("ub{c}"), "load.F0").unwrap()[last];
            // linear in F: SDM's finite step is exact too, to round-off
            assert!(
                (d - want[c]).abs() < 1e-10,
                "{method:?} du_b{c}/dF_x = {d}, closed form {}",
                want[c]
            );
        }
    }
}

#[test]
fn a_spring_group_of_a_solid_shape_is_a_typed_failure_not_a_panic() {
    let mut model = series();
    // a unit cube on the two spring nodes (0 at the origin, 1 at x = 1) and six new ones:
    // the spring set's group replaced, the loaded node 1 is still on an element (a load on a
    // node nothing holds is an error of its own,
    // `a_load_on_a_node_nothing_holds_is_an_error_naming_it`)
    for k in 2..8 {
        model
            .mesh
            .add_node([(k & 1) as f64, ((k >> 1) & 1) as f64, (k >> 2) as f64]);
    }
    let g = model
        .mesh
        .add_group(Shape::Hex8, (0..8).collect::<Vec<_>>())
        .unwrap();
    model.springs[1].group = g;
    let err = Solver::new(&model)
        .and_then(|mut s| s.run(&RunOptions::default(), &mut NoObserver))
        .unwrap_err();
    let msg = err.to_string();
    assert!(
        msg.contains("takes a material, it was given a stiffness"),
        "{msg}"
    );
}
