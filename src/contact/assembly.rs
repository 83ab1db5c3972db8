//! Contact in the global system: the fixed sparsity blocks of the hitting nodes, and the
//! evaluation of every pair's residual, tangent (forward AD over each node's local unknowns),
//! history update and branch decisions.
//!
//! Each hitting node owns one pattern block: its three displacement unknowns, the unknowns of
//! every node of its candidate target faces (faces within the pair's search radius in the
//! reference configuration) and its multiplier. The block never changes during a run, so the
//! symbolic factorization is done once however far the node slides over its candidates.

pub use super::eval::ContactEval;
use super::geometry::{
    closest_on_segments, closest_on_segments_keeping, node_jacobian, project_smoothed, Segment,
    SEGMENT_KEEP,
};
use super::{
    node_kernel, AnchorGeom, ContactChoice, ContactFailure, ContactPair, ContactState,
    KernelParams, MotionControl, StoredAnchor, Target, TargetGeom,
};
use crate::element::face::MAX_FACE_NODES;
use crate::mesh::FaceSet;
use crate::model::{node_dof, node_dofs, Lifted, Model};
use crate::scalar::Scalar;
use nalgebra::Vector3;
use num_dual::DualSVec64;
use std::convert::Infallible;

/// Local unknowns of one hitting node's block.
#[derive(Clone, Debug)]
pub(crate) struct NodeBlock {
    /// Global unknowns of the block: 3 of the hitting node, 3 per target node, the multiplier.
    pub dofs: Vec<usize>,
    /// Target nodes of the block, in block order.
    pub target_nodes: Vec<usize>,
    /// Pattern block index (set by the assembler).
    pub pattern_block: usize,
}

/// Contact layout of a model.
#[derive(Clone, Debug, Default)]
pub(crate) struct ContactLayout {
    /// `blocks[pair][node]`.
    pub blocks: Vec<Vec<NodeBlock>>,
    /// First multiplier unknown of each pair.
    pub lambda: Vec<usize>,
    /// First history scalar of each pair.
    pub history: Vec<usize>,
    /// First flat hitting-node index of each pair (for per-node result arrays).
    pub flat: Vec<usize>,
    /// Hitting nodes over all pairs (the length of the per-node result arrays).
    pub n_hitting: usize,
    /// `target[pair][k]`: the global unknown of motion entry `k` of a rigid target pushed by
    /// a force (its translation in that component), `None` for a prescribed translation.
    pub target: Vec<Vec<Option<usize>>>,
    /// Gap counted as touching in the active-set rule ([`super::KernelParams::touch`]): zero,
    /// or on a pair with a force-controlled target the round-off of its gaps, 1e-12 times the
    /// largest reference coordinate of its hitting nodes (measured against the round-off of a
    /// cylinder's `|x - c| - R`, a few 1e-16 of the coordinates).
    pub touch: Vec<f64>,
    /// `smooth_group[pair][face]`: the smooth group of each target face of a pair with
    /// smoothed normals ([`smooth_groups`]); empty for the other pairs.
    pub smooth_group: Vec<Vec<usize>>,
}

impl ContactLayout {
    /// Lay out the multipliers after `first_lambda`, the translations of force-controlled
    /// rigid targets after `first_target` and the histories after `first_history` (the
    /// numbering of [`Model::dof_map`]).
    pub fn new(
        model: &Model,
        first_lambda: usize,
        first_target: usize,
        first_history: usize,
    ) -> Self {
        let mut l = ContactLayout::default();
        let mut next_l = first_lambda;
        let mut next_t = first_target;
        let mut next_h = first_history;
        let mut flat = 0;
        // the reference coordinates, made where a pair needs them
        let reference = std::cell::OnceCell::new();
        let coords = || {
            reference.get_or_init(|| model.mesh.coordinates::<f64>(&model.mesh.block_geometry()))
        };
        for pair in &model.contacts {
            l.lambda.push(next_l);
            l.history.push(next_h);
            l.flat.push(flat);
            let target = pair.pushed_unknowns(&mut next_t);
            let touch = if target.iter().any(Option::is_some) {
                let x = coords();
                let size = (pair.hitting.iter()).fold(0.0f64, |m, &n| m.max(x[n].amax()));
                1e-12 * size
            } else {
                0.0
            };
            l.touch.push(touch);
            l.smooth_group.push(match &pair.target {
                Target::Faces { faces } if pair.smoothing => smooth_groups(faces, coords()),
                _ => Vec::new(),
            });
            let mut blocks = Vec::new();
            for (i, &s) in pair.hitting.iter().enumerate() {
                let mut target_nodes = Vec::new();
                if let Target::Faces { faces } = &pair.target {
                    for &f in &pair.candidates[i] {
                        for &n in faces.nodes(f) {
                            if !target_nodes.contains(&n) {
                                target_nodes.push(n);
                            }
                        }
                    }
                }
                let mut dofs: Vec<usize> = node_dofs(s).collect();
                for &n in &target_nodes {
                    dofs.extend(node_dofs(n));
                }
                // a pushed rigid target's translations (it has no target nodes)
                dofs.extend(target.iter().flatten());
                dofs.push(next_l + i);
                blocks.push(NodeBlock {
                    dofs,
                    target_nodes,
                    pattern_block: usize::MAX,
                });
            }
            next_l += pair.hitting.len();
            next_h += pair.history_len() * pair.hitting.len();
            flat += pair.hitting.len();
            l.blocks.push(blocks);
            l.target.push(target);
        }
        l.n_hitting = flat;
        l
    }
}

/// A contact failure with its place.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("contact pair '{pair}', hitting node {node}: {failure}")]
pub struct ContactError {
    /// Name of the contact pair.
    pub pair: String,
    /// The hitting node (global mesh node number).
    pub node: usize,
    /// What went wrong.
    pub failure: ContactFailure,
}

fn node_disp<S: Scalar>(z: &[S], n: usize) -> Vector3<S> {
    Vector3::from_column_slice(&z[node_dofs(n)])
}

fn node_pos<S: Scalar>(lifted: &Lifted<S>, z: &[S], n: usize) -> Vector3<S> {
    lifted.coords[n] + node_disp(z, n)
}

/// Target face `f` with its nodes at `position(node)`.
fn segment<T: Scalar>(
    faces: &FaceSet,
    f: usize,
    position: impl Fn(usize) -> Vector3<T>,
) -> Segment<T> {
    match try_segment(faces, f, |n| Ok::<_, Infallible>(position(n))) {
        Ok(seg) => seg,
        Err(never) => match never {},
    }
}

/// [`segment`] with a `position` that may fail.
fn try_segment<T: Scalar, E>(
    faces: &FaceSet,
    f: usize,
    mut position: impl FnMut(usize) -> Result<Vector3<T>, E>,
) -> Result<Segment<T>, E> {
    let face = faces.face(f);
    let mut nodes = [Vector3::zeros(); MAX_FACE_NODES];
    for (x, &n) in nodes.iter_mut().zip(face.nodes) {
        *x = position(n)?;
    }
    Ok(Segment {
        family: face.family,
        nodes,
    })
}

/// The stick anchor at `xi` on target face `f`: reference positions `reference(node)` and
/// displacements `displacement(node)` of its nodes.
fn face_anchor<T: Scalar>(
    faces: &FaceSet,
    f: usize,
    reference: impl Fn(usize) -> Vector3<T>,
    mut displacement: impl FnMut(usize) -> Result<Vector3<T>, ContactFailure>,
    xi: [T; 2],
) -> Result<AnchorGeom<T>, ContactFailure> {
    let face = faces.face(f);
    let mut r = [Vector3::zeros(); MAX_FACE_NODES];
    let mut d = [Vector3::zeros(); MAX_FACE_NODES];
    for (a, &n) in face.nodes.iter().enumerate() {
        r[a] = reference(n);
        d[a] = displacement(n)?;
    }
    Ok(AnchorGeom::Face {
        family: face.family,
        reference: r,
        displacement: d,
        xi,
    })
}

/// Which candidate face is closest to `x` (a branch decision, on real parts), and the
/// convected coordinates of the closest point on it; face `keep` (the last Newton iterate's)
/// is kept while `x` projects onto it within [`super::geometry::SEGMENT_KEEP`], and at a
/// shared boundary point against a face better aligned by less than
/// [`super::geometry::ALIGN_KEEP`].
fn closest_face<S: Scalar>(
    lifted: &Lifted<S>,
    z: &[S],
    faces: &FaceSet,
    candidates: &[usize],
    x: &Vector3<S>,
    keep: Option<usize>,
) -> Result<(usize, [f64; 2]), ContactFailure> {
    let segments: Vec<Segment<f64>> = candidates
        .iter()
        .map(|&f| segment(faces, f, |n| node_pos(lifted, z, n).map(|v| v.value())))
        .collect();
    let xr = x.map(|v| v.value());
    let keep = keep.and_then(|f| candidates.iter().position(|&c| c == f));
    let (k, pr) =
        closest_on_segments_keeping(&xr, &segments, keep).map_err(ContactFailure::Geometry)?;
    Ok((candidates[k], [pr.xi[0], pr.xi[1]]))
}

/// The candidate faces (of `candidates`) other than `f` that hold a node of face `f`: those
/// of `f`'s smooth group ([`smooth_groups`]) are the faces whose normals [`nodal_normals`]
/// sums at `f`'s nodes.
fn faces_around(faces: &FaceSet, f: usize, candidates: &[usize]) -> Vec<usize> {
    let own = faces.nodes(f);
    (candidates.iter().copied())
        .filter(|&g| g != f && faces.nodes(g).iter().any(|n| own.contains(n)))
        .collect()
}

/// Faces of a smoothed target whose reference normals differ by more than this angle (in
/// degrees) are not smoothed into each other where they meet, unless a chain of gentler
/// faces joins them ([`smooth_groups`]: a crease that ends inside the surface): the edge is
/// a feature, a block's corner, and a node's normal there averaged over both sides would
/// tilt the gap over the whole rim face (by 45 degrees at a right-angled corner). 60 degrees
/// keeps a curved surface faceted coarsely (a quarter circle in two facets, 45 degrees apart)
/// smooth, and the corners of boxes and wedges sharp.
pub(crate) const FEATURE_ANGLE_DEGREES: f64 = 60.0;

/// The smooth group of each face of `faces` (nodes at reference coordinates `x`): two faces
/// sharing a node are in one group where their normals (each the sum of its nodal
/// `t_1 × t_2`) lie within [`FEATURE_ANGLE_DEGREES`] of each other, and groups are closed
/// under that (the connected parts of the surface between its feature edges). A decision on
/// the reference geometry, made once: the groups do not change with the deformation or
/// within a run (a finite-difference rerun's perturbed geometry decides its own: an edge at
/// 60 degrees to round-off could fall either way). Groups are numbered by their lowest face.
pub(crate) fn smooth_groups(faces: &FaceSet, x: &[Vector3<f64>]) -> Vec<usize> {
    let nf = faces.len();
    let normal = |f: usize| {
        let seg = segment(faces, f, |n| x[n]);
        let n: Vector3<f64> = (0..seg.family.n_nodes())
            .map(|a| node_jacobian(&seg, a))
            .sum();
        n.try_normalize(0.0)
    };
    let normals: Vec<Option<Vector3<f64>>> = (0..nf).map(normal).collect();
    let cos_feature = FEATURE_ANGLE_DEGREES.to_radians().cos();
    // union-find over the faces, joined across smooth shared nodes
    let mut parent: Vec<usize> = (0..nf).collect();
    fn root(parent: &mut [usize], mut f: usize) -> usize {
        while parent[f] != f {
            parent[f] = parent[parent[f]];
            f = parent[f];
        }
        f
    }
    // the faces holding each node (the groups, connected parts, do not depend on the order)
    let mut at_node: Vec<Vec<usize>> = vec![Vec::new(); x.len()];
    for f in 0..nf {
        for &n in faces.nodes(f) {
            at_node[n].push(f);
        }
    }
    for held in &at_node {
        for (k, &f) in held.iter().enumerate() {
            for &g in &held[k + 1..] {
                let smooth = match (normals[f], normals[g]) {
                    (Some(a), Some(b)) => a.dot(&b) >= cos_feature,
                    _ => false,
                };
                if smooth {
                    let (rf, rg) = (root(&mut parent, f), root(&mut parent, g));
                    parent[rf.max(rg)] = rf.min(rg);
                }
            }
        }
    }
    (0..nf).map(|f| root(&mut parent, f)).collect()
}

/// The target's unit outward normals at `keys`, each a node and a smooth group
/// ([`ContactPair::smoothing`], [`smooth_groups`]: `groups` per face): at each, the sum of
/// `t_1 × t_2` at the node over the candidate faces of that group that hold it (each face's
/// Jacobian there: a quad4's area over four, a tri3's twice its area), normalised; `None`
/// where the sum vanishes. The sum runs over the same faces in the order of `candidates`
/// whichever face asks, so faces of a group sharing a node share its normal to the last bit.
/// Node `n` is at `position(n)`.
fn nodal_normals<T: Scalar, E>(
    faces: &FaceSet,
    candidates: &[usize],
    groups: &[usize],
    keys: &[(usize, usize)],
    mut position: impl FnMut(usize) -> Result<Vector3<T>, E>,
) -> Result<Vec<Option<Vector3<T>>>, E> {
    let mut sum = vec![Vector3::zeros(); keys.len()];
    for &g in candidates {
        let group = groups[g];
        let held = faces.nodes(g);
        if !held.iter().any(|n| keys.contains(&(*n, group))) {
            continue;
        }
        let seg = try_segment(faces, g, &mut position)?;
        for (b, n) in held.iter().enumerate() {
            if let Some(a) = keys.iter().position(|k| *k == (*n, group)) {
                sum[a] += node_jacobian(&seg, b);
            }
        }
    }
    Ok(sum
        .into_iter()
        .map(|n| {
            let len = n.dot(&n).sqrt();
            (len.value() > 0.0 && len.value().is_finite()).then(|| n / len)
        })
        .collect())
}

/// The keys ([`nodal_normals`]) of face `f`'s nodes.
fn face_keys<'a>(
    faces: &'a FaceSet,
    f: usize,
    groups: &[usize],
) -> impl Iterator<Item = (usize, usize)> + 'a {
    let group = groups[f];
    faces.nodes(f).iter().map(move |&n| (n, group))
}

/// Face `f`'s nodal normals, looked up in `normals` (of [`nodal_normals`] at `keys`, which
/// hold `f`'s); `None` where one of them vanishes.
fn face_normals<T: Scalar>(
    faces: &FaceSet,
    f: usize,
    groups: &[usize],
    keys: &[(usize, usize)],
    normals: &[Option<Vector3<T>>],
) -> Option<[Vector3<T>; MAX_FACE_NODES]> {
    let mut out = [Vector3::zeros(); MAX_FACE_NODES];
    for (o, key) in out.iter_mut().zip(face_keys(faces, f, groups)) {
        *o = normals[keys.iter().position(|k| *k == key)?]?;
    }
    Some(out)
}

/// The nodal normals of the contact face `f` in `T`, or the typed failure where one vanishes.
fn contact_face_normals<T: Scalar>(
    faces: &FaceSet,
    f: usize,
    candidates: &[usize],
    groups: &[usize],
    position: impl FnMut(usize) -> Result<Vector3<T>, ContactFailure>,
) -> Result<[Vector3<T>; MAX_FACE_NODES], ContactFailure> {
    // the face's own term is among the candidates' (every contact face is a candidate)
    debug_assert!(candidates.contains(&f), "contact face {f} not a candidate");
    let keys: Vec<(usize, usize)> = face_keys(faces, f, groups).collect();
    let normals = nodal_normals(faces, candidates, groups, &keys, position)?;
    face_normals(faces, f, groups, &keys, &normals).ok_or(ContactFailure::Geometry(
        super::geometry::GeometryError::DegenerateSegment {
            reason: "the faces around a target node have no mean normal",
        },
    ))
}

/// With smoothed normals, the contact face: of `start` and the candidate faces around it,
/// the one onto which `xr` projects along the smoothed normals (each face's group's:
/// `groups`, [`smooth_groups`]; the least outside it; ties: `keep`, the last converged
/// state's face, then `start`, then the lowest index; a face whose projection fails is passed
/// over), and the start of the projection on it; target node `n` is at `position(n)`. `None`
/// where `xr` projects onto none of them, further than [`SEGMENT_KEEP`] beyond a free edge
/// of the target: there the normals interpolated over
/// the extension of a face would be extrapolated far, and the node is projected onto the
/// face as without smoothing. Measured on the physics fuzzer (seeds 0-999): with the normals
/// extrapolated however far (no band) 986 complete, seeds 15, 748 and 972 failing and 976
/// passing; with this band 988, the other way round; at 1.0, 742 passes and 748 fails; at
/// 1e-10 the nodes on the end planes of extruded blocks, on the free edge to round-off,
/// flipped between the two and seven more seeds failed. A branch decision, on real parts.
fn smoothed_face(
    faces: &FaceSet,
    candidates: &[usize],
    groups: &[usize],
    position: impl Fn(usize) -> Vector3<f64>,
    xr: &Vector3<f64>,
    start: (usize, [f64; 2]),
    keep: Option<usize>,
) -> Option<(usize, [f64; 2])> {
    let mut best: Option<(f64, usize, [f64; 2])> = None;
    let mut tried = vec![start.0];
    tried.extend(faces_around(faces, start.0, candidates));
    // the last converged state's face wins ties: a node beyond a free edge, or on an edge,
    // projects equally far outside two faces, and the faceted pick alternates between them
    let preferred = match keep {
        Some(k) if candidates.contains(&k) => {
            if !tried.contains(&k) {
                tried.push(k);
            }
            k
        }
        _ => start.0,
    };
    // every tried face's nodal normals, each node's (of a group) once
    let mut keys: Vec<(usize, usize)> = Vec::new();
    for &g in &tried {
        for key in face_keys(faces, g, groups) {
            if !keys.contains(&key) {
                keys.push(key);
            }
        }
    }
    let normals = match nodal_normals(faces, candidates, groups, &keys, |n| {
        Ok::<_, Infallible>(position(n))
    }) {
        Ok(normals) => normals,
        Err(never) => match never {},
    };
    for g in tried {
        let Some(normals) = face_normals(faces, g, groups, &keys, &normals) else {
            continue;
        };
        let seg = segment(faces, g, &position);
        let from = if g == start.0 {
            start.1
        } else {
            seg.family.centre_st()
        };
        let Ok(p) = project_smoothed(xr, &seg, &normals, from) else {
            continue;
        };
        let out = seg.family.distance_outside(p.xi);
        let better = match best {
            None => true,
            // ties: the preferred face, then the start, then the lowest index
            Some((o, b, _)) => {
                let rank = |f: usize| (f != preferred, f != start.0, f);
                out < o - 1e-12 || (out <= o + 1e-12 && rank(g) < rank(b))
            }
        };
        if better {
            best = Some((out, g, p.xi));
        }
    }
    // nodes on a free edge (the faces of an extruded block at its end planes) project onto
    // it to round-off, on either side: the band keeps them smoothed
    best.filter(|(out, g, _)| {
        let width = if faces.face(*g).family.is_triangle() {
            0.5
        } else {
            1.0
        };
        *out <= SEGMENT_KEEP * width
    })
    .map(|(_, g, xi)| (g, xi))
}

/// Rigid translation of a pair's target at time `t`: the prescribed components from the
/// motion magnitudes `values`; a pushed target's ([`MotionControl::Force`]) from their
/// unknowns in `z` (`target`: the pair's [`ContactLayout::target`]), zero without them (where
/// the scene put it: at t = 0, or before the run).
pub(crate) fn rigid_translation<S: Scalar>(
    pair: &ContactPair,
    values: &[S],
    t: f64,
    pushed: Option<(&[Option<usize>], &[S])>,
) -> Vector3<S> {
    let mut d = Vector3::zeros();
    if let Target::Rigid { motion, .. } = &pair.target {
        for (m, v) in motion.iter().zip(values) {
            if m.control == MotionControl::Displacement {
                d[m.component] += *v * m.amplitude.at(t);
            }
        }
    }
    if let Some((target, z)) = pushed {
        for (_, dof, m) in pair.pushed(target) {
            d[m.component] += z[dof];
        }
    }
    d
}

/// The tangent of one hitting node: the dense `m x m` matrix (row-major) of the `m` block
/// unknowns it couples (`index`: positions in the node's block; every other entry of the block
/// is zero). A block spans all candidate faces; the tangent only the contact and anchor faces.
#[derive(Clone, Debug)]
pub(crate) struct LocalTangent {
    /// Positions of the rows and columns in the node's block.
    pub index: Vec<usize>,
    /// Row-major `index.len()` squared values.
    pub values: Vec<f64>,
}

/// Evaluate every contact pair: adds to `residual`, writes the friction history into
/// `hist_new`, fills `out`, and returns the local tangents (block-major, dense) if wanted.
#[allow(clippy::too_many_arguments)]
pub(crate) fn evaluate<S: Scalar>(
    model: &Model,
    layout: &ContactLayout,
    lifted: &Lifted<S>,
    z: &[S],
    hist_old: &[S],
    time: f64,
    frozen: Option<&[ContactChoice]>,
    keep_faces: Option<&[ContactChoice]>,
    force_stick: Option<&[bool]>,
    skip_nodes: Option<&[bool]>,
    terms: crate::terms::Terms,
    want_tangent: bool,
    residual: &mut [S],
    hist_new: &mut [S],
    out: &mut ContactEval<S>,
    tangents: &mut Vec<(usize, LocalTangent)>,
) -> Result<(), ContactError> {
    tangents.clear();
    for (p, pair) in model.contacts.iter().enumerate() {
        out.pair_force[p] = Vector3::zeros();
        // the contact forces of the terms the residual takes (`terms`), for a pushed
        // target's rows
        let mut pair_terms = Vector3::<S>::zeros();
        let target_dofs = &layout.target[p];
        let d: Vector3<S> =
            rigid_translation(pair, &lifted.rigid_motion[p], time, Some((target_dofs, z)));
        out.translation[p] = d;
        let nh = pair.history_len();
        let fparams = &lifted.friction[p];
        let eps_t = lifted.tangential[p];
        let mut par = KernelParams {
            normal: pair.normal,
            friction: pair.friction.as_ref(),
            friction_params: fparams,
            eps_t,
            k: pair.constraint_scale,
            activation: pair.activation,
            area: S::one(),
            touch: layout.touch[p],
            elastic_stick: false,
        };
        // the current pressure areas, for the Cauchy pressure (a pass over some nodes alone
        // leaves them: `Frozen::skip_contact`)
        if let (Some(faces), None) = (&pair.hitting_faces, skip_nodes) {
            let current = faces.pressure_areas_at(|n| node_pos(lifted, z, n), &pair.hitting);
            let first = layout.flat[p];
            out.current_area[first..first + current.len()].copy_from_slice(&current);
        }
        for (i, &s) in pair.hitting.iter().enumerate() {
            let flat = layout.flat[p] + i;
            if skip_nodes.is_some_and(|m| m[flat]) {
                let h0 = layout.history[p] + nh * i;
                hist_new[h0..h0 + nh].copy_from_slice(&hist_old[h0..h0 + nh]);
                out.normal_force[flat] = S::zero();
                out.traction[flat] = Vector3::zeros();
                out.cancelling[flat] = 0.0;
                continue;
            }
            par.area = lifted.area[p][i];
            par.friction_params = lifted.friction_of(p, i);
            out.area[flat] = lifted.pressure_area[p][i];
            par.eps_t = eps_t * pair.tangential_weight[i];
            let block = &layout.blocks[p][i];
            let lam_dof = layout.lambda[p] + i;
            let h0 = layout.history[p] + nh * i;
            let x_ref = lifted.coords[s];
            let u = node_disp(z, s);
            let x = x_ref + u;
            let lambda = z[lam_dof];
            let err = |failure| ContactError {
                pair: pair.name.clone(),
                node: s,
                failure,
            };
            let fz = frozen.map(|f| f[flat]);
            // ---- branch decisions on real parts: contact face ----
            let (face, xi_start) = match &pair.target {
                Target::Faces { faces } => match fz {
                    Some(c) => (c.face, [0.0, 0.0]),
                    None => closest_face(
                        lifted,
                        z,
                        faces,
                        &pair.candidates[i],
                        &x,
                        keep_faces.and_then(|k| k.get(flat)).map(|c| c.face),
                    )
                    .map_err(err)?,
                },
                Target::Rigid { .. } => (0, [0.0, 0.0]),
            };
            // smoothed normals where the node projects onto the target's faces along them
            let (face, xi_start, smoothed) = match &pair.target {
                Target::Faces { faces } if pair.smoothing => match fz {
                    Some(c) => (face, xi_start, c.smoothed),
                    None => {
                        let keep = keep_faces.and_then(|k| k.get(flat)).map(|c| c.face);
                        let at = (face, xi_start);
                        let groups = &layout.smooth_group[p];
                        let position = |n| node_pos(lifted, z, n).map(|v| v.value());
                        let xr = x.map(|v| v.value());
                        smoothed_face(faces, &pair.candidates[i], groups, position, &xr, at, keep)
                            .map_or((face, xi_start, false), |(f, xi)| (f, xi, true))
                    }
                },
                _ => (face, xi_start, false),
            };
            let target = match &pair.target {
                Target::Faces { faces } => TargetGeom::Face {
                    segment: segment(faces, face, |n| node_pos(lifted, z, n)),
                    xi_start,
                    normals: if smoothed {
                        Some(
                            contact_face_normals(
                                faces,
                                face,
                                &pair.candidates[i],
                                &layout.smooth_group[p],
                                |n| Ok(node_pos(lifted, z, n)),
                            )
                            .map_err(err)?,
                        )
                    } else {
                        None
                    },
                },
                Target::Rigid { surface, .. } => TargetGeom::Rigid { surface, d },
            };
            let h_old = &hist_old[h0..h0 + nh];
            let lambda_bar = pair.lambda_bar(h_old).unwrap_or(S::zero());
            let stored = pair.anchor(h_old);
            let anchor = match (stored, &pair.target) {
                (Some(StoredAnchor::Face { face: af, xi }), Target::Faces { faces }) => Some(
                    face_anchor(
                        faces,
                        af.min(faces.len() - 1),
                        |n| lifted.coords[n],
                        |n| Ok(node_disp(z, n)),
                        xi,
                    )
                    .map_err(err)?,
                ),
                (Some(StoredAnchor::Offset(offset)), _) => Some(AnchorGeom::Rigid { offset, d }),
                _ => None,
            };
            let kernel = |par: &KernelParams<'_, S>, state| {
                node_kernel(
                    &x_ref,
                    &u,
                    lambda,
                    lambda_bar,
                    &target,
                    anchor.as_ref(),
                    par,
                    state,
                )
                .map_err(err)
            };
            let mut ko = kernel(&par, fz.map(|c| c.state))?;
            // a node the solver forces to stick: evaluated again on the stick branch (its
            // normal state stays the free decision: slip implies closed) with the elastic
            // predictor as its friction force (KernelParams::elastic_stick), and the tangent
            // and the history follow that branch
            let mut fz = fz;
            let mut forced = false;
            if fz.is_none()
                && ko.state == ContactState::Slip
                && force_stick.and_then(|f| f.get(flat)).copied() == Some(true)
            {
                forced = true;
                let stick = KernelParams {
                    elastic_stick: true,
                    ..par
                };
                ko = kernel(&stick, Some(ContactState::Stick))?;
                fz = Some(ContactChoice {
                    state: ContactState::Stick,
                    face,
                    anchor_face: face,
                    smoothed,
                });
            }
            // ---- residual ----
            let normal_part = ko.projection.normal * ko.p_n;
            let force = if terms.contact_normal && terms.friction {
                ko.force
            } else {
                let mut f = Vector3::zeros();
                if terms.contact_normal {
                    f += normal_part;
                }
                if terms.friction {
                    f += ko.force - normal_part;
                }
                f
            };
            pair_terms += force;
            for c in 0..3 {
                residual[node_dof(s, c)] -= force[c];
            }
            if let Target::Faces { faces } = &pair.target {
                for (a, &n) in faces.nodes(face).iter().enumerate() {
                    for c in 0..3 {
                        residual[node_dof(n, c)] += ko.weights[a] * force[c];
                    }
                }
            }
            if terms.contact_normal {
                residual[lam_dof] += ko.r_lambda;
            }
            out.pair_force[p] += ko.force;
            out.normal_force[flat] = ko.p_n;
            out.force[flat] = ko.force.map(|v| v.value());
            out.traction[flat] = ko.force - normal_part;
            out.distance[flat] = (ko.normal_distance, ko.slip_ratio);
            out.gap[flat] = ko.projection.gap.value();
            out.cancelling[flat] = ko.cancelling;
            let h_new = &mut hist_new[h0..h0 + nh];
            if pair.augmented() {
                // the estimate is updated by the solver's augmentation, not within Newton
                pair.set_lambda_bar(h_new, lambda_bar);
            }
            // ---- history: the stick anchor ----
            let mut anchor_face = face;
            if let Some(old) = stored {
                match (&pair.target, ko.state) {
                    (_, ContactState::Stick) => {
                        // the anchor stays: its scalars are kept as stored (with their
                        // derivative parts)
                        pair.keep_anchor(h_old, h_new);
                        anchor_face = match old {
                            StoredAnchor::Face { face, .. } => face,
                            // a rigid target has no anchor face; the number recorded is the
                            // offset's first component truncated, as it always was (the
                            // solver compares whole choice vectors)
                            StoredAnchor::Offset(a) => a[0].value() as usize,
                        };
                    }
                    (Target::Rigid { .. }, _) => {
                        // offset from the node's reference position, in the body's frame:
                        // sep = u - d - offset
                        let a = (u - d) - ko.new_separation;
                        pair.set_anchor(h_new, StoredAnchor::Offset(a));
                    }
                    (Target::Faces { .. }, ContactState::Open | ContactState::Closed) => {
                        pair.set_anchor(
                            h_new,
                            StoredAnchor::Face {
                                face,
                                xi: ko.projection.xi,
                            },
                        );
                    }
                    (Target::Faces { faces }, ContactState::Slip) => {
                        // re-project the new anchor: which face is a real-part decision
                        anchor_face = match fz {
                            Some(c) => c.anchor_face,
                            None => {
                                // on the node's contact face while it lies on it (within the
                                // same hysteresis), else the closest
                                closest_face(
                                    lifted,
                                    z,
                                    faces,
                                    &pair.candidates[i],
                                    &ko.new_anchor,
                                    Some(face),
                                )
                                .map_err(err)?
                                .0
                            }
                        };
                        let seg = segment(faces, anchor_face, |n| node_pos(lifted, z, n));
                        let pa = project_on_segment_s(&ko.new_anchor, &seg).map_err(err)?;
                        pair.set_anchor(
                            h_new,
                            StoredAnchor::Face {
                                face: anchor_face,
                                xi: pa,
                            },
                        );
                    }
                }
            }
            out.choice[flat] = ContactChoice {
                state: ko.state,
                face,
                anchor_face,
                smoothed,
            };
            // ---- tangent by forward AD over the node's local unknowns ----
            if want_tangent {
                let kt = local_tangent(
                    model,
                    layout,
                    lifted,
                    z,
                    hist_old,
                    time,
                    (p, i, face),
                    fz,
                    forced,
                    smoothed.then_some(xi_start),
                )
                .map_err(err)?;
                tangents.push((block.pattern_block, kt));
            }
        }
        // a pushed target's equilibrium rows: the contact forces on the hitting nodes less
        // the applied force
        for (k, dof, m) in pair.pushed(target_dofs) {
            let applied = lifted.rigid_motion[p][k] * m.amplitude.at(time);
            residual[dof] += match (terms == crate::terms::Terms::ALL, terms.loads) {
                (true, _) => out.pair_force[p][m.component] - applied,
                (false, true) => pair_terms[m.component] - applied,
                (false, false) => pair_terms[m.component],
            };
        }
    }
    Ok(())
}

fn project_on_segment_s<S: Scalar>(
    x: &Vector3<S>,
    seg: &Segment<S>,
) -> Result<[S; 2], ContactFailure> {
    let p = super::geometry::project_on_segment(x, seg, seg.family.centre_st())
        .map_err(ContactFailure::Geometry)?;
    Ok(p.xi)
}

/// The dense block tangent of one hitting node (rows and columns in block order), from one
/// evaluation of the kernel with the node's local unknowns seeded: the hitting node (3), the
/// nodes of the contact face, of the faces around it in its smooth group where its normals
/// are smoothed (`smoothed`), and of the stick anchor's face (3 each, shared nodes once), the multiplier
/// (1). The dual type is as wide as the seeds need: 4 against a rigid target, 16 where the
/// anchor lies on the contact face (or there is none), 28 where it lies on another face, 52
/// or 76 with smoothed normals (every op on a 28-wide dual costs about seven times one on a
/// 4-wide one); more is [`ContactFailure::TooManySeeds`]. The smoothed projection starts
/// from `xi_start`, where the residual's converged.
#[allow(clippy::too_many_arguments)]
fn local_tangent<S: Scalar>(
    model: &Model,
    layout: &ContactLayout,
    lifted: &Lifted<S>,
    z: &[S],
    hist_old: &[S],
    time: f64,
    (p, i, face): (usize, usize, usize),
    fz: Option<ContactChoice>,
    forced: bool,
    smoothed: Option<[f64; 2]>,
) -> Result<LocalTangent, ContactFailure> {
    let pair = &model.contacts[p];
    let seeds = match &pair.target {
        Target::Faces { faces } => {
            // the contact face's nodes, those of the faces around it in its smooth group where
            // the normals are smoothed, and the anchor face's others
            let mut nodes: Vec<usize> = faces.nodes(face).to_vec();
            let mut add = |g: usize| {
                for &n in faces.nodes(g) {
                    if !nodes.contains(&n) {
                        nodes.push(n);
                    }
                }
            };
            if smoothed.is_some() {
                // those of its smooth group: their normals enter the contact face's
                let groups = &layout.smooth_group[p];
                (faces_around(faces, face, &pair.candidates[i]).into_iter())
                    .filter(|&g| groups[g] == groups[face])
                    .for_each(&mut add);
            }
            let nh = pair.history_len();
            let h0 = layout.history[p] + nh * i;
            if let Some(StoredAnchor::Face { face: af, .. }) = pair.anchor(&hist_old[h0..h0 + nh]) {
                add(af.min(faces.len() - 1));
            }
            4 + 3 * nodes.len()
        }
        // the node, its multiplier, and the translations of a pushed target
        Target::Rigid { .. } => 4 + layout.target[p].iter().flatten().count(),
    };
    let args = (
        model, layout, lifted, z, hist_old, time, p, i, face, fz, forced, smoothed,
    );
    if seeds <= 4 {
        local_tangent_n::<S, 4>(args)
    } else if seeds <= 8 {
        local_tangent_n::<S, 8>(args)
    } else if seeds <= 16 {
        local_tangent_n::<S, 16>(args)
    } else if seeds <= 28 {
        local_tangent_n::<S, 28>(args)
    } else if seeds <= 52 {
        // quadratic faces: up to 4 + 3 (8 + 8) seeds on a quad8 whose anchor lies on another;
        // smoothed quad4 faces: 4 + 3 x 16 on a regular 3D grid
        local_tangent_n::<S, 52>(args)
    } else if seeds <= 76 {
        // smoothed normals around a node of a higher valence, an anchor outside them
        local_tangent_n::<S, 76>(args)
    } else {
        Err(ContactFailure::TooManySeeds { seeds, most: 76 })
    }
}

/// The arguments of [`local_tangent`], passed on to the tangent of one dual width.
type TangentArgs<'a, S> = (
    &'a Model,
    &'a ContactLayout,
    &'a Lifted<S>,
    &'a [S],
    &'a [S],
    f64,
    usize,
    usize,
    usize,
    Option<ContactChoice>,
    bool,
    Option<[f64; 2]>,
);

/// [`local_tangent`] with `N`-wide duals (`N` at least the number of seeds).
fn local_tangent_n<S: Scalar, const N: usize>(
    (model, layout, lifted, z, hist_old, time, p, i, face, fz, forced, smoothed): TangentArgs<
        '_,
        S,
    >,
) -> Result<LocalTangent, ContactFailure> {
    type Ad<const N: usize> = DualSVec64<N>;
    let pair = &model.contacts[p];
    let block = &layout.blocks[p][i];
    let nb = block.dofs.len();
    let s = pair.hitting[i];
    let nh = pair.history_len();
    let h0 = layout.history[p] + nh * i;
    let re3 = |v: Vector3<S>| v.map(|c| c.value());
    let xref = |n: usize| re3(lifted.coords[n]).map(Ad::<N>::from_re);
    let disp = |n: usize| node_disp(z, n).map(|v| v.value());
    // seeds: slot -> block-local column
    let mut slots: Vec<usize> = Vec::with_capacity(N);
    let seed = |v: f64, col: usize, slots: &mut Vec<usize>| {
        let k = slots.len();
        slots.push(col);
        Ad::<N>::from_re(v).derivative(k)
    };
    let us = disp(s);
    let u = Vector3::new(
        seed(us[0], 0, &mut slots),
        seed(us[1], 1, &mut slots),
        seed(us[2], 2, &mut slots),
    );
    // the block column of a target node: a face outside the node's candidates (a history or
    // frozen choice from elsewhere) has none
    let local_of = |n: usize| {
        block
            .target_nodes
            .iter()
            .position(|&m| m == n)
            .ok_or(ContactFailure::OutsideCandidates { node: n })
    };
    let mut seeded_nodes: Vec<(usize, Vector3<Ad<N>>)> = Vec::new();
    let mut node_ad =
        |n: usize, slots: &mut Vec<usize>| -> Result<Vector3<Ad<N>>, ContactFailure> {
            if let Some((_, v)) = seeded_nodes.iter().find(|(m, _)| *m == n) {
                return Ok(*v);
            }
            let un = disp(n);
            let col = 3 + 3 * local_of(n)?;
            let v = Vector3::new(
                seed(un[0], col, slots),
                seed(un[1], col + 1, slots),
                seed(un[2], col + 2, slots),
            );
            seeded_nodes.push((n, v));
            Ok(v)
        };
    let fparams: Vec<Ad<N>> = (lifted.friction_of(p, i).iter())
        .map(|v| Ad::<N>::from_re(v.value()))
        .collect();
    let eps_t = Ad::<N>::from_re(lifted.tangential[p].value() * pair.tangential_weight[i]);
    let rv: Vec<Ad<N>> = lifted.rigid_motion[p]
        .iter()
        .map(|v| Ad::<N>::from_re(v.value()))
        .collect();
    // the prescribed translation, and a pushed target's translations seeded (block columns
    // 3.. after the hitting node: a rigid target has no target nodes)
    let mut d: Vector3<Ad<N>> = rigid_translation(pair, &rv, time, None);
    let mut target_cols: Vec<(usize, usize)> = Vec::new();
    for (_, dof, m) in pair.pushed(&layout.target[p]) {
        let col = 3 + target_cols.len();
        d[m.component] += seed(z[dof].value(), col, &mut slots);
        target_cols.push((col, m.component));
    }
    let (target, contact_nodes) = match &pair.target {
        Target::Faces { faces } => {
            let mut seg = segment(faces, face, xref);
            for (x, &n) in seg.nodes.iter_mut().zip(faces.nodes(face)) {
                *x += node_ad(n, &mut slots)?;
            }
            let normals = if smoothed.is_some() {
                Some(contact_face_normals(
                    faces,
                    face,
                    &pair.candidates[i],
                    &layout.smooth_group[p],
                    |n| Ok(xref(n) + node_ad(n, &mut slots)?),
                )?)
            } else {
                None
            };
            (
                TargetGeom::Face {
                    segment: seg,
                    xi_start: smoothed.unwrap_or(seg.family.centre_st()),
                    normals,
                },
                Some(faces.nodes(face)),
            )
        }
        Target::Rigid { surface, .. } => (TargetGeom::Rigid { surface, d }, None),
    };
    let h_old = &hist_old[h0..h0 + nh];
    let lambda_bar = Ad::<N>::from_re(pair.lambda_bar(h_old).map_or(0.0, |v| v.value()));
    let re = |v: S| Ad::<N>::from_re(v.value());
    let anchor = match (pair.anchor(h_old), &pair.target) {
        (Some(StoredAnchor::Face { face: af, xi }), Target::Faces { faces }) => Some(face_anchor(
            faces,
            af.min(faces.len() - 1),
            xref,
            |n| node_ad(n, &mut slots),
            xi.map(re),
        )?),
        (Some(StoredAnchor::Offset(offset)), _) => Some(AnchorGeom::Rigid {
            offset: offset.map(re),
            d,
        }),
        _ => None,
    };
    let lam_col = nb - 1;
    let lambda = seed(z[layout.lambda[p] + i].value(), lam_col, &mut slots);
    debug_assert!(
        slots.len() <= N,
        "local_tangent sized its duals to the seeds"
    );
    let par = KernelParams {
        normal: pair.normal,
        friction: pair.friction.as_ref(),
        friction_params: &fparams,
        eps_t,
        k: pair.constraint_scale,
        activation: pair.activation,
        area: Ad::<N>::from_re(lifted.area[p][i].value()),
        touch: layout.touch[p],
        elastic_stick: forced,
    };
    let ko = node_kernel(
        &xref(s),
        &u,
        lambda,
        lambda_bar,
        &target,
        anchor.as_ref(),
        &par,
        fz.map(|c| c.state),
    )?;
    // rows and columns: the seeded unknowns (every row with a force is one of them)
    let m = slots.len();
    let mut values = vec![0.0; m * m];
    let mut add_row = |row: usize, v: &Ad<N>| {
        let r = slots
            .iter()
            .position(|&c| c == row)
            .expect("a row with a force is a seeded unknown");
        if let Some(d) = &v.eps.0 {
            for (v, dv) in values[r * m..(r + 1) * m].iter_mut().zip(d.iter()) {
                *v += dv;
            }
        }
    };
    for c in 0..3 {
        add_row(c, &(-ko.force[c]));
    }
    if let Some(cn) = contact_nodes {
        for (a, &n) in cn.iter().enumerate() {
            let row = 3 + 3 * local_of(n)?;
            for c in 0..3 {
                add_row(row + c, &(ko.weights[a] * ko.force[c]));
            }
        }
    }
    for &(col, c) in &target_cols {
        add_row(col, &ko.force[c]);
    }
    add_row(lam_col, &ko.r_lambda);
    Ok(LocalTangent {
        index: slots,
        values,
    })
}

/// The history at t = 0: zero for the materials; for every frictional hitting node the stick
/// anchor at the projection of its reference position (generic, so shape parameters that move
/// the reference position carry into the anchor's sensitivity).
pub(crate) fn initial_history<S: Scalar>(
    model: &Model,
    layout: &ContactLayout,
    n_history: usize,
    lifted: &Lifted<S>,
) -> Result<Vec<S>, ContactError> {
    let mut h = vec![S::zero(); n_history];
    for (p, pair) in model.contacts.iter().enumerate() {
        if pair.anchor_len() == 0 {
            continue;
        }
        // at t = 0 a pushed target is where the scene put it
        let d: Vector3<S> = rigid_translation(pair, &lifted.rigid_motion[p], 0.0, None);
        let nh = pair.history_len();
        for (i, &s) in pair.hitting.iter().enumerate() {
            let h0 = layout.history[p] + nh * i;
            let x = lifted.coords[s];
            let err = |e: super::geometry::GeometryError| ContactError {
                pair: pair.name.clone(),
                node: s,
                failure: ContactFailure::Geometry(e),
            };
            match &pair.target {
                Target::Rigid { surface, .. } => {
                    let pr = surface.project(&x, &d).map_err(err)?;
                    let a = (pr.point - x) - d;
                    pair.set_anchor(&mut h[h0..h0 + nh], StoredAnchor::Offset(a));
                }
                Target::Faces { faces } => {
                    let segments: Vec<Segment<f64>> = pair.candidates[i]
                        .iter()
                        .map(|&f| segment(faces, f, |n| lifted.coords[n].map(|v| v.value())))
                        .collect();
                    let xr = x.map(|v| v.value());
                    let (k, _) = closest_on_segments(&xr, &segments, None).map_err(err)?;
                    let f = pair.candidates[i][k];
                    let seg = segment(faces, f, |n| lifted.coords[n]);
                    let pr = super::geometry::project_on_segment(&x, &seg, seg.family.centre_st())
                        .map_err(err)?;
                    pair.set_anchor(
                        &mut h[h0..h0 + nh],
                        StoredAnchor::Face { face: f, xi: pr.xi },
                    );
                }
            }
        }
    }
    Ok(h)
}

/// What the augmented-Lagrangian passes of one increment remember between them: each
/// augmented pair's last Uzawa update `p_n - lambda_bar` (over its hitting nodes) and the
/// relaxation factor it was applied with, for Aitken's acceleration ([`augment`]).
#[derive(Debug, Default)]
pub(crate) struct Augmentation {
    last: Vec<Option<(Vec<f64>, f64)>>,
}

/// Largest relaxation factor of the accelerated Uzawa update. Plain Uzawa contracts the
/// multipliers' error by about `rho = K / (K + eps_N A)` per pass (`K` the bodies' stiffness
/// at the node); on a uniform linear contraction (`rho` times the identity) Aitken's factor is
/// `1 / (1 - rho)` from the second update on, which makes that update exact. Over coupled
/// nodes the contraction is not uniform and one factor only approximates it. The bound admits
/// `rho` up to 0.9 and keeps an estimate made across an active-set change from overshooting by
/// more than a decade. Measured on the thirteen
/// augmented-Lagrangian scenes of the fuzzer's slow tail: 5,687 Newton iterations at 10,
/// 5,491 at 30 (and seed 537 over the time limit), 5,894 without the relaxation.
const AITKEN_MAX: f64 = 10.0;

/// Aitken's relaxation factor for the fixed-point update `r` that follows `previous`, applied
/// with `omega_previous` (Kuettler and Wall 2008): `-omega_{k-1} r_{k-1}.(r_k - r_{k-1}) /
/// |r_k - r_{k-1}|^2`, kept within `[1, AITKEN_MAX]` (1 where the updates did not change).
fn aitken(previous: &[f64], update: &[f64], omega_previous: f64) -> f64 {
    let (mut num, mut den) = (0.0, 0.0);
    for (r, r0) in update.iter().zip(previous) {
        num += r0 * (r - r0);
        den += (r - r0) * (r - r0);
    }
    if den > 0.0 {
        (-omega_previous * num / den).clamp(1.0, AITKEN_MAX)
    } else {
        1.0
    }
}

/// The largest violation of an augmented pair's constraint at a converged pass: a hitting
/// node carrying a normal force is pressed into the target, or held off it, by `|g|`
/// (`None` for the other normal laws). Its tolerance is the pair's.
pub(crate) fn augmented_violation(
    pair: &ContactPair,
    normal_force: &[f64],
    gap: &[f64],
) -> Option<(f64, f64)> {
    let super::NormalLaw::Augmented { tolerance, .. } = pair.normal else {
        return None;
    };
    let worst = normal_force
        .iter()
        .zip(gap)
        .filter(|(f, _)| **f > 0.0)
        .fold(0.0f64, |m, (_, g)| m.max(g.abs()));
    Some((worst, tolerance))
}

/// Augmented-Lagrangian update after a converged pass, for every augmented pair whose
/// constraint is violated by more than its tolerance ([`augmented_violation`]: a node pressed
/// into the target deeper than it, or held off it at a wider gap by a positive force, as a
/// multiplier estimate carried from a loaded increment into an unloading one does): the
/// multiplier estimates of `hist` move towards the converged normal forces. A pair's first
/// move is Uzawa's (`lambda_bar <- p_n`); later ones are relaxed, `lambda_bar <- <lambda_bar +
/// omega (p_n - lambda_bar)>` with Aitken's `omega` ([`aitken`]). The converged state is any
/// pass's that meets the tolerance: the relaxation changes which state within the tolerance is
/// reached and how many passes that takes (and, through the solver's pass limit, whether the
/// attempt gets there). `damping` scales every pair's step (1 but after a failed pass: the
/// solver's backtracking). Returns whether anything changed (then the increment is solved
/// again).
pub(crate) fn augment(
    model: &Model,
    layout: &ContactLayout,
    eval: &ContactEval<f64>,
    hist: &mut [f64],
    memory: &mut Augmentation,
    trace: bool,
    damping: f64,
) -> bool {
    memory.last.resize(model.contacts.len(), None);
    let mut changed = false;
    for (p, pair) in model.contacts.iter().enumerate() {
        let first = layout.flat[p];
        let n = pair.hitting.len();
        let nodes = first..first + n;
        let Some((worst, tolerance)) = augmented_violation(
            pair,
            &eval.normal_force[nodes.clone()],
            &eval.gap[nodes.clone()],
        ) else {
            continue;
        };
        if worst <= tolerance {
            // met: a later pass (for another pair) starts this pair's relaxation afresh
            memory.last[p] = None;
            continue;
        }
        let nh = pair.history_len();
        let node_history = |i: usize| layout.history[p] + nh * i..layout.history[p] + nh * (i + 1);
        let bars: Vec<f64> = (0..n)
            .map(|i| pair.lambda_bar(&hist[node_history(i)]).unwrap_or(0.0))
            .collect();
        let update: Vec<f64> = (eval.normal_force[nodes].iter().zip(&bars))
            .map(|(p_n, bar)| p_n - bar)
            .collect();
        let omega = damping
            * match &memory.last[p] {
                Some((previous, omega)) => aitken(previous, &update, *omega),
                None => 1.0,
            };
        for (i, (bar, r)) in bars.iter().zip(&update).enumerate() {
            pair.set_lambda_bar(&mut hist[node_history(i)], (bar + omega * r).max(0.0));
        }
        if trace {
            eprintln!(
                "    augmentation: pair {p}: constraint violated by {worst:.3e} (tolerance \
                 {tolerance:.3e}), relaxation {omega:.3}"
            );
        }
        memory.last[p] = Some((update, omega));
        changed = true;
    }
    changed
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::element::face::FaceFamily;

    /// On a uniform linear contraction `x <- x* + rho (x - x*)`, the relaxed iteration `x <- x +
    /// omega r` with Aitken's factor from its second update on reaches the fixed point in that
    /// update: `omega = 1 / (1 - rho)` to round-off.
    #[test]
    fn aitken_makes_a_linear_contraction_exact() {
        let fixed = [3.0, -1.0, 0.5];
        for rho in [0.3, 0.5, 0.8] {
            let update = |x: &[f64]| -> Vec<f64> {
                x.iter()
                    .zip(&fixed)
                    .map(|(x, f)| (rho - 1.0) * (x - f))
                    .collect()
            };
            let mut x = vec![0.0; 3];
            let r0 = update(&x);
            for (x, r) in x.iter_mut().zip(&r0) {
                *x += r;
            }
            let r1 = update(&x);
            let omega = aitken(&r0, &r1, 1.0);
            assert!((omega - 1.0 / (1.0 - rho)).abs() < 1e-12, "{rho}: {omega}");
            for (x, r) in x.iter_mut().zip(&r1) {
                *x += omega * r;
            }
            for (x, f) in x.iter().zip(&fixed) {
                assert!((x - f).abs() < 1e-12, "{rho}: {x} against {f}");
            }
        }
        // an update that did not change, and an overshooting estimate: within the bounds
        assert_eq!(aitken(&[1.0], &[1.0], 1.0), 1.0);
        assert_eq!(aitken(&[1.0], &[0.99], 1.0), AITKEN_MAX);
        assert_eq!(aitken(&[1.0], &[-1.0], 1.0), 1.0);
    }

    /// Two faces of a block's top (z = 1) and one of its side (x = 2), meeting at a right
    /// angle along x = 2: the side is a group of its own, the top's nodal normals at the rim
    /// are the top's, as on a flat face; averaged over all three faces they tilt by 45
    /// degrees there. A face turned by 30 degrees joins the top's group.
    #[test]
    fn feature_edges_part_the_smoothed_normals() {
        let x: Vec<Vector3<f64>> = [
            [0.0, 0.0, 1.0],
            [1.0, 0.0, 1.0],
            [1.0, 1.0, 1.0],
            [0.0, 1.0, 1.0],
            [2.0, 0.0, 1.0],
            [2.0, 1.0, 1.0],
            [2.0, 0.0, 0.0],
            [2.0, 1.0, 0.0],
            // the top continued beyond x = 0, turned down by 30 degrees
            [
                -(30f64.to_radians().cos()),
                0.0,
                1.0 - 30f64.to_radians().sin(),
            ],
            [
                -(30f64.to_radians().cos()),
                1.0,
                1.0 - 30f64.to_radians().sin(),
            ],
        ]
        .iter()
        .map(|p| Vector3::from(*p))
        .collect();
        let mut faces = FaceSet::new();
        for nodes in [[0, 1, 2, 3], [1, 4, 5, 2], [4, 6, 7, 5], [8, 0, 3, 9]] {
            faces.push(FaceFamily::Quad4, &nodes).unwrap();
        }
        let groups = smooth_groups(&faces, &x);
        assert_eq!(groups, vec![0, 0, 2, 0]);
        let candidates = [0, 1, 2, 3];
        let position = |n: usize| Ok(x[n]);
        let up = Vector3::new(0.0, 0.0, 1.0);
        let normals = contact_face_normals(&faces, 1, &candidates, &groups, position).unwrap();
        for n in &normals[..4] {
            assert!((n - up).norm() < 1e-15, "{n}");
        }
        // one group: the rim node's normal halfway between the top's and the side's
        let one = vec![0; 4];
        let tilted = contact_face_normals(&faces, 1, &candidates, &one, position).unwrap();
        let half = std::f64::consts::FRAC_1_SQRT_2;
        assert!((tilted[1] - Vector3::new(half, 0.0, half)).norm() < 1e-15);
        // across the 30-degree edge the normals are shared: the joint node's normal lies
        // between the two faces' (15 degrees from each, the faces' areas being equal)
        let left = contact_face_normals(&faces, 3, &candidates, &groups, position).unwrap();
        let own = contact_face_normals(&faces, 0, &candidates, &groups, position).unwrap();
        assert_eq!(
            left[1], own[0],
            "node 0 seen from both sides of the smooth edge"
        );
        assert!((own[0].dot(&up) - 15f64.to_radians().cos()).abs() < 1e-15);
    }
}
