//! Loading a scene file, building what it names, stepping it and recording every step.

use crate::record::{RecordError, Recorder};
use crate::schema::{
    ColliderSpec, ContactSpec, CutSpec, EventSpec, Object, PinSpec, Positive, PreconditionerSpec, Scene, SolverSpec,
    Transform,
};
use cleave_core::{
    CutSurface, Discretization, EmbeddedSurface, Embedding, Piece, Point3, Real, TopologyChange, TopologyError, Vector3,
};
use cleave_geometry::{Blade, Keyframe, TriangleMesh};
use cleave_integrator::{
    Constraints, Integrator, MeshCollider, PlaneCollider, Preconditioner, PreparedContact, Settings, Solver, StepError,
    StepReport, SurfaceContact,
};
use cleave_registry::{Backend, BackendError, Region, Shape, SolidRequest};
use nalgebra::{Rotation3, UnitQuaternion};
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
}

/// A timeline `Cut` applied to a copy of the body on threads of its own while the steps before
/// it run (the cut is in rest space: it does not depend on the motion), swapped in when due.
struct PreparedCut {
    /// Index of the event in the timeline.
    event: usize,
    /// Epoch of the body the copy was taken from: the copy is used only if the body is still
    /// at it when the cut is due (nothing else cut it in between).
    epoch: u64,
    handle: std::thread::JoinHandle<Result<CutCopy, TopologyError>>,
}

/// A copy of the body after a cut, with what the runner asks of the backend after one.
struct CutCopy {
    discretization: Box<dyn Discretization>,
    change: TopologyChange,
    surface: Option<EmbeddedSurface>,
    pieces: Vec<Piece>,
    /// The integrator's contact structures of the new surface (with surface contact).
    contact: Option<PreparedContact>,
    /// Wall time the preparation took to copy and cut the body and make its surface, pieces and
    /// contact structures [s].
    seconds: Real,
}

/// A timeline event ready to act: a fixed soup at a time, or a blade over a window.
enum TimedCut {
    Once {
        time: Real,
        surface: Option<CutSurface>,
    },
    /// `begun`: whether a step has handed over the blade's first soup (its face included).
    Blade {
        start: Real,
        end: Real,
        blade: Blade,
        begun: bool,
    },
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

fn transform_point(t: &Transform, p: &Point3<Real>) -> Point3<Real> {
    let [rx, ry, rz] = t.rotation_degrees.map(Real::to_radians);
    let rotation = Rotation3::from_axis_angle(&Vector3::z_axis(), rz)
        * Rotation3::from_axis_angle(&Vector3::y_axis(), ry)
        * Rotation3::from_axis_angle(&Vector3::x_axis(), rx);
    rotation * (p * t.scale) + Vector3::from(t.translation)
}

impl Simulation {
    /// Builds the discretization, constraints and integrator a scene names and opens the
    /// recording (`output` overrides the scene's `output.mcap`; no path means no recording).
    pub fn build(loaded: &LoadedScene, output: Option<&Path>) -> Result<Self, SceneError> {
        Self::build_with_backend(loaded, output, None)
    }

    /// [`Simulation::build`] with the backend overridden (`None`: the scene's `backend`).
    pub fn build_with_backend(
        loaded: &LoadedScene,
        output: Option<&Path>,
        backend: Option<&str>,
    ) -> Result<Self, SceneError> {
        let clock = Instant::now();
        let scene = &loaded.scene;
        let path = loaded.path.clone();
        let build_error = |message: String| SceneError::Build { path: path.clone(), message };
        let material = scene.material.0;

        // The solid: a closed surface mesh, or a box.
        let surface = match &scene.object {
            Object::Mesh { path: mesh_path, transform } => {
                let resolved = path.parent().unwrap_or(Path::new(".")).join(mesh_path);
                Ok((load_obj(&path, mesh_path, transform, None, Closed::Required)?, resolved))
            }
            Object::Box { min, max } => Err((*min, *max)),
        };
        let pins: Vec<Region> = scene
            .pins
            .iter()
            .map(|pin| {
                let PinSpec::Region { min, max } = pin;
                Region { min: *min, max: *max }
            })
            .collect();
        let mut constraints = Constraints::default();

        // The backend: the scene's default or the override, through its one registration.
        let name = backend.unwrap_or(&scene.backend);
        let registration = cleave_registry::find(name).ok_or_else(|| {
            build_error(format!("no backend {name:?}; registered: {}", cleave_registry::names().join(", ")))
        })?;
        let settings = scene.settings.get(name).ok_or_else(|| {
            let given: Vec<&str> = scene.settings.keys().map(String::as_str).collect();
            build_error(format!(
                "`settings` has no entry for backend {name:?} (it has: {}); add e.g. \"{name}\": (cell_size: ...)",
                given.join(", ")
            ))
        })?;
        // Capabilities the timeline needs, before anything is built.
        let capabilities = registration.capabilities();
        for (index, event) in scene.timeline.iter().enumerate() {
            let kind = match event {
                EventSpec::Cut { .. } => "Cut",
                EventSpec::Blade { .. } => "Blade",
            };
            if !capabilities.cut {
                return Err(build_error(format!(
                    "timeline[{index}] ({kind} at t = {} s) cuts, but the {name} backend cannot cut",
                    event.start()
                )));
            }
        }
        let shape = match &surface {
            Ok((mesh, _)) => Shape::Surface(mesh),
            Err((min, max)) => Shape::Box { min: *min, max: *max },
        };
        let request = SolidRequest { shape, material, pins: &pins };
        let built = registration.build_solid(settings.get_ron(), &request).map_err(|error| match error {
            BackendError::Settings { line, column, message } => {
                let (line, column) = position_within(&loaded.text, settings.get_ron(), line, column);
                SceneError::Parse { path: path.clone(), line, column, message: format!("settings.{name}: {message}") }
            }
            BackendError::Mesh(message) => match &surface {
                Ok((_, resolved)) => SceneError::Mesh { scene: path.clone(), mesh: resolved.clone(), message },
                Err(_) => build_error(message),
            },
            BackendError::Build(message) => build_error(message),
        })?;
        constraints.pinned_dofs = built.pins.pinned_dofs;
        constraints.extra_load = built.pins.extra_load;
        let mut discretization = built.discretization;
        let (element_count, element_size) = (built.elements, built.element_size);
        let (surface_vertices, mut surface_triangles) = (built.surface.vertices, built.surface.triangles);
        let mut surface_on_cut = vec![false; surface_triangles.len()];
        let mut surface_piece = Vec::new();
        let cut_surface = discretization.as_cuttable().and_then(|c| c.surface());
        let cut_surface_present = cut_surface.is_some();
        let info = BuildInfo {
            backend: discretization.name().to_string(),
            elements: element_count,
            dofs: 3 * discretization.num_nodes(),
            surface_vertices: surface_vertices.len(),
            surface_triangles: surface_triangles.len(),
            element_size,
            seconds: 0.0,
        };

        // A cuttable backend renders its own surface (it changes with every cut).
        let surface_points = match cut_surface {
            Some(own) => {
                surface_triangles = own.triangles;
                surface_on_cut = own.on_cut;
                surface_piece = own.piece;
                own.embedding
            }
            None => discretization
                .embed_surface(&surface_vertices)
                .map_err(|e| build_error(format!("surface vertex cannot be embedded: {e}")))?,
        };
        let probe_points: Vec<Point3<Real>> = scene.probes.iter().map(|p| Point3::from(p.position)).collect();
        let probes = discretization.embed(&probe_points).map_err(|e| build_error(format!("probe: {e}")))?;

        let nonnegative = |what: &str, value: Real| {
            if value.is_finite() && value >= 0.0 {
                Ok(value)
            } else {
                Err(build_error(format!("{what} must be finite and non-negative, got {value}")))
            }
        };
        let mut collider_meshes = Vec::new();
        for (index, collider) in scene.colliders.iter().enumerate() {
            match collider {
                ColliderSpec::Plane { point, normal, stiffness, damping, friction } => {
                    constraints.planes.push(PlaneCollider {
                        point: Point3::from(*point),
                        normal: Vector3::from(normal.0),
                        stiffness: stiffness.0,
                        damping: damping.max(0.0),
                        friction: nonnegative(&format!("colliders[{index}].friction"), *friction)?,
                    });
                }
                ColliderSpec::Mesh { path: obj, transform, stiffness, damping, friction, reach } => {
                    let mesh =
                        load_obj(&path, obj, transform, Some(&format!("colliders[{index}]")), Closed::NotRequired)?;
                    collider_meshes.push(mesh.clone());
                    let reach = nonnegative(
                        &format!("colliders[{index}].reach"),
                        reach.unwrap_or(DEFAULT_REACH * element_size),
                    )?;
                    let collider = MeshCollider::new(
                        mesh.vertices.clone(),
                        mesh.triangles.clone(),
                        stiffness.0,
                        damping.max(0.0),
                        nonnegative(&format!("colliders[{index}].friction"), *friction)?,
                        reach,
                    )
                    .map_err(|e| SceneError::Mesh {
                        scene: path.clone(),
                        mesh: path.parent().unwrap_or(Path::new(".")).join(obj),
                        message: format!("colliders[{index}]: {e}"),
                    })?;
                    constraints.meshes.push(collider);
                }
            }
        }
        // Surface contact: on by default for a body that cuts (its pieces must not pass through
        // each other), with the first collider's stiffness and damping.
        let first_collider = scene.colliders.first().map(|c| match c {
            ColliderSpec::Plane { stiffness, damping, .. } | ColliderSpec::Mesh { stiffness, damping, .. } => {
                (stiffness.0, damping.max(0.0))
            }
        });
        let contact_spec = match &scene.contact {
            Some(explicit) => explicit.clone(),
            None if cut_surface_present => {
                let (stiffness, damping) = first_collider.unwrap_or((DEFAULT_CONTACT_STIFFNESS, 0.0));
                Some(ContactSpec {
                    stiffness: Positive(stiffness),
                    damping,
                    friction: 0.5,
                    thickness: 0.0,
                    reach: None,
                })
            }
            None => None,
        };
        if let Some(spec) = contact_spec {
            constraints.surface_contact = Some(SurfaceContact {
                triangles: surface_triangles.clone(),
                on_cut: surface_on_cut.clone(),
                piece: surface_piece.clone(),
                stiffness: spec.stiffness.0,
                damping: nonnegative("contact.damping", spec.damping)?,
                friction: nonnegative("contact.friction", spec.friction)?,
                thickness: nonnegative("contact.thickness", spec.thickness)?,
                reach: nonnegative("contact.reach", spec.reach.unwrap_or(DEFAULT_REACH * element_size))?,
                edge_contact: true,
            });
        }
        if !constraints.planes.is_empty() || !constraints.meshes.is_empty() || constraints.surface_contact.is_some() {
            constraints.contact_points = Some(surface_points.clone());
        }

        let timeline = prepare_timeline(&scene.timeline, &path)?;
        let contact = Constraints {
            planes: constraints.planes.clone(),
            meshes: constraints.meshes.clone(),
            surface_contact: constraints.surface_contact.clone(),
            ..Default::default()
        };
        let pieces = discretization.as_cuttable().map(|c| c.pieces()).unwrap_or_default();
        let cuts = CutSummary {
            initial: (pieces.iter().map(|p| p.volume).sum(), pieces.iter().map(|p| p.mass).sum()),
            nodes: discretization.num_nodes(),
            elements: discretization.num_frames(),
            pieces,
            ..Default::default()
        };

        let mut settings = Settings::new(scene.time_step.0);
        settings.gravity = Vector3::from(scene.gravity);
        settings.rayleigh_alpha = material.rayleigh_alpha;
        settings.rayleigh_beta = material.rayleigh_beta;
        settings.conserve_angular_momentum = scene.conserve_angular_momentum;
        settings.rotation_refresh_angle = scene.rotation_refresh_angle.map(|a| a.0);
        settings.solver = match scene.solver {
            SolverSpec::Cholesky => Solver::Cholesky,
            SolverSpec::ConjugateGradient { tolerance, max_iterations, assembled, .. } => {
                Solver::ConjugateGradient { tolerance: tolerance.0, max_iterations, assembled }
            }
        };
        if let SolverSpec::ConjugateGradient { preconditioner, .. } = scene.solver {
            settings.preconditioner = match preconditioner {
                PreconditionerSpec::Auto => Preconditioner::Auto,
                PreconditionerSpec::BlockJacobi => Preconditioner::BlockJacobi,
                PreconditionerSpec::TwoLevel => Preconditioner::TwoLevel,
                PreconditionerSpec::Pieces => Preconditioner::Pieces,
            };
        }
        let plane_colliders: Vec<_> = constraints.planes.iter().map(|p| (p.point, p.normal)).collect();
        let integrator = Integrator::new(discretization.as_ref(), settings, constraints)
            .map_err(|source| SceneError::Step { path: path.clone(), source })?;

        let output_path = output.map(Path::to_path_buf).or_else(|| scene.output.mcap.as_ref().map(PathBuf::from));
        let recorder = match output_path {
            Some(p) => Some(Recorder::create(&p, &scene.name, &info.backend, scene.output.flush_every)?),
            None => None,
        };
        let mut simulation = Self {
            path,
            steps: scene.steps,
            surface_every: u64::from(scene.output.surface_every.max(1)),
            discretization: Arc::from(discretization),
            integrator,
            surface_triangles,
            surface_points,
            probe_names: scene.probes.iter().map(|p| p.name.clone()).collect(),
            probes,
            recorder,
            points: Vec::new(),
            info: BuildInfo { seconds: clock.elapsed().as_secs_f64(), ..info },
            registration,
            pins,
            contact,
            probe_points,
            surface_on_cut,
            surface_piece,
            timeline,
            cuts,
            prepared: None,
            retired: None,
            cut_ahead: true,
        };
        if let Some(recorder) = simulation.recorder.as_mut() {
            let i = &simulation.info;
            let message = format!(
                "built {}: {} elements, {} DOFs, element size {:.4} m, {} surface triangles",
                i.backend, i.elements, i.dofs, i.element_size, i.surface_triangles
            );
            recorder.event(0.0, "start", &message)?;
            recorder.colliders(&collider_meshes, &plane_colliders)?;
        }
        simulation.record_surface()?;
        let initial = simulation.integrator.energies(simulation.discretization.as_ref());
        simulation.record_stats(&initial)?;
        Ok(simulation)
    }

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

    /// Whether timeline `Cut`s are applied ahead to a copy of the body, off the step's thread,
    /// while the steps before them run (default: on). The result is the same bit for bit; off,
    /// a change's cost is all paid in the step it is due (what `compare` measures per change).
    pub fn set_cut_ahead(&mut self, on: bool) {
        self.cut_ahead = on;
        if !on && let Some(prepared) = self.prepared.take() {
            // Joined, not left running: it may still hold the body an in-place cut will change.
            let _ = prepared.handle.join();
        }
    }

    /// What cutting has done so far.
    pub fn cut_summary(&self) -> &CutSummary {
        &self.cuts
    }

    /// The surfaces the timeline cuts at the start of the step from `t0` to `t1`: a `Cut` once,
    /// at the first step that starts at or after its time (a plane stays a plane: the backend
    /// cuts it exactly, without the slivers a huge two-triangle stand-in leaves along its
    /// diagonal); the blades' soups swept over their part of this step, as one soup (the first
    /// step of a blade with its incision, [`Blade::swept`]; later ones only what its cutting
    /// edges sweep, [`Blade::swept_after`]).
    /// A `Cut` comes with its index in the timeline.
    fn due_cuts(&mut self, t0: Real, t1: Real) -> Vec<(Option<usize>, CutSurface)> {
        let mut due = Vec::new();
        let mut swept = Vec::new();
        for (k, event) in self.timeline.iter_mut().enumerate() {
            match event {
                TimedCut::Once { time, surface } => {
                    if *time <= t0 + 1e-9
                        && let Some(surface) = surface.take()
                    {
                        due.push((Some(k), surface));
                    }
                }
                TimedCut::Blade { start, end, blade, begun } => {
                    let (a, b) = (t0.max(*start), t1.min(*end));
                    // The first step the blade is due hands over its face there (even where the
                    // run starts after the blade did); later ones only what is new since the
                    // step before.
                    if !*begun && (a < b || (a == b && a == *start)) {
                        swept.extend(blade.swept(a, b));
                        *begun = true;
                    } else if *begun && a < b {
                        swept.extend(blade.swept_after(a, b));
                    }
                }
            }
        }
        if !swept.is_empty() {
            due.push((None, CutSurface::Triangles(swept)));
        }
        due
    }

    /// Starts applying the next timeline `Cut` to a copy of the body on threads of its own, if
    /// nothing can change the body before it (no blade acts before its time) and it is not due
    /// at the next step already. A backend that cannot copy itself
    /// (`Discretization::copy_for_cutting` gives `None`) ends the preparation at once, and the
    /// cut is made when due.
    fn prepare_next_cut(&mut self) {
        if self.prepared.is_some() || !self.cut_ahead {
            return;
        }
        let now = self.integrator.time();
        let h = self.integrator.settings().time_step;
        let next = self
            .timeline
            .iter()
            .enumerate()
            .filter_map(|(k, e)| match e {
                TimedCut::Once { time, surface: Some(surface) } => Some((k, *time, surface)),
                _ => None,
            })
            .min_by(|a, b| a.1.total_cmp(&b.1));
        let Some((event, time, surface)) = next else { return };
        let blade_before = self.timeline.iter().any(|e| match e {
            TimedCut::Blade { start, end, .. } => *start <= time + 1e-9 && *end > now,
            TimedCut::Once { .. } => false,
        });
        if blade_before || time <= now + h + 1e-9 {
            return;
        }
        let surface = surface.clone();
        let epoch = self.discretization.epoch();
        // The copy itself is made on the preparation's thread (40 ms on bunny_slice after its
        // first cuts): the body is shared until then, and the steps only read it.
        let body = Arc::clone(&self.discretization);
        let surface_contact = self.contact.surface_contact.clone();
        // As many threads as the step's pool, so the copy is cut exactly as the body would be
        // (per-thread chunking of the scatter plans) and the result is the same bit for bit.
        let threads = rayon::current_num_threads();
        let retired = self.retired.take();
        let spawned = std::thread::Builder::new().name("cleave-cut-ahead".into()).spawn(move || {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .thread_name(|k| format!("cleave-cut-ahead-{k}"))
                // What the step leaves of the cores (its sequential factorization, for one):
                // at the step's priority they took half of them, and the steps in between
                // slowed by as much (a step after a cut reached 119 ms). Where the priority
                // cannot be lowered they run at the step's.
                .start_handler(|_| {
                    let _ = thread_priority::set_current_thread_priority(thread_priority::ThreadPriority::Min);
                })
                .build()
                .map_err(|e| TopologyError::Invalid(format!("no threads to cut ahead on: {e}")))?;
            pool.install(move || {
                drop(retired);
                let clock = Instant::now();
                let copy = body.copy_for_cutting();
                drop(body);
                let mut discretization =
                    copy.ok_or_else(|| TopologyError::Invalid("the backend cannot copy itself to cut ahead".into()))?;
                let cuttable = discretization
                    .as_cuttable()
                    .ok_or_else(|| TopologyError::Invalid("the backend's copy cannot cut".into()))?;
                let change = cuttable.cut(&surface)?;
                let surface = cuttable.surface();
                let pieces = cuttable.pieces();
                // The contact structures the integrator builds from the new surface alone.
                let contact = surface_contact.zip(surface.as_ref()).map(|(settings, surface)| {
                    let constraints = Constraints {
                        contact_points: Some(surface.embedding.clone()),
                        surface_contact: Some(surface_contact_on(&settings, surface)),
                        ..Default::default()
                    };
                    PreparedContact::new(&constraints, discretization.rest_dofs())
                });
                Ok(CutCopy { discretization, change, surface, pieces, contact, seconds: clock.elapsed().as_secs_f64() })
            })
        });
        // No thread: the cut is made when due.
        if let Ok(handle) = spawned {
            self.prepared = Some(PreparedCut { event, epoch, handle });
        }
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

    /// The prepared copy of timeline event `event` if it is ready to use (waiting for it if
    /// needed); `None` (and the preparation dropped) if there is none, or it was taken from a
    /// body that has changed since, or it failed (the cut is then made in place, which reports
    /// the failure if it fails again).
    fn take_prepared(&mut self, event: Option<usize>) -> Option<CutCopy> {
        let prepared = self.prepared.take_if(|p| Some(p.event) == event)?;
        if prepared.epoch != self.discretization.epoch() {
            return None;
        }
        prepared.handle.join().ok()?.ok()
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
        let surface = surface.ok_or_else(|| build_error("a cut body must render its own surface".into()))?;
        let d = self.discretization.as_ref();
        let pins = self.registration.resolve_pins(d, &self.pins).map_err(|e| build_error(e.to_string()))?;
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
            .apply_topology_change_prepared(d, &change, constraints, prepared_contact)
            .map_err(|source| SceneError::Step { path: self.path.clone(), source })?;
        self.probes = d.embed(&self.probe_points).map_err(|e| build_error(format!("probe after a cut: {e}")))?;
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
            recorder.event(time, "cut", &message)?;
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
        let report = self
            .integrator
            .step(self.discretization.as_ref())
            .map_err(|source| SceneError::Step { path: self.path.clone(), source })?;
        if self.integrator.steps_taken().is_multiple_of(self.surface_every) {
            self.record_surface()?;
        }
        self.record_stats(&report)?;
        self.prepare_next_cut();
        Ok(report)
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

/// Whether an OBJ must bound a solid.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Closed {
    /// The object: closed, manifold, outward (`TriangleMesh::validate_closed`).
    Required,
    /// Colliders and cut soups: any triangles.
    NotRequired,
}

/// The one OBJ loader of scenes: reads an OBJ named by a scene (relative to the scene file),
/// validates it as a closed surface when `closed` asks, and places it by `transform` (`lowest_z`:
/// its lowest vertex lands at that height). Errors name the scene, the mesh and `what` (the
/// field, if not the object).
fn load_obj(
    scene: &Path,
    obj: &str,
    transform: &Transform,
    what: Option<&str>,
    closed: Closed,
) -> Result<TriangleMesh, SceneError> {
    let resolved = scene.parent().unwrap_or(Path::new(".")).join(obj);
    let mesh_error = |message: String| SceneError::Mesh {
        scene: scene.to_path_buf(),
        mesh: resolved.clone(),
        message: match what {
            Some(what) => format!("{what}: {message}"),
            None => message,
        },
    };
    let file = std::fs::File::open(&resolved).map_err(|e| mesh_error(format!("cannot open: {e}")))?;
    let mesh =
        TriangleMesh::from_obj_reader(&mut std::io::BufReader::new(file)).map_err(|e| mesh_error(e.to_string()))?;
    if closed == Closed::Required {
        mesh.validate_closed().map_err(|e| mesh_error(e.to_string()))?;
    }
    let mut mesh = mesh.transformed(|p| transform_point(transform, p));
    if let Some(z) = transform.lowest_z {
        let lowest = mesh.aabb().0.z;
        if lowest.is_finite() {
            let shift = z - lowest;
            mesh = mesh.transformed(|p| p + Vector3::new(0.0, 0.0, shift));
        }
    }
    Ok(mesh)
}

/// Default contact reach, as a fraction of the element size: deeper penetration is taken for
/// the far side of a thin part (a bunny's ear is a few elements thick, penalty contact sinks
/// micrometres).
pub const DEFAULT_REACH: Real = 0.1;

/// Penalty stiffness of surface contact when a scene has neither a `contact` entry nor a
/// collider to take it from [N/m].
pub const DEFAULT_CONTACT_STIFFNESS: Real = 1e4;

/// The scene's surface contact `settings` on the triangles of `surface` (a cut body's new one).
fn surface_contact_on(settings: &SurfaceContact, surface: &EmbeddedSurface) -> SurfaceContact {
    SurfaceContact {
        triangles: surface.triangles.clone(),
        on_cut: surface.on_cut.clone(),
        piece: surface.piece.clone(),
        stiffness: settings.stiffness,
        damping: settings.damping,
        friction: settings.friction,
        thickness: settings.thickness,
        reach: settings.reach,
        edge_contact: settings.edge_contact,
    }
}

/// Turns the scene's events into cuts ready to act: OBJ soups read and placed, blades checked.
fn prepare_timeline(events: &[EventSpec], scene: &Path) -> Result<Vec<TimedCut>, SceneError> {
    let build_error = |message: String| SceneError::Build { path: scene.to_path_buf(), message };
    let mut timeline = Vec::with_capacity(events.len());
    for (index, event) in events.iter().enumerate() {
        timeline.push(match event {
            EventSpec::Cut { time, surface } => {
                if !time.is_finite() {
                    return Err(build_error(format!("timeline[{index}]: Cut time must be finite, got {time}")));
                }
                let surface = match surface {
                    CutSpec::Plane { point, normal } => {
                        CutSurface::Plane { point: Point3::from(*point), normal: Vector3::from(normal.0) }
                    }
                    CutSpec::Obj { path: obj, transform } => {
                        let mesh =
                            load_obj(scene, obj, transform, Some(&format!("timeline[{index}]")), Closed::NotRequired)?;
                        CutSurface::Triangles(
                            (0..mesh.triangles.len()).filter_map(|t| mesh.triangle_points(t)).collect(),
                        )
                    }
                };
                TimedCut::Once { time: *time, surface: Some(surface) }
            }
            EventSpec::Blade { start, end, polygon, path, cutting_edges } => {
                if !(start.is_finite() && end.is_finite() && start <= end) {
                    return Err(build_error(format!("timeline[{index}]: blade window {start}..{end} is empty")));
                }
                let keyframes = path
                    .iter()
                    .map(|k| {
                        let [rx, ry, rz] = k.rotation_degrees.map(Real::to_radians);
                        Keyframe {
                            time: k.time,
                            translation: Vector3::from(k.translation),
                            rotation: UnitQuaternion::from_euler_angles(rx, ry, rz),
                        }
                    })
                    .collect();
                let polygon = polygon.iter().map(|p| Point3::from(*p)).collect();
                let mut blade = Blade::new(polygon, keyframes);
                if let Some(edges) = cutting_edges {
                    blade = blade.and_then(|b| b.with_cutting_edges(edges.clone()));
                }
                let blade = blade.map_err(|e| build_error(format!("timeline[{index}]: {e}")))?;
                TimedCut::Blade { start: *start, end: *end, blade, begun: false }
            }
        });
    }
    Ok(timeline)
}

/// Line and column in the scene file of a position (1-based) inside `inner`, a slice of the
/// file's text (a backend's settings); falls back to the position within `inner`.
fn position_within(text: &str, inner: &str, line: usize, column: usize) -> (usize, usize) {
    let Some(offset) = text.find(inner) else { return (line, column) };
    let before = &text[..offset];
    let start_line = before.matches('\n').count() + 1;
    let start_column = offset - before.rfind('\n').map_or(0, |i| i + 1) + 1;
    if line <= 1 { (start_line, start_column + column - 1) } else { (start_line + line - 1, column) }
}
