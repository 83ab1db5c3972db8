//! Shape maps: design-dependent reference coordinates for any node, generated or imported.
//!
//! A [`ShapeMap`] moves the nodes of one node set with a scalar design value `b`, whose
//! reference value `b_ref` is the one at which the mesh's coordinates `X0` hold:
//!
//! | kind | map | `dX/db` at `b_ref` |
//! |---|---|---|
//! | [`MapKind::Translate`] `d` | `X = X0 + (b - b_ref) d` | `d` |
//! | [`MapKind::Rotate`] about the axis `(c, a)` | `X = X0 + (R_a(b - b_ref) - I)(X0 - c)` | `a x (X0 - c)` |
//! | [`MapKind::Scale`] about a point `c` | `X = X0 + (b / b_ref - 1)(X0 - c)` | `(X0 - c) / b_ref` |
//! | [`MapKind::Scale`] about an axis `(c, a)` | the same on the part of `X0 - c` normal to `a` | its normal part `/ b_ref` |
//! | [`MapKind::Velocity`] `V` | `X = X0 + (b - b_ref) V` | `V` |
//!
//! A velocity field is given node by node: the difference of two meshes of one topology (a
//! morph `X = X_A + b (X_B - X_A)`, `b_ref = 0`), or computed by [`boundary_driven`]: a
//! surface moved by a prescribed field and the interior following by a Laplace or linear
//! elastic solve on the reference mesh.
//!
//! Every map is evaluated in the generic scalar, so a dual `b` gives `dX/db` exactly (the
//! rotation and the scale are nonlinear in `b`; their derivatives are exact too). At
//! `b = b_ref` every map is the identity bit for bit (each adds a term that is exactly zero),
//! so a model with shape maps at their reference values has the coordinates of its mesh.
//! A scale takes the size itself as its value (a cylinder's radius: `b_ref = R0`), so the
//! derivative is per unit of that size.

use super::Mesh;
use crate::element::Shape;
use crate::scalar::Scalar;
use nalgebra::{Matrix3, Vector3};

/// A design-dependent map of the reference coordinates of a node set.
#[derive(Clone, Debug, PartialEq)]
pub struct ShapeMap {
    /// Name (the design parameter's name).
    pub name: String,
    /// The nodes it moves.
    pub nodes: Vec<usize>,
    /// What it does with them.
    pub kind: MapKind,
    /// Reference value `b_ref`: the value at which the mesh's coordinates hold.
    pub reference: f64,
    /// Current value `b` (a rerun at a perturbed design sets it).
    pub value: f64,
}

/// The kinds of [`ShapeMap`] (module docs).
#[derive(Clone, Debug, PartialEq)]
pub enum MapKind {
    /// Translation along `direction` per unit of `b`.
    Translate {
        /// Motion per unit of `b`.
        direction: [f64; 3],
    },
    /// Rotation by the angle `b - b_ref` (radians) about the axis through `centre` along `axis`.
    Rotate {
        /// A point of the axis.
        centre: [f64; 3],
        /// Axis direction (normalised when the map is made).
        axis: [f64; 3],
    },
    /// Scale by `b / b_ref` about `centre`, or about the axis through it along `axis`
    /// (the part along the axis unchanged).
    Scale {
        /// Centre of the scaling (a point of the axis).
        centre: [f64; 3],
        /// Axis direction (normalised), or `None` for a scale about the point.
        axis: Option<[f64; 3]>,
    },
    /// Node-by-node velocity: `velocity[k]` moves `nodes[k]`.
    Velocity {
        /// `dX/db` of each node of the set.
        velocity: Vec<[f64; 3]>,
    },
}

/// Why a shape map cannot be made.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum ShapeMapError {
    /// A zero or non-finite axis or direction.
    #[error("shape map '{map}': the {what} must be a finite non-zero vector")]
    Direction {
        /// The map.
        map: String,
        /// `axis` or `direction`.
        what: &'static str,
    },
    /// A rotation's or scale's centre with a non-finite coordinate.
    #[error("shape map '{map}': the centre must be finite, got {centre:?}")]
    Centre {
        /// The map.
        map: String,
        /// The centre given.
        centre: [f64; 3],
    },
    /// A scale about a zero (or non-finite) reference size.
    #[error("shape map '{map}': a scale needs a positive finite reference value, got {value}")]
    Reference {
        /// The map.
        map: String,
        /// The reference value given.
        value: f64,
    },
    /// A velocity field of the wrong length.
    #[error("shape map '{map}': {nodes} nodes but {velocities} velocities")]
    Length {
        /// The map.
        map: String,
        /// Nodes of the set.
        nodes: usize,
        /// Velocities given.
        velocities: usize,
    },
    /// Two meshes of a morph that do not share their topology.
    #[error("shape map '{map}': {what}")]
    Topology {
        /// The map.
        map: String,
        /// What differs.
        what: String,
    },
    /// A boundary-driven field whose solve failed (no prescribed node, an element kind
    /// without a smoothing operator, a singular system).
    #[error("shape map '{map}': {what}")]
    Smoothing {
        /// The map.
        map: String,
        /// What went wrong.
        what: String,
    },
}

fn unit(map: &str, v: [f64; 3], what: &'static str) -> Result<[f64; 3], ShapeMapError> {
    let n = Vector3::from(v).norm();
    if !(n.is_finite() && n > 0.0) {
        return Err(ShapeMapError::Direction {
            map: map.to_string(),
            what,
        });
    }
    Ok([v[0] / n, v[1] / n, v[2] / n])
}

fn finite_centre(map: &str, centre: [f64; 3]) -> Result<[f64; 3], ShapeMapError> {
    if centre.iter().all(|c| c.is_finite()) {
        Ok(centre)
    } else {
        Err(ShapeMapError::Centre {
            map: map.to_string(),
            centre,
        })
    }
}

impl ShapeMap {
    /// A map of `nodes`, checked (axes finite, non-zero and normalised; a translation's
    /// direction finite; centres finite; a scale's reference positive; a velocity per node);
    /// its value starts at `reference`.
    pub fn new(
        name: &str,
        nodes: Vec<usize>,
        kind: MapKind,
        reference: f64,
    ) -> Result<Self, ShapeMapError> {
        let kind = match kind {
            MapKind::Translate { direction } => {
                if !direction.iter().all(|d| d.is_finite()) {
                    return Err(ShapeMapError::Direction {
                        map: name.to_string(),
                        what: "direction",
                    });
                }
                MapKind::Translate { direction }
            }
            MapKind::Rotate { centre, axis } => MapKind::Rotate {
                centre: finite_centre(name, centre)?,
                axis: unit(name, axis, "axis")?,
            },
            MapKind::Scale { centre, axis } => {
                finite_centre(name, centre)?;
                if !(reference.is_finite() && reference > 0.0) {
                    return Err(ShapeMapError::Reference {
                        map: name.to_string(),
                        value: reference,
                    });
                }
                MapKind::Scale {
                    centre,
                    axis: axis.map(|a| unit(name, a, "axis")).transpose()?,
                }
            }
            MapKind::Velocity { velocity } => {
                if velocity.len() != nodes.len() {
                    return Err(ShapeMapError::Length {
                        map: name.to_string(),
                        nodes: nodes.len(),
                        velocities: velocity.len(),
                    });
                }
                MapKind::Velocity { velocity }
            }
        };
        Ok(ShapeMap {
            name: name.to_string(),
            nodes,
            kind,
            reference,
            value: reference,
        })
    }

    /// Move the map's nodes of `x` for the design value `b` (module docs).
    pub fn apply<S: Scalar>(&self, b: S, x: &mut [Vector3<S>]) {
        let lift = |v: [f64; 3]| Vector3::new(S::lift(v[0]), S::lift(v[1]), S::lift(v[2]));
        let db = b - S::lift(self.reference);
        match &self.kind {
            MapKind::Translate { direction } => {
                let d = lift(*direction) * db;
                for &n in &self.nodes {
                    x[n] += d;
                }
            }
            MapKind::Rotate { centre, axis } => {
                // R - I = sin(t) [a]x + (1 - cos(t)) ([a]x)^2 (Rodrigues): exactly zero at t = 0
                let a = lift(*axis);
                let c = lift(*centre);
                let (s, one_minus_c) = (db.sin(), S::one() - db.cos());
                for &n in &self.nodes {
                    let r = x[n] - c;
                    let ar = a.cross(&r);
                    x[n] += ar * s + a.cross(&ar) * one_minus_c;
                }
            }
            MapKind::Scale { centre, axis } => {
                let f = b / S::lift(self.reference) - S::one();
                let c = lift(*centre);
                for &n in &self.nodes {
                    let mut r = x[n] - c;
                    if let Some(a) = axis {
                        let a = lift(*a);
                        r -= a * a.dot(&r);
                    }
                    x[n] += r * f;
                }
            }
            MapKind::Velocity { velocity } => {
                for (&n, v) in self.nodes.iter().zip(velocity) {
                    x[n] += lift(*v) * db;
                }
            }
        }
    }
}

/// How the interior follows a moved boundary in [`boundary_driven`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Smoothing {
    /// Each component harmonic: `div grad V = 0`.
    #[default]
    Laplace,
    /// Linear elasticity with Poisson's ratio 0.3: `div sigma(V) = 0`.
    Elastic,
}

/// The velocity field of a boundary-driven shape change of element group `group`: the nodes
/// of `prescribed` move with the given velocity, the components listed in `held` stay zero
/// (a symmetry plane keeps its normal component, a fixed surface all three), and every other
/// component of the group's nodes follows by a `smoothing` solve on the reference mesh `x`.
/// Returns the group's nodes (ascending) and their velocities.
pub fn boundary_driven(
    name: &str,
    mesh: &Mesh,
    x: &[Vector3<f64>],
    group: usize,
    prescribed: &[(usize, [f64; 3])],
    held: &[(usize, usize)],
    smoothing: Smoothing,
) -> Result<(Vec<usize>, Vec<[f64; 3]>), ShapeMapError> {
    use crate::linalg::{LinearSolver, SparseMatrix, SparsePattern};
    let fail = |what: String| ShapeMapError::Smoothing {
        map: name.to_string(),
        what,
    };
    let g = &mesh.groups[group];
    if g.shape != Shape::Hex8 {
        return Err(fail(format!(
            "no smoothing operator for {} elements",
            g.shape.name()
        )));
    }
    if prescribed.is_empty() {
        return Err(fail("no node is prescribed".into()));
    }
    // the group's nodes, numbered locally
    let mut nodes: Vec<usize> = g.nodes.clone();
    nodes.sort_unstable();
    nodes.dedup();
    let local = |n: usize| nodes.binary_search(&n).ok();
    let n = 3 * nodes.len();
    let blocks: Vec<Vec<usize>> = (0..g.len())
        .map(|k| {
            g.element(k)
                .iter()
                .flat_map(|&a| {
                    let l = local(a).expect("a node of the group");
                    [3 * l, 3 * l + 1, 3 * l + 2]
                })
                .collect()
        })
        .collect();
    let refs: Vec<&[usize]> = blocks.iter().map(|b| b.as_slice()).collect();
    let pattern = std::sync::Arc::new(
        SparsePattern::new(n, &refs, &[]).map_err(|e| fail(format!("pattern: {e}")))?,
    );
    let mut k = SparseMatrix::new(pattern.clone());
    // isotropic operator per element: Laplace (mu = 1), or elasticity with E = 1, nu = 0.3
    let (lambda, mu) = match smoothing {
        Smoothing::Laplace => (0.0, 1.0),
        Smoothing::Elastic => {
            let nu = 0.3;
            (nu / ((1.0 + nu) * (1.0 - 2.0 * nu)), 0.5 / (1.0 + nu))
        }
    };
    let gauss = crate::element::hex8::gauss_points();
    for (b, conn) in (0..g.len()).map(|k| g.element(k)).enumerate() {
        let mut ke = [0.0; 24 * 24];
        for xi in gauss {
            let dn = crate::element::hex8::shape_derivatives(xi);
            let mut jac = Matrix3::zeros();
            for (a, &node) in conn.iter().enumerate() {
                jac += x[node] * Vector3::from(dn[a]).transpose();
            }
            let det = jac.determinant();
            let inv_t = jac
                .try_inverse()
                .filter(|_| det > 0.0)
                .ok_or_else(|| fail(format!("element {} is degenerate or inverted", g.first + b)))?
                .transpose();
            let grads: Vec<Vector3<f64>> = dn.iter().map(|d| inv_t * Vector3::from(*d)).collect();
            for (a, ga) in grads.iter().enumerate() {
                for (c, gc) in grads.iter().enumerate() {
                    let dot = ga.dot(gc);
                    for i in 0..3 {
                        for j in 0..3 {
                            // Laplace: (g_a . g_c) I; elasticity adds the coupling terms
                            let mut v = if i == j { mu * dot } else { 0.0 };
                            if smoothing == Smoothing::Elastic {
                                v += lambda * ga[i] * gc[j] + mu * gc[i] * ga[j];
                            }
                            ke[(3 * a + i) * 24 + 3 * c + j] += v * det;
                        }
                    }
                }
            }
        }
        k.add_block(b, &ke)
            .map_err(|e| fail(format!("assembly: {e}")))?;
    }
    // Dirichlet values: prescribed velocities and held components
    let mut known: Vec<Option<f64>> = vec![None; n];
    for &(node, v) in prescribed {
        let l = local(node).ok_or_else(|| {
            fail(format!(
                "prescribed node {node} is not a node of the body's elements"
            ))
        })?;
        for c in 0..3 {
            known[3 * l + c] = Some(v[c]);
        }
    }
    for &(node, c) in held {
        if let Some(l) = local(node) {
            known[3 * l + c].get_or_insert(0.0);
        }
    }
    let mut rhs = vec![0.0; n];
    let kcsc = k.as_faer();
    for (j, v) in known.iter().enumerate() {
        if let Some(v) = v {
            if *v != 0.0 {
                let col = kcsc.col_range(j);
                let rows = &kcsc.row_idx()[col.clone()];
                let vals = &kcsc.val()[col];
                for (&i, &kij) in rows.iter().zip(vals) {
                    rhs[i] -= kij * v;
                }
            }
        }
    }
    let fixed: Vec<bool> = known.iter().map(Option::is_some).collect();
    k.set_identity_rows_cols(&fixed)
        .map_err(|e| fail(format!("constraint: {e}")))?;
    for (i, v) in known.iter().enumerate() {
        if let Some(v) = v {
            rhs[i] = *v;
        }
    }
    let mut solver = LinearSolver::new(pattern).map_err(|e| fail(format!("solver: {e}")))?;
    solver
        .factor(&k)
        .map_err(|e| fail(format!("the smoothing system is singular ({e})")))?;
    solver
        .solve_in_place(&mut rhs)
        .map_err(|e| fail(format!("solve: {e}")))?;
    let velocity = (0..nodes.len())
        .map(|l| [rhs[3 * l], rhs[3 * l + 1], rhs[3 * l + 2]])
        .collect();
    Ok((nodes, velocity))
}

#[cfg(test)]
mod tests {
    use super::*;
    use num_dual::Dual64;

    fn points() -> Vec<Vector3<f64>> {
        vec![
            Vector3::new(1.0, 0.0, 0.0),
            Vector3::new(0.3, -2.0, 0.5),
            Vector3::new(-1.5, 0.7, 2.0),
        ]
    }

    fn dual(x: &[Vector3<f64>]) -> Vec<Vector3<Dual64>> {
        x.iter().map(|p| p.map(Dual64::from)).collect()
    }

    #[test]
    fn every_map_is_the_identity_at_its_reference_value_bit_for_bit() {
        let kinds = [
            MapKind::Translate {
                direction: [0.3, -1.0, 2.0],
            },
            MapKind::Rotate {
                centre: [0.1, 0.2, 0.3],
                axis: [1.0, 1.0, 0.5],
            },
            MapKind::Scale {
                centre: [0.1, 0.2, 0.3],
                axis: Some([0.0, 0.0, 2.0]),
            },
            MapKind::Scale {
                centre: [0.1, 0.2, 0.3],
                axis: None,
            },
            MapKind::Velocity {
                velocity: vec![[1.0, 2.0, 3.0]; 3],
            },
        ];
        for kind in kinds {
            let m = ShapeMap::new("m", vec![0, 1, 2], kind, 1.7).unwrap();
            let mut x = points();
            m.apply(1.7, &mut x);
            assert_eq!(x, points());
        }
    }

    #[test]
    fn derivatives_are_the_closed_forms() {
        // rotation about z through c: dX/db = a x (X - c); scale about the z axis through c:
        // dX/db = the part of X - c normal to z, over b_ref
        let c = Vector3::new(0.5, -0.5, 1.0);
        let rot = ShapeMap::new(
            "r",
            vec![0, 1, 2],
            MapKind::Rotate {
                centre: c.into(),
                axis: [0.0, 0.0, 3.0],
            },
            0.0,
        )
        .unwrap();
        let mut x = dual(&points());
        rot.apply(Dual64::new(0.0, 1.0), &mut x);
        for (p, q) in points().iter().zip(&x) {
            let d = Vector3::z().cross(&(p - c));
            for i in 0..3 {
                assert!((q[i].eps - d[i]).abs() < 1e-15);
            }
        }
        let scale = ShapeMap::new(
            "s",
            vec![0, 1, 2],
            MapKind::Scale {
                centre: c.into(),
                axis: Some([0.0, 0.0, 1.0]),
            },
            4.0,
        )
        .unwrap();
        let mut x = dual(&points());
        scale.apply(Dual64::new(4.0, 1.0), &mut x);
        for (p, q) in points().iter().zip(&x) {
            let r = p - c;
            let d = Vector3::new(r.x, r.y, 0.0) / 4.0;
            for i in 0..3 {
                assert!((q[i].eps - d[i]).abs() < 1e-15);
                assert_eq!(q[i].re, p[i]);
            }
        }
        // a finite rotation by pi/2 about z through the origin maps (1, 0, 0) to (0, 1, 0)
        let quarter = ShapeMap::new(
            "q",
            vec![0],
            MapKind::Rotate {
                centre: [0.0; 3],
                axis: [0.0, 0.0, 1.0],
            },
            0.0,
        )
        .unwrap();
        let mut x = points();
        quarter.apply(std::f64::consts::FRAC_PI_2, &mut x);
        assert!((x[0] - Vector3::new(0.0, 1.0, 0.0)).norm() < 1e-15);
    }

    #[test]
    fn bad_maps_are_typed_errors() {
        let zero_axis = MapKind::Rotate {
            centre: [0.0; 3],
            axis: [0.0; 3],
        };
        assert!(matches!(
            ShapeMap::new("m", vec![0], zero_axis, 0.0),
            Err(ShapeMapError::Direction { .. })
        ));
        let scale = MapKind::Scale {
            centre: [0.0; 3],
            axis: None,
        };
        assert!(matches!(
            ShapeMap::new("m", vec![0], scale, 0.0),
            Err(ShapeMapError::Reference { .. })
        ));
        let v = MapKind::Velocity {
            velocity: vec![[0.0; 3]],
        };
        assert!(matches!(
            ShapeMap::new("m", vec![0, 1], v, 0.0),
            Err(ShapeMapError::Length { .. })
        ));
    }

    #[test]
    fn a_boundary_driven_field_reproduces_a_linear_field() {
        // a linear field is harmonic and equilibrated: prescribed on the x faces (x = 0 held,
        // x = L moving by 1), both smoothings give V_x = x / L inside, V_y = V_z = 0 with the
        // lateral components held on the sides
        use crate::mesh::{Axis, BlockSpec};
        let mut m = Mesh::default();
        m.add_block(BlockSpec {
            element: crate::element::Shape::Hex8,
            name: "b".into(),
            origin: [0.0; 3],
            x: Axis::uniform(2.0, 4),
            y: Axis::uniform(1.0, 2),
            z: Axis::uniform(1.0, 2),
        })
        .unwrap();
        let x = m.coordinates::<f64>(&m.block_geometry());
        let mut prescribed: Vec<(usize, [f64; 3])> = m.node_sets["b.xmax"]
            .iter()
            .map(|&n| (n, [1.0, 0.0, 0.0]))
            .collect();
        prescribed.extend(m.node_sets["b.xmin"].iter().map(|&n| (n, [0.0; 3])));
        let held: Vec<(usize, usize)> = m.node_sets["b.all"]
            .iter()
            .flat_map(|&n| [(n, 1), (n, 2)])
            .collect();
        for s in [Smoothing::Laplace, Smoothing::Elastic] {
            let (nodes, v) = boundary_driven("v", &m, &x, 0, &prescribed, &held, s).unwrap();
            for (n, v) in nodes.iter().zip(&v) {
                assert!((v[0] - x[*n].x / 2.0).abs() < 1e-12, "{s:?} {v:?}");
                assert!(v[1].abs() < 1e-12 && v[2].abs() < 1e-12);
            }
        }
    }
}
