//! The assembled contact tangent (forward AD over each hitting node's unknowns) against the
//! dual-number directional derivative of the whole residual, in stick and in slip, on a rigid
//! and on a deformable target.

// Index loops over responses, parameters and unknowns read like the formulas they check.
#![allow(clippy::needless_range_loop)]

use crate::common::{directional, solve, Directional};

use fricsens::assembly::{Assembler, Evaluation};
use fricsens::contact::ContactState;
use fricsens::linalg::SparseMatrix;
use fricsens::model::Model;
use fricsens::scene::{contact_patch, strip_pullout, StripSpec};

/// Check K v against d/de R(z + e v) at state `z` and committed history `hist`.
fn check(model: &Model, z: &[f64], hist: &[f64], t: f64) -> (usize, usize) {
    let v: Vec<f64> = (0..z.len())
        .map(|i| 1e-3 * ((i as f64) * 0.77).sin())
        .collect();
    let Directional { ev, dual: evd, kv } = directional(model, z, hist, t, &v);
    let stick = ev
        .contact
        .choice
        .iter()
        .filter(|c| c.state == ContactState::Stick)
        .count();
    let slip = ev
        .contact
        .choice
        .iter()
        .filter(|c| c.state == ContactState::Slip)
        .count();
    // the branches of the dual evaluation are those of the f64 one (decided on real parts)
    assert_eq!(evd.contact.choice, ev.contact.choice);
    let scale = kv.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    for i in 0..z.len() {
        let d = evd.residual[i].eps;
        assert!(
            (d - kv[i]).abs() <= 1e-8 * scale,
            "unknown {i}: dual {d} vs K v {}",
            kv[i]
        );
    }
    (stick, slip)
}

#[test]
fn contact_tangent_on_a_rigid_target_in_stick_and_slip() {
    let s = StripSpec {
        elements: 20,
        ..StripSpec::default()
    };
    let mut model = strip_pullout(&s).build().unwrap();
    model.times.retain(|t| *t <= 0.5 + 1e-12);
    let res = solve(&model);
    // partial slip at t = 0.5 (slip zone near the pulled end)
    let k = res.increment_at(0.5).unwrap();
    let (stick, slip) = check(&model, &res.states[k], &res.histories[k - 1], 0.5);
    println!("stick {stick}, slip {slip}");
    assert!(
        stick > 0 && slip > 0,
        "want both branches: stick {stick}, slip {slip}"
    );
}

#[test]
fn contact_tangent_on_a_deformable_target() {
    let model = contact_patch(Some(0.3)).build().unwrap();
    let res = solve(&model);
    // step off the converged state tangentially so the interface slips somewhere
    let mut z = res.states[1].clone();
    for n in &model.contacts[0].hitting {
        z[3 * n] += 1e-4 * (*n as f64 * 0.3).sin();
    }
    let (stick, slip) = check(&model, &z, &res.histories[0], 1.0);
    println!("stick {stick}, slip {slip}");
    assert!(stick + slip > 0);
}

/// The stick anchor on another face than the contact face: the node's tangent then has the
/// anchor face's unknowns too (the widest of the tangent's dual types). And an anchor on a
/// face outside the node's candidates, which has no place in its block: a typed error, not
/// a panic.
#[test]
fn contact_tangent_with_the_anchor_on_another_face() {
    use fricsens::contact::Target;
    let model = contact_patch(Some(0.3)).build().unwrap();
    let res = solve(&model);
    let pair = &model.contacts[0];
    let Target::Faces { faces } = &pair.target else {
        panic!("the patch's target is deformable")
    };
    let asm = Assembler::new(&model, &[]).unwrap();
    let h0 = asm.contact_history(0);
    let nh = pair.history_len();
    let z = &res.states[1];
    let mut hist = res.histories[0].clone();
    // each node's contact face at this state (the evaluation below keeps it: the contact
    // face is searched from the state, not from the history)
    let ne = model.mesh.n_elements();
    let lifted = model.lifted::<f64>(&[]);
    let mut ev = Evaluation::<f64>::new(&asm, ne);
    asm.evaluate(&model, &lifted, z, &hist, 1.0, None, None, &mut ev)
        .unwrap();
    let flat = asm.contact_flat(0);
    let mut moved = 0;
    let mut outside = None;
    for (i, cands) in pair.candidates.iter().enumerate() {
        let at = h0 + nh * i;
        let face = ev.contact.choice[flat + i].face;
        // a candidate face that shares no node with the contact face: the tangent then
        // seeds 3 + 4 x 3 + 4 x 3 + 1 = 28 unknowns, the widest dual
        if let Some(&other) = cands.iter().find(|&&f| {
            faces
                .nodes(f)
                .iter()
                .all(|n| !faces.nodes(face).contains(n))
        }) {
            hist[at] = other as f64;
            moved += 1;
        }
        // a face with a node outside this node's candidates
        if outside.is_none() {
            outside = (0..faces.len())
                .find(|f| {
                    faces
                        .nodes(*f)
                        .iter()
                        .any(|n| cands.iter().all(|&c| !faces.nodes(c).contains(n)))
                })
                .map(|f| (f, i));
        }
    }
    assert!(moved > 0, "no node has a second candidate face");
    let (stick, slip) = check(&model, z, &hist, 1.0);
    println!("{moved} anchors moved: stick {stick}, slip {slip}");
    assert!(stick + slip > 0);
    // an anchor face with a node outside the candidates of node i
    let (f, i) = outside.expect("a face outside some node's candidates");
    let mut bad = res.histories[0].clone();
    bad[h0 + nh * i] = f as f64;
    let mut k = SparseMatrix::new(asm.pattern.clone());
    let err = asm
        .evaluate(&model, &lifted, z, &bad, 1.0, None, Some(&mut k), &mut ev)
        .expect_err("an anchor outside the block");
    let msg = err.to_string();
    assert!(
        msg.contains("not on any of the hitting node's candidate faces"),
        "{msg}"
    );
}
