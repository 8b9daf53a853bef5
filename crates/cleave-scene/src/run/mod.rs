//! Loading a scene file, building what it names (`build.rs`), the timeline (`timeline.rs`), cuts
//! made ahead on a copy of the body (`cut_ahead.rs`), and here: stepping it and recording every
//! step.

mod build;
mod cut_ahead;
mod rigid;
mod timeline;

use build::{Closed, load_obj, surface_contact_on};
pub use build::{DEFAULT_CONTACT_STIFFNESS, DEFAULT_REACH};
use cut_ahead::{CutCopy, PreparedCut};
pub use rigid::RigidCounts;
use rigid::RigidHybrid;
use timeline::{TimedCut, prepare_timeline};

use crate::record::{RecordError, Recorder};
use crate::schema::Scene;
use cleave_core::{CutSurface, Discretization, Embedding, Matrix3, Piece, Point3, Real, Vector3};
use cleave_integrator::{Constraints, ContactSet, Integrator, StepError, StepReport};
use cleave_registry::{Backend, Region};
use serde_json::json;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Instant;

/// Everything that can go wrong with a scene, each naming the file it concerns.
#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    /// The scene file could not be read.
    #[error("{path}: cannot read scene: {source}")]
    Read {
        /// scene path
        path: PathBuf,
        /// the I/O error
        source: std::io::Error,
    },
    /// Syntax error, unknown or missing field, or an invalid value.
    #[error("{path}:{line}:{column}: {message}")]
    Parse {
        /// scene path
        path: PathBuf,
        /// 1-based line
        line: usize,
        /// 1-based column
        column: usize,
        /// what is wrong
        message: String,
    },
    /// The mesh file is missing or not a valid closed mesh.
    #[error("{scene}: mesh {mesh}: {message}")]
    Mesh {
        /// scene path
        scene: PathBuf,
        /// mesh path as resolved
        mesh: PathBuf,
        /// what is wrong
        message: String,
    },
    /// A consistent but unbuildable scene (a capability the backend lacks, an empty pin region…).
    #[error("{path}: {message}")]
    Build {
        /// scene path
        path: PathBuf,
        /// what is wrong
        message: String,
    },
    /// A step failed.
    #[error("{path}: {source}")]
    Step {
        /// scene path
        path: PathBuf,
        /// the step error
        source: StepError,
    },
    /// Writing the recording failed.
    #[error(transparent)]
    Record(#[from] RecordError),
}

/// A parsed scene and where it came from.
#[derive(Clone, Debug)]
pub struct LoadedScene {
    /// The scene file.
    pub path: PathBuf,
    /// Its content.
    pub scene: Scene,
    /// Its text (to place errors found later, e.g. in a backend's settings).
    pub text: String,
}

/// Reads and parses a scene; errors carry file, line and column.
pub fn load_scene(path: &Path) -> Result<LoadedScene, SceneError> {
    let text = std::fs::read_to_string(path).map_err(|source| SceneError::Read { path: path.to_path_buf(), source })?;
    parse_scene(path, &text)
}

/// Parses scene text (`path` is used for messages and to resolve relative mesh paths).
pub fn parse_scene(path: &Path, text: &str) -> Result<LoadedScene, SceneError> {
    // `implicit_some` lets scenes write `cell_size: 0.25` for optional fields.
    let options = ron::Options::default().with_default_extension(ron::extensions::Extensions::IMPLICIT_SOME);
    match options.from_str::<Scene>(text) {
        Ok(scene) => Ok(LoadedScene { path: path.to_path_buf(), scene, text: text.to_string() }),
        Err(error) => Err(SceneError::Parse {
            path: path.to_path_buf(),
            line: error.span.start.line,
            column: error.span.start.col,
            message: error.code.to_string(),
        }),
    }
}

/// Sizes of what was built.
#[derive(Clone, Debug, Default)]
pub struct BuildInfo {
    /// Backend name.
    pub backend: String,
    /// Elements (cubes).
    pub elements: usize,
    /// Scalar DOFs.
    pub dofs: usize,
    /// Surface vertices rendered.
    pub surface_vertices: usize,
    /// Surface triangles rendered.
    pub surface_triangles: usize,
    /// Element size [m] (cube edge).
    pub element_size: Real,
    /// Seconds spent loading, voxelizing and setting up the solver.
    pub seconds: Real,
}

/// A built scene, stepping and recording.
pub struct Simulation {
    path: PathBuf,
    steps: u64,
    surface_every: u64,
    /// Shared with a preparation thread while it copies the body (`prepare_next_cut`); changed
    /// only between steps, when no one else holds it (`body_mut`).
    discretization: Arc<dyn Discretization>,
    integrator: Integrator,
    surface_triangles: Vec<[u32; 3]>,
    surface_points: Embedding,
    probe_names: Vec<String>,
    probes: Embedding,
    recorder: Option<Recorder>,
    points: Vec<Point3<Real>>,
    info: BuildInfo,
    registration: Box<dyn Backend>,
    pins: Vec<Region>,
    /// Contact constraints kept across cuts (the surface contact's triangles are replaced).
    contact: Constraints,
    probe_points: Vec<Point3<Real>>,
    surface_on_cut: Vec<bool>,
    surface_piece: Vec<u32>,
    timeline: Vec<TimedCut>,
    cuts: CutSummary,
    /// The next timeline `Cut`, being applied to a copy of the body off the step's thread.
    prepared: Option<PreparedCut>,
    /// The body a prepared cut replaced, freed by the next preparation's thread (or with the
    /// simulation, after the last one).
    retired: Option<Arc<dyn Discretization>>,
    /// See [`Simulation::set_cut_ahead`].
    cut_ahead: bool,
    /// Stress fracture: when it is checked, and at what strength.
    fracture: Option<FractureCheck>,
    /// Adaptive refinement: when it is checked, and at what stress.
    refinement: Option<RefinementCheck>,
    /// The input surface's rest vertices, embedded again after a change when the body does not
    /// render its own surface (DG refined but not cut).
    input_surface: Option<Vec<Point3<Real>>>,
    /// Rigid fragments (`rigid_fragments` in the scene).
    rigid: Option<RigidHybrid>,
    /// Each pin region's velocity (zero: held still).
    pin_velocities: Vec<Vector3<Real>>,
    /// The components each pin region holds.
    pin_components: Vec<[bool; 3]>,
    /// The DOFs of moving pins and their velocity [m/s], moved after every step.
    moving_dofs: Vec<(usize, Real)>,
}

/// When stress fracture is checked.
#[derive(Clone, Copy, Debug)]
struct FractureCheck {
    /// After every this many steps…
    every: u64,
    /// …at this tensile strength [Pa]…
    strength: Real,
    /// …and, if set, only within this many steps after an impact…
    after_impacts: Option<u64>,
    /// …that is, up to this step.
    until: u64,
}

/// When adaptive refinement is checked.
#[derive(Clone, Copy, Debug)]
struct RefinementCheck {
    /// After every this many steps…
    every: u64,
    /// …at this stress [Pa].
    stress: Real,
}

/// A topology change just made, with what the rest of the simulation needs to follow it.
struct ChangeMade {
    change: cleave_core::TopologyChange,
    surface: Option<cleave_core::EmbeddedSurface>,
    pieces: Vec<Piece>,
    /// Seconds the change took ahead on a copy, if it was made there.
    ahead: Option<Real>,
    prepared_contact: Option<ContactSet>,
    clock: Instant,
    /// Nodes, frames and pieces before.
    before: (usize, usize, usize),
    /// The event's kind in the recording.
    kind: &'static str,
}

/// What cutting did over a run (for the summary table and the recording).
#[derive(Clone, Debug, Default)]
pub struct CutSummary {
    /// Topology changes applied.
    pub changes: usize,
    /// Wall-clock seconds in cutting and rebuilding after cuts.
    pub seconds: Real,
    /// Total volume and mass at the start [m³, kg] (from the pieces of a cuttable backend).
    pub initial: (Real, Real),
    /// The pieces now.
    pub pieces: Vec<Piece>,
    /// Wall-clock seconds spent ahead, off the step's thread, on timeline cuts prepared on a
    /// copy of the body (not in `seconds`).
    pub prepared_seconds: Real,
    /// Changes whose cut was prepared ahead.
    pub prepared: usize,
    /// Nodes and elements now.
    pub nodes: usize,
    /// Elements now (frames).
    pub elements: usize,
}

impl CutSummary {
    /// Relative drift of total volume and mass since the start.
    pub fn drift(&self) -> (Real, Real) {
        let volume: Real = self.pieces.iter().map(|p| p.volume).sum();
        let mass: Real = self.pieces.iter().map(|p| p.mass).sum();
        let relative = |now: Real, start: Real| if start > 0.0 { (now - start) / start } else { 0.0 };
        (relative(volume, self.initial.0), relative(mass, self.initial.1))
    }
}

impl Simulation {
    /// What was built.
    pub fn info(&self) -> &BuildInfo {
        &self.info
    }

    /// Steps the scene asks for.
    pub fn total_steps(&self) -> u64 {
        self.steps
    }

    /// Steps done so far.
    pub fn steps_done(&self) -> u64 {
        self.integrator.steps_taken()
    }

    /// The recording path, if recording.
    pub fn output(&self) -> Option<&Path> {
        self.recorder.as_ref().map(Recorder::path)
    }

    /// The current surface vertices.
    pub fn surface(&mut self) -> &[Point3<Real>] {
        self.surface_points.evaluate(self.integrator.positions(), &mut self.points);
        &self.points
    }

    fn record_surface(&mut self) -> Result<(), SceneError> {
        if self.recorder.is_none() {
            return Ok(());
        }
        self.surface_points.evaluate(self.integrator.positions(), &mut self.points);
        let time = self.integrator.time();
        if let Some(recorder) = self.recorder.as_mut() {
            recorder.surface(time, &self.points, &self.surface_triangles, &self.surface_on_cut, &self.surface_piece)?;
        }
        Ok(())
    }

    fn record_stats(&mut self, report: &StepReport) -> Result<(), SceneError> {
        let Some(recorder) = self.recorder.as_mut() else { return Ok(()) };
        let x = self.integrator.positions();
        let (mut lo, mut hi, mut sum) = (Real::MAX, Real::MIN, Vector3::zeros());
        for i in 0..self.surface_points.len() {
            let p = self.surface_points.point(x, i);
            lo = lo.min(p.z);
            hi = hi.max(p.z);
            sum += p.coords;
        }
        let centroid = sum / self.surface_points.len().max(1) as Real;
        let probes: serde_json::Map<String, serde_json::Value> = self
            .probe_names
            .iter()
            .enumerate()
            .map(|(i, name)| {
                let p = self.probes.point(x, i);
                (name.clone(), json!([p.x, p.y, p.z]))
            })
            .collect();
        let s = &report.seconds;
        let stats = json!({
            "step": report.step,
            "time": self.integrator.time(),
            "iterations": report.iterations,
            "residual": report.residual,
            "seconds": {
                "rotations": s.rotations, "assembly": s.assembly, "solve": s.solve, "rest": s.rest, "total": s.total(),
                "contact": s.contact, "pattern": s.pattern, "contact_forces": s.contact_forces,
            },
            "energy": {
                "kinetic": report.kinetic_energy, "elastic": report.elastic_energy,
                "gravitational": report.gravitational_energy, "penalty": report.penalty_energy,
                "total": report.total_energy(),
            },
            "inverted_elements": report.inverted_elements,
            "active_contacts": report.active_contacts,
            "contacts": {
                "planes": report.contacts.planes, "meshes": report.contacts.meshes,
                "surface": report.contacts.surface, "edges": report.contacts.edges,
                "max_penetration": report.contacts.max_penetration,
                "seconds": report.contacts.seconds,
            },
            "surface": { "min_z": lo, "max_z": hi, "centroid": [centroid.x, centroid.y, centroid.z] },
            "probes": probes,
        });
        recorder.stats(self.integrator.time(), &stats)?;
        Ok(())
    }

    /// What cutting has done so far.
    pub fn cut_summary(&self) -> &CutSummary {
        &self.cuts
    }

    /// The body, to change between steps. A preparation still holding it (copying it for a
    /// later cut) is waited for and dropped first: its copy would be of the body before this
    /// change.
    fn body_mut(&mut self) -> Result<&mut (dyn Discretization + 'static), SceneError> {
        if Arc::get_mut(&mut self.discretization).is_none()
            && let Some(prepared) = self.prepared.take()
        {
            let _ = prepared.handle.join();
        }
        let path = self.path.clone();
        Arc::get_mut(&mut self.discretization).ok_or_else(|| SceneError::Build {
            path,
            message: "the body is still shared with a cut prepared ahead".into(),
        })
    }

    /// Applies a cut between steps: the backend cuts, the integrator carries the state across,
    /// pins, contact rows, probes and the render surface are resolved again, and the change is
    /// recorded as a `cut` event.
    ///
    /// `prepared`: the same cut already applied to a copy of the body (when the copy was taken,
    /// the body was what it is now), swapped in instead of cutting.
    fn apply_cut(&mut self, surface: &CutSurface, prepared: Option<CutCopy>) -> Result<(), SceneError> {
        let clock = Instant::now();
        let path = self.path.clone();
        let build_error = |message: String| SceneError::Build { path: path.clone(), message };
        let before = (self.discretization.num_nodes(), self.discretization.num_frames(), self.cuts.pieces.len());
        let epoch = self.discretization.epoch();
        let mut prepared_contact = None;
        let (change, surface, pieces, ahead) = match prepared {
            Some(copy) => {
                if copy.change.epoch == epoch {
                    return Ok(());
                }
                // Freeing the old body's many small allocations took 13-21 ms on bunny_slice,
                // and as much on another thread at the same time (the allocator's locks): the
                // next preparation frees it, off the step's thread and between cuts.
                self.retired = Some(std::mem::replace(&mut self.discretization, Arc::from(copy.discretization)));
                prepared_contact = copy.contact;
                (copy.change, copy.surface, copy.pieces, Some(copy.seconds))
            }
            None => {
                let (backend, time) = (self.info.backend.clone(), self.integrator.time());
                let cuttable = self
                    .body_mut()?
                    .as_cuttable()
                    .ok_or_else(|| build_error(format!("the {backend} backend cannot cut")))?;
                let change = cuttable.cut(surface).map_err(|e| build_error(format!("cut at t = {time} s: {e}")))?;
                if change.epoch == epoch {
                    return Ok(());
                }
                let made = (change, cuttable.surface(), cuttable.pieces(), None);
                // A preparation copied the body before this change: its copy can no longer be
                // used, and dropping it lets the next one start.
                self.prepared = None;
                made
            }
        };
        self.finish_change(ChangeMade { change, surface, pieces, ahead, prepared_contact, clock, before, kind: "cut" })
    }

    /// Breaks the body where its stress exceeds the material's strength (`Fracturable`), and
    /// carries everything across as a cut does; recorded as a `fracture` event.
    fn apply_fracture(&mut self, strength: Real) -> Result<(), SceneError> {
        self.apply_fracture_at(strength, None)
    }

    /// [`apply_fracture`](Self::apply_fracture) with the stress read from `state` (positions and
    /// element frames) instead of the integrator's: a static analysis of an impact.
    fn apply_fracture_at(
        &mut self,
        strength: Real,
        state: Option<(&[Real], &[Matrix3<Real>])>,
    ) -> Result<(), SceneError> {
        self.apply_stress_change("fracture", state, |body, x, rotations| match body.as_fracturable() {
            Some(fracturable) => fracturable.fracture(x, rotations, strength).map_err(|e| e.to_string()),
            None => Err("the backend cannot fracture".into()),
        })
    }

    /// Refines the body where its stress exceeds `stress` (`Refinable`) and carries everything
    /// across as a cut does; recorded as a `refine` event.
    fn apply_refinement(&mut self, stress: Real) -> Result<(), SceneError> {
        self.apply_stress_change("refine", None, |body, x, rotations| match body.as_refinable() {
            Some(refinable) => refinable.refine(x, rotations, stress).map_err(|e| e.to_string()),
            None => Err("the backend cannot refine".into()),
        })
    }

    /// A topology change read from the stress (a fracture or a refinement, `kind` in errors and
    /// the recording): `change` gets the body alone and the positions and frames (`state`, or
    /// the integrator's: no copy in a step that checks), and everything is carried across as
    /// a cut does. A body that renders no surface of its own gets the input surface embedded
    /// again ([`finish_change`](Self::finish_change)).
    fn apply_stress_change(
        &mut self,
        kind: &'static str,
        state: Option<(&[Real], &[Matrix3<Real>])>,
        change: impl FnOnce(
            &mut dyn Discretization,
            &[Real],
            &[Matrix3<Real>],
        ) -> Result<Option<cleave_core::TopologyChange>, String>,
    ) -> Result<(), SceneError> {
        let clock = Instant::now();
        let path = self.path.clone();
        let build_error = |message: String| SceneError::Build { path: path.clone(), message };
        let before = (self.discretization.num_nodes(), self.discretization.num_frames(), self.cuts.pieces.len());
        let (backend, time) = (self.info.backend.clone(), self.integrator.time());
        // The body alone (a preparation holding it is waited for), borrowed beside the
        // integrator's state.
        self.body_mut()?;
        let body = Arc::get_mut(&mut self.discretization).expect("body_mut made the body unshared");
        let (x, rotations) = state.unwrap_or((self.integrator.positions(), self.integrator.rotations()));
        let Some(change) =
            change(body, x, rotations).map_err(|e| build_error(format!("{kind} at t = {time} s ({backend}): {e}")))?
        else {
            return Ok(());
        };
        let (surface, pieces) = match body.as_cuttable() {
            Some(cuttable) => (cuttable.surface(), cuttable.pieces()),
            None => (None, self.cuts.pieces.clone()),
        };
        self.prepared = None;
        self.finish_change(ChangeMade {
            change,
            surface,
            pieces,
            ahead: None,
            prepared_contact: None,
            clock,
            before,
            kind,
        })
    }

    /// After the body changed: the integrator carries the state across, pins, contact rows,
    /// probes and the render surface are resolved again, and the change is recorded.
    fn finish_change(&mut self, made: ChangeMade) -> Result<(), SceneError> {
        let ChangeMade { change, surface, pieces, ahead, prepared_contact, clock, before, kind } = made;
        let path = self.path.clone();
        let build_error = |message: String| SceneError::Build { path: path.clone(), message };
        let d = self.discretization.as_ref();
        let surface = match (surface, &self.input_surface) {
            (Some(surface), _) => surface,
            // Not rendering its own (DG refined, not cut): the input surface embedded again.
            (None, Some(rest)) => cleave_core::EmbeddedSurface {
                embedding: d
                    .embed_surface(rest)
                    .map_err(|e| build_error(format!("embedding the surface after a {kind}: {e}")))?,
                rest_vertices: rest.clone(),
                triangles: self.surface_triangles.clone(),
                on_cut: self.surface_on_cut.clone(),
                piece: self.surface_piece.clone(),
            },
            (None, None) => return Err(build_error("a cut body must render its own surface".into())),
        };
        let mut pins = self.registration.resolve_pins(d, &self.pins).map_err(|e| build_error(e.to_string()))?;
        if self.pin_components.iter().any(|c| *c != [true; 3]) {
            pins.pinned_dofs = build::component_pins(self.registration.as_ref(), d, &self.pins, &self.pin_components)
                .map_err(build_error)?;
        }
        // The change renumbers the nodes: every rigid fragment returns (its nodes carry its
        // motion) and may go rigid again at a later check.
        let returned = self.rigid.as_mut().map_or(0, |rigid| rigid.return_all(pins.pinned_dofs.clone()));
        let constraints = Constraints {
            pinned_dofs: pins.pinned_dofs,
            extra_load: pins.extra_load,
            planes: self.contact.planes.clone(),
            meshes: self.contact.meshes.clone(),
            surface_contact: self.contact.surface_contact.as_ref().map(|c| surface_contact_on(c, &surface)),
            ..Default::default()
        };
        let constraints = Constraints {
            contact_points: constraints.has_any_contact().then(|| surface.embedding.clone()),
            ..constraints
        };
        self.integrator
            .apply_topology_change_with(d, &change, constraints, prepared_contact)
            .map_err(|source| SceneError::Step { path: self.path.clone(), source })?;
        self.probes = d.embed(&self.probe_points).map_err(|e| build_error(format!("probe after a {kind}: {e}")))?;
        self.surface_triangles = surface.triangles;
        self.surface_on_cut = surface.on_cut;
        self.surface_piece = surface.piece;
        self.surface_points = surface.embedding;
        let seconds = clock.elapsed().as_secs_f64();
        self.cuts.changes += 1;
        self.cuts.seconds += seconds;
        if let Some(ahead) = ahead {
            self.cuts.prepared += 1;
            self.cuts.prepared_seconds += ahead;
        }
        self.cuts.pieces = pieces;
        self.cuts.nodes = d.num_nodes();
        self.cuts.elements = d.num_frames();
        self.info.dofs = 3 * d.num_nodes();
        self.resolve_moving_pins()?;
        let time = self.integrator.time();
        if let Some(recorder) = self.recorder.as_mut() {
            let message = format!(
                "nodes {} -> {}, elements {} -> {}, pieces {} -> {}, {:.2} ms",
                before.0,
                self.cuts.nodes,
                before.1,
                self.cuts.elements,
                before.2,
                self.cuts.pieces.len(),
                1e3 * seconds
            );
            let message = match ahead {
                Some(ahead) => format!("{message} (cut and surface made ahead on a copy: {:.2} ms)", 1e3 * ahead),
                None => message,
            };
            recorder.event(time, kind, &message)?;
            if returned > 0 {
                recorder.event(
                    time,
                    "rigid",
                    &format!("{returned} rigid fragments returned by the {kind}; 0 rigid now"),
                )?;
            }
        }
        Ok(())
    }

    /// Takes one step (applying the cuts due before it) and records it.
    pub fn step(&mut self) -> Result<StepReport, SceneError> {
        let t0 = self.integrator.time();
        for (event, surface) in self.due_cuts(t0, t0 + self.integrator.settings().time_step) {
            let prepared = self.take_prepared(event);
            self.apply_cut(&surface, prepared)?;
        }
        let step_error = |source| SceneError::Step { path: self.path.clone(), source };
        let counts_before = self.rigid.as_ref().map(|r| r.counts);
        if let Some(rigid) = self.rigid.as_mut() {
            rigid
                .before_step(self.discretization.as_ref(), &mut self.integrator, &self.cuts.pieces)
                .map_err(step_error)?;
        }
        let mut report = self.integrator.step(self.discretization.as_ref()).map_err(step_error)?;
        let d = self.discretization.as_ref();
        // Moving pins: held through the step, then moved on at their velocity.
        let mut edited = !self.moving_dofs.is_empty();
        if edited {
            let (moving, h) = (&self.moving_dofs, self.integrator.settings().time_step);
            self.integrator.edit_state(d, |x, v| {
                for &(dof, velocity) in moving {
                    x[dof] += h * velocity;
                    v[dof] = velocity;
                }
            });
        }
        if let Some(rigid) = self.rigid.as_mut() {
            let surface = (&self.surface_points, self.surface_triangles.as_slice(), self.surface_piece.as_slice());
            edited |= rigid.after_step(d, &mut self.integrator, &self.cuts.pieces, surface).map_err(step_error)?;
        }
        if edited {
            // Nodes moved after the step: the energies of the state now.
            let now = self.integrator.energies(d);
            report.kinetic_energy = now.kinetic_energy;
            report.elastic_energy = now.elastic_energy;
            report.gravitational_energy = now.gravitational_energy;
            report.penalty_energy = now.penalty_energy;
        }
        if self.rigid.is_some() {
            self.record_rigid_changes(counts_before)?;
        }
        if self.integrator.steps_taken().is_multiple_of(self.surface_every) {
            self.record_surface()?;
        }
        self.record_stats(&report)?;
        let d = self.discretization.as_ref();
        let impacts = self.rigid.as_ref().map(|r| r.impact_loads(d, &self.cuts.pieces)).unwrap_or_default();
        if !impacts.is_empty() {
            self.apply_static_impact(impacts)?;
        }
        if let Some(check) = self.refinement
            && self.integrator.steps_taken().is_multiple_of(check.every)
        {
            self.apply_refinement(check.stress)?;
        }
        if let Some(check) = self.fracture.as_mut() {
            let steps = self.integrator.steps_taken();
            let impacts = |c: Option<RigidCounts>| c.map_or(0, |c| c.by_impact);
            if let Some(window) = check.after_impacts
                && impacts(self.rigid.as_ref().map(|r| r.counts)) > impacts(counts_before)
            {
                check.until = steps + window;
            }
            let due = steps.is_multiple_of(check.every) && (check.after_impacts.is_none() || steps <= check.until);
            if due {
                let strength = check.strength;
                self.apply_fracture(strength)?;
            }
        }
        self.prepare_next_cut();
        Ok(report)
    }

    /// The static analysis of this step's impacts on rigid fragments (`impact: Static`, the
    /// paper's pig; docs/math/rigid-fragments.md §5), recorded as an `impact` event; with
    /// `fracture` (only then is it solved): each hit fragment's displacement under its contact
    /// impulses by inertia relief, scaled so that its strain energy is the kinetic energy of the
    /// approach (the energy method for impact), and the body broken where the sum of those
    /// displacements stresses it beyond the strength (every other node at rest, every frame
    /// unrotated: the analysis is in the rest frame). Nothing of it enters the state.
    fn apply_static_impact(&mut self, impacts: Vec<rigid::ImpactLoad>) -> Result<(), SceneError> {
        let clock = Instant::now();
        let strength = self.fracture.as_ref().map(|f| f.strength);
        let d = self.discretization.as_ref();
        let mut displacement = vec![0.0; 3 * d.num_nodes()];
        let mut messages = Vec::new();
        for impact in &impacts {
            let mut message = format!(
                "velocity change {:.3} m/s, approach energy {:.4e} J, {} pieces loaded",
                impact.velocity_change,
                impact.approach_energy,
                impact.bodies.len()
            );
            // The analysis only feeds fracture: without a strength, the event alone.
            if strength.is_some() {
                let step = self.integrator.steps_taken();
                let solution = cleave_integrator::solve_inertia_relief(d, &impact.load, &impact.bodies)
                    .map_err(|kind| SceneError::Step { path: self.path.clone(), source: StepError { step, kind } })?;
                let scale = if solution.strain_energy > 0.0 {
                    (impact.approach_energy / solution.strain_energy).sqrt()
                } else {
                    0.0
                };
                displacement.iter_mut().zip(&solution.displacement).for_each(|(u, s)| *u += scale * s);
                message += &format!(", strain energy {:.4e} J", scale * scale * solution.strain_energy);
            }
            messages.push(message);
        }
        let time = self.integrator.time();
        if let Some(recorder) = self.recorder.as_mut() {
            let message = format!(
                "static impact on {} rigid fragments: {}; analysed in {:.2} ms",
                impacts.len(),
                messages.join("; "),
                1e3 * clock.elapsed().as_secs_f64()
            );
            recorder.event(time, "impact", &message)?;
        }
        let Some(strength) = strength else { return Ok(()) };
        let x: Vec<Real> = d.rest_dofs().iter().zip(&displacement).map(|(r, u)| r + u).collect();
        let unrotated = vec![Matrix3::identity(); d.num_frames()];
        self.apply_fracture_at(strength, Some((&x, &unrotated)))
    }

    /// The DOFs the moving pin regions hold now (after a topology change, again).
    fn resolve_moving_pins(&mut self) -> Result<(), SceneError> {
        self.moving_dofs.clear();
        for ((region, velocity), held) in self.pins.iter().zip(&self.pin_velocities).zip(&self.pin_components) {
            if *velocity == Vector3::zeros() {
                continue;
            }
            let resolved = self
                .registration
                .resolve_pins(self.discretization.as_ref(), std::slice::from_ref(region))
                .map_err(|e| SceneError::Build { path: self.path.clone(), message: e.to_string() })?;
            if resolved.pinned_dofs.is_empty() {
                return Err(SceneError::Build {
                    path: self.path.clone(),
                    message: format!(
                        "a moving pin needs nodes to move, and the {} backend holds its pins weakly",
                        self.info.backend
                    ),
                });
            }
            self.moving_dofs
                .extend(resolved.pinned_dofs.iter().filter(|&&d| held[d % 3]).map(|&d| (d, velocity[d % 3])));
        }
        Ok(())
    }

    /// Records a `rigid` event when pieces went rigid or returned in this step.
    fn record_rigid_changes(&mut self, before: Option<RigidCounts>) -> Result<(), SceneError> {
        let (Some(before), Some(now)) = (before, self.rigid_counts()) else { return Ok(()) };
        let (to, impact, near) =
            (now.to_rigid - before.to_rigid, now.by_impact - before.by_impact, now.by_proximity - before.by_proximity);
        if to + impact + near == 0 {
            return Ok(());
        }
        let time = self.integrator.time();
        if let Some(recorder) = self.recorder.as_mut() {
            let message = format!(
                "{to} pieces to rigid bodies, {impact} returned by an impact, {near} by a deformable piece near; {} rigid now",
                now.rigid
            );
            recorder.event(time, "rigid", &message)?;
        }
        Ok(())
    }

    /// The state now: positions and velocities, three DOFs per node.
    pub fn state(&self) -> (&[Real], &[Real]) {
        (self.integrator.positions(), self.integrator.velocities())
    }

    /// The body being simulated (the backend's discretization).
    pub fn body(&self) -> &dyn Discretization {
        self.discretization.as_ref()
    }

    /// Hand-offs between the deformable body and the rigid world so far (`None` without
    /// `rigid_fragments`).
    pub fn rigid_counts(&self) -> Option<RigidCounts> {
        self.rigid.as_ref().map(|r| r.counts)
    }

    /// Triangles of the render surface now (the surface contact searches the same ones).
    pub fn surface_triangle_count(&self) -> usize {
        self.surface_triangles.len()
    }

    /// Ends the run: records the outcome as an event and closes the file.
    pub fn finish(mut self, failure: Option<&str>) -> Result<(), SceneError> {
        let time = self.integrator.time();
        let steps = self.integrator.steps_taken();
        if let Some(recorder) = self.recorder.as_mut() {
            match failure {
                Some(message) => recorder.event(time, "failed", message)?,
                None => recorder.event(time, "end", &format!("finished {steps} steps"))?,
            }
            recorder.finish()?;
        }
        Ok(())
    }
}
