//! The analysis model: mesh, bodies with their materials and element formulations, springs,
//! prescribed displacements, nodal loads, the load history, and the unknowns' numbering.
//!
//! The model holds plain values. Evaluation lifts them to a scalar type through [`Lifted`], with
//! any design parameter replaced by a value of that type (seeded dual for DDM, perturbed `f64`
//! for SDM), so that every kernel sees its parameters as `S`.

use crate::element::{ElementFamily, Formulation, FormulationError, Kinematics, Shape, SpringSet};
pub use crate::load::Amplitude;
pub use crate::material::Material;
use crate::mesh::{BlockGeometry, Mesh, MeshError};
use crate::scalar::Scalar;
use nalgebra::Vector3;

/// A deformable body: one element group of the mesh with one material.
#[derive(Clone, Debug)]
pub struct Body {
    /// Name of the body (from the scene).
    pub name: String,
    /// Index of the mesh's element group (elements `mesh.group_elements(group)`; the block
    /// generator makes group `b` from block `b`).
    pub group: usize,
    /// Constitutive law.
    pub material: Material,
    /// Small or large deformation.
    pub kinematics: Kinematics,
    /// Element formulation (full or reduced integration, incompatible modes, F-bar, ...),
    /// or `None` for the standard one of the body's shape
    /// ([`crate::element::family`]'s table).
    pub formulation: Option<Formulation>,
}

impl Body {
    /// The element family of the body's elements in `mesh`, or a typed error when the
    /// body's shape does not take its formulation.
    pub fn family(&self, mesh: &Mesh) -> Result<ElementFamily, FormulationError> {
        ElementFamily::new(mesh.groups[self.group].shape, self.formulation)
    }
}

/// A prescribed displacement on some nodes: `u_c(t) = value * amplitude(t)`.
#[derive(Clone, Debug)]
pub struct Prescribed {
    /// Name (from the scene).
    pub name: String,
    /// Constrained nodes.
    pub nodes: Vec<usize>,
    /// Constrained displacement component (0 = x, 1 = y, 2 = z).
    pub component: usize,
    /// Magnitude of the displacement (a length), scaled by `amplitude`.
    pub value: f64,
    /// Time history of the displacement.
    pub amplitude: Amplitude,
}

/// A total force `value * amplitude(t)` in `component`, shared by `nodes` with `weights`
/// (summing to one: tributary areas of a face set, or equal shares of a node set).
#[derive(Clone, Debug)]
pub struct NodalLoad {
    /// Name (from the scene).
    pub name: String,
    /// Loaded nodes.
    pub nodes: Vec<usize>,
    /// Share of the total force on each node (summing to one).
    pub weights: Vec<f64>,
    /// Force component (0 = x, 1 = y, 2 = z).
    pub component: usize,
    /// Total force (summed over `nodes`), scaled by `amplitude`.
    pub value: f64,
    /// Time history of the force.
    pub amplitude: Amplitude,
}

/// Newton-Raphson settings.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SolverSettings {
    /// Relative force residual: `|R_free| <= force_tol * F_ref`.
    pub force_tol: f64,
    /// Relative energy norm: `|du . R| <= energy_tol * |du_0 . R_0|`.
    pub energy_tol: f64,
    /// Newton iterations per attempt.
    pub max_iterations: usize,
    /// Successive halvings of an increment before giving up.
    pub max_cutbacks: usize,
    /// Start an increment from the linear extrapolation of the last two converged states
    /// where the load path goes straight on ([`Model::load_path_straight`]); otherwise, and
    /// when `false`, from the last converged state.
    ///
    /// Measured (`fricsens run`, increments / Newton iterations, off -> on): leaf spring
    /// 37 / 214 with the penetration limiter -> 37 / 182, sliding block 157 -> 71 iterations;
    /// the 200-element strip pull-out 31 / 552 -> 113 / 593. On the strip's unloading branch,
    /// where most nodes stick with friction forces locked in at the slip limit, Newton from
    /// the extrapolated start spreads slip far beyond the reverse-slip zone and lifts nodes off
    /// until cut back; its scene turns it off.
    pub extrapolate: bool,
    /// Extra solves allowed to settle the contact states of each attempt's first Newton step
    /// on the linearised problem, before the state moves (0: none; see
    /// [`crate::solver::Solver`]'s active-set predictor).
    ///
    /// Measured (factorizations, 0 -> 30; `fricsens run`): leaf spring 242 -> 172 and no
    /// cutback (was 2), without friction 203 -> 167, hertz 20 -> 16, coarse leaf spring
    /// 74 -> 75, stacked leaves 22 -> 24, the other built-in scenes unchanged. The leaf
    /// spring's first increment refined (`fricsens scaling-one --scene leaf-spring
    /// --refinement R`): R = 3, 63 -> 15; R = 4, 180 -> 57.
    pub active_set_solves: usize,
    /// Shrink the next step by a quarter (to no less than a quarter of the user's increment)
    /// after an increment that took more than this many Newton iterations, as CalculiX and
    /// Abaqus do (their I_L is 10); 0: off, the default. Steps always grow back after an easy
    /// increment (4 iterations or fewer) up to the user's increment, and are halved when an
    /// attempt fails.
    ///
    /// Measured on the physics fuzzer's seeds 0-999 with default settings: 97.8 % of the
    /// scenes complete with 12, 97.7 % without, and the slowest runs are as slow; an increment
    /// that is hard at any size (an active set settling node by node) shrinks the steps to
    /// the floor, and the solution then depends on the iteration counts (the coarse leaf
    /// spring took 18 increments instead of 16 and moved by 1.7e-4 at t = 0.875). Hence off.
    pub shrink_after: usize,
}

impl Default for SolverSettings {
    fn default() -> Self {
        SolverSettings {
            force_tol: 1e-9,
            energy_tol: 1e-20,
            max_iterations: 30,
            max_cutbacks: 10,
            extrapolate: true,
            active_set_solves: 30,
            shrink_after: 0,
        }
    }
}

pub use crate::element::{node_dof, node_dofs, NODE_DOFS};

/// Where each unknown and each history scalar lives, computed from the element families.
///
/// Nodal unknowns come first (three per node), then each body's element-internal unknowns
/// (body after body, element after element), then the contact multipliers, then the
/// translations of rigid targets pushed by a force. History: each
/// assembled element's `n_gauss * history_len` scalars (body after body), then the contact
/// history. Gauss points are numbered flat in element order (`gauss(e)`), the layout of every
/// per-point array (branches, yield ratios).
#[derive(Clone, Debug)]
pub struct DofMap {
    /// Number of nodal unknowns (3 per node).
    pub n_nodal: usize,
    /// First internal unknown of each element (incompatible modes), if any.
    pub element_internal: Vec<Option<usize>>,
    /// Total number of unknowns.
    pub n_total: usize,
    /// Body of each element (`usize::MAX` for an element no body owns: a spring, or not
    /// assembled).
    pub element_body: Vec<usize>,
    /// Spring set of each element (`usize::MAX` for an element of no [`SpringSet`]).
    pub element_springs: Vec<usize>,
    /// Family of each element (`None`: not assembled).
    pub element_family: Vec<Option<ElementFamily>>,
    /// First history scalar of each element (`n_gauss * history_len` per element).
    pub history_offset: Vec<usize>,
    /// Total history length.
    pub n_history: usize,
    /// First contact multiplier (all pairs follow, one per hitting node).
    pub first_lambda: usize,
    /// First translation of a rigid target pushed by a force (one per force-controlled motion
    /// entry, pair after pair, up to `n_total`; [`crate::contact::MotionControl::Force`]).
    pub first_target: usize,
    /// First contact history scalar.
    pub first_contact_history: usize,
    /// History scalars of each element.
    history_len: Vec<usize>,
    /// Element `e`'s unknowns are `dofs[dof_offset[e]..dof_offset[e + 1]]`.
    dof_offset: Vec<usize>,
    /// Global unknowns of every element (nodal, then internal), flat.
    dofs: Vec<usize>,
    /// Element `e`'s Gauss points are `gauss_offset[e]..gauss_offset[e + 1]`.
    gauss_offset: Vec<usize>,
}

impl DofMap {
    /// The global unknown of component `c` of node `n`.
    #[inline]
    pub fn node_dof(&self, n: usize, c: usize) -> usize {
        node_dof(n, c)
    }

    /// The three global unknowns of node `n`.
    #[inline]
    pub fn node_dofs(&self, n: usize) -> std::ops::Range<usize> {
        node_dofs(n)
    }

    /// Global unknowns of element `e` (nodal in node order, then internal; empty for an
    /// element that is not assembled).
    #[inline]
    pub fn element_dofs(&self, e: usize) -> &[usize] {
        &self.dofs[self.dof_offset[e]..self.dof_offset[e + 1]]
    }

    /// Flat numbers of element `e`'s Gauss points (empty when not assembled).
    #[inline]
    pub fn gauss(&self, e: usize) -> std::ops::Range<usize> {
        self.gauss_offset[e]..self.gauss_offset[e + 1]
    }

    /// Number of Gauss points of the model.
    pub fn n_gauss(&self) -> usize {
        self.gauss_offset.last().copied().unwrap_or(0)
    }

    /// The element and its local point of flat Gauss point `i`.
    pub fn gauss_owner(&self, i: usize) -> (usize, usize) {
        let e = self.gauss_offset.partition_point(|&o| o <= i) - 1;
        (e, i - self.gauss_offset[e])
    }

    /// Element `e`'s history scalars.
    #[inline]
    pub fn history(&self, e: usize) -> std::ops::Range<usize> {
        self.history_offset[e]..self.history_offset[e] + self.history_len[e]
    }
}

/// A complete analysis model.
#[derive(Clone, Debug, Default)]
pub struct Model {
    /// Nodes and element groups.
    pub mesh: Mesh,
    /// Deformable bodies (each one element group).
    pub bodies: Vec<Body>,
    /// Linear springs: element groups of the discrete shapes with their stiffness.
    pub springs: Vec<SpringSet>,
    /// Prescribed displacements.
    pub prescribed: Vec<Prescribed>,
    /// Nodal loads.
    pub loads: Vec<NodalLoad>,
    /// Pressure loads on face sets.
    pub pressures: Vec<crate::load::PressureLoad>,
    /// End times of the load increments, increasing.
    pub times: Vec<f64>,
    /// Contact pairs.
    pub contacts: Vec<crate::contact::ContactPair>,
    /// Responses recorded at every increment.
    pub responses: Vec<crate::response::Response>,
    /// Newton-Raphson settings.
    pub solver: SolverSettings,
    /// What building the model chose for the user (defaults derived from the scene, hitting
    /// nodes left out of a pair), one sentence each: `fricsens run` prints them.
    pub notes: Vec<String>,
    /// A material field: `(element, parameter index) -> value` where an element's material
    /// parameter differs from its body's ([`DesignParam::ElementMaterial`]). Empty unless a
    /// design sets one.
    pub element_params: std::collections::BTreeMap<(usize, usize), f64>,
    /// A friction field: `(pair, hitting node index, parameter index) -> value` where a
    /// hitting node's friction-law parameter differs from its pair's
    /// ([`DesignParam::NodeFriction`]). Empty unless a design sets one.
    pub node_friction: std::collections::BTreeMap<(usize, usize, usize), f64>,
}

/// A design parameter: something the responses can be differentiated with respect to.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
#[serde(tag = "kind", rename_all = "kebab-case")]
pub enum DesignParam {
    /// Material parameter number `index` of body `body` (e.g. 0 = E, 1 = nu).
    Material {
        /// Index into [`Model::bodies`].
        body: usize,
        /// Index into the body's [`Material::params`].
        index: usize,
    },
    /// Length of mesh block `block` along `axis` (a shape parameter).
    BlockLength {
        /// Index of the mesh block.
        block: usize,
        /// Axis (0 = x, 1 = y, 2 = z).
        axis: usize,
    },
    /// Origin component of mesh block `block` (a shape parameter).
    BlockOrigin {
        /// Index of the mesh block.
        block: usize,
        /// Axis (0 = x, 1 = y, 2 = z).
        axis: usize,
    },
    /// Magnitude of prescribed displacement number `index`.
    Prescribed {
        /// Index into [`Model::prescribed`].
        index: usize,
    },
    /// Magnitude of nodal load number `index`.
    Load {
        /// Index into [`Model::loads`].
        index: usize,
    },
    /// Friction-law parameter `index` of contact pair `pair` (0 = mu for Coulomb).
    Friction {
        /// Index into [`Model::contacts`].
        pair: usize,
        /// Index into the law's [`crate::contact::Friction::params`].
        index: usize,
    },
    /// Magnitude of motion component `index` of a rigid target of pair `pair`.
    RigidMotion {
        /// Index into [`Model::contacts`].
        pair: usize,
        /// Index into the target's motion components.
        index: usize,
    },
    /// Tangential penalty stiffness of contact pair `pair`.
    TangentialStiffness {
        /// Index into [`Model::contacts`].
        pair: usize,
    },
    /// Value of shape map `map` (a shape parameter of any mesh, [`crate::mesh::shape_map`]).
    Shape {
        /// Index into [`Mesh::shape_maps`].
        map: usize,
    },
    /// Magnitude of pressure load number `index`.
    Pressure {
        /// Index into [`Model::pressures`].
        index: usize,
    },
    /// Material parameter `index` of element `element` alone (a material field: one
    /// parameter per element; its nominal value is its body's).
    ElementMaterial {
        /// Global element number.
        element: usize,
        /// Index into the body's [`Material::params`].
        index: usize,
    },
    /// Friction-law parameter `index` at hitting node `node` of pair `pair` alone (a
    /// friction field along a surface; its nominal value is the pair's).
    NodeFriction {
        /// Index into [`Model::contacts`].
        pair: usize,
        /// Index into the pair's hitting nodes.
        node: usize,
        /// Index into the law's [`crate::contact::Friction::params`].
        index: usize,
    },
    /// Offset of reference coordinate `axis` of node `node` (a nodal shape parameter: the
    /// design velocity of one node in one direction; nominal 0).
    NodeShape {
        /// Node number.
        node: usize,
        /// Axis (0 = x, 1 = y, 2 = z).
        axis: usize,
    },
}

/// Model data lifted to a scalar type, design parameters substituted.
#[derive(Clone, Debug)]
pub struct Lifted<S: Scalar> {
    /// Reference coordinates of every node.
    pub coords: Vec<Vector3<S>>,
    /// Material parameters of every body.
    pub material: Vec<Vec<S>>,
    /// Magnitudes of the prescribed displacements.
    pub prescribed: Vec<S>,
    /// Magnitudes of the nodal loads.
    pub loads: Vec<S>,
    /// Friction-law parameters of each contact pair.
    pub friction: Vec<Vec<S>>,
    /// Rigid-target motion magnitudes of each pair.
    pub rigid_motion: Vec<Vec<S>>,
    /// Tangential penalty stiffness of each pair.
    pub tangential: Vec<S>,
    /// Values of the shape maps.
    pub shape: Vec<S>,
    /// Tributary area of each hitting node of each contact pair at these reference
    /// coordinates (the pair's `area` where it has no faces).
    pub area: Vec<Vec<S>>,
    /// The area each hitting node of each contact pair reads its pressure over, at these
    /// reference coordinates ([`crate::contact::ContactPair::pressure_areas_at`]).
    pub pressure_area: Vec<Vec<S>>,
    /// Magnitudes of the pressure loads.
    pub pressures: Vec<S>,
    /// The elements whose material parameters differ from their body's (a material field),
    /// sorted by element: `(element, body, parameters)`.
    pub element_material: Vec<(usize, usize, Vec<S>)>,
    /// Per pair, the hitting nodes whose friction parameters differ from the pair's (a
    /// friction field), sorted by hitting index: `(node index, parameters)`.
    pub node_friction: Vec<Vec<(usize, Vec<S>)>>,
}

impl<S: Scalar> Lifted<S> {
    /// The material parameters of element `e` of body `b`: its own where a material field
    /// sets them, else its body's.
    #[inline]
    pub fn material_of(&self, b: usize, e: usize) -> &[S] {
        if self.element_material.is_empty() {
            return &self.material[b];
        }
        match self.element_material.binary_search_by_key(&e, |m| m.0) {
            Ok(k) => &self.element_material[k].2,
            Err(_) => &self.material[b],
        }
    }

    /// The friction-law parameters at hitting node `i` of pair `p`: its own where a friction
    /// field sets them, else the pair's.
    #[inline]
    pub fn friction_of(&self, p: usize, i: usize) -> &[S] {
        let own = &self.node_friction[p];
        if own.is_empty() {
            return &self.friction[p];
        }
        match own.binary_search_by_key(&i, |m| m.0) {
            Ok(k) => &own[k].1,
            Err(_) => &self.friction[p],
        }
    }
}

impl Model {
    /// Whether every body's shape takes the body's formulation (a typed error naming the
    /// body otherwise).
    pub fn check_families(&self) -> Result<(), (String, FormulationError)> {
        self.bodies.iter().try_for_each(|b| {
            b.family(&self.mesh)
                .map(|_| ())
                .map_err(|e| (b.name.clone(), e))
        })
    }

    /// Whether every body's material and every contact pair's friction law have admissible
    /// parameter values (a design set from outside the scene file, e.g. from Python).
    pub fn check_laws(&self) -> Result<(), crate::law::ParamError> {
        self.bodies.iter().try_for_each(|b| b.material.check())?;
        (self.contacts.iter())
            .filter_map(|c| c.friction.as_ref())
            .try_for_each(|f| f.check())
    }

    /// Add a linear spring of stiffness `stiffness` (row-major 3x3) between nodes `a` and `b`,
    /// or from `a` to the ground (`b = None`): a group of one `line2` (`point1`) element and
    /// its [`SpringSet`]. Returns the set's index.
    pub fn add_spring(
        &mut self,
        name: &str,
        a: usize,
        b: Option<usize>,
        stiffness: [[f64; 3]; 3],
    ) -> Result<usize, MeshError> {
        let group = match b {
            Some(b) => self.mesh.add_group(Shape::Line2, vec![a, b])?,
            None => self.mesh.add_group(Shape::Point1, vec![a])?,
        };
        self.springs.push(SpringSet {
            name: name.to_string(),
            group,
            stiffness,
        });
        Ok(self.springs.len() - 1)
    }

    /// Every amplitude of the load path: prescribed displacements, nodal loads and the
    /// translations of rigid targets.
    pub fn amplitudes(&self) -> impl Iterator<Item = &Amplitude> {
        let rigid = self.contacts.iter().flat_map(|c| match &c.target {
            crate::contact::Target::Rigid { motion, .. } => motion.as_slice(),
            crate::contact::Target::Faces { .. } => &[],
        });
        self.prescribed
            .iter()
            .map(|p| &p.amplitude)
            .chain(self.loads.iter().map(|l| &l.amplitude))
            .chain(self.pressures.iter().map(|p| &p.amplitude))
            .chain(rigid.map(|m| &m.amplitude))
    }

    /// Whether the load path goes on in a straight line from `[t0, t1]` to `[t1, t2]`: every
    /// amplitude changes over `[t1, t2]` by `(t2 - t1) / (t1 - t0)` times its change over
    /// `[t0, t1]` (to 1e-9 of the larger change). False across a reversal or a kink of any
    /// amplitude, and for `t0 >= t1`.
    pub fn load_path_straight(&self, t0: f64, t1: f64, t2: f64) -> bool {
        if !(t0 < t1 && t1 < t2) {
            return false;
        }
        let ratio = (t2 - t1) / (t1 - t0);
        self.amplitudes().all(|a| {
            let (a0, a1, a2) = (a.at(t0), a.at(t1), a.at(t2));
            let (before, after) = (a1 - a0, a2 - a1);
            (after - ratio * before).abs() <= 1e-9 * before.abs().max(after.abs())
        })
    }

    /// Number the unknowns and the history from the element families.
    pub fn dof_map(&self) -> DofMap {
        let n_nodal = NODE_DOFS * self.mesh.n_nodes();
        let ne = self.mesh.n_elements();
        let mut element_internal = vec![None; ne];
        let mut element_body = vec![usize::MAX; ne];
        let mut element_family = vec![None; ne];
        let mut history_offset = vec![0; ne];
        let mut history_len = vec![0; ne];
        let mut next = n_nodal;
        let mut hist = 0;
        for (b, body) in self.bodies.iter().enumerate() {
            let nh = body.material.history_len();
            // a formulation the shape does not take is refused where the model is made and
            // by `Solver::new` (`Model::check_families`); numbered here as the shape's
            // standard one
            let shape = self.mesh.groups[body.group].shape;
            let family = body
                .family(&self.mesh)
                .unwrap_or(ElementFamily::standard(shape));
            for e in self.mesh.group_elements(body.group) {
                element_body[e] = b;
                element_family[e] = Some(family);
                let ni = family.internal_dofs();
                if ni > 0 {
                    element_internal[e] = Some(next);
                    next += ni;
                }
                history_offset[e] = hist;
                history_len[e] = family.n_gauss() * nh;
                hist += history_len[e];
            }
        }
        let mut element_springs = vec![usize::MAX; ne];
        for (s, set) in self.springs.iter().enumerate() {
            // a discrete shape gives its spring family; a solid one a continuum family, whose
            // evaluation with a stiffness is a typed failure (ElementFailure::Section)
            let shape = self.mesh.groups[set.group].shape;
            let family = ElementFamily::standard(shape);
            for e in self.mesh.group_elements(set.group) {
                element_springs[e] = s;
                element_family[e] = Some(family);
                history_offset[e] = hist;
            }
        }
        let first_lambda = next;
        let first_contact_history = hist;
        for c in &self.contacts {
            next += c.hitting.len();
            hist += c.history_len() * c.hitting.len();
        }
        let first_target = next;
        for c in &self.contacts {
            c.pushed_unknowns(&mut next);
        }
        let mut dof_offset = Vec::with_capacity(ne + 1);
        let mut gauss_offset = Vec::with_capacity(ne + 1);
        let mut dofs = Vec::new();
        dof_offset.push(0);
        gauss_offset.push(0);
        for (e, family) in element_family.iter().enumerate() {
            if let Some(family) = family {
                for &n in self.mesh.element_nodes(e) {
                    dofs.extend(node_dofs(n));
                }
                if let Some(first) = element_internal[e] {
                    dofs.extend(first..first + family.internal_dofs());
                }
            }
            dof_offset.push(dofs.len());
            gauss_offset.push(gauss_offset[e] + family.map_or(0, |f| f.n_gauss()));
        }
        DofMap {
            n_nodal,
            element_internal,
            n_total: next,
            element_body,
            element_springs,
            element_family,
            history_offset,
            n_history: hist,
            first_lambda,
            first_target,
            first_contact_history,
            history_len,
            dof_offset,
            dofs,
            gauss_offset,
        }
    }

    /// Current value of a design parameter.
    pub fn param_value(&self, p: DesignParam) -> Option<f64> {
        match p {
            DesignParam::Material { body, index } => self
                .bodies
                .get(body)
                .and_then(|b| b.material.params().get(index).copied()),
            DesignParam::BlockLength { block, axis } => {
                let b = self.mesh.blocks.get(block)?;
                [&b.x, &b.y, &b.z].get(axis).map(|a| a.length)
            }
            DesignParam::BlockOrigin { block, axis } => {
                self.mesh.blocks.get(block)?.origin.get(axis).copied()
            }
            DesignParam::Prescribed { index } => self.prescribed.get(index).map(|p| p.value),
            DesignParam::Load { index } => self.loads.get(index).map(|l| l.value),
            DesignParam::Shape { map } => self.mesh.shape_maps.get(map).map(|m| m.value),
            DesignParam::Pressure { index } => self.pressures.get(index).map(|p| p.value),
            DesignParam::Friction { pair, index } => self
                .contacts
                .get(pair)?
                .friction
                .as_ref()?
                .params()
                .get(index)
                .copied(),
            DesignParam::RigidMotion { pair, index } => match &self.contacts.get(pair)?.target {
                crate::contact::Target::Rigid { motion, .. } => motion.get(index).map(|m| m.value),
                _ => None,
            },
            DesignParam::TangentialStiffness { pair } => {
                self.contacts.get(pair).map(|c| c.tangential_stiffness)
            }
            DesignParam::ElementMaterial { element, index } => {
                let body = self.element_body(element)?;
                (self.element_params.get(&(element, index)).copied())
                    .or_else(|| self.bodies[body].material.params().get(index).copied())
            }
            DesignParam::NodeFriction { pair, node, index } => {
                let c = self.contacts.get(pair)?;
                c.hitting.get(node)?;
                (self.node_friction.get(&(pair, node, index)).copied())
                    .or_else(|| c.friction.as_ref()?.params().get(index).copied())
            }
            DesignParam::NodeShape { node, axis } => {
                (node < self.mesh.n_nodes() && axis < 3).then(|| {
                    self.mesh
                        .node_moves
                        .get(&(node, axis))
                        .copied()
                        .unwrap_or(0.0)
                })
            }
        }
    }

    /// The body element `e` belongs to (`None` for a spring or an element beyond the mesh).
    pub fn element_body(&self, e: usize) -> Option<usize> {
        (e < self.mesh.n_elements())
            .then(|| {
                (self.bodies.iter()).position(|b| self.mesh.group_elements(b.group).contains(&e))
            })
            .flatten()
    }

    /// A length scale of the model: the diagonal of its reference bounding box.
    pub fn characteristic_length(&self) -> f64 {
        let x = self.mesh.coordinates::<f64>(&self.mesh.block_geometry());
        let mut lo = nalgebra::Vector3::from_element(f64::INFINITY);
        let mut hi = nalgebra::Vector3::from_element(f64::NEG_INFINITY);
        for p in &x {
            lo = lo.inf(p);
            hi = hi.sup(p);
        }
        let d = (hi - lo).norm();
        if d.is_finite() && d > 0.0 {
            d
        } else {
            1.0
        }
    }

    /// Set a design parameter to a new value (for reruns).
    pub fn set_param(&mut self, p: DesignParam, v: f64) {
        match p {
            DesignParam::Material { body, index } => self.bodies[body].material.set_param(index, v),
            DesignParam::BlockLength { block, axis } => {
                let b = &mut self.mesh.blocks[block];
                [&mut b.x, &mut b.y, &mut b.z][axis].length = v;
            }
            DesignParam::BlockOrigin { block, axis } => self.mesh.blocks[block].origin[axis] = v,
            DesignParam::Prescribed { index } => self.prescribed[index].value = v,
            DesignParam::Load { index } => self.loads[index].value = v,
            DesignParam::Shape { map } => self.mesh.shape_maps[map].value = v,
            DesignParam::Pressure { index } => self.pressures[index].value = v,
            DesignParam::Friction { pair, index } => {
                if let Some(f) = self.contacts[pair].friction.as_mut() {
                    f.set_param(index, v)
                }
            }
            DesignParam::RigidMotion { pair, index } => {
                if let crate::contact::Target::Rigid { motion, .. } =
                    &mut self.contacts[pair].target
                {
                    motion[index].value = v;
                }
            }
            DesignParam::TangentialStiffness { pair } => {
                self.contacts[pair].tangential_stiffness = v
            }
            DesignParam::ElementMaterial { element, index } => {
                self.element_params.insert((element, index), v);
            }
            DesignParam::NodeFriction { pair, node, index } => {
                self.node_friction.insert((pair, node, index), v);
            }
            DesignParam::NodeShape { node, axis } => {
                self.mesh.node_moves.insert((node, axis), v);
            }
        }
    }

    /// Lift the model to `S`, replacing the listed design parameters by the given values.
    pub fn lifted<S: Scalar>(&self, overrides: &[(DesignParam, S)]) -> Lifted<S> {
        let mut geometry: Vec<BlockGeometry<S>> = self.mesh.block_geometry();
        let mut material: Vec<Vec<S>> = self
            .bodies
            .iter()
            .map(|b| b.material.params().iter().map(|v| S::lift(*v)).collect())
            .collect();
        let mut prescribed: Vec<S> = self.prescribed.iter().map(|p| S::lift(p.value)).collect();
        let mut loads: Vec<S> = self.loads.iter().map(|l| S::lift(l.value)).collect();
        let mut shape: Vec<S> = (self.mesh.shape_maps.iter())
            .map(|m| S::lift(m.value))
            .collect();
        let mut pressures: Vec<S> = self.pressures.iter().map(|p| S::lift(p.value)).collect();
        let mut friction: Vec<Vec<S>> = self
            .contacts
            .iter()
            .map(|c| match &c.friction {
                Some(f) => f.params().iter().map(|v| S::lift(*v)).collect(),
                None => Vec::new(),
            })
            .collect();
        let mut rigid_motion: Vec<Vec<S>> = self
            .contacts
            .iter()
            .map(|c| match &c.target {
                crate::contact::Target::Rigid { motion, .. } => {
                    motion.iter().map(|m| S::lift(m.value)).collect()
                }
                _ => Vec::new(),
            })
            .collect();
        let mut tangential: Vec<S> = self
            .contacts
            .iter()
            .map(|c| S::lift(c.tangential_stiffness))
            .collect();
        let mut element_own: Vec<(usize, usize, S)> = (self.element_params.iter())
            .map(|(&(e, i), v)| (e, i, S::lift(*v)))
            .collect();
        let mut node_own: Vec<(usize, usize, usize, S)> = (self.node_friction.iter())
            .map(|(&(p, n, i), v)| (p, n, i, S::lift(*v)))
            .collect();
        let mut moves: Vec<(usize, usize, S)> = Vec::new();
        for (p, v) in overrides {
            match *p {
                // after the model's own values: the later of two equal keys wins below
                DesignParam::ElementMaterial { element, index } => {
                    element_own.push((element, index, *v))
                }
                DesignParam::NodeFriction { pair, node, index } => {
                    node_own.push((pair, node, index, *v))
                }
                DesignParam::NodeShape { node, axis } => {
                    // the coordinates below hold the nominal offset: add the change
                    let nominal = self.mesh.node_moves.get(&(node, axis)).copied();
                    moves.push((node, axis, *v - S::lift(nominal.unwrap_or(0.0))));
                }
                DesignParam::Material { body, index } => material[body][index] = *v,
                DesignParam::BlockLength { block, axis } => geometry[block].lengths[axis] = *v,
                DesignParam::BlockOrigin { block, axis } => geometry[block].origin[axis] = *v,
                DesignParam::Prescribed { index } => prescribed[index] = *v,
                DesignParam::Load { index } => loads[index] = *v,
                DesignParam::Friction { pair, index } => friction[pair][index] = *v,
                DesignParam::RigidMotion { pair, index } => rigid_motion[pair][index] = *v,
                DesignParam::TangentialStiffness { pair } => tangential[pair] = *v,
                DesignParam::Shape { map } => shape[map] = *v,
                DesignParam::Pressure { index } => pressures[index] = *v,
            }
        }
        let mut coords = self.mesh.coordinates_at(&geometry, &shape);
        for (node, axis, dv) in moves {
            coords[node][axis] += dv;
        }
        // the fields: each element's (hitting node's) whole parameter vector, its body's
        // (pair's) with its own values in place
        // stable: equal keys keep their order, and the last written is the one that holds
        element_own.sort_by_key(|m| m.0);
        let mut element_material: Vec<(usize, usize, Vec<S>)> = Vec::new();
        for (e, i, v) in element_own {
            if element_material.last().is_none_or(|m| m.0 != e) {
                let b = self
                    .element_body(e)
                    .expect("a material field on a body's element");
                element_material.push((e, b, material[b].clone()));
            }
            element_material.last_mut().expect("pushed").2[i] = v;
        }
        node_own.sort_by_key(|m| (m.0, m.1));
        let mut node_friction: Vec<Vec<(usize, Vec<S>)>> = vec![Vec::new(); self.contacts.len()];
        for (p, n, i, v) in node_own {
            let own = &mut node_friction[p];
            if own.last().is_none_or(|m| m.0 != n) {
                own.push((n, friction[p].clone()));
            }
            own.last_mut().expect("pushed").1[i] = v;
        }
        let area: Vec<Vec<S>> = (self.contacts.iter())
            .map(|c| match &c.hitting_faces {
                Some(faces) => faces.tributary_areas(&coords, &c.hitting),
                None => c.area.iter().map(|a| S::lift(*a)).collect(),
            })
            .collect();
        // equal to the tributary areas, bit for bit, on linear faces
        let pressure_area = (self.contacts.iter().zip(&area))
            .map(|(c, a)| match &c.hitting_faces {
                Some(faces) if faces.has_quadratic() => c.pressure_areas_at(|n| coords[n]),
                _ => a.clone(),
            })
            .collect();
        Lifted {
            coords,
            area,
            pressure_area,
            shape,
            pressures,
            material,
            prescribed,
            loads,
            friction,
            rigid_motion,
            tangential,
            element_material,
            node_friction,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn model_with(amplitudes: &[Vec<(f64, f64)>]) -> Model {
        Model {
            prescribed: amplitudes
                .iter()
                .map(|points| Prescribed {
                    name: "p".into(),
                    nodes: vec![],
                    component: 0,
                    value: 1.0,
                    amplitude: Amplitude {
                        points: points.clone(),
                    },
                })
                .collect(),
            ..Model::default()
        }
    }

    #[test]
    fn a_straight_load_path_is_told_from_a_kink_or_a_reversal() {
        // load 0 -> 1 -> 0 (reversal at t = 1), and a hold from t = 2
        let m = model_with(&[
            vec![(0.0, 0.0), (1.0, 1.0), (2.0, 0.0)],
            vec![(0.0, 0.0), (2.0, 2.0)],
        ]);
        assert!(m.load_path_straight(0.1, 0.2, 0.3));
        // unequal steps on one segment
        assert!(m.load_path_straight(0.1, 0.2, 0.45));
        assert!(m.load_path_straight(1.1, 1.3, 1.4));
        // across the reversal of the first amplitude
        assert!(!m.load_path_straight(0.8, 0.9, 1.1));
        // the step that ends at the kink is still straight, the next one is not
        assert!(m.load_path_straight(0.8, 0.9, 1.0));
        assert!(!m.load_path_straight(0.9, 1.0, 1.1));
        // past the end of both amplitudes: constant, the first after a ramp is a kink
        assert!(!m.load_path_straight(1.9, 2.0, 2.1));
        assert!(m.load_path_straight(2.1, 2.2, 2.3));
        // degenerate times
        assert!(!m.load_path_straight(0.2, 0.2, 0.3));
        assert!(!m.load_path_straight(f64::NAN, 0.2, 0.3));
        // no amplitude at all: nothing bends
        assert!(Model::default().load_path_straight(0.0, 1.0, 5.0));
    }
}
