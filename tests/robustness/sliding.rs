//! A deformable block slid over several faces of another deformable block: mu = 0 reproduces
//! the frictionless pair, a very large mu sticks everywhere, and the friction force stays at
//! mu N while the hitting nodes cross segment boundaries. The VTK output carries the state map.

use crate::common::{scratch_path, solve, solve_scene};

use fricsens::contact::ContactState;
use fricsens::model::Model;
use fricsens::scene::sliding_block as scene;
use fricsens::solver::Results;

const N: f64 = 1.0; // total normal load on the slider

fn run(friction: Option<f64>) -> (Model, Results) {
    let mut s = scene(friction);
    // converge to round-off so two runs can be compared beyond the default 1e-9 tolerance
    s.solver.force_tol = 1e-13;
    solve_scene(s)
}

#[test]
fn mu_zero_reproduces_the_frictionless_pair() {
    let (m0, r0) = run(Some(0.0));
    let (mf, rf) = run(None);
    assert_eq!(r0.states.len(), rf.states.len());
    let n = mf.dof_map().first_lambda; // compare the displacements
    for k in 0..r0.states.len() {
        let scale = rf.states[k][..n]
            .iter()
            .fold(1e-12f64, |m, v| m.max(v.abs()));
        let diff = (0..n).fold(0.0f64, |m, i| {
            m.max((r0.states[k][i] - rf.states[k][i]).abs())
        });
        println!(
            "increment {k}: largest difference {:.3e} of the largest displacement",
            diff / scale
        );
        assert!(diff <= 1e-10 * scale, "increment {k}: {}", diff / scale);
        // the pull equals the frictionless one (it is not zero: the base's top bends under
        // the slider and the tilted normals carry an x-component)
        let (p0, pf) = (r0.response_value(&m0, 0, k), rf.response_value(&mf, 0, k));
        assert!(
            (p0 - pf).abs() <= 1e-10 * N,
            "increment {k}: pull {p0} vs frictionless {pf}"
        );
    }
}

#[test]
fn very_large_mu_sticks_everywhere() {
    let model = {
        let mut s = scene(Some(1e4));
        // a small pull: the base shears elastically under the stuck slider
        s.prescribed[3].value = 1e-3;
        s.build().unwrap()
    };
    let res = solve(&model);
    for (k, c) in res.contact.iter().enumerate().skip(1) {
        for ch in &c.choice {
            assert!(
                matches!(ch.state, ContactState::Stick),
                "increment {k}: {:?}",
                ch.state
            );
        }
    }
}

#[test]
fn friction_force_stays_at_mu_n_while_sliding_across_segments() {
    let mu = 0.3;
    let (model, res) = run(Some(mu));
    let mut worst: f64 = 0.0;
    let mut sliding = 0;
    for k in 1..res.states.len() {
        let all_slip = res.contact[k]
            .choice
            .iter()
            .all(|c| matches!(c.state, ContactState::Slip));
        if !all_slip {
            continue;
        }
        sliding += 1;
        // the pull balances the friction force: -(reaction) = mu N in full slip
        let pull = res.response_value(&model, 0, k);
        worst = worst.max((pull.abs() / (mu * N) - 1.0).abs());
    }
    let iters: Vec<usize> = res.records.iter().map(|r| r.iterations).collect();
    println!("{sliding} increments in full slip; largest |F / (mu N) - 1| = {worst:.3e}; iterations {iters:?}");
    assert!(sliding >= 20, "only {sliding} increments in full slip");
    // In full slip every hitting node carries mu p_n along the local tangent; the base's top
    // is bent by the slider, so the tangents deviate from x by the surface slope (~1e-3 here),
    // which bounds the deviation of the x-force from mu N, also when a node crosses a face
    // boundary (the slope is continuous to within the same order).
    assert!(worst < 1e-2, "friction force deviates from mu N by {worst}");
    // the state map is written to the VTK files
    let dir = scratch_path("sliding");
    fricsens::output::write_run(&dir, &model, &res, fricsens::output::VtkOutput::Every(1)).unwrap();
    let vtu = std::fs::read_to_string(dir.join("vtk").join("step_0010.vtu")).unwrap();
    assert!(vtu.contains("Name=\"contact_state\"") && vtu.contains("Name=\"friction_force\""));
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn newton_converges_quadratically_once_the_contact_states_are_settled() {
    let (_, res) = run(Some(0.3));
    let mut checked = 0;
    for rec in &res.records {
        // residuals relative to the increment's reference force (the force criterion's
        // scale): the initial residual is no scale of the increment once the predictor
        // extrapolates, and can be anything from 1e-4 to 30 times this one
        let r0 = rec.reference_force.max(f64::MIN_POSITIVE);
        let r: Vec<f64> = rec.residuals.iter().map(|x| x / r0).collect();
        println!(
            "increment {}: {:?}",
            rec.index,
            r.iter().map(|x| format!("{x:.1e}")).collect::<Vec<_>>()
        );
        // every pair in the asymptotic range, once the stick/slip pattern no longer changes
        // (after the last rise of the residual, the mark of a changed pattern): r_{k+1} <= C
        // r_k^2 above the round-off floor (~1e-14 of the forces that cancel in the residual,
        // which reach ~30 times the reference force while the block slides). With the
        // extrapolating predictor most increments start at ~3e-2 and converge in two or three
        // iterations, so the range reaches up to 0.1; C = 10 keeps the bound below the
        // residual it starts from (measured C up to ~1e-3)
        let settled = r
            .windows(2)
            .rposition(|w| w[1] > w[0] && w[1] > 1e-12)
            .map_or(0, |i| i + 1);
        for w in r[settled..].windows(2) {
            if w[0] < 1e-1 && w[1] > 1e-12 {
                assert!(
                    w[1] <= 10.0 * w[0] * w[0],
                    "increment {}: {:.2e} -> {:.2e}",
                    rec.index,
                    w[0],
                    w[1]
                );
                checked += 1;
            }
        }
    }
    assert!(checked >= 20, "too few asymptotic pairs ({checked})");
}
