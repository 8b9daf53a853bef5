//! `cargo xtask`: cleave's command line. Thin by design: argument parsing, progress, tables,
//! plots and files; everything else lives in the library crates.

mod animation;
mod compare;
mod cutting;
mod machine;
mod perf;
mod plots;
mod raster;
mod recording;
mod render;
mod stability;
mod tidy;

use anyhow::{Context, Result};
use clap::{Parser, Subcommand};
use cleave_scene::{Simulation, load_scene};
use indicatif::{ProgressBar, ProgressStyle};
use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
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
        /// Run on this backend instead of the scene's default (it must have settings in the
        /// scene; `cargo xtask backends` lists what exists).
        #[arg(long)]
        backend: Option<String>,
        /// No progress bar (for logs and CI).
        #[arg(long)]
        quiet: bool,
    },
    /// Draw a recording's /surface frames to PNG (and an animated GIF): flat shading, cut faces
    /// in their recorded colour, the ground, the simulated time.
    Render {
        /// The recording (several with --grid).
        #[arg(required = true)]
        files: Vec<PathBuf>,
        /// The same instants of every recording side by side, each labelled with its backend.
        #[arg(long)]
        grid: bool,
        /// Output directory: PNGs in DIR/<name>/, the GIF as DIR/<name>.gif (name: the first
        /// file's stem, with "_grid" after it for --grid).
        #[arg(long, default_value = "out/render")]
        out: PathBuf,
        /// Draw every N-th recorded frame.
        #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..))]
        every: u32,
        /// Viewer's azimuth (from +x towards +y) and elevation in degrees.
        #[arg(long, default_value = "-60,25", allow_hyphen_values = true)]
        camera: String,
        /// Size of one picture, WIDTHxHEIGHT in pixels.
        #[arg(long, default_value = "480x360")]
        size: String,
        /// Also write an animated GIF, played in simulated time.
        #[arg(long)]
        gif: bool,
        /// No progress bar.
        #[arg(long)]
        quiet: bool,
    },
    /// List the registered backends and what they can do.
    Backends,
    /// Refine every registered backend on the benchmark problems under a time budget; write
    /// compare.csv, compare.md and plots.
    Compare {
        /// Small levels only (CI); writes to target/ci unless --out is given.
        #[arg(long)]
        quick: bool,
        /// What to run: any of mms, cantilever, dynamic, cut-cantilever (refinement studies; the
        /// last is benchmarks.md §5 static and cut at t = 1 s in the dynamic beam, on every backend
        /// that cuts), table1
        /// (kaufmann2008 Table 1 timings), cutting (the timeline of scenes/bunny_slice.ron on
        /// every selected backend that can cut), or all. What is not selected is kept from the
        /// previous compare.csv, table1.csv, cutting.csv and compare.md.
        #[arg(long, num_args = 1.., default_values_t = vec!["all".to_string()])]
        problem: Vec<String>,
        /// Backends to run (default: all registered).
        #[arg(long, num_args = 1..)]
        backend: Vec<String>,
        /// Wall-clock seconds per (backend, variant, problem) study.
        #[arg(long, default_value_t = 120.0)]
        budget: f64,
        /// Output directory (default docs/results, or target/ci with --quick).
        #[arg(long)]
        out: Option<PathBuf>,
        /// No progress bar.
        #[arg(long)]
        quiet: bool,
        /// Run the I-th of N disjoint slices of the work list (studies, Table 1 timings, cutting
        /// runs; round robin) and write only its rows into --out, which it needs; see
        /// docs/distributed-compare.md.
        #[arg(long, value_name = "I/N", requires = "out", conflicts_with = "merge")]
        shard: Option<String>,
        /// Run nothing: build compare.md, the CSVs and the plots in --out (default docs/results)
        /// from the rows of every shard's directory.
        #[arg(long, value_name = "DIR", num_args = 1..)]
        merge: Vec<PathBuf>,
    },
    /// The headline measurements (bunny_slice, the voxel bunny drop, Table 1's solves, the voxel
    /// stiffness action), appended with the commit to docs/results/perf-history.csv; prints the
    /// ratio of each to the previous row.
    Perf {
        /// History file to append to.
        #[arg(long, default_value = "docs/results/perf-history.csv")]
        history: PathBuf,
        /// No progress lines.
        #[arg(long)]
        quiet: bool,
    },
    /// One measurement of `perf` in a process of its own: the peak memory per voxel of a 100³
    /// voxel box taking one step.
    #[command(hide = true)]
    PerfMemory,
    /// The stability grid (E × ν × h and extreme starts) for every registered backend; write
    /// stability.md and stability.csv.
    Stability {
        /// 20 steps per cell instead of 600; writes to target/ci unless --out is given.
        #[arg(long)]
        quick: bool,
        /// Backends to run (default: all registered).
        #[arg(long, num_args = 1..)]
        backend: Vec<String>,
        /// Output directory (default docs/results, or target/ci with --quick).
        #[arg(long)]
        out: Option<PathBuf>,
        /// No progress bar.
        #[arg(long)]
        quiet: bool,
    },
    /// Check the invariants of docs/architecture.md the compiler does not: which crate may
    /// depend on which, no terminal or file I/O in library code, a `//!` line atop every file.
    Tidy,
}

/// The command as typed (for the reports), without the binary path.
fn typed_command() -> String {
    let args: Vec<String> = std::env::args().skip(1).collect();
    format!("cargo xtask {}", args.join(" "))
}

fn default_out(quick: bool, out: Option<PathBuf>) -> PathBuf {
    out.unwrap_or_else(|| PathBuf::from(if quick { "target/ci" } else { "docs/results" }))
}

fn main() {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Run { scene, out, steps, backend, quiet } => run(scene, out, steps, backend.as_deref(), quiet),
        Command::Render { files, grid, out, every, camera, size, gif, quiet } => render::parse_camera(&camera)
            .and_then(|camera| {
                render::render(render::RenderArgs {
                    files,
                    grid,
                    out,
                    every: every as usize,
                    camera,
                    size: render::parse_size(&size)?,
                    gif,
                    quiet,
                })
            }),
        Command::Backends => {
            println!("| backend | cut | fracture | refine | method |");
            println!("|---|---|---|---|---|");
            for b in cleave_registry::registered() {
                let c = b.capabilities();
                let yes = |v: bool| if v { "yes" } else { "—" };
                println!(
                    "| {} | {} | {} | {} | {} |",
                    b.name(),
                    yes(c.cut),
                    yes(c.fracture),
                    yes(c.refine),
                    b.summary()
                );
            }
            Ok(())
        }
        Command::Compare { quick, problem, backend, budget, out, quiet, shard, merge } => {
            if !(budget.is_finite() && budget > 0.0) {
                Err(anyhow::anyhow!("--budget must be a positive number of seconds, got {budget}"))
            } else {
                shard.as_deref().map(compare::Shard::parse).transpose().and_then(|shard| {
                    let args = compare::CompareArgs {
                        quick,
                        problems: problem,
                        backends: backend,
                        budget,
                        out: default_out(quick, out),
                        command: typed_command(),
                        quiet,
                        shard,
                    };
                    if merge.is_empty() { compare::compare(args) } else { compare::merge(args, &merge) }
                })
            }
        }
        Command::Perf { history, quiet } => perf::perf(perf::PerfArgs { history, quiet }),
        Command::PerfMemory => perf::memory_child(perf::MEMORY_BOX_EDGE),
        Command::Tidy => {
            let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
            let violations = tidy::check(&root);
            for v in &violations {
                println!("{v}");
            }
            if violations.is_empty() {
                println!("tidy: no violations");
                Ok(())
            } else {
                Err(anyhow::anyhow!("tidy: {} violations", violations.len()))
            }
        }
        Command::Stability { quick, backend, out, quiet } => stability::stability(stability::StabilityArgs {
            quick,
            backends: backend,
            out: default_out(quick, out),
            command: typed_command(),
            quiet,
        }),
    };
    if let Err(error) = result {
        // One line: the cause chain joined, so scripts and humans see file:line:column first.
        let chain: Vec<String> = error.chain().map(ToString::to_string).collect();
        eprintln!("error: {}", chain.join(": "));
        std::process::exit(1);
    }
}

/// Contact over a run, for the summary: the most active contacts of each kind in one step, the
/// deepest penetration, and the time finding contacts, adding their forces and matrix blocks, and
/// growing the pattern for them.
#[derive(Default)]
struct ContactTotals {
    most: [usize; 4],
    deepest: f64,
    finding: f64,
    forces: f64,
    pattern: f64,
    wall: f64,
    triangles: (usize, usize),
}

impl ContactTotals {
    fn add(&mut self, report: &cleave_scene::StepReport, wall: f64, triangles: usize) {
        let c = &report.contacts;
        for (most, now) in self.most.iter_mut().zip([c.planes, c.meshes, c.surface, c.edges]) {
            *most = (*most).max(now);
        }
        self.deepest = self.deepest.max(c.max_penetration);
        self.finding += report.seconds.contact;
        self.forces += report.seconds.contact_forces;
        self.pattern += report.seconds.pattern;
        self.wall += wall;
        self.triangles = if self.triangles.1 == 0 {
            (triangles, triangles)
        } else {
            (self.triangles.0.min(triangles), self.triangles.1.max(triangles))
        };
    }

    fn print(&self, steps: u64) {
        if self.most.iter().all(|&m| m == 0) || steps == 0 {
            return;
        }
        let per_step = |x: f64| 1e3 * x / steps as f64;
        println!();
        println!(
            "| most contacts: planes | meshes | surface | edges | deepest [mm] | surface triangles | finding [ms/step] | forces [ms/step] | pattern [ms/step] | share of the step | finding and forces alone |"
        );
        println!("|---|---|---|---|---|---|---|---|---|---|---|");
        println!(
            "| {} | {} | {} | {} | {:.3} | {}–{} | {:.2} | {:.2} | {:.2} | {:.1} % | {:.1} % |",
            self.most[0],
            self.most[1],
            self.most[2],
            self.most[3],
            1e3 * self.deepest,
            self.triangles.0,
            self.triangles.1,
            per_step(self.finding),
            per_step(self.forces),
            per_step(self.pattern),
            100.0 * (self.finding + self.forces + self.pattern) / self.wall.max(1e-12),
            100.0 * (self.finding + self.forces) / self.wall.max(1e-12)
        );
    }
}

fn run(
    scene_path: PathBuf,
    out: Option<PathBuf>,
    steps: Option<u64>,
    backend: Option<&str>,
    quiet: bool,
) -> Result<()> {
    let mut loaded = load_scene(&scene_path)?;
    if let Some(steps) = steps {
        loaded.scene.steps = steps;
    }
    let out = out.or_else(|| loaded.scene.output.mcap.as_ref().map(PathBuf::from)).unwrap_or_else(|| {
        let stem = scene_path.file_stem().map_or_else(|| "run".into(), |s| s.to_string_lossy().into_owned());
        PathBuf::from("out").join(format!("{stem}.mcap"))
    });
    let mut simulation = Simulation::build_with_backend(&loaded, Some(&out), backend)?;
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
    let mut frame_walls = [(0.0f64, 0usize); 2];
    // The slowest step (wall, step) and how many took longer than a tenth of a second.
    let mut slowest = (0.0f64, 0u64);
    let mut over_a_tenth = 0usize;
    let mut contact_totals = ContactTotals::default();
    while simulation.steps_done() < total {
        if interrupted.load(Ordering::SeqCst) {
            failure = Some(format!("interrupted by Ctrl-C after {} steps", simulation.steps_done()));
            break;
        }
        let changes_before = simulation.cut_summary().changes;
        let step_clock = Instant::now();
        let result = simulation.step();
        let step_wall = step_clock.elapsed().as_secs_f64();
        // Frame rate with and without a topology change in the step (recording included).
        let bucket = usize::from(simulation.cut_summary().changes > changes_before);
        frame_walls[bucket].0 += step_wall;
        frame_walls[bucket].1 += 1;
        if step_wall > slowest.0 {
            slowest = (step_wall, simulation.steps_done());
        }
        over_a_tenth += usize::from(step_wall > 0.1);
        match result {
            Ok(report) => {
                let s = report.seconds;
                for (acc, value) in phase.iter_mut().zip([s.rotations, s.assembly, s.solve, s.rest]) {
                    *acc += value;
                }
                iterations += report.iterations;
                max_inverted = max_inverted.max(report.inverted_elements);
                contact_totals.add(&report, step_wall, simulation.surface_triangle_count());
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
    let simulation_cuts = simulation.cut_summary().clone();
    simulation.finish(failure.as_deref())?;

    let per_step = |x: f64| if done > 0 { 1e3 * x / done as f64 } else { 0.0 };
    println!(
        "| scene | backend | elements | DOFs | steps | wall [s] | steps/s | ms/step rot | asm | solve | rest | iterations/step | max inverted |"
    );
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
    contact_totals.print(done);
    let cuts = simulation_cuts;
    if cuts.changes > 0 || !cuts.pieces.is_empty() {
        let (volume_drift, mass_drift) = cuts.drift();
        println!();
        println!(
            "| topology changes | cutting [ms] | ms/change | pieces | nodes | elements | volume drift | mass drift |"
        );
        println!("|---|---|---|---|---|---|---|---|");
        println!(
            "| {} | {:.1} | {:.2} | {} | {} | {} | {:.2e} | {:.2e} |",
            cuts.changes,
            1e3 * cuts.seconds,
            1e3 * cuts.seconds / cuts.changes.max(1) as f64,
            cuts.pieces.len(),
            cuts.nodes,
            cuts.elements,
            volume_drift,
            mass_drift
        );
        let rate =
            |(wall, steps): (f64, usize)| if steps > 0 { format!("{:.1}", steps as f64 / wall) } else { "—".into() };
        println!(
            "steps/s (recording included): {} in the {} steps that cut, {} in the {} others",
            rate(frame_walls[1]),
            frame_walls[1].1,
            rate(frame_walls[0]),
            frame_walls[0].1
        );
        println!(
            "slowest step (recording included): {:.1} ms ({:.1} frames/s), step {}; {} steps over 100 ms",
            1e3 * slowest.0,
            1.0 / slowest.0.max(1e-9),
            slowest.1,
            over_a_tenth
        );
        if cuts.prepared > 0 {
            println!(
                "timeline cuts made ahead on a copy, off the step's thread: {} of {} changes, {:.1} ms (not in cutting [ms])",
                cuts.prepared,
                cuts.changes,
                1e3 * cuts.prepared_seconds
            );
        }
        for (k, piece) in cuts.pieces.iter().enumerate() {
            println!(
                "piece {k}: {} elements, volume {:.6e} m³, mass {:.6e} kg",
                piece.elements.len(),
                piece.volume,
                piece.mass
            );
        }
    }
    if let (Some(first), Some(last)) = (first_energy, &last_report) {
        println!("total energy {:.4e} J after step 1, {:.4e} J at the end", first, last.total_energy());
    }
    println!("recording: {}", out.display());
    match failure {
        Some(message) => Err(anyhow::anyhow!(message)),
        None => Ok(()),
    }
}
