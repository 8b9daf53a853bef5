//! The corotated linearly implicit backward Euler step (docs/math/corotated-integrator.md):
//!
//! ```text
//! (M + h D + h² K_R + h² K_c + h C_c) v⁺ = M v + h (f_int(x) + f_ext + f_c(x)),   x⁺ = x + h v⁺
//! D = αM + βK_R
//! ```
//!
//! with rotations frozen at `x`, pinned DOFs eliminated and penalty terms (pins, plane contacts)
//! linearized implicitly.

use crate::cg::CgWorkspace;
use crate::constraints::Constraints;
use crate::error::{StepError, StepErrorKind};
use crate::low_rank::{self, LowRankUpdate};
use crate::momentum::FreePieces;
use crate::penalty::{self, MatrixScratch};
use crate::pieces::PiecePreconditioner;
use crate::system::AssembledSystem;
use crate::two_level::TwoLevel;
use cleave_contact::{ContactSet, ContactStats};
use cleave_core::{Discretization, Matrix3, Point3, Real, TopologyChange, Vector3};
use rayon::prelude::*;
use std::time::Instant;

/// Linear solver of a step.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Solver {
    /// faer sparse Cholesky (LLT): symbolic factorization once per epoch, numeric every step.
    Cholesky,
    /// Block-Jacobi (3×3) preconditioned CG warm-started from the previous velocity.
    ConjugateGradient {
        /// Relative residual `‖r‖ / max(‖b‖, h‖f_ext‖)` to reach.
        tolerance: Real,
        /// Iteration limit; reaching it is a step error.
        max_iterations: usize,
        /// Multiply with an assembled matrix (`true`) or with the backend's matrix-free kernel.
        assembled: bool,
    },
}

/// Preconditioner of the CG solver.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Preconditioner {
    /// Inverse 3×3 diagonal node blocks of the step matrix, rebuilt every step.
    BlockJacobi,
    /// Block-Jacobi plus a coarse-space correction `P A_c⁻¹ Pᵀ` from the backend's
    /// [`cleave_core::CoarseSpace`], with `A_c` factorized once per epoch (rotations at identity,
    /// no contacts). Falls back to block-Jacobi when the backend offers no coarse space.
    TwoLevel,
    /// `TwoLevel` when the backend offers a coarse space of at most [`AUTO_COARSE_DOFS`] DOFs
    /// (its factor grows faster than linearly), else `BlockJacobi`.
    #[default]
    Auto,
    /// For bodies cut into many pieces: the Cholesky factor of the step matrix without the
    /// couplings contacts make between nodes (block diagonal by piece, contacts lumped by
    /// surface point) plus a coarse space of the pieces' rigid motions with the contacts between
    /// them (docs/math/corotated-integrator.md, "Piecewise preconditioner"). Its cost grows with
    /// the pieces' sizes and the contacts, not with the fill that contacts knit between pieces
    /// in one factorization of everything. It assembles the elastic part itself and multiplies
    /// with it (contacts matrix-free), whatever `Solver::ConjugateGradient::assembled` says.
    Pieces,
}

/// Largest coarse space `Preconditioner::Auto` factorizes: the 2h space of the 10k-cube bunny
/// has 6.5k DOFs and a 2.3M-entry factor (18 MB); see docs/results/voxel-bench.md.
pub const AUTO_COARSE_DOFS: usize = 30_000;

/// A [`Settings::rotation_refresh_angle`] [rad] with which a bent block tumbling at 6 rad/s
/// gains no energy at h = 1/60 s (18.5 % without) and `bunny_slice.ron` none after its last cut.
pub const RECOMMENDED_ROTATION_REFRESH_ANGLE: Real = 0.05;

/// Fixed parameters of a run.
#[derive(Clone, Debug)]
pub struct Settings {
    /// Time step `h` [s].
    pub time_step: Real,
    /// Gravity [m/s²].
    pub gravity: Vector3<Real>,
    /// Mass-proportional Rayleigh damping `α` [1/s].
    pub rayleigh_alpha: Real,
    /// Stiffness-proportional Rayleigh damping `β` [s].
    pub rayleigh_beta: Real,
    /// The linear solver.
    pub solver: Solver,
    /// The CG preconditioner (ignored by Cholesky).
    pub preconditioner: Preconditioner,
    /// A step fails as diverged when a node moves farther than this many rest-shape diagonals.
    pub divergence_factor: Real,
    /// Remove, after each solve, the angular momentum that the linearized elastic forces and the
    /// couples of surface contact pairs added to a free piece (no pins), so that internal forces
    /// conserve it as they do in the continuum, on pieces whose rotation the step resolves
    /// (docs/math/corotated-integrator.md, "Angular momentum"). Off by default: the correction
    /// is explicit, and on pieces that turn fast or are stiff slivers it is limited to 1 % of
    /// their angular momentum per step, where it is not exact; looser limits added energy on
    /// `bunny_slice.ron`.
    pub conserve_angular_momentum: bool,
    /// When some frame turns by more than this angle [rad] within a step (between its rotation
    /// at `x` and at the step's solution `x + h v⁺`), the step is solved once more with the
    /// rotations of that solution (docs/math/corotated-integrator.md, "Rotations of fast-turning
    /// steps"): the lagged rotations of the linearly implicit step put elastic energy
    /// ∝ (ω h)² into a piece that tumbles. `None` (the default): never; it costs a second
    /// numeric factorization in every step that turns that much (on `bunny_slice.ron` at
    /// [`RECOMMENDED_ROTATION_REFRESH_ANGLE`], a third of its steps). Steps that turn less are
    /// bit for bit the plain step.
    pub rotation_refresh_angle: Option<Real>,
}

impl Settings {
    /// Defaults: matrix-free CG at 1e-6 with the `Auto` preconditioner, no damping, Earth
    /// gravity along −z, h = 1/60 s, the plain step (no angular momentum correction, no second
    /// solve of fast-turning steps).
    pub fn new(time_step: Real) -> Self {
        Self {
            time_step,
            gravity: Vector3::new(0.0, 0.0, -9.81),
            rayleigh_alpha: 0.0,
            rayleigh_beta: 0.0,
            solver: Solver::ConjugateGradient { tolerance: 1e-6, max_iterations: 2000, assembled: false },
            preconditioner: Preconditioner::Auto,
            divergence_factor: 1e3,
            conserve_angular_momentum: false,
            rotation_refresh_angle: None,
        }
    }
}

/// Wall-clock seconds per phase of one step.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PhaseSeconds {
    /// Rotation extraction.
    pub rotations: Real,
    /// Forces, right-hand side and (assembled paths) matrix assembly.
    pub assembly: Real,
    /// Factorization and solve, or CG.
    pub solve: Real,
    /// Everything else (update, energies, checks).
    pub rest: Real,
    /// Finding contacts (part of `assembly`).
    pub contact: Real,
    /// Growing the pattern and its symbolic factorization for new surface contacts (part of
    /// `assembly`; zero in most steps). In the first step after a topology change only merging
    /// that step's contact couplings into the epoch's new pattern counts here: the pattern and
    /// symbolic factorization the change needs anyway count in `assembly` alone.
    pub pattern: Real,
    /// Adding the active contacts' forces and matrix blocks (and penalty pins', where there are
    /// any; part of `assembly`).
    pub contact_forces: Real,
}

impl PhaseSeconds {
    /// Sum of all phases.
    pub fn total(&self) -> Real {
        self.rotations + self.assembly + self.solve + self.rest
    }
}

/// What one step did.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct StepReport {
    /// Index of the step (0-based).
    pub step: u64,
    /// Simulated time after the step [s].
    pub time: Real,
    /// CG iterations (1 for a direct solve).
    pub iterations: usize,
    /// Final relative residual `‖b − A v‖ / max(‖b‖, h‖f_ext‖)` (0 for a direct solve).
    pub residual: Real,
    /// Phase timings.
    pub seconds: PhaseSeconds,
    /// Kinetic energy `½ vᵀMv` [J].
    pub kinetic_energy: Real,
    /// Warped elastic energy [J].
    pub elastic_energy: Real,
    /// Gravitational potential `−f_extᵀ x` [J].
    pub gravitational_energy: Real,
    /// Penalty energy of contacts and pins [J].
    pub penalty_energy: Real,
    /// Elements with `det F ≤ 0`.
    pub inverted_elements: usize,
    /// Contact points in contact (all kinds).
    pub active_contacts: usize,
    /// Active contacts per kind, deepest penetration and the time spent finding contacts.
    pub contacts: ContactStats,
}

impl StepReport {
    /// Kinetic + elastic + gravitational + penalty energy [J].
    pub fn total_energy(&self) -> Real {
        self.kinetic_energy + self.elastic_energy + self.gravitational_energy + self.penalty_energy
    }
}

/// How many times a step is solved again for pairs its solution drives into each other.
const DRIVEN_CONTACT_PASSES: usize = 2;

/// The factors of a step's matrix `(1 + hα) M + (hβ + h²) K_R` and the time step.
#[derive(Clone, Copy, Debug)]
struct StepScales {
    mass: Real,
    stiffness: Real,
    h: Real,
}

/// Per-step scratch, sized once per epoch.
#[derive(Debug, Default)]
struct Workspace {
    rhs: Vec<Real>,
    /// The rotations of `x + h v⁺` (warm-started from the step's), with the inverted count: the
    /// end-of-step rotations when no refresh follows. (The step's force, trial positions and
    /// stiffness actions live in the CG vectors between solves: `CgWorkspace::spare`.)
    trial_rotations: Vec<Matrix3<Real>>,
    trial_inverted: Option<usize>,
    preconditioner: Vec<Matrix3<Real>>,
    contacts: ContactSet,
    matrix_scratch: MatrixScratch,
    cg: CgWorkspace,
    low_rank: LowRankUpdate,
}

/// Owns the state `{x, v, epoch}` and advances it.
pub struct Integrator {
    settings: Settings,
    constraints: Constraints,
    x: Vec<Real>,
    v: Vec<Real>,
    rotations: Vec<Matrix3<Real>>,
    external_force: Vec<Real>,
    pinned: Vec<bool>,
    epoch: u64,
    step: u64,
    time: Real,
    divergence_limit: Real,
    system: Option<AssembledSystem>,
    two_level: Option<TwoLevel>,
    /// The piecewise preconditioner ([`Preconditioner::Pieces`]) of this epoch.
    pieces: Option<PiecePreconditioner>,
    work: Workspace,
    last_inverted: usize,
    /// Times the pattern grew for new surface contacts (whole run).
    pattern_growths: u64,
    /// Wall time of the last fill of the matrix values that ran without a symbolic factorization
    /// beside it: what a growth's fill is measured against.
    last_fill_seconds: Real,
    /// Whether the assembled system of this epoch is still to be built (by the next step).
    assembly_pending: bool,
    /// Whether the contacts were found for an earlier state (set by a topology change).
    contacts_stale: bool,
    /// Pieces without pins, whose elastic torque a step removes.
    free_pieces: FreePieces,
}

impl Integrator {
    /// Starts at rest in the rest shape of `discretization`.
    pub fn new(
        discretization: &dyn Discretization,
        settings: Settings,
        constraints: Constraints,
    ) -> Result<Self, StepError> {
        let x = discretization.rest_dofs().to_vec();
        let v = vec![0.0; x.len()];
        let mut integrator = Self {
            settings,
            constraints,
            x,
            v,
            rotations: Vec::new(),
            external_force: Vec::new(),
            pinned: Vec::new(),
            epoch: discretization.epoch(),
            step: 0,
            time: 0.0,
            divergence_limit: 0.0,
            system: None,
            two_level: None,
            pieces: None,
            work: Workspace::default(),
            last_inverted: 0,
            pattern_growths: 0,
            last_fill_seconds: 0.0,
            assembly_pending: false,
            contacts_stale: false,
            free_pieces: FreePieces::default(),
        };
        integrator.rebuild(discretization, false, None).map_err(|kind| StepError { step: 0, kind })?;
        Ok(integrator)
    }

    /// Rebuilds everything that depends on the topology: loads, pins, pattern, factorization
    /// (or, with `defer_assembly`, leaves the assembled system to the next step, which builds it
    /// with that step's contact couplings in it).
    fn rebuild(
        &mut self,
        discretization: &dyn Discretization,
        defer_assembly: bool,
        // Contact structures built beforehand for these constraints (checked by the caller).
        prepared: Option<ContactSet>,
    ) -> Result<(), StepErrorKind> {
        let n = self.x.len();
        // Warm starts survive a topology change when the caller remapped them frame by frame.
        if self.rotations.len() != discretization.num_frames() {
            self.rotations = vec![Matrix3::identity(); discretization.num_frames()];
        }
        self.last_inverted = discretization.write_rotations(&self.x, &mut self.rotations).inverted;
        self.external_force = vec![0.0; n];
        let g = self.settings.gravity;
        if g != Vector3::zeros() {
            discretization.add_gravity_load(&g, &mut self.external_force);
        }
        if !self.constraints.extra_load.is_empty() {
            if self.constraints.extra_load.len() != n {
                let len = self.constraints.extra_load.len();
                return Err(StepErrorKind::LoadLength { what: "extra load", len, dofs: n });
            }
            self.external_force.iter_mut().zip(&self.constraints.extra_load).for_each(|(f, e)| *f += e);
        }
        self.pinned = vec![false; n];
        for &d in &self.constraints.pinned_dofs {
            if d >= n {
                return Err(StepErrorKind::DofOutOfRange { what: "pinned", dof: d, dofs: n });
            }
            self.pinned[d] = true;
        }
        self.check_embeddings(discretization.num_nodes())?;
        let rest = discretization.rest_dofs();
        let (mut lo, mut hi) = (Point3::from([Real::MAX; 3]), Point3::from([Real::MIN; 3]));
        for p in rest.chunks_exact(3) {
            for a in 0..3 {
                lo[a] = lo[a].min(p[a]);
                hi[a] = hi[a].max(p[a]);
            }
        }
        self.divergence_limit = self.settings.divergence_factor * (hi - lo).norm().max(1e-3);
        // The piecewise preconditioner assembles the elastic part itself and multiplies with it
        // (contacts matrix-free): an assembled system with contact couplings would only be filled.
        let needs_assembly = match self.settings.solver {
            Solver::Cholesky => true,
            Solver::ConjugateGradient { assembled, .. } => {
                assembled && discretization.wants_assembly() && self.settings.preconditioner != Preconditioner::Pieces
            }
        };
        self.assembly_pending = needs_assembly && defer_assembly;
        self.system = if needs_assembly && !defer_assembly {
            Some(AssembledSystem::new(discretization, &self.constraints, self.settings.solver == Solver::Cholesky)?)
        } else {
            None
        };
        self.two_level = None;
        let cg = matches!(self.settings.solver, Solver::ConjugateGradient { .. });
        self.pieces = if cg && self.settings.preconditioner == Preconditioner::Pieces {
            Some(PiecePreconditioner::new(discretization, &self.constraints, &self.pinned)?)
        } else {
            None
        };
        let wants_two_level =
            cg && !matches!(self.settings.preconditioner, Preconditioner::BlockJacobi | Preconditioner::Pieces);
        if wants_two_level {
            let space = discretization.coarse_space().filter(|space| {
                self.settings.preconditioner == Preconditioner::TwoLevel || 3 * space.num_nodes <= AUTO_COARSE_DOFS
            });
            if let Some(space) = space {
                let h = self.settings.time_step;
                let mass_scale = 1.0 + h * self.settings.rayleigh_alpha;
                let stiffness_scale = h * self.settings.rayleigh_beta + h * h;
                let pins = self.constraints.penalty_pins.as_ref();
                self.two_level =
                    Some(TwoLevel::new(discretization, space, &self.pinned, pins, mass_scale, stiffness_scale, h)?);
            }
        }
        self.work.rhs = vec![0.0; n];
        self.work.cg.spare(n);
        // Only a refresh compares the trial rotations with the step's (72 B a frame otherwise).
        self.work.trial_rotations = match self.settings.rotation_refresh_angle {
            Some(_) => vec![Matrix3::identity(); self.rotations.len()],
            None => Vec::new(),
        };
        self.work.preconditioner = vec![Matrix3::zeros(); discretization.num_nodes()];
        let previous = std::mem::take(&mut self.work.contacts);
        self.work.contacts = match prepared {
            Some(mut prepared) => {
                prepared.forget_steps();
                prepared
            }
            None => ContactSet::new(&self.constraints.colliders(), discretization.rest_dofs()),
        };
        self.work.contacts.reuse_trees(previous);
        // The penetrating pairs of the new state are found only if its energy is asked for
        // before the next step finds its own (a detection builds every hierarchy from scratch:
        // 48 ms per cut on bunny_slice, for a number nobody read).
        self.contacts_stale = self.constraints.has_contact();
        self.free_pieces = if self.settings.conserve_angular_momentum {
            let pinned_nodes = self.constraints.pinned_dofs.iter().map(|&d| d / 3);
            let pin_nodes =
                self.constraints.penalty_pins.iter().flat_map(|pins| {
                    (0..pins.points.len()).flat_map(|i| pins.points.row(i).0.iter().map(|&n| n as usize))
                });
            FreePieces::new(discretization, pinned_nodes.chain(pin_nodes))
        } else {
            FreePieces::default()
        };
        self.epoch = discretization.epoch();
        Ok(())
    }

    /// Contact and penalty-pin rows must name existing nodes, and every pin needs one target:
    /// checked once per epoch so that the per-step loops can index without failing.
    fn check_embeddings(&self, nodes: usize) -> Result<(), StepErrorKind> {
        let contacts = self.constraints.contact_points.as_ref().map(|points| ("contact point", points));
        let pins = self.constraints.penalty_pins.as_ref().map(|pins| ("penalty pin", &pins.points));
        for (what, points) in contacts.into_iter().chain(pins) {
            for row in 0..points.len() {
                if let Some(&node) = points.row(row).0.iter().find(|&&node| node as usize >= nodes) {
                    return Err(StepErrorKind::NodeOutOfRange { what, row, node, nodes });
                }
            }
        }
        if let Some(pins) = &self.constraints.penalty_pins
            && pins.targets.len() != pins.points.len()
        {
            return Err(StepErrorKind::PinTargets { targets: pins.targets.len(), points: pins.points.len() });
        }
        if let Some(surface) = &self.constraints.surface_contact
            && !surface.piece.is_empty()
            && surface.piece.len() != surface.triangles.len()
        {
            return Err(StepErrorKind::SurfacePieces {
                pieces: surface.piece.len(),
                triangles: surface.triangles.len(),
            });
        }
        Ok(())
    }

    /// Carries the state across a topology change and rebuilds the per-epoch structures, between
    /// steps (never inside one). `discretization` is already in its new epoch; `change` is what
    /// its cut, fracture or refinement returned. `x` and `v` are remapped by `change.remap`
    /// (exactly: a `Gather` copies, a `Linear` interpolates, so every material point keeps its
    /// position and velocity), the rotations by `change.frames` (warm starts, not identities).
    /// Then loads, pins, pattern, symbolic factorization and coarse space are rebuilt for the
    /// new topology; the caller passes constraints resolved again on it (pins from their
    /// rest-space regions, contact rows from the new surface, weak boundary loads). With surface
    /// contact the assembled system (pattern, symbolic factorization) is left to the next
    /// [`step`](Self::step), which builds it with its contact couplings in it, so an error
    /// setting it up comes from there.
    pub fn apply_topology_change(
        &mut self,
        discretization: &dyn Discretization,
        change: &TopologyChange,
        constraints: Constraints,
    ) -> Result<(), StepError> {
        self.apply_topology_change_with(discretization, change, constraints, None).map(|_| ())
    }

    /// [`apply_topology_change`](Self::apply_topology_change) with the contact structures of
    /// the new topology built beforehand ([`ContactSet::new`], e.g. off the step's thread by a
    /// caller that knew the change ahead). They are used if they were built from the same
    /// contact points, surface and rest positions as `constraints` and `discretization` hold
    /// (checked by their sizes and a hash of all they were built from), else built again here.
    /// Returns whether they were used.
    pub fn apply_topology_change_with(
        &mut self,
        discretization: &dyn Discretization,
        change: &TopologyChange,
        constraints: Constraints,
        prepared: Option<ContactSet>,
    ) -> Result<bool, StepError> {
        let fail = |kind| StepError { step: self.step, kind };
        let old_nodes = self.x.len() / 3;
        let new_nodes = change.remap.new_num_nodes(old_nodes);
        if new_nodes != discretization.num_nodes() || change.epoch != discretization.epoch() {
            return Err(fail(StepErrorKind::Solver(format!(
                "topology change to epoch {} with {new_nodes} nodes does not match the discretization \
                 (epoch {}, {} nodes)",
                change.epoch,
                discretization.epoch(),
                discretization.num_nodes()
            ))));
        }
        let mut remapped = Vec::with_capacity(3 * new_nodes);
        change.remap.apply_into(&self.x, &mut remapped);
        std::mem::swap(&mut self.x, &mut remapped);
        change.remap.apply_into(&self.v, &mut remapped);
        std::mem::swap(&mut self.v, &mut remapped);
        self.rotations = change.frames.apply(&self.rotations);
        self.constraints = constraints;
        // With surface contact the first step's contacts grow the pattern anyway: its system is
        // built then, with them, and one symbolic factorization per cut is saved.
        let defer = self.constraints.surface_contact.is_some();
        let prepared = prepared.filter(|p| p.built_for(&self.constraints.colliders(), discretization.rest_dofs()));
        let used = prepared.is_some();
        self.rebuild(discretization, defer, prepared).map(|()| used).map_err(|kind| StepError { step: self.step, kind })
    }

    /// Current positions (DOF vector).
    pub fn positions(&self) -> &[Real] {
        &self.x
    }

    /// Current velocities.
    pub fn velocities(&self) -> &[Real] {
        &self.v
    }

    /// Sets positions and velocities (e.g. an initial stretch), refreshing the rotations.
    pub fn set_state(&mut self, discretization: &dyn Discretization, x: Vec<Real>, v: Vec<Real>) {
        assert_eq!(x.len(), self.x.len(), "state has the wrong length");
        assert_eq!(v.len(), self.v.len(), "state has the wrong length");
        self.x = x;
        self.v = v;
        self.last_inverted = discretization.write_rotations(&self.x, &mut self.rotations).inverted;
        self.contacts_stale = self.constraints.has_contact();
    }

    /// Overwrites part of the state in place (`edit` gets positions and velocities; e.g. the
    /// nodes of a piece that moves as a rigid body elsewhere), then refreshes the rotations.
    /// Allocates nothing.
    pub fn edit_state(&mut self, discretization: &dyn Discretization, edit: impl FnOnce(&mut [Real], &mut [Real])) {
        edit(&mut self.x, &mut self.v);
        self.last_inverted = discretization.write_rotations(&self.x, &mut self.rotations).inverted;
        self.contacts_stale = self.constraints.has_contact();
    }

    /// The DOFs held where they are (velocity zero) in a step.
    pub fn pinned_dofs(&self) -> &[usize] {
        &self.constraints.pinned_dofs
    }

    /// Changes which DOFs are pinned (e.g. the nodes of pieces that move as rigid bodies, which
    /// then sit still in the step) and rebuilds what depends on them as a topology change does
    /// (pattern, factorization, preconditioner; with surface contact left to the next step).
    pub fn set_pinned_dofs(
        &mut self,
        discretization: &dyn Discretization,
        pinned_dofs: Vec<usize>,
    ) -> Result<(), StepError> {
        self.constraints.pinned_dofs = pinned_dofs;
        let defer = self.constraints.surface_contact.is_some();
        self.rebuild(discretization, defer, None).map_err(|kind| StepError { step: self.step, kind })
    }

    /// Current rotations (one per frame, valid for the current positions).
    pub fn rotations(&self) -> &[Matrix3<Real>] {
        &self.rotations
    }

    /// Simulated time [s].
    pub fn time(&self) -> Real {
        self.time
    }

    /// Number of steps taken.
    pub fn steps_taken(&self) -> u64 {
        self.step
    }

    /// The settings.
    pub fn settings(&self) -> &Settings {
        &self.settings
    }

    /// Nonzeros of the assembled matrix and of its Cholesky factor, if assembled (`None` also
    /// between a topology change with surface contact and the next step, which builds it).
    pub fn matrix_stats(&self) -> Option<(usize, Option<usize>)> {
        self.system.as_ref().map(|s| (s.pattern.nnz(), s.factor_nnz()))
    }

    /// Times the assembled pattern grew for surface contacts between nodes it did not couple.
    pub fn pattern_growths(&self) -> u64 {
        self.pattern_growths
    }

    /// Coarse DOFs and nonzeros of the coarse Cholesky factor, if the two-level preconditioner
    /// is active.
    pub fn coarse_stats(&self) -> Option<(usize, usize)> {
        self.two_level.as_ref().map(TwoLevel::size)
    }

    /// Times this epoch's coarse operator was factorized again to take the steps' contacts
    /// (two-level preconditioner only).
    pub fn coarse_refreshes(&self) -> Option<usize> {
        self.two_level.as_ref().map(TwoLevel::refreshes)
    }

    /// Energies of the current state (rotations must be current, which they are between steps).
    pub fn energies(&mut self, discretization: &dyn Discretization) -> StepReport {
        let mut report = StepReport {
            step: self.step,
            time: self.time,
            kinetic_energy: discretization.mass().kinetic_energy(&self.v),
            elastic_energy: discretization.elastic_energy(&self.rotations, &self.x),
            gravitational_energy: -cleave_core::reduce::deterministic_sum(self.x.len(), |i| {
                self.external_force[i] * self.x[i]
            }),
            inverted_elements: self.last_inverted,
            ..Default::default()
        };
        let (energy, active) = self.penalty_energy();
        report.penalty_energy = energy;
        report.active_contacts = active;
        report
    }

    /// Penalty energy of the pins and of the contact pairs the last step acted on, at the
    /// current state (pairs keep their normal and barycentric point; a pair that separated
    /// contributes nothing).
    fn penalty_energy(&mut self) -> (Real, usize) {
        let mut energy = 0.0;
        let mut active = 0;
        if self.contacts_stale {
            // Energy is a function of the state: the pairs penetrating now.
            self.work.contacts.detect(&self.constraints.colliders(), &self.x, &self.v, 0.0, &Vector3::zeros());
            self.contacts_stale = false;
        }
        if let Some(points) = self.constraints.contact_points.as_ref().filter(|_| self.constraints.has_contact()) {
            (energy, active) = cleave_contact::energy(points, self.work.contacts.contacts(), &self.x);
        }
        if let Some(pins) = &self.constraints.penalty_pins {
            for (i, target) in pins.targets.iter().enumerate() {
                energy += 0.5 * pins.stiffness * (pins.points.point(&self.x, i) - target).norm_squared();
            }
        }
        (energy, active)
    }

    /// Advances one step of size `h`.
    pub fn step(&mut self, discretization: &dyn Discretization) -> Result<StepReport, StepError> {
        let step = self.step;
        self.step_inner(discretization).map_err(|kind| StepError { step, kind })
    }

    fn step_inner(&mut self, discretization: &dyn Discretization) -> Result<StepReport, StepErrorKind> {
        if discretization.epoch() != self.epoch {
            return Err(StepErrorKind::Solver(format!(
                "the discretization is at epoch {} but the integrator at {}: call apply_topology_change",
                discretization.epoch(),
                self.epoch
            )));
        }
        let h = self.settings.time_step;
        // Every DOF pinned (e.g. the whole body moving as a rigid body elsewhere, which writes
        // its motion after the step): nothing moves and nothing is solved.
        if !self.pinned.is_empty() && self.pinned.iter().all(|&p| p) {
            let clock = Instant::now();
            self.v.fill(0.0);
            self.step += 1;
            self.time += h;
            let mut report = self.energies(discretization);
            report.step = self.step - 1;
            report.seconds.rest = clock.elapsed().as_secs_f64();
            return Ok(report);
        }
        let (alpha, beta) = (self.settings.rayleigh_alpha, self.settings.rayleigh_beta);
        let scales = StepScales { mass: 1.0 + h * alpha, stiffness: h * beta + h * h, h };
        let mut seconds = PhaseSeconds::default();
        let clock = Instant::now();
        self.detect_and_load(discretization, &mut seconds);
        // Assemble and solve; then, once or twice, the pairs that were near but not active and
        // that the solution drives into each other (a piece deflected into another within the
        // step, which the start-of-step velocities did not predict) join the step and it is
        // solved again with the same right-hand side (their gap is not negative, so they add
        // no force, only the implicit term that stops their approach: docs/math/contact.md §3).
        let mut assembly_clock = clock;
        let mut passes = 0;
        // Iterations summed over the passes (a Cholesky pass counts one).
        let mut iterations = 0;
        let mut rotations_refreshed = false;
        let mut pieces_prepared = false;
        self.work.trial_inverted = None;
        let mut built_with_contacts = self.build_pending_system(discretization, &mut seconds)?;
        let residual = loop {
            // A system just built with this step's contacts has their couplings already.
            let skip_growth = std::mem::take(&mut built_with_contacts);
            self.assemble(discretization, scales, skip_growth, &mut seconds)?;
            seconds.assembly += assembly_clock.elapsed().as_secs_f64();

            let clock = Instant::now();
            let solved = self.solve(discretization, scales, &mut pieces_prepared)?;
            iterations += solved.0;
            // Pairs the solution drives together join the step (one or two more passes); the
            // search for them counts as solve time.
            let finished = self.join_driven_pairs(h, &mut passes, &mut iterations);
            seconds.solve += clock.elapsed().as_secs_f64();
            if finished {
                if !rotations_refreshed && self.refresh_rotations(discretization, h, &mut seconds) {
                    rotations_refreshed = true;
                    pieces_prepared = false;
                    assembly_clock = Instant::now();
                    continue;
                }
                break solved.1;
            }
            assembly_clock = Instant::now();
        };
        self.finish_step(discretization, h, (iterations, residual), seconds)
    }

    /// The step's right-hand side `M v + h (f_int(x) + f_ext + f_c(x))`, pinned rows zeroed,
    /// with this step's contacts found at `x` first (their forces are in it).
    fn detect_and_load(&mut self, discretization: &dyn Discretization, seconds: &mut PhaseSeconds) {
        let h = self.settings.time_step;
        let mass = discretization.mass();
        // The force lives in a CG vector until the right-hand side has it (taken out of `self`
        // so the contact and pin loops can borrow the rest; a move, no allocation).
        let mut cg = std::mem::take(&mut self.work.cg);
        let [force, _, _] = cg.spare(self.x.len());
        let rhs = &mut self.work.rhs;
        force.copy_from_slice(&self.external_force);
        discretization.add_internal_force(&self.rotations, &self.x, force);
        if !self.free_pieces.is_empty() {
            let external = &self.external_force;
            let force = &*force;
            self.free_pieces.record_start_torque(&self.x, |node| {
                Vector3::from_fn(|a, _| force[3 * node + a] - external[3 * node + a])
            });
        }
        mass.apply(&self.v, rhs);
        let contact_clock = Instant::now();
        if self.constraints.has_contact() {
            self.work.contacts.detect(&self.constraints.colliders(), &self.x, &self.v, h, &self.settings.gravity);
        }
        self.contacts_stale = false;
        seconds.contact = contact_clock.elapsed().as_secs_f64();
        let forces_clock = Instant::now();
        self.add_penalty_forces(force);
        seconds.contact_forces += forces_clock.elapsed().as_secs_f64();
        let rhs = &mut self.work.rhs;
        rhs.par_iter_mut().zip(&*force).for_each(|(r, f)| *r += h * f);
        for (r, &p) in rhs.iter_mut().zip(&self.pinned) {
            if p {
                *r = 0.0;
            }
        }
        self.work.cg = cg;
    }

    /// The epoch's assembled system when a topology change left it to this step: its pattern
    /// with this step's contact couplings merged in. Returns whether it was built.
    fn build_pending_system(
        &mut self,
        discretization: &dyn Discretization,
        seconds: &mut PhaseSeconds,
    ) -> Result<bool, StepErrorKind> {
        if !self.assembly_pending {
            return Ok(false);
        }
        let mut pattern = AssembledSystem::base_pattern(discretization, &self.constraints);
        // Only merging this step's contact couplings counts as contact's pattern work: the
        // epoch's own pattern and symbolic factorization are what the topology change needs
        // with or without contact (built here, once, instead of at the change and again
        // for the contacts).
        let clock = Instant::now();
        if let Some(points) =
            self.constraints.contact_points.as_ref().filter(|_| self.constraints.surface_contact.is_some())
        {
            let missing = penalty::missing_couplings(points, &self.work.contacts, &pattern);
            if !missing.is_empty() {
                pattern = pattern.with_groups(missing.iter().map(Vec::as_slice));
            }
        }
        seconds.pattern += clock.elapsed().as_secs_f64();
        let cholesky = self.settings.solver == Solver::Cholesky;
        self.system = Some(AssembledSystem::on_pattern(pattern, discretization, &self.constraints, cholesky)?);
        self.assembly_pending = false;
        Ok(true)
    }

    /// Fills the assembled system (if the solver uses one) with the step matrix and the
    /// contacts' blocks, first growing its pattern for contact couplings it lacks (unless it
    /// was just built with them).
    fn assemble(
        &mut self,
        discretization: &dyn Discretization,
        scales: StepScales,
        skip_growth: bool,
        seconds: &mut PhaseSeconds,
    ) -> Result<(), StepErrorKind> {
        let StepScales { mass: mass_scale, stiffness: stiffness_scale, h } = scales;
        let mut grew = false;
        if !skip_growth
            && let Some(system) = &self.system
            && self.constraints.surface_contact.is_some()
            && let Some(points) = &self.constraints.contact_points
        {
            // A point and a surface triangle that were never in contact in this epoch couple
            // nodes the pattern lacks: grow the pattern (a new symbolic factorization), keeping
            // every coupling seen so far, so contacts that persist cost nothing more.
            let missing = penalty::missing_couplings(points, &self.work.contacts, &system.pattern);
            if !missing.is_empty() {
                let clock = Instant::now();
                self.system = Some(system.grown(&missing, discretization, &self.constraints)?);
                self.pattern_growths += 1;
                seconds.pattern += clock.elapsed().as_secs_f64();
                grew = true;
            }
        }
        if let Some(system) = &mut self.system {
            let clock = Instant::now();
            let with_symbolic = system.symbolic_pending();
            let (constraints, rotations) = (&self.constraints, &self.rotations);
            let contacts = (&self.work.contacts, &self.work.matrix_scratch);
            let (fill_seconds, forces_seconds) = system.fill_beside_symbolic(|system, values| {
                let clock = Instant::now();
                system.fill_values(values, discretization, rotations, mass_scale, stiffness_scale);
                let forces_clock = Instant::now();
                Self::add_penalty_matrix(constraints, contacts, h, system, values);
                let forces_seconds = forces_clock.elapsed().as_secs_f64();
                system.apply_pins_to(values);
                (clock.elapsed().as_secs_f64(), forces_seconds)
            })?;
            seconds.contact_forces += forces_seconds;
            if !with_symbolic {
                self.last_fill_seconds = fill_seconds;
            } else if grew {
                // The growth's symbolic factorization ran beside the fill: it cost what the
                // two took beyond a fill alone.
                seconds.pattern += (clock.elapsed().as_secs_f64() - self.last_fill_seconds).max(0.0);
            }
        }
        Ok(())
    }

    /// Solves the assembled or matrix-free system for `v⁺`: iterations (a Cholesky solve counts
    /// one) and the relative residual.
    fn solve(
        &mut self,
        discretization: &dyn Discretization,
        scales: StepScales,
        pieces_prepared: &mut bool,
    ) -> Result<(usize, Real), StepErrorKind> {
        let StepScales { mass: mass_scale, stiffness: stiffness_scale, h } = scales;
        let mass = discretization.mass();
        Ok(match self.settings.solver {
            Solver::Cholesky => {
                let system = self.system.as_mut().expect("Cholesky builds the system");
                system.factorize()?;
                self.v.copy_from_slice(&self.work.rhs);
                system.solve_in_place(&mut self.v);
                (1, 0.0)
            }
            Solver::ConjugateGradient { tolerance, max_iterations, .. } => {
                // The piecewise factors are those of the step's first pass (and of its second
                // rotations): pairs that join in a later pass are in CG's operator, and any
                // positive definite preconditioner keeps CG valid.
                if let Some(pieces) = self.pieces.as_mut().filter(|_| !*pieces_prepared) {
                    *pieces_prepared = true;
                    let contacts = self.work.contacts.contacts();
                    let (constraints, rotations, x) = (&self.constraints, &self.rotations, &self.x);
                    pieces.prepare(
                        discretization,
                        constraints,
                        rotations,
                        x,
                        contacts,
                        mass_scale,
                        stiffness_scale,
                        h,
                    )?;
                } else if self.pieces.is_none() {
                    self.build_preconditioner(discretization, mass_scale, stiffness_scale, h);
                }
                if let (Some(two_level), Some(points)) =
                    (self.two_level.as_mut(), self.constraints.contact_points.as_ref())
                {
                    two_level.take_contacts(points, self.work.contacts.contacts())?;
                }
                for (v, &p) in self.v.iter_mut().zip(&self.pinned) {
                    if p {
                        *v = 0.0;
                    }
                }
                let pinned = &self.pinned;
                let rotations = &self.rotations;
                let contact_points = self.constraints.contact_points.as_ref();
                let contacts = self.work.contacts.contacts();
                let penalty_pins = self.constraints.penalty_pins.as_ref();
                let system = &self.system;
                let preconditioner = &self.work.preconditioner;
                let mut two_level = self.two_level.as_mut();
                let (pieces_operator, mut pieces_correction) = match self.pieces.as_mut() {
                    Some(pieces) => {
                        let (operator, correction) = pieces.split();
                        (Some(operator), Some(correction))
                    }
                    None => (None, None),
                };
                let x = &self.x;
                // One step's external impulse `h ‖f_ext‖` floors the residual scale (see cg.rs).
                let load_scale = h * self.external_force.iter().map(|f| f * f).sum::<Real>().sqrt();
                let outcome = self.work.cg.solve(
                    |p, out| match (&pieces_operator, system) {
                        (Some(operator), _) => operator.multiply(contact_points, contacts, pinned, p, out),
                        (None, Some(s)) => {
                            s.pattern.mul_vec(&s.values, p, out);
                        }
                        (None, None) => {
                            mass.apply(p, out);
                            if mass_scale != 1.0 {
                                out.iter_mut().for_each(|o| *o *= mass_scale);
                            }
                            discretization.add_stiffness_action(rotations, p, stiffness_scale, out);
                            if let Some(points) = contact_points {
                                cleave_contact::add_action(points, contacts, p, out);
                            }
                            add_pin_action(penalty_pins, h, p, out);
                            for (o, &pin) in out.iter_mut().zip(pinned) {
                                if pin {
                                    *o = 0.0;
                                }
                            }
                        }
                    },
                    |r, z| {
                        if let Some(correction) = pieces_correction.as_mut() {
                            correction.apply(x, r, z);
                            return;
                        }
                        z.par_chunks_mut(3).zip(r.par_chunks(3)).zip(preconditioner).for_each(|((z, r), m)| {
                            let y = m * Vector3::new(r[0], r[1], r[2]);
                            z.copy_from_slice(y.as_slice());
                        });
                        if let Some(two_level) = two_level.as_deref_mut() {
                            two_level.add_correction(r, z);
                        }
                    },
                    &self.work.rhs,
                    load_scale,
                    &mut self.v,
                    tolerance,
                    max_iterations,
                );
                if !outcome.converged {
                    return Err(StepErrorKind::CgNotConverged {
                        iterations: outcome.iterations,
                        residual: outcome.relative_residual,
                        tolerance,
                    });
                }
                (outcome.iterations, outcome.relative_residual)
            }
        })
    }

    /// Activates the near pairs the solution drives into each other and, with a factorization
    /// at hand, solves them in as a low-rank update. Returns whether the step's solution is
    /// final (`false`: assemble and solve again with them).
    fn join_driven_pairs(&mut self, h: Real, passes: &mut usize, iterations: &mut usize) -> bool {
        if *passes == DRIVEN_CONTACT_PASSES {
            return true;
        }
        let Some(points) = self.constraints.contact_points.as_ref() else { return true };
        let mut added = self.work.contacts.activate_driven(points, &self.v, h);
        if added == 0 {
            return true;
        }
        *passes += 1;
        // With a factorization at hand, the pairs that joined are a low-rank update of it
        // (low_rank.rs); their couplings join the pattern when the next step's contacts need
        // them. Too many columns, or a capacitance that is not positive definite: the pattern
        // grows and the matrix is factorized again with them.
        if self.settings.solver != Solver::Cholesky || *passes != 1 {
            return false;
        }
        let system = self.system.as_mut().expect("Cholesky builds the system");
        let update = &mut self.work.low_rank;
        update.begin(&self.v);
        let contacts = &mut self.work.contacts;
        loop {
            update.push_contacts(points, &contacts.contacts()[contacts.contacts().len() - added..], &self.pinned);
            if update.rank() > low_rank::MAX_COLUMNS
                || !update.solve(|rhs, count| system.solve_columns_in_place(rhs, count), &mut self.v)
            {
                return false;
            }
            *iterations += 1;
            if *passes == DRIVEN_CONTACT_PASSES {
                return true;
            }
            added = contacts.activate_driven(points, &self.v, h);
            if added == 0 {
                return true;
            }
            *passes += 1;
        }
    }

    /// Positions from `v⁺` (after the lagged normal forces and the optional angular momentum
    /// correction), the divergence check, the end-of-step rotations and the report.
    fn finish_step(
        &mut self,
        discretization: &dyn Discretization,
        h: Real,
        (iterations, residual): (usize, Real),
        mut seconds: PhaseSeconds,
    ) -> Result<StepReport, StepErrorKind> {
        let mass = discretization.mass();
        // Update and check.
        let clock = Instant::now();
        if let Some(dof) = self.v.iter().position(|v| !v.is_finite()) {
            return Err(StepErrorKind::NotFinite { dof });
        }
        if let Some(points) = self.constraints.contact_points.as_ref().filter(|_| self.constraints.has_contact()) {
            self.work.contacts.store_normal_forces(points, &self.v, h);
        }
        // Internal forces conserve angular momentum (docs/math/corotated-integrator.md,
        // "Angular momentum"): elastic torque and contact couples, from the solved v⁺ (after
        // the normal forces friction lags are stored from it).
        if !self.free_pieces.is_empty() {
            let mut cg = std::mem::take(&mut self.work.cg);
            let [kv, _, _] = cg.spare(self.x.len());
            kv.iter_mut().for_each(|k| *k = 0.0);
            discretization.add_stiffness_action(&self.rotations, &self.v, 1.0, kv);
            if self.constraints.surface_contact.is_some()
                && let Some(points) = &self.constraints.contact_points
            {
                let pieces = &mut self.free_pieces;
                self.work.contacts.visit_pair_couples(points, &self.x, &self.v, h, |a, b, couple| {
                    pieces.add_pair_couple(a, b, couple)
                });
            }
            let beta = self.settings.rayleigh_beta;
            self.free_pieces.cancel_elastic_torque(&self.x, mass.diagonal(), kv, h, beta, &mut self.v);
            self.work.cg = cg;
        }
        self.x.par_iter_mut().zip(&self.v).for_each(|(x, v)| *x += h * v);
        let rest = discretization.rest_dofs();
        let distance = self
            .x
            .par_chunks(3)
            .zip(rest.par_chunks(3))
            .map(|(x, r)| ((x[0] - r[0]).powi(2) + (x[1] - r[1]).powi(2) + (x[2] - r[2]).powi(2)).sqrt())
            .reduce(|| 0.0, Real::max);
        if distance > self.divergence_limit {
            return Err(StepErrorKind::Diverged { distance, limit: self.divergence_limit });
        }
        self.step += 1;
        self.time += h;
        let rest_seconds = clock.elapsed().as_secs_f64();

        let clock = Instant::now();
        match self.work.trial_inverted.take().filter(|_| self.free_pieces.is_empty()) {
            // The rotations of x + h v⁺ were found already (the same positions bit for bit:
            // no refresh and no momentum correction changed v⁺ since).
            Some(inverted) => {
                std::mem::swap(&mut self.rotations, &mut self.work.trial_rotations);
                self.last_inverted = inverted;
            }
            None => self.last_inverted = discretization.write_rotations(&self.x, &mut self.rotations).inverted,
        }
        seconds.rotations += clock.elapsed().as_secs_f64();

        let clock = Instant::now();
        let mut report = self.energies(discretization);
        report.step = self.step - 1;
        report.iterations = iterations;
        report.residual = residual;
        report.contacts = ContactStats { seconds: seconds.contact, ..self.work.contacts.stats() };
        seconds.rest = rest_seconds + clock.elapsed().as_secs_f64();
        report.seconds = seconds;
        if !report.total_energy().is_finite() {
            return Err(StepErrorKind::NotFinite { dof: 0 });
        }
        Ok(report)
    }

    /// After a solve: the rotations of `x + h v⁺` (kept for the end of the step), and whether
    /// some frame turned by more than [`Settings::rotation_refresh_angle`] from the step's
    /// rotations. If so the step's rotations become those, the right-hand side takes the
    /// internal force at `x` with them instead of the old ones, and the caller solves again
    /// (docs/math/corotated-integrator.md, "Rotations of fast-turning steps").
    fn refresh_rotations(&mut self, discretization: &dyn Discretization, h: Real, seconds: &mut PhaseSeconds) -> bool {
        let Some(limit) = self.settings.rotation_refresh_angle else { return false };
        let clock = Instant::now();
        let mut cg = std::mem::take(&mut self.work.cg);
        let [trial_x, scratch, _] = cg.spare(self.x.len());
        trial_x.par_iter_mut().zip(&self.x).zip(&self.v).for_each(|((t, x), v)| *t = x + h * v);
        self.work.trial_rotations.copy_from_slice(&self.rotations);
        self.work.trial_inverted =
            Some(discretization.write_rotations(trial_x, &mut self.work.trial_rotations).inverted);
        // cos of the largest turn: tr(Aᵀ B) = 1 + 2 cos θ.
        let cos_turn = self
            .rotations
            .par_iter()
            .zip(&self.work.trial_rotations)
            .map(|(a, b)| 0.5 * (a.component_mul(b).sum() - 1.0))
            .reduce(|| 1.0, Real::min);
        seconds.rotations += clock.elapsed().as_secs_f64();
        if cos_turn >= limit.cos() {
            self.work.cg = cg;
            return false;
        }
        // rhs += h (f(R⁺, x) − f(R, x)) on the free DOFs.
        scratch.iter_mut().for_each(|s| *s = 0.0);
        discretization.add_internal_force(&self.work.trial_rotations, &self.x, scratch);
        scratch.iter_mut().for_each(|s| *s = -*s);
        discretization.add_internal_force(&self.rotations, &self.x, scratch);
        for ((r, s), &pinned) in self.work.rhs.iter_mut().zip(scratch.iter()).zip(&self.pinned) {
            if !pinned {
                *r -= h * s;
            }
        }
        std::mem::swap(&mut self.rotations, &mut self.work.trial_rotations);
        self.work.trial_inverted = None;
        self.work.cg = cg;
        true
    }

    /// Adds contact forces (found by [`ContactSet::detect`] at the start of the step) and
    /// penalty-pin forces at `x` to `force`.
    ///
    /// A contact is active when its point is below the surface at `x` or would be at
    /// `x + h (v + h g)` (gravity only for points not moving away): a point 2.4 m/s fast moves
    /// 4 cm in a 1/60 s step, so testing `x` alone lets it sink a whole step's travel before the
    /// penalty sees it; and a body placed at rest on a plane would otherwise fall freely for its
    /// first step onto thousands of contact points at once. An active contact gets the
    /// linearized force `−k (min(d, 0) + h n·v⁺) n` (the `h² k` matrix term supplies the `v⁺`
    /// part). A point still above the surface (`d > 0`) only has its approach stopped: the
    /// consistent `−k d` would pull it down, and points at the edge of a resting patch,
    /// flickering in and out of the active set, would pump energy into the body through it.
    fn add_penalty_forces(&self, force: &mut [Real]) {
        if let Some(points) = &self.constraints.contact_points {
            cleave_contact::add_forces(points, self.work.contacts.contacts(), force);
        }
        if let Some(pins) = &self.constraints.penalty_pins {
            for (i, target) in pins.targets.iter().enumerate() {
                let f = (target - pins.points.point(&self.x, i)) * pins.stiffness;
                let (nodes, weights) = pins.points.row(i);
                for (&n, &w) in nodes.iter().zip(weights) {
                    for a in 0..3 {
                        force[3 * n as usize + a] += w * f[a];
                    }
                }
            }
        }
    }

    /// Adds the within-side blocks of the active contacts and `h² k I` of penalty pins to the
    /// matrix.
    fn add_penalty_matrix(
        constraints: &Constraints,
        (contacts, scratch): (&ContactSet, &MatrixScratch),
        h: Real,
        system: &AssembledSystem,
        values: &mut [Real],
    ) {
        if let Some(points) = &constraints.contact_points {
            penalty::add_matrix(points, contacts.contacts(), scratch, &system.pattern, values);
        }
        if let Some(pins) = &constraints.penalty_pins {
            let k = Matrix3::identity() * (h * h * pins.stiffness);
            for i in 0..pins.points.len() {
                system.pin_ranks.add_row(&pins.points, i, &k, &system.pattern, values);
            }
        }
    }

    /// 3×3 block-Jacobi preconditioner: inverse diagonal blocks of the system matrix.
    fn build_preconditioner(
        &mut self,
        discretization: &dyn Discretization,
        mass_scale: Real,
        stiffness_scale: Real,
        h: Real,
    ) {
        let blocks = &mut self.work.preconditioner;
        blocks.iter_mut().for_each(|b| *b = Matrix3::zeros());
        discretization.blocks().add_diagonal_blocks(&self.rotations, stiffness_scale, blocks);
        let mass = discretization.mass().diagonal();
        if let Some(points) = &self.constraints.contact_points {
            cleave_contact::add_diagonal_blocks(points, self.work.contacts.contacts(), blocks);
        }
        if let Some(pins) = &self.constraints.penalty_pins {
            for i in 0..pins.points.len() {
                let (nodes, weights) = pins.points.row(i);
                for (&n, &w) in nodes.iter().zip(weights) {
                    blocks[n as usize] += Matrix3::identity() * (h * h * pins.stiffness * w * w);
                }
            }
        }
        let pinned = &self.pinned;
        blocks.par_iter_mut().enumerate().for_each(|(node, b)| {
            for a in 0..3 {
                b[(a, a)] += mass_scale * mass[3 * node + a];
            }
        });
        invert_blocks_with_pins(blocks, pinned);
    }
}

/// Inverts every node's 3×3 diagonal block in place, a pinned DOF's row and column replaced by
/// the identity's first (so the block-Jacobi preconditioner leaves pinned DOFs alone); a singular
/// block falls back to its inverted diagonal.
pub(crate) fn invert_blocks_with_pins(blocks: &mut [Matrix3<Real>], pinned: &[bool]) {
    blocks.par_iter_mut().enumerate().for_each(|(node, b)| {
        for a in 0..3 {
            if pinned[3 * node + a] {
                for c in 0..3 {
                    b[(a, c)] = 0.0;
                    b[(c, a)] = 0.0;
                }
                b[(a, a)] = 1.0;
            }
        }
        *b = b
            .try_inverse()
            .unwrap_or_else(|| Matrix3::from_diagonal(&b.diagonal().map(|d| if d != 0.0 { 1.0 / d } else { 1.0 })));
    });
}

/// `out += h² k p` for penalty pins (matrix-free).
fn add_pin_action(pins: Option<&crate::constraints::PenaltyPins>, h: Real, p: &[Real], out: &mut [Real]) {
    if let Some(pins) = pins {
        let coefficient = h * h * pins.stiffness;
        for i in 0..pins.points.len() {
            let q = pins.points.point(p, i).coords * coefficient;
            let (nodes, weights) = pins.points.row(i);
            for (&n, &w) in nodes.iter().zip(weights) {
                for a in 0..3 {
                    out[3 * n as usize + a] += w * q[a];
                }
            }
        }
    }
}
