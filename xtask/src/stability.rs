//! `cargo xtask stability`: the benchmarks.md §4 grid for every registered backend and variant,
//! a table per method to the terminal and to `stability.md`, every cell to `stability.csv`
//! (appended and flushed as it finishes). Methods an invocation does not run keep their CSV lines
//! and their `stability.md` sections from the previous files.

use crate::compare::selected_backends;
use crate::machine::machine_line;
use anyhow::{Context, Result};
use cleave_testkit::stability::{
    CSV_HEADER, CellResult, DENSITY, ENERGY_TOLERANCE, NEAR_NODE_PLANE_OFFSET, POISSON_RATIOS, Start, TIME_STEPS,
    Verdict, YOUNGS_MODULI, beam_grid, cells, run_cell,
};
use indicatif::{ProgressBar, ProgressStyle};
use std::fmt::Write as _;
use std::fs::{self, OpenOptions};
use std::io::Write;
use std::path::{Path, PathBuf};

/// Parsed arguments of `cargo xtask stability`.
pub struct StabilityArgs {
    /// 20 steps per cell instead of 600 (CI).
    pub quick: bool,
    /// Backends (empty = all).
    pub backends: Vec<String>,
    /// Output directory.
    pub out: PathBuf,
    /// The command as typed.
    pub command: String,
    /// No progress bar.
    pub quiet: bool,
}

fn h_label(h: f64) -> String {
    if (h - 1.0 / 60.0).abs() < 1e-12 {
        "1/60".into()
    } else if (h - 1.0 / 30.0).abs() < 1e-12 {
        "1/30".into()
    } else {
        format!("{h:e}")
    }
}

/// Runs `cargo xtask stability`.
pub fn stability(args: StabilityArgs) -> Result<()> {
    let chosen = selected_backends(&args.backends)?;
    let steps = if args.quick { 20 } else { 600 };
    fs::create_dir_all(&args.out).with_context(|| format!("creating {}", args.out.display()))?;
    let csv_path = args.out.join("stability.csv");
    let md_path = args.out.join("stability.md");
    let grid = cells();
    let methods: Vec<(usize, String)> =
        chosen.iter().enumerate().flat_map(|(i, b)| b.variants().into_iter().map(move |v| (i, v))).collect();
    let run_names: Vec<String> = methods.iter().map(|(b, v)| format!("{}/{v}", chosen[*b].name())).collect();
    // Keep the other methods' cells and sections.
    let mut kept_csv = String::new();
    if let Ok(text) = fs::read_to_string(&csv_path)
        && text.lines().next().map(str::trim_end) == Some(CSV_HEADER)
    {
        for line in text.lines().skip(1).filter(|l| !l.trim().is_empty()) {
            let mut f = line.split(',');
            let method = format!("{}/{}", f.next().unwrap_or(""), f.next().unwrap_or(""));
            if !run_names.contains(&method) {
                kept_csv.push_str(line);
                kept_csv.push('\n');
            }
        }
    }
    let kept_sections: Vec<(String, String)> =
        previous_sections(&md_path).into_iter().filter(|(m, _)| !run_names.contains(m)).collect();
    fs::write(&csv_path, format!("{CSV_HEADER}\n{kept_csv}"))
        .with_context(|| format!("writing {}", csv_path.display()))?;
    let mut csv =
        OpenOptions::new().append(true).open(&csv_path).with_context(|| format!("opening {}", csv_path.display()))?;
    let bar = if args.quiet { ProgressBar::hidden() } else { ProgressBar::new((methods.len() * grid.len()) as u64) };
    bar.set_style(
        ProgressStyle::with_template("{bar:30.cyan/blue} {pos}/{len} cells  {elapsed_precise}  {msg}")
            .expect("static template")
            .progress_chars("=> "),
    );
    let mut results: Vec<CellResult> = Vec::new();
    for (b, variant) in &methods {
        let backend = chosen[*b].as_ref();
        for cell in &grid {
            bar.set_message(format!(
                "{}/{variant} {} E={:e} ν={} h={}",
                backend.name(),
                cell.case(),
                cell.youngs_modulus,
                cell.poisson_ratio,
                h_label(cell.time_step)
            ));
            let result = run_cell(backend, variant, *cell, steps);
            writeln!(csv, "{}", result.to_csv(steps))
                .and_then(|_| csv.flush())
                .with_context(|| format!("appending to {}", csv_path.display()))?;
            results.push(result);
            bar.inc(1);
        }
    }
    bar.finish_and_clear();

    let beam = beam_grid();
    let mut md = String::new();
    let w = &mut md;
    let _ = writeln!(w, "# Stability grid\n");
    let _ = writeln!(
        w,
        "benchmarks.md §4 for every registered backend and variant. Each cell is a beam of {:.2} m × {:.2} m × \
         {:.2} m as {} × {} × {} cells, clamped at x = 0 (Dirichlet data as the backend imposes it), ρ = {DENSITY} \
         kg/m³, no damping, released from rest under gravity and run for {steps} corotated linearly implicit Euler \
         steps with the backend's time-stepping solver. A cell passes when the run finishes without NaN, the \
         solver converges at every step, and the total energy E = kinetic + elastic + gravitational (measured \
         from the start) never exceeds E(0) by more than {:.0}% of the run's energy scale, the largest of \
         |E(0)|, kinetic + elastic and the gravitational work over the run (a start from rest has E(0) = 0, so \
         a bare ratio to E(0) would be meaningless). A failure names its mode and step; *×N* is \
         1 + max(E − E(0))/scale. Extreme cases run at E = 1e6 Pa, ν = 0.3, h = 1/60 s; a backend whose \
         slivers come from cutting runs the sliver case on a beam it cuts first (`CompareBackend::build_extreme`; \
         virtual node tets: `cleave_registry::sliver_beam`, a crack 1e-5 h from a lattice node plane leaving \
         regions down to 2.0e-15 of a lattice tetrahedron, `crates/cleave-registry/tests/virtualnode_sliver.rs`). \
         *Cut beam* cells (benchmarks.md §5's crack on this beam, for every backend that cuts, \
         `CompareBackend::build_cut_box`): the plane x = 0.5 (a node plane) through the whole width from the \
         top face down to half the depth, applied before the start, at E ∈ {{1e6, 1e12}} Pa, ν ∈ {{0.3, \
         0.4999}}, h = 1/60 s; and the same crack {NEAR_NODE_PLANE_OFFSET:e} h off the node plane, where \
         cutting leaves tiny and sliver pieces (voxel cubes separate across the faces whose dual edges the \
         crack crosses, the same faces as on the node plane; what the virtual node cells meet there: \
         `docs/math/virtual-node.md` §4). Every \
         backend runs \
         with its defaults (for DG the paper's penalty rule); what the ν = 0.4999 row measured before \
         and after the corotated Dirichlet fix is in `docs/math/dg.md` §9. Raw cells: \
         [`stability.csv`](stability.csv).\n",
        beam.max_corner().x,
        beam.max_corner().y,
        beam.max_corner().z,
        beam.dims[0],
        beam.dims[1],
        beam.dims[2],
        100.0 * ENERGY_TOLERANCE
    );
    let _ = writeln!(
        w,
        "{}  \nCommand: `{}` (release build){}.\n",
        machine_line(),
        args.command,
        if kept_sections.is_empty() { "" } else { "; sections of methods it did not run are kept from earlier runs" }
    );
    let mut sections: Vec<(String, String)> = kept_sections;
    for (b, variant) in &methods {
        let name = chosen[*b].name();
        let mut section = String::new();
        let w = &mut section;
        let own: Vec<&CellResult> = results.iter().filter(|r| r.backend == name && r.variant == *variant).collect();
        let passed = own.iter().filter(|r| r.verdict.passed()).count();
        let not_applicable = own.iter().filter(|r| matches!(r.verdict, Verdict::NotApplicable(_))).count();
        let _ = writeln!(
            w,
            "## {name}/{variant}: {passed} pass, {} fail, {not_applicable} not applicable (of {} cells)\n",
            own.len() - passed - not_applicable,
            own.len()
        );
        let _ = write!(w, "| E [Pa] | ν |");
        for h in TIME_STEPS {
            let _ = write!(w, " h = {} s |", h_label(h));
        }
        let _ = writeln!(w, "\n|---|---|{}", "---|".repeat(TIME_STEPS.len()));
        for e in YOUNGS_MODULI {
            for nu in POISSON_RATIOS {
                let _ = write!(w, "| {e:e} | {nu} |");
                for h in TIME_STEPS {
                    let text = own
                        .iter()
                        .find(|r| {
                            r.cell.start == Start::Rest
                                && r.cell.youngs_modulus == e
                                && r.cell.poisson_ratio == nu
                                && r.cell.time_step == h
                        })
                        .map_or("—".into(), |r| r.verdict.to_string());
                    let _ = write!(w, " {text} |");
                }
                let _ = writeln!(w);
            }
        }
        let _ = writeln!(w, "\n| extreme case | verdict | steps done | max energy factor | max inverted elements |");
        let _ = writeln!(w, "|---|---|---|---|---|");
        for r in own.iter().filter(|r| matches!(r.cell.start, Start::Extreme(_))) {
            let _ = writeln!(
                w,
                "| {} | {} | {} | {:.4} | {} |",
                r.cell.case(),
                r.verdict,
                r.steps_done,
                r.max_energy_factor,
                r.max_inverted
            );
        }
        let _ = writeln!(w);
        let cut: Vec<&&CellResult> = own.iter().filter(|r| matches!(r.cell.start, Start::Cut(_))).collect();
        if !cut.is_empty() {
            let _ = writeln!(
                w,
                "| cut beam | E [Pa] | ν | h [s] | verdict | steps done | max energy factor | max inverted elements |"
            );
            let _ = writeln!(w, "|---|---|---|---|---|---|---|---|");
            for r in cut {
                let _ = writeln!(
                    w,
                    "| {} | {:e} | {} | {} | {} | {} | {:.4} | {} |",
                    r.cell.case(),
                    r.cell.youngs_modulus,
                    r.cell.poisson_ratio,
                    h_label(r.cell.time_step),
                    r.verdict,
                    r.steps_done,
                    r.max_energy_factor,
                    r.max_inverted
                );
            }
            let _ = writeln!(w);
        }
        sections.push((format!("{name}/{variant}"), section));
    }
    // Registered order, then anything else.
    let order: Vec<String> = cleave_registry::registered()
        .iter()
        .flat_map(|b| b.variants().into_iter().map(|v| format!("{}/{v}", b.name())).collect::<Vec<_>>())
        .collect();
    let rank = |m: &str| order.iter().position(|o| o == m).unwrap_or(order.len());
    sections.sort_by_key(|(m, _)| rank(m));
    for (_, section) in &sections {
        md.push_str(section);
    }
    println!("{md}");
    fs::write(&md_path, &md).with_context(|| format!("writing {}", md_path.display()))?;
    println!("wrote {} and {}", csv_path.display(), md_path.display());
    Ok(())
}

/// The per-method sections of a previous `stability.md`: `(method, text)`, each from its
/// `## method: …` heading to the next heading of that level.
fn previous_sections(path: &Path) -> Vec<(String, String)> {
    let Ok(text) = fs::read_to_string(path) else { return Vec::new() };
    let mut sections: Vec<(String, String)> = Vec::new();
    for line in text.lines() {
        if let Some(heading) = line.strip_prefix("## ") {
            let method = heading.split_once(':').map_or(heading, |(m, _)| m).to_string();
            sections.push((method, String::new()));
        }
        if let Some((_, section)) = sections.last_mut() {
            section.push_str(line);
            section.push('\n');
        }
    }
    sections
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sections_are_split_at_their_headings() {
        let dir = std::env::temp_dir().join(format!("cleave-stability-{}", std::process::id()));
        fs::create_dir_all(&dir).unwrap();
        let path = dir.join("stability.md");
        fs::write(
            &path,
            "# Stability grid\n\nintro\n\n## voxel/trilinear: 60 pass\n\n| a |\n\n## dg/bz-1: 59 pass\n\n| b |\n",
        )
        .unwrap();
        let sections = previous_sections(&path);
        fs::remove_dir_all(&dir).unwrap();
        let names: Vec<&str> = sections.iter().map(|(m, _)| m.as_str()).collect();
        assert_eq!(names, vec!["voxel/trilinear", "dg/bz-1"]);
        assert_eq!(sections[0].1, "## voxel/trilinear: 60 pass\n\n| a |\n\n");
        assert_eq!(sections[1].1, "## dg/bz-1: 59 pass\n\n| b |\n");
    }
}
