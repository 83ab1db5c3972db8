//! # A rigid block indents and slides on an elastic foundation: the paper's first example
//!
//! **What.** The `indentation` scene (Chen, Hisada, Nakamura & Mori, section 3.1): a rigid block
//! 20 mm wide with rounded corners is pressed 0.01 mm into an elastic slab (plane strain,
//! E = 200 GPa, nu = 0.3, 500 mm x 250 mm, 1.67 mm elements under the block) and then slid
//! 3.33 mm — two element widths — with Coulomb friction mu = 0.5. After the slide we take the
//! block's reaction forces (tangential `Fx`, normal `Fy`) and the contact pressure at the
//! trailing edge, the middle and the leading edge of the contact, and their sensitivities to
//! the friction coefficient mu and to Young's modulus E by three methods:
//!
//! * **DDM** — the residual evaluated with dual numbers at each converged state: the exact
//!   derivative of the discrete equations (the reference);
//! * **SDM** — the paper's semi-analytical method, forward, beta = 1e-6: the finite difference of
//!   the unbalance force at the fixed converged state;
//! * **central FDM**, beta = 1e-5: four complete reruns (mu and E, each +- beta).
//!
//! DDM and SDM run in line with one primal analysis and solve with the tangent at the converged
//! state (`TangentChoice::Exact`); the timings are each method's own work and, for FDM, the sum
//! of its reruns (they run in parallel, two at a time on two cores).
//!
//! **Why.** Finite sliding with friction is the case a sensitivity method must survive: the
//! friction history is path dependent, the contact zone travels two element widths, and the
//! derivative of a converged state needs the derivative of the history that led to it. The
//! three methods share the kernels but not the arithmetic, so their agreement is a check of each.
//!
//! **Result.** Run `cargo run --release --example indentation_study` (about 40 s on two
//! cores, most of it FDM's four reruns). The mesh is the paper's; the slide takes 5 increments
//! instead of the built-in scene's 10 (0.67 mm, 0.4 element widths, each), which halves the
//! time; the validation harness runs the built-in scene. The example asserts, and so the run
//! shows:
//!
//! * central FDM (beta = 1e-5) and forward SDM (beta = 1e-6) agree with DDM to 1e-5 of each
//!   derivative in the table (relative, with a floor of 1e-3 of the largest derivative of its
//!   kind). FDM's reruns converge to a force tolerance of 1e-9, and 1e-9 / beta = 1e-4 bounds
//!   their noise, far above what is seen; SDM's forward truncation is of order beta;
//! * at the end of the slide every closed contact node slips, so Coulomb's law gives
//!   `Fx = -mu Fy` (friction opposes the sliding) and `dFx/dmu = -(Fy + mu dFy/dmu)`: DDM
//!   satisfies both to 1e-8;
//! * the slab is linear elastic, the block's motion is prescribed and every node slips, so
//!   every force and pressure is proportional to E: `E dF/dE = F` to 1e-6;
//! * the pressure is higher at the trailing edge than at the leading edge, and the asymmetry
//!   grows with mu: `dp/dmu > 0` at the trailing edge and `< 0` at the leading edge. A
//!   tangential traction on an elastic half-space also moves its surface normally, by a term
//!   proportional to `(1 - 2 nu) / (2 (1 - nu))` (Johnson, *Contact Mechanics*, section 2.2):
//!   the surface ahead of the friction sinks and the surface behind rises, so a rigid flat block
//!   bears harder behind and lighter ahead, and more so the larger mu.
//!
//! The table lists the values; `cargo run --release -- validate` sweeps beta for the same scene
//! and redraws the paper's figures 4 and 5.

use fricsens::response::ResponseKind;
use fricsens::scene::indentation;
use fricsens::sensitivity::{
    run_fdm_sweep, run_inline_sweep, Method, Parameter, SensitivityResults, Settings, TangentChoice,
};

/// The responses of the table: name and index into the model's responses.
struct Row {
    label: String,
    index: usize,
}

/// What the study found, for the caller (and the test that runs it) to check.
pub struct Summary {
    /// Largest relative difference from DDM over the table, `[SDM, FDM]`.
    pub max_difference: [f64; 2],
    /// Wall seconds: primal, DDM, SDM, FDM (sum of reruns).
    pub seconds: [f64; 4],
}

/// Run the study on `indentation(press, slide)` and print the table.
pub fn study(press: usize, slide: usize) -> Result<Summary, Box<dyn std::error::Error>> {
    let model = indentation(press, slide).build()?;
    let params = [
        Parameter::by_name(&model, "mu")?,
        Parameter::by_name(&model, "E")?,
    ];
    let (mu, young) = (params[0].value, params[1].value);

    // DDM and forward SDM on one primal run; the sensitivity solves use the converged tangent
    let settings = |method, beta| Settings {
        method,
        beta,
        tangent: TangentChoice::Exact,
        ..Settings::default()
    };
    let (_, inline) = run_inline_sweep(
        &model,
        &params,
        &[settings(Method::Ddm, 0.0), settings(Method::Sdm, 1e-6)],
    )?;
    let (ddm, sdm) = (&inline[0], &inline[1]);
    let (_, mut fdm) = run_fdm_sweep(&model, &params, &[1e-5], true)?;
    let fdm = fdm.pop().expect("central FDM");
    for s in [ddm, sdm, &fdm] {
        if let Some(why) = &s.failure {
            return Err(why.clone().into());
        }
    }

    // the contact nodes after sliding, by reference position x; the slab is one element
    // thick, so each x has two nodes (z = 0 and z = h): keep z = 0
    let x = model.mesh.coordinates::<f64>(&model.mesh.block_geometry());
    let last = ddm.increments.last().expect("increments");
    let mut contact: Vec<(f64, usize)> = model
        .responses
        .iter()
        .enumerate()
        .filter_map(|(r, resp)| match resp.kind {
            ResponseKind::ContactPressure {
                pair, ref nodes, ..
            } => {
                let p = x[model.contacts[pair].hitting[nodes[0]]];
                (p[2] == 0.0 && last.values[r] > 0.0).then_some((p[0], r))
            }
            _ => None,
        })
        .collect();
    contact.sort_by(|a, b| a.0.total_cmp(&b.0));
    let (trailing, leading) = (contact[0], contact[contact.len() - 1]);
    let middle = contact[contact.len() / 2];
    let position = |r: &str| model.responses.iter().position(|x| x.name == r);
    let (fx, fy) = (
        position("block-force-x").expect("Fx"),
        position("block-force-y").expect("Fy"),
    );
    let rows = [
        Row {
            label: "Fx (N)".into(),
            index: fx,
        },
        Row {
            label: "Fy (N)".into(),
            index: fy,
        },
        Row {
            label: format!("p trailing, x = {:.2} (MPa)", trailing.0),
            index: trailing.1,
        },
        Row {
            label: format!("p middle, x = {:.2} (MPa)", middle.0),
            index: middle.1,
        },
        Row {
            label: format!("p leading, x = {:.2} (MPa)", leading.0),
            index: leading.1,
        },
    ];

    println!(
        "indentation: {} unknowns, {} increments, {} contact nodes (z = 0) closed after sliding\n",
        model.dof_map().n_total,
        last.increment,
        contact.len()
    );
    let d = |s: &SensitivityResults, r: usize, p: usize| {
        s.increments.last().expect("increments").derivatives[r][p]
    };
    let mut max_difference = [0.0f64; 2];
    for (p, pname) in ["mu", "E (per MPa)"].iter().enumerate() {
        println!(
            "{:<28} {:>12} | {:>14} {:>14} {:>14} | {:>9} {:>9}",
            "response",
            "value",
            format!("d/d{pname} DDM"),
            "SDM",
            "central FDM",
            "SDM-DDM",
            "FDM-DDM"
        );
        for row in &rows {
            let reference = d(ddm, row.index, p);
            // relative to the derivative, with a floor: the largest |derivative| of the table's
            // responses of this kind (forces or pressures) times 1e-3
            let scale = rows
                .iter()
                .filter(|o| {
                    (o.index == fx || o.index == fy) == (row.index == fx || row.index == fy)
                })
                .map(|o| d(ddm, o.index, p).abs())
                .fold(0.0, f64::max);
            let rel = |s: &SensitivityResults| {
                (d(s, row.index, p) - reference).abs() / reference.abs().max(1e-3 * scale)
            };
            let (es, ef) = (rel(sdm), rel(&fdm));
            max_difference[0] = max_difference[0].max(es);
            max_difference[1] = max_difference[1].max(ef);
            println!(
                "{:<28} {:>12.5e} | {:>14.6e} {:>14.6e} {:>14.6e} | {:>9.1e} {:>9.1e}",
                row.label,
                last.values[row.index],
                reference,
                d(sdm, row.index, p),
                d(&fdm, row.index, p),
                es,
                ef
            );
        }
        println!();
    }
    let seconds = [
        ddm.primal_seconds,
        ddm.cost.wall_seconds,
        sdm.cost.wall_seconds,
        fdm.cost.wall_seconds,
    ];
    println!(
        "wall time (s): primal {:.1}; for both parameters: DDM {:.1}, SDM {:.1}, central FDM {:.1} ({} reruns)",
        seconds[0], seconds[1], seconds[2], seconds[3], fdm.cost.primal_reruns
    );

    // what it means
    let (vfx, vfy) = (last.values[fx], last.values[fy]);
    let (dfx, dfy) = (d(ddm, fx, 0), d(ddm, fy, 0));
    // Fx = sign mu Fy at full slip (the friction force opposes the sliding)
    let sign = (vfx / vfy).signum();
    let (pt, pl) = (last.values[trailing.1], last.values[leading.1]);
    let (dpt, dpl) = (d(ddm, trailing.1, 0), d(ddm, leading.1, 0));
    println!(
        "\nCoulomb at full slip: Fx / Fy = {:.9} (mu = {mu}); dFx/dmu = {dfx:.9e}, \
         {}(Fy + mu dFy/dmu) = {:.9e}",
        vfx / vfy,
        if sign < 0.0 { "-" } else { "" },
        sign * (vfy + mu * dfy)
    );
    println!(
        "Pressure asymmetry: trailing {pt:.1} MPa, leading {pl:.1} MPa; it grows with mu: \
         dp/dmu = {dpt:+.1} MPa behind, {dpl:+.1} MPa ahead.\n\
         E dFy/dE / Fy = {:.9}: linear elasticity, prescribed displacements and full slip, so \
         every force scales with E.",
        young * d(ddm, fy, 1) / vfy
    );

    // the checks the doc comment states
    assert!(
        max_difference[1] <= 1e-5,
        "central FDM vs DDM: {:.2e}",
        max_difference[1]
    );
    assert!(
        max_difference[0] <= 1e-5,
        "forward SDM vs DDM: {:.2e}",
        max_difference[0]
    );
    assert!(
        (vfx - sign * mu * vfy).abs() <= 1e-8 * vfx.abs(),
        "full slip: Fx / Fy = {} vs mu = {mu}",
        vfx / vfy
    );
    assert!(
        (dfx - sign * (vfy + mu * dfy)).abs() <= 1e-8 * dfx.abs(),
        "dFx/dmu {dfx} vs Fy + mu dFy/dmu {}",
        vfy + mu * dfy
    );
    assert!(pt > pl && dpt > 0.0 && dpl < 0.0, "pressure asymmetry");
    // linear elasticity, prescribed displacements, every closed node slipping: scaling E
    // scales every force and pressure and leaves the displacements alone
    for row in &rows {
        let (v, scaled) = (last.values[row.index], young * d(ddm, row.index, 1));
        assert!(
            (scaled - v).abs() <= 1e-6 * v.abs(),
            "{}: E d/dE = {scaled} vs {v}",
            row.label
        );
    }
    Ok(Summary {
        max_difference,
        seconds,
    })
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    // the paper's mesh; 2 increments pressing, 5 sliding (the built-in scene slides in 10)
    study(2, 5).map(|_| ())
}
