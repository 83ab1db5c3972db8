//! Meshes: nodes, hex8 connectivity, named node and face sets, and a structured block generator
//! with grading.
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

use crate::scalar::Scalar;
use nalgebra::Vector3;
use std::collections::BTreeMap;

/// One zone of an axis: a fraction of the block's length split into `elements` elements whose
/// sizes grow geometrically from the first to the last by `ratio`.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Zone {
    /// Fraction of the axis length this zone covers (the fractions of an axis add up to one).
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
    /// Zones, whose fractions add up to one.
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

/// A structured brick of hex8 elements.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BlockSpec {
    /// Block name: the prefix of its node and face sets (`NAME.xmin`, `NAME.all`, ...).
    pub name: String,
    /// Reference position of the block's corner with the smallest coordinates.
    pub origin: [f64; 3],
    /// Division along x.
    pub x: Axis,
    /// Division along y.
    pub y: Axis,
    /// Division along z.
    pub z: Axis,
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

/// A mesh of hex8 elements grouped by generating block.
#[derive(Clone, Debug, Default)]
pub struct Mesh {
    /// Where each node's reference position comes from, by node number.
    pub places: Vec<NodePlace>,
    /// The generating blocks, in the order they were added.
    pub blocks: Vec<BlockSpec>,
    /// Connectivity of every element.
    pub elements: Vec<[usize; 8]>,
    /// Element range of each block.
    pub block_elements: Vec<std::ops::Range<usize>>,
    /// Named node sets (`BLOCK.all`, `BLOCK.xmin`, ..., and those added by the caller).
    pub node_sets: BTreeMap<String, Vec<usize>>,
    /// Faces as 4 node numbers ordered counter-clockwise seen from outside the block.
    pub face_sets: BTreeMap<String, Vec<[usize; 4]>>,
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

    /// The shortest element edge (the twelve edges of every hex8) at the coordinates `x`
    /// (infinite without elements).
    pub fn smallest_edge(&self, x: &[Vector3<f64>]) -> f64 {
        const EDGES: [(usize, usize); 12] = [
            (0, 1),
            (1, 2),
            (2, 3),
            (3, 0),
            (4, 5),
            (5, 6),
            (6, 7),
            (7, 4),
            (0, 4),
            (1, 5),
            (2, 6),
            (3, 7),
        ];
        self.elements
            .iter()
            .flat_map(|e| EDGES.iter().map(move |(a, b)| (x[e[*a]] - x[e[*b]]).norm()))
            .fold(f64::INFINITY, f64::min)
    }

    /// Add a free node with fixed coordinates; returns its number.
    pub fn add_free_node(&mut self, x: [f64; 3]) -> usize {
        self.places.push(NodePlace::Free(x));
        self.places.len() - 1
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
        let e0 = self.elements.len();
        for k in 0..nz - 1 {
            for j in 0..ny - 1 {
                for i in 0..nx - 1 {
                    self.elements.push([
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
        self.block_elements.push(e0..self.elements.len());
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
        // face sets, oriented outward (see element::hex8::FACE_NODES)
        let mut faces: [Vec<[usize; 4]>; 6] = Default::default();
        for k in 0..nz - 1 {
            for j in 0..ny - 1 {
                for i in 0..nx - 1 {
                    let conn = [
                        id(i, j, k),
                        id(i + 1, j, k),
                        id(i + 1, j + 1, k),
                        id(i, j + 1, k),
                        id(i, j, k + 1),
                        id(i + 1, j, k + 1),
                        id(i + 1, j + 1, k + 1),
                        id(i, j + 1, k + 1),
                    ];
                    let on = [
                        i == 0,
                        i == nx - 2,
                        j == 0,
                        j == ny - 2,
                        k == 0,
                        k == nz - 2,
                    ];
                    for f in 0..6 {
                        if on[f] {
                            let l = crate::element::hex8::FACE_NODES[f];
                            faces[f].push([conn[l[0]], conn[l[1]], conn[l[2]], conn[l[3]]]);
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
    /// geometry: `X = origin + L o t`.
    pub fn coordinates<S: Scalar>(&self, geometry: &[BlockGeometry<S>]) -> Vec<Vector3<S>> {
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
        assert_eq!(m.elements.len(), 8 * 2);
        assert_eq!(m.n_nodes(), 9 * 3 * 2);
        assert_eq!(m.node_sets["b.xmin"].len(), 3 * 2);
        assert_eq!(m.face_sets["b.ymax"].len(), 8);
        let x = m.coordinates::<f64>(&m.block_geometry());
        // outward normal of every ymax face is +y
        for f in &m.face_sets["b.ymax"] {
            let n = (x[f[1]] - x[f[0]]).cross(&(x[f[3]] - x[f[0]]));
            assert!(n[1] > 0.0 && n[0].abs() < 1e-12 && n[2].abs() < 1e-12);
        }
        for f in &m.face_sets["b.xmin"] {
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
