//! `cargo xtask perf`: the headline measurements every change reports against, one row per run
//! appended with the commit to `docs/results/perf-history.csv`, and the ratio of each figure to
//! the previous row printed.
//!
//! Measured (release build, no recording): `scenes/bunny_slice.ron` (steps/s over all steps, the
//! steps that cut and the others; contact's share of the step), `scenes/bunny_drop_voxel.ron`
//! (steps/s, CG iterations a step), kaufmann2008 Table 1 (numeric factorization and solve of the
//! four DG variants, median of three), the voxel stiffness action on 10,164 cubes, and the static
//! voxel cantilever at n = 16 (build, assembly and direct solve, as `compare` times it), and the
//! peak memory per voxel of a 100³ box taking one step, in a child process of its own. Timings
//! share the machine with whatever else runs: the row keeps the load average, and a change that
//! claims a gain should alternate old and new builds.

use crate::machine::machine_line;
use anyhow::{Context, Result, bail};
use cleave_core::{Matrix3, Point3, Real, Vector3};
use cleave_registry::registered;
use cleave_scene::{Simulation, load_scene};
use cleave_testkit::compare::{BoxGrid, DirichletSpec, Problem, run_problem, table1_timings};
use std::fs;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

/// Columns of `perf-history.csv`, after the date, commit and load.
const FIGURES: [(&str, bool); 13] = [
    // (name, larger is better)
    ("bunny_slice_steps_per_s", true),
    ("bunny_slice_cutting_steps_per_s", true),
    ("bunny_slice_other_steps_per_s", true),
    ("bunny_slice_contact_share_pct", false),
    ("voxel_drop_steps_per_s", true),
    ("voxel_drop_iterations_per_step", false),
    ("table1_bz1_solve_ms", false),
    ("table1_ip1_solve_ms", false),
    ("table1_bz2_solve_ms", false),
    ("table1_ip2_solve_ms", false),
    ("voxel_stiffness_gflops", true),
    ("voxel_cantilever_n16_s", false),
    ("voxel_memory_kb_per_voxel", false),
];

/// Parsed arguments of `cargo xtask perf`.
pub struct PerfArgs {
    /// The history file the row is appended to.
    pub history: PathBuf,
    /// Quiet: no per-workload lines.
    pub quiet: bool,
}

/// Runs the measurements, appends a row and prints it beside the previous one.
pub fn perf(args: PerfArgs) -> Result<()> {
    let say = |what: &str| {
        if !args.quiet {
            eprintln!("perf: {what}");
        }
    };
    let mut figures = Vec::with_capacity(FIGURES.len());
    say("scenes/bunny_slice.ron");
    let (all, cutting, others, share, _) = scene_run(Path::new("scenes/bunny_slice.ron"))?;
    figures.extend([all, cutting, others, share]);
    say("scenes/bunny_drop_voxel.ron");
    let (steps_per_s, _, _, _, iterations) = scene_run(Path::new("scenes/bunny_drop_voxel.ron"))?;
    figures.extend([steps_per_s, iterations]);
    say("kaufmann2008 Table 1");
    let dg = registered().into_iter().find(|b| b.name() == "dg").context("the dg backend is not registered")?;
    for variant in ["bz-1", "ip-1", "bz-2", "ip-2"] {
        let timing = table1_timings(dg.as_ref(), variant, 3).map_err(|e| anyhow::anyhow!("Table 1, {variant}: {e}"))?;
        figures.push(1e3 * timing.solve);
    }
    say("voxel stiffness action");
    figures.push(stiffness_gflops()?);
    say("static voxel cantilever at n = 16");
    let voxel =
        registered().into_iter().find(|b| b.name() == "voxel").context("the voxel backend is not registered")?;
    let row = run_problem(voxel.as_ref(), "trilinear", Problem::Cantilever, 16)
        .map_err(|e| anyhow::anyhow!("static cantilever: {e}"))?;
    figures.push(row.seconds_total.unwrap_or(f64::NAN));
    say("peak memory per voxel at 1M voxels (a child process)");
    figures.push(memory_per_voxel()?);

    let commit = git(&["rev-parse", "--short", "HEAD"]).unwrap_or_else(|| "unknown".into());
    // Changes to tracked files other than the history itself (which the last run edited).
    let dirty = git(&["status", "--porcelain", "--untracked-files=no", "--", ".", ":!docs/results/perf-history.csv"])
        .is_some_and(|s| !s.is_empty());
    let load = fs::read_to_string("/proc/loadavg")
        .ok()
        .and_then(|t| t.split_whitespace().next().map(str::to_string))
        .unwrap_or_default();
    let date = today_utc();
    let header = format!("date,commit,load_1min,{}", FIGURES.map(|f| f.0).join(","));
    // Only a missing file starts a new history: any other read error stops before writing.
    let previous = match fs::read_to_string(&args.history) {
        Ok(text) if text.trim().is_empty() => None,
        Ok(text) => Some(text),
        Err(error) if error.kind() == std::io::ErrorKind::NotFound => None,
        Err(error) => return Err(error).with_context(|| format!("reading {}", args.history.display())),
    };
    if let Some(text) = &previous
        && text.lines().next() != Some(header.as_str())
    {
        bail!("{} has other columns than this version writes; move it aside", args.history.display());
    }
    let last_row: Option<Vec<f64>> = previous
        .as_deref()
        .and_then(|t| t.lines().skip(1).last())
        .map(|line| line.split(',').skip(3).map(|v| v.parse().unwrap_or(f64::NAN)).collect());
    let row = format!(
        "{date},{}{},{load},{}",
        commit,
        if dirty { "+dirty" } else { "" },
        figures.iter().map(|v| format!("{v:.4}")).collect::<Vec<_>>().join(",")
    );
    let mut text = previous.unwrap_or_else(|| header.clone() + "\n");
    if !text.ends_with('\n') {
        text.push('\n');
    }
    text.push_str(&row);
    text.push('\n');
    fs::write(&args.history, text).with_context(|| format!("writing {}", args.history.display()))?;

    println!("{}", machine_line());
    println!("commit {commit}{}, load {load} (1 min)", if dirty { " (uncommitted changes)" } else { "" });
    println!("| figure | this run | previous | ratio (> 1: better) |");
    println!("|---|---|---|---|");
    for (k, (name, larger_is_better)) in FIGURES.iter().enumerate() {
        let now = figures[k];
        let before = last_row.as_ref().and_then(|r| r.get(k).copied()).filter(|v| v.is_finite());
        let (before_text, ratio) = match before {
            Some(b) if b > 0.0 && now > 0.0 => {
                (format!("{b:.2}"), format!("{:.2}", if *larger_is_better { now / b } else { b / now }))
            }
            _ => ("—".into(), "—".into()),
        };
        println!("| {name} | {now:.2} | {before_text} | {ratio} |");
    }
    println!("appended to {}", args.history.display());
    Ok(())
}

/// A scene run without recording: steps/s over all steps, the steps that cut and the others,
/// contact's share of the step time (finding, forces, pattern growth) and mean iterations.
fn scene_run(path: &Path) -> Result<(f64, f64, f64, f64, f64)> {
    let loaded = load_scene(path)?;
    let mut simulation = Simulation::build(&loaded, None)?;
    let total = simulation.total_steps();
    let (mut walls, mut contact, mut iterations) = ([(0.0f64, 0usize); 2], 0.0, 0usize);
    while simulation.steps_done() < total {
        let changes = simulation.cut_summary().changes;
        let clock = Instant::now();
        let report = simulation.step()?;
        let wall = clock.elapsed().as_secs_f64();
        let bucket = usize::from(simulation.cut_summary().changes > changes);
        walls[bucket].0 += wall;
        walls[bucket].1 += 1;
        contact += report.seconds.contact + report.seconds.contact_forces + report.seconds.pattern;
        iterations += report.iterations;
    }
    let rate = |(wall, steps): (f64, usize)| if wall > 0.0 { steps as f64 / wall } else { 0.0 };
    let whole = (walls[0].0 + walls[1].0, walls[0].1 + walls[1].1);
    Ok((
        rate(whole),
        rate(walls[1]),
        rate(walls[0]),
        100.0 * contact / whole.0.max(1e-12),
        iterations as f64 / total.max(1) as f64,
    ))
}

/// The registered voxel backend's box `grid` of `material`, pinned nowhere.
fn voxel_box(grid: &BoxGrid, material: cleave_core::Material) -> Result<cleave_testkit::compare::BuiltProblem> {
    let voxel =
        registered().into_iter().find(|b| b.name() == "voxel").context("the voxel backend is not registered")?;
    let nowhere = |_: &Point3<Real>| false;
    let zero = |_: &Point3<Real>| Vector3::zeros();
    voxel
        .build_box("trilinear", &material, grid, &DirichletSpec { region: &nowhere, value: &zero })
        .map_err(|e| anyhow::anyhow!("building the voxel box: {e}"))
}

/// The voxel stiffness action `out += K dx` with the corotated kernel on 22 × 22 × 21 cubes
/// (10,164, the voxel bunny's size) at identity rotations, best of five runs of 50 products:
/// GFLOP/s counting 1,392 operations a cube (the 24 × 24 product, 1,152, and rotating the eight
/// corners' 3-vectors in and out, 240).
fn stiffness_gflops() -> Result<f64> {
    let grid = BoxGrid { origin: Point3::origin(), h: 0.01, dims: [22, 22, 21] };
    let built = voxel_box(&grid, cleave_core::Material::new(2e5, 0.3, 1000.0)?)?;
    let d = built.discretization.as_ref();
    let rotations = vec![Matrix3::identity(); d.num_frames()];
    let dx: Vec<Real> = (0..3 * d.num_nodes()).map(|i| (i as Real * 0.37).sin()).collect();
    let mut out = vec![0.0; dx.len()];
    let cubes: usize = grid.dims.iter().product();
    let mut best = f64::INFINITY;
    for _ in 0..5 {
        let clock = Instant::now();
        for _ in 0..50 {
            d.add_stiffness_action(&rotations, &dx, 1.0, &mut out);
        }
        best = best.min(clock.elapsed().as_secs_f64() / 50.0);
    }
    std::hint::black_box(&out);
    Ok(cubes as f64 * 1392.0 / best / 1e9)
}

/// Edge of the memory measurement's box, in cubes (100³ = 1M voxels, issue 35's size).
pub const MEMORY_BOX_EDGE: usize = 100;

/// Peak resident memory per voxel [KB = 1000 B] of [`memory_child`], run as `xtask perf-memory`
/// in a process of its own so nothing this process holds counts.
fn memory_per_voxel() -> Result<f64> {
    let exe = std::env::current_exe().context("finding the xtask binary")?;
    let out = Command::new(exe).arg("perf-memory").output().context("running xtask perf-memory")?;
    if !out.status.success() {
        bail!("xtask perf-memory failed: {}", String::from_utf8_lossy(&out.stderr).trim());
    }
    let text = String::from_utf8_lossy(&out.stdout);
    text.lines()
        .find_map(|l| l.strip_prefix("kb_per_voxel "))
        .and_then(|v| v.trim().parse().ok())
        .with_context(|| format!("xtask perf-memory printed no kb_per_voxel line: {text}"))
}

/// A box of `edge³` voxels resting on a ground plane through its bottom nodes (one contact row
/// each), one matrix-free block-Jacobi CG step at the scene tolerance, then the peak resident
/// set (`VmHWM`, everything included) per voxel, printed as `kb_per_voxel X`.
pub fn memory_child(edge: usize) -> Result<()> {
    use cleave_integrator::{Constraints, Integrator, PlaneCollider, Preconditioner, Settings, Solver};
    let h = 0.2 / edge as Real;
    let grid = BoxGrid { origin: Point3::new(0.0, 0.0, 0.01), h, dims: [edge, edge, edge] };
    let built = voxel_box(&grid, cleave_core::Material::new(2e5, 0.3, 1000.0)?.with_damping(0.0, 0.01)?)?;
    let mesh = built.discretization.as_ref();
    let bottom: Vec<Point3<Real>> =
        mesh.rest_dofs().chunks(3).filter(|p| p[2] < 0.01 + 0.5 * h).map(|p| Point3::new(p[0], p[1], p[2])).collect();
    let contact = mesh.embed(&bottom).map_err(|e| anyhow::anyhow!("embedding the bottom nodes: {e}"))?;
    drop(bottom);
    let mut settings = Settings::new(1.0 / 60.0);
    settings.rayleigh_beta = 0.01;
    settings.solver = Solver::ConjugateGradient { tolerance: 1e-3, max_iterations: 2000, assembled: false };
    settings.preconditioner = Preconditioner::BlockJacobi;
    let ground =
        PlaneCollider { point: Point3::origin(), normal: Vector3::z(), stiffness: 2e4, damping: 20.0, friction: 0.0 };
    let constraints = Constraints { contact_points: Some(contact), planes: vec![ground], ..Default::default() };
    let mut integrator = Integrator::new(mesh, settings, constraints)?;
    integrator.step(mesh)?;
    let status = fs::read_to_string("/proc/self/status").context("reading /proc/self/status")?;
    let kib: f64 = status
        .lines()
        .find_map(|l| l.strip_prefix("VmHWM:"))
        .and_then(|v| v.trim().trim_end_matches("kB").trim().parse().ok())
        .context("no VmHWM in /proc/self/status")?;
    let voxels = (edge * edge * edge) as f64;
    println!("kb_per_voxel {}", kib * 1024.0 / 1000.0 / voxels);
    Ok(())
}

fn git(args: &[&str]) -> Option<String> {
    let out = Command::new("git").args(args).output().ok()?;
    out.status.success().then(|| String::from_utf8_lossy(&out.stdout).trim().to_string())
}

/// Today's UTC date from the system clock, as YYYY-MM-DD (civil from days, Howard Hinnant's
/// algorithm), without a date crate.
fn today_utc() -> String {
    let seconds = std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).map_or(0, |d| d.as_secs());
    let days = (seconds / 86_400) as i64 + 719_468;
    let era = days.div_euclid(146_097);
    let day_of_era = days.rem_euclid(146_097);
    let year_of_era = (day_of_era - day_of_era / 1460 + day_of_era / 36_524 - day_of_era / 146_096) / 365;
    let day_of_year = day_of_era - (365 * year_of_era + year_of_era / 4 - year_of_era / 100);
    let month_index = (5 * day_of_year + 2) / 153;
    let day = day_of_year - (153 * month_index + 2) / 5 + 1;
    let month = if month_index < 10 { month_index + 3 } else { month_index - 9 };
    let year = year_of_era + era * 400 + i64::from(month <= 2);
    format!("{year:04}-{month:02}-{day:02}")
}
