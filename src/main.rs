//! The `fricsens` command line: list scenes, run a primal analysis.

use clap::{Parser, Subcommand};
use fricsens::output;
use fricsens::scene::{builtin_list, Scene};
use fricsens::solver::{AnalysisError, Converged, Observer, RunOptions, Solver};
use indicatif::{ProgressBar, ProgressStyle};
use std::path::{Path, PathBuf};
use std::process::ExitCode;

/// `println!` that ends the program quietly when stdout is closed (e.g. piped into `head`)
/// instead of panicking on the broken pipe.
macro_rules! out {
    ($($arg:tt)*) => {{
        use std::io::Write as _;
        if writeln!(std::io::stdout(), $($arg)*).is_err() {
            std::process::exit(0);
        }
    }};
}

/// `print!` with the same behaviour as `out!`.
macro_rules! outp {
    ($($arg:tt)*) => {{
        use std::io::Write as _;
        if write!(std::io::stdout(), $($arg)*).is_err() {
            std::process::exit(0);
        }
    }};
}

#[derive(Parser)]
#[command(
    name = "fricsens",
    version,
    about = "Frictional contact FE with design sensitivities (SDM, DDM, FDM)"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// List the built-in scenes, or print one (or a scene file, every default filled in) as
    /// TOML.
    Scenes {
        /// Print the TOML of this built-in scene or scene file.
        #[arg(long)]
        show: Option<String>,
    },
    /// Design sensitivities of every response at every increment.
    Sensitivity {
        /// A built-in scene name or a TOML scene file.
        scene: String,
        /// Design parameter(s): E, nu, sigma_y, H, BODY.PARAM, BODY.length.x, PAIR.mu, mu,
        /// load.NAME, prescribed.NAME (repeat for several; DDM batches them). Default: the
        /// scene's `[study] params`.
        #[arg(long = "param")]
        params: Vec<String>,
        /// sdm, sdm-central, ddm, fdm, fdm-central or adjoint (every response at the
        /// increments of `--at`, for any number of parameters at the cost of one).
        #[arg(long, default_value = "ddm")]
        method: MethodArg,
        /// Relative perturbation beta (b = b0 (1 + beta)) for SDM and FDM. Default: the
        /// scene's `[study] beta`, else 1e-6. `auto` (SDM, SDM central): each parameter's step
        /// chosen at every increment from a ladder of probes at the fixed state, and every
        /// derivative given an error bar (twice the sum of the difference from a shadow run at a
        /// tenth of the step and the round-off both runs expect); (FDM, FDM central): the same
        /// rule on reruns at every step of a ladder, the noise from the Newton residual the
        /// chosen and the shadow reruns reached.
        #[arg(long)]
        beta: Option<String>,
        /// Tangent of the sensitivity solve (SDM, DDM). `exact`: the tangent at the converged
        /// state, solved to a relative residual of 1e-13 (GMRES preconditioned with Newton's
        /// last factorization, a factorization of its own where GMRES does not converge in
        /// 30 steps) and refined with double-double residuals to 1e-13 of the solution; DDM
        /// is then the exact derivative to the solver's accuracy. `last`: Newton's last
        /// factorization alone, the tangent of the iterate before convergence (the paper's
        /// choice; no extra solve, but an error of the order of Newton's last correction in
        /// every in-line method: 1.2e-2 relative on the leaf spring). `refined`: the last
        /// factorization plus two steps of iterative refinement against the converged tangent.
        /// The adjoint takes the same three, transposed: `exact` factors the converged tangent
        /// anew at every increment of its backward sweep (or solves it by GMRES with
        /// --adjoint-krylov); `last` and `refined` solve with
        /// Newton's last factorizations, which the forward run then keeps (the memory is
        /// reported), and equal DDM with the same tangent.
        #[arg(long, default_value = "exact")]
        tangent: TangentArg,
        /// Factor the converged tangent (exact, or where Newton's last factor is on other
        /// branches) instead of solving with GMRES preconditioned with the factor at hand.
        /// (A forced tangent, a one-sided derivative's side, is factored always.)
        #[arg(long)]
        no_krylov: bool,
        /// The adjoint with --tangent exact: the transposed solves by GMRES preconditioned
        /// with Newton's last factorization of each increment, which the forward run then
        /// keeps (DDM's default solve, transposed), instead of a factorization per increment.
        /// Slower on the leaf spring (the sweep 0.187 s against 0.144 s for one response) and
        /// 2.6 times the memory; it pays where a factorization costs many solves.
        #[arg(long)]
        adjoint_krylov: bool,
        /// DDM and the adjoint: leave out each side's derivative at the flagged
        /// (non-differentiable) increments, the flagged points forced onto it (`one_sided` in
        /// sensitivity.json): DDM two more solves per flagged increment, the adjoint two more
        /// columns per response read there.
        #[arg(long)]
        no_one_sided: bool,
        /// SDM and SDM central: split SDM's error against DDM at every increment into the
        /// terms of the residual (elastic and plastic elements, springs, contact normal,
        /// friction, loads; each into truncation and round-off from the same term at 10
        /// times the step), the response's own difference and the error the history carries
        /// in; print, per parameter, what dominates the largest error and why, and write
        /// anatomy.csv.
        #[arg(long)]
        explain: bool,
        /// SDM and SDM central: the refined SDM for shape parameters. Each node's rigid
        /// rotation is differentiated exactly (the perturbed unknowns turned with the
        /// material, the tangent times that turn taken out of the difference), only the
        /// deformation by the difference: the truncation no longer grows with refinement
        /// where elements rotate (the semi-analytical inaccuracy of shape sensitivities).
        #[arg(long)]
        rigid_modes: bool,
        /// Also write vtk/ for ParaView: per increment, the primal fields and, for every
        /// parameter, the derivatives of the displacement, contact force and pressure,
        /// friction force, stress and equivalent plastic strain fields (`d(FIELD)/d(PARAM)`),
        /// collected in vtk/sensitivity.pvd.
        #[arg(long)]
        vtk: bool,
        /// FDM and FDM central: run share K of N of the reruns (with the nominal run, which
        /// every share runs) and write OUT/partial-K-of-N.json; `fricsens merge` combines the
        /// shares into the unsharded run's results, bit for bit.
        #[arg(long, value_name = "K/N")]
        shard: Option<String>,
        /// The adjoint's functionals: every response at the increment ending at time T
        /// (repeat for several), `last` (the default) or `all` (every increment, the table the
        /// other methods write; one column of the backward sweep per response and increment).
        #[arg(long, value_name = "T")]
        at: Vec<String>,
        /// The adjoint's checkpoints: keep the solver's state after every K-th user increment
        /// instead of every increment's, and recompute the increments between two of them
        /// when the backward sweep reaches them (the same states bit for bit; the output
        /// reports the memory kept and the recomputation).
        #[arg(long, value_name = "K")]
        checkpoint: Option<usize>,
        /// The responses to differentiate, by name (repeat for several). Default: every
        /// response of the scene. The adjoint's cost grows with them (one column of its
        /// backward sweep each), the other methods' hardly.
        #[arg(long, value_name = "NAME")]
        response: Vec<String>,
        /// Seconds of wall time (at least 0) the primal analysis may take, the in-line
        /// methods' work after each increment included (the adjoint: its forward run, not the
        /// backward sweep), before the run stops with an error naming the increment. FDM: the
        /// nominal run stops so; each rerun has the limit on its own clock, and one out of
        /// time leaves its parameter's differences empty.
        #[arg(long, value_name = "SECONDS", conflicts_with = "shard",
              value_parser = parse_time_limit, allow_negative_numbers = true)]
        time_limit: Option<f64>,
        /// Output directory (default: out/SCENE).
        #[arg(long)]
        out: Option<PathBuf>,
    },
    /// Combine the shares of a sharded run into the unsharded run's outputs: a
    /// finite-difference sweep (`fricsens sensitivity --shard K/N`: sensitivity.csv and
    /// sensitivity.json), a validation (`fricsens validate --shard K/N`: the report, its data
    /// and figures) or a scaling study (`fricsens scaling --shard K/N`).
    Merge {
        /// The shares' partial-K-of-N.json files (every share exactly once).
        #[arg(required = true)]
        partials: Vec<PathBuf>,
        /// Output directory (default: the first share's).
        #[arg(long)]
        out: Option<PathBuf>,
    },
    /// Every method across a perturbation sweep on the paper's scenes and the oracle scenes,
    /// compared with DDM and closed forms; writes the verification report.
    Validate {
        /// Built-in scene names or TOML files (default: the paper's two examples and the
        /// oracle scenes).
        scenes: Vec<String>,
        /// Report directory.
        #[arg(long, default_value = "validation")]
        out: PathBuf,
        /// The leaf spring on its paper-resolution mesh, and every scene's finite-difference
        /// sweep at every beta (by default the leaf spring's and Hertz's are thinned).
        #[arg(long)]
        full: bool,
        /// Largest and smallest beta of the sweep, by decades.
        #[arg(long, default_value_t = 1e-1)]
        beta_max: f64,
        #[arg(long, default_value_t = 1e-14)]
        beta_min: f64,
        /// Run share K of N of the validation's independent jobs (each scene, the leaf spring
        /// without friction, the friction-law comparison, each imported-geometry check, each
        /// batched-cost measurement) and write OUT/partial-K-of-N.json; `fricsens merge`
        /// combines the shares into the unsharded run's report.
        #[arg(long, value_name = "K/N")]
        shard: Option<String>,
        /// Elements of the strip of the friction-law comparison; 0 leaves the comparison out.
        #[arg(long, default_value_t = 100, value_name = "N")]
        friction_laws: usize,
    },
    /// Compare with CalculiX (ccx): the same mesh, increments and tolerance; time ratio,
    /// forces, and ccx's finite-difference d/d mu (frictionless: d/d E of the first body)
    /// against fricsens' DDM. Skips (exit 0) when ccx is not on PATH.
    Ccx {
        /// A built-in scene name or a TOML scene file whose contact pairs have a rigid
        /// rounded-box target (compared: the force on it) or are face to face between
        /// deformable bodies (compared: the scene's reaction and displacement responses).
        #[arg(default_value = "indentation")]
        scene: String,
        /// Report directory (ccx.csv, ccx.svg, ccx.md).
        #[arg(long, default_value = "validation/ccx")]
        out: PathBuf,
        /// Relative step of ccx's central difference, mu (1 +- beta).
        #[arg(long, default_value_t = 1e-2)]
        beta: f64,
        /// Write only the CalculiX deck to this file (no run; ccx not needed).
        #[arg(long)]
        deck: Option<PathBuf>,
        /// Keep ccx's scratch files in this directory (default: a temporary one, removed).
        #[arg(long)]
        keep: Option<PathBuf>,
    },
    /// Scaling study: the indentation and leaf-spring meshes refined from ~1e3 to >2e5 DOFs;
    /// primal and sensitivity time and peak memory against DOFs, fitted exponents
    /// (writes scaling.csv, scaling.svg, scaling.md).
    Scaling {
        /// Output directory.
        #[arg(long, default_value = "validation/scaling")]
        out: PathBuf,
        /// Skip sizes with more free unknowns than this.
        #[arg(long, default_value_t = 300_000)]
        max_dofs: usize,
        /// Two small sizes per scene only (checks the tool, measures nothing useful).
        #[arg(long)]
        quick: bool,
        /// Skip sizes whose peak memory, extrapolated from the smaller ones, exceeds this (MiB).
        #[arg(long, default_value_t = 12288.0)]
        memory_budget_mib: f64,
        /// Skip sizes whose wall time, extrapolated from the smaller ones, exceeds this (s).
        #[arg(long, default_value_t = 300.0)]
        time_budget_s: f64,
        /// Only rewrite the CSV, SVG and markdown from DIR/scaling.json (no measuring).
        #[arg(long)]
        rewrite: bool,
        /// Add sizes measured on their own (files of `fricsens scaling-one` JSON lines) to
        /// DIR/scaling.json, replacing their entries, and rewrite the outputs (no measuring).
        #[arg(long, conflicts_with = "rewrite")]
        merge: Vec<PathBuf>,
        /// Measure share K of N of the sizes (the budgets extrapolate from the share's own
        /// smaller sizes) and write OUT/partial-K-of-N.json; `fricsens merge` combines the
        /// shares into the study's outputs.
        #[arg(long, value_name = "K/N", conflicts_with_all = ["rewrite", "merge"])]
        shard: Option<String>,
    },
    /// The adjoint's study: cost against the number of parameters (1 to 10,000 element-wise
    /// fields) for DDM, SDM, FDM and the adjoint on the leaf spring and the indentation, where
    /// the adjoint becomes cheaper; the map of d(block force)/d(sigma_y) and d/d(E) of every
    /// element of the leaf spring (VTK and SVG), spot-checked by DDM (writes adjoint.md,
    /// crossover.csv, crossover.svg, map.vtu, map-*.svg, adjoint.json)
    AdjointStudy {
        /// Output directory.
        #[arg(long, default_value = "validation/adjoint")]
        out: PathBuf,
        /// The coarse leaf spring alone (checks the tool, measures nothing useful).
        #[arg(long)]
        quick: bool,
        /// Seconds one measurement may take before a method's larger counts are extrapolated.
        #[arg(long, default_value_t = 60.0)]
        budget_s: f64,
        /// Also every element's E, sigma_y and H of the leaf spring refined by this factor
        /// (6: 4,944 elements, 14,832 parameters), over its whole path.
        #[arg(long)]
        large: Option<f64>,
    },
    /// One size of the scaling study, measured in this process; prints one JSON line.
    #[command(hide = true)]
    ScalingOne {
        /// indentation, leaf-spring or leaf-spring-3d.
        #[arg(long)]
        scene: String,
        /// Mesh refinement factor.
        #[arg(long)]
        refinement: f64,
    },
    /// The physics fuzzer: random valid contact scenes run with default settings, each
    /// converged increment checked (equilibrium, Coulomb, penetration); writes fuzz.md and
    /// fuzz.json, and every failing scene as TOML into --corpus.
    Fuzz {
        /// Number of seeds.
        #[arg(long, default_value_t = 1000)]
        seeds: u64,
        /// First seed.
        #[arg(long, default_value_t = 0)]
        start: u64,
        /// Output directory (fuzz.md, fuzz.json; with --methods, methods.md and methods.json).
        #[arg(long, default_value = "validation/robustness")]
        out: PathBuf,
        /// Write every failing scene as TOML into this directory.
        #[arg(long)]
        corpus: Option<PathBuf>,
        /// Wall-time limit of one scene, seconds, at least 0 (with --methods: of each
        /// method's primal analysis).
        #[arg(long, default_value_t = 120.0, value_parser = parse_time_limit,
              allow_negative_numbers = true)]
        time_limit: f64,
        /// Run only these seeds (repeat), e.g. to rerun failures.
        #[arg(long = "seed")]
        only: Vec<u64>,
        /// Run and check these scenes (built-in names or TOML files, e.g. the corpus) instead
        /// of generated ones.
        #[arg(long = "scene")]
        scenes: Vec<String>,
        /// Print the scene of this seed as TOML and exit.
        #[arg(long)]
        show: Option<u64>,
        /// A baseline campaign's fuzz.json: the report section (robustness.md) compares with it.
        #[arg(long)]
        before: Option<PathBuf>,
        /// Markdown appended to the report section (what changed, what is left).
        #[arg(long)]
        notes: Option<PathBuf>,
        /// Instead of the physics checks: DDM against the adjoint on each scene, every
        /// derivative at every increment for the parameters the scene declares, each method
        /// with its default settings and --time-limit (`fricsens::studies::fuzz_methods`); writes methods.md
        /// and methods.json, and exits 1 if on any scene the two disagree: a derivative off
        /// by more than 1e-10 of its scale, a method failing where the other does not, or
        /// tables that differ in what they hold. A scene DDM runs out of --time-limit on is
        /// skipped (the adjoint is not run), and one the adjoint runs out of it on where DDM
        /// ran or failed in the primal analysis.
        #[arg(long, conflicts_with_all = ["corpus", "before", "notes"])]
        methods: bool,
    },
    /// The mesh readers' fuzzer: mutants of a block of hex8, hex20 and tet10 elements written
    /// as MSH 4.1 ASCII, binary and .inp, and of any --file, read and imported; none may panic, and every refusal must name
    /// its file. Writes mesh-fuzz.md and mesh-fuzz.json; keeps each panicking mutant in
    /// --corpus. Exits 1 if any mutant panicked.
    FuzzMeshes {
        /// Number of mutants.
        #[arg(long, default_value_t = 10_000)]
        mutants: usize,
        /// The mutation generator's seed.
        #[arg(long, default_value_t = 1)]
        seed: u64,
        /// Also mutate this .msh or .inp file (repeat), e.g. your mesher's output.
        #[arg(long = "file")]
        files: Vec<PathBuf>,
        /// A file an *INCLUDE of a --file names (repeat): copied beside each mutant.
        #[arg(long = "include")]
        includes: Vec<PathBuf>,
        /// Keep each panicking mutant here.
        #[arg(long, default_value = "tests/corpus/meshes")]
        corpus: PathBuf,
        /// Output directory (mesh-fuzz.md, mesh-fuzz.json).
        #[arg(long, default_value = "validation/robustness")]
        out: PathBuf,
    },
    /// Primal analysis: history CSV, Newton records, VTK files.
    Run {
        /// A built-in scene name or a TOML scene file.
        scene: String,
        /// Output directory (default: out/SCENE).
        #[arg(long)]
        out: Option<PathBuf>,
        /// Write no VTK files (history.csv and newton.json only).
        #[arg(long)]
        no_vtk: bool,
        /// Write the VTK file of every N-th converged increment (and of the last one).
        #[arg(long, default_value_t = 1, conflicts_with = "no_vtk")]
        vtk_every: usize,
        /// Stop once the analysis has taken this many seconds of wall time (at least 0;
        /// checked at every Newton iteration) with an error naming the increment; the results
        /// up to the last converged increment are written.
        #[arg(long, value_name = "SECONDS", value_parser = parse_time_limit,
              allow_negative_numbers = true)]
        time_limit: Option<f64>,
    },
}

#[derive(Clone, Copy, clap::ValueEnum)]
enum MethodArg {
    Sdm,
    SdmCentral,
    Ddm,
    Fdm,
    FdmCentral,
    Adjoint,
}

#[derive(Clone, Copy, clap::ValueEnum)]
enum TangentArg {
    Last,
    Refined,
    Exact,
}

/// The in-line methods' options of `fricsens sensitivity`.
struct InlineArgs {
    tangent: TangentArg,
    krylov: bool,
    adjoint_krylov: bool,
    one_sided: bool,
    explain: bool,
    rigid_modes: bool,
    vtk: bool,
    shard: Option<String>,
    at: Vec<String>,
    checkpoint: Option<usize>,
    responses: Vec<String>,
    time_limit: Option<f64>,
}

/// A `--time-limit`: seconds, at least 0 (`inf`: none).
fn parse_time_limit(s: &str) -> Result<f64, String> {
    let v: f64 = (s.parse()).map_err(|_| format!("seconds expected, got `{s}`"))?;
    if v.is_nan() || v < 0.0 {
        return Err(format!("must be at least 0 s, got {s}"));
    }
    Ok(v)
}

/// `fricsens merge`: the shares of one FDM sweep into the unsharded run's outputs.
fn merge(files: &[PathBuf], out: Option<PathBuf>) -> Result<(), String> {
    use fricsens::sensitivity::{merge_fdm, FdmPartial, Parameter};
    let mut scene_name: Option<String> = None;
    let mut partials = Vec::new();
    for f in files {
        let text = std::fs::read_to_string(f).map_err(|e| format!("{}: {e}", f.display()))?;
        let v: serde_json::Value =
            serde_json::from_str(&text).map_err(|e| format!("{}: {e}", f.display()))?;
        let name = v["scene"]
            .as_str()
            .ok_or_else(|| format!("{}: no `scene`: not a partial result", f.display()))?;
        match &scene_name {
            Some(n) if n != name => {
                return Err(format!(
                    "{}: a share of scene `{name}`, the others are of `{n}`",
                    f.display()
                ))
            }
            _ => scene_name = Some(name.to_string()),
        }
        let p: FdmPartial = serde_json::from_value(v["partial"].clone())
            .map_err(|e| format!("{}: not a partial result: {e}", f.display()))?;
        partials.push(p);
    }
    let scene_name = scene_name.ok_or("no partial results given")?;
    let scene = Scene::load(&scene_name).map_err(|e| e.to_string())?;
    let model = scene.build().map_err(|e| format!("{scene_name}: {e}"))?;
    let params: Vec<Parameter> = partials[0]
        .params
        .iter()
        .map(|n| Parameter::by_name(&model, n).map_err(|e| e.to_string()))
        .collect::<Result<_, _>>()?;
    let mut results = merge_fdm(&model, &params, &partials).map_err(|e| e.to_string())?;
    // [forward] or [forward, central]: the sharded method is the last
    let sens = results.pop().ok_or("nothing merged")?;
    if let Some(why) = &sens.failure {
        return Err(format!("{}: {why}", scene.name));
    }
    let dir = match out {
        Some(d) => d,
        None => files[0]
            .parent()
            .map(|p| p.to_path_buf())
            .unwrap_or_else(|| PathBuf::from(".")),
    };
    std::fs::create_dir_all(&dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    write_sensitivity(&dir, &sens)?;
    out!(
        "{}: {} shares merged, {} reruns, {} increments; written to {}",
        scene.name,
        partials.len(),
        sens.cost.primal_reruns,
        sens.increments.len(),
        dir.display()
    );
    Ok(())
}

/// Write `sensitivity.csv` (one row per increment: value and derivatives of every response)
/// and `sensitivity.json` (everything) of a sensitivity run into `dir`.
fn write_sensitivity(
    dir: &std::path::Path,
    sens: &fricsens::sensitivity::SensitivityResults,
) -> Result<(), String> {
    // `--beta auto`'s error bars and steps, where the run has them
    let beta_auto = sens
        .increments
        .first()
        .is_some_and(|i| !i.error_bars.is_empty());
    // CSV: one row per increment, value and derivatives of every response
    let mut csv = String::from("increment,time,kinks");
    for r in &sens.responses {
        csv.push_str(&format!(",{r}"));
        for p in &sens.parameters {
            csv.push_str(&format!(",d({r})/d({p})"));
            if beta_auto {
                csv.push_str(&format!(",error bar of d({r})/d({p})"));
            }
        }
    }
    if beta_auto {
        for p in &sens.parameters {
            csv.push_str(&format!(",beta({p})"));
        }
    }
    csv.push('\n');
    for inc in &sens.increments {
        csv.push_str(&format!(
            "{},{:.10e},{}",
            inc.increment,
            inc.time,
            inc.kinks.len()
        ));
        for (r, v) in inc.values.iter().enumerate() {
            csv.push_str(&format!(",{v:.12e}"));
            for (k, d) in inc.derivatives[r].iter().enumerate() {
                csv.push_str(&format!(",{d:.12e}"));
                if let Some(e) = inc.error_bars.get(r).and_then(|row| row.get(k)) {
                    csv.push_str(&format!(",{e:.3e}"));
                }
            }
        }
        for b in &inc.betas {
            csv.push_str(&format!(",{b:.0e}"));
        }
        csv.push('\n');
    }
    let path = dir.join("sensitivity.csv");
    std::fs::write(&path, csv).map_err(|e| format!("{}: {e}", path.display()))?;
    let path = dir.join("sensitivity.json");
    let json = serde_json::to_string_pretty(&sens).map_err(|e| e.to_string())?;
    std::fs::write(&path, json).map_err(|e| format!("{}: {e}", path.display()))?;
    Ok(())
}

fn sensitivity(
    scene_name: &str,
    names: &[String],
    method: MethodArg,
    beta: Option<String>,
    inline: InlineArgs,
    out: Option<PathBuf>,
) -> Result<(), String> {
    let InlineArgs {
        tangent,
        krylov,
        adjoint_krylov,
        one_sided,
        explain,
        rigid_modes,
        vtk,
        shard,
        at,
        checkpoint,
        responses,
        time_limit,
    } = inline;
    use fricsens::sensitivity::{
        run_sensitivity_watched, Method, Parameter, Settings, TangentChoice,
    };
    let scene = Scene::load(scene_name).map_err(|e| e.to_string())?;
    let beta_auto = beta.as_deref() == Some("auto");
    let beta = match beta.as_deref() {
        None | Some("auto") => scene.study.beta(),
        Some(b) => b
            .parse::<f64>()
            .map_err(|_| format!("--beta takes a number or `auto`, got `{b}`"))?,
    };
    if !(beta > 0.0 && beta < 1.0) {
        return Err(format!("--beta must lie in (0, 1), got {beta}"));
    }
    print_defaults(scene_name)?;
    let mut model = scene.build().map_err(|e| format!("{scene_name}: {e}"))?;
    for n in &model.notes {
        eprintln!("default: {n}");
    }
    if let Some(r) = (responses.iter()).find(|r| !model.responses.iter().any(|m| &m.name == *r)) {
        let known: Vec<&str> = model.responses.iter().map(|m| m.name.as_str()).collect();
        return Err(format!(
            "--response {r}: {scene_name} has no response of that name (it has {})",
            known.join(", ")
        ));
    }
    if !responses.is_empty() {
        if shard.is_some() {
            return Err("--response with --shard: `fricsens merge` rebuilds the scene with every response; run the shares without --response".into());
        }
        model.responses.retain(|m| responses.contains(&m.name));
    }
    let names = if names.is_empty() {
        if scene.study.params.is_empty() {
            return Err(format!(
                "{scene_name}: no --param given and the scene declares no `[study] params`"
            ));
        }
        &scene.study.params[..]
    } else {
        names
    };
    let mut params: Vec<Parameter> = Vec::new();
    for n in names {
        params.extend(Parameter::expand(&model, n).map_err(|e| e.to_string())?);
    }
    let mut settings = Settings {
        method: match method {
            MethodArg::Sdm => Method::Sdm,
            MethodArg::SdmCentral => Method::SdmCentral,
            MethodArg::Ddm => Method::Ddm,
            MethodArg::Fdm => Method::Fdm,
            MethodArg::FdmCentral => Method::FdmCentral,
            MethodArg::Adjoint => Method::Adjoint,
        },
        beta,
        tangent: match tangent {
            TangentArg::Last => TangentChoice::Last,
            TangentArg::Refined => TangentChoice::Refined,
            TangentArg::Exact => TangentChoice::Exact,
        },
        probe_floor: true,
        krylov,
        adjoint_krylov,
        one_sided,
        explain,
        beta_auto,
        // the adjoint's --vtk draws the field parameters' derivatives alone
        fields: vtk && !matches!(method, MethodArg::Adjoint),
        adjoint_checkpoint: checkpoint.unwrap_or(0),
        rigid_modes,
        time_limit,
        ..Settings::default()
    };
    if rigid_modes && !matches!(settings.method, Method::Sdm | Method::SdmCentral) {
        return Err(format!(
            "--rigid-modes refines SDM's difference: use it with --method sdm or sdm-central, not {}",
            settings.method.name()
        ));
    }
    if !one_sided && !matches!(settings.method, Method::Ddm | Method::Adjoint) {
        return Err(format!(
            "--no-one-sided leaves out DDM's and the adjoint's one-sided derivatives; {} gives none",
            settings.method.name()
        ));
    }
    if rigid_modes && explain {
        return Err(
            "--explain splits plain SDM's error (which --rigid-modes is there to remove): drop one of them"
                .into(),
        );
    }
    if checkpoint.is_some() && settings.method != Method::Adjoint {
        return Err(format!(
            "--checkpoint sets the adjoint's checkpoints: use it with --method adjoint, not {}",
            settings.method.name()
        ));
    }
    if adjoint_krylov {
        let tangent = match settings.tangent {
            TangentChoice::Exact => "exact",
            TangentChoice::Last => "last",
            TangentChoice::Refined => "refined",
        };
        if settings.method != Method::Adjoint || settings.tangent != TangentChoice::Exact {
            return Err(format!(
                "--adjoint-krylov solves the adjoint's exact tangent by GMRES: use it with --method adjoint and --tangent exact, not --method {} --tangent {tangent}",
                settings.method.name()
            ));
        }
        if !krylov {
            return Err(
                "--adjoint-krylov asks for GMRES, --no-krylov for factorizations: drop one of them"
                    .into(),
            );
        }
    }
    if checkpoint == Some(0) {
        return Err(
            "--checkpoint K keeps the state after every K-th user increment: K must be at least 1"
                .into(),
        );
    }
    if settings.method == Method::Adjoint {
        if vtk && !params.iter().any(|p| p.name.contains('[')) {
            return Err("--vtk with the adjoint draws the derivatives in field parameters (BODY.PARAM[*], PAIR.PARAM[*], SET.x[*]) on the mesh; none was given".into());
        }
        let last = *model.times.last().ok_or("the scene has no increments")?;
        settings.adjoint_at = if at.iter().any(|a| a == "all") {
            Vec::new()
        } else if at.is_empty() {
            vec![last]
        } else {
            (at.iter())
                .map(|a| match a.as_str() {
                    "last" => Ok(last),
                    t => t
                        .parse::<f64>()
                        .map_err(|_| format!("--at takes a time, `last` or `all`, got `{t}`")),
                })
                .collect::<Result<_, _>>()?
        };
    } else if !at.is_empty() {
        return Err(format!(
            "--at chooses the adjoint's functionals: use it with --method adjoint, not {}",
            settings.method.name()
        ));
    }
    if beta_auto && !settings.method.uses_beta() {
        return Err(format!(
            "--beta auto chooses the step of a difference: use it with --method sdm, sdm-central, fdm or fdm-central, not {}",
            settings.method.name()
        ));
    }
    if beta_auto && shard.is_some() {
        return Err("--shard splits the reruns at one beta: give --beta B, not auto".into());
    }
    if beta_auto && explain {
        return Err("--explain splits the error at one fixed beta: give --beta B, not auto".into());
    }
    if explain && !matches!(settings.method, Method::Sdm | Method::SdmCentral) {
        return Err(format!(
            "--explain splits SDM's error: use it with --method sdm or sdm-central, not {}",
            settings.method.name()
        ));
    }
    if let Some(shard) = shard {
        let shard = fricsens::sensitivity::Shard::parse(&shard)?;
        let central = match settings.method {
            Method::Fdm => false,
            Method::FdmCentral => true,
            m => {
                return Err(format!(
                    "--shard splits the finite-difference reruns: use it with --method fdm or fdm-central, not {}",
                    m.name()
                ))
            }
        };
        if vtk {
            return Err("--shard writes no fields: leave out --vtk".into());
        }
        let partial =
            fricsens::sensitivity::run_fdm_shard(&model, &params, &[beta], central, shard)
                .map_err(|e| e.to_string())?;
        let dir = out.unwrap_or_else(|| PathBuf::from("out").join(&scene.name));
        std::fs::create_dir_all(&dir).map_err(|e| format!("{}: {e}", dir.display()))?;
        let path = dir.join(format!("partial-{}-of-{}.json", shard.index, shard.count));
        let json = serde_json::json!({ "scene": scene_name, "partial": partial });
        std::fs::write(&path, json.to_string()).map_err(|e| format!("{}: {e}", path.display()))?;
        out!(
            "{}: share {}/{} of the reruns ({} of them) written to {}; combine the shares with `fricsens merge`",
            scene.name,
            shard.index,
            shard.count,
            partial.reruns.len(),
            path.display()
        );
        return Ok(());
    }
    let bar = progress(model.times.len());
    if settings.method.is_inline() {
        bar.set_prefix(settings.method.name());
    } else if settings.method == Method::Adjoint {
        bar.set_prefix("forward run (then the backward sweep)");
    } else {
        bar.set_prefix("nominal run (then the reruns)");
    }
    let run = run_sensitivity_watched(&model, &params, &settings, &mut |c| show(&bar, c));
    bar.finish_and_clear();
    let (res, sens) = run.map_err(|e| e.to_string())?;
    let dir = out.unwrap_or_else(|| PathBuf::from("out").join(&scene.name));
    std::fs::create_dir_all(&dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    write_sensitivity(&dir, &sens)?;
    if vtk && settings.method != Method::Adjoint {
        fricsens::output::write_sensitivity_vtk(&dir, &model, &res, &sens)
            .map_err(|e| e.to_string())?;
    }
    let maps = if vtk {
        fricsens::output::write_parameter_fields_vtk(&dir, &model, &res, &sens, &params)
            .map_err(|e| e.to_string())?
    } else {
        Vec::new()
    };
    if !maps.is_empty() {
        out!(
            "field parameters: d(response)/d(field) drawn on the mesh in {} file(s), {}",
            maps.len(),
            dir.join("vtk").join("parameters.pvd").display()
        );
    }
    let flagged = sens
        .increments
        .iter()
        .filter(|i| !i.kinks.is_empty())
        .count();
    let sided = sens.increments.iter().any(|i| i.one_sided.is_some());
    out!(
        "{}: {} increments, method {}, parameters {:?}; {} increments flagged non-differentiable{}",
        scene.name,
        sens.increments.len(),
        settings.method.name(),
        sens.parameters,
        flagged,
        if sided {
            " (each side's derivatives there: one_sided in sensitivity.json)"
        } else {
            ""
        }
    );
    // a one-sided side that failed: the run kept the rest, and says which side and why
    for line in sens
        .increments
        .iter()
        .flat_map(|i| (i.one_sided.iter()).flat_map(|o| o.failed.iter()))
    {
        out!("one-sided derivatives: {line}");
    }
    let c = &sens.cost;
    out!(
        "cost: primal {:.3} s; sensitivity {:.3} s ({:.2} % of the primal per parameter): {} residual evaluations ({} over only the elements a parameter reaches), {} factorizations, {} GMRES solves ({} steps) instead of factorizations, {} solve columns, {} reruns",
        sens.primal_seconds,
        c.wall_seconds,
        100.0 * c.wall_seconds / sens.primal_seconds.max(1e-12) / params.len() as f64,
        c.residual_evaluations,
        c.partial_evaluations,
        c.factorizations,
        c.krylov_solves,
        c.krylov_iterations,
        c.solve_columns,
        c.primal_reruns
    );
    if settings.method.is_inline() || settings.method == Method::Adjoint {
        out!(
            "  tangent: {}",
            match settings.tangent {
                TangentChoice::Exact =>
                    "exact (the converged tangent, refined to 1e-13 of the solution: DDM is exact to the solver's accuracy)",
                TangentChoice::Last =>
                    "last (Newton's last factorization: every value is off by the order of Newton's last correction, 1.2e-2 relative on the leaf spring; the default --tangent exact removes it)",
                TangentChoice::Refined =>
                    "refined (Newton's last factorization and two refinement steps against the converged tangent: what is left of the last correction's error is not measured; the default --tangent exact removes it)",
            }
        );
    }
    if settings.method.is_inline() {
        let other = c.rest_seconds();
        out!(
            "  where it went: evaluations {:.3} s, factorizations {:.3} s, solves {:.3} s, the rest {:.3} s; the floor (one evaluation and one solve per parameter and increment) {:.3} s: {:.2} times the floor",
            c.evaluation_seconds,
            c.factor_seconds,
            c.solve_seconds,
            other,
            c.floor_seconds * params.len() as f64,
            c.wall_seconds / (c.floor_seconds * params.len() as f64).max(1e-12)
        );
    }
    if let Some(last) = sens.increments.last() {
        if !last.betas.is_empty() {
            let steps: Vec<String> = sens
                .parameters
                .iter()
                .zip(&last.betas)
                .map(|(p, b)| format!("{p} {b:.0e}"))
                .collect();
            out!(
                "  steps chosen at the last increment: {} (error bars: twice the sum of the difference from a run at a tenth of each step and the round-off both expect)",
                steps.join(", ")
            );
        }
        for (r, name) in sens.responses.iter().enumerate().take(8) {
            outp!("  {name:<24} {:>14.6e}", last.values[r]);
            for (k, d) in last.derivatives[r].iter().enumerate() {
                match last.error_bars.get(r).and_then(|row| row.get(k)) {
                    Some(e) => outp!("  {d:>14.6e} +- {e:.1e}"),
                    None => outp!("  {d:>14.6e}"),
                }
            }
            out!();
        }
    }
    if settings.method == Method::Adjoint {
        out!(
            "  where it went: evaluations {:.3} s ({} local-derivative and design evaluations), factorizations {:.3} s, solves {:.3} s, recomputation {:.3} s, the rest {:.3} s; {:.3} s of these at the same time as others (factorizations beside the recordings, design derivatives beside the solves)",
            c.evaluation_seconds,
            c.partial_evaluations,
            c.factor_seconds,
            c.solve_seconds,
            c.recompute_seconds,
            c.rest_seconds() - c.recompute_seconds,
            c.overlap_seconds
        );
        out!(
            "  adjoint: kept {:.1} MiB of forward states ({} checkpoint(s)); recomputed {} increment(s) in {:.3} s ({:.2} of the primal)",
            c.stored_bytes as f64 / (1024.0 * 1024.0),
            c.checkpoints,
            c.recomputed_increments,
            c.recompute_seconds,
            c.recompute_seconds / sens.primal_seconds.max(1e-12)
        );
    }
    if explain {
        let path = dir.join("anatomy.csv");
        std::fs::write(&path, fricsens::sensitivity::anatomy::anatomy_csv(&sens))
            .map_err(|e| format!("{}: {e}", path.display()))?;
        let values: Vec<f64> = params.iter().map(|p| p.value).collect();
        print_explanations(&sens, &values, settings.method == Method::SdmCentral);
    }
    out!("written to {}", dir.display());
    Ok(())
}

/// The verification report's error floor: `--explain` measures errors as the report does.
const EXPLAIN_FLOOR: f64 = 1e-3;

/// `--explain`: per parameter, SDM's largest error and what it is made of.
fn print_explanations(
    sens: &fricsens::sensitivity::SensitivityResults,
    values: &[f64],
    central: bool,
) {
    use fricsens::sensitivity::anatomy::explain;
    let beta = sens.beta;
    out!(
        "why SDM errs (beta {beta:e}; against DDM, relative to the derivative or {EXPLAIN_FLOOR:e} of its largest value, as the verification report; anatomy {:.2} s, not in the cost above):",
        sens.cost.anatomy_seconds
    );
    for x in explain(sens, values, EXPLAIN_FLOOR) {
        let p = &x.parts;
        out!(
            "  {}: largest error in d({})/d({}) at increment {} (t = {}): {:.2e} of {:.3e}",
            x.parameter,
            x.response,
            x.parameter,
            x.increment,
            x.time,
            x.relative_error,
            x.scale
        );
        let named = p.named();
        let sum: f64 = named.iter().map(|(_, e, _)| e.abs()).sum();
        let shown: Vec<String> = named
            .iter()
            .filter(|(_, e, _)| *e != 0.0 && e.abs() >= 1e-3 * sum)
            .map(|(part, e, _)| {
                format!(
                    "{} {:+.2e} ({:.0} %)",
                    part.name(),
                    e / x.scale,
                    100.0 * e.abs() / sum
                )
            })
            .collect();
        out!("    parts (over that): {}", shown.join(", "));
        let (part, _, split) = x.dominant();
        if let Some(split) = split {
            let order = split.order().map_or("-".to_string(), |o| format!("{o:.2}"));
            let c = x.truncation_coefficient(&split, beta, central);
            out!(
                "    {}: truncation {:+.2e}, round-off {:+.2e} (over that); local order {order} between beta and 10 beta (the method's order: {}; -1: round-off){}",
                part.name(),
                split.truncation / x.scale,
                split.roundoff() / x.scale,
                if central { 2 } else { 1 },
                if central {
                    format!(", b^2 d3/db3 over d/db = {:.2e}", 6.0 * c)
                } else {
                    format!(
                        ", relative curvature b d2/db2 over d/db = {:.2e}: its truncation reaches the derivative at beta = {:.1e}",
                        2.0 * c,
                        1.0 / c
                    )
                }
            );
        }
        out!(
            "    sum of the parts {:+.6e} against SDM - DDM {:+.6e}",
            p.sum() / x.scale,
            p.total / x.scale
        );
    }
}

/// `fricsens scaling --merge`: read the measurements and merge them into the study in `out`.
fn merge_scaling(out: &std::path::Path, files: &[PathBuf]) -> Result<(), String> {
    let mut added = Vec::new();
    for f in files {
        let text = std::fs::read_to_string(f).map_err(|e| format!("{}: {e}", f.display()))?;
        for (i, line) in text
            .lines()
            .enumerate()
            .filter(|(_, l)| !l.trim().is_empty())
        {
            added.push(
                serde_json::from_str(line)
                    .map_err(|e| format!("{}, line {}: {e}", f.display(), i + 1))?,
            );
        }
    }
    let n = added.len();
    fricsens::studies::scaling::merge_measurements(out, added).map_err(|e| e.to_string())?;
    out!(
        "{n} measurement(s) merged into {}",
        out.join("scaling.json").display()
    );
    Ok(())
}

/// Progress bar over increments (drawn only on a terminal).
struct Progress(ProgressBar);

impl Observer for Progress {
    fn converged(&mut self, c: &Converged<'_>) -> Result<(), AnalysisError> {
        show(&self.0, c);
        Ok(())
    }
}

/// Where a run is: increment, pseudo-time, iterations and cutbacks of the increment.
fn show(bar: &ProgressBar, c: &Converged<'_>) {
    bar.set_position(c.index as u64);
    bar.set_message(format!(
        "t = {:.4}, {} iterations{}",
        c.time,
        c.record.iterations,
        match c.record.cutbacks {
            0 => String::new(),
            n => format!(", {n} cutbacks"),
        }
    ));
}

fn progress(n: usize) -> ProgressBar {
    let pb = ProgressBar::new(n as u64);
    pb.set_style(
        ProgressStyle::with_template("{prefix} {bar:40} {pos}/{len} increments {msg} [{elapsed}]")
            .expect("valid template"),
    );
    pb
}

/// For a scene file, print every setting it leaves to its default, with the value in effect.
fn print_defaults(scene_name: &str) -> Result<(), String> {
    let path = std::path::Path::new(scene_name);
    if !path.is_file() {
        return Ok(());
    }
    let text = std::fs::read_to_string(path).map_err(|e| format!("{scene_name}: {e}"))?;
    for d in Scene::defaulted(&text, scene_name).map_err(|e| e.to_string())? {
        eprintln!("default: {d}");
    }
    Ok(())
}

fn run(
    scene_name: &str,
    out: Option<PathBuf>,
    vtk: output::VtkOutput,
    time_limit: Option<f64>,
) -> Result<(), String> {
    let scene = Scene::load(scene_name).map_err(|e| e.to_string())?;
    print_defaults(scene_name)?;
    let model = scene.build().map_err(|e| format!("{scene_name}: {e}"))?;
    let dir = out.unwrap_or_else(|| PathBuf::from("out").join(&scene.name));
    for n in &model.notes {
        eprintln!("default: {n}");
    }
    let mut solver = Solver::new(&model).map_err(|e| e.to_string())?;
    for w in solver.warnings() {
        eprintln!("warning: {w}");
    }
    let mut obs = Progress(progress(model.times.len()));
    let result = solver.run(&RunOptions::limited(time_limit), &mut obs);
    obs.0.finish_and_clear();
    let res = match result {
        Ok(r) => r,
        Err(e) => {
            if let Some(partial) = e.partial() {
                match output::write_run(&dir, &model, partial, vtk) {
                    Ok(()) => eprintln!(
                        "results up to the last converged increment written to {}",
                        dir.display()
                    ),
                    Err(w) => {
                        eprintln!("results up to the last converged increment not written: {w}")
                    }
                }
            }
            return Err(e.to_string());
        }
    };
    output::write_run(&dir, &model, &res, vtk).map_err(|e| e.to_string())?;
    let iters: usize = res.records.iter().map(|r| r.iterations).sum();
    out!(
        "{}: {} increments, {} Newton iterations ({:.2} per increment; {} factorizations and {} residual evaluations with the failed attempts and line searches), {} unknowns, {:.3} s",
        scene.name,
        res.records.len(),
        iters,
        iters as f64 / res.records.len().max(1) as f64,
        res.cost.factorizations,
        res.cost.assemblies,
        solver.assembler.dofs.n_total,
        res.cost.wall_seconds
    );
    out!(
        "  where it went: assembly {:.3} s, factorizations {:.3} s, solves {:.3} s, the rest {:.3} s",
        res.cost.assembly_seconds,
        res.cost.factor_seconds,
        res.cost.solve_seconds,
        res.cost.rest_seconds(res.cost.wall_seconds)
    );
    if res.cost.limited_steps > 0 {
        out!(
            "  the penetration limiter shortened {} Newton steps (to just past where a node crossing a gap first touched)",
            res.cost.limited_steps
        );
    }
    let last = res.states.len() - 1;
    for (k, r) in model.responses.iter().enumerate() {
        out!(
            "  {:<24} {:>16.8e}",
            r.name,
            res.response_value(&model, k, last)
        );
    }
    out!("written to {}", dir.display());
    Ok(())
}

/// `fricsens merge`: the shares of a sharded run, of whichever kind their files say.
fn merge_any(files: &[PathBuf], out: Option<PathBuf>) -> Result<(), String> {
    use fricsens::studies::validate::partial::partial_kind;
    let mut kind: Option<(Option<String>, &PathBuf)> = None;
    for f in files {
        let k = partial_kind(f).map_err(|e| e.to_string())?;
        match &kind {
            Some((first, file)) if *first != k => {
                let name =
                    |k: &Option<String>| k.clone().unwrap_or_else(|| "finite-difference".into());
                return Err(format!(
                    "{}: a share of a {} run, {} is of a {} run: merge the shares of one run",
                    f.display(),
                    name(&k),
                    file.display(),
                    name(first)
                ));
            }
            _ => kind = Some((k, f)),
        }
    }
    let dir = || match &out {
        Some(d) => d.clone(),
        None => files[0]
            .parent()
            .map(|p| p.to_path_buf())
            .unwrap_or_else(|| PathBuf::from(".")),
    };
    match kind.and_then(|k| k.0).as_deref() {
        Some(fricsens::studies::validate::PARTIAL_KIND) => {
            let out = dir();
            let v = fricsens::studies::validate::merge_shards(files, &out)
                .map_err(|e| e.to_string())?;
            print_validation(&v, &out);
            Ok(())
        }
        Some(fricsens::studies::scaling::PARTIAL_KIND) => {
            let out = dir();
            let study =
                fricsens::studies::scaling::merge_shards(files, &out).map_err(|e| e.to_string())?;
            out!(
                "{} shares merged: {} sizes measured, {} skipped; written to {}",
                files.len(),
                study.rows.len(),
                study.skipped.len(),
                out.join("scaling.md").display()
            );
            Ok(())
        }
        Some(other) => Err(format!(
            "{}: a partial result of kind `{other}`, which this fricsens does not merge",
            files[0].display()
        )),
        None => merge(files, out),
    }
}

fn print_validation(v: &fricsens::studies::validate::Validation, out: &std::path::Path) {
    for s in &v.scenes {
        out!(
            "{:<18} {:>6} unknowns {:>4} increments  primal {:>7.2} s  DDM/primal {:.3}",
            s.scene,
            s.unknowns,
            s.increments,
            s.primal_seconds,
            s.ddm_cost_ratio
        );
    }
    let failed = v.oracles.iter().filter(|o| !o.pass).count();
    out!(
        "{} oracle checks, {} failed; report written to {} in {:.0} s",
        v.oracles.len(),
        failed,
        out.join("README.md").display(),
        v.wall_seconds
    );
}

fn validate(
    names: &[String],
    out: PathBuf,
    full: bool,
    (beta_max, beta_min): (f64, f64),
    shard: Option<String>,
    friction_laws: Option<usize>,
) -> Result<(), String> {
    use fricsens::studies::validate::{
        resolve_scenes, run_shard, validate_observed, ValidateOptions, ValidateProgress,
    };
    if !(beta_max > 0.0 && beta_max < 1.0 && beta_min > 0.0 && beta_min <= beta_max) {
        return Err(format!(
            "--beta-max and --beta-min must satisfy 0 < beta-min <= beta-max < 1, got {beta_max:e} and {beta_min:e}"
        ));
    }
    let shard = shard
        .map(|s| fricsens::sensitivity::Shard::parse(&s))
        .transpose()?;
    let scenes = resolve_scenes(names, full).map_err(|e| e.to_string())?;
    let mut betas = Vec::new();
    let mut b = beta_max;
    while b >= beta_min * (1.0 - 1e-9) {
        betas.push(b);
        b /= 10.0;
    }
    let opts = ValidateOptions {
        out: out.clone(),
        betas,
        reduced_fdm: if full {
            Vec::new()
        } else {
            ValidateOptions::default().reduced_fdm
        },
        // the imported-geometry section with the default scenes only
        imported: if names.is_empty() {
            ValidateOptions::default().imported
        } else {
            None
        },
        friction_laws,
        ..ValidateOptions::default()
    };
    if let Some(shard) = shard {
        let path = run_shard(names, full, &scenes, &opts, shard, &mut |_| {})
            .map_err(|e| e.to_string())?;
        out!(
            "share {}/{} of the validation written to {}; combine the shares with `fricsens merge`",
            shard.index,
            shard.count,
            path.display()
        );
        return Ok(());
    }
    let bar = if std::io::IsTerminal::is_terminal(&std::io::stderr()) {
        ProgressBar::new(scenes.len() as u64)
    } else {
        ProgressBar::hidden()
    };
    let v = validate_observed(&scenes, &opts, &mut |p| match p {
        ValidateProgress::Scene { index, name, .. } => {
            bar.set_position(index as u64);
            bar.set_message(name.to_string());
        }
        ValidateProgress::Report => bar.finish_and_clear(),
    })
    .map_err(|e| e.to_string())?;
    print_validation(&v, &out);
    Ok(())
}

fn ccx(
    scene_name: &str,
    out: PathBuf,
    beta: f64,
    deck: Option<PathBuf>,
    keep: Option<PathBuf>,
) -> Result<(), String> {
    use fricsens::studies::ccx::{compare, export, find_ccx, CompareOptions, ExportOptions};
    let scene = Scene::load(scene_name).map_err(|e| e.to_string())?;
    let model = scene.build().map_err(|e| format!("{scene_name}: {e}"))?;
    if let Some(path) = deck {
        let d = export(&model, &ExportOptions::default()).map_err(|e| e.to_string())?;
        std::fs::write(&path, &d.text).map_err(|e| format!("{}: {e}", path.display()))?;
        out!(
            "{}: {} nodes, {} elements written to {}",
            scene.name,
            d.nodes,
            d.elements,
            path.display()
        );
        return Ok(());
    }
    let Some(program) = find_ccx() else {
        out!(
            "ccx not found: skipping the CalculiX comparison (install Debian package calculix-ccx)"
        );
        return Ok(());
    };
    let work = keep.clone().unwrap_or_else(|| {
        std::env::temp_dir().join(format!("fricsens-ccx-{}", std::process::id()))
    });
    let opts = CompareOptions {
        ccx: program,
        work: work.clone(),
        beta,
        threads: rayon::current_num_threads(),
        export: ExportOptions::default(),
        time_limit: None,
    };
    // the report's name for the scene is what regenerates it: a built-in name or the file
    let result = compare(&model, scene_name, &opts);
    if keep.is_none() {
        let _ = std::fs::remove_dir_all(&work);
    }
    let c = result.map_err(|e| e.to_string())?;
    c.write(&out).map_err(|e| e.to_string())?;
    out!(
        "{}: fricsens primal {:.2} s, ccx {:.2} s (ratio ccx/fricsens {:.2}); DDM {:.2} s, ccx FD reruns {:.2} s; report in {}",
        c.scene,
        c.fricsens_primal_seconds,
        c.ccx_seconds,
        c.ccx_seconds / c.fricsens_primal_seconds.max(1e-12),
        c.ddm_seconds,
        c.ccx_rerun_seconds[0] + c.ccx_rerun_seconds[1],
        out.join("ccx.md").display()
    );
    Ok(())
}

fn adjoint_study(
    out: PathBuf,
    quick: bool,
    budget_seconds: f64,
    large: Option<f64>,
) -> Result<(), String> {
    use fricsens::studies::adjoint_study::{run_study, StudyOptions};
    let study = run_study(&StudyOptions {
        out: out.clone(),
        quick,
        budget_seconds,
        large,
    })
    .map_err(|e| e.to_string())?;
    for c in &study.crossovers {
        out!(
            "{}: the adjoint is cheaper than {} beyond {} parameters",
            c.scene,
            c.method,
            c.n.map_or("no number of".to_string(), |n| format!("{n:.1}"))
        );
    }
    out!(
        "study in {:.0} s; written to {}",
        study.wall_seconds,
        out.join("adjoint.md").display()
    );
    Ok(())
}

fn scaling(
    out: PathBuf,
    max_dofs: usize,
    quick: bool,
    memory_budget_mib: f64,
    time_budget_seconds: f64,
    shard: Option<String>,
) -> Result<(), String> {
    use fricsens::studies::scaling::{run_shard, run_study, StudyOptions};
    let exe = std::env::current_exe().map_err(|e| format!("cannot locate fricsens itself: {e}"))?;
    let opts = StudyOptions {
        out: out.clone(),
        max_dofs,
        quick,
        child_exe: Some(exe),
        memory_budget_mib,
        time_budget_seconds,
        verbose: true,
    };
    if let Some(shard) = shard {
        let shard = fricsens::sensitivity::Shard::parse(&shard)?;
        let path = run_shard(&opts, shard).map_err(|e| e.to_string())?;
        out!(
            "share {}/{} of the scaling study written to {}; combine the shares with `fricsens merge`",
            shard.index,
            shard.count,
            path.display()
        );
        return Ok(());
    }
    let study = run_study(&opts).map_err(|e| e.to_string())?;
    out!(
        "{} sizes measured, {} skipped, in {:.0} s; written to {}",
        study.rows.len(),
        study.skipped.len(),
        study.wall_seconds,
        out.join("scaling.md").display()
    );
    Ok(())
}

#[allow(clippy::too_many_arguments)]
fn fuzz_meshes(
    mutants: usize,
    seed: u64,
    files: Vec<PathBuf>,
    includes: Vec<PathBuf>,
    corpus: PathBuf,
    out: PathBuf,
) -> Result<(), String> {
    use fricsens::studies::mesh_fuzz::{builtin_seeds, run, seed_from, MeshFuzzOptions};
    let mut seeds = builtin_seeds().map_err(|e| e.to_string())?;
    for f in &files {
        seeds.push(seed_from(f).map_err(|e| e.to_string())?);
    }
    let opts = MeshFuzzOptions {
        mutants,
        seed,
        seeds,
        includes,
        corpus: Some(corpus),
    };
    let scratch = std::env::temp_dir().join(format!("fricsens-fuzz-meshes-{}", std::process::id()));
    // a panic's message goes into the report, not onto the terminal
    let hook = std::panic::take_hook();
    std::panic::set_hook(Box::new(|_| {}));
    let report = run(&opts, &scratch);
    std::panic::set_hook(hook);
    let _ = std::fs::remove_dir_all(&scratch);
    let report = report.map_err(|e| e.to_string())?;
    std::fs::create_dir_all(&out).map_err(|e| format!("{}: {e}", out.display()))?;
    let md = report.markdown();
    let write = |name: &str, text: &str| {
        let p = out.join(name);
        std::fs::write(&p, text).map_err(|e| format!("{}: {e}", p.display()))
    };
    write("mesh-fuzz.md", &md)?;
    write(
        "mesh-fuzz.json",
        &serde_json::to_string_pretty(&report).expect("the report serialises"),
    )?;
    out!("{md}");
    if report.clean() {
        Ok(())
    } else {
        Err(format!(
            "{} mutant(s) panicked and {} refusal(s) do not name the file: see {}",
            report.panics.len(),
            report.unnamed.len(),
            out.join("mesh-fuzz.md").display()
        ))
    }
}

fn fuzz(
    seeds: Vec<u64>,
    scenes: Vec<String>,
    out: PathBuf,
    corpus: Option<PathBuf>,
    time_limit: f64,
    before: Option<PathBuf>,
    notes: Option<PathBuf>,
) -> Result<(), String> {
    use fricsens::studies::fuzz::{report_section, run_case, Summary};
    let read =
        |p: &PathBuf| std::fs::read_to_string(p).map_err(|e| format!("{}: {e}", p.display()));
    let before: Option<Summary> = match &before {
        Some(p) => {
            let v: serde_json::Value =
                serde_json::from_str(&read(p)?).map_err(|e| format!("{}: {e}", p.display()))?;
            Some(
                serde_json::from_value(v["summary"].clone())
                    .map_err(|e| format!("{}: summary: {e}", p.display()))?,
            )
        }
        None => None,
    };
    let notes = match &notes {
        Some(p) => read(p)?,
        None => String::new(),
    };
    use rayon::prelude::*;
    let fs = FuzzScenes::new(seeds, &scenes, &out)?;
    if let Some(c) = &corpus {
        std::fs::create_dir_all(c).map_err(|e| format!("{}: {e}", c.display()))?;
    }
    let pb = &fs.pb;
    let failed = std::sync::atomic::AtomicUsize::new(0);
    let outcomes: Vec<_> = fs
        .seeds
        .par_iter()
        .with_max_len(1)
        .map(|&seed| {
            let scene = fs.scene(seed);
            let o = run_case(seed, &scene, Some(time_limit));
            if !o.passed {
                let n = failed.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1;
                pb.set_message(format!("{n} failed"));
                pb.suspend(|| {
                    eprintln!(
                        "{}: {} ({} unknowns, {}/{} increments, {:.1} s)",
                        scene.name,
                        o.failure
                            .as_ref()
                            .map(|f| f.to_string())
                            .unwrap_or_default(),
                        o.unknowns,
                        o.converged,
                        o.increments,
                        o.seconds
                    )
                });
                if let (Some(c), Ok(text)) = (&corpus, scene.to_toml()) {
                    let _ = std::fs::write(c.join(format!("seed-{seed}.toml")), text);
                }
            }
            pb.inc(1);
            o
        })
        .collect();
    pb.finish_and_clear();
    let summary = Summary::of(&outcomes);
    let md = summary.markdown();
    std::fs::write(out.join("fuzz.md"), &md).map_err(|e| e.to_string())?;
    let failures: Vec<_> = outcomes.iter().filter(|o| !o.passed).collect();
    let json = serde_json::to_string_pretty(&serde_json::json!({
        "summary": summary,
        "failures": failures,
    }))
    .map_err(|e| e.to_string())?;
    std::fs::write(out.join("fuzz.json"), json).map_err(|e| e.to_string())?;
    let mut csv = String::from(
        "seed,unknowns,three_d,increments,converged,passed,seconds,work_seconds,iteration_seconds,iterations,solves,limited_steps,cutbacks,failure\n",
    );
    for o in &outcomes {
        csv.push_str(&format!(
            "{},{},{},{},{},{},{:.4},{:.4},{:.6},{},{},{},{},\"{}\"\n",
            o.seed,
            o.unknowns,
            o.three_d,
            o.increments,
            o.converged,
            o.passed,
            o.seconds,
            o.work_seconds,
            o.iteration_seconds,
            o.iterations.iter().sum::<usize>(),
            o.solves,
            o.limited_steps,
            o.cutbacks,
            o.failure
                .as_ref()
                .map(|f| f.to_string())
                .unwrap_or_default()
        ));
    }
    std::fs::write(out.join("fuzz.csv"), csv).map_err(|e| e.to_string())?;
    std::fs::write(
        out.join("robustness.md"),
        report_section(&summary, before.as_ref(), &notes),
    )
    .map_err(|e| e.to_string())?;
    outp!("{md}");
    out!("written to {}", out.display());
    Ok(())
}

/// The fuzzer's scenes: the seeds' generated scenes, or the `scenes` given (built-in names or
/// files), numbered from 0; the output directory made; a progress bar over them.
struct FuzzScenes {
    seeds: Vec<u64>,
    given: Vec<Scene>,
    pb: ProgressBar,
}

impl FuzzScenes {
    fn new(seeds: Vec<u64>, scenes: &[String], out: &Path) -> Result<Self, String> {
        let given: Vec<Scene> = scenes
            .iter()
            .map(|s| Scene::load(s).map_err(|e| e.to_string()))
            .collect::<Result<_, _>>()?;
        let seeds: Vec<u64> = if given.is_empty() {
            seeds
        } else {
            (0..given.len() as u64).collect()
        };
        std::fs::create_dir_all(out).map_err(|e| format!("{}: {e}", out.display()))?;
        let pb = progress(seeds.len());
        pb.set_style(
            ProgressStyle::with_template("{bar:40} {pos}/{len} scenes {msg} [{elapsed}]")
                .expect("valid template"),
        );
        Ok(FuzzScenes { seeds, given, pb })
    }

    /// Scene `seed`: the given one of that number, else the generated one.
    fn scene(&self, seed: u64) -> Scene {
        match self.given.get(seed as usize) {
            Some(s) => s.clone(),
            None => fricsens::studies::fuzz::generate(seed),
        }
    }
}

/// `fricsens fuzz --methods`: DDM against the adjoint on generated scenes (or `scenes`).
fn fuzz_methods(
    seeds: Vec<u64>,
    scenes: Vec<String>,
    out: PathBuf,
    time_limit: f64,
) -> Result<(), String> {
    use fricsens::studies::fuzz_methods::{check, Campaign};
    use rayon::prelude::*;
    let fs = FuzzScenes::new(seeds, &scenes, &out)?;
    let pb = &fs.pb;
    let disagreeing = std::sync::atomic::AtomicUsize::new(0);
    let checks: Vec<_> = fs
        .seeds
        .par_iter()
        .with_max_len(1)
        .map(|&seed| {
            let scene = fs.scene(seed);
            let c = check(seed, &scene, Some(time_limit));
            if !c.agrees() {
                let n = disagreeing.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1;
                pb.set_message(format!("{n} disagree"));
                pb.suspend(|| {
                    eprintln!("{}: {}", scene.name, c.disagreements.join("; "));
                });
            }
            pb.inc(1);
            c
        })
        .collect();
    pb.finish_and_clear();
    let campaign = Campaign::of(checks, Some(time_limit));
    let md = campaign.markdown();
    std::fs::write(out.join("methods.md"), &md).map_err(|e| e.to_string())?;
    let json = serde_json::to_string_pretty(&campaign).map_err(|e| e.to_string())?;
    std::fs::write(out.join("methods.json"), json).map_err(|e| e.to_string())?;
    outp!("{md}");
    out!("written to {}", out.display());
    if campaign.disagreeing > 0 {
        return Err(format!(
            "{} scene(s) where DDM and the adjoint disagree",
            campaign.disagreeing
        ));
    }
    Ok(())
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Scenes { show: None } => {
            for (name, what) in builtin_list() {
                out!("{name:<20} {what}");
            }
            Ok(())
        }
        Command::Scenes { show: Some(name) } => match Scene::load(&name) {
            Ok(s) => s.to_toml().map_err(|e| e.to_string()).map(|text| {
                outp!("{}", text);
            }),
            Err(e) => Err(e.to_string()),
        },
        Command::Fuzz {
            show: Some(seed), ..
        } => fricsens::studies::fuzz::generate(seed)
            .to_toml()
            .map_err(|e| e.to_string())
            .map(|text| {
                outp!("{}", text);
            }),
        Command::Fuzz {
            seeds,
            start,
            out,
            corpus,
            time_limit,
            only,
            scenes,
            show: None,
            before,
            notes,
            methods,
        } => {
            let list = if only.is_empty() {
                (start..start + seeds).collect()
            } else {
                only
            };
            if methods {
                fuzz_methods(list, scenes, out, time_limit)
            } else {
                fuzz(list, scenes, out, corpus, time_limit, before, notes)
            }
        }
        Command::FuzzMeshes {
            mutants,
            seed,
            files,
            includes,
            corpus,
            out,
        } => fuzz_meshes(mutants, seed, files, includes, corpus, out),
        Command::Run {
            scene,
            out,
            no_vtk,
            vtk_every,
            time_limit,
        } => {
            if vtk_every == 0 {
                Err("--vtk-every must be at least 1".to_string())
            } else {
                let vtk = if no_vtk {
                    output::VtkOutput::None
                } else {
                    output::VtkOutput::Every(vtk_every)
                };
                run(&scene, out, vtk, time_limit)
            }
        }
        Command::Ccx {
            scene,
            out,
            beta,
            deck,
            keep,
        } => ccx(&scene, out, beta, deck, keep),
        Command::AdjointStudy {
            out,
            quick,
            budget_s,
            large,
        } => adjoint_study(out, quick, budget_s, large),
        Command::Scaling {
            out,
            max_dofs,
            quick,
            memory_budget_mib,
            time_budget_s,
            rewrite: false,
            merge,
            shard,
        } if merge.is_empty() => scaling(
            out,
            max_dofs,
            quick,
            memory_budget_mib,
            time_budget_s,
            shard,
        ),
        Command::Scaling {
            out,
            merge,
            rewrite: false,
            ..
        } => merge_scaling(&out, &merge),
        Command::Scaling {
            out, rewrite: true, ..
        } => fricsens::studies::scaling::rewrite_outputs(&out)
            .map(|_| out!("rewritten from {}", out.join("scaling.json").display()))
            .map_err(|e| e.to_string()),
        Command::ScalingOne { scene, refinement } => {
            fricsens::studies::scaling::measure_child(&scene, refinement)
                .map(|line| out!("{line}"))
                .map_err(|e| e.to_string())
        }
        Command::Validate {
            scenes,
            out,
            full,
            beta_max,
            beta_min,
            shard,
            friction_laws,
        } => validate(
            &scenes,
            out,
            full,
            (beta_max, beta_min),
            shard,
            (friction_laws > 0).then_some(friction_laws),
        ),
        Command::Merge { partials, out } => merge_any(&partials, out),
        Command::Sensitivity {
            scene,
            params,
            method,
            beta,
            tangent,
            no_krylov,
            adjoint_krylov,
            no_one_sided,
            explain,
            rigid_modes,
            vtk,
            shard,
            at,
            checkpoint,
            response,
            time_limit,
            out,
        } => sensitivity(
            &scene,
            &params,
            method,
            beta,
            InlineArgs {
                tangent,
                krylov: !no_krylov,
                adjoint_krylov,
                one_sided: !no_one_sided,
                explain,
                rigid_modes,
                vtk,
                shard,
                at,
                checkpoint,
                responses: response,
                time_limit,
            },
            out,
        ),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::FAILURE
        }
    }
}
