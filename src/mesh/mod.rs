//! Meshes: nodes, element groups of any shape with flat connectivity, named node and face
//! sets, and a structured block generator with grading (one way to make a mesh; a mesh built in
//! code or imported adds nodes with [`Mesh::add_node`] and elements with [`Mesh::add_group`]).
//!
//! Elements are numbered globally in group order: group `g` holds the elements
//! `groups[g].first..groups[g].first + groups[g].len()`.
//!
//! A generated node does not store its coordinates: it stores its *fractional* position
//! `t in [0, 1]^3` inside its block, and the reference coordinates are computed on demand as
//! `X = origin + L o t` in the generic scalar ([`Mesh::coordinates`]). A block length `L` (or an
//! origin component) can therefore be a design parameter, and `dX/dL = t` comes out of a dual
//! evaluation exactly. Free nodes (for discrete models) carry fixed coordinates.
//!
//! Grading along each axis is a list of zones, each a fraction of the axis length with a number
//! of elements and a size ratio (last element / first element), so a fine region can sit next
//! to a coarse one in one conforming block.

pub mod abaqus;
mod file;
pub mod gmsh;
pub mod import;
pub mod shape_map;

pub use file::read;
pub use shape_map::{MapKind, ShapeMap, ShapeMapError, Smoothing};

use crate::element::{FaceFamily, Shape};
use crate::scalar::Scalar;
use nalgebra::Vector3;
use std::collections::{BTreeMap, HashMap};

/// One zone of an axis: a fraction of the block's length split into `elements` elements whose
/// sizes grow geometrically from the first to the last by `ratio`.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Zone {
    /// Fraction of the axis length this zone covers: the zones' fractions are weights, each
    /// zone covering its fraction over their sum (fractions that add up to one are taken as
    /// given; `0.3` alone is the whole axis).
    pub fraction: f64,
    /// Number of elements in the zone.
    pub elements: usize,
    /// Size of the zone's last element over its first (1 = uniform; default 1).
    #[serde(default = "one")]
    pub ratio: f64,
}

fn one() -> f64 {
    1.0
}

/// Division of one axis of a block.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Axis {
    /// Length of the block along this axis.
    pub length: f64,
    /// Zones, whose fractions are taken over their sum ([`Zone::fraction`]).
    pub zones: Vec<Zone>,
}

impl Axis {
    /// Uniform division into `n` elements.
    pub fn uniform(length: f64, n: usize) -> Self {
        Axis {
            length,
            zones: vec![Zone {
                fraction: 1.0,
                elements: n,
                ratio: 1.0,
            }],
        }
    }

    /// Total number of elements.
    pub fn elements(&self) -> usize {
        self.zones.iter().map(|z| z.elements).sum()
    }

    /// The elements' sizes along the axis, in order (`elements` values).
    pub fn element_sizes(&self) -> Vec<f64> {
        let t = self.fractions();
        t.windows(2).map(|w| (w[1] - w[0]) * self.length).collect()
    }

    /// Node positions as fractions of the length, from 0 to 1 (`elements + 1` values).
    pub fn fractions(&self) -> Vec<f64> {
        let total: f64 = self.zones.iter().map(|z| z.fraction).sum();
        let mut t = vec![0.0];
        let mut start = 0.0;
        for z in &self.zones {
            let n = z.elements.max(1);
            let q = if n > 1 {
                z.ratio.powf(1.0 / (n as f64 - 1.0))
            } else {
                1.0
            };
            let sizes: Vec<f64> = (0..n).map(|i| q.powi(i as i32)).collect();
            let sum: f64 = sizes.iter().sum();
            let mut acc = 0.0;
            for s in &sizes {
                acc += s / sum;
                t.push((start + acc * z.fraction) / total);
            }
            start += z.fraction;
        }
        if let Some(last) = t.last_mut() {
            *last = 1.0;
        }
        t
    }
}

/// A structured brick of solid elements: a grid of hexahedral cells, each one hex8 or hex20,
/// split into six tetrahedra (tet4, tet10) or into two wedges (wedge6, wedge15).
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BlockSpec {
    /// Block name: the prefix of its node and face sets (`NAME.xmin`, `NAME.all`, ...).
    pub name: String,
    /// Element shape (a solid; default hex8).
    #[serde(default = "hex8", skip_serializing_if = "is_hex8")]
    pub element: Shape,
    /// Reference position of the block's corner with the smallest coordinates.
    pub origin: [f64; 3],
    /// Division along x.
    pub x: Axis,
    /// Division along y.
    pub y: Axis,
    /// Division along z.
    pub z: Axis,
}

fn hex8() -> Shape {
    Shape::Hex8
}

fn is_hex8(s: &Shape) -> bool {
    *s == Shape::Hex8
}

impl BlockSpec {
    fn axes(&self) -> [&Axis; 3] {
        [&self.x, &self.y, &self.z]
    }
}

/// Where a node's reference position comes from.
#[derive(Clone, Debug, PartialEq)]
pub enum NodePlace {
    /// Inside block `block` at fractional position `t`.
    Block {
        /// Index of the generating block in [`Mesh::blocks`].
        block: usize,
        /// Fractional position `t in [0, 1]^3`: `X = origin + L o t`.
        t: [f64; 3],
    },
    /// Fixed coordinates.
    Free([f64; 3]),
}

/// Block geometry lifted to a scalar type: the design-dependent part of the coordinates.
#[derive(Clone, Debug)]
pub struct BlockGeometry<S: Scalar> {
    /// The block's origin: its corner with the smallest coordinates.
    pub origin: Vector3<S>,
    /// Block lengths `L` along x, y, z.
    pub lengths: Vector3<S>,
}

/// Elements of one shape, with flat connectivity.
#[derive(Clone, Debug, PartialEq)]
pub struct ElementGroup {
    /// Shape of every element of the group.
    pub shape: Shape,
    /// Node numbers, `shape.n_nodes()` per element, element after element.
    pub nodes: Vec<usize>,
    /// Global number of the group's first element.
    pub first: usize,
    /// The generating block, if the block generator made the group (its shape parameters
    /// move the group's nodes).
    pub block: Option<usize>,
}

impl ElementGroup {
    /// Number of elements.
    pub fn len(&self) -> usize {
        self.nodes.len() / self.shape.n_nodes()
    }

    /// Whether the group has no element.
    pub fn is_empty(&self) -> bool {
        self.nodes.is_empty()
    }

    /// Global element numbers of the group.
    pub fn elements(&self) -> std::ops::Range<usize> {
        self.first..self.first + self.len()
    }

    /// Nodes of the group's `k`-th element.
    pub fn element(&self, k: usize) -> &[usize] {
        let n = self.shape.n_nodes();
        &self.nodes[n * k..n * (k + 1)]
    }
}

/// A set of boundary faces of any families, with flat storage.
#[derive(Clone, Debug, PartialEq)]
pub struct FaceSet {
    families: Vec<FaceFamily>,
    offsets: Vec<usize>,
    nodes: Vec<usize>,
}

impl Default for FaceSet {
    fn default() -> Self {
        FaceSet::new()
    }
}

/// One face of a [`FaceSet`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Face<'a> {
    /// The face's family.
    pub family: FaceFamily,
    /// Its nodes, counter-clockwise seen from outside.
    pub nodes: &'a [usize],
}

impl FaceSet {
    /// An empty set.
    pub fn new() -> Self {
        FaceSet {
            families: Vec::new(),
            offsets: vec![0],
            nodes: Vec::new(),
        }
    }

    /// A set of quad4 faces.
    pub fn quad4(faces: &[[usize; 4]]) -> Self {
        let mut s = FaceSet::new();
        for f in faces {
            s.push_unchecked(FaceFamily::Quad4, f);
        }
        s
    }

    /// Add a face; a typed error when `nodes` is not the family's node count.
    pub fn push(&mut self, family: FaceFamily, nodes: &[usize]) -> Result<(), MeshError> {
        if nodes.len() != family.n_nodes() {
            return Err(MeshError::FaceNodes {
                face: self.len(),
                family: family.name(),
                expected: family.n_nodes(),
                got: nodes.len(),
            });
        }
        self.push_unchecked(family, nodes);
        Ok(())
    }

    /// Add a face whose node count is the family's (checked by the caller).
    fn push_unchecked(&mut self, family: FaceFamily, nodes: &[usize]) {
        self.families.push(family);
        self.nodes.extend_from_slice(nodes);
        self.offsets.push(self.nodes.len());
    }

    /// Number of faces.
    pub fn len(&self) -> usize {
        self.families.len()
    }

    /// Whether the set has no face.
    pub fn is_empty(&self) -> bool {
        self.families.is_empty()
    }

    /// Face `k`.
    pub fn face(&self, k: usize) -> Face<'_> {
        Face {
            family: self.families[k],
            nodes: &self.nodes[self.offsets[k]..self.offsets[k + 1]],
        }
    }

    /// Nodes of face `k`.
    pub fn nodes(&self, k: usize) -> &[usize] {
        &self.nodes[self.offsets[k]..self.offsets[k + 1]]
    }

    /// The faces in order.
    pub fn iter(&self) -> impl Iterator<Item = Face<'_>> + '_ {
        (0..self.len()).map(|k| self.face(k))
    }

    /// Whether any face is of a quadratic family (quad8, tri6).
    pub fn has_quadratic(&self) -> bool {
        self.families.iter().any(|f| f.is_quadratic())
    }

    /// Every node of every face, face after face (with repetitions).
    pub fn all_nodes(&self) -> &[usize] {
        &self.nodes
    }

    /// Tributary area of each of `nodes` over these faces at coordinates `x`: each face's
    /// area shared among its nodes by its family (a quarter each on a quad4). Generic in the
    /// scalar: at design-dependent coordinates (a shape parameter) the areas carry its derivative,
    /// so that a contact pressure and a penalty law follow the design's geometry.
    pub fn tributary_areas<S: Scalar>(&self, x: &[Vector3<S>], nodes: &[usize]) -> Vec<S> {
        self.tributary_areas_at(|n| x[n], nodes)
    }

    /// [`FaceSet::tributary_areas`] with node `n` at `x(n)` (a deformed position, say).
    pub fn tributary_areas_at<S: Scalar>(
        &self,
        x: impl Fn(usize) -> Vector3<S>,
        nodes: &[usize],
    ) -> Vec<S> {
        self.shared_areas_at(x, nodes, FaceFamily::tributary_share)
    }

    /// The area each of `nodes` reads its contact pressure over, at coordinates `x(n)`: each
    /// face's area shared by its family's pressure shares ([`FaceFamily::pressure_share`]:
    /// the tributary areas on quad4 and tri3 faces; none at the corners of quadratic ones).
    pub fn pressure_areas_at<S: Scalar>(
        &self,
        x: impl Fn(usize) -> Vector3<S>,
        nodes: &[usize],
    ) -> Vec<S> {
        self.shared_areas_at(x, nodes, FaceFamily::pressure_share)
    }

    /// Each face's area at `x(n)` shared among `nodes` by `share(family, area, node of face)`.
    fn shared_areas_at<S: Scalar>(
        &self,
        x: impl Fn(usize) -> Vector3<S>,
        nodes: &[usize],
        share: impl Fn(FaceFamily, S, usize) -> S,
    ) -> Vec<S> {
        // position of each node in `nodes` (the first, as a linear search would find)
        let mut index = HashMap::with_capacity(nodes.len());
        for (k, n) in nodes.iter().enumerate() {
            index.entry(*n).or_insert(k);
        }
        let mut area = vec![S::zero(); nodes.len()];
        let mut corners = [Vector3::<S>::zeros(); MAX_FACE_NODES];
        for k in 0..self.len() {
            let family = self.face(k).family;
            let face = self.nodes(k);
            for (c, n) in corners.iter_mut().zip(face) {
                *c = x(*n);
            }
            let a = family.area(&corners[..face.len()]);
            for (l, n) in face.iter().enumerate() {
                if let Some(&j) = index.get(n) {
                    area[j] += share(family, a, l);
                }
            }
        }
        area
    }

    /// The coordinates of face `k`'s nodes (at most eight nodes per face).
    pub fn coordinates(&self, k: usize, x: &[Vector3<f64>]) -> FaceCoordinates {
        let mut c = FaceCoordinates {
            x: [Vector3::zeros(); MAX_FACE_NODES],
            n: 0,
        };
        for (a, &n) in self.nodes(k).iter().enumerate() {
            c.x[a] = x[n];
            c.n += 1;
        }
        c
    }
}

/// Most nodes of a face of any family (the face families' own bound).
pub use crate::element::face::MAX_FACE_NODES;

/// Node coordinates of one face, on the stack.
#[derive(Clone, Copy, Debug)]
pub struct FaceCoordinates {
    x: [Vector3<f64>; MAX_FACE_NODES],
    n: usize,
}

impl std::ops::Deref for FaceCoordinates {
    type Target = [Vector3<f64>];
    fn deref(&self) -> &[Vector3<f64>] {
        &self.x[..self.n]
    }
}

/// A mesh: nodes and element groups of any shape.
#[derive(Clone, Debug, Default)]
pub struct Mesh {
    /// Where each node's reference position comes from, by node number.
    pub places: Vec<NodePlace>,
    /// The generating blocks, in the order they were added.
    pub blocks: Vec<BlockSpec>,
    /// Element groups, in element order.
    pub groups: Vec<ElementGroup>,
    /// Named node sets (`BLOCK.all`, `BLOCK.xmin`, ..., and those added by the caller).
    pub node_sets: BTreeMap<String, Vec<usize>>,
    /// Named face sets, faces outward oriented.
    pub face_sets: BTreeMap<String, FaceSet>,
    /// Design-dependent maps of the reference coordinates, applied in order after the blocks'
    /// placement ([`shape_map`]).
    pub shape_maps: Vec<ShapeMap>,
    /// Offsets of single node coordinates, `(node, axis) -> offset`, added after the shape
    /// maps: the values of nodal shape parameters (a design velocity per node and direction,
    /// [`crate::model::DesignParam::NodeShape`]). Empty unless a design moves a node.
    pub node_moves: BTreeMap<(usize, usize), f64>,
}

/// Mesh construction errors.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum MeshError {
    /// An axis of a block is divided into no elements.
    #[error("block '{block}': axis {axis} has no elements")]
    NoElements {
        /// Block name.
        block: String,
        /// `x`, `y` or `z`.
        axis: char,
    },
    /// An axis of a block is ill-formed (non-positive length, fraction or ratio, ...).
    #[error("block '{block}': axis {axis}: {what}")]
    BadAxis {
        /// Block name.
        block: String,
        /// `x`, `y` or `z`.
        axis: char,
        /// What is wrong with it.
        what: String,
    },
    /// A block of elements that are no solid.
    #[error("block '{block}': a block is made of solid elements, not {shape}")]
    BlockElement {
        /// Block name.
        block: String,
        /// The shape asked for.
        shape: &'static str,
    },
    /// An element's connectivity has the wrong number of nodes for its shape.
    #[error("group {group}, element {element}: a {shape} needs {expected} nodes, got {got}")]
    Connectivity {
        /// Group number (the one being added).
        group: usize,
        /// Element number inside the group (the first incomplete one).
        element: usize,
        /// Name of the shape.
        shape: &'static str,
        /// Nodes per element of the shape.
        expected: usize,
        /// Nodes given for that element.
        got: usize,
    },
    /// A face has the wrong number of nodes for its family.
    #[error("face {face}: a {family} face needs {expected} nodes, got {got}")]
    FaceNodes {
        /// Number of the face in its set.
        face: usize,
        /// Name of the face family.
        family: &'static str,
        /// Nodes of the family.
        expected: usize,
        /// Nodes given.
        got: usize,
    },
    /// An element names a node the mesh does not have.
    #[error("group {group}, element {element}: node {node} does not exist ({n_nodes} nodes)")]
    UnknownNode {
        /// Group number (the one being added).
        group: usize,
        /// Element number inside the group.
        element: usize,
        /// The node named.
        node: usize,
        /// Number of nodes of the mesh.
        n_nodes: usize,
    },
    /// Two blocks share a name (their node and face sets would collide).
    #[error("block '{block}': a block of that name already exists")]
    DuplicateBlock {
        /// The repeated name.
        block: String,
    },
}

impl Mesh {
    /// Number of nodes.
    pub fn n_nodes(&self) -> usize {
        self.places.len()
    }

    /// Number of elements.
    pub fn n_elements(&self) -> usize {
        self.groups.last().map_or(0, |g| g.first + g.len())
    }

    /// The group holding element `e` and `e`'s place in it.
    fn locate(&self, e: usize) -> (&ElementGroup, usize) {
        let g = self.groups.partition_point(|g| g.first <= e) - 1;
        let group = &self.groups[g];
        (group, e - group.first)
    }

    /// Nodes of element `e`, in its shape's node order.
    pub fn element_nodes(&self, e: usize) -> &[usize] {
        let (g, k) = self.locate(e);
        g.element(k)
    }

    /// Shape of element `e`.
    pub fn element_shape(&self, e: usize) -> Shape {
        self.locate(e).0.shape
    }

    /// Every element's shape and nodes, in element order.
    pub fn elements(&self) -> impl Iterator<Item = (Shape, &[usize])> + '_ {
        self.groups
            .iter()
            .flat_map(|g| (0..g.len()).map(move |k| (g.shape, g.element(k))))
    }

    /// Global element numbers of group `g`.
    pub fn group_elements(&self, g: usize) -> std::ops::Range<usize> {
        self.groups[g].elements()
    }

    /// The group a generating block made (the block generator makes one per block).
    pub fn block_group(&self, block: usize) -> Option<usize> {
        self.groups.iter().position(|g| g.block == Some(block))
    }

    /// The shortest element edge at the coordinates `x` (infinite without elements).
    pub fn smallest_edge(&self, x: &[Vector3<f64>]) -> f64 {
        self.elements()
            .flat_map(|(shape, e)| {
                shape
                    .edges()
                    .iter()
                    .map(move |[a, b]| (x[e[*a]] - x[e[*b]]).norm())
            })
            .fold(f64::INFINITY, f64::min)
    }

    /// Add a free node with fixed coordinates; returns its number.
    pub fn add_free_node(&mut self, x: [f64; 3]) -> usize {
        self.places.push(NodePlace::Free(x));
        self.places.len() - 1
    }

    /// Add a node at fixed coordinates (a mesh built in code or imported); returns its number.
    pub fn add_node(&mut self, x: [f64; 3]) -> usize {
        self.add_free_node(x)
    }

    /// Add a group of elements of one shape (`nodes`: `shape.n_nodes()` node numbers per
    /// element, in the shape's node order); returns the group number. Typed errors name the
    /// element whose connectivity is incomplete or names a missing node.
    pub fn add_group(&mut self, shape: Shape, nodes: Vec<usize>) -> Result<usize, MeshError> {
        self.push_group(shape, nodes, None)
    }

    fn push_group(
        &mut self,
        shape: Shape,
        nodes: Vec<usize>,
        block: Option<usize>,
    ) -> Result<usize, MeshError> {
        let group = self.groups.len();
        let nn = shape.n_nodes();
        if nodes.len() % nn != 0 {
            return Err(MeshError::Connectivity {
                group,
                element: nodes.len() / nn,
                shape: shape.name(),
                expected: nn,
                got: nodes.len() % nn,
            });
        }
        let n_nodes = self.n_nodes();
        if let Some(k) = nodes.iter().position(|&n| n >= n_nodes) {
            return Err(MeshError::UnknownNode {
                group,
                element: k / nn,
                node: nodes[k],
                n_nodes,
            });
        }
        let first = self.n_elements();
        self.groups.push(ElementGroup {
            shape,
            nodes,
            first,
            block,
        });
        Ok(group)
    }

    /// The boundary faces of group `g`: the faces of its elements that no other element of
    /// the group shares, outward oriented, in element order. A mesh built in code gets its
    /// face sets from here.
    pub fn boundary_faces(&self, g: usize) -> FaceSet {
        let group = &self.groups[g];
        let key = |nodes: &[usize]| {
            let mut k = nodes.to_vec();
            k.sort_unstable();
            k
        };
        let mut count: std::collections::HashMap<Vec<usize>, usize> =
            std::collections::HashMap::new();
        let faces = group.shape.faces();
        for k in 0..group.len() {
            let e = group.element(k);
            for f in faces {
                let nodes: Vec<usize> = f.nodes.iter().map(|&l| e[l]).collect();
                *count.entry(key(&nodes)).or_default() += 1;
            }
        }
        let mut set = FaceSet::new();
        for k in 0..group.len() {
            let e = group.element(k);
            for f in faces {
                let nodes: Vec<usize> = f.nodes.iter().map(|&l| e[l]).collect();
                if count[&key(&nodes)] == 1 {
                    set.push_unchecked(f.family, &nodes);
                }
            }
        }
        set
    }

    /// Generate a block and its named sets: node sets `NAME.all`, `NAME.xmin`, `NAME.xmax`,
    /// `NAME.ymin`, ... and face sets `NAME.xmin`, ... (outward oriented); returns the block
    /// index.
    pub fn add_block(&mut self, spec: BlockSpec) -> Result<usize, MeshError> {
        if self.blocks.iter().any(|b| b.name == spec.name) {
            return Err(MeshError::DuplicateBlock { block: spec.name });
        }
        let names = ['x', 'y', 'z'];
        for (k, a) in spec.axes().iter().enumerate() {
            let bad = |what: &str| MeshError::BadAxis {
                block: spec.name.clone(),
                axis: names[k],
                what: what.to_string(),
            };
            if a.elements() == 0 {
                return Err(MeshError::NoElements {
                    block: spec.name.clone(),
                    axis: names[k],
                });
            }
            if !(a.length.is_finite() && a.length > 0.0) {
                return Err(bad("length must be positive and finite"));
            }
            if a.zones
                .iter()
                .any(|z| !(z.fraction.is_finite() && z.fraction > 0.0))
            {
                return Err(bad("zone fractions must be positive and finite"));
            }
            if a.zones
                .iter()
                .any(|z| !(z.ratio.is_finite() && z.ratio > 0.0))
            {
                return Err(bad("zone ratios must be positive and finite"));
            }
            if a.elements() > 100_000 {
                return Err(bad("more than 100000 elements along one axis"));
            }
        }
        let b = self.blocks.len();
        let tx = spec.x.fractions();
        let ty = spec.y.fractions();
        let tz = spec.z.fractions();
        let (nx, ny, nz) = (tx.len(), ty.len(), tz.len());
        let first = self.places.len();
        let id = |i: usize, j: usize, k: usize| first + i + nx * (j + ny * k);
        // the hex8 of cell (i, j, k), in the element's node order
        let cell = |i: usize, j: usize, k: usize| {
            [
                id(i, j, k),
                id(i + 1, j, k),
                id(i + 1, j + 1, k),
                id(i, j + 1, k),
                id(i, j, k + 1),
                id(i + 1, j, k + 1),
                id(i + 1, j + 1, k + 1),
                id(i, j + 1, k + 1),
            ]
        };
        for &z in &tz {
            for &y in &ty {
                for &x in &tx {
                    self.places.push(NodePlace::Block {
                        block: b,
                        t: [x, y, z],
                    });
                }
            }
        }
        if !spec.element.is_solid() {
            return Err(MeshError::BlockElement {
                block: spec.name.clone(),
                shape: spec.element.name(),
            });
        }
        if spec.element != Shape::Hex8 {
            let cells = (0..nz - 1).flat_map(|k| {
                (0..ny - 1).flat_map(move |j| (0..nx - 1).map(move |i| cell(i, j, k)))
            });
            let cells: Vec<[usize; 8]> = cells.collect();
            let ends = [
                [tx[0], tx[nx - 1]],
                [ty[0], ty[ny - 1]],
                [tz[0], tz[nz - 1]],
            ];
            return self.add_split_block(spec, b, first, &cells, ends);
        }
        let mut connectivity = Vec::with_capacity(8 * (nx - 1) * (ny - 1) * (nz - 1));
        for k in 0..nz - 1 {
            for j in 0..ny - 1 {
                for i in 0..nx - 1 {
                    connectivity.extend_from_slice(&cell(i, j, k));
                }
            }
        }
        self.push_group(Shape::Hex8, connectivity, Some(b))?;
        let name = spec.name.clone();
        let all: Vec<usize> = (first..first + nx * ny * nz).collect();
        self.node_sets.insert(format!("{name}.all"), all);
        // node sets on the six sides
        let mut side = |label: &str, pred: &dyn Fn(usize, usize, usize) -> bool| {
            let mut v = Vec::new();
            for k in 0..nz {
                for j in 0..ny {
                    for i in 0..nx {
                        if pred(i, j, k) {
                            v.push(id(i, j, k));
                        }
                    }
                }
            }
            self.node_sets.insert(format!("{name}.{label}"), v);
        };
        side("xmin", &|i, _, _| i == 0);
        side("xmax", &|i, _, _| i == nx - 1);
        side("ymin", &|_, j, _| j == 0);
        side("ymax", &|_, j, _| j == ny - 1);
        side("zmin", &|_, _, k| k == 0);
        side("zmax", &|_, _, k| k == nz - 1);
        // face sets, oriented outward (the hex8 faces -x, +x, -y, +y, -z, +z)
        let mut faces: [FaceSet; 6] = Default::default();
        for k in 0..nz - 1 {
            for j in 0..ny - 1 {
                for i in 0..nx - 1 {
                    let conn = cell(i, j, k);
                    let on = [
                        i == 0,
                        i == nx - 2,
                        j == 0,
                        j == ny - 2,
                        k == 0,
                        k == nz - 2,
                    ];
                    for (f, face) in Shape::Hex8.faces().iter().enumerate() {
                        if on[f] {
                            let mut nodes = [0; 4];
                            for (n, &l) in nodes.iter_mut().zip(face.nodes) {
                                *n = conn[l];
                            }
                            faces[f].push_unchecked(face.family, &nodes);
                        }
                    }
                }
            }
        }
        for (f, label) in ["xmin", "xmax", "ymin", "ymax", "zmin", "zmax"]
            .iter()
            .enumerate()
        {
            self.face_sets
                .insert(format!("{name}.{label}"), std::mem::take(&mut faces[f]));
        }
        self.blocks.push(spec);
        Ok(b)
    }

    /// The rest of [`Mesh::add_block`] for a block of another shape than hex8: the grid's
    /// hex8 `cells` (corner nodes placed from `first` on) split into the block's shape, a node
    /// added at the middle of every edge of a quadratic shape (placed at the middle of its
    /// corners' block coordinates, so the block's shape parameters move it with them), and
    /// the node and face sets of the six sides (`ends`: the block coordinates of each axis's
    /// two sides).
    fn add_split_block(
        &mut self,
        spec: BlockSpec,
        b: usize,
        first: usize,
        cells: &[[usize; 8]],
        ends: [[f64; 2]; 3],
    ) -> Result<usize, MeshError> {
        // hex8 cell -> linear elements (local hex8 node numbers), positively oriented: six
        // tetrahedra around the diagonal 0-6 (Kuhn), or two wedges either side of the bottom
        // diagonal 0-2; the splits of neighbouring cells meet on their shared faces
        const KUHN: [[usize; 4]; 6] = [
            [0, 1, 2, 6],
            [0, 2, 3, 6],
            [0, 3, 7, 6],
            [0, 7, 4, 6],
            [0, 4, 5, 6],
            [0, 5, 1, 6],
        ];
        const PRISMS: [[usize; 6]; 2] = [[0, 1, 2, 4, 5, 6], [0, 2, 3, 4, 6, 7]];
        let shape = spec.element;
        let linear = shape.corners();
        let mut corners: Vec<Vec<usize>> = Vec::new();
        for c in cells {
            match linear {
                Shape::Tet4 => corners.extend(KUHN.iter().map(|t| t.map(|l| c[l]).to_vec())),
                Shape::Wedge6 => corners.extend(PRISMS.iter().map(|t| t.map(|l| c[l]).to_vec())),
                _ => corners.push(c.to_vec()),
            }
        }
        let mut mid: HashMap<(usize, usize), usize> = HashMap::new();
        let mut connectivity = Vec::with_capacity(shape.n_nodes() * corners.len());
        for e in &corners {
            connectivity.extend_from_slice(e);
            if shape.is_quadratic() {
                for [a, c] in shape.edges() {
                    let key = (e[*a].min(e[*c]), e[*a].max(e[*c]));
                    let n = match mid.get(&key) {
                        Some(&n) => n,
                        None => {
                            let t = |n: usize| match self.places[n] {
                                NodePlace::Block { t, .. } => t,
                                NodePlace::Free(_) => [0.0; 3],
                            };
                            let (ta, tc) = (t(key.0), t(key.1));
                            let n = self.places.len();
                            self.places.push(NodePlace::Block {
                                block: b,
                                t: [0, 1, 2].map(|k| 0.5 * (ta[k] + tc[k])),
                            });
                            mid.insert(key, n);
                            n
                        }
                    };
                    connectivity.push(n);
                }
            }
        }
        let g = self.push_group(shape, connectivity, Some(b))?;
        let name = spec.name.clone();
        let nodes: Vec<usize> = (first..self.places.len()).collect();
        let t_of = |n: usize| match self.places[n] {
            NodePlace::Block { t, .. } => t,
            NodePlace::Free(_) => [f64::NAN; 3],
        };
        // side s = 2 axis + (0 min, 1 max)
        let on_side = |n: usize, s: usize| t_of(n)[s / 2] == ends[s / 2][s % 2];
        const SIDES: [&str; 6] = ["xmin", "xmax", "ymin", "ymax", "zmin", "zmax"];
        let mut faces: [FaceSet; 6] = Default::default();
        let boundary = self.boundary_faces(g);
        for f in boundary.iter() {
            if let Some(s) = (0..6).find(|&s| f.nodes.iter().all(|&n| on_side(n, s))) {
                faces[s].push_unchecked(f.family, f.nodes);
            }
        }
        for (s, label) in SIDES.iter().enumerate() {
            let set: Vec<usize> = nodes.iter().copied().filter(|&n| on_side(n, s)).collect();
            self.node_sets.insert(format!("{name}.{label}"), set);
            self.face_sets
                .insert(format!("{name}.{label}"), std::mem::take(&mut faces[s]));
        }
        self.node_sets.insert(format!("{name}.all"), nodes);
        self.blocks.push(spec);
        Ok(b)
    }

    /// Block geometry with plain values (no design dependence).
    pub fn block_geometry<S: Scalar>(&self) -> Vec<BlockGeometry<S>> {
        self.blocks
            .iter()
            .map(|b| BlockGeometry {
                origin: Vector3::new(
                    S::lift(b.origin[0]),
                    S::lift(b.origin[1]),
                    S::lift(b.origin[2]),
                ),
                lengths: Vector3::new(
                    S::lift(b.x.length),
                    S::lift(b.y.length),
                    S::lift(b.z.length),
                ),
            })
            .collect()
    }

    /// Reference coordinates of every node for the given (possibly design-dependent) block
    /// geometry: `X = origin + L o t`, then the shape maps at their current values.
    pub fn coordinates<S: Scalar>(&self, geometry: &[BlockGeometry<S>]) -> Vec<Vector3<S>> {
        let values: Vec<S> = self.shape_maps.iter().map(|m| S::lift(m.value)).collect();
        self.coordinates_at(geometry, &values)
    }

    /// [`Mesh::coordinates`] with the shape maps at the values `shape` (one per map).
    pub fn coordinates_at<S: Scalar>(
        &self,
        geometry: &[BlockGeometry<S>],
        shape: &[S],
    ) -> Vec<Vector3<S>> {
        let mut x = self.placed(geometry);
        for (m, b) in self.shape_maps.iter().zip(shape) {
            m.apply(*b, &mut x);
        }
        for (&(node, axis), v) in &self.node_moves {
            x[node][axis] += S::lift(*v);
        }
        x
    }

    fn placed<S: Scalar>(&self, geometry: &[BlockGeometry<S>]) -> Vec<Vector3<S>> {
        self.places
            .iter()
            .map(|p| match p {
                NodePlace::Block { block, t } => {
                    let g = &geometry[*block];
                    Vector3::new(
                        g.origin[0] + g.lengths[0] * t[0],
                        g.origin[1] + g.lengths[1] * t[1],
                        g.origin[2] + g.lengths[2] * t[2],
                    )
                }
                NodePlace::Free(x) => Vector3::new(S::lift(x[0]), S::lift(x[1]), S::lift(x[2])),
            })
            .collect()
    }

    /// Node of a block nearest to a fractional position (handy for picking tip nodes).
    pub fn block_node_at(&self, block: usize, t: [f64; 3]) -> Option<usize> {
        self.places
            .iter()
            .enumerate()
            .filter_map(|(n, p)| match p {
                NodePlace::Block { block: b, t: tn } if *b == block => {
                    let d =
                        (tn[0] - t[0]).powi(2) + (tn[1] - t[1]).powi(2) + (tn[2] - t[2]).powi(2);
                    Some((n, d))
                }
                _ => None,
            })
            .min_by(|a, b| a.1.total_cmp(&b.1))
            .map(|(n, _)| n)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;
    use num_dual::Dual64;

    fn block() -> BlockSpec {
        BlockSpec {
            element: crate::element::Shape::Hex8,
            name: "b".into(),
            origin: [1.0, 0.0, 0.0],
            x: Axis {
                length: 10.0,
                zones: vec![
                    Zone {
                        fraction: 0.2,
                        elements: 4,
                        ratio: 1.0,
                    },
                    Zone {
                        fraction: 0.8,
                        elements: 4,
                        ratio: 4.0,
                    },
                ],
            },
            y: Axis::uniform(1.0, 2),
            z: Axis::uniform(0.5, 1),
        }
    }

    #[test]
    fn graded_axis_sizes_grow_by_the_ratio() {
        let t = block().x.fractions();
        assert_eq!(t.len(), 9);
        // fine zone: 4 equal elements over 0.2
        assert_relative_eq!(t[1], 0.05, max_relative = 1e-14);
        assert_relative_eq!(t[4], 0.2, max_relative = 1e-14);
        let first = t[5] - t[4];
        let last = t[8] - t[7];
        assert_relative_eq!(last / first, 4.0, max_relative = 1e-12);
    }

    #[test]
    fn block_counts_sets_and_outward_faces() {
        let mut m = Mesh::default();
        m.add_block(block()).unwrap();
        assert_eq!(m.n_elements(), 8 * 2);
        assert_eq!(m.n_nodes(), 9 * 3 * 2);
        assert_eq!(m.node_sets["b.xmin"].len(), 3 * 2);
        assert_eq!(m.face_sets["b.ymax"].len(), 8);
        let x = m.coordinates::<f64>(&m.block_geometry());
        // outward normal of every ymax face is +y
        for f in m.face_sets["b.ymax"].iter().map(|f| f.nodes) {
            let n = (x[f[1]] - x[f[0]]).cross(&(x[f[3]] - x[f[0]]));
            assert!(n[1] > 0.0 && n[0].abs() < 1e-12 && n[2].abs() < 1e-12);
        }
        for f in m.face_sets["b.xmin"].iter().map(|f| f.nodes) {
            let n = (x[f[1]] - x[f[0]]).cross(&(x[f[3]] - x[f[0]]));
            assert!(n[0] < 0.0);
        }
    }

    #[test]
    fn length_derivative_of_coordinates_is_the_fraction() {
        let mut m = Mesh::default();
        m.add_block(block()).unwrap();
        let mut g = m.block_geometry::<Dual64>();
        g[0].lengths[0] = Dual64::new(10.0, 1.0);
        let x = m.coordinates(&g);
        let tip = m.block_node_at(0, [1.0, 0.0, 0.0]).unwrap();
        assert_relative_eq!(x[tip][0].re, 11.0, max_relative = 1e-15);
        assert_relative_eq!(x[tip][0].eps, 1.0, max_relative = 1e-15);
    }
}
