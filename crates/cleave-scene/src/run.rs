//! Loading a scene file, building what it names, stepping it and recording every step.

use crate::record::{RecordError, Recorder};
use crate::schema::{
    ColliderSpec, DiscretizationSpec, EventSpec, FluxSpec, Object, PinSpec, Scene, SolverSpec, Transform,
};
use cleave_core::{Discretization, Embedding, Point3, Real, Vector3};
use cleave_dg::{DgMesh, DgOptions, Flux, WeakDirichlet};
use cleave_geometry::{PolyhedralMesh, TriangleMesh};
use cleave_integrator::{Constraints, Integrator, PlaneCollider, Settings, Solver, StepError, StepReport};
use cleave_voxel::VoxelMesh;
use nalgebra::Rotation3;
use serde_json::json;
use std::path::{Path, PathBuf};
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
        Ok(scene) => Ok(LoadedScene { path: path.to_path_buf(), scene }),
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
    discretization: Box<dyn Discretization>,
    integrator: Integrator,
    surface_triangles: Vec<[u32; 3]>,
    surface_points: Embedding,
    probe_names: Vec<String>,
    probes: Embedding,
    recorder: Option<Recorder>,
    points: Vec<Point3<Real>>,
    info: BuildInfo,
}

fn transform_point(t: &Transform, p: &Point3<Real>) -> Point3<Real> {
    let [rx, ry, rz] = t.rotation_degrees.map(Real::to_radians);
    let rotation = Rotation3::from_axis_angle(&Vector3::z_axis(), rz)
        * Rotation3::from_axis_angle(&Vector3::y_axis(), ry)
        * Rotation3::from_axis_angle(&Vector3::x_axis(), rx);
    rotation * (p * t.scale) + Vector3::from(t.translation)
}

/// Cubes per axis of a box of cell size `h`, or why it is not a whole number of cells.
fn box_dims(min: &[Real; 3], max: &[Real; 3], h: Real) -> Result<[usize; 3], String> {
    let dims: Vec<usize> = (0..3).map(|a| ((max[a] - min[a]) / h).round().max(0.0) as usize).collect();
    if dims.contains(&0) || (0..3).any(|a| ((max[a] - min[a]) - dims[a] as Real * h).abs() > 1e-9 * h.max(1.0)) {
        return Err(format!("the box {min:?}..{max:?} is not a whole number of cells of size {h}"));
    }
    Ok([dims[0], dims[1], dims[2]])
}

/// The boundary faces of a polyhedral mesh as fan triangles over its vertices, outward.
fn polyhedral_boundary(mesh: &PolyhedralMesh) -> Vec<[u32; 3]> {
    let mut triangles = Vec::new();
    for face in mesh.faces.iter().filter(|f| f.outer.is_none()) {
        for k in 1..face.polygon.len().saturating_sub(1) {
            triangles.push([face.polygon[0], face.polygon[k], face.polygon[k + 1]]);
        }
    }
    triangles
}

/// The boundary faces of a voxel mesh as triangles over its nodes, outward oriented.
fn voxel_boundary(mesh: &VoxelMesh) -> Vec<[u32; 3]> {
    // For each axis and side: the four corners of that face (bit `axis` fixed), in cyclic order.
    let mut triangles = Vec::new();
    for (cube, cell) in mesh.cells().iter().enumerate() {
        for axis in 0..3 {
            for side in [0, 1] {
                let mut neighbour = *cell;
                neighbour[axis] += if side == 1 { 1 } else { -1 };
                if mesh.cube_at(neighbour).is_some() {
                    continue;
                }
                let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
                let corner = |a: usize, b: usize| (side << axis) | (a << u) | (b << v);
                let quad = [corner(0, 0), corner(1, 0), corner(1, 1), corner(0, 1)];
                let nodes = quad.map(|c| mesh.cube_nodes()[cube][c]);
                // (u, v, axis) is right-handed, so the cyclic order above faces +axis; flip it on
                // the minus side.
                if side == 1 {
                    triangles.push([nodes[0], nodes[1], nodes[2]]);
                    triangles.push([nodes[0], nodes[2], nodes[3]]);
                } else {
                    triangles.push([nodes[0], nodes[2], nodes[1]]);
                    triangles.push([nodes[0], nodes[3], nodes[2]]);
                }
            }
        }
    }
    triangles
}

impl Simulation {
    /// Builds the discretization, constraints and integrator a scene names and opens the
    /// recording (`output` overrides the scene's `output.mcap`; no path means no recording).
    pub fn build(loaded: &LoadedScene, output: Option<&Path>) -> Result<Self, SceneError> {
        let clock = Instant::now();
        let scene = &loaded.scene;
        let path = loaded.path.clone();
        let build_error = |message: String| SceneError::Build { path: path.clone(), message };
        let material = scene.material.0;

        // The solid: a closed surface mesh, or a box.
        let surface = match &scene.object {
            Object::Mesh { path: mesh_path, transform } => {
                let resolved = path.parent().unwrap_or(Path::new(".")).join(mesh_path);
                let mesh_error =
                    |message: String| SceneError::Mesh { scene: path.clone(), mesh: resolved.clone(), message };
                let file = std::fs::File::open(&resolved).map_err(|e| mesh_error(format!("cannot open: {e}")))?;
                let mesh = TriangleMesh::from_obj_reader(&mut std::io::BufReader::new(file))
                    .map_err(|e| mesh_error(e.to_string()))?;
                mesh.validate_closed().map_err(|e| mesh_error(e.to_string()))?;
                let mut mesh = mesh.transformed(|p| transform_point(transform, p));
                if let Some(lowest) = transform.lowest_z {
                    let shift = lowest - mesh.aabb().0.z;
                    mesh = mesh.transformed(|p| p + Vector3::new(0.0, 0.0, shift));
                }
                Ok((mesh, resolved))
            }
            Object::Box { min, max } => Err((*min, *max)),
        };
        let pin_regions: Vec<([Real; 3], [Real; 3])> = scene
            .pins
            .iter()
            .map(|pin| {
                let PinSpec::Region { min, max } = pin;
                (*min, *max)
            })
            .collect();
        let in_region = |p: &[Real], (min, max): &([Real; 3], [Real; 3])| {
            (0..3).all(|a| p[a] >= min[a] - 1e-9 && p[a] <= max[a] + 1e-9)
        };
        let mut constraints = Constraints::default();

        let (discretization, element_count, element_size, surface_vertices, surface_triangles): (
            Box<dyn Discretization>,
            usize,
            Real,
            _,
            _,
        ) = match &scene.discretization {
            DiscretizationSpec::Voxel { cell_size, target_cubes } => {
                let (voxels, vertices, triangles) = match surface {
                    Ok((mesh, resolved)) => {
                        let mesh_error =
                            |message: String| SceneError::Mesh { scene: path.clone(), mesh: resolved.clone(), message };
                        let h = match (cell_size, target_cubes) {
                            (Some(h), None) => h.0,
                            (None, Some(target)) if *target > 0 => cell_size_for(&mesh, *target).map_err(mesh_error)?,
                            _ => {
                                return Err(build_error(
                                    "Voxel needs exactly one of `cell_size` and `target_cubes` (> 0)".into(),
                                ));
                            }
                        };
                        let grid = cleave_geometry::voxelize(&mesh, h).map_err(|e| mesh_error(e.to_string()))?;
                        let voxels = VoxelMesh::new(material, grid.origin, grid.cell_size, &grid.cells)
                            .map_err(|e| build_error(e.to_string()))?;
                        (voxels, mesh.vertices, mesh.triangles)
                    }
                    Err((min, max)) => {
                        let h =
                            cell_size.ok_or_else(|| build_error("a Box object needs Voxel(cell_size: ...)".into()))?.0;
                        let dims = box_dims(&min, &max, h).map_err(&build_error)?;
                        let voxels = VoxelMesh::from_box(material, Point3::from(min), h, dims)
                            .map_err(|e| build_error(e.to_string()))?;
                        let triangles = voxel_boundary(&voxels);
                        let vertices: Vec<Point3<Real>> =
                            voxels.rest_dofs().chunks(3).map(|p| Point3::new(p[0], p[1], p[2])).collect();
                        (voxels, vertices, triangles)
                    }
                };
                for (index, region) in pin_regions.iter().enumerate() {
                    let before = constraints.pinned_dofs.len();
                    for (node, p) in voxels.rest_dofs().chunks(3).enumerate() {
                        if in_region(p, region) {
                            constraints.pinned_dofs.extend(3 * node..3 * node + 3);
                        }
                    }
                    if constraints.pinned_dofs.len() == before {
                        return Err(build_error(format!(
                            "pins[{index}]: the region {:?}..{:?} contains no node",
                            region.0, region.1
                        )));
                    }
                }
                let (count, h) = (voxels.num_cubes(), voxels.cell_size());
                (Box::new(voxels), count, h, vertices, triangles)
            }
            DiscretizationSpec::Dg { cell_size, target_elements, degree, flux, penalty, penalty_margin } => {
                let (poly, h, vertices, triangles) = match surface {
                    Ok((mesh, resolved)) => {
                        let mesh_error =
                            |message: String| SceneError::Mesh { scene: path.clone(), mesh: resolved.clone(), message };
                        let h = match (cell_size, target_elements) {
                            (Some(h), None) => h.0,
                            (None, Some(target)) if *target > 0 => {
                                slicing_cell_size_for(&mesh, *target).map_err(mesh_error)?
                            }
                            _ => {
                                return Err(build_error(
                                    "Dg needs exactly one of `cell_size` and `target_elements` (> 0)".into(),
                                ));
                            }
                        };
                        let slicing = cleave_geometry::hex_slice(&mesh, h).map_err(|e| mesh_error(e.to_string()))?;
                        (slicing.mesh, h, mesh.vertices, mesh.triangles)
                    }
                    Err((min, max)) => {
                        let h = cell_size.ok_or_else(|| build_error("a Box object needs Dg(cell_size: ...)".into()))?.0;
                        let dims = box_dims(&min, &max, h).map_err(&build_error)?;
                        let grid = PolyhedralMesh::grid(Point3::from(min), h, dims);
                        let triangles = polyhedral_boundary(&grid);
                        (grid.clone(), h, grid.vertices, triangles)
                    }
                };
                let flux = match flux {
                    FluxSpec::InteriorPenalty => Flux::InteriorPenalty,
                    FluxSpec::BabuskaZlamal => Flux::BabuskaZlamal,
                };
                let mut options = DgOptions::new(*degree, flux);
                if let Some(margin) = penalty_margin {
                    options.penalty_margin = margin.0;
                }
                if let Some(eta) = penalty {
                    options.penalty = eta.0;
                }
                // Pins clamp the boundary faces whose centroid lies in a pin region (weak
                // Dirichlet data u = 0: DG has no nodal values to hold).
                for (index, region) in pin_regions.iter().enumerate() {
                    let clamps_a_face = poly.faces.iter().enumerate().any(|(f, face)| {
                        face.outer.is_none()
                            && in_region(
                                cleave_geometry::face_area_normal_centroid(&poly, f).2.coords.as_slice(),
                                region,
                            )
                    });
                    if !clamps_a_face {
                        return Err(build_error(format!(
                            "pins[{index}]: the region {:?}..{:?} contains no boundary face centroid",
                            region.0, region.1
                        )));
                    }
                }
                let on_boundary =
                    |p: &Point3<Real>| pin_regions.iter().any(|region| in_region(p.coords.as_slice(), region));
                let zero = |_: &Point3<Real>| Vector3::zeros();
                let dirichlet = WeakDirichlet { on_boundary: &on_boundary, data: &zero };
                let dg = DgMesh::new(poly, material, options, (!pin_regions.is_empty()).then_some(&dirichlet))
                    .map_err(|e| build_error(format!("discretization: {e}")))?;
                let count = dg.num_elements();
                (Box::new(dg), count, h, vertices, triangles)
            }
        };
        let info = BuildInfo {
            backend: discretization.name().to_string(),
            elements: element_count,
            dofs: 3 * discretization.num_nodes(),
            surface_vertices: surface_vertices.len(),
            surface_triangles: surface_triangles.len(),
            element_size,
            seconds: 0.0,
        };
        let mut discretization = discretization;

        // Capabilities the timeline needs.
        for (index, event) in scene.timeline.iter().enumerate() {
            match event {
                EventSpec::Cut { .. } => {
                    if discretization.as_cuttable().is_none() {
                        return Err(build_error(format!(
                            "timeline[{index}] cuts, but the {} backend cannot be cut",
                            discretization.name()
                        )));
                    }
                }
            }
        }

        let surface_points = discretization
            .embed_surface(&surface_vertices)
            .map_err(|e| build_error(format!("surface vertex cannot be embedded: {e}")))?;
        let probe_points: Vec<Point3<Real>> = scene.probes.iter().map(|p| Point3::from(p.position)).collect();
        let probes = discretization.embed(&probe_points).map_err(|e| build_error(format!("probe: {e}")))?;

        for collider in &scene.colliders {
            let ColliderSpec::Plane { point, normal, stiffness, damping } = collider;
            constraints.planes.push(PlaneCollider {
                point: Point3::from(*point),
                normal: Vector3::from(normal.0),
                stiffness: stiffness.0,
                damping: damping.max(0.0),
            });
        }
        if !constraints.planes.is_empty() {
            constraints.contact_points = Some(surface_points.clone());
        }

        let mut settings = Settings::new(scene.time_step.0);
        settings.gravity = Vector3::from(scene.gravity);
        settings.rayleigh_alpha = material.rayleigh_alpha;
        settings.rayleigh_beta = material.rayleigh_beta;
        settings.solver = match scene.solver {
            SolverSpec::Cholesky => Solver::Cholesky,
            SolverSpec::ConjugateGradient { tolerance, max_iterations, assembled } => {
                Solver::ConjugateGradient { tolerance: tolerance.0, max_iterations, assembled }
            }
        };
        let integrator = Integrator::new(discretization.as_ref(), settings, constraints)
            .map_err(|source| SceneError::Step { path: path.clone(), source })?;

        let output_path = output.map(Path::to_path_buf).or_else(|| scene.output.mcap.as_ref().map(PathBuf::from));
        let recorder = match output_path {
            Some(p) => Some(Recorder::create(&p, &scene.name, scene.output.flush_every)?),
            None => None,
        };
        let mut simulation = Self {
            path,
            steps: scene.steps,
            surface_every: u64::from(scene.output.surface_every.max(1)),
            discretization,
            integrator,
            surface_triangles,
            surface_points,
            probe_names: scene.probes.iter().map(|p| p.name.clone()).collect(),
            probes,
            recorder,
            points: Vec::new(),
            info: BuildInfo { seconds: clock.elapsed().as_secs_f64(), ..info },
        };
        if let Some(recorder) = simulation.recorder.as_mut() {
            let i = &simulation.info;
            let message = format!(
                "built {}: {} elements, {} DOFs, element size {:.4} m, {} surface triangles",
                i.backend, i.elements, i.dofs, i.element_size, i.surface_triangles
            );
            recorder.event(0.0, "start", &message)?;
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
            recorder.surface(time, &self.points, &self.surface_triangles)?;
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
            "seconds": { "rotations": s.rotations, "assembly": s.assembly, "solve": s.solve, "rest": s.rest, "total": s.total() },
            "energy": {
                "kinetic": report.kinetic_energy, "elastic": report.elastic_energy,
                "gravitational": report.gravitational_energy, "penalty": report.penalty_energy,
                "total": report.total_energy(),
            },
            "inverted_elements": report.inverted_elements,
            "active_contacts": report.active_contacts,
            "surface": { "min_z": lo, "max_z": hi, "centroid": [centroid.x, centroid.y, centroid.z] },
            "probes": probes,
        });
        recorder.stats(self.integrator.time(), &stats)?;
        Ok(())
    }

    /// Takes one step and records it.
    pub fn step(&mut self) -> Result<StepReport, SceneError> {
        let report = self
            .integrator
            .step(self.discretization.as_ref())
            .map_err(|source| SceneError::Step { path: self.path.clone(), source })?;
        if self.integrator.steps_taken().is_multiple_of(self.surface_every) {
            self.record_surface()?;
        }
        self.record_stats(&report)?;
        Ok(report)
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

/// A cube edge giving about `target` cubes: start from volume/target, correct by the measured
/// count (the surface layer makes the first guess too many cubes).
fn cell_size_for(mesh: &TriangleMesh, target: usize) -> Result<Real, String> {
    let volume = mesh.signed_volume();
    if volume.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
        return Err(format!("enclosed volume is {volume}, cannot size cubes"));
    }
    let mut h = (volume / target as Real).cbrt();
    for _ in 0..4 {
        let count = cleave_geometry::voxelize(mesh, h).map_err(|e| e.to_string())?.cells.len();
        let ratio = count as Real / target as Real;
        if (ratio - 1.0).abs() < 0.05 {
            break;
        }
        h *= ratio.cbrt();
    }
    Ok(h)
}

/// The slicing cell edge giving about `target` DG elements (a few slicings, refining `h` by the
/// cube root of the count ratio).
fn slicing_cell_size_for(mesh: &TriangleMesh, target: usize) -> Result<Real, String> {
    let volume = mesh.signed_volume();
    if volume.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
        return Err(format!("enclosed volume is {volume}, cannot size elements"));
    }
    let mut h = (volume / target as Real).cbrt();
    for _ in 0..4 {
        let count = cleave_geometry::hex_slice(mesh, h).map_err(|e| e.to_string())?.mesh.num_elements;
        let ratio = count as Real / target as Real;
        if (ratio - 1.0).abs() < 0.1 {
            break;
        }
        h *= ratio.cbrt();
    }
    Ok(h)
}
