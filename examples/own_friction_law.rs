//! # Bring your own friction law
//!
//! **What.** A friction law that fricsens does not ship — Coulomb friction whose force saturates
//! at a shear limit, `limit = t_max tanh(mu p_n / t_max)` (Coulomb's `mu p_n` at light
//! pressures, never more than `t_max`: the shear strength of a soft coating or an interface
//! that yields) — is written in this file, plugged into the frictional strip pull-out, and its
//! design sensitivities to both of its parameters, `mu` and `t_max`, are computed by the three
//! methods: DDM (dual numbers), SDM (central, finite perturbation at the converged state) and
//! central FDM (two complete reruns per parameter).
//!
//! **Why.** The semi-analytical method's promise, in the paper's words, is that it needs only
//! the routine that computes the friction force, "regardless of the friction law employed".
//! fricsens extends that to all three methods: the law below is a page of code, generic over
//! the scalar, with no derivative written by hand. The solver's consistent tangent and DDM get
//! exact derivatives from it through [`fricsens::contact::friction::UserFriction`], which
//! differentiates the law on its own inputs with a dual number and applies the chain rule.
//!
//! What a user writes: the struct, one `law_params!` line (its name and parameter names: the
//! [`fricsens::law::Law`] trait) and its [`FrictionLaw`] implementation (about 30 lines,
//! `SaturatingCoulomb` below), then one line to put it on a contact pair:
//! `model.contacts[0].friction = Some(Friction::user(law)?)`. Its parameters are design
//! parameters by name (`ground.mu`, `ground.t_max`).
//!
//! **Result.** Run with `cargo run --release --example own_friction_law`. The three methods
//! agree on every response at every increment of the load-unload path: DDM against central FDM
//! to within 1e-6 of the largest sensitivity, DDM against SDM central to within 1e-6 — the
//! example asserts both (the test suite runs it, `tests/methods/examples.rs`). The pulled end's
//! displacement depends on the cap as much as on `mu` (its two sensitivities come out of the
//! same size): the cap binds.

use fricsens::contact::friction::{radial_return, FrictionBranch, FrictionLaw, FrictionUpdate};
use fricsens::contact::Friction;
use fricsens::model::Model;
use fricsens::scalar::Scalar;
use fricsens::scene::{strip_pullout, StripSpec};
use fricsens::sensitivity::{
    run_sensitivity, Method, Parameter, SensitivityResults, Settings, TangentChoice,
};
use nalgebra::Vector3;

/// Coulomb friction with a saturating force: `limit = t_max tanh(mu p_n / t_max)`.
/// Parameters: `mu` (the coefficient at light pressures) and `t_max` (the largest tangential
/// force of a hitting node).
#[derive(Clone, Debug)]
pub struct SaturatingCoulomb {
    params: [f64; 2],
}

// Its name and named parameters (the `Law` trait, shared with the shipped laws and materials):
// the parameters are the field `params`, in the order of the names, and must be finite.
fricsens::law_params!(
    SaturatingCoulomb,
    "saturating-coulomb",
    ["mu", "t_max"],
    check = |p| {
        fricsens::law::nonnegative(p[0], "mu")?;
        fricsens::law::positive(p[1], "t_max")
    }
);

impl FrictionLaw for SaturatingCoulomb {
    fn return_map<S: Scalar>(
        &self,
        p: &[S],
        t_trial: &Vector3<S>,
        p_n: S,
        margin: f64,
        frozen: Option<FrictionBranch>,
    ) -> FrictionUpdate<S> {
        let (mu, t_max) = (p[0], p[1]);
        let limit = (mu * p_n / t_max).tanh() * t_max;
        // the radial return onto the circle |t| = limit, shared with the shipped Coulomb laws
        radial_return(t_trial, limit, margin, frozen)
    }
}

/// The largest disagreement of each method with DDM, over every response, increment and
/// parameter, relative to the largest DDM sensitivity of that response and parameter.
#[derive(Debug)]
pub struct Agreement {
    /// Central FDM (two reruns per parameter) against DDM.
    pub fdm_central: f64,
    /// SDM central against DDM.
    pub sdm_central: f64,
    /// Parameter names.
    pub parameters: Vec<String>,
    /// Final-increment DDM sensitivities of the first response, per parameter.
    pub final_ddm: Vec<f64>,
    /// Name of the first response.
    pub response: String,
}

/// The strip pull-out of `shared/oracles.md` section 7, coarsened to 20 elements, loaded and
/// unloaded, with the user's law on its contact pair.
pub fn model() -> Model {
    let spec = StripSpec {
        elements: 20,
        ..StripSpec::default()
    };
    let mut model = strip_pullout(&spec)
        .build()
        .expect("the built-in strip scene builds");
    // a cap near the Coulomb force of a node: the derivative in t_max comes out of the size of
    // the derivative in mu, so the cap binds without removing Coulomb's range
    let law = SaturatingCoulomb { params: [0.5, 0.2] };
    model.contacts[0].friction = Some(Friction::user(law).expect("two parameters fit"));
    model
}

/// Largest `|a - b|` over the path, relative to the largest `|a|` per (response, parameter).
fn disagreement(a: &SensitivityResults, b: &SensitivityResults) -> f64 {
    let (nr, np) = (a.responses.len(), a.parameters.len());
    let mut worst: f64 = 0.0;
    for r in 0..nr {
        for p in 0..np {
            let scale = a
                .increments
                .iter()
                .fold(0.0f64, |m, i| m.max(i.derivatives[r][p].abs()));
            if scale == 0.0 {
                continue;
            }
            for (x, y) in a.increments.iter().zip(&b.increments) {
                worst = worst.max((x.derivatives[r][p] - y.derivatives[r][p]).abs() / scale);
            }
        }
    }
    worst
}

/// Run DDM, SDM central and central FDM on the user's law and compare them.
pub fn run() -> Agreement {
    let model = model();
    let params: Vec<Parameter> = ["ground.mu", "ground.t_max"]
        .iter()
        .map(|name| Parameter::by_name(&model, name).expect("the law names its parameters"))
        .collect();
    let sensitivities = |method, beta| {
        let settings = Settings {
            method,
            beta,
            tangent: TangentChoice::Exact,
            ..Settings::default()
        };
        run_sensitivity(&model, &params, &settings)
            .expect("the strip converges")
            .1
    };
    let ddm = sensitivities(Method::Ddm, 0.0);
    let sdm = sensitivities(Method::SdmCentral, 1e-5);
    let fdm = sensitivities(Method::FdmCentral, 1e-6);
    assert_eq!(ddm.increments.len(), fdm.increments.len());
    let last = ddm.increments.last().expect("at least one increment");
    Agreement {
        fdm_central: disagreement(&ddm, &fdm),
        sdm_central: disagreement(&ddm, &sdm),
        parameters: ddm.parameters.clone(),
        final_ddm: last.derivatives[0].clone(),
        response: ddm.responses[0].clone(),
    }
}

/// Print the comparison and assert the agreement (the test suite calls this, `tests/methods/examples.rs`).
pub fn main() {
    let a = run();
    println!("A friction law written in this file: limit = t_max tanh(mu p_n / t_max)");
    println!("final-increment DDM sensitivities of '{}':", a.response);
    for (name, d) in a.parameters.iter().zip(&a.final_ddm) {
        println!("  d/d{name:<14} {d:+.6e}");
    }
    println!("largest disagreement with DDM over the path (relative to the largest sensitivity):");
    println!("  central FDM (beta 1e-6): {:.2e}", a.fdm_central);
    println!("  SDM central (beta 1e-5): {:.2e}", a.sdm_central);
    // tolerances: central differences at these betas are accurate to ~beta^2 plus round-off
    // ~eps/beta relative to the force tolerance; 1e-6 of the largest sensitivity holds both
    assert!(
        a.fdm_central < 1e-6,
        "central FDM disagrees: {}",
        a.fdm_central
    );
    assert!(
        a.sdm_central < 1e-6,
        "SDM central disagrees: {}",
        a.sdm_central
    );
    println!("the three methods agree, with no derivative of the law written by hand");
}
