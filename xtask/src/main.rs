//! `cargo xtask`: cleave's command line. Thin by design: argument parsing, progress, tables;
//! everything else lives in the library crates.

use anyhow::{Context, Result};
use clap::{Parser, Subcommand};
use cleave_scene::{load_scene, Simulation};
use indicatif::{ProgressBar, ProgressStyle};
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::Instant;

#[derive(Parser)]
#[command(name = "cargo xtask", about = "cleave: run scenes, compare backends")]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Replay a RON scene and record it to MCAP.
    Run {
        /// The scene file.
        scene: PathBuf,
        /// Where to write the recording (default: the scene's `output.mcap`, else
        /// `out/<scene name>.mcap`).
        #[arg(long)]
        out: Option<PathBuf>,
        /// Run this many steps instead of the scene's.
        #[arg(long)]
        steps: Option<u64>,
        /// No progress bar (for logs and CI).
        #[arg(long)]
        quiet: bool,
    },
}

fn main() {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Run { scene, out, steps, quiet } => run(scene, out, steps, quiet),
    };
    if let Err(error) = result {
        // One line: the cause chain joined, so scripts and humans see file:line:column first.
        let chain: Vec<String> = error.chain().map(ToString::to_string).collect();
        eprintln!("error: {}", chain.join(": "));
        std::process::exit(1);
    }
}

fn run(scene_path: PathBuf, out: Option<PathBuf>, steps: Option<u64>, quiet: bool) -> Result<()> {
    let mut loaded = load_scene(&scene_path)?;
    if let Some(steps) = steps {
        loaded.scene.steps = steps;
    }
    let out = out.or_else(|| loaded.scene.output.mcap.as_ref().map(PathBuf::from)).unwrap_or_else(|| {
        let stem = scene_path.file_stem().map_or_else(|| "run".into(), |s| s.to_string_lossy().into_owned());
        PathBuf::from("out").join(format!("{stem}.mcap"))
    });
    let mut simulation = Simulation::build(&loaded, Some(&out))?;
    let info = simulation.info().clone();
    eprintln!(
        "{}: {} backend, {} elements (h = {:.4} m), {} DOFs, built in {:.2} s",
        loaded.scene.name, info.backend, info.elements, info.element_size, info.dofs, info.seconds
    );

    let interrupted = Arc::new(AtomicBool::new(false));
    {
        let flag = interrupted.clone();
        // A second Ctrl-C while we finish the file falls through to the default handler.
        ctrlc::set_handler(move || flag.store(true, Ordering::SeqCst)).context("installing the Ctrl-C handler")?;
    }

    let total = simulation.total_steps();
    let bar = if quiet { ProgressBar::hidden() } else { ProgressBar::new(total) };
    bar.set_style(
        ProgressStyle::with_template("{bar:40.cyan/blue} {pos}/{len} steps  {per_sec}  eta {eta}  {msg}")
            .expect("static template")
            .progress_chars("=> "),
    );
    let clock = Instant::now();
    let mut phase = [0.0; 4];
    let (mut iterations, mut max_inverted) = (0usize, 0usize);
    let mut first_energy = None;
    let mut last_report = None;
    let mut failure = None;
    while simulation.steps_done() < total {
        if interrupted.load(Ordering::SeqCst) {
            failure = Some(format!("interrupted by Ctrl-C after {} steps", simulation.steps_done()));
            break;
        }
        match simulation.step() {
            Ok(report) => {
                let s = report.seconds;
                for (acc, value) in phase.iter_mut().zip([s.rotations, s.assembly, s.solve, s.rest]) {
                    *acc += value;
                }
                iterations += report.iterations;
                max_inverted = max_inverted.max(report.inverted_elements);
                first_energy.get_or_insert(report.total_energy());
                bar.set_message(format!("E = {:.3e} J, {} contacts", report.total_energy(), report.active_contacts));
                bar.inc(1);
                last_report = Some(report);
            }
            Err(error) => {
                failure = Some(error.to_string());
                break;
            }
        }
    }
    bar.finish_and_clear();
    let wall = clock.elapsed().as_secs_f64();
    let done = simulation.steps_done();
    simulation.finish(failure.as_deref())?;

    let per_step = |x: f64| if done > 0 { 1e3 * x / done as f64 } else { 0.0 };
    println!("| scene | backend | elements | DOFs | steps | wall [s] | steps/s | ms/step rot | asm | solve | rest | iterations/step | max inverted |");
    println!("|---|---|---|---|---|---|---|---|---|---|---|---|---|");
    println!(
        "| {} | {} | {} | {} | {}/{} | {:.2} | {:.1} | {:.2} | {:.2} | {:.2} | {:.2} | {:.1} | {} |",
        loaded.scene.name,
        info.backend,
        info.elements,
        info.dofs,
        done,
        total,
        wall,
        done as f64 / wall.max(1e-9),
        per_step(phase[0]),
        per_step(phase[1]),
        per_step(phase[2]),
        per_step(phase[3]),
        iterations as f64 / done.max(1) as f64,
        max_inverted
    );
    if let (Some(first), Some(last)) = (first_energy, &last_report) {
        println!("total energy {:.4e} J after step 1, {:.4e} J at the end", first, last.total_energy());
    }
    println!("recording: {}", out.display());
    match failure {
        Some(message) => Err(anyhow::anyhow!(message)),
        None => Ok(()),
    }
}
