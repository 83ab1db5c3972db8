//! Element shapes (the topology a mesh stores) and the face families of their boundaries.
//!
//! A mesh knows the shape of each element (its node count, its faces, its edges), never its
//! formulation: how an element is integrated is the choice of the body that owns it
//! ([`super::ElementFamily`]). A face family is the shape of a boundary face as contact sees
//! it: the target segments of node-to-segment contact and the faces of load and hitting sets.
//!
//! Registering a shape: a variant here, its tables in the family's own file (node order,
//! faces outward counter-clockwise, edges), one arm in each `match` below.

use super::hex8;
use crate::scalar::{safe_norm, Scalar};
use nalgebra::Vector3;

/// The shape of an element: its nodes, faces and edges.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
#[non_exhaustive]
pub enum Shape {
    /// Eight-node hexahedron (trilinear), nodes as in [`hex8::NODE_XI`].
    Hex8,
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
    #[error("unknown element shape '{name}' (known: hex8, point1, line2)")]
    UnknownShape {
        /// The name asked for.
        name: String,
    },
}

impl Shape {
    /// Every registered shape.
    pub const ALL: [Shape; 3] = [Shape::Hex8, Shape::Point1, Shape::Line2];

    /// Short name (`hex8`, `point1`, `line2`), as in scene and mesh files.
    pub fn name(self) -> &'static str {
        match self {
            Shape::Hex8 => "hex8",
            Shape::Point1 => "point1",
            Shape::Line2 => "line2",
        }
    }

    /// Whether it fills a volume. Only solids have a boundary, faces for contact and edges
    /// that measure the mesh: a discrete element (a spring between two nodes) is no part of
    /// the geometry, however far apart its nodes are.
    pub fn is_solid(self) -> bool {
        match self {
            Shape::Hex8 => true,
            Shape::Point1 | Shape::Line2 => false,
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

    /// Number of nodes.
    pub fn n_nodes(self) -> usize {
        match self {
            Shape::Hex8 => 8,
            Shape::Point1 => 1,
            Shape::Line2 => 2,
        }
    }

    /// The faces, outward oriented (none for a discrete element).
    pub fn faces(self) -> &'static [FaceTopology] {
        match self {
            Shape::Hex8 => &hex8::FACES,
            Shape::Point1 | Shape::Line2 => &[],
        }
    }

    /// The geometric edges (pairs of local node numbers; none for a discrete element, see
    /// [`Shape::is_solid`]).
    pub fn edges(self) -> &'static [[usize; 2]] {
        match self {
            Shape::Hex8 => &hex8::EDGES,
            Shape::Point1 | Shape::Line2 => &[],
        }
    }

    /// The VTK cell type of this shape.
    pub fn vtk_cell(self) -> vtkio::model::CellType {
        match self {
            Shape::Hex8 => vtkio::model::CellType::Hexahedron,
            Shape::Point1 => vtkio::model::CellType::Vertex,
            Shape::Line2 => vtkio::model::CellType::Line,
        }
    }
}

/// The shape of a boundary face as contact and surface loads see it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
#[non_exhaustive]
pub enum FaceFamily {
    /// Four-node bilinear quadrilateral, nodes counter-clockwise seen from outside.
    Quad4,
}

impl FaceFamily {
    /// Short name (`quad4`).
    pub fn name(self) -> &'static str {
        match self {
            FaceFamily::Quad4 => "quad4",
        }
    }

    /// Number of nodes.
    pub fn n_nodes(self) -> usize {
        match self {
            FaceFamily::Quad4 => 4,
        }
    }

    /// Area of a face with node coordinates `x` (in the family's node order): reference or
    /// deformed, whichever `x` holds.
    /// Quad4: the two triangles `(0, 1, 3)` and `(2, 3, 1)`, exact for a planar face.
    /// Generic in the scalar, so that a shape parameter's dual part reaches the area.
    pub fn area<S: Scalar>(self, x: &[Vector3<S>]) -> S {
        match self {
            FaceFamily::Quad4 => {
                safe_norm(&(x[1] - x[0]).cross(&(x[3] - x[0]))) * 0.5
                    + safe_norm(&(x[3] - x[2]).cross(&(x[1] - x[2]))) * 0.5
            }
        }
    }

    /// The share of a face's area `area` that node `a` of the face carries (tributary
    /// areas). Quad4: a quarter each.
    pub fn tributary_share<S: Scalar>(self, area: S, _a: usize) -> S {
        match self {
            FaceFamily::Quad4 => area / 4.0,
        }
    }

    /// The largest distance across a face (quad4: the longer diagonal): the face's size
    /// for contact search radii.
    pub fn diameter(self, x: &[Vector3<f64>]) -> f64 {
        match self {
            FaceFamily::Quad4 => (x[2] - x[0]).norm().max((x[3] - x[1]).norm()),
        }
    }

    /// The face's centre: the mean of its corner nodes.
    pub fn centre(self, x: &[Vector3<f64>]) -> Vector3<f64> {
        match self {
            FaceFamily::Quad4 => (x[0] + x[1] + x[2] + x[3]) / 4.0,
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
        for s in Shape::ALL {
            assert_eq!(Shape::from_name(s.name()), Ok(s));
            assert_eq!(s.is_solid(), !s.faces().is_empty());
        }
    }

    #[test]
    fn quad4_area_and_shares_of_a_unit_square() {
        let x = [
            Vector3::new(0.0, 0.0, 0.0),
            Vector3::new(2.0, 0.0, 0.0),
            Vector3::new(2.0, 3.0, 0.0),
            Vector3::new(0.0, 3.0, 0.0),
        ];
        let a = FaceFamily::Quad4.area(&x);
        assert_eq!(a, 6.0);
        let total: f64 = (0..4)
            .map(|k| FaceFamily::Quad4.tributary_share(a, k))
            .sum();
        assert_eq!(total, a);
        assert_eq!(FaceFamily::Quad4.centre(&x), Vector3::new(1.0, 1.5, 0.0));
    }
}
