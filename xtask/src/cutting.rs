//! The cutting study of `cargo xtask compare`: the whole timeline of `scenes/bunny_slice.ron`
//! (its blade path and its two planes) run through `cleave_scene::Simulation` on every selected
//! backend whose registration says it can cut, without recording; one row per backend in
//! `cutting.csv` (kept for backends an invocation does not rerun) and the "Cutting" table of
//! `compare.md`.

use anyhow::{Context, Result, bail};
use cleave_scene::{Simulation, load_scene};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// The scene whose timeline the table measures, relative to the workspace root.
pub const SCENE: &str = "scenes/bunny_slice.ron";

/// The scene's path (the workspace root is the xtask crate's parent).
pub fn scene_path() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..").join(SCENE)
}

/// One backend's run of the scene's timeline.
#[derive(Clone, Debug, PartialEq)]
pub struct CutRow {
    /// Backend name.
    pub backend: String,
    /// Characteristic element size [m].
    pub element_size: f64,
    /// Elements before and after.
    pub elements: (usize, usize),
    /// Nodes before and after.
    pub nodes: (usize, usize),
    /// Pieces at the end.
    pub pieces: usize,
    /// Topology changes applied.
    pub changes: usize,
    /// Mean milliseconds per topology change (cut and rebuild).
    pub ms_per_change: f64,
    /// Relative volume and mass drift over the run.
    pub volume_drift: f64,
    /// Relative mass drift.
    pub mass_drift: f64,
    /// Steps per second in the steps that cut, and in the others (no recording).
    pub steps_per_second: (f64, f64),
    /// Steps that cut, and the others.
    pub steps: (usize, usize),
}

/// CSV header of `cutting.csv`.
pub const CSV_HEADER: &str = "backend,element_size,elements_before,elements_after,nodes_before,nodes_after,pieces,changes,ms_per_change,volume_drift,mass_drift,cut_steps,cut_steps_per_second,other_steps,other_steps_per_second";

impl CutRow {
    /// One CSV line.
    pub fn to_csv(&self) -> String {
        format!(
            "{},{:.9e},{},{},{},{},{},{},{:.6e},{:.6e},{:.6e},{},{:.6e},{},{:.6e}",
            self.backend,
            self.element_size,
            self.elements.0,
            self.elements.1,
            self.nodes.0,
            self.nodes.1,
            self.pieces,
            self.changes,
            self.ms_per_change,
            self.volume_drift,
            self.mass_drift,
            self.steps.0,
            self.steps_per_second.0,
            self.steps.1,
            self.steps_per_second.1
        )
    }

    /// Parses a line of [`CutRow::to_csv`]; the error names the column.
    pub fn from_csv(line: &str) -> Result<CutRow, String> {
        let f: Vec<&str> = line.trim_end().split(',').collect();
        let columns = CSV_HEADER.split(',').count();
        if f.len() != columns {
            return Err(format!("expected {columns} columns, found {}: {line}", f.len()));
        }
        let name = |i: usize| CSV_HEADER.split(',').nth(i).unwrap_or("?");
        let int = |i: usize| f[i].parse::<usize>().map_err(|e| format!("column {}: {e} in {:?}", name(i), f[i]));
        let real = |i: usize| f[i].parse::<f64>().map_err(|e| format!("column {}: {e} in {:?}", name(i), f[i]));
        Ok(CutRow {
            backend: f[0].to_string(),
            element_size: real(1)?,
            elements: (int(2)?, int(3)?),
            nodes: (int(4)?, int(5)?),
            pieces: int(6)?,
            changes: int(7)?,
            ms_per_change: real(8)?,
            volume_drift: real(9)?,
            mass_drift: real(10)?,
            steps: (int(11)?, int(13)?),
            steps_per_second: (real(12)?, real(14)?),
        })
    }
}

/// Rows of `path` (none if it is missing or unreadable: they are regenerated).
pub fn read_rows(path: &Path) -> Vec<CutRow> {
    let Ok(text) = std::fs::read_to_string(path) else { return Vec::new() };
    let mut lines = text.lines();
    if lines.next().map(str::trim_end) != Some(CSV_HEADER) {
        return Vec::new();
    }
    lines.filter(|l| !l.trim().is_empty()).filter_map(|l| CutRow::from_csv(l).ok()).collect()
}

/// Writes `rows` to `path` under the header.
pub fn write_rows(path: &Path, rows: &[CutRow]) -> Result<()> {
    let mut text = format!("{CSV_HEADER}\n");
    for r in rows {
        text.push_str(&r.to_csv());
        text.push('\n');
    }
    std::fs::write(path, text).with_context(|| format!("writing {}", path.display()))
}

/// Runs the scene's whole timeline on `backend` (no recording) and measures it.
pub fn run(backend: &str) -> Result<CutRow> {
    let path = scene_path();
    let loaded = load_scene(&path)?;
    let mut simulation = Simulation::build_with_backend(&loaded, None, Some(backend))?;
    // Every change paid in its own step: the serial cost of a topology change, per backend.
    simulation.set_cut_ahead(false);
    let before = simulation.cut_summary().clone();
    let element_size = simulation.info().element_size;
    let total = simulation.total_steps();
    // (wall, steps) of the steps without and with a topology change.
    let mut walls = [(0.0f64, 0usize); 2];
    while simulation.steps_done() < total {
        let changes = simulation.cut_summary().changes;
        let clock = Instant::now();
        simulation.step().with_context(|| format!("{} on {backend}", path.display()))?;
        let bucket = usize::from(simulation.cut_summary().changes > changes);
        walls[bucket].0 += clock.elapsed().as_secs_f64();
        walls[bucket].1 += 1;
    }
    let after = simulation.cut_summary().clone();
    if after.changes == 0 {
        bail!("{} on {backend}: the timeline changed no topology", path.display());
    }
    let (volume_drift, mass_drift) = after.drift();
    let rate = |(wall, steps): (f64, usize)| if steps > 0 { steps as f64 / wall.max(1e-12) } else { f64::NAN };
    Ok(CutRow {
        backend: backend.to_string(),
        element_size,
        elements: (before.elements, after.elements),
        nodes: (before.nodes, after.nodes),
        pieces: after.pieces.len(),
        changes: after.changes,
        ms_per_change: 1e3 * after.seconds / after.changes as f64,
        volume_drift,
        mass_drift,
        steps: (walls[1].1, walls[0].1),
        steps_per_second: (rate(walls[1]), rate(walls[0])),
    })
}

/// The "Cutting" section of `compare.md`: one row per backend that has one, in `order`, and the
/// registered backends that cannot cut yet.
pub fn section(rows: &[CutRow], order: &[String], cannot_cut: &[String], errors: &[(String, String)]) -> String {
    let mut md = String::new();
    let w = &mut md;
    let _ = writeln!(w, "## Cutting\n");
    let _ = writeln!(
        w,
        "The whole timeline of [`{SCENE}`](../../{SCENE}) (a horizontal plane at 0.25 s, a blade path \
         sweeping down through the bunny between 0.5 s and 1.5 s, then a plane at 1.8 s and one at 2.1 s \
         crossing the earlier cuts; contact between the pieces; 240 steps of 1/60 s) run through \
         `cleave_scene::Simulation` on every registered backend whose capabilities include cutting, with \
         the scene's settings for that backend and no recording (`xtask/src/cutting.rs`). *ms per change* \
         is the mean wall clock of a topology change: the backend's cut, the integrator's rebuild, pins, \
         contact rows and surface (with surface contact the pattern and symbolic factorization are built \
         by the next step, with its contacts, and count in that step's time); each cut is made when it is due \
         (`cargo xtask run` makes a timeline `Cut` ahead on a copy of the body while the steps before it run: \
         not measured here). Drifts are relative to the start. Steps per second are measured in the steps that \
         cut and in the others separately. Raw rows: [`cutting.csv`](cutting.csv), one per backend, kept \
         for backends a later invocation does not rerun.\n"
    );
    let _ = writeln!(
        w,
        "| backend | h [m] | elements before → after | nodes before → after | pieces | topology changes | ms per change (mean) | volume drift | mass drift | steps/s while cutting | steps/s otherwise |"
    );
    let _ = writeln!(w, "|---|---|---|---|---|---|---|---|---|---|---|");
    let mut ordered: Vec<&CutRow> = Vec::new();
    for name in order {
        ordered.extend(rows.iter().filter(|r| &r.backend == name));
    }
    ordered.extend(rows.iter().filter(|r| !order.contains(&r.backend)));
    for r in ordered {
        let _ = writeln!(
            w,
            "| {} | {:.4} | {} → {} | {} → {} | {} | {} | {:.1} | {:.1e} | {:.1e} | {:.1} ({} steps) | {:.1} ({} steps) |",
            r.backend,
            r.element_size,
            r.elements.0,
            r.elements.1,
            r.nodes.0,
            r.nodes.1,
            r.pieces,
            r.changes,
            r.ms_per_change,
            r.volume_drift,
            r.mass_drift,
            r.steps_per_second.0,
            r.steps.0,
            r.steps_per_second.1,
            r.steps.1
        );
    }
    if rows.is_empty() {
        let _ = writeln!(w, "| (no backend has run the timeline yet: `--problem cutting`) | | | | | | | | | | |");
    }
    let _ = writeln!(w);
    for (backend, error) in errors {
        let _ = writeln!(w, "- {backend}: failed: {}", error.replace('\n', " "));
    }
    if !errors.is_empty() {
        let _ = writeln!(w);
    }
    if !cannot_cut.is_empty() {
        let _ = writeln!(w, "Registered backends that cannot cut yet: {}.\n", cannot_cut.join(", "));
    }
    md
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_row_round_trips_through_its_csv_line() {
        let row = CutRow {
            backend: "virtualnode".into(),
            element_size: 0.02,
            elements: (3518, 4744),
            nodes: (894, 1539),
            pieces: 6,
            changes: 26,
            ms_per_change: 85.5,
            volume_drift: 1.8e-15,
            mass_drift: -1.7e-15,
            steps_per_second: (9.2, 42.1),
            steps: (26, 214),
        };
        let line = row.to_csv();
        assert_eq!(line.split(',').count(), CSV_HEADER.split(',').count());
        assert_eq!(CutRow::from_csv(&line).unwrap(), row);
        let error = CutRow::from_csv("virtualnode,0.02,x,1,1,1,1,1,1,1,1,1,1,1,1").unwrap_err();
        assert!(error.contains("elements_before"), "{error}");
    }
}
