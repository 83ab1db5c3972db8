//! Element shapes: the topology a mesh stores (node count, faces, edges).
//!
//! A mesh knows the shape of each element (its node count, its faces, its edges), never its
//! formulation: how an element is integrated is the choice of the body that owns it
//! ([`super::ElementFamily`]). A face family is the shape of a boundary face as contact sees
//! it: the target segments of node-to-segment contact and the faces of load and hitting sets.
//!
//! Registering a shape: a variant here, its tables in the family's own file (node order,
//! faces outward counter-clockwise, edges), one arm in each `match` below.

use super::{hex20, hex8, tet, wedge, FaceFamily};

/// The shape of an element: its nodes, faces and edges.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
#[non_exhaustive]
pub enum Shape {
    /// Eight-node hexahedron (trilinear), nodes as in [`hex8::NODE_XI`].
    Hex8,
    /// Twenty-node serendipity hexahedron, nodes as in [`hex20::NODE_XI`].
    Hex20,
    /// Four-node tetrahedron (linear), nodes as in [`tet::NODE_XI`].
    Tet4,
    /// Ten-node tetrahedron (quadratic), nodes as in [`tet::NODE_XI`].
    Tet10,
    /// Six-node wedge (triangular prism), nodes as in [`wedge::NODE_XI`].
    Wedge6,
    /// Fifteen-node wedge (serendipity), nodes as in [`wedge::NODE_XI`].
    Wedge15,
    /// One node: a discrete element tied to the ground (a grounded spring).
    Point1,
    /// Two nodes: a discrete element between them (a spring).
    Line2,
}

/// One face of an element shape: its family and its local node numbers, counter-clockwise
/// seen from outside (so the face normal points out of the element).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FaceTopology {
    /// The face's family.
    pub family: FaceFamily,
    /// Local node numbers of the face, in the family's node order.
    pub nodes: &'static [usize],
}

/// Why a shape or face family could not be named.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
pub enum ShapeError {
    /// No registered shape has this name.
    #[error("unknown element shape '{name}' (known: hex8, hex20, tet4, tet10, wedge6, wedge15, point1, line2)")]
    UnknownShape {
        /// The name asked for.
        name: String,
    },
}

impl Shape {
    /// Every registered shape.
    pub const ALL: [Shape; 8] = [
        Shape::Hex8,
        Shape::Hex20,
        Shape::Tet4,
        Shape::Tet10,
        Shape::Wedge6,
        Shape::Wedge15,
        Shape::Point1,
        Shape::Line2,
    ];

    /// The solid shapes.
    pub const SOLIDS: [Shape; 6] = [
        Shape::Hex8,
        Shape::Hex20,
        Shape::Tet4,
        Shape::Tet10,
        Shape::Wedge6,
        Shape::Wedge15,
    ];

    /// Short name (`hex8`, `tet10`, `point1`, ...), as in scene and mesh files.
    pub fn name(self) -> &'static str {
        match self {
            Shape::Hex8 => "hex8",
            Shape::Hex20 => "hex20",
            Shape::Tet4 => "tet4",
            Shape::Tet10 => "tet10",
            Shape::Wedge6 => "wedge6",
            Shape::Wedge15 => "wedge15",
            Shape::Point1 => "point1",
            Shape::Line2 => "line2",
        }
    }

    /// Whether it fills a volume. Only solids have a boundary, faces for contact and edges
    /// that measure the mesh: a discrete element (a spring between two nodes) is no part of
    /// the geometry, however far apart its nodes are.
    pub fn is_solid(self) -> bool {
        !matches!(self, Shape::Point1 | Shape::Line2)
    }

    /// Whether its edges are curved (quadratic): a mid-edge node on each.
    pub fn is_quadratic(self) -> bool {
        matches!(self, Shape::Hex20 | Shape::Tet10 | Shape::Wedge15)
    }

    /// The linear shape with the same corners (itself if linear; a discrete shape has none).
    pub fn corners(self) -> Shape {
        match self {
            Shape::Hex20 => Shape::Hex8,
            Shape::Tet10 => Shape::Tet4,
            Shape::Wedge15 => Shape::Wedge6,
            s => s,
        }
    }

    /// The shape of a name (`hex8`).
    pub fn from_name(name: &str) -> Result<Shape, ShapeError> {
        Shape::ALL
            .into_iter()
            .find(|s| s.name() == name)
            .ok_or_else(|| ShapeError::UnknownShape {
                name: name.to_string(),
            })
    }

    /// Natural coordinates of the nodes (none for a discrete shape).
    pub fn natural_nodes(self) -> &'static [[f64; 3]] {
        match self {
            Shape::Hex8 => &hex8::NODE_XI,
            Shape::Hex20 => &hex20::NODE_XI,
            Shape::Tet4 => &tet::NODE_XI[..4],
            Shape::Tet10 => &tet::NODE_XI,
            Shape::Wedge6 => &wedge::NODE_XI[..6],
            Shape::Wedge15 => &wedge::NODE_XI,
            Shape::Point1 | Shape::Line2 => &[],
        }
    }

    /// Number of nodes.
    pub fn n_nodes(self) -> usize {
        match self {
            Shape::Hex8 => 8,
            Shape::Hex20 => 20,
            Shape::Tet4 => 4,
            Shape::Tet10 => 10,
            Shape::Wedge6 => 6,
            Shape::Wedge15 => 15,
            Shape::Point1 => 1,
            Shape::Line2 => 2,
        }
    }

    /// The faces, outward oriented (none for a discrete element).
    pub fn faces(self) -> &'static [FaceTopology] {
        match self {
            Shape::Hex8 => &hex8::FACES,
            Shape::Hex20 => &hex20::FACES,
            Shape::Tet4 => &tet::FACES4,
            Shape::Tet10 => &tet::FACES10,
            Shape::Wedge6 => &wedge::FACES6,
            Shape::Wedge15 => &wedge::FACES15,
            Shape::Point1 | Shape::Line2 => &[],
        }
    }

    /// The geometric edges, corner to corner (pairs of local node numbers; a quadratic
    /// shape's mid-edge node lies inside its edge; none for a discrete element, see
    /// [`Shape::is_solid`]).
    pub fn edges(self) -> &'static [[usize; 2]] {
        match self {
            Shape::Hex8 => &hex8::EDGES,
            Shape::Hex20 => &hex20::EDGES,
            Shape::Tet4 | Shape::Tet10 => &tet::EDGES,
            Shape::Wedge6 | Shape::Wedge15 => &wedge::EDGES,
            Shape::Point1 | Shape::Line2 => &[],
        }
    }

    /// The VTK cell type of this shape.
    pub fn vtk_cell(self) -> vtkio::model::CellType {
        use vtkio::model::CellType;
        match self {
            Shape::Hex8 => CellType::Hexahedron,
            Shape::Hex20 => CellType::QuadraticHexahedron,
            Shape::Tet4 => CellType::Tetra,
            Shape::Tet10 => CellType::QuadraticTetra,
            Shape::Wedge6 => CellType::Wedge,
            Shape::Wedge15 => CellType::QuadraticWedge,
            Shape::Point1 => CellType::Vertex,
            Shape::Line2 => CellType::Line,
        }
    }

    /// The VTK cell's node `k` is this shape's node `vtk_order()[k]` (VTK's wedges turn
    /// their triangles the other way; every other shape numbers as this code does).
    pub fn vtk_order(self) -> &'static [usize] {
        const WEDGE6: [usize; 6] = [0, 2, 1, 3, 5, 4];
        const WEDGE15: [usize; 15] = [0, 2, 1, 3, 5, 4, 8, 7, 6, 11, 10, 9, 12, 14, 13];
        const IDENTITY: [usize; 20] = [
            0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15, 16, 17, 18, 19,
        ];
        match self {
            Shape::Wedge6 => &WEDGE6,
            Shape::Wedge15 => &WEDGE15,
            s => &IDENTITY[..s.n_nodes()],
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hex8_faces_are_the_outward_face_table_and_edges_join_neighbours() {
        let faces = Shape::Hex8.faces();
        assert_eq!(faces.len(), hex8::FACE_NODES.len());
        for (f, l) in faces.iter().zip(hex8::FACE_NODES) {
            assert_eq!(f.nodes, &l[..]);
            assert_eq!(f.nodes.len(), f.family.n_nodes());
        }
        // every edge joins two nodes one natural coordinate apart
        for [a, b] in Shape::Hex8.edges() {
            let (xa, xb) = (hex8::NODE_XI[*a], hex8::NODE_XI[*b]);
            let differ = (0..3).filter(|&k| xa[k] != xb[k]).count();
            assert_eq!(differ, 1);
        }
        assert_eq!(Shape::from_name("hex8"), Ok(Shape::Hex8));
        assert_eq!(Shape::from_name("tet10"), Ok(Shape::Tet10));
        for s in Shape::ALL {
            assert_eq!(Shape::from_name(s.name()), Ok(s));
            assert_eq!(s.is_solid(), !s.faces().is_empty());
        }
    }

    /// Natural coordinates as a point.
    fn at(xi: [f64; 3]) -> nalgebra::Vector3<f64> {
        nalgebra::Vector3::new(xi[0], xi[1], xi[2])
    }

    #[test]
    fn every_solid_face_points_out_and_mid_nodes_sit_between_their_corners() {
        for shape in Shape::SOLIDS {
            let xi = shape.natural_nodes();
            assert_eq!(xi.len(), shape.n_nodes());
            let n_corners = shape.corners().n_nodes();
            let centre: nalgebra::Vector3<f64> = xi[..n_corners]
                .iter()
                .map(|p| at(*p))
                .sum::<nalgebra::Vector3<f64>>()
                / n_corners as f64;
            let mut face_count = std::collections::HashMap::new();
            for face in shape.faces() {
                assert_eq!(face.nodes.len(), face.family.n_nodes());
                let c = face.family.n_corners();
                let p: Vec<_> = face.nodes.iter().map(|&l| at(xi[l])).collect();
                // outward: (x1 - x0) x (x_last_corner - x0) away from the element's centre
                let normal = (p[1] - p[0]).cross(&(p[c - 1] - p[0]));
                let fc = p[..c].iter().sum::<nalgebra::Vector3<f64>>() / c as f64;
                assert!(
                    normal.dot(&(fc - centre)) > 0.0,
                    "{shape:?} face {:?}",
                    face.nodes
                );
                // a quadratic face's mid-side node m sits between corners m and m + 1
                for m in c..face.nodes.len() {
                    let (a, b) = (m - c, (m - c + 1) % c);
                    assert!(((p[a] + p[b]) * 0.5 - p[m]).norm() < 1e-15, "{shape:?}");
                }
                let mut key = face.nodes[..c].to_vec();
                key.sort_unstable();
                *face_count.entry(key).or_insert(0) += 1;
            }
            assert!(
                face_count.values().all(|&k| k == 1),
                "{shape:?}: a face twice"
            );
            // every edge joins two corners; a quadratic shape's mid-edge nodes follow the
            // edge table in order
            for (k, [a, b]) in shape.edges().iter().enumerate() {
                assert!(*a < n_corners && *b < n_corners && a != b);
                if shape.is_quadratic() {
                    let mid = (at(xi[*a]) + at(xi[*b])) * 0.5;
                    assert!(
                        (mid - at(xi[n_corners + k])).norm() < 1e-15,
                        "{shape:?} edge {k}"
                    );
                }
            }
            if shape.is_quadratic() {
                assert_eq!(n_corners + shape.edges().len(), shape.n_nodes());
            }
            // the VTK order is a permutation
            let mut order = shape.vtk_order().to_vec();
            order.sort_unstable();
            assert_eq!(order, (0..shape.n_nodes()).collect::<Vec<_>>());
        }
    }
}
