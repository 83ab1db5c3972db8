//! The contact active set: the first prediction of an attempt from a linear step, and the
//! diagnosis of a Newton iteration cycling between contact states.

use super::*;
use crate::assembly::{Assembler, Evaluation, Frozen};
use crate::contact::{ContactChoice, ContactState};
use crate::model::{Lifted, Model};

/// The contact states the first step of an attempt leads to ([`Solver::settle_active_set`]).
pub(super) struct ActiveSetPredictor {
    /// The trial state `z + dz`.
    pub(super) z: Vec<f64>,
    /// Contact-only evaluation at the trial state.
    pub(super) trial: Evaluation<f64>,
    /// The states to impose next: open or closed, friction left free.
    pub(super) choice: Vec<ContactChoice>,
    /// First flat hitting-node index of each pair, and the end.
    pub(super) pair_start: Vec<usize>,
}

/// Per flat hitting node, the elements at it that carry history (a path-dependent
/// material): where [`ActiveSetPredictor::next`] looks for a yielded body. Built once per
/// run ([`Solver::new`]).
pub(super) fn history_elements_at_hitting_nodes(model: &Model, asm: &Assembler) -> Vec<Vec<usize>> {
    let mesh = &model.mesh;
    let mut with_history: Vec<Vec<usize>> = vec![Vec::new(); mesh.n_nodes()];
    for e in 0..mesh.n_elements() {
        if !asm.dofs.history(e).is_empty() {
            for &n in mesh.element_nodes(e) {
                with_history[n].push(e);
            }
        }
    }
    (model.contacts.iter())
        .flat_map(|pair| pair.hitting.iter().map(|&n| with_history[n].clone()))
        .collect()
}

/// A first step the active-set predictor solved with: how many states its prediction
/// changed, the step, the states it was solved with and the residual, and whether it is
/// Newton's own.
pub(super) struct SettledStep {
    pub(super) changes: usize,
    pub(super) dz: Vec<f64>,
    pub(super) choice: Vec<ContactChoice>,
    pub(super) residual: Vec<f64>,
    pub(super) newtons: bool,
}

impl ActiveSetPredictor {
    pub(super) fn new(asm: &Assembler) -> Self {
        let mut pair_start = asm.contact.flat.clone();
        pair_start.push(asm.contact.n_hitting);
        ActiveSetPredictor {
            z: vec![0.0; asm.dofs.n_total],
            trial: Evaluation::new(asm, 0),
            choice: Vec::new(),
            pair_start,
        }
    }

    /// Decide the states at the trial state `self.z` against those `current.contact.choice`
    /// the step was solved with. `None` when they agree (or the trial state's contact
    /// geometry fails: Newton's own step then meets it). Otherwise the states to solve with
    /// next in `self.choice`, what changed (for the trace) and how many states the trial
    /// state changes (releases and closings predicted, taken or not).
    ///
    /// Releases come first: when any closed node's multiplier would turn negative, all such
    /// nodes open and no node closes; but not a node the last converged state (`keep_faces`)
    /// holds where the body around it has yielded: a history scalar of an element at the
    /// node (`around`, [`history_elements_at_hitting_nodes`]) moved from zero, where every
    /// law's history starts ([`crate::material::MaterialLaw::history_len`]). The fuzzer's
    /// seed 342, a J2 block under a rigid cylinder that touches two nodes, released both at
    /// every sub-increment's first step: the block unloaded elastically, and Newton took
    /// five iterations to come back to the converged states (1,106 iterations over its path;
    /// 926 with the held nodes kept). Otherwise, of the nodes the step would close, those
    /// whose penetration is at least [`ACTIVE_SET_ADD_FRACTION`] of their pair's deepest
    /// close. Taking every predicted change at once cycles on nearly conforming surfaces:
    /// the leaves' whole interface closes, the glued leaves' multipliers alternate in sign,
    /// the released nodes penetrate again (the leaf spring's first step did not settle in
    /// 8 solves; on the mesh refined 3 times, 50 factorizations for the first increment
    /// against 15 this way).
    pub(super) fn next(
        &mut self,
        model: &Model,
        asm: &Assembler,
        lifted: &Lifted<f64>,
        (hist, t): (&[f64], f64),
        current: &Evaluation<f64>,
        (keep_faces, around): (&[ContactChoice], &[Vec<usize>]),
    ) -> Option<(String, usize)> {
        let trial = &mut self.trial;
        trial.residual.iter_mut().for_each(|r| *r = 0.0);
        let mut tangents = Vec::new();
        crate::contact::assembly::evaluate(
            model,
            &asm.contact,
            lifted,
            &self.z,
            hist,
            t,
            None,
            Some(keep_faces),
            None,
            None,
            crate::assembly::Terms::ALL,
            false,
            &mut trial.residual,
            &mut trial.hist_new,
            &mut trial.contact,
            &mut tangents,
        )
        .ok()?;
        let open = |c: &ContactChoice| c.state == ContactState::Open;
        let now = &current.contact.choice;
        let then = &trial.contact.choice;
        // a node the last converged state holds, on a body that has yielded around it (a
        // history scalar moved from its initial zero), is not released by the prediction
        let held = |i: usize| {
            keep_faces.get(i).is_some_and(|c| !open(c))
                && (around.get(i).into_iter().flatten())
                    .any(|&e| hist[asm.dofs.history(e)].iter().any(|v| *v != 0.0))
        };
        let releases = (0..then.len())
            .filter(|&i| open(&then[i]) && !open(&now[i]) && !held(i))
            .count();
        let closing = then
            .iter()
            .zip(now)
            .filter(|(a, b)| !open(a) && open(b))
            .count();
        if releases + closing == 0 {
            return None;
        }
        self.choice.clear();
        self.choice.extend(now.iter().map(|c| ContactChoice {
            state: if open(c) {
                ContactState::Open
            } else {
                ContactState::Closed
            },
            ..*c
        }));
        let mut taken = 0;
        // the first few changes taken, for the trace
        let mut taken_list: Vec<String> = Vec::new();
        for w in self.pair_start.windows(2) {
            let range = w[0]..w[1];
            let deepest = range
                .clone()
                .filter(|&i| !open(&then[i]) && open(&now[i]))
                .map(|i| trial.contact.gap[i])
                .fold(0.0f64, f64::min);
            for i in range {
                let release = open(&then[i]) && !open(&now[i]) && !held(i);
                let close = releases == 0
                    && !open(&then[i])
                    && open(&now[i])
                    && trial.contact.gap[i] <= ACTIVE_SET_ADD_FRACTION * deepest;
                if release || close {
                    self.choice[i] = ContactChoice {
                        state: if release {
                            ContactState::Open
                        } else {
                            ContactState::Closed
                        },
                        ..then[i]
                    };
                    taken += 1;
                    if taken_list.len() < 12 {
                        taken_list.push(format!(
                            "{}{i} (g {:.1e})",
                            if release { '-' } else { '+' },
                            trial.contact.gap[i]
                        ));
                    }
                }
            }
        }
        let taken_list = taken_list.join(" ");
        Some((
            if releases > 0 {
                format!("{releases} releases predicted ({closing} closings), taken: {taken_list}")
            } else {
                format!("{closing} closings predicted, {taken} taken: {taken_list}")
            },
            releases + closing,
        ))
    }
}

impl Solver<'_> {
    /// Settle the contact active set of the first Newton step of an attempt on the
    /// linearised problem, before the state moves; returns the extra solves made.
    ///
    /// The step `dz` was solved with the open/closed states decided at `z`. The contact
    /// kernel, evaluated alone at `z + dz`, predicts the states the step leads to (the
    /// multipliers' signs and the gaps, decided by the primal-dual rule). While they differ,
    /// the tangent at `z` is assembled again with the predicted states imposed and the step
    /// solved again ([`ActiveSetPredictor::next`] decides which changes to take).
    ///
    /// Why: at an increment's start the bodies overlap where a rigid target moved by a whole
    /// increment, and a deformable body the first step bends can overshoot a whole nearly
    /// conforming surface. Newton taking that step with the states decided at the start
    /// state loads the body with forces far from equilibrium: the leaf spring's first step
    /// held three nodes on the block's cylindrical nose 1.3 to 2 mm deep (bending plastic at
    /// 640 of its 1,104 Gauss points), then pressed the upper leaf up to 1.4 mm into the lower
    /// one along its whole length; 30 iterations later the attempt was cut back, twice. Settled
    /// on the linearised problem, the step holds the nose at one node row and the lower leaf
    /// at its tip, what the converged state has, and the increment converges without cutback.
    ///
    /// Only the first step of an attempt: on the strip pull-out, whose friction couples the
    /// normal and tangential directions, the linearised problem's states cycle (multipliers
    /// going negative where released nodes then penetrate) and settling every step multiplied
    /// the factorizations by 4.6; its first steps settle at once.
    pub(super) fn settle_active_set(
        &mut self,
        (z, hist, t): At<'_>,
        dz: &mut [f64],
        eval: &mut Evaluation<f64>,
        predictor: &mut ActiveSetPredictor,
        cost: &mut PrimalCost,
    ) -> Result<usize, AttemptFailure> {
        let model = self.model;
        let mut solves = 0;
        let closed = |c: &[ContactChoice]| -> Vec<bool> {
            c.iter().map(|c| c.state != ContactState::Open).collect()
        };
        // the active sets solved with, and the step of the one whose prediction changed the
        // fewest states (Newton's own first step unless another changed strictly fewer, then
        // the latest of equals)
        let mut seen = vec![closed(&eval.contact.choice)];
        let mut best: Option<SettledStep> = None;
        while solves < model.solver.active_set_solves {
            for ((tz, zi), d) in predictor.z.iter_mut().zip(z).zip(dz.iter()) {
                *tz = zi + d;
            }
            let Some((trial, changes)) = predictor.next(
                model,
                &self.assembler,
                &self.lifted,
                (hist, t),
                eval,
                (&self.converged_choice, &self.history_at_hitting),
            ) else {
                break;
            };
            if self.trace {
                eprintln!("    active-set predictor: {trial}");
            }
            if best
                .as_ref()
                .is_none_or(|b| changes < b.changes || (changes == b.changes && !b.newtons))
            {
                best = Some(SettledStep {
                    changes,
                    dz: dz.to_vec(),
                    choice: eval.contact.choice.clone(),
                    residual: eval.residual.clone(),
                    newtons: best.is_none(),
                });
            }
            // A set solved with before: the prediction cycles (the block's nose between two
            // node rows, one tensile when closed and penetrating when open). Take the step of
            // the set whose prediction changed the fewest states and leave the rest to
            // Newton's iterations; Newton's own step wins a tie (the strip pull-out's
            // unloading cycles between it and the set releasing its end node at g = 0, and
            // the other step moves du0/dmu 2.26 % off -u0/mu, tests/oracles/contact_oracles.rs).
            // Newton's own first step is the worst on refined leaf springs: refined 7 times it
            // pressed the upper leaf 0.07 mm into the lower one along its whole length, the
            // active set then released the spurious contacts a row or two per iteration under
            // the yield-crossing limiter's short steps, and the increment never converged
            // (four cutbacks). With the fewest changes the first step holds the lower leaf at
            // its tip only, as the converged state does: refined 7 times 46 factorizations,
            // 8 times 40 (71 before), 10.4 times (230,567 unknowns) 73.
            let next = closed(&predictor.choice);
            if seen.contains(&next) {
                if let Some(b) = best.take() {
                    dz.copy_from_slice(&b.dz);
                    eval.contact.choice = b.choice;
                    eval.residual = b.residual;
                    if self.trace {
                        eprintln!(
                            "    active-set predictor: cycle, the step of the set with the fewest predicted changes ({}) taken",
                            b.changes
                        );
                    }
                }
                break;
            }
            seen.push(next);
            let frozen = Frozen {
                gauss: None,
                contact: &predictor.choice,
                skip: None,
                ..Frozen::default()
            };
            self.assemble((z, hist, t), Some(&frozen), eval, cost)
                .map_err(AttemptFailure::Element)?;
            self.newton_step(eval, dz, cost)?;
            solves += 1;
        }
        Ok(solves)
    }

    /// What cycles in a stalled attempt, in words: the hitting nodes whose contact state or
    /// face and the Gauss points whose branch change over the window, with the states they
    /// take, and what to try.
    pub(super) fn diagnose_cycle(
        &self,
        window: &std::collections::VecDeque<super::attempt::Decisions>,
        tolerance: f64,
    ) -> String {
        let mut flips = Vec::new();
        let mut nodes = 0;
        let mut bodies: Vec<usize> = Vec::new();
        // the bodies, under large kinematics, of those flipping points whose elements have
        // incompatible modes
        let mut enhanced: Vec<usize> = Vec::new();
        if let Some((first, branches, _)) = window.front() {
            for i in 0..first.len() {
                let mut seen: Vec<String> = Vec::new();
                for (c, _, _) in window {
                    let what = self.contact_state_words(i, &c[i]);
                    if !seen.contains(&what) {
                        seen.push(what);
                    }
                }
                if seen.len() > 1 {
                    flips.push(format!(
                        "{} ({})",
                        self.hitting_node_words(i),
                        seen.join(" / ")
                    ));
                }
            }
            nodes = flips.len();
            for i in 0..branches.len() {
                if window.iter().any(|(_, b, _)| b[i] != branches[i]) {
                    let (e, q) = self.assembler.dofs.gauss_owner(i);
                    flips.push(format!("element {e} Gauss point {q} (elastic / plastic)"));
                    if let Some(b) = self.model.element_body(e).filter(|b| !bodies.contains(b)) {
                        bodies.push(b);
                    }
                    // large kinematics: the geometric stiffness that folds the modes
                    let large = |b: &usize| {
                        self.model.bodies[*b].kinematics == crate::element::Kinematics::Large
                    };
                    if let Some(b) = (self.incompatible_modes_body(e))
                        .filter(|b| large(b) && !enhanced.contains(b))
                    {
                        enhanced.push(b);
                    }
                }
            }
        }
        let best = window
            .iter()
            .map(|(_, _, r)| *r)
            .fold(f64::INFINITY, f64::min);
        let n = flips.len();
        let points = n - nodes;
        let what = if flips.is_empty() {
            "with the contact states and material branches unchanged".to_string()
        } else {
            let who = match (nodes, points) {
                (_, 0) => format!("{nodes} hitting node(s)"),
                (0, _) => format!("{points} Gauss point(s)"),
                _ => format!("{nodes} hitting node(s) and {points} Gauss point(s)"),
            };
            flips.truncate(6);
            format!(
                "with {who} flipping: {}{}",
                flips.join(", "),
                if n > 6 { ", ..." } else { "" }
            )
        };
        // a mixed cycle counts as a contact one (the fuzzer's class too), with both advices
        let contact = "a softer tangential_stiffness or normal penalty on those pairs";
        let advice = match (nodes, points) {
            (0, 0) => "or a softer tangential_stiffness or normal penalty".to_string(),
            (0, _) => format!(
                "or, changing the model, a larger hardening modulus H for {}",
                self.bodies_words(&bodies)
            ),
            (_, 0) => format!("or {contact}"),
            _ => format!(
                "or {contact}, or, changing the model, a larger hardening modulus H for {}",
                self.bodies_words(&bodies)
            ),
        };
        // the physics fuzzer's seed 968 (J2 with incompatible modes under large kinematics
        // beneath a contact; 931 did before the modes were relaxed after a failed attempt)
        // cycles so, and completes its whole path with F-bar;
        // a mixed cycle, of contact states too, gets the advice as well
        let formulation = if enhanced.is_empty() {
            String::new()
        } else {
            format!(
                "; the flipping points of {} are in elements with incompatible modes, whose enhanced modes can fold a Gauss point under large plastic flow: formulation = \"f-bar\" may hold there",
                self.bodies_words(&enhanced)
            )
        };
        format!(
            "Newton cycles {what}, the residual staying above {best:.3e} (tolerance {tolerance:.3e}); try more increments in this step, {advice}{formulation}"
        )
    }

    /// `body 'a'` or `bodies 'a', 'b'` of the model's bodies `bodies`.
    fn bodies_words(&self, bodies: &[usize]) -> String {
        let names: Vec<String> = (bodies.iter())
            .map(|&b| format!("'{}'", self.model.bodies[b].name))
            .collect();
        match names.len() {
            1 => format!("body {}", names[0]),
            _ => format!("bodies {}", names.join(", ")),
        }
    }

    /// The pair of flat hitting node `i`.
    pub(super) fn pair_of(&self, i: usize) -> usize {
        (self.assembler.contact.flat.iter())
            .rposition(|&f| f <= i)
            .unwrap_or(0)
    }

    /// `pair 'name' node n` of flat hitting node `i`.
    pub(super) fn hitting_node_words(&self, i: usize) -> String {
        let p = self.pair_of(i);
        let pair = &self.model.contacts[p];
        let first = self.assembler.contact.flat[p];
        format!("pair '{}' node {}", pair.name, pair.hitting[i - first])
    }

    /// A contact state in words (`slip on face 3`; no face on a rigid target).
    fn contact_state_words(&self, i: usize, c: &ContactChoice) -> String {
        let p = self.pair_of(i);
        let rigid = matches!(
            self.model.contacts[p].target,
            crate::contact::Target::Rigid { .. }
        );
        let state = match c.state {
            ContactState::Open => return "open".to_string(),
            ContactState::Closed => "closed",
            ContactState::Stick => "stick",
            ContactState::Slip => "slip",
        };
        if rigid {
            state.to_string()
        } else {
            format!("{state} on face {}", c.face)
        }
    }
}
