//! # An elastoplastic two-leaf spring, loaded, unloaded and reloaded: the paper's second example
//!
//! **What.** The coarse leaf spring (`leaf-spring-coarse`, [`LeafSpringSpec::reduced`]): a
//! half model of a two-leaf spring clamped at its centre, J2 elastoplastic leaves (E = 206 GPa,
//! sigma_y = 800 MPa, linear hardening H = 2 GPa), large deformation, 5 mm elements along the
//! 100 mm upper leaf. A rigid block with a cylindrical nose pushes the upper leaf 10 mm from its
//! tip down 20 mm, back up to 10 mm and down to 20 mm again; Coulomb friction mu = 0.5 acts
//! between the leaves and between the leaf and the block. We follow the block's force `F` and
//! its derivatives `dF/dmu` and `dF/dL` (L, the upper leaf's length, is a shape parameter: the
//! mesh generator is differentiated with it) along the whole path by DDM, in one run.
//!
//! **Why.** Plasticity and friction both make the response path dependent: the same block
//! position gives a different force, and a different sensitivity, in loading and unloading.
//! The derivative of the state at an increment depends on the derivative of the history
//! (plastic strains, friction anchors) that led to it, which DDM carries from increment to
//! increment. When the block reverses, friction reverses too: it resisted the leaf's sliding
//! under the nose in loading (adding to F) and now holds the leaf up (taking from F), so the
//! sign of `dF/dmu` follows the direction of motion, not the position.
//!
//! **Result.** Run `cargo run --release --example leaf_spring` (about 20 s on two cores, half of
//! it FDM's four reruns). It prints the history, then checks:
//!
//! * at the same block position (15 mm down) `dF/dmu` is positive in loading and in reloading
//!   and negative in unloading;
//! * `dF/dmu` at 15 mm in unloading and `dF/dL` at the end of loading agree with central
//!   finite differences of reruns (beta = 1e-6) to 1e-5 relative. The reruns follow the
//!   nominal run's increments; a rerun that needs a cutback the nominal run did not take solves
//!   the path-dependent problem on other steps, and its difference then measures the change of
//!   the discrete path over the perturbation, not the derivative. The example checks that
//!   neither value it compares is such a case (at larger beta, some of this spring's reruns
//!   are).
//!
//! Increments at which the converged state sits on a yield, contact or stick/slip transition
//! (where the response has only one-sided derivatives) are marked `*`. The paper-resolution
//! spring (`leaf-spring`, 40 x 2 elements, 56 increments) is in `cargo run --release --
//! validate`, which redraws the paper's figures 7-9.

use fricsens::scene::{leaf_spring, LeafSpringSpec};
use fricsens::sensitivity::{run_sensitivity, Method, Parameter, Settings, TangentChoice};

/// What the study found, for the caller (and the test that runs it) to check.
pub struct Summary {
    /// Relative differences of DDM from central FDM: `dF/dmu` (unloading, 15 mm), `dF/dL` (end of loading).
    pub fdm_difference: [f64; 2],
    /// Sign changes of `dF/dmu` along the path.
    pub sign_changes: usize,
    /// Wall seconds: primal, DDM, central FDM (sum of its reruns).
    pub seconds: [f64; 3],
}

/// Run the study and print the history.
pub fn study() -> Result<Summary, Box<dyn std::error::Error>> {
    let spec = LeafSpringSpec::reduced();
    let model = leaf_spring(&spec).build()?;
    let params = [
        Parameter::by_name(&model, "mu")?,
        Parameter::by_name(&model, "upper.length.x")?,
    ];
    let settings = Settings {
        method: Method::Ddm,
        tangent: TangentChoice::Exact,
        ..Settings::default()
    };
    let (_, ddm) = run_sensitivity(&model, &params, &settings)?;
    let force = ddm
        .responses
        .iter()
        .position(|r| r == "block-force")
        .expect("block-force response");

    // the block's downward displacement at pseudo-time t (the scene's load path)
    let down = |t: f64| {
        let a = if t <= 1.0 {
            t
        } else if t <= 2.0 {
            1.0 - (t - 1.0) * (1.0 - spec.unload_to / spec.stroke)
        } else {
            spec.unload_to / spec.stroke + (t - 2.0) * (1.0 - spec.unload_to / spec.stroke)
        };
        a * spec.stroke
    };
    let phase = |t: f64| {
        if t <= 1.0 + 1e-9 {
            "load"
        } else if t <= 2.0 + 1e-9 {
            "unload"
        } else {
            "reload"
        }
    };
    println!(" inc      t   phase   block (mm)     F (N)    dF/dmu (N)   dF/dL (N/mm)");
    for inc in &ddm.increments {
        println!(
            "{:>4}{} {:>6.3}  {:<6}  {:>9.2}  {:>9.2}  {:>11.3}  {:>12.4}",
            inc.increment,
            if inc.kinks.is_empty() { " " } else { "*" },
            inc.time,
            phase(inc.time),
            down(inc.time),
            inc.values[force],
            inc.derivatives[force][0],
            inc.derivatives[force][1]
        );
    }

    // path dependence: dF/dmu at the same block position in each phase
    let at = |t: f64| {
        ddm.increments
            .iter()
            .find(|i| (i.time - t).abs() < 1e-9)
            .expect("an increment at t")
    };
    let fifteen = [0.75, 1.5, 2.5]; // 15 mm down in loading, unloading, reloading
    println!("\nat 15 mm down:");
    for t in fifteen {
        let i = at(t);
        println!(
            "  {:<6}  F = {:>8.2} N   dF/dmu = {:>9.3} N   dF/dL = {:>8.4} N/mm",
            phase(t),
            i.values[force],
            i.derivatives[force][0],
            i.derivatives[force][1]
        );
    }
    let dmu: Vec<f64> = ddm
        .increments
        .iter()
        .map(|i| i.derivatives[force][0])
        .collect();
    let sign_changes = dmu.windows(2).filter(|w| w[0] * w[1] < 0.0).count();
    println!("dF/dmu changes sign {sign_changes} times along the path");

    // one value of each derivative against central finite differences of reruns
    // small enough that no rerun needs a cutback the nominal run did not take (see below)
    let beta = 1e-6;
    let fdm_settings = Settings {
        method: Method::FdmCentral,
        beta,
        ..Settings::default()
    };
    let (_, fdm) = run_sensitivity(&model, &params, &fdm_settings)?;
    let fdm_at = |t: f64| {
        fdm.increments
            .iter()
            .find(|i| (i.time - t).abs() < 1e-9)
            .expect("an increment at t")
    };
    let checks = [
        (1.5, 0, "dF/dmu, unloading at 15 mm"),
        (1.0, 1, "dF/dL, end of loading"),
    ];
    let mut fdm_difference = [0.0; 2];
    for (k, (t, p, what)) in checks.into_iter().enumerate() {
        let (a, b) = (at(t), fdm_at(t));
        assert!(a.kinks.is_empty(), "{what}: flagged non-differentiable");
        assert!(
            !b.rerun_substeps[p],
            "{what}: a rerun took other sub-increments"
        );
        let (x, y) = (a.derivatives[force][p], b.derivatives[force][p]);
        fdm_difference[k] = (x - y).abs() / x.abs();
        println!(
            "{what}: DDM {x:.6e}, central FDM (beta {beta:e}) {y:.6e}, relative difference {:.1e}",
            fdm_difference[k]
        );
    }
    let seconds = [
        ddm.primal_seconds,
        ddm.cost.wall_seconds,
        fdm.cost.wall_seconds,
    ];
    println!(
        "wall time (s): primal {:.1}, DDM (2 parameters) {:.1}, central FDM {:.1} ({} reruns)",
        seconds[0], seconds[1], seconds[2], fdm.cost.primal_reruns
    );

    // the checks the doc comment states
    let [load, unload, reload] = fifteen.map(|t| at(t).derivatives[force][0]);
    assert!(
        load > 0.0 && unload < 0.0 && reload > 0.0,
        "dF/dmu at 15 mm: load {load}, unload {unload}, reload {reload}"
    );
    for (d, (_, _, what)) in fdm_difference.iter().zip(checks) {
        // central FDM at beta 1e-6: truncation ~1e-12, the reruns' Newton tolerance (1e-9 of the
        // reference force) over beta bounds the noise at ~1e-3 of F, far above what is seen
        assert!(*d <= 1e-5, "{what}: DDM vs central FDM {d:.2e}");
    }
    Ok(Summary {
        fdm_difference,
        sign_changes,
        seconds,
    })
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    study().map(|_| ())
}
