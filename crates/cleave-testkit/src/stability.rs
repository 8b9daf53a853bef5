//! The stability suite of `docs/math/benchmarks.md` §4 for any registered backend: a small
//! clamped beam released under gravity for every (E, ν, h) of the grid, plus the extreme start
//! states and the beam cut by a half-depth crack (on a node plane, and 1e-6 h off it), each cell
//! ending in a pass or a named failure.

use crate::compare::{BoxGrid, BuiltProblem, CompareBackend, CutError, DirichletSpec, ExtremeCase, NotApplicable};
use crate::problems::crack;
use cleave_core::{Material, Point3, Real, Vector3};
use cleave_integrator::{Constraints, Integrator, Settings, StepError, StepErrorKind};
use std::fmt;
use std::time::Instant;

/// Young's moduli of the grid [Pa].
pub const YOUNGS_MODULI: [Real; 4] = [1e4, 1e6, 1e9, 1e12];
/// Poisson ratios of the grid.
pub const POISSON_RATIOS: [Real; 5] = [0.0, 0.3, 0.45, 0.49, 0.4999];
/// Time steps of the grid [s].
pub const TIME_STEPS: [Real; 3] = [1e-4, 1.0 / 60.0, 1.0 / 30.0];
/// Density of every cell [kg/m³].
pub const DENSITY: Real = 1000.0;
/// Allowed rise of the total energy, as a fraction of the run's energy scale.
pub const ENERGY_TOLERANCE: Real = 0.01;

/// The beam of every cell: 1 m × 0.25 m × 0.25 m as 8 × 2 × 2 cells, clamped at x = 0.
pub fn beam_grid() -> BoxGrid {
    BoxGrid { origin: Point3::origin(), h: 0.125, dims: [8, 2, 2] }
}

/// Where the crack of a cut cell lies (benchmarks.md §5's crack on the stability beam: the plane
/// at the beam's middle node plane x = 0.5, through the whole width from the top face down to
/// half the depth).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CrackPlacement {
    /// Exactly on the node plane x = 0.5 (cube faces; lattice nodes of the virtual node BCC
    /// lattice).
    OnNodePlane,
    /// At x = 0.5 + [`NEAR_NODE_PLANE_OFFSET`]·h: tiny pieces next to the node plane.
    NearNodePlane,
}

/// Distance of the near-node-plane crack from the node plane, relative to the cell edge.
pub const NEAR_NODE_PLANE_OFFSET: Real = 1e-6;

impl CrackPlacement {
    /// Both placements, in table order.
    pub const ALL: [CrackPlacement; 2] = [CrackPlacement::OnNodePlane, CrackPlacement::NearNodePlane];

    /// The crack on the stability beam `grid`: x = the middle node plane (+ the offset), from
    /// half the depth up through the top, overhanging the box by one cell.
    pub fn surface(self, grid: &BoxGrid) -> cleave_core::CutSurface {
        let offset = match self {
            CrackPlacement::OnNodePlane => 0.0,
            CrackPlacement::NearNodePlane => NEAR_NODE_PLANE_OFFSET,
        };
        let (lo, hi) = (grid.origin, grid.max_corner());
        let x = lo.x + (grid.dims[0] / 2) as Real * grid.h + offset * grid.h;
        crack::half_plane(&lo, &hi, x, 0.5 * (lo.z + hi.z), grid.h)
    }
}

/// What a cell starts from.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Start {
    /// Rest shape, at rest, gravity on.
    Rest,
    /// An extreme state, at rest, gravity on.
    Extreme(ExtremeCase),
    /// The beam cut by the crack (each backend's own cutting), at rest, gravity on.
    Cut(CrackPlacement),
}

/// One cell of the grid.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Cell {
    /// Young's modulus [Pa].
    pub youngs_modulus: Real,
    /// Poisson ratio.
    pub poisson_ratio: Real,
    /// Time step [s].
    pub time_step: Real,
    /// Start state.
    pub start: Start,
}

impl Cell {
    /// Case name for tables and CSV ("grid" or the extreme case).
    pub fn case(&self) -> &'static str {
        match self.start {
            Start::Rest => "grid",
            Start::Extreme(e) => e.key(),
            Start::Cut(CrackPlacement::OnNodePlane) => "cut-on-node-plane",
            Start::Cut(CrackPlacement::NearNodePlane) => "cut-near-node-plane",
        }
    }
}

/// Young's moduli of the cut cells [Pa].
pub const CUT_YOUNGS_MODULI: [Real; 2] = [1e6, 1e12];
/// Poisson ratios of the cut cells.
pub const CUT_POISSON_RATIOS: [Real; 2] = [0.3, 0.4999];
/// Time step of the cut cells [s].
pub const CUT_TIME_STEP: Real = 1.0 / 60.0;

/// The whole §4 grid (E-major, then ν, then h) followed by the three extreme cases at E = 1e6,
/// ν = 0.3, h = 1/60 s, then the cut beam for both crack placements at E ∈ [`CUT_YOUNGS_MODULI`],
/// ν ∈ [`CUT_POISSON_RATIOS`], h = 1/60 s.
pub fn cells() -> Vec<Cell> {
    let mut cells = Vec::new();
    for youngs_modulus in YOUNGS_MODULI {
        for poisson_ratio in POISSON_RATIOS {
            for time_step in TIME_STEPS {
                cells.push(Cell { youngs_modulus, poisson_ratio, time_step, start: Start::Rest });
            }
        }
    }
    for case in ExtremeCase::ALL {
        cells.push(Cell {
            youngs_modulus: 1e6,
            poisson_ratio: 0.3,
            time_step: 1.0 / 60.0,
            start: Start::Extreme(case),
        });
    }
    for placement in CrackPlacement::ALL {
        for youngs_modulus in CUT_YOUNGS_MODULI {
            for poisson_ratio in CUT_POISSON_RATIOS {
                cells.push(Cell {
                    youngs_modulus,
                    poisson_ratio,
                    time_step: CUT_TIME_STEP,
                    start: Start::Cut(placement),
                });
            }
        }
    }
    cells
}

/// How a cell ended.
#[derive(Clone, Debug, PartialEq)]
pub enum Verdict {
    /// Finished, finite, energy bounded, solver converged.
    Pass,
    /// The backend cannot express the case (with the reason).
    NotApplicable(String),
    /// NaN or infinity at a step.
    NotFinite {
        /// 0-based step
        step: u64,
    },
    /// The total energy rose above its start by more than the tolerance.
    EnergyGrowth {
        /// `1 + ΔE / scale` at its maximum
        factor: Real,
        /// first offending step (0-based)
        step: u64,
    },
    /// CG hit its iteration limit or Cholesky met a non-positive pivot.
    SolverFailed {
        /// 0-based step
        step: u64,
        /// the solver's message
        message: String,
    },
    /// Nodes ran away past the divergence limit.
    Diverged {
        /// 0-based step
        step: u64,
        /// how far [m]
        distance: Real,
    },
    /// Building or another error, with its text.
    Error(String),
}

impl Verdict {
    /// Whether the cell passed.
    pub fn passed(&self) -> bool {
        *self == Verdict::Pass
    }
}

impl fmt::Display for Verdict {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Verdict::Pass => write!(f, "pass"),
            Verdict::NotApplicable(why) => write!(f, "not applicable: {why}"),
            Verdict::NotFinite { step } => write!(f, "NaN at step {step}"),
            Verdict::EnergyGrowth { factor, step } => write!(f, "energy growth ×{factor:.3} at step {step}"),
            Verdict::SolverFailed { step, message } => write!(f, "solver failed at step {step}: {message}"),
            Verdict::Diverged { step, distance } => {
                write!(f, "diverged at step {step} (a node moved {distance:.2e} m)")
            }
            Verdict::Error(message) => write!(f, "error: {message}"),
        }
    }
}

/// The result of one cell.
#[derive(Clone, Debug)]
pub struct CellResult {
    /// The cell.
    pub cell: Cell,
    /// Backend name.
    pub backend: String,
    /// Variant.
    pub variant: String,
    /// Pass or the failure.
    pub verdict: Verdict,
    /// Steps completed.
    pub steps_done: u64,
    /// Largest `1 + (E(t) − E(0)) / scale` seen (1 or less = no growth).
    pub max_energy_factor: Real,
    /// Largest number of inverted elements seen.
    pub max_inverted: usize,
    /// Wall clock [s].
    pub seconds: Real,
}

/// CSV header of the stability results.
pub const CSV_HEADER: &str = "backend,variant,case,youngs_modulus,poisson_ratio,time_step,steps,steps_done,passed,verdict,max_energy_factor,max_inverted,seconds";

impl CellResult {
    /// One CSV line (the verdict text has its commas replaced by semicolons).
    pub fn to_csv(&self, steps: usize) -> String {
        format!(
            "{},{},{},{:e},{},{:.9e},{},{},{},{},{:.6e},{},{:.4e}",
            self.backend,
            self.variant,
            self.cell.case(),
            self.cell.youngs_modulus,
            self.cell.poisson_ratio,
            self.cell.time_step,
            steps,
            self.steps_done,
            self.verdict.passed(),
            self.verdict.to_string().replace(',', ";"),
            self.max_energy_factor,
            self.max_inverted,
            self.seconds
        )
    }
}

fn step_failure(error: StepError) -> Verdict {
    let step = error.step;
    match error.kind {
        StepErrorKind::NotFinite { .. } => Verdict::NotFinite { step },
        StepErrorKind::Diverged { distance, .. } => Verdict::Diverged { step, distance },
        kind @ (StepErrorKind::CgNotConverged { .. }
        | StepErrorKind::NotPositiveDefinite { .. }
        | StepErrorKind::Solver(_)) => Verdict::SolverFailed { step, message: kind.to_string() },
        // Malformed input (a registration's bug), not a property of the cell.
        kind @ (StepErrorKind::LoadLength { .. }
        | StepErrorKind::DofOutOfRange { .. }
        | StepErrorKind::NodeOutOfRange { .. }
        | StepErrorKind::PinTargets { .. }
        | StepErrorKind::SurfacePieces { .. }
        | StepErrorKind::SingularBody { .. }
        | StepErrorKind::OverlappingBodies { .. }) => Verdict::Error(kind.to_string()),
    }
}

/// Runs one cell for `steps` steps. The total energy is kinetic + elastic + gravitational, the
/// latter measured from the start so that the datum cancels; the cell fails when
/// `E(t) − E(0) > 1% · scale`, with `scale` the largest of |E(0)|, kinetic + elastic and the
/// gravitational work over the run (the energy that was in play).
pub fn run_cell(backend: &dyn CompareBackend, variant: &str, cell: Cell, steps: usize) -> CellResult {
    let clock = Instant::now();
    let mut result = CellResult {
        cell,
        backend: backend.name().into(),
        variant: variant.into(),
        verdict: Verdict::Pass,
        steps_done: 0,
        max_energy_factor: 1.0,
        max_inverted: 0,
        seconds: 0.0,
    };
    let verdict = run_cell_inner(backend, variant, cell, steps, &mut result);
    result.verdict = verdict;
    result.seconds = clock.elapsed().as_secs_f64();
    result
}

fn run_cell_inner(
    backend: &dyn CompareBackend,
    variant: &str,
    cell: Cell,
    steps: usize,
    result: &mut CellResult,
) -> Verdict {
    let material = match Material::new(cell.youngs_modulus, cell.poisson_ratio, DENSITY) {
        Ok(m) => m,
        Err(e) => return Verdict::Error(e.to_string()),
    };
    let grid = beam_grid();
    let clamped = |p: &Point3<Real>| p.x.abs() < 1e-9;
    let dirichlet = DirichletSpec { region: &clamped, value: &|_| Vector3::zeros() };
    let extreme: Result<Option<BuiltProblem>, crate::compare::BuildError> = match cell.start {
        Start::Rest => Ok(None),
        Start::Extreme(case) => backend.build_extreme(variant, case, &material, &grid, &dirichlet),
        Start::Cut(placement) => {
            if !backend.cuts(variant) {
                return Verdict::NotApplicable("cannot cut".into());
            }
            match backend.build_cut_box(variant, &material, &grid, &dirichlet, &placement.surface(&grid)) {
                Ok(cut) => Ok(Some(cut.built)),
                Err(CutError::CannotCut(why)) => return Verdict::NotApplicable(why),
                Err(CutError::Build(why)) => return Verdict::Error(why),
            }
        }
    };
    let built =
        match extreme.and_then(|b| b.map_or_else(|| backend.build_box(variant, &material, &grid, &dirichlet), Ok)) {
            Ok(b) => b,
            Err(e) => return Verdict::Error(e.to_string()),
        };
    let start = match cell.start {
        Start::Rest | Start::Cut(_) => None,
        Start::Extreme(case) => match backend.extreme_start(variant, case, &built, &grid) {
            Ok(x) => Some(x),
            Err(NotApplicable(why)) => return Verdict::NotApplicable(why),
        },
    };
    let d = built.discretization.as_ref();
    let mut settings = Settings::new(cell.time_step);
    settings.solver = backend.dynamic_solver(variant);
    let constraints = Constraints {
        pinned_dofs: built.prescribed.iter().map(|&(dof, _)| dof).collect(),
        extra_load: built.dirichlet_load.clone(),
        ..Default::default()
    };
    let mut integrator = match Integrator::new(d, settings, constraints) {
        Ok(i) => i,
        Err(e) => return step_failure(e),
    };
    if let Some(x) = start {
        if x.len() != d.rest_dofs().len() {
            return Verdict::Error(format!(
                "extreme start has {} DOFs, the discretization {}",
                x.len(),
                d.rest_dofs().len()
            ));
        }
        let v = vec![0.0; x.len()];
        integrator.set_state(d, x, v);
    }
    let first = integrator.energies(d);
    if !first.total_energy().is_finite() {
        return Verdict::NotFinite { step: 0 };
    }
    result.max_inverted = first.inverted_elements;
    let gravity0 = first.gravitational_energy;
    let e0 = first.kinetic_energy + first.elastic_energy;
    let mut scale = e0.abs();
    // (step, E(t) − E(0)) per step, judged against the scale of the whole run afterwards.
    let mut rises = Vec::with_capacity(steps);
    let mut failure = None;
    for _ in 0..steps {
        match integrator.step(d) {
            Ok(report) => {
                let work = report.gravitational_energy - gravity0;
                let total = report.kinetic_energy + report.elastic_energy + work;
                if !total.is_finite() {
                    failure = Some(Verdict::NotFinite { step: report.step });
                    break;
                }
                scale = scale.max(report.kinetic_energy + report.elastic_energy).max(work.abs());
                rises.push((report.step, total - e0));
                result.max_inverted = result.max_inverted.max(report.inverted_elements);
                result.steps_done += 1;
            }
            Err(e) => {
                failure = Some(step_failure(e));
                break;
            }
        }
    }
    if scale > 0.0 {
        result.max_energy_factor = rises.iter().map(|&(_, rise)| 1.0 + rise / scale).fold(1.0, Real::max);
    }
    if let Some(f) = failure {
        return f;
    }
    match rises.iter().find(|&&(_, rise)| rise > ENERGY_TOLERANCE * scale) {
        Some(&(step, _)) => Verdict::EnergyGrowth { factor: result.max_energy_factor, step },
        None => Verdict::Pass,
    }
}
