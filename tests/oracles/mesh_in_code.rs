//! A model built in code — nodes at given coordinates, hex8 connectivity, face sets from the
//! mesh's boundary — gets what a scene's generated blocks get (tributary areas, candidate
//! faces, constraint scale, tangential penalty) and solves the contact patch test as they do.
//!
//! Oracles: the generated twin (`scene::contact_patch`, the same geometry numbered by the
//! block generator) for the derived contact data; the closed form of the patch test for the
//! solution: two stacked blocks of one linear material under a uniform pressure `p` are in
//! uniaxial stress, so every hitting node carries `p A_i`, the top moves by `-p H / E` and the
//! sides by `nu p x / E`.

use fricsens::contact::friction::Coulomb;
use fricsens::contact::{setup, Friction};
use fricsens::element::{Formulation, Kinematics, Shape};
use fricsens::material::StVenantKirchhoff;
use fricsens::mesh::{FaceSet, Mesh, MeshError};
use fricsens::model::{node_dof, Amplitude, Body, Material, Model, NodalLoad, Prescribed};
use fricsens::solver::{NoObserver, RunOptions, Solver};
use nalgebra::Vector3;

const E: f64 = 1000.0;
const NU: f64 = 0.3;
const P: f64 = 10.0;

/// A brick `[0, 2] x [y0, y0 + 1] x [0, 2]` of 4 x 2 x 4 hex8, nodes numbered z fastest
/// (the block generator numbers x fastest), added to `mesh`; returns its group.
fn brick(mesh: &mut Mesh, y0: f64) -> usize {
    let (nx, ny, nz) = (5, 3, 5);
    let first = mesh.n_nodes();
    let id = |i: usize, j: usize, k: usize| first + k + nz * (j + ny * i);
    for i in 0..nx {
        for j in 0..ny {
            for k in 0..nz {
                let n = mesh.add_node([0.5 * i as f64, y0 + 0.5 * j as f64, 0.5 * k as f64]);
                assert_eq!(n, id(i, j, k));
            }
        }
    }
    let mut conn = Vec::new();
    for i in 0..nx - 1 {
        for j in 0..ny - 1 {
            for k in 0..nz - 1 {
                conn.extend_from_slice(&[
                    id(i, j, k),
                    id(i + 1, j, k),
                    id(i + 1, j + 1, k),
                    id(i, j + 1, k),
                    id(i, j, k + 1),
                    id(i + 1, j, k + 1),
                    id(i + 1, j + 1, k + 1),
                    id(i, j + 1, k + 1),
                ]);
            }
        }
    }
    mesh.add_group(Shape::Hex8, conn).unwrap()
}

/// The boundary faces of group `g` whose nodes all satisfy `on`.
fn faces_where(
    mesh: &Mesh,
    g: usize,
    x: &[Vector3<f64>],
    on: impl Fn(&Vector3<f64>) -> bool,
) -> FaceSet {
    let mut set = FaceSet::new();
    for f in mesh.boundary_faces(g).iter() {
        if f.nodes.iter().all(|&n| on(&x[n])) {
            set.push(f.family, f.nodes).unwrap();
        }
    }
    set
}

fn nodes_where(
    mesh: &Mesh,
    g: usize,
    x: &[Vector3<f64>],
    on: impl Fn(&Vector3<f64>) -> bool,
) -> Vec<usize> {
    let mut v: Vec<usize> = mesh.groups[g]
        .nodes
        .iter()
        .copied()
        .filter(|&n| on(&x[n]))
        .collect();
    v.sort_unstable();
    v.dedup();
    v
}

fn fixed(name: &str, nodes: Vec<usize>, component: usize) -> Prescribed {
    Prescribed {
        name: name.into(),
        nodes,
        component,
        value: 0.0,
        amplitude: Amplitude::ramp(),
    }
}

/// The contact patch built in code.
fn patch_in_code() -> Model {
    let mut mesh = Mesh::default();
    let lower = brick(&mut mesh, 0.0);
    let upper = brick(&mut mesh, 1.0);
    let x = mesh.coordinates::<f64>(&mesh.block_geometry());
    let near = |a: f64, b: f64| (a - b).abs() < 1e-12;
    let body = |name: &str, group| Body {
        name: name.into(),
        group,
        material: Material::Svk(StVenantKirchhoff::new(E, NU)),
        kinematics: Kinematics::Small,
        formulation: Some(Formulation::IncompatibleModes),
    };
    let bodies = vec![body("lower", lower), body("upper", upper)];
    let prescribed = vec![
        fixed(
            "lower-x",
            nodes_where(&mesh, lower, &x, |p| near(p.x, 0.0)),
            0,
        ),
        fixed(
            "upper-x",
            nodes_where(&mesh, upper, &x, |p| near(p.x, 0.0)),
            0,
        ),
        fixed(
            "lower-z",
            nodes_where(&mesh, lower, &x, |p| near(p.z, 0.0)),
            2,
        ),
        fixed(
            "upper-z",
            nodes_where(&mesh, upper, &x, |p| near(p.z, 0.0)),
            2,
        ),
        fixed(
            "lower-y",
            nodes_where(&mesh, lower, &x, |p| near(p.y, 0.0)),
            1,
        ),
    ];
    let top = faces_where(&mesh, upper, &x, |p| near(p.y, 2.0));
    let top_nodes = setup::face_set_nodes(&top);
    let area = top.tributary_areas(&x, &top_nodes);
    let total: f64 = area.iter().sum();
    let loads = vec![NodalLoad {
        name: "p".into(),
        nodes: top_nodes,
        weights: area.iter().map(|a| a / total).collect(),
        component: 1,
        value: -P * total,
        amplitude: Amplitude::ramp(),
    }];
    let hitting = faces_where(&mesh, upper, &x, |p| near(p.y, 1.0));
    let target = faces_where(&mesh, lower, &x, |p| near(p.y, 1.0));
    let (pair, derivation) = setup::pair_between_faces(
        "interface",
        &mesh,
        &bodies,
        &[],
        &prescribed,
        &hitting,
        &target,
        Some(Friction::Coulomb(Coulomb::new(0.3))),
        None,
    )
    .unwrap();
    assert!(derivation.dropped.is_empty());
    Model {
        mesh,
        bodies,
        prescribed,
        loads,
        times: vec![1.0],
        contacts: vec![pair],
        ..Model::default()
    }
}

fn coords(model: &Model) -> Vec<Vector3<f64>> {
    model.mesh.coordinates::<f64>(&model.mesh.block_geometry())
}

/// The node of `model` in group `g` at `p`.
fn node_at(model: &Model, g: usize, p: &Vector3<f64>) -> usize {
    let x = coords(model);
    *model.mesh.groups[g]
        .nodes
        .iter()
        .find(|&&n| (x[n] - p).norm() < 1e-12)
        .expect("a node at that point")
}

#[test]
fn a_mesh_built_in_code_gets_the_contact_data_of_the_generated_block() {
    let code = patch_in_code();
    let generated = fricsens::scene::contact_patch(Some(0.3)).build().unwrap();
    let (c, g) = (&code.contacts[0], &generated.contacts[0]);
    let (xc, xg) = (coords(&code), coords(&generated));
    assert_eq!(c.hitting.len(), 25);
    assert_eq!(c.hitting.len(), g.hitting.len());
    assert_eq!(c.constraint_scale, g.constraint_scale);
    assert_eq!(c.tangential_stiffness, g.tangential_stiffness);
    let (
        fricsens::contact::Target::Faces { faces: fc },
        fricsens::contact::Target::Faces { faces: fg },
    ) = (&c.target, &g.target)
    else {
        panic!("deformable targets")
    };
    let centre = |faces: &FaceSet, k: usize, x: &[Vector3<f64>]| {
        faces.nodes(k).iter().map(|&n| x[n]).sum::<Vector3<f64>>() / 4.0
    };
    for (i, &s) in c.hitting.iter().enumerate() {
        // the same node of the generated twin, found by its coordinates
        let j = g
            .hitting
            .iter()
            .position(|&t| (xg[t] - xc[s]).norm() < 1e-12)
            .expect("the twin hitting node");
        assert_eq!(c.area[i], g.area[j]);
        assert_eq!(c.tangential_weight[i], g.tangential_weight[j]);
        let mut a: Vec<[i64; 3]> = c.candidates[i]
            .iter()
            .map(|&k| centre(fc, k, &xc).map(|v| (v * 1e6).round() as i64).into())
            .collect();
        let mut b: Vec<[i64; 3]> = g.candidates[j]
            .iter()
            .map(|&k| centre(fg, k, &xg).map(|v| (v * 1e6).round() as i64).into())
            .collect();
        a.sort_unstable();
        b.sort_unstable();
        assert_eq!(a, b, "candidate faces of the node at {:?}", xc[s]);
    }
    // tributary areas add up to the interface's area
    assert!((c.area.iter().sum::<f64>() - 4.0).abs() < 1e-12);
}

#[test]
fn the_contact_patch_built_in_code_solves_to_uniaxial_stress() {
    let model = patch_in_code();
    let res = Solver::new(&model)
        .unwrap()
        .run(&RunOptions::default(), &mut NoObserver)
        .unwrap();
    let z = res.states.last().unwrap();
    let x = coords(&model);
    // uniform pressure on the interface: p A_i at every hitting node
    let pair = &model.contacts[0];
    let contact = res.contact.last().unwrap();
    for (i, _) in pair.hitting.iter().enumerate() {
        let f = contact.normal_force[res.contact_flat[0] + i];
        assert!(
            (f - P * pair.area[i]).abs() < 1e-9 * P,
            "node {i}: {f} against {}",
            P * pair.area[i]
        );
    }
    // uniaxial stress: u_y = -p y / E, u_x = nu p x / E, u_z = nu p z / E
    for (n, p) in x.iter().enumerate() {
        let u = [NU * P * p.x / E, -P * p.y / E, NU * P * p.z / E];
        for (c, uc) in u.iter().enumerate() {
            assert!(
                (z[node_dof(n, c)] - uc).abs() < 1e-10,
                "node {n} at {p:?}, component {c}"
            );
        }
    }
    // and the generated twin agrees node by node
    let twin = fricsens::scene::contact_patch(Some(0.3)).build().unwrap();
    let rt = Solver::new(&twin)
        .unwrap()
        .run(&RunOptions::default(), &mut NoObserver)
        .unwrap();
    let zt = rt.states.last().unwrap();
    for g in 0..2 {
        for &n in &model.mesh.groups[g].nodes {
            let m = node_at(&twin, g, &x[n]);
            for c in 0..3 {
                assert!((z[node_dof(n, c)] - zt[node_dof(m, c)]).abs() < 1e-12);
            }
        }
    }
}

#[test]
fn bad_connectivity_is_a_typed_error_naming_the_element() {
    let mut mesh = Mesh::default();
    for k in 0..8 {
        mesh.add_node([(k & 1) as f64, ((k >> 1) & 1) as f64, (k >> 2) as f64]);
    }
    // one full hex8 and three nodes of a second
    let err = mesh
        .add_group(Shape::Hex8, vec![0, 1, 3, 2, 4, 5, 7, 6, 0, 1, 2])
        .unwrap_err();
    assert_eq!(
        err,
        MeshError::Connectivity {
            group: 0,
            element: 1,
            shape: "hex8",
            expected: 8,
            got: 3
        }
    );
    let err = mesh
        .add_group(Shape::Hex8, vec![0, 1, 3, 2, 4, 5, 7, 9])
        .unwrap_err();
    assert!(matches!(
        err,
        MeshError::UnknownNode {
            element: 0,
            node: 9,
            ..
        }
    ));
    assert!(Shape::from_name("hex27").is_err());
    assert!(FaceSet::new()
        .push(fricsens::element::FaceFamily::Quad4, &[0, 1, 2])
        .is_err());
}
