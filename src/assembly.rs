//! Global assembly: element loop (parallel over chunks of elements, deterministic scatter),
//! springs, external loads; generic over the scalar so the same loop gives the primal residual
//! and tangent (`f64`), SDM's perturbed unbalance force (`f64` at a perturbed design) and DDM's
//! exact pseudo-load (dual numbers).
//!
//! The residual is `R(z) = f_int(z) + f_spring(z) - f_ext(t)` over every unknown, including the
//! constrained ones (where it is the reaction). Dirichlet conditions are applied by the solver.

use crate::contact::assembly::{ContactError, ContactEval, ContactLayout};
use crate::contact::ContactChoice;
use crate::element::family::{MAX_DOFS, MAX_GAUSS, MAX_GEN, MAX_NODES};
use crate::element::{ElementFailure, ElementInput, ElementOutput};
use crate::linalg::{LinalgError, SparseMatrix, SparsePattern};
use crate::material::Branch;
use crate::model::{DofMap, Lifted, Model};
use crate::scalar::Scalar;
pub use crate::terms::Terms;
use crate::with_material;
use nalgebra::{Matrix3, Vector3};
use rayon::prelude::*;

/// Halvings of a local Newton step on an element's incompatible modes
/// ([`Assembler::relax_modes`]) before the element's relaxation stops.
const MODE_HALVINGS: usize = 4;

/// Elements evaluated per parallel chunk (bounds the scratch memory of the tangent buffers).
const CHUNK: usize = 512;

/// Fewer elements than this are evaluated on the calling thread: waking the pool costs more
/// than it saves. Measured (`fricsens validate`, primal seconds): the Jenkins slider, one spring
/// element since springs became elements, 0.58 ms on the spring loop of old, 3.45 ms through
/// the pool, 0.6 ms on the calling thread.
const PARALLEL_MIN: usize = 4;

/// The fixed structure of the global system: unknown numbering and sparsity pattern. A clone
/// shares the pattern (and so the linear solvers' symbolic analyses made on it).
#[derive(Clone)]
pub struct Assembler {
    /// Where each unknown lives in the global vector `z`.
    pub dofs: DofMap,
    /// The sparsity pattern of the tangent, fixed over the run (every candidate contact pair
    /// included), shared with the linear solvers that factor it.
    pub pattern: std::sync::Arc<SparsePattern>,
    /// Pattern block of each element (`usize::MAX` for unassembled ones).
    elem_block: Vec<usize>,
    /// Contact blocks and offsets.
    pub(crate) contact: ContactLayout,
    /// Elements whose stress a response reads ([`crate::response::Reads::stress_elements`]),
    /// sorted: their stress is kept in the evaluation's scalar ([`Evaluation::stress`]).
    pub stress_elements: Vec<usize>,
    /// Position of each element in `stress_elements` (`usize::MAX`: not read).
    stress_slot: Vec<usize>,
}

/// Branch decisions imposed on an evaluation (SDM's frozen state, one-sided derivatives), and
/// the guidance the primal solver gives free decisions (face hysteresis, forced stick).
/// `Frozen::default()` leaves everything free.
#[derive(Clone, Copy, Debug, Default)]
pub struct Frozen<'a> {
    /// Per Gauss point (flat, [`DofMap::gauss`]); `None` leaves them free.
    pub gauss: Option<&'a [Branch]>,
    /// Per hitting node (flat over pairs); empty: every contact state decided freely.
    pub contact: &'a [ContactChoice],
    /// Per hitting node (flat over pairs), for the nodes whose contact is not frozen: the
    /// target face to keep while the node projects onto it within
    /// [`crate::contact::geometry::SEGMENT_KEEP`], or at a shared boundary point against a
    /// face better aligned by less than [`crate::contact::geometry::ALIGN_KEEP`] (the faces of
    /// the last Newton iterate, the last converged state's at an increment's first: hysteresis
    /// of the face choice, see there).
    pub keep_faces: Option<&'a [ContactChoice]>,
    /// Per hitting node (flat over pairs), for the nodes whose contact is not frozen: a node
    /// the free decision puts in slip sticks instead (the primal solver's remedy for a slip
    /// direction that reverses between Newton iterates; the evaluation is then not the true
    /// residual and never accepted as converged).
    pub stick: Option<&'a [bool]>,
    /// Per element: left out of the evaluation. A skipped element adds nothing to the
    /// residual and carries its history over unchanged (`hist_new = hist_old`, derivative
    /// parts included). For evaluations that want only the updated history and responses
    /// that do not read its residual: an element whose Gauss points are all frozen elastic
    /// keeps its history, so the sensitivity update of the history (DDM's second evaluation,
    /// SDM's perturbed update) need not evaluate it (`crate::sensitivity`'s element mask). And
    /// an element the design perturbation does not reach contributes the same residual to
    /// both evaluations of SDM's unbalance, so both may leave it out.
    pub skip: Option<&'a [bool]>,
    /// Per hitting node (flat over pairs): left out of the contact evaluation. A node left out
    /// adds nothing to the residual (nor to its pair's force), carries its history over
    /// unchanged and reports no normal force. The adjoint's local Jacobians
    /// ([`crate::sensitivity`]) evaluate a few nodes at a time with their own seeds. With
    /// any mask, the pairs' current pressure areas ([`ContactEval::current_area`]) are not
    /// computed: they are the whole surface's, and such a pass does not read them.
    pub skip_contact: Option<&'a [bool]>,
    /// The terms of the residual the evaluation adds (all by default). SDM's error anatomy
    /// ([`crate::sensitivity::anatomy`]) evaluates them one at a time.
    pub terms: Terms,
    /// The caller reads only the outputs of the elements and hitting nodes evaluated (their
    /// residual rows, history, stress, normal force): the skipped ones' history, branches and
    /// stress are left as an earlier evaluation wrote them, and contact is not evaluated at all
    /// when every hitting node is skipped. The adjoint's local Jacobians evaluate a colour of a
    /// few elements per pass and pay for those alone.
    pub members_only: bool,
}

/// What failed during assembly, and where.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum AssemblyFailure {
    /// An element could not be evaluated (e.g. an inverted element, `det F <= 0`).
    #[error("element {element}: {failure}")]
    Element {
        /// Global element number.
        element: usize,
        /// What went wrong in it.
        failure: ElementFailure,
    },
    /// The contact kernel failed (e.g. a degenerate target segment).
    #[error("{0}")]
    Contact(ContactError),
}

/// Everything an evaluation produces besides the tangent.
#[derive(Clone, Debug)]
pub struct Evaluation<S: Scalar> {
    /// `f_int + f_spring - f_ext` over every unknown.
    pub residual: Vec<S>,
    /// Updated history (trial values until the increment is committed).
    pub hist_new: Vec<S>,
    /// Branch at each Gauss point (flat, [`DofMap::gauss`]).
    pub branches: Vec<Branch>,
    /// Trial yield ratio at each Gauss point.
    pub yield_ratio: Vec<f64>,
    /// Volume-averaged Cauchy stress per element (real parts): an `f64` evaluation's every
    /// element's; a differentiating one sums it only where [`Evaluation::stress`] keeps it
    /// (zero elsewhere: nothing reads a derivative there, and its value is the `f64`
    /// evaluation's).
    pub cauchy: Vec<Matrix3<f64>>,
    /// Volume-averaged Cauchy stress, in the evaluation's scalar, of the elements a response
    /// reads ([`Assembler::stress_elements`]; empty where none does).
    pub stress: Vec<Matrix3<S>>,
    /// Smallest det F over the model.
    pub min_det_f: f64,
    /// Contact results.
    pub contact: ContactEval<S>,
    /// The element tangents of a chunk, kept for the next evaluation with a tangent.
    kbuf: TangentSlots<S>,
}

/// Room for the element tangents of a chunk of [`Assembler::evaluate`], grown as needed and
/// never zeroed: every element kernel writes the whole of its slot
/// ([`crate::element::ElementOutput::tangent`]). A Newton iteration then spares its
/// allocation and zeroing (the leaf spring's 1.2 MB). A clone starts without it.
struct TangentSlots<S>(Vec<S>);

impl<S> Clone for TangentSlots<S> {
    fn clone(&self) -> Self {
        TangentSlots(Vec::new())
    }
}

impl<S> std::fmt::Debug for TangentSlots<S> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "TangentSlots({} scalars)", self.0.len())
    }
}

impl<S: Scalar> Evaluation<S> {
    /// An empty evaluation sized for a model.
    pub fn new(asm: &Assembler, n_elements: usize) -> Self {
        let dofs = &asm.dofs;
        Evaluation {
            contact: ContactEval::new(asm.contact.n_hitting, asm.contact.lambda.len()),
            residual: vec![S::zero(); dofs.n_total],
            hist_new: vec![S::zero(); dofs.n_history],
            branches: vec![Branch::Elastic; dofs.n_gauss()],
            yield_ratio: vec![-1.0; dofs.n_gauss()],
            cauchy: vec![Matrix3::zeros(); n_elements],
            stress: vec![Matrix3::zeros(); asm.stress_elements.len()],
            min_det_f: f64::INFINITY,
            kbuf: TangentSlots(Vec::new()),
        }
    }
}

impl<S: Scalar> Evaluation<S> {
    /// The response input at unknowns `z` (history: this evaluation's updated history).
    pub fn response_input<'a>(
        &'a self,
        z: &'a [S],
        asm: &'a Assembler,
    ) -> crate::response::ResponseInput<'a, S> {
        crate::response::ResponseInput {
            z,
            residual: &self.residual,
            hist: &self.hist_new,
            contact: Some(&self.contact),
            flat: Some(&asm.contact.flat),
            stress: &self.stress,
            stress_elements: Some(&asm.stress_elements),
        }
    }
}

/// Per-element scratch filled in parallel.
struct Local<S: Scalar> {
    force: [S; MAX_DOFS],
    branches: [Branch; MAX_GAUSS],
    yield_ratio: [f64; MAX_GAUSS],
    cauchy: Matrix3<S>,
    min_det_f: f64,
    failure: Option<ElementFailure>,
}

impl<S: Scalar> Local<S> {
    /// No force, elastic branches, no history: what an element without unknowns returns.
    fn empty() -> Self {
        Local {
            force: [S::zero(); MAX_DOFS],
            branches: [Branch::Elastic; MAX_GAUSS],
            yield_ratio: [-1.0; MAX_GAUSS],
            cauchy: Matrix3::zeros(),
            min_det_f: f64::INFINITY,
            failure: None,
        }
    }
}

impl Assembler {
    /// The same assembler keeping the stress of every element in the evaluation's scalar
    /// ([`Evaluation::stress`]): the stress fields' derivatives ([`crate::fields`]).
    pub fn reading_every_stress(mut self) -> Self {
        self.stress_elements = (0..self.stress_slot.len()).collect();
        self.stress_slot = self.stress_elements.clone();
        self
    }

    /// Where element `e`'s stress is kept in [`Evaluation::stress`], if it is.
    pub fn stress_slot(&self, e: usize) -> Option<usize> {
        self.stress_slot
            .get(e)
            .copied()
            .filter(|s| *s != usize::MAX)
    }

    /// Number the unknowns and build the sparsity pattern (once per model).
    pub fn new(model: &Model, extra: &[(usize, usize)]) -> Result<Self, LinalgError> {
        let dofs = model.dof_map();
        let ne = model.mesh.n_elements();
        let mut blocks: Vec<Vec<usize>> = (0..ne)
            .map(|e| dofs.element_dofs(e))
            .filter(|d| !d.is_empty())
            .map(|d| d.to_vec())
            .collect();
        let mut contact = ContactLayout::new(
            model,
            dofs.first_lambda,
            dofs.first_target,
            dofs.first_contact_history,
        );
        for pair_blocks in contact.blocks.iter_mut() {
            for nb in pair_blocks.iter_mut() {
                nb.pattern_block = blocks.len();
                blocks.push(nb.dofs.clone());
            }
        }
        let refs: Vec<&[usize]> = blocks.iter().map(|b| b.as_slice()).collect();
        let pattern = std::sync::Arc::new(
            SparsePattern::new(dofs.n_total, &refs, extra)?
                .with_multipliers_from(dofs.first_lambda)
                .with_last_from(dofs.first_target),
        );
        let mut elem_block = vec![usize::MAX; ne];
        let mut k = 0;
        for (e, b) in elem_block.iter_mut().enumerate() {
            if !dofs.element_dofs(e).is_empty() {
                *b = k;
                k += 1;
            }
        }
        let mut stress_elements: Vec<usize> = model
            .responses
            .iter()
            .flat_map(|r| r.kind.reads().stress_elements.to_vec())
            .filter(|e| *e < ne)
            .collect();
        stress_elements.sort_unstable();
        stress_elements.dedup();
        let mut stress_slot = vec![usize::MAX; ne];
        for (i, &e) in stress_elements.iter().enumerate() {
            stress_slot[e] = i;
        }
        Ok(Assembler {
            stress_elements,
            stress_slot,
            dofs,
            pattern,
            elem_block,
            contact,
        })
    }

    /// First history scalar of contact pair `pair` (its hitting nodes' histories follow,
    /// `ContactPair::history_len()` scalars each).
    pub fn contact_history(&self, pair: usize) -> usize {
        self.contact.history[pair]
    }

    /// First flat hitting-node index of contact pair `pair` in the per-node result arrays
    /// ([`Evaluation::contact`]).
    pub fn contact_flat(&self, pair: usize) -> usize {
        self.contact.flat[pair]
    }

    /// Global unknowns of element `e`.
    pub fn element_dofs(&self, e: usize) -> &[usize] {
        self.dofs.element_dofs(e)
    }

    /// Reference coordinates of element `e`'s nodes (`MAX_NODES` slots, the first
    /// `n_nodes` filled) and the element's node count.
    #[inline]
    fn reference_nodes<S: Scalar>(
        model: &Model,
        coords: &[Vector3<S>],
        e: usize,
    ) -> ([Vector3<S>; MAX_NODES], usize) {
        let conn = model.mesh.element_nodes(e);
        let mut x = [Vector3::<S>::zeros(); MAX_NODES];
        for (xa, &n) in x.iter_mut().zip(conn) {
            *xa = coords[n];
        }
        (x, conn.len())
    }

    /// The shortest fraction of the step from `z` to `z + dz` at which a Gauss point plastic
    /// at `z` (`branches`) has crossed its material's elastic domain to the far side of its
    /// yield surface ([`crate::material::MaterialLaw::elastic_crossing`]), and how many
    /// points do; `(1.0, 0)` when none. Real parts; F-bar elements are not examined.
    pub fn elastic_crossing(
        &self,
        model: &Model,
        lifted: &Lifted<f64>,
        z: &[f64],
        dz: &[f64],
        hist_old: &[f64],
        branches: &[Branch],
    ) -> (f64, usize) {
        let mut fraction = 1.0f64;
        let mut points = 0;
        for e in 0..model.mesh.n_elements() {
            let plastic = &branches[self.dofs.gauss(e)];
            if !plastic.contains(&Branch::Plastic) {
                continue;
            }
            let Some(family) = self.dofs.element_family[e] else {
                continue;
            };
            let b = self.dofs.element_body[e];
            let body = &model.bodies[b];
            let (x_ref, nn) = Self::reference_nodes(model, &lifted.coords, e);
            let gdofs = self.element_dofs(e);
            let n = gdofs.len() / 3;
            let mut d0 = [Vector3::<f64>::zeros(); MAX_GEN];
            let mut d1 = [Vector3::<f64>::zeros(); MAX_GEN];
            for a in 0..n {
                let g = &gdofs[3 * a..3 * a + 3];
                d0[a] = Vector3::new(z[g[0]], z[g[1]], z[g[2]]);
                d1[a] = d0[a] + Vector3::new(dz[g[0]], dz[g[1]], dz[g[2]]);
            }
            let strains = |d: &[Vector3<f64>]| {
                let mut out = [nalgebra::Matrix3::<f64>::zeros(); MAX_GAUSS];
                match family.gauss_strains(&x_ref[..nn], d, body.kinematics, &mut out) {
                    Ok(true) => Some(out),
                    _ => None,
                }
            };
            let (Some(e0), Some(e1)) = (strains(&d0[..n]), strains(&d1[..n])) else {
                continue;
            };
            let nh = body.material.history_len();
            let h0 = self.dofs.history_offset[e];
            for g in (0..plastic.len()).filter(|&g| plastic[g] == Branch::Plastic) {
                let hist = &hist_old[h0 + nh * g..h0 + nh * (g + 1)];
                let crossing = with_material!(&body.material, m => {
                    crate::material::MaterialLaw::elastic_crossing(
                        m,
                        lifted.material_of(b, e),
                        &e0[g],
                        &e1[g],
                        hist,
                    )
                });
                if let Some(s) = crossing {
                    fraction = fraction.min(s);
                    points += 1;
                }
            }
        }
        (fraction, points)
    }

    /// Evaluate the residual (and, if `tangent` is given, the tangent) at unknowns `z`, time `t`,
    /// with committed history `hist_old`. `frozen` imposes the Gauss-point branches.
    #[allow(clippy::too_many_arguments)]
    pub fn evaluate<S: Scalar>(
        &self,
        model: &Model,
        lifted: &Lifted<S>,
        z: &[S],
        hist_old: &[S],
        time: f64,
        frozen: Option<&Frozen<'_>>,
        mut tangent: Option<&mut SparseMatrix>,
        out: &mut Evaluation<S>,
    ) -> Result<(), AssemblyFailure> {
        for r in out.residual.iter_mut() {
            *r = S::zero();
        }
        if let Some(k) = tangent.as_deref_mut() {
            k.zero();
        }
        out.min_det_f = f64::INFINITY;
        let want_k = tangent.is_some();
        // elements left out of this evaluation. The masks are drawn from Gauss points and
        // histories: an element without Gauss points (a spring) is always evaluated.
        let skip = frozen.and_then(|f| f.skip);
        let terms = frozen.map_or(Terms::ALL, |f| f.terms);
        let skipped = |e: usize| {
            let spring = self.dofs.gauss(e).is_empty();
            if spring {
                !terms.springs
            } else {
                !terms.solids || skip.is_some_and(|s| s[e])
            }
        };
        let ne = model.mesh.n_elements();
        // the elements evaluated; a skipped one's outputs are written directly (no force,
        // history carried over, branches as frozen), without a `Local` of its own: a pass
        // over a few elements pays for those alone
        let order: Vec<usize> = (0..ne).filter(|&e| !skipped(e)).collect();
        let members_only = frozen.is_some_and(|f| f.members_only);
        for e in (0..ne).filter(|&e| !members_only && skipped(e)) {
            self.write_skipped(hist_old, frozen.and_then(|f| f.gauss), e, out);
        }
        let ne = order.len();
        let mut locals: Vec<Local<S>> = Vec::new();
        // element tangents of one chunk, in room kept from one evaluation to the next
        // (`TangentSlots`); the largest element of this evaluation sets the slots' size
        let max_dofs = order
            .iter()
            .map(|&e| self.element_dofs(e).len())
            .max()
            .unwrap_or(0);
        debug_assert!(max_dofs <= MAX_DOFS);
        let stride = max_dofs.max(1) * max_dofs.max(1);
        // every slot is written whole by its element (`TangentSlots`)
        let mut kbuf = std::mem::take(&mut out.kbuf.0);
        if want_k && kbuf.len() < CHUNK.min(ne) * stride {
            kbuf.resize(CHUNK.min(ne) * stride, S::zero());
        }
        let mut kf = vec![0.0; if want_k { stride } else { 0 }];
        // the elements' updated histories, one slot per element of a chunk, sized by the
        // largest of this evaluation (a hex20's 27 points are not every element's)
        let hstride = order
            .iter()
            .map(|&e| self.dofs.history(e).len())
            .max()
            .unwrap_or(0)
            .max(1);
        let mut hbuf = vec![S::zero(); CHUNK.min(ne) * hstride];
        let mut start = 0;
        while start < ne {
            let end = (start + CHUNK).min(ne);
            // evaluate the chunk in parallel
            let slots: Vec<Option<&mut [S]>> = if want_k {
                kbuf[..(end - start) * stride]
                    .chunks_mut(stride)
                    .map(Some)
                    .collect()
            } else {
                (start..end).map(|_| None).collect()
            };
            let hslots: Vec<&mut [S]> = hbuf[..(end - start) * hstride]
                .chunks_mut(hstride)
                .collect();
            let local = |(i, (k, h)): (usize, (Option<&mut [S]>, &mut [S]))| {
                let e = order[i];
                self.element_local(
                    model,
                    lifted,
                    z,
                    hist_old,
                    frozen.and_then(|f| f.gauss),
                    e,
                    k,
                    h,
                    !S::DIFFERENTIATES || self.stress_slot(e).is_some(),
                )
            };
            // a tape is a thread's: a recording evaluation stays on the calling thread
            if end - start < PARALLEL_MIN || S::RECORDS {
                locals.clear();
                locals.extend((start..end).zip(slots.into_iter().zip(hslots)).map(local));
            } else {
                (start..end)
                    .into_par_iter()
                    .zip(slots.into_par_iter().zip(hslots.into_par_iter()))
                    .map(local)
                    .collect_into_vec(&mut locals);
            }
            // scatter sequentially in element order (bit-identical whatever the thread count)
            for (off, loc) in locals.iter().enumerate() {
                let e = order[start + off];
                let nd = self.dofs.element_dofs(e).len();
                if nd == 0 {
                    continue;
                }
                if let Some(f) = &loc.failure {
                    out.kbuf.0 = kbuf;
                    return Err(AssemblyFailure::Element {
                        element: e,
                        failure: f.clone(),
                    });
                }
                for (l, &g) in self.element_dofs(e).iter().enumerate() {
                    out.residual[g] += loc.force[l];
                }
                let gauss = self.dofs.gauss(e);
                let ng = gauss.len();
                out.branches[gauss.clone()].copy_from_slice(&loc.branches[..ng]);
                out.yield_ratio[gauss].copy_from_slice(&loc.yield_ratio[..ng]);
                out.cauchy[e] = loc.cauchy.map(|c| c.value());
                if let Some(slot) = self.stress_slot(e) {
                    out.stress[slot] = loc.cauchy;
                }
                let hist = self.dofs.history(e);
                let nh = hist.len();
                out.hist_new[hist].copy_from_slice(&hbuf[off * hstride..off * hstride + nh]);
                out.min_det_f = out.min_det_f.min(loc.min_det_f);
                if let Some(k) = tangent.as_deref_mut() {
                    let ks = &kbuf[off * stride..off * stride + nd * nd];
                    for (f, v) in kf.iter_mut().zip(ks) {
                        *f = v.value();
                    }
                    k.add_block(self.elem_block[e], &kf[..nd * nd])
                        .expect("element block of this pattern");
                }
            }
            start = end;
        }
        out.kbuf.0 = kbuf;
        // contact
        let no_node = frozen
            .and_then(|f| f.skip_contact)
            .is_some_and(|s| s.iter().all(|k| *k));
        let skip_all = members_only && no_node;
        let contact = !model.contacts.is_empty() && !skip_all;
        if contact {
            let mut local = Vec::new();
            crate::contact::assembly::evaluate(
                model,
                &self.contact,
                lifted,
                z,
                hist_old,
                time,
                frozen.map(|f| f.contact).filter(|c| !c.is_empty()),
                frozen.and_then(|f| f.keep_faces),
                frozen.and_then(|f| f.stick),
                frozen.and_then(|f| f.skip_contact),
                terms,
                want_k,
                &mut out.residual,
                &mut out.hist_new,
                &mut out.contact,
                &mut local,
            )
            .map_err(AssemblyFailure::Contact)?;
            if let Some(k) = tangent {
                for (b, kt) in &local {
                    k.add_block_part(*b, &kt.index, &kt.values)
                        .expect("contact block of this pattern");
                }
            }
        }
        // external loads
        if !terms.loads {
            return Ok(());
        }
        for (l, load) in model.loads.iter().enumerate() {
            let f = lifted.loads[l] * load.amplitude.at(time);
            for (&n, w) in load.nodes.iter().zip(&load.weights) {
                out.residual[self.dofs.node_dof(n, load.component)] -= f * *w;
            }
        }
        for (l, load) in model.pressures.iter().enumerate() {
            let p = lifted.pressures[l] * load.amplitude.at(time);
            load.add_to_residual(&lifted.coords, p, &mut out.residual);
        }
        Ok(())
    }

    /// The outputs of an element left out of the evaluation ([`Frozen::skip`]): no force,
    /// history carried over, branches as frozen (else elastic), no stress.
    fn write_skipped<S: Scalar>(
        &self,
        hist_old: &[S],
        frozen: Option<&[Branch]>,
        e: usize,
        out: &mut Evaluation<S>,
    ) {
        if self.dofs.element_dofs(e).is_empty() {
            return;
        }
        let gauss = self.dofs.gauss(e);
        match frozen {
            Some(f) => out.branches[gauss.clone()].copy_from_slice(&f[gauss.clone()]),
            None => out.branches[gauss.clone()].fill(Branch::Elastic),
        }
        out.yield_ratio[gauss].fill(-1.0);
        out.cauchy[e] = Matrix3::zeros();
        if let Some(slot) = self.stress_slot(e) {
            out.stress[slot] = Matrix3::zeros();
        }
        let hist = self.dofs.history(e);
        out.hist_new[hist.clone()].copy_from_slice(&hist_old[hist]);
    }

    /// The unknowns of element `e`'s incompatible modes (its last nine), if it has them.
    pub(crate) fn mode_dofs(&self, e: usize) -> Option<&[usize]> {
        let gdofs = self.element_dofs(e);
        (self.dofs.element_internal[e].is_some() && gdofs.len() >= 9)
            .then(|| &gdofs[gdofs.len() - 9..])
    }

    /// Local Newton on the incompatible-mode amplitudes of `elements` (hex8s with incompatible
    /// modes: each element's last nine unknowns), the other unknowns of `z` held: each
    /// element's mode rows of the residual driven towards zero by at most `steps` Newton steps
    /// on its own 9 x 9 block of the element tangent, from the modes in `z`, keeping the
    /// modes of the smallest mode residual met (stopping once it is 1e-12 of the element's
    /// nodal force, or once no halving of a step, down to 1/16 of it, lowers it). An element
    /// whose evaluation fails at the modes in `z` keeps them (the evaluation that follows
    /// reports it); an element without internal unknowns is passed over. The history read is
    /// `hist_old`, as the evaluation's; nothing is committed. Returns the number of elements
    /// whose modes moved. Each element on its own (in parallel): the modes are no other
    /// element's unknowns.
    pub(crate) fn relax_modes(
        &self,
        model: &Model,
        lifted: &Lifted<f64>,
        z: &mut [f64],
        hist_old: &[f64],
        elements: &[usize],
        steps: usize,
    ) -> usize {
        let zr: &[f64] = z;
        let moved: Vec<(usize, [f64; 9])> = elements
            .par_iter()
            .map_init(
                || (zr.to_vec(), Vec::new(), Vec::new()),
                |(local, k, h), &e| {
                    let mode_dofs = self.mode_dofs(e)?;
                    let gdofs = self.element_dofs(e);
                    let nd = gdofs.len();
                    let modes = nd - 9;
                    k.resize(nd * nd, 0.0);
                    h.resize(self.dofs.history(e).len().max(1), 0.0);
                    type Modes = nalgebra::SVector<f64, 9>;
                    // the mode residual, its norm, the nodal force's and the modes' block of
                    // the element tangent, at modes `m`; `None` where the element fails
                    let mut at = |m: &Modes| {
                        for (&g, v) in mode_dofs.iter().zip(m.iter()) {
                            local[g] = *v;
                        }
                        let loc = self.element_local(
                            model,
                            lifted,
                            local,
                            hist_old,
                            None,
                            e,
                            Some(&mut k[..]),
                            &mut h[..],
                            false,
                        );
                        if loc.failure.is_some() {
                            return None;
                        }
                        let r = Modes::from_fn(|i, _| loc.force[modes + i]);
                        let nodal = loc.force[..modes].iter().map(|f| f * f).sum::<f64>();
                        let kaa = nalgebra::SMatrix::<f64, 9, 9>::from_fn(|i, j| {
                            k[(modes + i) * nd + modes + j]
                        });
                        Some((r, r.norm(), nodal.sqrt(), kaa))
                    };
                    let start = Modes::from_fn(|i, _| zr[mode_dofs[i]]);
                    let mut m = start;
                    let relaxed = at(&m).map(|(mut r, mut norm, nodal, mut kaa)| {
                        for _ in 0..steps {
                            if norm <= 1e-12 * nodal {
                                break;
                            }
                            let Some(d) = kaa.lu().solve(&r) else {
                                break;
                            };
                            // backtracking: a step that does not lower the mode residual
                            // (a Gauss point's branch changing on the way) is halved
                            let mut alpha = 1.0;
                            let mut taken = false;
                            for _ in 0..=MODE_HALVINGS {
                                let trial = m - d * alpha;
                                if let Some((rt, nt, _, kt)) = at(&trial).filter(|t| t.1 < norm) {
                                    (m, r, norm, kaa) = (trial, rt, nt, kt);
                                    taken = true;
                                    break;
                                }
                                alpha *= 0.5;
                            }
                            if !taken {
                                break;
                            }
                        }
                        m
                    });
                    for &g in mode_dofs {
                        local[g] = zr[g];
                    }
                    relaxed.filter(|m| *m != start).map(|m| (e, m.into()))
                },
            )
            .flatten()
            .collect();
        let n = moved.len();
        for (e, modes) in moved {
            for (&g, v) in self.mode_dofs(e).into_iter().flatten().zip(modes) {
                z[g] = v;
            }
        }
        n
    }

    /// One solid element alone, on the calling thread: its rows of the residual into `force`
    /// (in [`Assembler::element_dofs`] order), its updated history into `hist_new` (its
    /// [`DofMap::history`] range), and its volume-averaged Cauchy stress returned (zero where
    /// not `want_cauchy`: a recording of an element whose stress nothing reads). The
    /// adjoint's reverse-mode local derivatives ([`crate::scalar::Rev`]) record one element
    /// at a time on the thread that evaluates it.
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn element_outputs<S: Scalar>(
        &self,
        model: &Model,
        lifted: &Lifted<S>,
        z: &[S],
        hist_old: &[S],
        frozen: Option<&[Branch]>,
        e: usize,
        force: &mut [S],
        hist_new: &mut [S],
        want_cauchy: bool,
    ) -> Result<Matrix3<S>, AssemblyFailure> {
        let loc = self.element_local(
            model,
            lifted,
            z,
            hist_old,
            frozen,
            e,
            None,
            hist_new,
            want_cauchy,
        );
        if let Some(failure) = loc.failure {
            return Err(AssemblyFailure::Element {
                element: e,
                failure,
            });
        }
        let nd = self.element_dofs(e).len();
        force[..nd].copy_from_slice(&loc.force[..nd]);
        Ok(loc.cauchy)
    }

    #[allow(clippy::too_many_arguments)]
    fn element_local<S: Scalar>(
        &self,
        model: &Model,
        lifted: &Lifted<S>,
        z: &[S],
        hist_old: &[S],
        frozen: Option<&[Branch]>,
        e: usize,
        k_out: Option<&mut [S]>,
        h_out: &mut [S],
        want_cauchy: bool,
    ) -> Local<S> {
        let mut loc = Local::empty();
        let Some(family) = self.dofs.element_family[e] else {
            return loc;
        };
        let gdofs = self.element_dofs(e);
        let nd = gdofs.len();
        let mut d = [Vector3::<S>::zeros(); MAX_GEN];
        for (a, da) in d.iter_mut().enumerate().take(nd / 3) {
            *da = Vector3::new(z[gdofs[3 * a]], z[gdofs[3 * a + 1]], z[gdofs[3 * a + 2]]);
        }
        // a discrete element: its spring set's stiffness is its section
        if let Some(set) = model.springs.get(self.dofs.element_springs[e]) {
            let mut out = ElementOutput {
                force: &mut loc.force[..nd],
                tangent: k_out,
                hist_new: &mut [],
                branches: &mut [],
                yield_ratio: &mut [],
                cauchy: Matrix3::zeros(),
                want_cauchy,
                min_det_f: f64::INFINITY,
            };
            if let Err(f) = family.evaluate_discrete(&set.k(), &d[..nd / 3], &mut out) {
                loc.failure = Some(f);
            }
            return loc;
        }
        let b = self.dofs.element_body[e];
        let body = &model.bodies[b];
        let (x_ref, nn) = Self::reference_nodes(model, &lifted.coords, e);
        let hist = self.dofs.history(e);
        let nh = hist.len();
        let gauss = self.dofs.gauss(e);
        let ng = gauss.len();
        let fr: Option<&[Branch]> = frozen.map(|f| &f[gauss]);
        let result = with_material!(&body.material, m => {
            let input = ElementInput {
                x_ref: &x_ref[..nn],
                dofs: &d[..nd / 3],
                kinematics: body.kinematics,
                material: m,
                params: lifted.material_of(b, e),
                hist_old: &hist_old[hist],
                frozen: fr,
            };
            let mut out = ElementOutput {
                force: &mut loc.force[..nd],
                tangent: k_out,
                hist_new: &mut h_out[..nh],
                branches: &mut loc.branches[..ng],
                yield_ratio: &mut loc.yield_ratio[..ng],
                cauchy: Matrix3::zeros(),
                want_cauchy,
                min_det_f: f64::INFINITY,
            };
            let r = family.evaluate(&input, &mut out);
            loc.cauchy = out.cauchy;
            loc.min_det_f = out.min_det_f;
            r
        });
        if let Err(f) = result {
            loc.failure = Some(f);
            return loc;
        }
        loc
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::element::Formulation;

    /// [`Assembler::relax_modes`] holds the nodal unknowns and brings each incompatible-modes
    /// element's mode rows of the residual to its local equilibrium (zero, to round-off), from
    /// zero modes under a bending field (where the modes are not zero: a homogeneous field
    /// would need none) large enough to yield the J2 body of the fuzzer's seed 931 (a J2
    /// slider over a Neo-Hookean base, both hex8s with incompatible modes), up to twice the
    /// yield strain. (At four times the curvature, eight times the yield strain in one step
    /// from the virgin state, two of the slider's elements, `H / E = 0.003`, stall at 7 % of
    /// their starting mode residual, Newton's steps as long as a tenth of the element: the
    /// relaxation keeps the lowest residual met, and the global Newton goes on from there.)
    #[test]
    fn relaxed_modes_balance_their_elements_and_leave_the_nodes() {
        let path = concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/tests/corpus/robustness/seed-931.toml"
        );
        let model = crate::scene::Scene::from_file(std::path::Path::new(path))
            .unwrap()
            .build()
            .unwrap();
        let asm = Assembler::new(&model, &[]).unwrap();
        let lifted = model.lifted::<f64>(&[]);
        let hist = crate::contact::assembly::initial_history(
            &model,
            &asm.contact,
            asm.dofs.n_history,
            &lifted,
        )
        .unwrap();
        let mut z = vec![0.0; asm.dofs.n_total];
        let curvature = 0.05;
        for (n, x) in lifted.coords.iter().enumerate() {
            z[asm.dofs.node_dof(n, 0)] = -curvature * x.x * x.y;
            z[asm.dofs.node_dof(n, 1)] = 0.5 * curvature * x.x * x.x;
        }
        // the elements with incompatible modes, by their formulation: `mode_dofs` gives
        // each its nine unknowns
        let modes: Vec<usize> = (0..model.mesh.n_elements())
            .filter(|&e| {
                asm.dofs.element_family[e].and_then(|f| f.formulation())
                    == Some(Formulation::IncompatibleModes)
            })
            .collect();
        assert!(!modes.is_empty());
        for e in 0..model.mesh.n_elements() {
            assert_eq!(
                asm.mode_dofs(e).is_some(),
                modes.contains(&e),
                "element {e}"
            );
        }
        // each element's mode residual, relative to its nodal force, and its plastic points
        let balance = |z: &[f64]| {
            let mut worst = 0.0f64;
            let mut plastic = 0;
            for &e in &modes {
                let mut h = vec![0.0; asm.dofs.history(e).len().max(1)];
                let loc =
                    asm.element_local(&model, &lifted, z, &hist, None, e, None, &mut h, false);
                assert!(loc.failure.is_none(), "element {e}");
                let nd = asm.element_dofs(e).len();
                let norm = |f: &[f64]| f.iter().map(|v| v * v).sum::<f64>().sqrt();
                let (nodal, mode) = (norm(&loc.force[..nd - 9]), norm(&loc.force[nd - 9..nd]));
                worst = worst.max(mode / nodal);
                plastic += (loc.branches.iter())
                    .filter(|b| **b == Branch::Plastic)
                    .count();
            }
            (worst, plastic)
        };
        let (before, plastic) = balance(&z);
        assert!(plastic > 0, "the bending field yields the J2 body");
        assert!(
            before > 1e-2,
            "the modes are out of balance at zero: {before:e}"
        );
        let nodal = z.clone();
        assert_eq!(
            asm.relax_modes(&model, &lifted, &mut z, &hist, &modes, 10),
            modes.len(),
            "every element's modes move"
        );
        let (after, _) = balance(&z);
        // Newton on nine unknowns per element, quadratic once the branches settle: the
        // round-off of the element's force sums is the floor
        assert!(after < 1e-10, "mode residual / nodal force {after:e}");
        for (d, (a, b)) in nodal.iter().zip(&z).enumerate() {
            let is_mode = (modes.iter()).any(|&e| asm.mode_dofs(e).unwrap().contains(&d));
            if !is_mode {
                assert_eq!(a.to_bits(), b.to_bits(), "unknown {d} moved");
            }
        }
    }
}
