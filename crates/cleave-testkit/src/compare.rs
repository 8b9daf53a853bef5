//! The backend-neutral half of `cargo xtask compare`: how a backend registers
//! ([`CompareBackend`]), the benchmark problems of `docs/math/benchmarks.md` §1–§3 and §5 run
//! through the trait ([`run_problem`]), the refinement study under a time budget ([`run_study`]),
//! CSV rows, observed rates and the Richardson references of the cantilever and of the cut
//! cantilever. No file or terminal I/O: xtask writes what these functions return.

use crate::problems::{Manufactured, cantilever, crack, field_errors, on_unit_cube_boundary};
use cleave_core::{CutSurface, Discretization, Material, Point3, Real, TopologyChange, Vector3};
use cleave_integrator::{Constraints, Integrator, Settings, Solver, StepErrorKind, solve_static};
use std::fmt;
use std::time::Instant;

/// A box of equal cells: `dims` cells of edge `h` from `origin`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BoxGrid {
    /// Minimum corner.
    pub origin: Point3<Real>,
    /// Cell edge [m].
    pub h: Real,
    /// Cells along x, y, z.
    pub dims: [usize; 3],
}

impl BoxGrid {
    /// The maximum corner.
    pub fn max_corner(&self) -> Point3<Real> {
        self.origin + Vector3::new(self.dims[0] as Real, self.dims[1] as Real, self.dims[2] as Real) * self.h
    }
}

/// Dirichlet data known when the discretization is built: a boundary point `p` is on the
/// Dirichlet part iff `region(p)`, where `u = value(p)`. Nodal backends pin the nodes in the
/// region; weak (DG) backends test boundary faces (e.g. their centroids) and integrate `value`.
pub struct DirichletSpec<'a> {
    /// Is this boundary point on the Dirichlet part?
    pub region: &'a (dyn Fn(&Point3<Real>) -> bool + Sync),
    /// The prescribed displacement there.
    pub value: &'a (dyn Fn(&Point3<Real>) -> Vector3<Real> + Sync),
}

impl DirichletSpec<'_> {
    /// No Dirichlet boundary at all.
    pub fn none() -> DirichletSpec<'static> {
        fn nowhere(_: &Point3<Real>) -> bool {
            false
        }
        fn zero(_: &Point3<Real>) -> Vector3<Real> {
            Vector3::zeros()
        }
        DirichletSpec { region: &nowhere, value: &zero }
    }
}

/// A discretization built for one run, with its boundary conditions in the form the solvers use.
pub struct BuiltProblem {
    /// The discretization.
    pub discretization: Box<dyn Discretization>,
    /// Strongly imposed DOF values `(scalar DOF, value)`: eliminated by the solvers.
    pub prescribed: Vec<(usize, Real)>,
    /// Weakly imposed data as a load vector (the `g` terms of Nitsche/interior-penalty boundary
    /// integrals), added to the right-hand side; empty when there is none.
    pub dirichlet_load: Vec<Real>,
    /// Number of elements (cells, tets, polyhedra).
    pub elements: usize,
    /// Seconds of `build_box` spent on a backend-specific search rather than on integrals (DG's
    /// penalty doubling), so Table 1 can report integration on its own; 0 when there is none.
    pub search_seconds: Real,
}

/// A backend that could not build a problem, with the backend's own message.
#[derive(Clone, Debug, PartialEq)]
pub struct BuildError(pub String);

impl fmt::Display for BuildError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for BuildError {}

/// The extreme start states of the stability suite (benchmarks.md §4).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ExtremeCase {
    /// One element inverted: a node pushed through its opposite face.
    PreInverted,
    /// An element of volume 1e-9 of its neighbours'.
    Sliver,
    /// The body stretched 100× along x (from the clamped face) and released at once.
    Stretch100,
}

impl ExtremeCase {
    /// All three, in table order.
    pub const ALL: [ExtremeCase; 3] = [ExtremeCase::PreInverted, ExtremeCase::Sliver, ExtremeCase::Stretch100];

    /// Short name for tables and CSV.
    pub fn key(self) -> &'static str {
        match self {
            ExtremeCase::PreInverted => "pre-inverted",
            ExtremeCase::Sliver => "sliver",
            ExtremeCase::Stretch100 => "stretch-100x",
        }
    }
}

/// Why a backend cannot run an extreme case (printed in the stability table).
#[derive(Clone, Debug, PartialEq)]
pub struct NotApplicable(pub String);

/// A built problem for a nodal backend: Dirichlet data pinned at the nodes in its region.
pub fn nodal_problem(
    discretization: Box<dyn Discretization>,
    elements: usize,
    dirichlet: &DirichletSpec,
) -> BuiltProblem {
    let prescribed = crate::problems::nodal_dirichlet(discretization.as_ref(), dirichlet.region, dirichlet.value);
    BuiltProblem { discretization, prescribed, dirichlet_load: Vec::new(), elements, search_seconds: 0.0 }
}

/// The pre-inverted start of a nodal backend: the node at the box's outer corner (x, y, z
/// maximal) moved by 1.5 h inwards along every axis, through the faces of the elements around it
/// (for a cube, F at its centre is I − (9/8)·(1,1,1)⊗(1,1,1)/3 with det F = −1/8).
pub fn corner_pushed_in(built: &BuiltProblem, grid: &BoxGrid) -> Result<Vec<Real>, NotApplicable> {
    let rest = built.discretization.rest_dofs();
    let corner = grid.max_corner();
    let node = rest
        .chunks_exact(3)
        .position(|p| (0..3).all(|a| (p[a] - corner[a]).abs() < 1e-9 * grid.h.max(1.0)))
        .ok_or_else(|| NotApplicable("no node at the outer corner of the box".into()))?;
    let mut x = rest.to_vec();
    for a in 0..3 {
        x[3 * node + a] -= 1.5 * grid.h;
    }
    Ok(x)
}

/// The 100× stretch along x from the clamped face: the linear map on every coefficient of the
/// rest DOFs, the translation through the backend (non-nodal bases carry it on their constant
/// functions only), so it is exact for every backend.
pub fn stretch_start(built: &BuiltProblem, grid: &BoxGrid) -> Vec<Real> {
    let d = built.discretization.as_ref();
    let mut x: Vec<Real> = d.rest_dofs().chunks_exact(3).flat_map(|p| [100.0 * p[0], p[1], p[2]]).collect();
    d.add_translation(&Vector3::new(-99.0 * grid.origin.x, 0.0, 0.0), &mut x);
    x
}

/// A box built and then cut by a backend's own cutting ([`CompareBackend::build_cut_box`]).
pub struct CutProblem {
    /// The cut discretization with its Dirichlet data resolved again on it.
    pub built: BuiltProblem,
    /// The change from the uncut box of [`CompareBackend::build_box`] (same arguments) to it:
    /// what a run that cuts between steps hands the integrator.
    pub change: TopologyChange,
}

/// Why a backend did not build a cut box.
#[derive(Clone, Debug, PartialEq)]
pub enum CutError {
    /// The backend cannot make this cut (no cutting at all, or a cut off its cube faces).
    CannotCut(String),
    /// Building or cutting failed.
    Build(String),
}

impl fmt::Display for CutError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            CutError::CannotCut(why) => write!(f, "cannot cut: {why}"),
            CutError::Build(why) => f.write_str(why),
        }
    }
}

impl std::error::Error for CutError {}

impl From<CutError> for RunError {
    fn from(e: CutError) -> Self {
        RunError::Build(BuildError(e.to_string()))
    }
}

/// One registration of a backend with the comparison harness. Adding a backend to `cargo xtask
/// compare` and `cargo xtask stability` is one `impl` of this trait plus one line in
/// `cleave_registry::backends()`.
pub trait CompareBackend: Send + Sync {
    /// Backend name as in `--backend` ("voxel", "dg").
    fn name(&self) -> &str;

    /// Variants compared separately ("trilinear"; "bz-1", "ip-2", …).
    fn variants(&self) -> Vec<String>;

    /// Builds the box `grid` of one material with the Dirichlet data `dirichlet`.
    fn build_box(
        &self,
        variant: &str,
        material: &Material,
        grid: &BoxGrid,
        dirichlet: &DirichletSpec,
    ) -> Result<BuiltProblem, BuildError>;

    /// Whether `variant` is consistent: an exact solution satisfies its discrete equations, so
    /// it converges to the exact answer and may serve as a reference (DG's Babuška–Zlámal flux
    /// is not).
    fn is_consistent(&self, _variant: &str) -> bool {
        true
    }

    /// The linear solver of time-stepping runs (dynamic beam, stability grid).
    fn dynamic_solver(&self, _variant: &str) -> Solver {
        Solver::Cholesky
    }

    /// The problem an extreme case starts on, when it is not the box of [`build_box`]: e.g. the
    /// sliver case of a backend whose slivers come from cutting builds the box and cuts it first.
    /// `Ok(None)` (the default) means the box of `build_box`. [`extreme_start`] then receives
    /// what this built.
    ///
    /// [`build_box`]: CompareBackend::build_box
    /// [`extreme_start`]: CompareBackend::extreme_start
    fn build_extreme(
        &self,
        _variant: &str,
        _case: ExtremeCase,
        _material: &Material,
        _grid: &BoxGrid,
        _dirichlet: &DirichletSpec,
    ) -> Result<Option<BuiltProblem>, BuildError> {
        Ok(None)
    }

    /// Whether `variant` can run the cut problems (the cut cantilever, the dynamic cut, the cut
    /// cells of the stability grid) through [`CompareBackend::build_cut_box`].
    fn cuts(&self, _variant: &str) -> bool {
        false
    }

    /// The box of [`build_box`] cut by `surface` (rest space) with the backend's own cutting, its
    /// Dirichlet data resolved again on the cut discretization, and the topology change from the
    /// uncut box. The default cannot cut.
    ///
    /// [`build_box`]: CompareBackend::build_box
    fn build_cut_box(
        &self,
        _variant: &str,
        _material: &Material,
        _grid: &BoxGrid,
        _dirichlet: &DirichletSpec,
        _surface: &CutSurface,
    ) -> Result<CutProblem, CutError> {
        Err(CutError::CannotCut(format!("{} has no cutting", self.name())))
    }

    /// The start positions of an extreme case for a problem built from `grid` (whose x = min
    /// face is clamped). The default handles the stretch (the linear map on every coefficient of
    /// the rest DOFs plus `add_translation`, exact for every backend) and declines the others.
    fn extreme_start(
        &self,
        _variant: &str,
        case: ExtremeCase,
        built: &BuiltProblem,
        grid: &BoxGrid,
    ) -> Result<Vec<Real>, NotApplicable> {
        match case {
            ExtremeCase::Stretch100 => Ok(stretch_start(built, grid)),
            _ => Err(NotApplicable("not implemented by this backend's registration".into())),
        }
    }
}

/// The benchmark problems a study runs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Problem {
    /// §1 `sin111` on the unit cube, u = 0 on the boundary.
    MmsSin111,
    /// §1 `cos123`, inhomogeneous Dirichlet data on the whole boundary.
    MmsCos123,
    /// §2 static cantilever, ν = 0.3.
    Cantilever,
    /// §3 dynamic beam.
    Dynamic,
    /// §5 static cantilever cut by the half-plane crack (backends that cut only).
    CutCantilever,
    /// §3's dynamic beam cut by §5's crack at t = 1 s, run to t = 4 s (backends that cut only).
    CutDynamic,
}

impl Problem {
    /// Every problem, in report order.
    pub const ALL: [Problem; 6] = [
        Problem::MmsSin111,
        Problem::MmsCos123,
        Problem::Cantilever,
        Problem::Dynamic,
        Problem::CutCantilever,
        Problem::CutDynamic,
    ];

    /// Name in the CSV `problem` column.
    pub fn key(self) -> &'static str {
        match self {
            Problem::MmsSin111 => "mms-sin111",
            Problem::MmsCos123 => "mms-cos123",
            Problem::Cantilever => "cantilever",
            Problem::Dynamic => "dynamic",
            Problem::CutCantilever => "cut-cantilever",
            Problem::CutDynamic => "cut-dynamic",
        }
    }

    /// The problem named `key`.
    pub fn from_key(key: &str) -> Option<Problem> {
        Problem::ALL.into_iter().find(|p| p.key() == key)
    }

    /// Whether only backends that cut run it.
    pub fn needs_cutting(self) -> bool {
        matches!(self, Problem::CutCantilever | Problem::CutDynamic)
    }

    /// Refinement levels n (h = 1/n): MMS from 2, the beams from 1, the cut beams from 2 (their
    /// crack front z = 0.5 lies on cube faces and lattice node planes for even n only).
    pub fn sizes(self) -> Vec<usize> {
        let first = match self {
            Problem::MmsSin111 | Problem::MmsCos123 | Problem::CutCantilever | Problem::CutDynamic => 2,
            Problem::Cantilever | Problem::Dynamic => 1,
        };
        (0..8).map(|k| first << k).collect()
    }

    /// The grid of refinement level `n`.
    pub fn grid(self, n: usize) -> BoxGrid {
        let dims = match self {
            Problem::MmsSin111 | Problem::MmsCos123 => [n, n, n],
            Problem::Cantilever | Problem::Dynamic | Problem::CutCantilever | Problem::CutDynamic => [4 * n, n, n],
        };
        BoxGrid { origin: Point3::origin(), h: 1.0 / n as Real, dims }
    }
}

/// Young's modulus of the dynamic beam [Pa] (benchmarks.md §3); the static cantilever has 1e6.
pub const DYNAMIC_YOUNGS_MODULUS: Real = 1e8;

/// The dynamic beam's final tip against the same method's static deflection on the same mesh,
/// scaled by the ratio of Young's moduli (the static problem is linear): `(dyn − s·stat) / (s·stat)`
/// with `s = E_static / E_dynamic`. A run that has settled lands on its own static answer; a
/// defect in the corotated forces (a lever arm to the origin, a ghost force) shows here.
/// The dynamic beam is checked against the static cantilever, the cut dynamic beam against the
/// cut cantilever.
pub fn self_consistency(dynamic: &Row, rows: &[Row]) -> Option<Real> {
    let static_problem =
        if dynamic.problem == Problem::CutDynamic.key() { Problem::CutCantilever } else { Problem::Cantilever };
    let statics = rows
        .iter()
        .find(|r| r.problem == static_problem.key() && r.method() == dynamic.method() && r.n == dynamic.n)?;
    let scaled = statics.tip_uz_avg? * crate::problems::cantilever::YOUNGS_MODULUS / DYNAMIC_YOUNGS_MODULUS;
    Some((dynamic.tip_uz_avg? - scaled) / scaled)
}

/// Steps and step size of the dynamic beam (benchmarks.md §3).
pub const DYNAMIC_STEPS: usize = 120;
/// Steps of the cut dynamic beam: cut after [`CUT_DYNAMIC_CUT_STEP`] steps (t = 1 s), run to
/// t = 4 s.
pub const CUT_DYNAMIC_STEPS: usize = 240;
/// Steps before the cut of the cut dynamic beam.
pub const CUT_DYNAMIC_CUT_STEP: usize = 60;
/// Time step of the dynamic beam [s].
pub const DYNAMIC_TIME_STEP: Real = 1.0 / 60.0;

/// One run of one problem: a CSV row. `None` = not applicable (an empty CSV cell).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Row {
    /// [`Problem::key`].
    pub problem: String,
    /// Backend name.
    pub backend: String,
    /// Variant name.
    pub variant: String,
    /// Refinement level (h = 1/n).
    pub n: usize,
    /// Scalar DOFs.
    pub dofs: usize,
    /// Elements.
    pub elements: usize,
    /// Stored nonzeros of the assembled matrix.
    pub nnz: Option<usize>,
    /// Relative L2 error (MMS).
    pub l2_rel_error: Option<Real>,
    /// Relative H1 seminorm error (MMS).
    pub h1_rel_error: Option<Real>,
    /// Mean u_z over the face x = 4 [m] (beams; the dynamic beam at the last step).
    pub tip_uz_avg: Option<Real>,
    /// u_z at (4, 0.5, 0.5) [m].
    pub tip_uz_point: Option<Real>,
    /// Strain energy ½ fᵀu [J] (static problems).
    pub strain_energy: Option<Real>,
    /// Building the discretization, loads and Dirichlet data, pattern and symbolic factorization
    /// (dynamic: building the discretization and the integrator) [s].
    pub seconds_setup: Option<Real>,
    /// Assembling matrix values (dynamic: forces and matrices over all steps) [s].
    pub seconds_assemble: Option<Real>,
    /// Numeric factorization and solve (dynamic: over all steps) [s].
    pub seconds_solve: Option<Real>,
    /// Wall clock of the whole run, error evaluation excluded [s].
    pub seconds_total: Option<Real>,
    /// Peak resident memory of the run [MB] (filled by the caller that can measure it).
    pub peak_rss_mb: Option<Real>,
    /// Repetitions the timings are the median of.
    pub repetitions: usize,
    /// Time steps (dynamic).
    pub steps: Option<usize>,
    /// Rotation extraction over all steps (dynamic) [s].
    pub seconds_rotations: Option<Real>,
    /// Crack opening u_x(2⁺, 0.5, 1) − u_x(2⁻, 0.5, 1) [m] (cut cantilever).
    pub crack_opening: Option<Real>,
    /// Total energy (kinetic + elastic + gravitational) just before the cut [J] (cut dynamic).
    pub energy_before_cut: Option<Real>,
    /// Total energy just after the cut, same state carried across [J] (cut dynamic).
    pub energy_after_cut: Option<Real>,
    /// Largest total energy of any step after the cut [J] (cut dynamic).
    pub energy_max_after_cut: Option<Real>,
    /// |p| just before the cut, p = Σ m v [kg m/s] (cut dynamic).
    pub momentum_before_cut: Option<Real>,
    /// |p_after − p_before| across the cut [kg m/s] (cut dynamic).
    pub momentum_change: Option<Real>,
    /// The static cantilever solved again matrix-free by two-level CG (backends with a coarse
    /// space), one point per tolerance of [`ITERATIVE_TOLERANCES`] until the tip agrees with the
    /// direct solve to 1e-6: the time-to-accuracy column picks the first point whose solver error
    /// is at most 1 % of the discretization error.
    pub iterative: Vec<SweepPoint>,
}

/// One tolerance of the matrix-free static solve.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SweepPoint {
    /// CG's relative residual tolerance.
    pub tolerance: Real,
    /// Wall clock from nothing to the solution: building the discretization and load, the
    /// preconditioner, and this tolerance's iterations [s].
    pub seconds: Real,
    /// CG iterations.
    pub iterations: usize,
    /// Mean u_z over the tip face [m].
    pub tip_uz_avg: Real,
}

/// Tolerances of the matrix-free static sweep.
pub const ITERATIVE_TOLERANCES: [Real; 8] = [1e-1, 1e-2, 1e-3, 1e-4, 1e-5, 1e-6, 1e-7, 1e-8];

impl SweepPoint {
    fn to_cell(points: &[SweepPoint]) -> String {
        points
            .iter()
            .map(|p| format!("{:e}:{:e}:{}:{:e}", p.tolerance, p.seconds, p.iterations, p.tip_uz_avg))
            .collect::<Vec<_>>()
            .join(";")
    }

    fn from_cell(cell: &str) -> Result<Vec<SweepPoint>, String> {
        cell.split(';')
            .filter(|p| !p.is_empty())
            .map(|p| {
                let f: Vec<&str> = p.split(':').collect();
                let bad = || format!("iterative sweep point {p:?} is not tolerance:seconds:iterations:tip");
                let [tolerance, seconds, iterations, tip] = f.as_slice() else { return Err(bad()) };
                Ok(SweepPoint {
                    tolerance: tolerance.parse().map_err(|_| bad())?,
                    seconds: seconds.parse().map_err(|_| bad())?,
                    iterations: iterations.parse().map_err(|_| bad())?,
                    tip_uz_avg: tip.parse().map_err(|_| bad())?,
                })
            })
            .collect()
    }
}

/// The CSV header, in column order.
pub const CSV_HEADER: &str = "problem,backend,variant,n,dofs,elements,nnz,l2_rel_error,h1_rel_error,tip_uz_avg,tip_uz_point,strain_energy,seconds_setup,seconds_assemble,seconds_solve,seconds_total,peak_rss_mb,repetitions,steps,seconds_rotations,crack_opening,energy_before_cut,energy_after_cut,energy_max_after_cut,momentum_before_cut,momentum_change,iterative_sweep";

/// Columns of files written before the cut problems existed: [`CSV_HEADER`]'s first 20. Such
/// files are still read (the cut columns empty), so their rows are kept.
const CSV_COLUMNS_BEFORE_CUTS: usize = 20;

/// Columns of files written before the iterative sweep (its column then reads as empty).
const CSV_COLUMNS_BEFORE_SWEEP: usize = 26;

fn cell<T: fmt::Display>(value: Option<T>) -> String {
    value.map_or_else(String::new, |v| v.to_string())
}

/// The shortest text that reads back as the same `f64`: the cut rows' energy before and after a
/// cut differ by 1e-14 of their size, and ten digits (as written before) read back as equal.
fn real_cell(value: Option<Real>) -> String {
    value.map_or_else(String::new, |v| format!("{v:e}"))
}

impl Row {
    /// `backend/variant`, the name of a method in tables and plots.
    pub fn method(&self) -> String {
        format!("{}/{}", self.backend, self.variant)
    }

    /// The row as one CSV line (no newline), columns as in [`CSV_HEADER`].
    pub fn to_csv(&self) -> String {
        [
            self.problem.clone(),
            self.backend.clone(),
            self.variant.clone(),
            self.n.to_string(),
            self.dofs.to_string(),
            self.elements.to_string(),
            cell(self.nnz),
            real_cell(self.l2_rel_error),
            real_cell(self.h1_rel_error),
            real_cell(self.tip_uz_avg),
            real_cell(self.tip_uz_point),
            real_cell(self.strain_energy),
            real_cell(self.seconds_setup),
            real_cell(self.seconds_assemble),
            real_cell(self.seconds_solve),
            real_cell(self.seconds_total),
            real_cell(self.peak_rss_mb),
            self.repetitions.to_string(),
            cell(self.steps),
            real_cell(self.seconds_rotations),
            real_cell(self.crack_opening),
            real_cell(self.energy_before_cut),
            real_cell(self.energy_after_cut),
            real_cell(self.energy_max_after_cut),
            real_cell(self.momentum_before_cut),
            real_cell(self.momentum_change),
            SweepPoint::to_cell(&self.iterative),
        ]
        .join(",")
    }

    /// Parses a line written by [`Row::to_csv`]; the error names the column.
    pub fn from_csv(line: &str) -> Result<Row, String> {
        let mut f: Vec<&str> = line.trim_end().split(',').collect();
        let columns = CSV_HEADER.split(',').count();
        if f.len() == CSV_COLUMNS_BEFORE_CUTS || f.len() == CSV_COLUMNS_BEFORE_SWEEP {
            f.resize(columns, "");
        }
        if f.len() != columns {
            return Err(format!("expected {columns} columns, found {}: {line}", f.len()));
        }
        let name = |i: usize| CSV_HEADER.split(',').nth(i).unwrap_or("?");
        let int = |i: usize| f[i].parse::<usize>().map_err(|e| format!("column {}: {e} in {:?}", name(i), f[i]));
        let opt_int = |i: usize| if f[i].is_empty() { Ok(None) } else { int(i).map(Some) };
        let opt_real = |i: usize| {
            if f[i].is_empty() {
                Ok(None)
            } else {
                f[i].parse::<Real>().map(Some).map_err(|e| format!("column {}: {e} in {:?}", name(i), f[i]))
            }
        };
        Ok(Row {
            problem: f[0].to_string(),
            backend: f[1].to_string(),
            variant: f[2].to_string(),
            n: int(3)?,
            dofs: int(4)?,
            elements: int(5)?,
            nnz: opt_int(6)?,
            l2_rel_error: opt_real(7)?,
            h1_rel_error: opt_real(8)?,
            tip_uz_avg: opt_real(9)?,
            tip_uz_point: opt_real(10)?,
            strain_energy: opt_real(11)?,
            seconds_setup: opt_real(12)?,
            seconds_assemble: opt_real(13)?,
            seconds_solve: opt_real(14)?,
            seconds_total: opt_real(15)?,
            peak_rss_mb: opt_real(16)?,
            repetitions: int(17)?,
            steps: opt_int(18)?,
            seconds_rotations: opt_real(19)?,
            crack_opening: opt_real(20)?,
            energy_before_cut: opt_real(21)?,
            energy_after_cut: opt_real(22)?,
            energy_max_after_cut: opt_real(23)?,
            momentum_before_cut: opt_real(24)?,
            momentum_change: opt_real(25)?,
            iterative: SweepPoint::from_cell(f[26]).map_err(|e| format!("column iterative_sweep: {e}"))?,
        })
    }
}

/// Parses a whole CSV written by the harness (header checked).
pub fn parse_csv(text: &str) -> Result<Vec<Row>, String> {
    let mut lines = text.lines();
    let before_cuts = CSV_HEADER.split(',').take(CSV_COLUMNS_BEFORE_CUTS).collect::<Vec<_>>().join(",");
    let before_sweep = CSV_HEADER.split(',').take(CSV_COLUMNS_BEFORE_SWEEP).collect::<Vec<_>>().join(",");
    match lines.next() {
        Some(header)
            if header.trim_end() == CSV_HEADER
                || header.trim_end() == before_cuts
                || header.trim_end() == before_sweep => {}
        other => return Err(format!("header {other:?} is not {CSV_HEADER:?}")),
    }
    lines.filter(|l| !l.trim().is_empty()).map(Row::from_csv).collect()
}

/// Why a run failed.
#[derive(Clone, Debug, PartialEq)]
pub enum RunError {
    /// The backend could not build the problem.
    Build(BuildError),
    /// A solve or a step failed.
    Solve(String),
}

impl fmt::Display for RunError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            RunError::Build(e) => write!(f, "build failed: {e}"),
            RunError::Solve(e) => write!(f, "solve failed: {e}"),
        }
    }
}

impl std::error::Error for RunError {}

impl From<BuildError> for RunError {
    fn from(e: BuildError) -> Self {
        RunError::Build(e)
    }
}

impl From<StepErrorKind> for RunError {
    fn from(e: StepErrorKind) -> Self {
        RunError::Solve(e.to_string())
    }
}

fn clamped_face(p: &Point3<Real>) -> bool {
    p.x.abs() < 1e-9
}

/// Mean u_z over the tip face and u_z at its centre, by embedding (any backend).
fn tip_values(d: &dyn Discretization, displacement: &[Real], n: usize) -> Result<(Real, Real), RunError> {
    let quadrature = cantilever::tip_face_quadrature(n);
    let mut points: Vec<Point3<Real>> = quadrature.iter().map(|(p, _)| *p).collect();
    points.push(Point3::new(cantilever::LENGTH, 0.5, 0.5));
    let embedding = d.embed(&points).map_err(|e| RunError::Solve(format!("embedding the tip: {e}")))?;
    let average = quadrature.iter().enumerate().map(|(i, (_, w))| w * embedding.point(displacement, i).z).sum();
    Ok((average, embedding.point(displacement, quadrature.len()).z))
}

fn add(a: &mut [Real], b: &[Real]) {
    a.iter_mut().zip(b).for_each(|(a, b)| *a += b);
}

/// One run of `problem` at level `n` (timings of this single run).
pub fn run_problem(backend: &dyn CompareBackend, variant: &str, problem: Problem, n: usize) -> Result<Row, RunError> {
    let grid = problem.grid(n);
    let mut row = Row {
        problem: problem.key().into(),
        backend: backend.name().into(),
        variant: variant.into(),
        n,
        repetitions: 1,
        ..Default::default()
    };
    match problem {
        Problem::MmsSin111 | Problem::MmsCos123 => {
            let case = if problem == Problem::MmsSin111 { Manufactured::Sin111 } else { Manufactured::Cos123 };
            let material = Material::new(1e6, 0.3, 1000.0).expect("benchmark material is valid");
            let value = move |p: &Point3<Real>| case.displacement(p);
            let dirichlet = DirichletSpec { region: &on_unit_cube_boundary, value: &value };
            let clock = Instant::now();
            let built = backend.build_box(variant, &material, &grid, &dirichlet)?;
            let d = built.discretization.as_ref();
            let mut load = vec![0.0; 3 * d.num_nodes()];
            d.add_load(&|p| case.body_force(&material, p), &mut load);
            add(&mut load, &built.dirichlet_load);
            let seconds_build = clock.elapsed().as_secs_f64();
            let solution = solve_static(d, &load, &built.prescribed)?;
            row.seconds_total = Some(clock.elapsed().as_secs_f64());
            let errors = field_errors(d, &solution.displacement, 6, &|p| (case.displacement(p), case.gradient(p)));
            fill_static(&mut row, &built, &load, &solution, seconds_build);
            row.l2_rel_error = Some(errors.l2_relative);
            row.h1_rel_error = Some(errors.h1_relative);
        }
        Problem::Cantilever | Problem::CutCantilever => {
            let material = cantilever::material(0.3);
            let dirichlet = DirichletSpec { region: &clamped_face, value: &|_| Vector3::zeros() };
            let clock = Instant::now();
            let built = if problem == Problem::CutCantilever {
                backend.build_cut_box(variant, &material, &grid, &dirichlet, &crack::cantilever(grid.h))?.built
            } else {
                backend.build_box(variant, &material, &grid, &dirichlet)?
            };
            let d = built.discretization.as_ref();
            let mut load = vec![0.0; 3 * d.num_nodes()];
            let f = cantilever::force_density(&material);
            d.add_load(&|_| f, &mut load);
            add(&mut load, &built.dirichlet_load);
            let seconds_build = clock.elapsed().as_secs_f64();
            let solution = solve_static(d, &load, &built.prescribed)?;
            row.seconds_total = Some(clock.elapsed().as_secs_f64());
            let (average, point) = tip_values(d, &solution.displacement, n)?;
            fill_static(&mut row, &built, &load, &solution, seconds_build);
            row.tip_uz_avg = Some(average);
            row.tip_uz_point = Some(point);
            if problem == Problem::Cantilever && d.coarse_space().is_some() {
                row.iterative = iterative_sweep(d, &load, &built.prescribed, n, seconds_build, average)?;
            }
            if problem == Problem::CutCantilever {
                row.crack_opening = Some(crack_opening(d, &solution.displacement, grid.h)?);
            }
        }
        Problem::Dynamic | Problem::CutDynamic => run_dynamic(backend, variant, &grid, &mut row)?,
    }
    Ok(row)
}

/// The static solve again by matrix-free two-level CG at each of [`ITERATIVE_TOLERANCES`], from
/// zero, until its tip agrees with the direct solve's `direct_tip` to 1e-6 relative.
fn iterative_sweep(
    d: &dyn Discretization,
    load: &[Real],
    prescribed: &[(usize, Real)],
    n: usize,
    seconds_build: Real,
    direct_tip: Real,
) -> Result<Vec<SweepPoint>, RunError> {
    let mut statics = cleave_integrator::IterativeStatics::new(d, load, prescribed)?;
    let mut points = Vec::new();
    for tolerance in ITERATIVE_TOLERANCES {
        let solution = statics.solve(tolerance, 100 * d.num_nodes().max(100));
        if !solution.converged {
            break;
        }
        let (tip, _) = tip_values(d, &solution.displacement, n)?;
        points.push(SweepPoint {
            tolerance,
            seconds: seconds_build + statics.seconds_setup + solution.seconds_solve,
            iterations: solution.iterations,
            tip_uz_avg: tip,
        });
        if (tip - direct_tip).abs() <= 1e-6 * direct_tip.abs() {
            break;
        }
    }
    Ok(points)
}

/// The first point of a sweep whose solver error `|tip − direct|` is at most 1 % of the
/// discretization error `|direct − reference|`: the matrix-free path's time to the direct
/// solve's accuracy.
pub fn time_to_accuracy(row: &Row, reference_tip: Real) -> Option<SweepPoint> {
    let direct = row.tip_uz_avg?;
    let discretization_error = (direct - reference_tip).abs();
    row.iterative.iter().copied().find(|p| (p.tip_uz_avg - direct).abs() <= 0.01 * discretization_error)
}

/// u_x(2⁺, 0.5, 1) − u_x(2⁻, 0.5, 1) by embedding ([`crack::opening_points`]).
fn crack_opening(d: &dyn Discretization, displacement: &[Real], h: Real) -> Result<Real, RunError> {
    let embedding =
        d.embed(&crack::opening_points(h)).map_err(|e| RunError::Solve(format!("embedding the crack mouth: {e}")))?;
    Ok(embedding.point(displacement, 0).x - embedding.point(displacement, 1).x)
}

/// Σ m v per component (lumped masses).
fn momentum(d: &dyn Discretization, v: &[Real]) -> Vector3<Real> {
    let mut p = Vector3::zeros();
    for (m, v) in d.mass().diagonal().chunks_exact(3).zip(v.chunks_exact(3)) {
        for a in 0..3 {
            p[a] += m[a] * v[a];
        }
    }
    p
}

/// `fᵀX₀` for the gravity load `f` of `d`: added to the integrator's gravitational energy
/// `−fᵀx`, it measures that energy from the rest shape, `−fᵀu`, so the total is not dominated by
/// where the world origin is.
fn gravity_datum(d: &dyn Discretization, gravity: &Vector3<Real>) -> Real {
    let mut f = vec![0.0; 3 * d.num_nodes()];
    d.add_gravity_load(gravity, &mut f);
    f.iter().zip(d.rest_dofs()).map(|(f, x)| f * x).sum()
}

/// The integrator's constraints for a built problem: its strong pins and weak Dirichlet load.
fn dirichlet_constraints(built: &BuiltProblem) -> Constraints {
    Constraints {
        pinned_dofs: built.prescribed.iter().map(|&(dof, _)| dof).collect(),
        extra_load: built.dirichlet_load.clone(),
        ..Default::default()
    }
}

/// The dynamic beam (benchmarks.md §3) of `row.problem`: [`DYNAMIC_STEPS`] steps uncut, or
/// (cut dynamic) [`CUT_DYNAMIC_STEPS`] steps cut by §5's crack after [`CUT_DYNAMIC_CUT_STEP`],
/// the way `cleave_scene::Simulation` cuts between steps: the backend's cut box and topology
/// change handed to `Integrator::apply_topology_change` with the Dirichlet data resolved again.
fn run_dynamic(backend: &dyn CompareBackend, variant: &str, grid: &BoxGrid, row: &mut Row) -> Result<(), RunError> {
    let cut = row.problem == Problem::CutDynamic.key();
    let material = Material::new(DYNAMIC_YOUNGS_MODULUS, 0.3, 1000.0)
        .and_then(|m| m.with_damping(0.0, 0.01))
        .expect("benchmark material is valid");
    let dirichlet = DirichletSpec { region: &clamped_face, value: &|_| Vector3::zeros() };
    let clock = Instant::now();
    let mut built = backend.build_box(variant, &material, grid, &dirichlet)?;
    let mut settings = Settings::new(DYNAMIC_TIME_STEP);
    settings.rayleigh_beta = material.rayleigh_beta;
    settings.solver = backend.dynamic_solver(variant);
    let mut integrator = Integrator::new(built.discretization.as_ref(), settings, dirichlet_constraints(&built))
        .map_err(|e| RunError::Solve(e.to_string()))?;
    row.seconds_setup = Some(clock.elapsed().as_secs_f64());
    let (mut rotations, mut assembly, mut solve) = (0.0, 0.0, 0.0);
    let steps = if cut { CUT_DYNAMIC_STEPS } else { DYNAMIC_STEPS };
    let mut datum = 0.0;
    for step in 0..steps {
        if cut && step == CUT_DYNAMIC_CUT_STEP {
            let gravity = integrator.settings().gravity;
            let before = integrator.energies(built.discretization.as_ref()).total_energy()
                + gravity_datum(built.discretization.as_ref(), &gravity);
            let p_before = momentum(built.discretization.as_ref(), integrator.velocities());
            let cut_box = backend.build_cut_box(variant, &material, grid, &dirichlet, &crack::cantilever(grid.h))?;
            // The cut box must be the running box cut: every new node at its source's place
            // (to rounding: DG's restricted polynomials are computed, not copied).
            let rest = cut_box.change.remap.apply(built.discretization.rest_dofs());
            let target = cut_box.built.discretization.rest_dofs();
            let scale = target.iter().fold(1.0, |m: Real, v| m.max(v.abs()));
            if rest.len() != target.len()
                || rest.iter().zip(target).any(|(a, b)| (a - b).abs().is_nan() || (a - b).abs() > 1e-9 * scale)
            {
                return Err(RunError::Solve("the cut box is not the running box cut (rest positions differ)".into()));
            }
            let constraints = dirichlet_constraints(&cut_box.built);
            integrator
                .apply_topology_change(cut_box.built.discretization.as_ref(), &cut_box.change, constraints)
                .map_err(|e| RunError::Solve(e.to_string()))?;
            built = cut_box.built;
            let d = built.discretization.as_ref();
            datum = gravity_datum(d, &gravity);
            let after = integrator.energies(d).total_energy() + datum;
            row.energy_before_cut = Some(before);
            row.energy_after_cut = Some(after);
            row.energy_max_after_cut = Some(after);
            row.momentum_before_cut = Some(p_before.norm());
            row.momentum_change = Some((momentum(d, integrator.velocities()) - p_before).norm());
        }
        let report = integrator.step(built.discretization.as_ref()).map_err(|e| RunError::Solve(e.to_string()))?;
        rotations += report.seconds.rotations;
        assembly += report.seconds.assembly;
        solve += report.seconds.solve;
        if let Some(max) = row.energy_max_after_cut.as_mut() {
            *max = max.max(report.total_energy() + datum);
        }
    }
    row.seconds_total = Some(clock.elapsed().as_secs_f64());
    let d = built.discretization.as_ref();
    let displacement: Vec<Real> = integrator.positions().iter().zip(d.rest_dofs()).map(|(x, x0)| x - x0).collect();
    let (average, point) = tip_values(d, &displacement, row.n)?;
    row.dofs = 3 * d.num_nodes();
    row.elements = built.elements;
    row.nnz = integrator.matrix_stats().map(|(nnz, _)| nnz);
    row.tip_uz_avg = Some(average);
    row.tip_uz_point = Some(point);
    if cut {
        row.crack_opening = Some(crack_opening(d, &displacement, grid.h)?);
    }
    row.seconds_assemble = Some(assembly);
    row.seconds_solve = Some(solve);
    row.seconds_rotations = Some(rotations);
    row.steps = Some(steps);
    Ok(())
}

fn fill_static(
    row: &mut Row,
    built: &BuiltProblem,
    load: &[Real],
    solution: &cleave_integrator::StaticSolution,
    seconds_build: Real,
) {
    row.dofs = 3 * built.discretization.num_nodes();
    row.elements = built.elements;
    row.nnz = Some(solution.nnz);
    // ½ fᵀu as in benchmarks.md (equal to ½ uᵀKu at equilibrium with homogeneous data).
    row.strain_energy = Some(0.5 * load.iter().zip(&solution.displacement).map(|(f, u)| f * u).sum::<Real>());
    row.seconds_setup = Some(seconds_build + solution.seconds_setup);
    row.seconds_assemble = Some(solution.seconds_assemble);
    row.seconds_solve = Some(solution.seconds_solve);
}

fn median(mut values: Vec<Real>) -> Real {
    values.sort_by(Real::total_cmp);
    values[values.len() / 2]
}

/// `repetitions` runs of one level; the timings are medians, everything else from the first run
/// (the runs are deterministic).
pub fn run_repeated(
    backend: &dyn CompareBackend,
    variant: &str,
    problem: Problem,
    n: usize,
    repetitions: usize,
) -> Result<Row, RunError> {
    let mut rows = Vec::with_capacity(repetitions);
    for _ in 0..repetitions.max(1) {
        rows.push(run_problem(backend, variant, problem, n)?);
    }
    let mut row = rows[0].clone();
    let med = |f: fn(&Row) -> Option<Real>| {
        let values: Vec<Real> = rows.iter().filter_map(f).collect();
        (!values.is_empty()).then(|| median(values))
    };
    row.seconds_setup = med(|r| r.seconds_setup);
    row.seconds_assemble = med(|r| r.seconds_assemble);
    row.seconds_solve = med(|r| r.seconds_solve);
    row.seconds_total = med(|r| r.seconds_total);
    row.seconds_rotations = med(|r| r.seconds_rotations);
    row.repetitions = rows.len();
    Ok(row)
}

/// Limits of one refinement study.
#[derive(Clone, Debug)]
pub struct StudyPlan {
    /// Wall-clock seconds one (backend, variant, problem) may spend.
    pub budget_seconds: Real,
    /// Largest refinement level tried.
    pub max_n: usize,
    /// Stop before a level whose DOFs would exceed this (memory guard for direct solvers).
    pub max_dofs: usize,
    /// Runs predicted longer than this are done once, shorter ones three times.
    pub single_run_seconds: Real,
}

impl StudyPlan {
    /// The full study with a budget.
    pub fn full(budget_seconds: Real) -> Self {
        Self { budget_seconds, max_n: usize::MAX, max_dofs: 1_200_000, single_run_seconds: 3.0 }
    }

    /// The CI study: small levels only.
    pub fn quick(problem: Problem) -> Self {
        let max_n = match problem {
            Problem::MmsSin111 | Problem::MmsCos123 => 8,
            Problem::Cantilever | Problem::CutCantilever => 4,
            Problem::Dynamic | Problem::CutDynamic => 2,
        };
        Self { budget_seconds: 30.0, max_n, max_dofs: 100_000, single_run_seconds: 3.0 }
    }
}

/// What the caller sees of a study as it runs (progress, memory, files).
pub trait StudyObserver {
    /// About to run level `n` (e.g. reset the peak-RSS counter).
    fn before_level(&mut self, _problem: Problem, _n: usize, _repetitions: usize) {}
    /// Peak resident memory since `before_level`, in MB, if the caller can measure it.
    fn peak_rss_mb(&mut self) -> Option<Real> {
        None
    }
    /// A level finished: the row is final (write it now).
    fn row_done(&mut self, _row: &Row) {}
}

/// Observer that does nothing.
pub struct Silent;
impl StudyObserver for Silent {}

/// How a study ended.
#[derive(Clone, Debug)]
pub struct StudyOutcome {
    /// One row per finished level.
    pub rows: Vec<Row>,
    /// Why it stopped (budget, DOF cap, last level, error).
    pub stop_reason: String,
}

/// Refines `problem` for one method until the plan's budget, DOF cap or level cap stops it. The
/// next level's wall time is predicted as the last one's times the last growth factor clamped to
/// [8, 64] (16 with only one level done; a direct 3D solve grows up to 64× per halving of h once
/// fill dominates), and the study stops before a level whose predicted cost
/// (times its repetitions) would overrun the budget.
pub fn run_study(
    backend: &dyn CompareBackend,
    variant: &str,
    problem: Problem,
    plan: &StudyPlan,
    observer: &mut dyn StudyObserver,
) -> StudyOutcome {
    let mut rows: Vec<Row> = Vec::new();
    let mut walls: Vec<Real> = Vec::new();
    let mut spent = 0.0;
    for n in problem.sizes() {
        if n > plan.max_n {
            return StudyOutcome { rows, stop_reason: format!("level cap n ≤ {}", plan.max_n) };
        }
        let (predicted, predicted_dofs) = match (walls.as_slice(), rows.last()) {
            ([.., previous, last], Some(row)) => (last * (last / previous).clamp(8.0, 64.0), row.dofs * 8),
            ([last], Some(row)) => (last * 16.0, row.dofs * 8),
            _ => (0.0, 0),
        };
        if predicted_dofs > plan.max_dofs {
            return StudyOutcome {
                rows,
                stop_reason: format!("next level n = {n} would have ~{predicted_dofs} DOFs > {}", plan.max_dofs),
            };
        }
        let repetitions = if walls.is_empty() || predicted <= plan.single_run_seconds { 3 } else { 1 };
        if spent + predicted * repetitions as Real > plan.budget_seconds {
            return StudyOutcome {
                rows,
                stop_reason: format!(
                    "budget: n = {n} predicted {:.1} s × {repetitions} after {spent:.1} s of {:.0} s",
                    predicted, plan.budget_seconds
                ),
            };
        }
        observer.before_level(problem, n, repetitions);
        let clock = Instant::now();
        let result = run_repeated(backend, variant, problem, n, repetitions);
        let wall = clock.elapsed().as_secs_f64();
        spent += wall;
        match result {
            Ok(mut row) => {
                row.peak_rss_mb = observer.peak_rss_mb();
                observer.row_done(&row);
                walls.push(wall / repetitions as Real);
                rows.push(row);
            }
            Err(e) => return StudyOutcome { rows, stop_reason: format!("n = {n}: {e}") },
        }
    }
    StudyOutcome { rows, stop_reason: "largest level reached".into() }
}

/// Observed rate `log(e_i/e_{i+1}) / log(n_{i+1}/n_i)` between consecutive rows (h = 1/n).
pub fn observed_rates(rows: &[&Row], error: impl Fn(&Row) -> Option<Real>) -> Vec<Option<Real>> {
    let mut rates = vec![None];
    for w in rows.windows(2) {
        let rate = match (error(w[0]), error(w[1])) {
            (Some(a), Some(b)) if a > 0.0 && b > 0.0 => Some((a / b).ln() / (w[1].n as Real / w[0].n as Real).ln()),
            _ => None,
        };
        rates.push(rate);
    }
    rates
}

/// λ of the clamped-edge singularity at ν = 0.3 (benchmarks.md §2): errors behave like h^(2λ).
pub const CANTILEVER_LAMBDA: Real = 0.711;

/// Richardson extrapolation of a quantity converging like `h^rate` from levels `h` and `h/ratio`.
pub fn richardson(coarse: Real, fine: Real, ratio: Real, rate: Real) -> Real {
    fine + (fine - coarse) / (ratio.powf(rate) - 1.0)
}

/// The crack front's singularity (λ = 1/2, benchmarks.md §5): the cut cantilever's tip,
/// energy and opening converge like h¹.
pub const CUT_CANTILEVER_RATE: Real = 1.0;

/// One method's extrapolated limit of a quantity (the cantilever's tip by default).
#[derive(Clone, Debug, PartialEq)]
pub struct MethodLimit {
    /// `backend/variant`.
    pub method: String,
    /// Whether the method is consistent (an exact solution satisfies its discrete equations), so
    /// that its limit can be a reference at all.
    pub consistent: bool,
    /// The two finest levels used.
    pub levels: (usize, usize),
    /// Their values (tip [m], energy [J], opening [m]).
    pub values: (Real, Real),
    /// Richardson extrapolation with the problem's rate.
    pub limit: Real,
    /// Its estimated error: the size of the Richardson correction, |limit − finest| [m].
    pub estimated_error: Real,
}

/// A reference (of the cantilever's tip, or of a cut cantilever quantity): the limit that
/// independent consistent methods agree on.
#[derive(Clone, Debug, PartialEq)]
pub struct TipReference {
    /// The agreeing methods' limits averaged with weights 1/error² [m].
    pub value: Real,
    /// Its uncertainty [m] ([`cantilever_reference`]).
    pub uncertainty: Real,
    /// Methods whose limits make the reference.
    pub agreeing: Vec<String>,
    /// Every method with two levels, in input order.
    pub limits: Vec<MethodLimit>,
}

impl TipReference {
    /// How far `limit` lies outside the reference's uncertainty, relative to the reference:
    /// `None` when it is within `uncertainty + own estimated error` (it converges to the same
    /// limit as far as the data can tell).
    pub fn different_limit(&self, limit: &MethodLimit) -> Option<Real> {
        let distance = (limit.limit - self.value).abs();
        (distance > self.uncertainty + limit.estimated_error).then(|| distance / self.value.abs())
    }
}

/// Each method's limit by Richardson with rate 2λ from its two finest cantilever runs.
pub fn cantilever_limits(rows: &[Row], is_consistent: &dyn Fn(&str) -> bool) -> Vec<MethodLimit> {
    extrapolated_limits(rows, Problem::Cantilever, 2.0 * CANTILEVER_LAMBDA, |r| r.tip_uz_avg, is_consistent)
}

/// Each method's limit of `value` by Richardson with `rate` from its two finest runs of
/// `problem` that have a value.
pub fn extrapolated_limits(
    rows: &[Row],
    problem: Problem,
    rate: Real,
    value: impl Fn(&Row) -> Option<Real>,
    is_consistent: &dyn Fn(&str) -> bool,
) -> Vec<MethodLimit> {
    let mut methods: Vec<String> = rows.iter().filter(|r| r.problem == problem.key()).map(Row::method).collect();
    methods.dedup();
    methods
        .into_iter()
        .filter_map(|method| {
            let mut own: Vec<&Row> = rows
                .iter()
                .filter(|r| r.problem == problem.key() && r.method() == method && value(r).is_some())
                .collect();
            own.sort_by_key(|r| r.n);
            let [.., coarse, fine] = own.as_slice() else { return None };
            let (a, b) = (value(coarse)?, value(fine)?);
            let limit = richardson(a, b, fine.n as Real / coarse.n as Real, rate);
            Some(MethodLimit {
                consistent: is_consistent(&method),
                method,
                levels: (coarse.n, fine.n),
                values: (a, b),
                limit,
                estimated_error: (b - limit).abs(),
            })
        })
        .collect()
}

/// The reference of the cantilever study (issue 9's rule): only consistent methods are
/// candidates; starting from the one with the smallest estimated error, a candidate joins when
/// its limit agrees with every member's within the sum of their estimated errors. The reference
/// is the members' mean weighted by 1/error² (a poorly converged member that merely agrees does
/// not pull it); its uncertainty is the larger of the weighted mean's own error
/// `(Σ 1/e²)^(−1/2)` and the largest distance from it of the well-converged members (weight at
/// least a tenth of the largest): the spread of the methods that actually pin it down.
pub fn cantilever_reference(rows: &[Row], is_consistent: &dyn Fn(&str) -> bool) -> Option<TipReference> {
    agreed_reference(cantilever_limits(rows, is_consistent))
}

/// The reference of the cut cantilever for `value` (tip, energy or opening): each method's
/// limit with rate 1 ([`CUT_CANTILEVER_RATE`]) from its two finest levels, then the rule of
/// [`cantilever_reference`].
pub fn cut_cantilever_reference(
    rows: &[Row],
    value: impl Fn(&Row) -> Option<Real>,
    is_consistent: &dyn Fn(&str) -> bool,
) -> Option<TipReference> {
    agreed_reference(extrapolated_limits(rows, Problem::CutCantilever, CUT_CANTILEVER_RATE, value, is_consistent))
}

/// The rule of [`cantilever_reference`] applied to `limits`.
pub fn agreed_reference(limits: Vec<MethodLimit>) -> Option<TipReference> {
    let mut candidates: Vec<&MethodLimit> = limits.iter().filter(|l| l.consistent).collect();
    candidates.sort_by(|a, b| a.estimated_error.total_cmp(&b.estimated_error));
    let mut members: Vec<&MethodLimit> = Vec::new();
    for c in candidates {
        if members.iter().all(|m| (m.limit - c.limit).abs() <= m.estimated_error + c.estimated_error) {
            members.push(c);
        }
    }
    if members.is_empty() {
        return None;
    }
    let floor = members.iter().map(|m| m.limit.abs()).fold(0.0, Real::max) * 1e-12;
    let weight = |m: &MethodLimit| 1.0 / m.estimated_error.max(floor).powi(2);
    let total: Real = members.iter().map(|m| weight(m)).sum();
    let value = members.iter().map(|m| weight(m) * m.limit).sum::<Real>() / total;
    let heaviest = members.iter().map(|m| weight(m)).fold(0.0, Real::max);
    let spread =
        members.iter().filter(|m| weight(m) >= 0.1 * heaviest).map(|m| (m.limit - value).abs()).fold(0.0, Real::max);
    let uncertainty = spread.max(total.sqrt().recip());
    let agreeing = members.iter().map(|m| m.method.clone()).collect();
    Some(TipReference { value, uncertainty, agreeing, limits })
}

/// kaufmann2008 Table 1 (ms on a Core2 Duo 2.4 GHz, 10×10×10 grid): label, the (backend,
/// variant) it corresponds to here, the matrix sparsity [%] and integration / assembly / solve.
pub const KAUFMANN2008_TABLE1: [(&str, &str, &str, Real, [Real; 3]); 4] = [
    ("BZ-lin", "dg", "bz-1", 0.28, [532.0, 22.0, 656.0]),
    ("IP-lin", "dg", "ip-1", 0.62, [1437.0, 87.0, 734.0]),
    ("BZ-quad", "dg", "bz-2", 0.28, [3062.0, 152.0, 7797.0]),
    ("IP-quad", "dg", "ip-2", 0.64, [8344.0, 621.0, 8484.0]),
];

/// Our integration / assembly / solve seconds on the 10×10×10 grid of Table 1.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Table1Timings {
    /// Building the discretization (element integrals) [s].
    pub integration: Real,
    /// Matrix values: warped blocks written at precomputed positions, the right-hand side [s].
    /// What a time step repeats, and what the paper's "assembly" measures.
    pub assembly: Real,
    /// Sparsity pattern, fill-reducing order and symbolic factorization [s]: once per mesh
    /// (per epoch in a simulation), reused by every step.
    pub pattern: Real,
    /// Numeric factorization and solve [s].
    pub solve: Real,
    /// Backend-specific search inside the build (DG penalty doubling) [s], not in `integration`.
    pub search: Real,
    /// Scalar DOFs.
    pub dofs: usize,
    /// Stored entries of the assembled matrix (both triangles; 3×3 node blocks).
    pub nnz: usize,
    /// Entries of the Cholesky factor (supernodal storage).
    pub factor_nnz: usize,
}

/// Times one backend variant on the Table 1 problem: the unit cube as 10×10×10 cells, clamped at
/// x = 0 under gravity (E = 1e6, ν = 0.3, ρ = 1000), static solve; medians of `repetitions`.
pub fn table1_timings(
    backend: &dyn CompareBackend,
    variant: &str,
    repetitions: usize,
) -> Result<Table1Timings, RunError> {
    let grid = BoxGrid { origin: Point3::origin(), h: 0.1, dims: [10, 10, 10] };
    let material = cantilever::material(0.3);
    let dirichlet = DirichletSpec { region: &clamped_face, value: &|_| Vector3::zeros() };
    let mut samples = Vec::new();
    for _ in 0..repetitions.max(1) {
        let clock = Instant::now();
        let built = backend.build_box(variant, &material, &grid, &dirichlet)?;
        let integration = clock.elapsed().as_secs_f64() - built.search_seconds;
        let search = built.search_seconds;
        let d = built.discretization.as_ref();
        let mut load = vec![0.0; 3 * d.num_nodes()];
        let f = cantilever::force_density(&material);
        d.add_load(&|_| f, &mut load);
        add(&mut load, &built.dirichlet_load);
        let solution = solve_static(d, &load, &built.prescribed)?;
        samples.push(Table1Timings {
            integration,
            assembly: solution.seconds_assemble,
            pattern: solution.seconds_setup,
            solve: solution.seconds_solve,
            search,
            dofs: 3 * d.num_nodes(),
            nnz: solution.nnz,
            factor_nnz: solution.factor_nnz,
        });
    }
    let (dofs, nnz, factor_nnz) = (samples[0].dofs, samples[0].nnz, samples[0].factor_nnz);
    Ok(Table1Timings {
        integration: median(samples.iter().map(|s| s.integration).collect()),
        assembly: median(samples.iter().map(|s| s.assembly).collect()),
        pattern: median(samples.iter().map(|s| s.pattern).collect()),
        solve: median(samples.iter().map(|s| s.solve).collect()),
        search: median(samples.iter().map(|s| s.search).collect()),
        dofs,
        nnz,
        factor_nnz,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn richardson_recovers_the_limit_of_an_exact_power_law() {
        // u(h) = 3 + 2 h^1.422: two levels determine the limit exactly.
        let p = 2.0 * CANTILEVER_LAMBDA;
        let u = |h: Real| 3.0 + 2.0 * h.powf(p);
        assert!((richardson(u(0.25), u(0.125), 2.0, p) - 3.0).abs() < 1e-12);
    }

    #[test]
    fn csv_round_trips_with_empty_cells() {
        let row = Row {
            problem: "mms-sin111".into(),
            backend: "voxel".into(),
            variant: "trilinear".into(),
            n: 4,
            dofs: 375,
            elements: 64,
            l2_rel_error: Some(0.125),
            repetitions: 3,
            ..Default::default()
        };
        let text = format!("{CSV_HEADER}\n{}\n", row.to_csv());
        assert_eq!(parse_csv(&text).unwrap(), vec![row.clone()]);
        // A file from before the cut columns: its 20 columns are read, the cut columns empty.
        let old_header = CSV_HEADER.split(',').take(20).collect::<Vec<_>>().join(",");
        let old_line = row.to_csv().split(',').take(20).collect::<Vec<_>>().join(",");
        assert_eq!(parse_csv(&format!("{old_header}\n{old_line}\n")).unwrap(), vec![row.clone()]);
        let cut = Row { problem: "cut-dynamic".into(), crack_opening: Some(0.5), momentum_change: Some(1e-16), ..row };
        assert_eq!(Row::from_csv(&cut.to_csv()).unwrap(), cut);
        // Values read back bit for bit: an energy change of 1e-14 of the energy survives.
        let before: Real = -297.9123456789012;
        let after = before * (1.0 + 3.0 * Real::EPSILON * 16.0);
        let energies = Row { energy_before_cut: Some(before), energy_after_cut: Some(after), ..cut };
        let read = Row::from_csv(&energies.to_csv()).unwrap();
        assert_eq!(read.energy_after_cut.unwrap() - read.energy_before_cut.unwrap(), after - before);
        assert_ne!(after, before);
        assert!(parse_csv("a,b\n").is_err());
    }
}

#[cfg(test)]
mod reference_tests {
    use super::*;

    fn cantilever_row(backend: &str, variant: &str, n: usize, tip: Real) -> Row {
        Row {
            problem: Problem::Cantilever.key().into(),
            backend: backend.into(),
            variant: variant.into(),
            n,
            tip_uz_avg: Some(tip),
            ..Default::default()
        }
    }

    /// Two levels converging exactly like `limit + c h^(2λ)` with h = 1/n.
    fn converging(backend: &str, variant: &str, limit: Real, c: Real) -> [Row; 2] {
        let tip = |n: usize| limit + c * (1.0 / n as Real).powf(2.0 * CANTILEVER_LAMBDA);
        [cantilever_row(backend, variant, 8, tip(8)), cantilever_row(backend, variant, 16, tip(16))]
    }

    #[test]
    fn richardson_recovers_the_limit_of_an_exact_power_law() {
        // u(h) = L + c h^p: two levels give L back exactly (an independent closed form).
        let (l, c, p) = (-3.9, 0.7, 1.422);
        let value = richardson(l + c * 0.25f64.powf(p), l + c * 0.125f64.powf(p), 2.0, p);
        assert!((value - l).abs() < 1e-13, "{value}");
    }

    fn cut_row(backend: &str, n: usize, tip: Real, energy: Real) -> Row {
        Row {
            problem: Problem::CutCantilever.key().into(),
            backend: backend.into(),
            variant: "v".into(),
            n,
            tip_uz_avg: Some(tip),
            strain_energy: Some(energy),
            ..Default::default()
        }
    }

    #[test]
    fn rate_one_extrapolation_recovers_the_limit_of_a_plus_c_h() {
        // u(h) = a + c h, h = 1/n: any two levels give a back exactly, whatever c; the rate-2λ
        // rule of the uncut cantilever would not: it leaves c h_f (1 − 1/(2^1.422 − 1)) = 0.089.
        let (a, c) = (-4.25, 3.5);
        let u = |n: usize| a + c / n as Real;
        assert!((richardson(u(8), u(16), 2.0, CUT_CANTILEVER_RATE) - a).abs() < 1e-14);
        assert!((richardson(u(4), u(12), 3.0, CUT_CANTILEVER_RATE) - a).abs() < 1e-14);
        assert!((richardson(u(8), u(16), 2.0, 2.0 * CANTILEVER_LAMBDA) - a).abs() > 0.08);
        // Through the harness: the two finest levels of each method, for any quantity.
        let rows = vec![
            cut_row("voxel", 2, u(2) + 1.0, 7.0),
            cut_row("voxel", 4, u(4), 10.0 + 2.0 / 4.0),
            cut_row("voxel", 8, u(8), 10.0 + 2.0 / 8.0),
            cut_row("virtualnode", 4, a - 1.0 / 4.0, 10.0 - 1.0 / 4.0),
            cut_row("virtualnode", 8, a - 1.0 / 8.0, 10.0 - 1.0 / 8.0),
        ];
        let tip = cut_cantilever_reference(&rows, |r| r.tip_uz_avg, &|_| true).unwrap();
        assert_eq!(tip.limits[0].levels, (4, 8));
        assert!(tip.limits.iter().all(|l| (l.limit - a).abs() < 1e-13), "{tip:?}");
        assert!((tip.value - a).abs() < 1e-13 && tip.agreeing.len() == 2);
        let energy = cut_cantilever_reference(&rows, |r| r.strain_energy, &|_| true).unwrap();
        assert!((energy.value - 10.0).abs() < 1e-13, "{energy:?}");
        // The uncut cantilever's rows are not the cut problem's.
        assert!(cantilever_reference(&rows, &|_| true).is_none());
    }

    #[test]
    fn an_inconsistent_method_is_flagged_and_never_the_reference() {
        // Two consistent methods converging to −3.93 and one inconsistent one converging faster
        // to −4.13 (the situation of issue 9): the reference is −3.93, the other is flagged.
        let mut rows = Vec::new();
        rows.extend(converging("voxel", "trilinear", -3.93, 0.3));
        rows.extend(converging("dg", "ip-2", -3.9305, -0.2));
        rows.extend(converging("dg", "bz-2", -4.13, 0.01));
        let consistent = |m: &str| !m.ends_with("bz-2");
        let reference = cantilever_reference(&rows, &consistent).unwrap();
        assert_eq!(reference.agreeing, vec!["dg/ip-2".to_string(), "voxel/trilinear".to_string()]);
        assert!((reference.value + 3.93).abs() < 1e-3, "{reference:?}");
        let bz = reference.limits.iter().find(|l| l.method == "dg/bz-2").unwrap();
        let away = reference.different_limit(bz).expect("BZ must be flagged");
        assert!((away - 0.2 / 3.93).abs() < 2e-3, "{away}");
        // The consistency flag is what protects the reference: declared consistent, BZ's
        // smaller estimated error would make it the first member, and the right methods,
        // which disagree with it, would be left out. Registrations must declare it
        // (`CompareBackend::is_consistent`).
        let all = cantilever_reference(&rows, &|_| true).unwrap();
        assert_eq!(all.agreeing, vec!["dg/bz-2".to_string()], "{all:?}");
    }
}
