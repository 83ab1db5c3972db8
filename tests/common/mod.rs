//! Fixtures shared by the element test binaries.
#![allow(dead_code)]

use fricsens::element::hex8;
use fricsens::element::{Hex8Formulation, Kinematics};
use fricsens::mesh::{Axis, BlockSpec, Mesh, NodePlace};
use fricsens::model::{Body, Material, Model};
use nalgebra::Vector3;

pub fn block(name: &str, n: [usize; 3], l: [f64; 3]) -> BlockSpec {
    BlockSpec {
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
    formulation: Hex8Formulation,
) -> Model {
    Model {
        mesh,
        bodies: vec![Body {
            name: "b".into(),
            block: 0,
            material,
            kinematics,
            formulation,
        }],
        times: vec![1.0],
        ..Model::default()
    }
}

/// A 2x2x2 block whose interior node and some surface nodes are moved off the grid.
pub fn distorted_mesh() -> Mesh {
    let mut mesh = Mesh::default();
    mesh.add_block(block("b", [2, 2, 2], [2.0, 2.0, 2.0]))
        .unwrap();
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
