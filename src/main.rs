//! The `fricsens` command line: list scenes, run a primal analysis.

use clap::{Parser, Subcommand};
use fricsens::output;
use fricsens::scene::{builtin, builtin_list, Scene};
use fricsens::solver::{AnalysisError, Converged, Observer, RunOptions, Solver};
use indicatif::{ProgressBar, ProgressStyle};
use std::path::PathBuf;
use std::process::ExitCode;

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
    /// List the built-in scenes, or print one as TOML.
    Scenes {
        /// Print the TOML of this built-in scene.
        #[arg(long)]
        show: Option<String>,
    },
    /// Primal analysis: history CSV, Newton records, VTK files.
    Run {
        /// A built-in scene name or a TOML scene file.
        scene: String,
        /// Output directory (default: out/SCENE).
        #[arg(long)]
        out: Option<PathBuf>,
    },
}

/// Progress bar over increments (drawn only on a terminal).
struct Progress(ProgressBar);

impl Observer for Progress {
    fn converged(&mut self, c: &Converged<'_>) -> Result<(), AnalysisError> {
        self.0.set_position(c.index as u64);
        self.0.set_message(format!(
            "t = {:.4}, {} iterations",
            c.time, c.record.iterations
        ));
        Ok(())
    }
}

fn progress(n: usize) -> ProgressBar {
    let pb = ProgressBar::new(n as u64);
    pb.set_style(
        ProgressStyle::with_template("{bar:40} {pos}/{len} increments {msg} [{elapsed}]")
            .expect("valid template"),
    );
    pb
}

fn run(scene_name: &str, out: Option<PathBuf>) -> Result<(), String> {
    let scene = Scene::load(scene_name).map_err(|e| e.to_string())?;
    let model = scene.build().map_err(|e| format!("{scene_name}: {e}"))?;
    let dir = out.unwrap_or_else(|| PathBuf::from("out").join(&scene.name));
    let mut solver = Solver::new(&model).map_err(|e| e.to_string())?;
    let mut obs = Progress(progress(model.times.len()));
    let result = solver.run(&RunOptions::default(), &mut obs);
    obs.0.finish_and_clear();
    let res = match result {
        Ok(r) => r,
        Err(e) => {
            if let Some(partial) = e.partial() {
                let _ = output::write_run(&dir, &model, partial);
                eprintln!(
                    "results up to the last converged increment written to {}",
                    dir.display()
                );
            }
            return Err(e.to_string());
        }
    };
    output::write_run(&dir, &model, &res).map_err(|e| e.to_string())?;
    let iters: usize = res.records.iter().map(|r| r.iterations).sum();
    println!(
        "{}: {} increments, {} Newton iterations ({:.2} per increment), {} unknowns, {:.3} s",
        scene.name,
        res.records.len(),
        iters,
        iters as f64 / res.records.len().max(1) as f64,
        solver.assembler.dofs.n_total,
        res.cost.wall_seconds
    );
    let last = res.states.len() - 1;
    for (k, r) in model.responses.iter().enumerate() {
        println!(
            "  {:<24} {:>16.8e}",
            r.name,
            res.response_value(&model, k, last)
        );
    }
    println!("written to {}", dir.display());
    Ok(())
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Scenes { show: None } => {
            for (name, what) in builtin_list() {
                println!("{name:<20} {what}");
            }
            Ok(())
        }
        Command::Scenes { show: Some(name) } => match builtin(&name) {
            Some(s) => {
                print!("{}", s.to_toml());
                Ok(())
            }
            None => Err(format!(
                "unknown built-in scene '{name}' (see `fricsens scenes`)"
            )),
        },
        Command::Run { scene, out } => run(&scene, out),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::FAILURE
        }
    }
}
