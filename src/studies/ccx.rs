//! CalculiX (`ccx`) as a peer: export a [`Model`] as a CalculiX input deck, run it, read its
//! reaction forces (or displacements) back, and compare it with fricsens — cost of the primal,
//! force histories, and the peer's own finite-difference sensitivity (two reruns) against
//! fricsens' DDM.
//!
//! *Why one file of over 2,000 lines:* the deck writer and the reader of ccx's `.dat` output are
//! the two directions of one format and change together; the comparison they serve is the rest.
//!
//! ## The deck
//! * nodes and solid elements one for one (fricsens node `i` is CalculiX node `i + 1`, node
//!   order as it is: CalculiX numbers as Abaqus, as fricsens does); the element type follows
//!   the body's family: hex8 full (2x2x2 Gauss points) is `C3D8`, hex8 incompatible modes
//!   `C3D8I` (CalculiX's incompatible modes after Taylor, the same family as fricsens' nine
//!   Wilson-Taylor modes), hex20 `C3D20` / `C3D20R` (reduced), tet4 `C3D4`, tet10 `C3D10`
//!   (4 points), wedge6 `C3D6`, wedge15 `C3D15`. F-bar and tet10's 14-point rule have no
//!   CalculiX counterpart and are refused. Small kinematics leaves `NLGEOM` off, large
//!   kinematics sets it (CalculiX's `*ELASTIC` under `NLGEOM` is St Venant-Kirchhoff).
//! * St Venant-Kirchhoff materials as `*ELASTIC`; J2 plasticity and Neo-Hookean are refused.
//! * prescribed displacements as `*BOUNDARY` on node sets, nodal loads as `*CLOAD`, each with
//!   its amplitude written as `*AMPLITUDE, TIME=TOTAL TIME`; pressure loads as `*CLOAD` too,
//!   with fricsens' consistent nodal forces on the reference faces (fricsens' pressure is a
//!   dead load; CalculiX's `*DLOAD` would follow the deformed faces under `NLGEOM`);
//! * the load history as one `*STATIC, DIRECT` step per run of equal increments, so CalculiX
//!   takes exactly fricsens' increments (`DIRECT` switches its automatic incrementation off);
//! * `*CONTROLS` with fricsens' force tolerance as CalculiX's residual and correction ratios,
//!   fricsens' iteration limit as its iteration limit, and no cutback (see
//!   [`ExportOptions`]);
//! * contact: the slave surface is made of the free element faces all of whose nodes (corners
//!   and, on a quadratic element, mid-sides) are hitting nodes (a nodal surface if they do not
//!   cover the hitting nodes), the master of the target faces (quad4 faces only), each an
//!   element face `(element, Sn)` (the Abaqus sides of the element's shape, which the importer
//!   reads; faces found by their sorted corner nodes) on the target body's boundary, so that
//!   CalculiX takes its outward normal.
//!   - A rigid target is node-to-face penalty contact (`TYPE=NODE TO SURFACE`, large
//!     sliding). A [`RigidSurface::RoundedBox`] is meshed: its side facing the hitting nodes
//!     (the flat face, its two rounded edges and one radius of the adjacent faces), extruded
//!     along z over the hitting nodes' extent, one layer of `C3D8` elements made a
//!     `*RIGID BODY` whose reference node carries the prescribed motion (a `*BOUNDARY`, or a
//!     `*CLOAD` for a target pushed by a force) and whose `RF` is the force on the block.
//!     Other rigid surfaces are refused.
//!   - Faces of a deformable body ([`Target::Faces`]) are surface-to-surface penalty contact
//!     (`TYPE=SURFACE TO SURFACE`). Node to surface would be the closer image of fricsens'
//!     node-to-segment contact (a hitting node against the target facets), but it does not
//!     solve these scenes: on the punch (`meshes/punch-on-slab.toml`) and on Hertz's two
//!     cylinders its contact set chatters from the first increment and CalculiX stops
//!     diverging, on the punch even with automatic incrementation (it stalls at 62 % of the
//!     press), presumably because the slave nodes of a one-element-thick plane-strain mesh lie
//!     on the edges of the master surface, where the projection of a node is found or lost by
//!     round-off. Surface to surface checks the slave faces' integration points, which lie
//!     inside the faces, and solves both with fricsens' increments. Both discretize the same
//!     contact; they differ in where the gap is measured (nodes against facets, or
//!     integration points against facets), an O(h^2 / R) difference on curved surfaces that
//!     the report discusses. Hitting nodes that do not make whole faces stay node to surface.
//!   - A body that no prescribed displacement holds in some direction (the loaded cylinder of
//!     Hertz, a block under pressure) is carried by contact alone. fricsens' multipliers
//!     activate a closed node at the first iteration; CalculiX's surface-to-surface penalty
//!     has no contact element until an integration point penetrates, and the body floats. Such
//!     a pair gets `ADJUST = adjust_fraction * sqrt(A)`: slave nodes within that distance of
//!     the master are moved onto it at the start (on Hertz, 7.2e-5 mm: the first ring of nodes
//!     beside the line of first contact, whose gap is 2.8e-5 mm).
//! * normal contact `PRESSURE-OVERCLOSURE=LINEAR` with slope `K = factor * k / A` (`k` the
//!   pair's constraint scale, force per unit gap, `A` the median tributary area of the
//!   hitting nodes; node to surface also takes the tension at large clearance), Coulomb
//!   friction `*FRICTION` with `mu` and the stick slope `eps_T / A` (fricsens' tangential
//!   stiffness per unit area), the same for both kinds of pair.
//! * output: the rigid bodies' reference nodes (`RF, U`), and the node set of every reaction
//!   response (`*NODE PRINT, TOTALS=ONLY`: CalculiX sums the reactions before printing them to
//!   7 digits) and of every displacement response (each node's `U`).
//!
//! CalculiX's contact is a penalty (the bodies overlap by `p / K`), fricsens' a Lagrange
//! multiplier (no overlap): the force histories differ by about the overlap over the
//! indentation, which the report states.
//!
//! ## What is compared
//! * A scene with a rigid contact target: the force on it (its target-force responses against
//!   minus `RF` at the rigid body's reference node) and its derivative in the pair's friction
//!   coefficient.
//! * A scene whose contact pairs are between deformable bodies: every reaction response (the
//!   sum of the reactions of a node set in one component, against the set's total `RF`) and
//!   every displacement response (a node set's mean displacement, against the mean of its
//!   `U`); a scene with neither gets the mean displacement of each nodal load's nodes and the
//!   reaction of each nonzero prescribed displacement. The parameter is the friction
//!   coefficient of the first pair with Coulomb friction; in a frictionless scene, where
//!   d/d mu is zero in both codes, the Young's modulus of the first body (CalculiX's reruns
//!   change its `*ELASTIC`; nothing else in the deck depends on it). The report flags the
//!   increments where CalculiX's two reruns leave the nominal run's branch
//!   ([`Comparison::off_branch`]): there the difference quotient measures a jump. A rerun
//!   that stops early leaves the quotient NaN from there on and the report says why (the
//!   rigid case still fails). On the punch the mu (1 + beta) rerun converges to another state
//!   at its last two increments, and with two threads it diverged at the last one in one run
//!   of six (with one thread, three runs printed the same digits).

use crate::contact::geometry::RigidSurface;
use crate::contact::{ContactPair, Friction, Target};
use crate::element::Kinematics;
use crate::model::{Amplitude, DesignParam, Material, Model};
use crate::response::ResponseKind;
use crate::sensitivity::{run_sensitivity, Method, Parameter, Settings};
use crate::solver::{NoObserver, RunOptions, Solver};
use nalgebra::Vector3;
use std::collections::{BTreeMap, HashMap, HashSet};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

// Reals are written with `{:.12e}`: CalculiX reads a real from at most 20 characters, and 13
// significant digits with sign and exponent fit.

/// Errors of the export, of a CalculiX run and of the comparison.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum CcxError {
    /// The model uses something the exporter cannot write as CalculiX input.
    #[error("cannot export to CalculiX: {0}")]
    Unsupported(String),
    /// An option is out of range.
    #[error("invalid option: {0}")]
    Option(String),
    /// A file could not be written or read.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: String,
        /// What went wrong.
        #[source]
        source: std::io::Error,
    },
    /// CalculiX could not be started, stopped with an error or did not converge.
    #[error("ccx {job}: {what}")]
    Run {
        /// Job name.
        job: String,
        /// What went wrong, with the end of CalculiX's output.
        what: String,
    },
    /// The `.dat` file does not hold the expected reaction forces.
    #[error("{path}: {what}")]
    Parse {
        /// The `.dat` file.
        path: String,
        /// What is missing or malformed.
        what: String,
    },
    /// fricsens' own analysis failed.
    #[error("fricsens: {0}")]
    Analysis(#[from] crate::solver::AnalysisError),
    /// A figure could not be drawn.
    #[error("figure: {0}")]
    Plot(#[from] crate::studies::plot::PlotError),
}

fn io_err(path: &Path) -> impl FnOnce(std::io::Error) -> CcxError + '_ {
    move |source| CcxError::Io {
        path: path.display().to_string(),
        source,
    }
}

/// How the contact and the rigid targets are translated.
#[derive(Clone, Debug)]
pub struct ExportOptions {
    /// Normal penalty slope `K = normal_factor * k / A` (pressure per unit overlap), with `k`
    /// the pair's constraint scale (force per unit gap) and `A` the median tributary area of
    /// its hitting nodes.
    pub normal_factor: f64,
    /// CalculiX's tension at large clearance `sigma_inf` as a fraction of the largest Young's
    /// modulus (it sets the smoothing length `pi sigma_inf / K` of the penalty's kink).
    pub tension_fraction: f64,
    /// Facets per quarter circle on a rounded edge of a rigid box.
    pub arc_segments: usize,
    /// Facets along the flat face of a rigid box.
    pub flat_segments: usize,
    /// `ADJUST` distance of a face-to-face pair over the square root of its median tributary
    /// area, written only when the pair touches a body that no prescribed displacement holds
    /// in some direction (see [`export`]'s documentation).
    pub adjust_fraction: f64,
}

impl Default for ExportOptions {
    fn default() -> Self {
        ExportOptions {
            normal_factor: 10.0,
            tension_fraction: 1e-6,
            arc_segments: 32,
            flat_segments: 6,
            adjust_fraction: 5e-3,
        }
    }
}

/// A written deck and what it is made of.
#[derive(Clone, Debug)]
pub struct Deck {
    /// The input deck.
    pub text: String,
    /// Nodes written (model nodes, rigid-body nodes, reference and rotation nodes).
    pub nodes: usize,
    /// Elements written (model elements and rigid-body elements).
    pub elements: usize,
    /// CalculiX element type of each body.
    pub element_types: Vec<&'static str>,
    /// Whether `NLGEOM` is set.
    pub nlgeom: bool,
    /// Reference node of each contact pair's rigid body (`None`: deformable target).
    pub reference_nodes: Vec<Option<usize>>,
    /// Normal penalty slope of each pair (force / length^3).
    pub normal_stiffness: Vec<f64>,
    /// Tension at large clearance of each pair (stress).
    pub tension: Vec<f64>,
    /// Stick slope of each frictional pair (force / length^3; 0 when frictionless).
    pub stick_slope: Vec<f64>,
    /// Median tributary area of each pair's hitting nodes.
    pub median_area: Vec<f64>,
    /// `ADJUST` distance of each pair (0: none; see [`ExportOptions::adjust_fraction`]).
    pub adjust: Vec<f64>,
    /// Responses whose node set is printed (set [`response_set`]`(k)`): every reaction
    /// response (its total `RF`) and every displacement response (each node's `U`).
    pub printed: Vec<usize>,
    /// End time of every increment CalculiX is told to take.
    pub times: Vec<f64>,
}

// CalculiX sides S1.. of an element of any solid shape: the Abaqus sides the importer reads,
// each the face of `Shape::faces` with the side's corners
use crate::mesh::import::{abaqus_sides, face_of_side};

/// A face by its sorted corner nodes (three or four), padded with `usize::MAX`.
type CornerKey = [usize; 4];

fn corner_key(corners: &[usize]) -> CornerKey {
    let mut k = [usize::MAX; 4];
    for (slot, &n) in k.iter_mut().zip(corners) {
        *slot = n;
    }
    k.sort_unstable();
    k
}

/// Write lists of integers, 16 a line (CalculiX reads at most 16 entries per set line).
fn write_ids(s: &mut String, ids: impl IntoIterator<Item = usize>) {
    let ids: Vec<usize> = ids.into_iter().collect();
    for chunk in ids.chunks(16) {
        let line: Vec<String> = chunk.iter().map(|i| i.to_string()).collect();
        let _ = writeln!(s, "{},", line.join(","));
    }
}

fn write_amplitude(s: &mut String, name: &str, a: &Amplitude) {
    let _ = writeln!(s, "*AMPLITUDE,NAME={name},TIME=TOTAL TIME");
    for (t, v) in &a.points {
        let _ = writeln!(s, "{t:.12e},{v:.12e}");
    }
}

fn median(v: &[f64]) -> f64 {
    let mut w: Vec<f64> = v.iter().copied().filter(|x| x.is_finite()).collect();
    if w.is_empty() {
        return 1.0;
    }
    w.sort_by(f64::total_cmp);
    w[w.len() / 2]
}

/// Outer profile (x, y) of the lower side of a rounded box and its outward normals, from the
/// left side down over the left rounded edge, along the bottom, up over the right edge.
fn box_profile(
    c: &Vector3<f64>,
    h: &Vector3<f64>,
    r: f64,
    opts: &ExportOptions,
) -> Vec<([f64; 2], [f64; 2])> {
    let (x0, x1, y0) = (c.x - h.x, c.x + h.x, c.y - h.y);
    let side = if r > 0.0 { r } else { 0.1 * h.y.min(h.x) };
    let mut p: Vec<([f64; 2], [f64; 2])> = Vec::new();
    p.push(([x0, y0 + r + side], [-1.0, 0.0]));
    let na = opts.arc_segments.max(1);
    let quarter = std::f64::consts::FRAC_PI_2;
    if r > 0.0 {
        // left edge: angle from pi (pointing -x) to 3 pi / 2 (pointing -y)
        for k in 0..=na {
            let a = std::f64::consts::PI + quarter * k as f64 / na as f64;
            let n = [a.cos(), a.sin()];
            p.push(([x0 + r + r * n[0], y0 + r + r * n[1]], n));
        }
    } else {
        let s = std::f64::consts::FRAC_1_SQRT_2;
        p.push(([x0, y0], [-s, -s]));
    }
    let nf = opts.flat_segments.max(1);
    for k in 1..nf {
        let x = x0 + r + (x1 - x0 - 2.0 * r) * k as f64 / nf as f64;
        p.push(([x, y0], [0.0, -1.0]));
    }
    if r > 0.0 {
        for k in 0..=na {
            let a = 1.5 * std::f64::consts::PI + quarter * k as f64 / na as f64;
            let n = [a.cos(), a.sin()];
            p.push(([x1 - r + r * n[0], y0 + r + r * n[1]], n));
        }
    } else {
        let s = std::f64::consts::FRAC_1_SQRT_2;
        p.push(([x1, y0], [s, -s]));
    }
    p.push(([x1, y0 + r + side], [1.0, 0.0]));
    p
}

/// Write `model` as a CalculiX input deck.
///
/// # Errors
/// [`CcxError::Unsupported`] for what is not translated (naming the body or pair): F-bar
/// elements, J2 plasticity, Neo-Hookean, springs, friction laws other than Coulomb, rigid
/// surfaces other than a rounded box with the hitting nodes below it, target faces that are
/// not boundary faces of an element; [`CcxError::Option`] for out-of-range options.
pub fn export(model: &Model, opts: &ExportOptions) -> Result<Deck, CcxError> {
    if !(opts.normal_factor.is_finite() && opts.normal_factor > 0.0) {
        return Err(CcxError::Option(format!(
            "normal_factor must be positive, got {}",
            opts.normal_factor
        )));
    }
    if !(opts.tension_fraction.is_finite() && opts.tension_fraction > 0.0) {
        return Err(CcxError::Option(format!(
            "tension_fraction must be positive, got {}",
            opts.tension_fraction
        )));
    }
    if !model.springs.is_empty() {
        return Err(CcxError::Unsupported("springs".into()));
    }
    if model.times.is_empty() {
        return Err(CcxError::Unsupported("no load increment".into()));
    }
    let x = model.mesh.coordinates::<f64>(&model.mesh.block_geometry());
    let mut s = String::new();
    let _ = writeln!(s, "** written by fricsens {}", env!("CARGO_PKG_VERSION"));
    let _ = writeln!(s, "*HEADING");
    let _ = writeln!(s, "fricsens model exported for CalculiX");
    let _ = writeln!(s, "*NODE,NSET=NALL");
    for (i, p) in x.iter().enumerate() {
        let _ = writeln!(s, "{},{:.12e},{:.12e},{:.12e}", i + 1, p.x, p.y, p.z);
    }
    let mut next_node = x.len() + 1;
    let mut next_elem = model.mesh.n_elements() + 1;
    if let Some(g) = model.mesh.groups.iter().find(|g| !g.shape.is_solid()) {
        return Err(CcxError::Unsupported(format!(
            "{} elements have no CalculiX export yet",
            g.shape.name()
        )));
    }
    let mut element_types = Vec::new();
    let mut nlgeom = false;
    let mut young_max: f64 = 0.0;
    for (b, body) in model.bodies.iter().enumerate() {
        let family = body
            .family(&model.mesh)
            .map_err(|e| CcxError::Unsupported(format!("body '{}': {e}", body.name)))?;
        let ty = calculix_element(family).ok_or_else(|| {
            CcxError::Unsupported(format!(
                "body '{}': {} has no CalculiX element",
                body.name,
                family.name()
            ))
        })?;
        nlgeom |= body.kinematics == Kinematics::Large;
        element_types.push(ty);
        let _ = writeln!(s, "*ELEMENT,TYPE={ty},ELSET=B{b}");
        for e in model.mesh.group_elements(body.group) {
            let c = model.mesh.element_nodes(e);
            // a quadratic element's 20 nodes on continuation lines (CalculiX refuses a line
            // of more than 16 entries)
            let line = crate::mesh::abaqus::element_line(e + 1, c.iter().map(|n| n + 1), ",");
            let _ = writeln!(s, "{line}");
        }
        match &body.material {
            Material::Svk(_) => {
                young_max = young_max.max(body.material.young());
            }
            Material::J2(_) => {
                return Err(CcxError::Unsupported(format!(
                    "body '{}': J2 plasticity is not exported",
                    body.name
                )))
            }
            Material::NeoHookean(_) => {
                return Err(CcxError::Unsupported(format!(
                    "body '{}': the Neo-Hookean material is not exported",
                    body.name
                )))
            }
            // a material registered later is not exported until this function learns it
            #[allow(unreachable_patterns)]
            other => {
                return Err(CcxError::Unsupported(format!(
                    "body '{}': material '{}' is not exported",
                    body.name,
                    other.name()
                )))
            }
        }
    }
    // every face of every element by its sorted corners, to find the free faces and their
    // CalculiX sides: (element, side 1.., the face's local nodes, corners and mid-sides)
    type Side = (usize, usize, &'static [usize]);
    let mut face_of: HashMap<CornerKey, Vec<Side>> = HashMap::new();
    for (e, (shape, c)) in model.mesh.elements().enumerate() {
        for side in 1..=abaqus_sides(shape).len() {
            let Some(f) = face_of_side(shape, side) else {
                continue;
            };
            let face = &shape.faces()[f];
            let corners: Vec<usize> = face.nodes[..face.family.n_corners()]
                .iter()
                .map(|&l| c[l])
                .collect();
            face_of
                .entry(corner_key(&corners))
                .or_default()
                .push((e, side, face.nodes));
        }
    }
    let mut contact_text = String::new();
    let mut rigid_text = String::new();
    let mut step_bc = String::new();
    let mut reference_nodes = Vec::new();
    let (mut normal_stiffness, mut tension, mut stick_slope, mut median_area, mut adjust) =
        (Vec::new(), Vec::new(), Vec::new(), Vec::new(), Vec::new());
    let mut node_print = Vec::new();
    for (ci, pair) in model.contacts.iter().enumerate() {
        let a_med = median(&pair.area);
        let k_n = opts.normal_factor * pair.constraint_scale / a_med;
        let sig_inf = opts.tension_fraction * young_max.max(f64::MIN_POSITIVE);
        median_area.push(a_med);
        normal_stiffness.push(k_n);
        // slave surface: free faces all of whose nodes (corners and mid-sides) are hitting
        // nodes
        let hitting: HashSet<usize> = pair.hitting.iter().copied().collect();
        let face_nodes = |&(e, _, local): &Side| {
            let c = model.mesh.element_nodes(e);
            local.iter().map(move |&l| c[l])
        };
        let mut slave: Vec<Side> = face_of
            .values()
            .filter(|owners| {
                owners.len() == 1 && face_nodes(&owners[0]).all(|n| hitting.contains(&n))
            })
            .map(|owners| owners[0])
            .collect();
        slave.sort_unstable();
        let covered: HashSet<usize> = slave.iter().flat_map(face_nodes).collect();
        let element_slave = !slave.is_empty() && covered.len() == hitting.len();
        // face to face between deformable bodies: surface to surface (it needs an element-face
        // slave surface; hitting nodes that are not whole faces stay node to surface)
        let faces_target = matches!(pair.target, Target::Faces { .. }) && element_slave;
        // CalculiX's surface-to-surface contact has no tension at large clearance
        tension.push(if faces_target { 0.0 } else { sig_inf });
        if element_slave {
            let _ = writeln!(contact_text, "*SURFACE,NAME=SLAVE{ci},TYPE=ELEMENT");
            for (e, side, _) in &slave {
                let _ = writeln!(contact_text, "{},S{side}", e + 1);
            }
        } else {
            let _ = writeln!(contact_text, "*NSET,NSET=NSLAVE{ci}");
            write_ids(&mut contact_text, pair.hitting.iter().map(|n| n + 1));
            let _ = writeln!(contact_text, "*SURFACE,NAME=SLAVE{ci},TYPE=NODE");
            let _ = writeln!(contact_text, "NSLAVE{ci}");
        }
        let _ = writeln!(contact_text, "*SURFACE,NAME=MASTER{ci},TYPE=ELEMENT");
        match &pair.target {
            Target::Faces { faces } => {
                for k in 0..faces.len() {
                    let family = faces.face(k).family;
                    if family != crate::element::FaceFamily::Quad4 {
                        return Err(CcxError::Unsupported(format!(
                            "pair '{}': target face {k} is a {} face; only quad4 target faces \
                             are exported",
                            pair.name,
                            family.name()
                        )));
                    }
                    let f = &crate::contact::quad_nodes(faces, k);
                    let owners = face_of.get(&corner_key(f)).ok_or_else(|| {
                        CcxError::Unsupported(format!(
                            "pair '{}': target face {k} (nodes {f:?}) is not an element face",
                            pair.name
                        ))
                    })?;
                    let &[(e, side, _)] = owners.as_slice() else {
                        return Err(CcxError::Unsupported(format!(
                            "pair '{}': target face {k} (nodes {f:?}) is shared by {} elements, \
                             not a boundary face",
                            pair.name,
                            owners.len()
                        )));
                    };
                    let _ = writeln!(contact_text, "{},S{side}", e + 1);
                }
                reference_nodes.push(None);
            }
            Target::Rigid { surface, motion } => {
                let RigidSurface::RoundedBox {
                    center,
                    half_extents,
                    radius,
                } = surface
                else {
                    return Err(CcxError::Unsupported(format!(
                        "pair '{}': only a rigid rounded box is meshed for CalculiX",
                        pair.name
                    )));
                };
                let bottom = center.y - half_extents.y;
                if pair
                    .hitting
                    .iter()
                    .any(|&n| x[n].y > bottom + 1e-9 * half_extents.y)
                {
                    return Err(CcxError::Unsupported(format!(
                        "pair '{}': the hitting nodes must lie below the rigid box (its -y face is meshed)",
                        pair.name
                    )));
                }
                let (zlo, zhi) = pair
                    .hitting
                    .iter()
                    .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &n| {
                        (a.min(x[n].z), b.max(x[n].z))
                    });
                let margin = if zhi > zlo { zhi - zlo } else { 1.0 };
                let z0 = (center.z - half_extents.z).max(zlo - margin);
                let z1 = (center.z + half_extents.z).min(zhi + margin);
                let profile = box_profile(center, half_extents, *radius, opts);
                let t = if *radius > 0.0 {
                    0.5 * radius
                } else {
                    0.05 * half_extents.x.min(half_extents.y)
                };
                // nodes: outer and inner profile points at z0 and z1
                let first = next_node;
                let np = profile.len();
                let id = |i: usize, inner: usize, top: usize| first + i + np * (inner + 2 * top);
                let _ = writeln!(rigid_text, "*NODE,NSET=NRIGID{ci}");
                for (top, z) in [z0, z1].iter().enumerate() {
                    for inner in 0..2 {
                        for (i, (p, n)) in profile.iter().enumerate() {
                            let off = if inner == 1 { t } else { 0.0 };
                            let _ = writeln!(
                                rigid_text,
                                "{},{:.12e},{:.12e},{:.12e}",
                                id(i, inner, top),
                                p[0] - off * n[0],
                                p[1] - off * n[1],
                                z
                            );
                        }
                    }
                }
                next_node += 4 * np;
                let reference = next_node;
                let rotation = next_node + 1;
                next_node += 2;
                let _ = writeln!(
                    rigid_text,
                    "{reference},{:.12e},{:.12e},{:.12e}\n{rotation},{:.12e},{:.12e},{:.12e}",
                    center.x, center.y, center.z, center.x, center.y, center.z
                );
                let _ = writeln!(rigid_text, "*NSET,NSET=REF{ci}\n{reference},");
                let _ = writeln!(rigid_text, "*NSET,NSET=ROT{ci}\n{rotation},");
                let _ = writeln!(rigid_text, "*ELEMENT,TYPE=C3D8,ELSET=RIGID{ci}");
                for i in 0..np - 1 {
                    let nodes = [
                        id(i, 0, 0),
                        id(i + 1, 0, 0),
                        id(i + 1, 1, 0),
                        id(i, 1, 0),
                        id(i, 0, 1),
                        id(i + 1, 0, 1),
                        id(i + 1, 1, 1),
                        id(i, 1, 1),
                    ];
                    let ids: Vec<String> = nodes.iter().map(|n| n.to_string()).collect();
                    let _ = writeln!(rigid_text, "{},{}", next_elem, ids.join(","));
                    // the outer face (nodes 1, 2, 6, 5) is S3
                    let _ = writeln!(contact_text, "{next_elem},S3");
                    next_elem += 1;
                }
                let _ = writeln!(
                    rigid_text,
                    "*SOLID SECTION,ELSET=RIGID{ci},MATERIAL=M0\n*RIGID BODY,ELSET=RIGID{ci},REF NODE={reference},ROT NODE={rotation}"
                );
                // motion of the reference node; components without motion are held
                let _ = writeln!(step_bc, "*BOUNDARY\nROT{ci},1,3,0.");
                for comp in 0..3 {
                    match motion.iter().find(|m| m.component == comp) {
                        Some(m) => {
                            let amp = format!("AM{ci}_{comp}");
                            write_amplitude(&mut rigid_text, &amp, &m.amplitude);
                            let (c, v) = (comp + 1, m.value);
                            let _ = match m.control {
                                crate::contact::MotionControl::Displacement => writeln!(
                                    step_bc,
                                    "*BOUNDARY,AMPLITUDE={amp}\nREF{ci},{c},{c},{v:.12e}"
                                ),
                                // a pushed target: the force on its reference node
                                crate::contact::MotionControl::Force => writeln!(
                                    step_bc,
                                    "*CLOAD,AMPLITUDE={amp}\nREF{ci},{c},{v:.12e}"
                                ),
                            };
                        }
                        None => {
                            let _ =
                                writeln!(step_bc, "*BOUNDARY\nREF{ci},{c},{c},0.", c = comp + 1);
                        }
                    }
                }
                node_print.push(format!("*NODE PRINT,NSET=REF{ci}\nRF,U"));
                reference_nodes.push(Some(reference));
            }
        }
        let _ = writeln!(contact_text, "*SURFACE INTERACTION,NAME=SI{ci}");
        if faces_target {
            // surface to surface: no tension at large clearance
            let _ = writeln!(
                contact_text,
                "*SURFACE BEHAVIOR,PRESSURE-OVERCLOSURE=LINEAR\n{k_n:.9e}"
            );
        } else {
            let _ = writeln!(
                contact_text,
                "*SURFACE BEHAVIOR,PRESSURE-OVERCLOSURE=LINEAR\n{k_n:.9e},{sig_inf:.9e}"
            );
        }
        match &pair.friction {
            None => stick_slope.push(0.0),
            Some(f @ Friction::Coulomb(_)) => {
                let lambda = pair.tangential_stiffness / a_med;
                stick_slope.push(lambda);
                let _ = writeln!(
                    contact_text,
                    "*FRICTION\n{:.12e},{lambda:.9e}",
                    f.params()[0]
                );
            }
            Some(f) => {
                return Err(CcxError::Unsupported(format!(
                    "pair '{}': friction law '{}' (only Coulomb is exported)",
                    pair.name,
                    f.name()
                )))
            }
        }
        if faces_target {
            let d = if adjusted_pair(model, pair) {
                opts.adjust_fraction * a_med.sqrt()
            } else {
                0.0
            };
            adjust.push(d);
            let _ = writeln!(
                contact_text,
                "*CONTACT PAIR,INTERACTION=SI{ci},TYPE=SURFACE TO SURFACE{}\nSLAVE{ci},MASTER{ci}",
                if d > 0.0 {
                    format!(",ADJUST={d:.6e}")
                } else {
                    String::new()
                }
            );
        } else {
            adjust.push(0.0);
            let _ = writeln!(
                contact_text,
                "*CONTACT PAIR,INTERACTION=SI{ci},TYPE=NODE TO SURFACE\nSLAVE{ci},MASTER{ci}"
            );
        }
    }
    // materials and sections, then the rigid bodies (their elements borrow material M0)
    for (b, body) in model.bodies.iter().enumerate() {
        let (young, nu) = body.material.elastic_constants();
        let _ = writeln!(
            s,
            "*MATERIAL,NAME=M{b}\n*ELASTIC\n{:.12e},{:.12e}\n*SOLID SECTION,ELSET=B{b},MATERIAL=M{b}",
            young, nu
        );
    }
    s.push_str(&rigid_text);
    s.push_str(&contact_text);
    // prescribed displacements and loads (model data: node sets and amplitudes)
    for (i, p) in model.prescribed.iter().enumerate() {
        let _ = writeln!(s, "*NSET,NSET=P{i}");
        write_ids(&mut s, p.nodes.iter().map(|n| n + 1));
        let c = p.component + 1;
        if p.value == 0.0 {
            let _ = writeln!(step_bc, "*BOUNDARY\nP{i},{c},{c},0.");
        } else {
            write_amplitude(&mut s, &format!("AP{i}"), &p.amplitude);
            let _ = writeln!(
                step_bc,
                "*BOUNDARY,AMPLITUDE=AP{i}\nP{i},{c},{c},{:.12e}",
                p.value
            );
        }
    }
    for (i, l) in model.loads.iter().enumerate() {
        write_amplitude(&mut s, &format!("AL{i}"), &l.amplitude);
        let _ = writeln!(step_bc, "*CLOAD,AMPLITUDE=AL{i}");
        for (n, w) in l.nodes.iter().zip(&l.weights) {
            let _ = writeln!(
                step_bc,
                "{},{},{:.12e}",
                n + 1,
                l.component + 1,
                l.value * w
            );
        }
    }
    // pressure loads: fricsens' consistent nodal forces on the reference faces (a dead load,
    // as fricsens applies it, where CalculiX's *DLOAD would follow the deformed faces under
    // NLGEOM), written as concentrated loads with the pressure's amplitude
    for (i, pl) in model.pressures.iter().enumerate() {
        let mut r = vec![0.0; crate::element::NODE_DOFS * x.len()];
        pl.add_to_residual(&x, pl.value, &mut r);
        let mut nodes: Vec<usize> = pl.faces.all_nodes().to_vec();
        nodes.sort_unstable();
        nodes.dedup();
        write_amplitude(&mut s, &format!("APR{i}"), &pl.amplitude);
        let _ = writeln!(step_bc, "*CLOAD,AMPLITUDE=APR{i}");
        for n in nodes {
            for c in 0..3 {
                // the residual holds internal minus external force
                let f = -r[crate::element::node_dof(n, c)];
                if f != 0.0 {
                    let _ = writeln!(step_bc, "{},{},{f:.12e}", n + 1, c + 1);
                }
            }
        }
    }
    // node sets of the reaction and displacement responses: the total reaction (CalculiX sums
    // the full-precision values before printing) or every node's displacement
    let mut printed = Vec::new();
    for (k, r) in model.responses.iter().enumerate() {
        let (nodes, print) = match &r.kind {
            ResponseKind::Reaction { nodes, .. } => (nodes, "TOTALS=ONLY\nRF"),
            ResponseKind::Displacement { nodes, .. } => (nodes, "TOTALS=NO\nU"),
            _ => continue,
        };
        let _ = writeln!(s, "*NSET,NSET={}", response_set(k));
        write_ids(&mut s, nodes.iter().map(|n| n + 1));
        node_print.push(format!("*NODE PRINT,NSET={},{print}", response_set(k)));
        printed.push(k);
    }
    // steps: runs of equal increments
    let mut runs: Vec<(f64, f64, usize)> = Vec::new(); // (start, increment, count)
    let mut t0 = 0.0;
    for &t in &model.times {
        let dt = t - t0;
        match runs.last_mut() {
            Some((_, d, n)) if (dt - *d).abs() <= 1e-9 * d.abs() => *n += 1,
            _ => runs.push((t0, dt, 1)),
        }
        t0 = t;
    }
    let sv = &model.solver;
    for (k, (_, dt, n)) in runs.iter().enumerate() {
        let period = dt * *n as f64;
        let _ = writeln!(
            s,
            "*STEP{},INC={}",
            if nlgeom { ",NLGEOM" } else { "" },
            n + 1
        );
        let _ = writeln!(s, "*STATIC,DIRECT\n{dt:.12e},{period:.12e}");
        let tol = sv.force_tol;
        let _ = writeln!(
            s,
            "*CONTROLS,PARAMETERS=FIELD\n{tol:.3e},{tol:.3e},,,{tol:.3e},,,{tol:.3e}"
        );
        let it = sv.max_iterations;
        let _ = writeln!(
            s,
            "*CONTROLS,PARAMETERS=TIME INCREMENTATION\n{it},{it},{},{it},{it},{it},,1",
            it + 1
        );
        if k == 0 {
            s.push_str(&step_bc);
        }
        for print in &node_print {
            let _ = writeln!(s, "{print}");
        }
        let _ = writeln!(s, "*END STEP");
    }
    let times = model.times.clone();
    Ok(Deck {
        text: s,
        nodes: next_node - 1,
        elements: next_elem - 1,
        element_types,
        nlgeom,
        reference_nodes,
        normal_stiffness,
        tension,
        stick_slope,
        median_area,
        adjust,
        printed,
        times,
    })
}

/// Name of the node set of response `k` in the deck.
pub fn response_set(k: usize) -> String {
    format!("R{k}")
}

/// Whether a face-to-face pair touches a body that no prescribed displacement holds in some
/// direction (a body carried by contact alone, like the loaded cylinder of the Hertz scene):
/// CalculiX's surface-to-surface penalty then needs contact at the first iteration, which
/// `ADJUST` gives by moving the slave nodes within a small distance onto the master.
fn adjusted_pair(model: &Model, pair: &ContactPair) -> bool {
    let Target::Faces { faces } = &pair.target else {
        return false;
    };
    let body_nodes = |b: usize| -> HashSet<usize> {
        model
            .mesh
            .group_elements(model.bodies[b].group)
            .flat_map(|e| model.mesh.element_nodes(e).iter().copied())
            .collect()
    };
    let mut touched: HashSet<usize> = pair.hitting.iter().copied().collect();
    touched.extend(faces.all_nodes().iter().copied());
    (0..model.bodies.len()).any(|b| {
        let nodes = body_nodes(b);
        !nodes.is_disjoint(&touched)
            && (0..3).any(|c| {
                !model
                    .prescribed
                    .iter()
                    .any(|p| p.component == c && p.nodes.iter().any(|n| nodes.contains(n)))
            })
    })
}

/// Reaction forces of a node set per output time, read from a CalculiX `.dat` file:
/// `(time, [fx, fy, fz])` summed over the set's nodes, in file order.
///
/// # Errors
/// [`CcxError::Parse`] if a force block is malformed or none is found for `set`.
pub fn parse_dat_forces(
    text: &str,
    set: &str,
    path: &Path,
) -> Result<Vec<(f64, [f64; 3])>, CcxError> {
    Ok(parse_dat_blocks(text, DatBlock::Forces, set, path)?
        .into_iter()
        .map(|(t, f, _)| (t, f))
        .collect())
}

/// A kind of `*NODE PRINT` block of a `.dat` file.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum DatBlock {
    /// `RF` of every node of the set (`forces (fx,fy,fz)`).
    Forces,
    /// `RF` summed over the set by CalculiX (`TOTALS=ONLY`: `total force (fx,fy,fz)`).
    TotalForce,
    /// `U` of every node of the set (`displacements (vx,vy,vz)`).
    Displacements,
}

impl DatBlock {
    fn header(self) -> &'static str {
        match self {
            DatBlock::Forces => "forces (fx,fy,fz)",
            DatBlock::TotalForce => "total force (fx,fy,fz)",
            DatBlock::Displacements => "displacements (vx,vy,vz)",
        }
    }
}

/// Blocks of one kind for a node set per output time, read from a CalculiX `.dat` file:
/// `(time, sum of the rows, number of rows)` in file order (a total is one row without a
/// node number).
///
/// # Errors
/// [`CcxError::Parse`] if a block is malformed or none is found for `set`.
pub fn parse_dat_blocks(
    text: &str,
    what: DatBlock,
    set: &str,
    path: &Path,
) -> Result<Vec<(f64, [f64; 3], usize)>, CcxError> {
    let perr = |what: String| CcxError::Parse {
        path: path.display().to_string(),
        what,
    };
    let header = format!("{} for set {} and time", what.header(), set.to_uppercase());
    let mut out = Vec::new();
    let mut lines = text.lines().peekable();
    while let Some(line) = lines.next() {
        let l = line.trim();
        let Some(rest) = l.strip_prefix(&header) else {
            continue;
        };
        let t: f64 = rest
            .trim()
            .parse()
            .map_err(|_| perr(format!("bad time in '{l}'")))?;
        let mut f = [0.0; 3];
        let mut rows = 0;
        // blank line(s), then one row per node (or the total) until a blank line
        while let Some(next) = lines.peek() {
            if next.trim().is_empty() && rows == 0 {
                lines.next();
                continue;
            }
            if next.trim().is_empty() {
                break;
            }
            let cols: Vec<&str> = next.split_whitespace().collect();
            let values = match (what, cols.len()) {
                (DatBlock::TotalForce, 3) => &cols[..],
                (DatBlock::Forces | DatBlock::Displacements, n)
                    if n >= 4 && cols[0].parse::<usize>().is_ok() =>
                {
                    &cols[1..4]
                }
                _ => break,
            };
            for c in 0..3 {
                f[c] += values[c]
                    .parse::<f64>()
                    .map_err(|_| perr(format!("bad value in '{}'", next.trim())))?;
            }
            rows += 1;
            lines.next();
        }
        if rows == 0 {
            return Err(perr(format!("no rows after '{l}'")));
        }
        out.push((t, f, rows));
    }
    if out.is_empty() {
        return Err(perr(format!("no {} output for set {set}", what.header())));
    }
    Ok(out)
}

/// The `ccx` program on `PATH`, if any.
pub fn find_ccx() -> Option<PathBuf> {
    let path = std::env::var_os("PATH")?;
    std::env::split_paths(&path)
        .map(|d| d.join("ccx"))
        .find(|p| p.is_file())
}

/// One CalculiX run: wall time and the compared quantities per output time.
#[derive(Clone, Debug)]
pub(crate) struct CcxRun {
    /// Wall-clock seconds of the `ccx` process (start to exit).
    pub seconds: f64,
    /// `(time, value of each quantity)`, in file order.
    pub values: Vec<(f64, Vec<f64>)>,
    /// Newton iterations CalculiX reports, summed over the increments.
    pub iterations: usize,
    /// Why CalculiX stopped before the last increment (a run allowed to stop early).
    pub failure: Option<String>,
}

/// How CalculiX reports a compared quantity.
#[derive(Clone, Debug, PartialEq)]
pub enum Source {
    /// Force on the rigid target of pair `pair`: minus the reaction `RF` at its rigid body's
    /// reference node (node set `REF{pair}`).
    RigidReference {
        /// Contact pair index.
        pair: usize,
        /// 0, 1, 2 for x, y, z.
        component: usize,
    },
    /// The reaction `RF` of a response's node set ([`response_set`]) summed by CalculiX
    /// (`*NODE PRINT, TOTALS=ONLY`).
    ReactionTotal {
        /// Index of the response (its node set).
        response: usize,
        /// 0, 1, 2 for x, y, z.
        component: usize,
    },
    /// The mean displacement `U` of a response's node set ([`response_set`]).
    MeanDisplacement {
        /// Index of the response (its node set).
        response: usize,
        /// 0, 1, 2 for x, y, z.
        component: usize,
    },
}

/// A quantity both codes report per increment.
#[derive(Clone, Debug, PartialEq)]
pub struct Quantity {
    /// Label in the report, the CSV and the figure (`Fx`, or the response's name).
    pub label: String,
    /// The fricsens response (index into the compared model's responses).
    pub response: usize,
    /// How CalculiX reports it.
    pub source: Source,
}

impl Quantity {
    /// Unit of the quantity in the scenes' mm-N-MPa system.
    fn unit(&self) -> &'static str {
        match self.source {
            Source::MeanDisplacement { .. } => "mm",
            _ => "N",
        }
    }
}

/// Write `deck` as `dir/job.inp`, run `ccx` on it with `threads` threads, and read the
/// `quantities` from its `.dat` file. With `partial`, a run that fails or stops before the
/// last increment returns what it printed and why it stopped ([`CcxRun::failure`]).
///
/// # Errors
/// [`CcxError::Io`] for files, [`CcxError::Run`] if ccx cannot start, or (without `partial`)
/// fails or stops before the last increment, [`CcxError::Parse`] for its output.
#[allow(clippy::too_many_arguments)]
pub(crate) fn run_ccx(
    ccx: &Path,
    deck: &Deck,
    dir: &Path,
    job: &str,
    quantities: &[Quantity],
    threads: usize,
    partial: bool,
    limit: std::time::Duration,
) -> Result<CcxRun, CcxError> {
    std::fs::create_dir_all(dir).map_err(io_err(dir))?;
    let inp = dir.join(format!("{job}.inp"));
    std::fs::write(&inp, &deck.text).map_err(io_err(&inp))?;
    let n = threads.max(1).to_string();
    let start = Instant::now();
    // the output goes to files, so that the run can be waited for with a time limit
    let (log, err) = (
        dir.join(format!("{job}.log")),
        dir.join(format!("{job}.err")),
    );
    let file = |p: &Path| std::fs::File::create(p).map_err(io_err(p));
    let mut child = std::process::Command::new(ccx)
        .arg("-i")
        .arg(job)
        .current_dir(dir)
        .env("OMP_NUM_THREADS", &n)
        .env("CCX_NPROC_EQUATION_SOLVER", &n)
        .env("CCX_NPROC_STIFFNESS", &n)
        .env("CCX_NPROC_RESULTS", &n)
        .stdout(file(&log)?)
        .stderr(file(&err)?)
        .spawn()
        .map_err(|e| CcxError::Run {
            job: job.into(),
            what: format!("cannot start {}: {e}", ccx.display()),
        })?;
    let tail = |s: &str| {
        let lines: Vec<&str> = s.lines().collect();
        lines[lines.len().saturating_sub(15)..].join("\n")
    };
    let read =
        |p: &Path| String::from_utf8_lossy(&std::fs::read(p).unwrap_or_default()).into_owned();
    let status = loop {
        match child.try_wait() {
            Ok(Some(status)) => break status,
            Ok(None) if start.elapsed() > limit => {
                let _ = child.kill();
                let _ = child.wait();
                return Err(CcxError::Run {
                    job: job.into(),
                    what: format!(
                        "stopped after the time limit of {:.0} s; output ends:\n{}",
                        limit.as_secs_f64(),
                        tail(&read(&log))
                    ),
                });
            }
            Ok(None) => std::thread::sleep(std::time::Duration::from_millis(20)),
            Err(e) => {
                return Err(CcxError::Run {
                    job: job.into(),
                    what: format!("waiting for {}: {e}", ccx.display()),
                })
            }
        }
    };
    let seconds = start.elapsed().as_secs_f64();
    let out = std::process::Output {
        status,
        stdout: read(&log).into_bytes(),
        stderr: read(&err).into_bytes(),
    };
    let stdout = String::from_utf8_lossy(&out.stdout);
    let failed = !out.status.success() || stdout.contains("*ERROR");
    if failed && !partial {
        return Err(CcxError::Run {
            job: job.into(),
            what: format!(
                "exit status {}; output ends:\n{}\n{}",
                out.status,
                tail(&stdout),
                tail(&String::from_utf8_lossy(&out.stderr))
            ),
        });
    }
    let iterations = stdout
        .lines()
        .filter(|l| l.trim_start().starts_with("iteration "))
        .count();
    let dat = dir.join(format!("{job}.dat"));
    let values = match std::fs::read_to_string(&dat)
        .map_err(io_err(&dat))
        .and_then(|text| read_quantities(&text, &dat, quantities))
    {
        Ok(v) => v,
        // a failed run may have printed nothing
        Err(_) if failed => Vec::new(),
        Err(e) => return Err(e),
    };
    let last = deck.times.last().copied().unwrap_or(0.0);
    let stopped = values
        .last()
        .is_none_or(|(t, _)| (t - last).abs() > 1e-6 * last.abs().max(1.0));
    let failure = (failed || stopped).then(|| {
        let error: Vec<&str> = stdout
            .lines()
            .skip_while(|l| !l.contains("*ERROR"))
            .take_while(|l| !l.trim().is_empty())
            .map(str::trim)
            .collect();
        format!(
            "CalculiX stopped after t = {} ({}; {})",
            values.last().map_or(0.0, |(t, _)| *t),
            out.status,
            if error.is_empty() {
                "no *ERROR line".to_string()
            } else {
                error.join(" ")
            }
        )
    });
    if stopped && !partial {
        return Err(CcxError::Run {
            job: job.into(),
            what: format!("stopped before t = {last}; output ends:\n{}", tail(&stdout)),
        });
    }
    Ok(CcxRun {
        seconds,
        values,
        iterations,
        failure,
    })
}

/// The quantities' histories from a `.dat` file's text, zipped by output time.
fn read_quantities(
    text: &str,
    dat: &Path,
    quantities: &[Quantity],
) -> Result<Vec<(f64, Vec<f64>)>, CcxError> {
    let mut histories: Vec<Vec<(f64, f64)>> = Vec::new();
    for q in quantities {
        let h: Vec<(f64, f64)> = match q.source {
            Source::RigidReference { pair, component } => {
                parse_dat_blocks(text, DatBlock::Forces, &format!("REF{pair}"), dat)?
                    .into_iter()
                    .map(|(t, f, _)| (t, -f[component]))
                    .collect()
            }
            Source::ReactionTotal {
                response,
                component,
            } => parse_dat_blocks(text, DatBlock::TotalForce, &response_set(response), dat)?
                .into_iter()
                .map(|(t, f, _)| (t, f[component]))
                .collect(),
            Source::MeanDisplacement {
                response,
                component,
            } => parse_dat_blocks(text, DatBlock::Displacements, &response_set(response), dat)?
                .into_iter()
                .map(|(t, f, rows)| (t, f[component] / rows as f64))
                .collect(),
        };
        histories.push(h);
    }
    let mut values: Vec<(f64, Vec<f64>)> = Vec::new();
    if let Some(first) = histories.first() {
        for (k, (t, _)) in first.iter().enumerate() {
            let row: Option<Vec<f64>> = histories
                .iter()
                .map(|h| h.get(k).filter(|(s, _)| s == t).map(|(_, v)| *v))
                .collect();
            let row = row.ok_or_else(|| CcxError::Parse {
                path: dat.display().to_string(),
                what: format!("the printed node sets disagree on the output times at t = {t}"),
            })?;
            values.push((*t, row));
        }
    }
    Ok(values)
}

/// Settings of a comparison.
#[derive(Clone, Debug)]
pub struct CompareOptions {
    /// The `ccx` program.
    pub ccx: PathBuf,
    /// Directory for CalculiX's files (decks, `.dat`, `.sta`...).
    pub work: PathBuf,
    /// Relative step of CalculiX's central difference: `p (1 +- beta)`.
    pub beta: f64,
    /// Threads for CalculiX (fricsens uses rayon's pool).
    pub threads: usize,
    /// The translation of the model.
    pub export: ExportOptions,
    /// Wall-time limit of one CalculiX run, seconds; `None`: the larger of ten minutes and 100
    /// times fricsens' primal run (CalculiX took 8 to 10 times as long on the scenes compared
    /// so far). A run past it is stopped and reported: CalculiX can iterate on without end
    /// past its own iteration limit.
    pub time_limit: Option<f64>,
}

/// A comparison in a few numbers (`ccx.json`), for the verification report's table of the
/// comparisons side by side.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct CcxSummary {
    /// Scene name (what regenerates the comparison).
    pub scene: String,
    /// CalculiX element types, one per body.
    pub element_types: Vec<String>,
    /// fricsens' element families, one per body.
    pub families: Vec<String>,
    /// fricsens' unknowns.
    pub unknowns: usize,
    /// Nodes of CalculiX's deck.
    pub ccx_nodes: usize,
    /// fricsens' primal wall time (s).
    pub fricsens_seconds: f64,
    /// CalculiX's primal wall time (s).
    pub ccx_seconds: f64,
    /// The largest difference between the two codes' compared quantities (the forces on a
    /// rigid target, or the scene's reactions and displacements) over the history, over the
    /// quantity's largest fricsens value, the worst quantity's (quantities fricsens keeps at
    /// zero left out).
    pub largest_difference: f64,
}

/// The comparison's data, per increment and in all.
#[derive(Clone, Debug)]
pub struct Comparison {
    /// Scene name.
    pub scene: String,
    /// Whether the compared quantities are the forces on a rigid target (else the scene's
    /// reaction and displacement responses between deformable bodies).
    pub rigid: bool,
    /// The contact pair whose rigid target's force is compared, or whose friction coefficient
    /// is the design parameter (empty when the parameter is a Young's modulus).
    pub pair: String,
    /// The design parameter as fricsens names it (`block.mu`, `upper.E`).
    pub parameter: String,
    /// Its symbol in the report and the CSV (`mu`, `E`).
    pub symbol: String,
    /// Its nominal value.
    pub value: f64,
    /// Relative finite-difference step of CalculiX's reruns.
    pub beta: f64,
    /// The deck of the nominal run (for its counts and contact constants).
    pub deck: Deck,
    /// Unknowns of fricsens' system.
    pub unknowns: usize,
    /// Increment end times.
    pub times: Vec<f64>,
    /// The compared quantities.
    pub quantities: Vec<Quantity>,
    /// Each quantity by fricsens, per increment (`[increment][quantity]`).
    pub fricsens: Vec<Vec<f64>>,
    /// Each quantity by CalculiX, per increment.
    pub ccx: Vec<Vec<f64>>,
    /// Its derivative in the parameter by fricsens' DDM.
    pub ddm: Vec<Vec<f64>>,
    /// Its derivative in the parameter by CalculiX's central difference.
    pub fd: Vec<Vec<f64>>,
    /// Each quantity by CalculiX's reruns at p (1 + beta) and p (1 - beta), per increment.
    pub ccx_reruns: [Vec<Vec<f64>>; 2],
    /// fricsens primal wall seconds (solver set-up and run).
    pub fricsens_primal_seconds: f64,
    /// fricsens Newton iterations.
    pub fricsens_iterations: usize,
    /// DDM's own work for the one parameter (on top of its primal run).
    pub ddm_seconds: f64,
    /// The primal run inside the DDM run.
    pub ddm_primal_seconds: f64,
    /// CalculiX nominal wall seconds.
    pub ccx_seconds: f64,
    /// CalculiX Newton iterations (nominal run).
    pub ccx_iterations: usize,
    /// CalculiX reruns at p (1 + beta) and p (1 - beta), wall seconds.
    pub ccx_rerun_seconds: [f64; 2],
    /// Why a rerun stopped before the last increment (its difference quotients are NaN from
    /// there on; only between deformable bodies: the rigid case fails instead).
    pub ccx_rerun_failures: [Option<String>; 2],
    /// Threads of each code.
    pub threads: usize,
    /// fricsens' force tolerance (also written as CalculiX's ratios).
    pub force_tol: f64,
    /// fricsens' element family of each body (shape and formulation).
    pub formulations: Vec<String>,
    /// The export options used.
    pub export: ExportOptions,
    /// `ccx -v`'s version.
    pub ccx_version: String,
    /// The contact pair whose pressures and penalty estimate the overlap.
    pub pressure_pair: usize,
    /// Mean and largest contact pressure of that pair's closed hitting nodes at the last
    /// increment (fricsens), for the penalty overlap estimate.
    pub pressure: (f64, f64),
    /// The indentation the overlap is measured against: the rigid target's largest prescribed
    /// motion along y, or the largest displacement prescribed on the node set of the largest
    /// compared reaction in its direction (0 when there is none).
    pub normal_motion: f64,
    /// What `normal_motion` is (for the report).
    pub normal_motion_source: String,
}

/// The quantities, the parameter and (possibly with added responses) the model a comparison
/// follows. The rigid case: the target-force responses of the first pair with a rigid target,
/// and its friction coefficient. Otherwise: every reaction and displacement response of the
/// model; when it has none, responses are added: the mean displacement of each nodal load's
/// nodes in its direction, and the reaction of each nonzero prescribed displacement's nodes in
/// its component. The parameter: the friction coefficient of the first pair with Coulomb
/// friction, else the Young's modulus of the first body.
struct Plan {
    model: Model,
    quantities: Vec<Quantity>,
    rigid: Option<usize>,
    pair: String,
    parameter: String,
    symbol: String,
    design: DesignParam,
    value: f64,
}

fn plan(model: &Model) -> Result<Plan, CcxError> {
    if let Some(pi) = model
        .contacts
        .iter()
        .position(|c| matches!(c.target, Target::Rigid { .. }))
    {
        let pair = &model.contacts[pi];
        let mu = match &pair.friction {
            Some(f @ Friction::Coulomb(_)) => f.params()[0],
            _ => {
                return Err(CcxError::Unsupported(format!(
                    "pair '{}' has no Coulomb friction",
                    pair.name
                )))
            }
        };
        let quantities: Vec<Quantity> = (0..3)
            .filter_map(|c| {
                model
                    .responses
                    .iter()
                    .position(|r| {
                        matches!(r.kind, ResponseKind::TargetForce { pair: p, component } if p == pi && component == c)
                    })
                    .map(|r| Quantity {
                        label: format!("F{}", AXES[c]),
                        response: r,
                        source: Source::RigidReference {
                            pair: pi,
                            component: c,
                        },
                    })
            })
            .collect();
        if quantities.is_empty() {
            return Err(CcxError::Unsupported(format!(
                "the model has no target-force response of pair '{}'",
                pair.name
            )));
        }
        return Ok(Plan {
            model: model.clone(),
            quantities,
            rigid: Some(pi),
            pair: pair.name.clone(),
            parameter: format!("{}.mu", pair.name),
            symbol: "mu".into(),
            design: DesignParam::Friction { pair: pi, index: 0 },
            value: mu,
        });
    }
    let mut model = model.clone();
    let has = |m: &Model| {
        m.responses.iter().any(|r| {
            matches!(
                r.kind,
                ResponseKind::Reaction { .. } | ResponseKind::Displacement { .. }
            )
        })
    };
    if !has(&model) {
        let mut added = Vec::new();
        for l in &model.loads {
            added.push(crate::response::Response {
                name: format!("{}.u{}", l.name, AXES[l.component]),
                kind: ResponseKind::Displacement {
                    nodes: l.nodes.clone(),
                    component: l.component,
                },
            });
        }
        for p in model.prescribed.iter().filter(|p| p.value != 0.0) {
            added.push(crate::response::Response {
                name: format!("{}.F{}", p.name, AXES[p.component]),
                kind: ResponseKind::Reaction {
                    nodes: p.nodes.clone(),
                    component: p.component,
                },
            });
        }
        model.responses.extend(added);
    }
    let quantities: Vec<Quantity> = model
        .responses
        .iter()
        .enumerate()
        .filter_map(|(k, r)| {
            let source = match r.kind {
                ResponseKind::Reaction { component, .. } => Source::ReactionTotal {
                    response: k,
                    component,
                },
                ResponseKind::Displacement { component, .. } => Source::MeanDisplacement {
                    response: k,
                    component,
                },
                _ => return None,
            };
            Some(Quantity {
                label: r.name.clone(),
                response: k,
                source,
            })
        })
        .collect();
    if quantities.is_empty() {
        return Err(CcxError::Unsupported(
            "nothing to compare: no rigid contact target, no reaction or displacement response, \
             no nodal load and no nonzero prescribed displacement"
                .into(),
        ));
    }
    let coulomb = model
        .contacts
        .iter()
        .position(|c| matches!(c.friction, Some(Friction::Coulomb(_))));
    let (pair, parameter, symbol, design, value) = match coulomb {
        Some(pi) => {
            let c = &model.contacts[pi];
            let mu = c.friction.as_ref().map_or(f64::NAN, |f| f.params()[0]);
            (
                c.name.clone(),
                format!("{}.mu", c.name),
                "mu",
                DesignParam::Friction { pair: pi, index: 0 },
                mu,
            )
        }
        None => {
            let b = model
                .bodies
                .first()
                .ok_or_else(|| CcxError::Unsupported("no body".into()))?;
            (
                String::new(),
                format!("{}.E", b.name),
                "E",
                DesignParam::Material { body: 0, index: 0 },
                b.material.young(),
            )
        }
    };
    Ok(Plan {
        model,
        quantities,
        rigid: None,
        pair,
        parameter,
        symbol: symbol.into(),
        design,
        value,
    })
}

/// Run the comparison: fricsens primal (timed), DDM for the derivative in one design
/// parameter, CalculiX nominal and at the parameter times (1 +- beta). What is compared and in
/// which parameter: a scene with a rigid contact target compares the force on it and its
/// derivative in the pair's friction coefficient; a scene whose contact pairs are between
/// deformable bodies compares its reaction and displacement responses (see [`Comparison`]) in
/// the friction coefficient of its first pair with Coulomb friction, or, frictionless, in the
/// Young's modulus of its first body.
///
/// # Errors
/// Export, run and parse errors of CalculiX, fricsens' analysis errors, and
/// [`CcxError::Unsupported`] when a rigid pair has no Coulomb friction or the model no
/// target-force response of it, or when a model without rigid target has nothing to compare.
pub fn compare(model: &Model, name: &str, opts: &CompareOptions) -> Result<Comparison, CcxError> {
    if !(opts.beta > 0.0 && opts.beta < 1.0) {
        return Err(CcxError::Option(format!(
            "beta must lie in (0, 1), got {}",
            opts.beta
        )));
    }
    let plan = plan(model)?;
    let model = &plan.model;
    let quantities = &plan.quantities;
    // fricsens: primal, timed from the solver's set-up
    let start = Instant::now();
    let mut solver = Solver::new(model)?;
    let res = solver.run(&RunOptions::default(), &mut NoObserver)?;
    let fricsens_primal_seconds = start.elapsed().as_secs_f64();
    let unknowns = solver.assembler.dofs.n_total;
    let fricsens_iterations = res.records.iter().map(|r| r.iterations).sum();
    let times = model.times.clone();
    let mut fricsens = Vec::new();
    for t in &times {
        let k = res.increment_at(*t).ok_or_else(|| {
            CcxError::Analysis(
                crate::sensitivity::SensitivityError::NoIncrementAt { time: *t }.into(),
            )
        })?;
        fricsens.push(
            quantities
                .iter()
                .map(|q| res.response_value(model, q.response, k))
                .collect::<Vec<f64>>(),
        );
    }
    // contact pressures at the end, for the penalty overlap estimate: the rigid pair, the
    // pair of the friction coefficient, else the first pair
    let pressure_pair = plan.rigid.unwrap_or_else(|| {
        model
            .contacts
            .iter()
            .position(|c| c.name == plan.pair)
            .unwrap_or(0)
    });
    let last = res.states.len() - 1;
    let closed: Vec<f64> = model
        .responses
        .iter()
        .enumerate()
        .filter(|(_, r)| matches!(r.kind, ResponseKind::ContactPressure { pair: p, .. } if p == pressure_pair))
        .map(|(k, _)| res.response_value(model, k, last))
        .filter(|p| *p > 0.0)
        .collect();
    let pressure = (
        closed.iter().sum::<f64>() / closed.len().max(1) as f64,
        closed.iter().copied().fold(0.0, f64::max),
    );
    let peak = |a: &Amplitude, v: f64| {
        a.points
            .iter()
            .map(|(_, s)| (s * v).abs())
            .fold(0.0, f64::max)
    };
    let (normal_motion, normal_motion_source) = match plan
        .rigid
        .map(|pi| &model.contacts[pi].target)
    {
        Some(Target::Rigid { motion, .. }) => (
            motion
                .iter()
                .filter(|m| m.component == 1)
                .filter(|m| m.control == crate::contact::MotionControl::Displacement)
                .map(|m| peak(&m.amplitude, m.value))
                .fold(0.0, f64::max),
            "the rigid target's motion along y".to_string(),
        ),
        _ => {
            // the reaction compared with the largest force, and what is prescribed on its set
            let largest = quantities
                .iter()
                .enumerate()
                .filter(|(_, q)| matches!(q.source, Source::ReactionTotal { .. }))
                .max_by(|a, b| {
                    let m = |i: usize| fricsens.iter().map(|f| f[i].abs()).fold(0.0, f64::max);
                    m(a.0).total_cmp(&m(b.0))
                });
            let mut found = (0.0, String::new());
            if let Some((_, q)) = largest {
                if let ResponseKind::Reaction { nodes, component } =
                    &model.responses[q.response].kind
                {
                    let set: HashSet<usize> = nodes.iter().copied().collect();
                    for p in &model.prescribed {
                        let d = peak(&p.amplitude, p.value);
                        if p.component == *component
                            && d > found.0
                            && p.nodes.iter().any(|n| set.contains(n))
                        {
                            found = (
                                d,
                                format!(
                                    "the displacement prescribed by `{}` along {} on the node set of `{}`",
                                    p.name, AXES[p.component], q.label
                                ),
                            );
                        }
                    }
                }
            }
            found
        }
    };
    // DDM in the parameter
    let param = Parameter::single(model, &plan.parameter, plan.design)
        .map_err(crate::solver::AnalysisError::from)?;
    let settings = Settings {
        method: Method::Ddm,
        ..Settings::default()
    };
    let (_, sens) = run_sensitivity(model, std::slice::from_ref(&param), &settings)?;
    let mut ddm = Vec::new();
    for t in &times {
        let inc = sens
            .increments
            .iter()
            .find(|i| (i.time - t).abs() <= 1e-12 * t.abs().max(1.0));
        ddm.push(
            quantities
                .iter()
                .map(|q| inc.map_or(f64::NAN, |i| i.derivatives[q.response][0]))
                .collect::<Vec<f64>>(),
        );
    }
    // CalculiX: nominal and the two reruns
    let deck = export(model, &opts.export)?;
    // a negative or NaN limit stops at once, one no Duration holds never
    let limit = crate::solver::saturating_duration(
        (opts.time_limit).unwrap_or_else(|| (100.0 * sens.primal_seconds).max(600.0)),
    );
    let nominal = run_ccx(
        &opts.ccx,
        &deck,
        &opts.work,
        "nominal",
        quantities,
        opts.threads,
        false,
        limit,
    )?;
    let (plus, minus) = if plan.symbol == "mu" {
        ("mu-plus", "mu-minus")
    } else {
        ("p-plus", "p-minus")
    };
    let mut reruns = Vec::new();
    for (job, sign) in [(plus, 1.0), (minus, -1.0)] {
        let mut m = model.clone();
        m.set_param(plan.design, plan.value * (1.0 + sign * opts.beta));
        let d = export(&m, &opts.export)?;
        reruns.push(run_ccx(
            &opts.ccx,
            &d,
            &opts.work,
            job,
            quantities,
            opts.threads,
            // a rerun that stops early leaves the difference quotient undefined from there
            // on (the rigid case keeps its error)
            plan.rigid.is_none(),
            limit,
        )?);
    }
    let at = |run: &CcxRun, t: f64| -> Result<Vec<f64>, CcxError> {
        run.values
            .iter()
            .rev()
            .find(|(s, _)| (s - t).abs() <= 1e-6 * t.abs().max(1.0))
            .map(|(_, f)| f.clone())
            .ok_or_else(|| CcxError::Run {
                job: "output".into(),
                what: format!("no CalculiX output at t = {t}"),
            })
    };
    let mut ccx = Vec::new();
    let mut fd = Vec::new();
    let mut ccx_reruns = [Vec::new(), Vec::new()];
    let h = 2.0 * opts.beta * plan.value;
    for t in &times {
        ccx.push(at(&nominal, *t)?);
        let rerun = |r: &CcxRun| match at(r, *t) {
            Err(_) if r.failure.is_some() => Ok(vec![f64::NAN; quantities.len()]),
            v => v,
        };
        let (p, m) = (rerun(&reruns[0])?, rerun(&reruns[1])?);
        fd.push(p.iter().zip(&m).map(|(p, m)| (p - m) / h).collect());
        ccx_reruns[0].push(p);
        ccx_reruns[1].push(m);
    }
    Ok(Comparison {
        scene: name.to_string(),
        rigid: plan.rigid.is_some(),
        pair: plan.pair.clone(),
        parameter: plan.parameter.clone(),
        symbol: plan.symbol.clone(),
        value: plan.value,
        beta: opts.beta,
        deck,
        unknowns,
        times,
        quantities: quantities.clone(),
        fricsens,
        ccx,
        ddm,
        fd,
        ccx_reruns,
        fricsens_primal_seconds,
        fricsens_iterations,
        ddm_seconds: sens.cost.wall_seconds,
        ddm_primal_seconds: sens.primal_seconds,
        ccx_seconds: nominal.seconds,
        ccx_iterations: nominal.iterations,
        ccx_rerun_seconds: [reruns[0].seconds, reruns[1].seconds],
        ccx_rerun_failures: [reruns[0].failure.clone(), reruns[1].failure.clone()],
        threads: opts.threads,
        force_tol: model.solver.force_tol,
        formulations: model
            .bodies
            .iter()
            .map(|b| {
                b.family(&model.mesh)
                    .map_or_else(|e| e.to_string(), |f| f.name().to_string())
            })
            .collect(),
        export: opts.export.clone(),
        ccx_version: ccx_version(&opts.ccx).unwrap_or_else(|| "(version unknown)".into()),
        pressure_pair,
        pressure,
        normal_motion,
        normal_motion_source,
    })
}

/// Smoothness of a history: total variation `sum |d_{k+1} - d_k|` and the largest jump.
pub fn variation(v: &[f64]) -> (f64, f64) {
    v.windows(2)
        .map(|w| (w[1] - w[0]).abs())
        .filter(|d| d.is_finite())
        .fold((0.0, 0.0), |(tv, mx), d| (tv + d, f64::max(mx, d)))
}

/// Largest `|a - b|` over the history, relative to the largest `|b|` (the floor keeps
/// near-zero values from exploding), and the index where it occurs.
pub fn relative_difference(a: &[f64], b: &[f64]) -> (f64, usize) {
    let scale = b.iter().map(|v| v.abs()).fold(0.0, f64::max);
    a.iter()
        .zip(b)
        .enumerate()
        .map(|(k, (x, y))| ((x - y).abs() / scale.max(f64::MIN_POSITIVE), k))
        .fold((0.0, 0), |m, v| if v.0 > m.0 { v } else { m })
}

const AXES: [&str; 3] = ["x", "y", "z"];

impl Comparison {
    /// How the elements of the two codes compare, for the report.
    fn element_note(&self) -> &'static str {
        if self.formulations.iter().any(|f| f.contains("incompatible")) {
            "the same incompatible-mode idea, not the same implementation (Taylor's modes vs Wilson-Taylor / Simo-Armero)"
        } else {
            "the same interpolation, each code's own implementation"
        }
    }

    fn column(v: &[Vec<f64>], i: usize) -> Vec<f64> {
        v.iter().map(|f| f[i]).collect()
    }

    /// The comparison in a few numbers.
    pub fn summary(&self) -> CcxSummary {
        // quantities that stay zero (a force component nothing loads) have no relative
        // difference
        let largest_difference = (0..self.quantities.len())
            .filter(|i| Self::largest(&self.fricsens, *i) > 0.0)
            .map(|i| {
                let diff = (self.fricsens.iter().zip(&self.ccx))
                    .map(|(f, c)| (f[i] - c[i]).abs())
                    .filter(|d| d.is_finite())
                    .fold(0.0, f64::max);
                diff / Self::largest(&self.fricsens, i)
            })
            .fold(0.0, f64::max);
        CcxSummary {
            scene: self.scene.clone(),
            element_types: self
                .deck
                .element_types
                .iter()
                .map(|t| t.to_string())
                .collect(),
            families: self.formulations.clone(),
            unknowns: self.unknowns,
            ccx_nodes: self.deck.nodes,
            fricsens_seconds: self.fricsens_primal_seconds,
            ccx_seconds: self.ccx_seconds,
            largest_difference,
        }
    }

    fn largest(v: &[Vec<f64>], i: usize) -> f64 {
        v.iter().map(|f| f[i].abs()).fold(0.0, f64::max)
    }

    /// One unit in the 7th significant digit of the largest value CalculiX printed for
    /// quantity `i` (the step of its printed values).
    fn print_quantum(&self, i: usize) -> f64 {
        let big = Self::largest(&self.ccx, i);
        if big > 0.0 {
            10f64.powf(big.log10().floor() - 6.0)
        } else {
            0.0
        }
    }

    /// Increments (0-based) where CalculiX's reruns are not on one smooth branch with its
    /// nominal run for quantity `i`. On a smooth history the nominal value is the midpoint of
    /// the reruns' to O(beta^2) while they differ by O(beta); an increment is flagged when the
    /// nominal value misses the midpoint by more than a quarter of their half-difference (plus
    /// two print steps): a rerun has changed branch (contact or stick-slip state, or CalculiX
    /// converged elsewhere), and the difference quotient measures a jump, not a derivative.
    pub fn off_branch(&self, i: usize) -> Vec<usize> {
        let q = self.print_quantum(i);
        (0..self.times.len())
            .filter(|&k| {
                let (n, p, m) = (
                    self.ccx[k][i],
                    self.ccx_reruns[0][k][i],
                    self.ccx_reruns[1][k][i],
                );
                (0.5 * (p + m) - n).abs() > 0.25 * 0.5 * (p - m).abs() + 2.0 * q
            })
            .collect()
    }

    /// The points of CalculiX's difference quotient of quantity `i` times `scale`: every
    /// increment in the rigid case, else those [`Comparison::off_branch`] does not flag (the
    /// report lists the flagged ones, `ccx.csv` has them all).
    fn fd_points(&self, i: usize, scale: f64) -> Vec<(f64, f64)> {
        let off = if self.rigid {
            Vec::new()
        } else {
            self.off_branch(i)
        };
        (0..self.times.len())
            .filter(|k| !off.contains(k) && (self.rigid || self.fd[*k][i].is_finite()))
            .map(|k| (self.times[k], self.fd[k][i] * scale))
            .collect()
    }

    /// Unit of d(quantity)/d(parameter).
    fn derivative_unit(&self, q: &Quantity) -> String {
        if self.symbol == "E" {
            format!("{}/MPa", q.unit())
        } else {
            q.unit().to_string()
        }
    }

    /// The CSV: increment, time, then per quantity its value by fricsens and by ccx, its
    /// derivative in the parameter by DDM and by ccx's central difference.
    pub fn csv(&self) -> String {
        let sym = &self.symbol;
        let mut s = String::from("increment,time");
        for q in &self.quantities {
            let l = &q.label;
            let _ = write!(
                s,
                ",{l}_fricsens,{l}_ccx,d{l}/d{sym}_fricsens_ddm,d{l}/d{sym}_ccx_fd"
            );
        }
        s.push('\n');
        for (k, t) in self.times.iter().enumerate() {
            let _ = write!(s, "{},{t:.10e}", k + 1);
            for i in 0..self.quantities.len() {
                let _ = write!(
                    s,
                    ",{:.12e},{:.12e},{:.12e},{:.12e}",
                    self.fricsens[k][i], self.ccx[k][i], self.ddm[k][i], self.fd[k][i]
                );
            }
            s.push('\n');
        }
        s
    }

    /// The figure: histories of the quantities and of their derivatives, both codes. The rigid
    /// case draws dF/dmu (force units); otherwise the derivatives are drawn times the
    /// parameter, `p dq/dp`, in the quantity's units.
    pub fn figure(&self) -> crate::studies::plot::Figure {
        use crate::studies::plot::{Figure, Style};
        let sym = &self.symbol;
        let mut fig = if self.rigid {
            Figure::new(
                format!(
                    "{}: force on the block and its derivative in mu, fricsens vs CalculiX",
                    self.scene
                ),
                "pseudo-time",
                "force, d force / d mu (N)",
            )
        } else {
            Figure::new(
                format!(
                    "{}: compared responses q and {sym} dq/d{sym}, fricsens vs CalculiX",
                    self.scene
                ),
                "pseudo-time",
                format!("q, {sym} dq / d{sym} (N or mm)"),
            )
        };
        let pts = |v: Vec<f64>| -> Vec<(f64, f64)> { self.times.iter().copied().zip(v).collect() };
        let scale = if self.rigid { 1.0 } else { self.value };
        let scaled = |v: Vec<f64>| -> Vec<f64> { v.into_iter().map(|d| d * scale).collect() };
        let prefix = if self.rigid {
            String::new()
        } else {
            format!("{sym} ")
        };
        for (i, q) in self.quantities.iter().enumerate() {
            let l = &q.label;
            fig = fig
                .series(
                    format!("{l} fricsens"),
                    pts(Self::column(&self.fricsens, i)),
                    Style::Line,
                )
                .series(
                    format!("{l} CalculiX"),
                    pts(Self::column(&self.ccx, i)),
                    Style::Points,
                )
                .series(
                    format!("{prefix}d{l}/d{sym} fricsens DDM"),
                    pts(scaled(Self::column(&self.ddm, i))),
                    Style::Dashed,
                )
                .series(
                    format!("{prefix}d{l}/d{sym} CalculiX FD"),
                    self.fd_points(i, scale),
                    Style::LinePoints,
                );
        }
        fig
    }

    /// The Markdown report, starting with `## Against CalculiX`.
    pub fn markdown(&self) -> String {
        let mut s = format!("## Against CalculiX: {}\n\n", self.scene);
        let d = &self.deck;
        let sym = &self.symbol;
        let n_inc = self.times.len();
        let ratio = self.ccx_seconds / self.fricsens_primal_seconds.max(1e-12);
        let _ = writeln!(
            s,
            "The `{}` scene solved by CalculiX {} (`ccx`) with the same mesh, the same {n_inc} increments (`*STATIC, DIRECT`: no automatic incrementation) and fricsens' force tolerance {:.0e} as CalculiX's residual and correction ratios (`*CONTROLS, PARAMETERS=FIELD`), written by `fricsens ccx` (`src/studies/ccx.rs`). Both codes on {} thread(s). Regenerate with `cargo run --release -- ccx {}`.\n",
            self.scene,
            self.ccx_version,
            self.force_tol,
            self.threads,
            self.scene
        );
        let _ = writeln!(s, "### Cost\n");
        let _ = writeln!(s, "| | fricsens | CalculiX |\n|---|---|---|");
        let _ = writeln!(
            s,
            "| unknowns | {} (incl. multipliers and any incompatible modes) | {} nodes, {} elements{} |",
            self.unknowns,
            d.nodes,
            d.elements,
            if self.rigid {
                " (incl. the rigid block)"
            } else {
                ""
            }
        );
        let _ = writeln!(
            s,
            "| primal, wall clock | {:.2} s ({} Newton iterations) | {:.2} s ({} iterations) |",
            self.fricsens_primal_seconds,
            self.fricsens_iterations,
            self.ccx_seconds,
            self.ccx_iterations
        );
        let fd_cost = self.ccx_rerun_seconds[0] + self.ccx_rerun_seconds[1];
        let _ = writeln!(
            s,
            "| d/d {sym}, one parameter | DDM: {:.2} s on top of its primal ({:.2} x the primal) | central FD: two reruns, {:.2} s ({:.2} x its primal) |",
            self.ddm_seconds,
            self.ddm_seconds / self.ddm_primal_seconds.max(1e-12),
            fd_cost,
            fd_cost / self.ccx_seconds.max(1e-12)
        );
        let _ = writeln!(
            s,
            "| primal + d/d {sym} | {:.2} s | {:.2} s |\n",
            self.ddm_primal_seconds + self.ddm_seconds,
            self.ccx_seconds + fd_cost
        );
        let _ = writeln!(
            s,
            "Time ratio CalculiX / fricsens, primal: **{ratio:.2}** ({}); primal and one sensitivity: **{:.2}**. Single runs on a shared machine: the two CalculiX reruns, the same work, took {:.2} s and {:.2} s, a spread of {:.0} % that bounds how far to trust the ratios.\n",
            if ratio >= 1.0 {
                "fricsens is at least as fast"
            } else {
                "CalculiX is faster"
            },
            (self.ccx_seconds + fd_cost) / (self.ddm_primal_seconds + self.ddm_seconds).max(1e-12),
            self.ccx_rerun_seconds[0],
            self.ccx_rerun_seconds[1],
            100.0 * (self.ccx_rerun_seconds[0] - self.ccx_rerun_seconds[1]).abs()
                / (0.5 * fd_cost).max(1e-12)
        );
        if self.rigid {
            self.rigid_forces(&mut s);
        } else {
            self.responses(&mut s);
        }
        let _ = writeln!(s, "### Sensitivity to {sym}\n");
        if self.rigid {
            let _ = writeln!(
                s,
                "fricsens: DDM (exact derivative of its discrete solution). CalculiX: central difference of two reruns at mu (1 +- {:.0e}).\n",
                self.beta
            );
        } else {
            let what = if sym == "mu" {
                format!(
                    "the friction coefficient mu = {} of pair `{}`",
                    self.value, self.pair
                )
            } else {
                format!(
                    "the Young's modulus E = {:e} MPa of body `{}` (`{}`; the scene is frictionless, so d/d mu would be zero in both codes)",
                    self.value,
                    self.parameter.trim_end_matches(".E"),
                    self.parameter
                )
            };
            let _ = writeln!(
                s,
                "The parameter is {what}. fricsens: DDM (exact derivative of its discrete solution). CalculiX: central difference of two reruns at {sym} (1 +- {:.0e}).\n",
                self.beta
            );
        }
        let (q_head, q_unit) = if self.rigid {
            ("component", " (N)")
        } else {
            ("quantity", "")
        };
        let _ = writeln!(
            s,
            "| {q_head} | final DDM{q_unit} | final CalculiX FD{q_unit} | largest difference / largest DDM value | at increment | total variation DDM | total variation FD | largest jump DDM | largest jump FD | variation beyond the largest jump, DDM | the same, FD |\n|---|---|---|---|---|---|---|---|---|---|---|"
        );
        for (i, q) in self.quantities.iter().enumerate() {
            let dd = Self::column(&self.ddm, i);
            let fd = Self::column(&self.fd, i);
            let (rel, k) = relative_difference(&fd, &dd);
            let (tv_d, j_d) = variation(&dd);
            let (tv_f, j_f) = variation(&fd);
            let unit = if self.rigid {
                String::new()
            } else {
                format!(" {}", self.derivative_unit(q))
            };
            let _ = writeln!(
                s,
                "| d{}/d{sym} | {:.6e}{unit} | {:.6e}{unit} | {:.2e} | {} (t = {:.2}) | {:.4e} | {:.4e} | {:.4e} | {:.4e} | {:.3e} | {:.3e} |",
                q.label,
                dd.last().copied().unwrap_or(f64::NAN),
                fd.last().copied().unwrap_or(f64::NAN),
                rel,
                k + 1,
                self.times[k],
                tv_d,
                tv_f,
                j_d,
                j_f,
                tv_d - j_d,
                tv_f - j_f
            );
        }
        if !self.rigid {
            let mut lines = Vec::new();
            for (i, q) in self.quantities.iter().enumerate() {
                let off = self.off_branch(i);
                let on: Vec<usize> = (0..self.times.len())
                    .filter(|k| !off.contains(k) && self.fd[*k][i].is_finite())
                    .collect();
                let dd: Vec<f64> = on.iter().map(|&k| self.ddm[k][i]).collect();
                let fd: Vec<f64> = on.iter().map(|&k| self.fd[k][i]).collect();
                let (rel, k) = relative_difference(&fd, &dd);
                let flagged = if off.is_empty() {
                    "none".to_string()
                } else {
                    off.iter()
                        .map(|k| format!("{} (t = {:.3})", k + 1, self.times[*k]))
                        .collect::<Vec<_>>()
                        .join(", ")
                };
                lines.push(format!(
                    "d{}/d{sym}: flagged increments {flagged}; over the {} unflagged increments with both reruns, the largest difference FD vs DDM / largest DDM value there is {}",
                    q.label,
                    on.len(),
                    if on.is_empty() {
                        "undefined".to_string()
                    } else {
                        format!("{rel:.2e} (increment {})", on[k] + 1)
                    }
                ));
            }
            for (f, sign) in self.ccx_rerun_failures.iter().zip(["+", "-"]) {
                if let Some(f) = f {
                    let _ = writeln!(
                        s,
                        "\nThe rerun at {sym} (1 {sign} beta) did not reach the end: {f}. Its difference quotients are missing from there on (NaN in `ccx.csv`); CalculiX's nominal run and fricsens' DDM are complete."
                    );
                }
            }
            let _ = writeln!(
                s,
                "\nBranch check of the difference quotient: on a smooth history CalculiX's nominal value lies at the midpoint of its two reruns to O(beta^2); an increment is flagged when it misses it by more than a quarter of their half-difference (plus two print steps), i.e. a rerun changed branch (contact or stick-slip state, or CalculiX converged elsewhere) and the quotient measures a jump, not a derivative. {}.",
                lines.join("; ")
            );
        }
        let quantum: Vec<String> = self
            .quantities
            .iter()
            .enumerate()
            .map(|(i, q)| {
                let ulp = self.print_quantum(i);
                format!(
                    "{:.2e} {} on d{}/d{sym}",
                    ulp / (2.0 * self.beta * self.value),
                    self.derivative_unit(q),
                    q.label
                )
            })
            .collect();
        let per_node = if self.rigid {
            ""
        } else {
            " (a total reaction is summed by CalculiX before it is printed; a mean displacement averages printed values)"
        };
        let _ = writeln!(
            s,
            "\nCalculiX prints forces to 7 significant digits in its `.dat` file{per_node}, so its difference quotient moves in steps of one unit in the 7th digit over 2 beta {sym}: {}. A smaller beta makes that step larger; fricsens' DDM has no step and no beta.",
            quantum.join(", ")
        );
        if self.rigid {
            let _ = writeln!(
                s,
                "\nSmoothness: the total variation sums the changes between increments (the histories start from zero, so it is at least the largest value); a difference quotient carries the solver's tolerance and the branch changes of the perturbed runs divided by 2 beta mu, which shows as extra variation. The variation beyond the largest jump leaves out the one genuine jump (stick to slip when the block starts sliding) and measures the wiggles. The derivative histories are in `ccx.csv`, drawn in `ccx.svg`.\n"
            );
            let _ = writeln!(
                s,
                "![force and d force / d mu histories](ccx.svg)\n\nDeck: {} nodes, {} elements, element types {}, NLGEOM {}, normal penalty K = {:.3e}, tension at large clearance {:.3e}, stick slope {:.3e}.",
                d.nodes,
                d.elements,
                d.element_types.join(", "),
                if d.nlgeom { "on" } else { "off (small kinematics, as fricsens)" },
                d.normal_stiffness.first().copied().unwrap_or(f64::NAN),
                d.tension.first().copied().unwrap_or(f64::NAN),
                d.stick_slope.first().copied().unwrap_or(f64::NAN),
            );
        } else {
            let _ = writeln!(
                s,
                "\nSmoothness: the total variation sums the changes between increments (the histories start from zero, so it is at least the largest value); a difference quotient carries the solver's tolerance and the branch changes of the perturbed runs divided by 2 beta {sym}, which shows as extra variation. The variation beyond the largest jump leaves out the largest change between two increments (in a sliding scene the onset of sliding) and measures the wiggles. The histories are in `ccx.csv`; `ccx.svg` draws them, the derivatives times {sym} (`{sym} dq/d{sym}`, in the quantity's units), CalculiX's difference quotient without the flagged increments.\n"
            );
            let pairs: Vec<String> = (0..d.normal_stiffness.len())
                .map(|c| {
                    format!(
                        "pair {c}: K = {:.3e}, stick slope {:.3e}{}",
                        d.normal_stiffness[c],
                        d.stick_slope[c],
                        if d.adjust[c] > 0.0 {
                            format!(", ADJUST = {:.3e} mm", d.adjust[c])
                        } else {
                            String::new()
                        }
                    )
                })
                .collect();
            let _ = writeln!(
                s,
                "![compared responses and their derivatives](ccx.svg)\n\nDeck: {} nodes, {} elements, element types {}, NLGEOM {}, contact {}.",
                d.nodes,
                d.elements,
                d.element_types.join(", "),
                if d.nlgeom { "on" } else { "off (small kinematics, as fricsens)" },
                pairs.join("; ")
            );
        }
        s
    }

    /// The rigid case's force section.
    fn rigid_forces(&self, s: &mut String) {
        let d = &self.deck;
        let _ = writeln!(s, "### Forces\n");
        let _ = writeln!(
            s,
            "Force on the rigid block (fricsens: the target-force response; CalculiX: minus the reaction `RF` at the rigid body's reference node).\n"
        );
        let _ = writeln!(
            s,
            "| component | final fricsens (N) | final CalculiX (N) | largest difference / largest fricsens value | at increment |\n|---|---|---|---|---|"
        );
        for (i, q) in self.quantities.iter().enumerate() {
            let f = Self::column(&self.fricsens, i);
            let g = Self::column(&self.ccx, i);
            let (rel, k) = relative_difference(&g, &f);
            let _ = writeln!(
                s,
                "| {} | {:.6e} | {:.6e} | {:.2e} | {} (t = {:.2}) |",
                q.label,
                f.last().copied().unwrap_or(f64::NAN),
                g.last().copied().unwrap_or(f64::NAN),
                rel,
                k + 1,
                self.times[k]
            );
        }
        let k_n = d.normal_stiffness.first().copied().unwrap_or(f64::NAN);
        let lam = d.stick_slope.first().copied().unwrap_or(f64::NAN);
        let a = d.median_area.first().copied().unwrap_or(f64::NAN);
        let fy = (0..self.quantities.len())
            .map(|i| Self::largest(&self.fricsens, i))
            .fold(0.0, f64::max);
        let _ = writeln!(
            s,
            "\nWhy they differ. (1) Normal contact: fricsens enforces impenetrability with a Lagrange multiplier per hitting node; CalculiX's node-to-face contact is a penalty, `p = K d` with K = {k_n:.3e} N/mm^3 ({:.0} x fricsens' constraint scale over the median tributary area {a:.3} mm^2), so the block sinks into the slab by p / K in addition to the prescribed indentation: a softer response by about (p / K) / indentation. (2) Friction: both are Coulomb with an elastic stick range; fricsens' tangential stiffness per node over the median tributary area gives CalculiX's stick slope {lam:.3e} N/mm^3, equal on the fine region, larger where the nodes' areas are larger. (3) Elements: {} in CalculiX for fricsens' {}; {}. (4) Geometry: fricsens' rigid block is analytic (a rounded box); CalculiX's is meshed with {} facets per rounded edge and {} along the flat face. (5) Tolerance: the same number, on different norms (fricsens: Euclidean norm of the free residual over the reference force; CalculiX: the largest residual component over the mean element nodal force). The largest force is {fy:.4e} N.\n",
            self.export.normal_factor,
            d.element_types.join(", "),
            self.formulations.join(", "),
            self.element_note(),
            self.export.arc_segments,
            self.export.flat_segments,
        );
        let (p_mean, p_max) = self.pressure;
        if p_mean > 0.0 && self.normal_motion > 0.0 {
            let _ = writeln!(
                s,
                "Penalty overlap, estimated from fricsens' contact pressures at the end (mean {p_mean:.1} MPa, largest {p_max:.1} MPa over the closed nodes): p / K = {:.2e} mm on average, {:.2e} mm at most, i.e. {:.2} % and {:.2} % of the {} mm indentation.\n",
                p_mean / k_n,
                p_max / k_n,
                100.0 * p_mean / k_n / self.normal_motion,
                100.0 * p_max / k_n / self.normal_motion,
                self.normal_motion
            );
        }
    }

    /// The deformable case's section on the compared responses.
    fn responses(&self, s: &mut String) {
        let d = &self.deck;
        let pp = self.pressure_pair;
        let _ = writeln!(s, "### Responses\n");
        let _ = writeln!(
            s,
            "The scene's reaction responses (fricsens: the sum of the reactions of a node set in one component; CalculiX: the total `RF` of the same node set, `*NODE PRINT, TOTALS=ONLY`) and displacement responses (the mean displacement of a node set; CalculiX: the mean of the printed `U`). A scene with neither gets the mean displacement of each nodal load's nodes and the reaction of each nonzero prescribed displacement.\n"
        );
        let _ = writeln!(
            s,
            "| quantity | final fricsens | final CalculiX | largest difference / largest fricsens value | at increment | mean difference / largest fricsens value |\n|---|---|---|---|---|---|"
        );
        for (i, q) in self.quantities.iter().enumerate() {
            let f = Self::column(&self.fricsens, i);
            let g = Self::column(&self.ccx, i);
            let (rel, k) = relative_difference(&g, &f);
            let mean = g.iter().zip(&f).map(|(a, b)| (a - b).abs()).sum::<f64>()
                / f.len().max(1) as f64
                / Self::largest(&self.fricsens, i).max(f64::MIN_POSITIVE);
            let _ = writeln!(
                s,
                "| {} | {:.6e} {u} | {:.6e} {u} | {:.2e} | {} (t = {:.2}) | {:.2e} |",
                q.label,
                f.last().copied().unwrap_or(f64::NAN),
                g.last().copied().unwrap_or(f64::NAN),
                rel,
                k + 1,
                self.times[k],
                mean,
                u = q.unit()
            );
        }
        let k_n = d.normal_stiffness.get(pp).copied().unwrap_or(f64::NAN);
        let a = d.median_area.get(pp).copied().unwrap_or(f64::NAN);
        let friction = if self.symbol == "mu" {
            let lam = d.stick_slope.get(pp).copied().unwrap_or(f64::NAN);
            format!(" (2) Friction: both are Coulomb with an elastic stick range; fricsens' tangential stiffness scale over the median tributary area gives CalculiX's stick slope {lam:.3e} N/mm^3 (one slope per interaction; fricsens weights each node's stiffness by the element layer under it).")
        } else {
            " (2) Friction: none.".to_string()
        };
        let adjust = if d.adjust.iter().any(|&x| x > 0.0) {
            let a = d.adjust.iter().copied().fold(0.0, f64::max);
            format!(" (6) Start: a body of the scene is held by contact alone in some direction, so CalculiX's pair carries `ADJUST = {a:.3e}` mm: slave nodes that close to the master are moved onto it before the first increment (CalculiX's penalty needs contact at the first iteration, which fricsens' multipliers do not), a change of the geometry by at most that distance.")
        } else {
            String::new()
        };
        let _ = writeln!(
            s,
            "\nWhy they differ. (1) Normal contact: fricsens enforces impenetrability with a Lagrange multiplier per hitting node against the target faces (node to segment); CalculiX's is a surface-to-surface penalty (`TYPE=SURFACE TO SURFACE`), `p = K d` at the integration points of the slave faces, with K = {k_n:.3e} N/mm^3 ({:.0} x fricsens' constraint scale over the median tributary area {a:.3e} mm^2), so the bodies overlap by p / K.{friction} (3) Contact discretization: fricsens' hitting nodes meet the target facets, CalculiX's slave-face integration points do; over a contact patch a few elements wide the two resolve the pressure differently, and where one body slides over the other's facets both histories wiggle as nodes and integration points cross facet edges. (4) Elements: {} in CalculiX for fricsens' {}; {}. (5) Tolerance: the same number, on different norms (fricsens: Euclidean norm of the free residual over the reference force; CalculiX: the largest residual component over the mean element nodal force).{adjust}\n",
            self.export.normal_factor,
            d.element_types.join(", "),
            self.formulations.join(", "),
            self.element_note(),
        );
        let (p_mean, p_max) = self.pressure;
        if p_mean > 0.0 {
            let _ = write!(
                s,
                "Penalty overlap, estimated from fricsens' contact pressures at the end (mean {p_mean:.1} MPa, largest {p_max:.1} MPa over the closed nodes of pair {pp}): p / K = {:.2e} mm on average, {:.2e} mm at most",
                p_mean / k_n,
                p_max / k_n,
            );
            if self.normal_motion > 0.0 {
                let _ = write!(
                    s,
                    ", i.e. {:.2} % and {:.2} % of the {} mm of {}",
                    100.0 * p_mean / k_n / self.normal_motion,
                    100.0 * p_max / k_n / self.normal_motion,
                    self.normal_motion,
                    self.normal_motion_source
                );
            }
            let _ = writeln!(s, ".\n");
        }
    }

    /// Write `ccx.csv`, `ccx.svg`, `ccx.md` and `ccx.json` ([`CcxSummary`]) into `dir`.
    ///
    /// # Errors
    /// [`CcxError::Io`] and [`CcxError::Plot`].
    pub fn write(&self, dir: &Path) -> Result<(), CcxError> {
        std::fs::create_dir_all(dir).map_err(io_err(dir))?;
        let p = dir.join("ccx.csv");
        std::fs::write(&p, self.csv()).map_err(io_err(&p))?;
        crate::studies::plot::write_svg(&self.figure(), &dir.join("ccx.svg"))?;
        let p = dir.join("ccx.md");
        std::fs::write(&p, self.markdown()).map_err(io_err(&p))?;
        let p = dir.join("ccx.json");
        let json = serde_json::to_string_pretty(&self.summary()).expect("serialisable");
        std::fs::write(&p, json).map_err(io_err(&p))?;
        Ok(())
    }
}

/// The version line of `ccx -v`, e.g. "2.20".
pub(crate) fn ccx_version(ccx: &Path) -> Option<String> {
    let out = std::process::Command::new(ccx).arg("-v").output().ok()?;
    let text = String::from_utf8_lossy(&out.stdout).to_string();
    text.lines().find_map(|l| {
        l.trim()
            .strip_prefix("This is Version")
            .map(|v| v.trim().to_string())
    })
}

/// Keyword blocks of a deck, counted by name (for tests and sanity checks).
pub fn keyword_counts(deck: &str) -> BTreeMap<String, usize> {
    let mut m = BTreeMap::new();
    for l in deck.lines() {
        if l.starts_with('*') && !l.starts_with("**") {
            let kw = l[1..].split(',').next().unwrap_or("").trim().to_uppercase();
            *m.entry(kw).or_insert(0) += 1;
        }
    }
    m
}

/// The CalculiX element of a family, node order as it is (CalculiX numbers as Abaqus, and so
/// do these families): `C3D8` (full), `C3D8I` (incompatible modes), `C3D20` / `C3D20R`,
/// `C3D4`, `C3D10` (4 points), `C3D6`, `C3D15`. F-bar and tet10's 14-point rule have none.
fn calculix_element(family: crate::element::ElementFamily) -> Option<&'static str> {
    Some(match family.name() {
        "hex8" => "C3D8",
        "hex8-incompatible-modes" => "C3D8I",
        "hex20" => "C3D20",
        "hex20-reduced" => "C3D20R",
        "tet4" => "C3D4",
        "tet10" => "C3D10",
        "wedge6" => "C3D6",
        "wedge15" => "C3D15",
        _ => return None,
    })
}
