//! # A curved part from Gmsh, pressed and slid on another: d/d(radius) and d/d mu by three methods
//!
//! **What.** The scene `meshes/punch-on-slab.toml`, around a mesh made by Gmsh
//! (`meshes/make_meshes.py`): an elastic punch, the lower half of a disc of radius R = 10
//! (E = 10 000, nu = 0.3), stands on an elastic slab 40 x 10 (E = 1 000, nu = 0.3), plane
//! strain, one hex8 layer 0.5 thick, large kinematics. Both bodies are deformable: the punch's
//! arc is the hitting surface, the slab's top the target, Lagrange normal law and Coulomb
//! friction mu = 0.3. The punch's top is pressed down 0.25 (2 increments) and then slid 1.0
//! along x (8 increments); the slab's bottom is held. After the slide we take the forces on
//! the punch's top (`Fx`, `Fy`, sums of the reactions of its nodes) and the peak contact
//! pressure, and their sensitivities to
//!
//! * the **radius R**, a shape parameter of the imported mesh: the scene's `[[shapes]]` entry
//!   scales the punch about the axis z through its contact point (20, 0), so that the arc stays
//!   a circle of radius R that touches the slab at the same point. The map is evaluated in the
//!   generic scalar, so DDM differentiates the mesh too;
//! * the friction coefficient **mu**;
//! * the two Young's moduli (`punch.E`, `slab.E`), for a check below.
//!
//! by three methods: **DDM** (dual numbers: the exact derivative of the discrete equations),
//! **SDM** (the paper's semi-analytical method, forward, beta = 1e-6) and **central FDM**
//! (beta = 1e-5, four complete reruns: R and mu, each +- beta; a rerun of R maps the punch's
//! nodes to R (1 +- beta) and recomputes the contact areas there, while the contact pair's
//! derived numerical settings, such as its candidate faces and tangential penalty, stay those
//! of the nominal design).
//!
//! **Why.** This is what a researcher brings: a curved part meshed in their own mesher, in
//! frictional contact with another deformable part, and a shape parameter that is not a block
//! length. The shape sensitivity goes through the mesh map, the element kernels, the contact
//! search on a curved and moving surface and the friction history.
//!
//! **Result.** Run `cargo run --release --example curved_punch` (about 15 s on two cores, most
//! of it FDM's reruns). The example asserts, and so the run shows:
//!
//! * central FDM and forward SDM agree with DDM to 1e-4 of each derivative in the table
//!   (relative, with a floor of 1e-3 of the largest derivative of its kind). The reruns converge
//!   to a relative force tolerance of 1e-9, so their noise over 2 beta R is of order
//!   1e-9 / 1e-5 = 1e-4 of the derivative at worst; SDM's forward truncation is of order beta;
//! * **homogeneity in E**: the loading is prescribed displacements only, the materials are
//!   St Venant-Kirchhoff (stress linear in E at a given strain), Coulomb's law and the
//!   Lagrange normal law have no stiffness of their own, and the default tangential penalty is
//!   proportional to the moduli. Multiplying both moduli by one factor multiplies every force
//!   and pressure by it and leaves the motion alone, so by Euler's theorem
//!   `E_p dF/dE_p + E_s dF/dE_s = F` for every force and pressure. DDM satisfies it to 1e-8 —
//!   a check of the two E columns that no other method gives;
//! * **signs**: friction opposes the sliding (`Fx` on the punch's top pushes the punch along
//!   +x, the direction of the slide, against the slab's friction: `Fx > 0`, and more so with mu,
//!   `dFx/dmu > 0`); a larger radius is a blunter punch that spreads the contact over a wider
//!   zone at the same indentation: the peak pressure falls, `dp_max/dR < 0`, while the force
//!   it takes to press grows, `dFy/dR < 0` (`Fy` is negative, pushing the punch down);
//! * **Hertz's scaling**: for line contact `p0^2 = P E* / (pi R)` (Johnson, *Contact
//!   Mechanics*, section 4.3), so `d ln p0 / d ln R = (d ln P / d ln R - 1) / 2` whatever the
//!   load. With `P` the force `Fy` and its DDM derivative, the peak pressure's DDM derivative
//!   meets it within 10 %: the peak is a nodal pressure (normal force over tributary area,
//!   about five elements across the half-width), the slab is finite (10 deep for a half-width
//!   of about 1.3) and the friction shifts the peak off the centre; measured 6 %. The pressure
//!   is divided by the node's tributary area at the design's own geometry, so its derivative
//!   includes how the area grows with R (without it, `dp_max/dR` came out positive).
//!
//! The FDM reruns of R show that the shape map is differentiated correctly: each rerun is a new
//! mesh, built by the map at a perturbed R, with no derivative anywhere.

use fricsens::response::ResponseKind;
use fricsens::scene::Scene;
use fricsens::sensitivity::{
    run_fdm_sweep, run_inline_sweep, Method, Parameter, SensitivityResults, Settings, TangentChoice,
};
use std::path::Path;

/// What the study found, for the caller (and the test that runs it) to check.
pub struct Summary {
    /// Largest relative difference from DDM over the table, `[SDM, FDM]`.
    pub max_difference: [f64; 2],
    /// Largest relative defect of `E_p dF/dE_p + E_s dF/dE_s = F` over the table.
    pub homogeneity: f64,
    /// Wall seconds: primal, DDM, SDM, FDM (sum of reruns).
    pub seconds: [f64; 4],
}

/// Run the study on `meshes/punch-on-slab.toml` and print the table.
pub fn study() -> Result<Summary, Box<dyn std::error::Error>> {
    let file = Path::new(env!("CARGO_MANIFEST_DIR")).join("meshes/punch-on-slab.toml");
    let model = Scene::from_file(&file)?.build()?;
    let by_name = |n: &str| Parameter::by_name(&model, n);
    let params = [
        by_name("R")?,
        by_name("mu")?,
        by_name("punch.E")?,
        by_name("slab.E")?,
    ];
    let moduli = [params[2].value, params[3].value];

    // DDM and forward SDM on one primal run, solved with the converged tangent
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
    // central FDM of R and mu only: the moduli are for the homogeneity check
    let (_, mut fdm) = run_fdm_sweep(&model, &params[..2], &[1e-5], true)?;
    let fdm = fdm.pop().expect("central FDM");
    for s in [ddm, sdm, &fdm] {
        if let Some(why) = &s.failure {
            return Err(why.clone().into());
        }
    }

    // the table's rows: the forces, and the pressure at the node that bears most at the end
    let last = ddm.increments.last().expect("increments");
    let position = |r: &str| model.responses.iter().position(|x| x.name == r);
    let (fx, fy) = (position("Fx").expect("Fx"), position("Fy").expect("Fy"));
    let peak = model
        .responses
        .iter()
        .enumerate()
        .filter(|(_, r)| matches!(r.kind, ResponseKind::ContactPressure { .. }))
        .max_by(|a, b| last.values[a.0].total_cmp(&last.values[b.0]))
        .map(|(i, _)| i)
        .expect("a pressure response");
    let closed = model
        .responses
        .iter()
        .enumerate()
        .filter(|(i, r)| {
            matches!(r.kind, ResponseKind::ContactPressure { .. }) && last.values[*i] > 0.0
        })
        .count();
    let rows = [
        ("Fx", fx),
        ("Fy", fy),
        (model.responses[peak].name.as_str(), peak),
    ];
    let is_force = |r: usize| r == fx || r == fy;

    println!(
        "punch-on-slab: {} unknowns, {} increments, {closed} hitting nodes closed after sliding; \
         peak pressure at {}\n",
        model.dof_map().n_total,
        last.increment,
        model.responses[peak].name
    );
    let d = |s: &SensitivityResults, r: usize, p: usize| {
        s.increments.last().expect("increments").derivatives[r][p]
    };
    let mut max_difference = [0.0f64; 2];
    for (p, pname) in ["R", "mu"].iter().enumerate() {
        println!(
            "{:<10} {:>12} | {:>14} {:>14} {:>14} | {:>9} {:>9}",
            "response",
            "value",
            format!("d/d{pname} DDM"),
            "SDM",
            "central FDM",
            "SDM-DDM",
            "FDM-DDM"
        );
        for &(label, r) in &rows {
            let reference = d(ddm, r, p);
            // relative to the derivative, with a floor: 1e-3 of the largest |derivative| of
            // the table's responses of this kind (forces or pressures)
            let scale = rows
                .iter()
                .filter(|o| is_force(o.1) == is_force(r))
                .map(|o| d(ddm, o.1, p).abs())
                .fold(0.0, f64::max);
            let rel = |s: &SensitivityResults| {
                (d(s, r, p) - reference).abs() / reference.abs().max(1e-3 * scale)
            };
            let (es, ef) = (rel(sdm), rel(&fdm));
            max_difference[0] = max_difference[0].max(es);
            max_difference[1] = max_difference[1].max(ef);
            println!(
                "{:<10} {:>12.5e} | {:>14.6e} {:>14.6e} {:>14.6e} | {:>9.1e} {:>9.1e}",
                label,
                last.values[r],
                reference,
                d(sdm, r, p),
                d(&fdm, r, p),
                es,
                ef
            );
        }
        println!();
    }

    // Euler's theorem for a response homogeneous of degree one in the two moduli
    let mut homogeneity = 0.0f64;
    for &(label, r) in &rows {
        let v = last.values[r];
        let euler = moduli[0] * d(ddm, r, 2) + moduli[1] * d(ddm, r, 3);
        let defect = (euler - v).abs() / v.abs();
        homogeneity = homogeneity.max(defect);
        println!(
            "{label:<10} E_p dF/dE_p + E_s dF/dE_s = {euler:.9e}, F = {v:.9e} (defect {defect:.1e})"
        );
    }
    let seconds = [
        ddm.primal_seconds,
        ddm.cost.wall_seconds,
        sdm.cost.wall_seconds,
        fdm.cost.wall_seconds,
    ];
    println!(
        "\nwall time (s): primal {:.1}; DDM {:.2} (four parameters), SDM {:.2} (four), \
         central FDM {:.1} (two parameters, {} reruns)",
        seconds[0], seconds[1], seconds[2], seconds[3], fdm.cost.primal_reruns
    );

    // the checks the doc comment states
    assert!(
        max_difference[1] <= 1e-4,
        "central FDM vs DDM: {:.2e}",
        max_difference[1]
    );
    assert!(
        max_difference[0] <= 1e-4,
        "forward SDM vs DDM: {:.2e}",
        max_difference[0]
    );
    assert!(homogeneity <= 1e-8, "homogeneity in E: {homogeneity:.2e}");
    let v = |r: usize| last.values[r];
    assert!(
        v(fx) > 0.0 && d(ddm, fx, 1) > 0.0,
        "friction opposes the slide"
    );
    assert!(
        v(fy) < 0.0 && d(ddm, fy, 0) < 0.0,
        "a blunter punch takes more force"
    );
    assert!(
        d(ddm, peak, 0) < 0.0,
        "a blunter punch has a lower peak pressure"
    );
    let radius = params[0].value;
    let hertz = 0.5 * (d(ddm, fy, 0) * radius / v(fy) - 1.0);
    let model_slope = d(ddm, peak, 0) * radius / v(peak);
    println!(
        "d ln p_max / d ln R = {model_slope:.4}, Hertz (d ln P / d ln R - 1) / 2 = {hertz:.4}"
    );
    assert!(
        (model_slope - hertz).abs() <= 0.1 * hertz.abs(),
        "Hertz's scaling: {model_slope} vs {hertz}"
    );
    Ok(Summary {
        max_difference,
        homogeneity,
        seconds,
    })
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    study().map(|_| ())
}
