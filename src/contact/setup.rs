//! What a contact pair derives from the mesh, whoever made the mesh (the block generator, code,
//! an importer): hitting nodes of a face set and their tributary areas, the thickness of the
//! element layer under them, the candidate target faces within a search radius, the row scale
//! of the multiplier constraints and the default tangential penalty.
//!
//! The scene layer validates its fields, writes its notes and calls these; a model built in
//! code calls them directly.

use crate::element::SpringSet;
use crate::mesh::{FaceSet, Mesh};
use crate::model::{Body, Prescribed};
use nalgebra::Vector3;
use std::collections::{HashMap, HashSet};

/// Factor `c_T` of the default tangential penalty `c_T E* A_i / h_i`: the stiffness of the
/// element layer under a hitting node times this. With it the elastic slip in stick,
/// `mu p_n / eps_T = (mu sigma_n / (c_T E*)) h_i`, is a strain-sized fraction of the element
/// (0.5 % of it at mu = 0.5 and a contact pressure of E* / 100), and Newton meets a stick
/// stiffness no larger than the structure's next to it.
pub const TANGENTIAL_STIFFNESS_FACTOR: f64 = 1.0;

/// The nodes of a face set, sorted, each once: the hitting nodes of a face-set pair.
pub fn face_set_nodes(faces: &FaceSet) -> Vec<usize> {
    let mut nodes = faces.all_nodes().to_vec();
    nodes.sort();
    nodes.dedup();
    nodes
}

/// Per node of `nodes` (sorted, with tributary areas `area`) on the boundary faces `faces`:
/// `A_i / h_i`, the node's area over the thickness of the element layer under it (the mean of
/// twice the distance from each adjacent face's centre to its element's centre). `None` when a
/// face belongs to no element.
pub fn layer_stiffness(
    mesh: &Mesh,
    x: &[Vector3<f64>],
    faces: &FaceSet,
    nodes: &[usize],
    area: &[f64],
) -> Option<Vec<f64>> {
    let key = |f: &[usize]| {
        let mut k = f.to_vec();
        k.sort_unstable();
        k
    };
    let wanted: HashSet<Vec<usize>> = faces.iter().map(|f| key(f.nodes)).collect();
    let mut element_of: HashMap<Vec<usize>, usize> = HashMap::new();
    let mut face_nodes = Vec::new();
    for (e, (shape, conn)) in mesh.elements().enumerate() {
        for f in shape.faces() {
            face_nodes.clear();
            face_nodes.extend(f.nodes.iter().map(|&i| conn[i]));
            let k = key(&face_nodes);
            if wanted.contains(&k) {
                element_of.insert(k, e);
            }
        }
    }
    let index: HashMap<usize, usize> = nodes.iter().enumerate().map(|(k, n)| (*n, k)).collect();
    let mut h = vec![0.0; nodes.len()];
    let mut count = vec![0usize; nodes.len()];
    for f in faces.iter() {
        let e = *element_of.get(&key(f.nodes))?;
        let centre_f = f.nodes.iter().map(|n| x[*n]).sum::<Vector3<f64>>() / f.nodes.len() as f64;
        let conn = mesh.element_nodes(e);
        let centre_e = conn.iter().map(|n| x[*n]).sum::<Vector3<f64>>() / conn.len() as f64;
        let hf = 2.0 * (centre_e - centre_f).norm();
        for n in f.nodes {
            if let Some(&k) = index.get(n) {
                h[k] += hf;
                count[k] += 1;
            }
        }
    }
    Some(
        area.iter()
            .zip(h.iter().zip(&count))
            .map(|(a, (h, c))| a / (h / (*c).max(1) as f64))
            .collect(),
    )
}

/// The largest face size of a face set (quad4: its longer diagonal).
pub(crate) fn largest_face_diameter(x: &[Vector3<f64>], faces: &FaceSet) -> f64 {
    (0..faces.len())
        .map(|k| faces.face(k).family.diameter(&faces.coordinates(k, x)))
        .fold(0.0f64, f64::max)
}

/// Candidate target faces of each hitting node: the faces whose centre lies within `radius`
/// of the node (reference coordinates `x`) and that do not contain the node.
pub fn candidates(
    x: &[Vector3<f64>],
    faces: &FaceSet,
    hitting: &[usize],
    radius: f64,
) -> Vec<Vec<usize>> {
    let centres: Vec<Vector3<f64>> = (0..faces.len())
        .map(|k| faces.face(k).family.centre(&faces.coordinates(k, x)))
        .collect();
    hitting
        .iter()
        .map(|&s| {
            (0..faces.len())
                .filter(|&k| (x[s] - centres[k]).norm() <= radius && !faces.nodes(k).contains(&s))
                .collect()
        })
        .collect()
}

/// The solid element group of each node (the first solid group with an element on it; `None`
/// for a node on no solid element, such as a node held by springs alone).
pub(crate) fn node_groups(mesh: &Mesh) -> Vec<Option<usize>> {
    let mut g = vec![None; mesh.n_nodes()];
    for (k, group) in mesh.groups.iter().enumerate() {
        if !group.shape.is_solid() {
            continue;
        }
        for &n in &group.nodes {
            if g[n].is_none() {
                g[n] = Some(k);
            }
        }
    }
    g
}

/// How far the prescribed displacements can move nodes of `groups` (`None`: nodes on no
/// element): per component the sum of `|value| max |amplitude|` over the prescribed entries
/// acting on them, as a vector norm.
pub(crate) fn prescribed_travel(
    node_group: &[Option<usize>],
    prescribed: &[Prescribed],
    groups: &[Option<usize>],
) -> f64 {
    let mut m = [0.0f64; 3];
    for p in prescribed {
        if p.nodes.iter().any(|&n| groups.contains(&node_group[n])) {
            let amp = p
                .amplitude
                .points
                .iter()
                .map(|(_, v)| v.abs())
                .fold(0.0f64, f64::max);
            m[p.component] += p.value.abs() * amp;
        }
    }
    (m[0] * m[0] + m[1] * m[1] + m[2] * m[2]).sqrt()
}

/// Plane-strain modulus `E / (1 - nu^2)` of the body owning node `n` (0 for a node no body
/// owns).
pub(crate) fn plane_modulus(node_group: &[Option<usize>], bodies: &[Body], n: usize) -> f64 {
    match node_group[n] {
        Some(group) => bodies
            .iter()
            .find(|b| b.group == group)
            .map(|b| {
                let (young, nu) = b.material.elastic_constants();
                young / (1.0 - nu * nu)
            })
            .unwrap_or(0.0),
        None => 0.0,
    }
}

/// The contact modulus of a pair: the hitting body's plane-strain modulus against a rigid
/// target (`target_node = None`), `1 / (1 / E*_1 + 1 / E*_2)` against a deformable one.
pub fn contact_modulus(
    node_group: &[Option<usize>],
    bodies: &[Body],
    hitting_node: usize,
    target_node: Option<usize>,
) -> f64 {
    let e1 = plane_modulus(node_group, bodies, hitting_node);
    match target_node {
        Some(t) => {
            let e2 = plane_modulus(node_group, bodies, t);
            if e1 > 0.0 && e2 > 0.0 {
                1.0 / (1.0 / e1 + 1.0 / e2)
            } else {
                e1.max(e2)
            }
        }
        None => e1,
    }
}

/// Where the default constraint scale came from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ScaleSource {
    /// The largest Young's modulus times the square root of the mean tributary area.
    Modulus,
    /// The largest spring stiffness (no body with a modulus; 1 when that is zero too).
    Spring,
}

/// The default row scale `k` of the multiplier constraints (force per unit gap): the largest
/// E of the bodies times the square root of the mean tributary area; without bodies the
/// largest spring stiffness; 1 when that is not positive.
pub fn default_constraint_scale(
    bodies: &[Body],
    springs: &[SpringSet],
    area: &[f64],
) -> (f64, ScaleSource) {
    let e = bodies
        .iter()
        .map(|b| b.material.young())
        .fold(0.0f64, f64::max);
    let mean_area = area.iter().sum::<f64>() / area.len() as f64;
    let ks = springs
        .iter()
        .flat_map(|s| s.stiffness.iter().flatten().map(|v| v.abs()))
        .fold(0.0f64, f64::max);
    let (k, source) = if e > 0.0 {
        (e * mean_area.sqrt(), ScaleSource::Modulus)
    } else {
        (ks, ScaleSource::Spring)
    };
    (if k > 0.0 { k } else { 1.0 }, source)
}

/// The default tangential penalty of a pair: `c_T E* A_i / h_i` per hitting node.
#[derive(Clone, Debug, PartialEq)]
pub struct TangentialDefault {
    /// Each node's penalty.
    pub per_node: Vec<f64>,
    /// Their mean: the pair's `tangential_stiffness`.
    pub mean: f64,
    /// Each node's penalty over the mean: the pair's `tangential_weight`.
    pub weight: Vec<f64>,
}

/// The default tangential penalty per hitting node, `c_T E* A_i / h_i` (`layer`: the
/// `A_i / h_i` of [`layer_stiffness`], `e_star` the pair's [`contact_modulus`]).
pub fn default_tangential(e_star: f64, layer: &[f64]) -> TangentialDefault {
    let per_node: Vec<f64> = layer
        .iter()
        .map(|l| TANGENTIAL_STIFFNESS_FACTOR * e_star * l)
        .collect();
    let mean = per_node.iter().sum::<f64>() / per_node.len() as f64;
    let weight = per_node.iter().map(|k| k / mean).collect();
    TangentialDefault {
        per_node,
        mean,
        weight,
    }
}

/// Why a pair could not be set up from the mesh.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum SetupError {
    /// A face set has no face.
    #[error("the {which} face set is empty")]
    EmptyFaces {
        /// `hitting` or `target`.
        which: &'static str,
    },
    /// No target face lies within the search radius of any hitting node.
    #[error("no target face is within the search radius {radius:.3e} of any hitting node")]
    NeverTouching {
        /// The search radius used.
        radius: f64,
    },
    /// The surface elements give no default tangential penalty (a face on no element, or a
    /// body without modulus).
    #[error("no default tangential stiffness from the surface elements: give one")]
    NoTangentialDefault,
}

/// The default search radius of a pair whose first hitting node is `hitting` against
/// `target`: three of the target's largest face diameters, plus how far the prescribed
/// displacements can move the two bodies against each other. Returns the radius, the face
/// diameter and the travel.
pub(crate) fn default_search_radius(
    x: &[Vector3<f64>],
    node_group: &[Option<usize>],
    prescribed: &[Prescribed],
    hitting: usize,
    target: &FaceSet,
) -> (f64, f64, f64) {
    let diameter = largest_face_diameter(x, target);
    let groups = [node_group[hitting], node_group[target.nodes(0)[0]]];
    let travel = prescribed_travel(node_group, prescribed, &groups);
    (3.0 * diameter + travel, diameter, travel)
}

/// The hitting nodes of a pair that can touch its target, with their data: those with a
/// candidate face within the search radius (`candidates[i]` not empty).
pub(crate) struct Reachable {
    /// Kept hitting nodes.
    pub hitting: Vec<usize>,
    /// Their tributary areas.
    pub area: Vec<f64>,
    /// Their element layers' stiffness `A_i / h_i`, if known.
    pub layer: Option<Vec<f64>>,
    /// Their candidate faces.
    pub candidates: Vec<Vec<usize>>,
    /// The hitting nodes left out: no target face within the radius.
    pub dropped: Vec<usize>,
}

/// Keep the hitting nodes with candidate faces (and their areas, layers and candidates);
/// the others are `dropped`.
pub(crate) fn keep_reachable(
    hitting: &[usize],
    area: &[f64],
    layer: Option<&[f64]>,
    candidates: Vec<Vec<usize>>,
) -> Reachable {
    let keep: Vec<bool> = candidates.iter().map(|c| !c.is_empty()).collect();
    let pick = |v: &[f64]| -> Vec<f64> {
        v.iter()
            .zip(&keep)
            .filter(|(_, k)| **k)
            .map(|(x, _)| *x)
            .collect()
    };
    let nodes = |kept: bool| -> Vec<usize> {
        hitting
            .iter()
            .zip(&keep)
            .filter(|(_, k)| **k == kept)
            .map(|(n, _)| *n)
            .collect()
    };
    Reachable {
        hitting: nodes(true),
        area: pick(area),
        layer: layer.map(pick),
        candidates: candidates.into_iter().filter(|c| !c.is_empty()).collect(),
        dropped: nodes(false),
    }
}

/// What [`pair_between_faces`] chose besides the pair.
#[derive(Clone, Debug, PartialEq)]
pub struct PairDerivation {
    /// The search radius (given, or 3 face diameters plus the bodies' prescribed travel).
    pub radius: f64,
    /// Hitting nodes left out: no target face within the radius.
    pub dropped: Vec<usize>,
    /// Where the constraint scale came from.
    pub scale: ScaleSource,
}

/// A face-to-face contact pair of `model`'s mesh, with everything the mesh gives: the hitting
/// nodes of `hitting` and their tributary areas, the candidate faces of `target` within
/// `search_radius` (default: three face diameters plus how far the prescribed displacements
/// move the two bodies), the default constraint scale and the default tangential penalty
/// (`c_T E* A_i / h_i`). The same derivation a scene's pair gets; for models built in code or
/// imported. Lagrange multipliers, activation 1, smoothed normals on linear target faces;
/// change the returned pair's fields to taste.
#[allow(clippy::too_many_arguments)]
pub fn pair_between_faces(
    name: &str,
    mesh: &Mesh,
    bodies: &[Body],
    springs: &[SpringSet],
    prescribed: &[Prescribed],
    hitting: &FaceSet,
    target: &FaceSet,
    friction: Option<super::Friction>,
    search_radius: Option<f64>,
) -> Result<(super::ContactPair, PairDerivation), SetupError> {
    if hitting.is_empty() {
        return Err(SetupError::EmptyFaces { which: "hitting" });
    }
    if target.is_empty() {
        return Err(SetupError::EmptyFaces { which: "target" });
    }
    let x = mesh.coordinates::<f64>(&mesh.block_geometry());
    let node_group = node_groups(mesh);
    let nodes = face_set_nodes(hitting);
    let area = hitting.tributary_areas(&x, &nodes);
    let layer = layer_stiffness(mesh, &x, hitting, &nodes, &area);
    let radius = match search_radius {
        Some(r) => r,
        None => default_search_radius(&x, &node_group, prescribed, nodes[0], target).0,
    };
    let r = keep_reachable(
        &nodes,
        &area,
        layer.as_deref(),
        candidates(&x, target, &nodes, radius),
    );
    if r.hitting.is_empty() {
        return Err(SetupError::NeverTouching { radius });
    }
    let (kept, area, dropped) = (r.hitting, r.area, r.dropped);
    let layer = r.layer.ok_or(SetupError::NoTangentialDefault)?;
    let (scale, source) = default_constraint_scale(bodies, springs, &area);
    let e_star = contact_modulus(&node_group, bodies, kept[0], Some(target.nodes(0)[0]));
    let t = default_tangential(e_star, &layer);
    if !(t.mean.is_finite() && t.mean > 0.0) {
        return Err(SetupError::NoTangentialDefault);
    }
    let pair = super::ContactPair {
        name: name.to_string(),
        hitting: kept,
        area,
        hitting_faces: Some(hitting.clone()),
        target: super::Target::Faces {
            faces: target.clone(),
        },
        normal: super::NormalLaw::Lagrange,
        friction,
        tangential_stiffness: t.mean,
        tangential_weight: t.weight,
        constraint_scale: scale,
        activation: 1.0,
        candidates: r.candidates,
        // as a scene's pair: smoothed normals on linear target faces
        smoothing: !target.has_quadratic(),
    };
    Ok((
        pair,
        PairDerivation {
            radius,
            dropped,
            scale: source,
        },
    ))
}
