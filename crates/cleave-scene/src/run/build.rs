//! Building a scene: the solid through its backend's registration, the one OBJ loader, colliders,
//! contact defaults, the solver settings, the recorder and the first frame.

use super::rigid::RigidRules;
use super::*;
use crate::record::Recorder;
use crate::schema::{
    ColliderSpec, ContactSpec, EventSpec, ImpactSpec, Object, PinSpec, Positive, PreconditionerSpec, SolverSpec,
    Transform,
};
use cleave_core::{EmbeddedSurface, Point3, Real, Vector3};
use cleave_geometry::TriangleMesh;
use cleave_integrator::{
    Constraints, Integrator, MeshCollider, PlaneCollider, Preconditioner, Settings, Solver, SurfaceContact,
};
use cleave_registry::{BackendError, Region, Shape, SolidRequest};
use cleave_rigid::{ImpactResponse, Obstacle, RigidWorld, WorldSettings};
use nalgebra::Rotation3;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Instant;

pub(super) fn transform_point(t: &Transform, p: &Point3<Real>) -> Point3<Real> {
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
                let PinSpec::Region { min, max, .. } = pin;
                Region { min: *min, max: *max }
            })
            .collect();
        let pin_velocities: Vec<Vector3<Real>> = scene
            .pins
            .iter()
            .map(|pin| {
                let PinSpec::Region { velocity, .. } = pin;
                Vector3::from(*velocity)
            })
            .collect();
        let pin_components: Vec<[bool; 3]> = scene
            .pins
            .iter()
            .map(|pin| {
                let PinSpec::Region { components, .. } = pin;
                *components
            })
            .collect();
        for (index, (velocity, held)) in pin_velocities.iter().zip(&pin_components).enumerate() {
            if let Some(axis) = (0..3).find(|&a| velocity[a] != 0.0 && !held[a]) {
                return Err(build_error(format!(
                    "pins[{index}] moves along {} but does not hold that component (components: {held:?})",
                    ["x", "y", "z"][axis]
                )));
            }
        }
        if let Some(bad) = pin_velocities.iter().find(|v| !v.iter().all(|c| c.is_finite())) {
            return Err(build_error(format!("a pin's velocity must be finite, got {bad:?}")));
        }
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
        if let Some(key) = scene.solver_for.keys().find(|k| !scene.settings.contains_key(*k)) {
            return Err(build_error(format!(
                "`solver_for` has an entry for {key:?}, but `settings` has none (a backend this scene runs on needs both)"
            )));
        }
        // Capabilities the timeline and fracture need, before anything is built.
        let capabilities = registration.capabilities();
        if let Some(refinement) = &scene.refinement {
            if !capabilities.refine {
                return Err(build_error(format!("`refinement` is set, but the {name} backend cannot refine")));
            }
            if refinement.every == 0 {
                return Err(build_error("`refinement.every` must be at least 1 step".into()));
            }
        }
        if let Some(fracture) = &scene.fracture {
            if !capabilities.fracture {
                return Err(build_error(format!("`fracture` is set, but the {name} backend cannot fracture")));
            }
            if material.tensile_strength.is_none() {
                return Err(build_error(
                    "`fracture` is set, but the material has no `tensile_strength` (the stress it breaks at)".into(),
                ));
            }
            if fracture.every == 0 {
                return Err(build_error("`fracture.every` must be at least 1 step".into()));
            }
            if fracture.after_impacts.is_some() && scene.rigid_fragments.is_none() {
                return Err(build_error(
                    "`fracture.after_impacts` is set, but there are no `rigid_fragments` to have impacts".into(),
                ));
            }
        }
        if scene.rigid_fragments.is_some() && !capabilities.cut {
            return Err(build_error(format!(
                "`rigid_fragments` is set, but the {name} backend cannot cut, so it has no pieces to hand over"
            )));
        }
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
        if pin_components.iter().any(|c| *c != [true; 3]) {
            constraints.pinned_dofs =
                component_pins(registration.as_ref(), built.discretization.as_ref(), &pins, &pin_components)
                    .map_err(build_error)?;
        }
        let mut discretization = built.discretization;
        let (element_count, element_size) = (built.elements, built.element_size);
        let TriangleMesh { vertices: surface_vertices, triangles: mut surface_triangles, .. } = built.surface;
        let mut surface_on_cut = vec![false; surface_triangles.len()];
        let mut surface_piece = Vec::new();
        let can_cut = discretization.as_cuttable().is_some();
        let cut_surface = discretization.as_cuttable().and_then(|c| c.surface());
        // Pieces are to be expected: a body that renders its own cut surface, or one that can cut
        // in a scene that cuts or fractures (DG keeps its MLS surface until its first cut).
        let pieces_expected = cut_surface.is_some()
            || (can_cut && (!scene.timeline.is_empty() || scene.fracture.is_some() || scene.rigid_fragments.is_some()));
        let info = BuildInfo {
            backend: discretization.name().to_string(),
            elements: element_count,
            dofs: 3 * discretization.num_nodes(),
            surface_vertices: surface_vertices.len(),
            surface_triangles: surface_triangles.len(),
            element_size,
            seconds: 0.0,
        };

        // A body that does not render its own surface embeds the input's again after a change.
        let input_surface = cut_surface.is_none().then(|| surface_vertices.clone());
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
        let mut collider_frictions = Vec::new();
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
                    collider_frictions.push(*friction);
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
            None if pieces_expected => {
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
        let solver = scene.solver_for.get(name).unwrap_or(&scene.solver).clone();
        settings.solver = match solver {
            SolverSpec::Cholesky => Solver::Cholesky,
            SolverSpec::ConjugateGradient { tolerance, max_iterations, assembled, .. } => {
                Solver::ConjugateGradient { tolerance: tolerance.0, max_iterations, assembled }
            }
        };
        if let SolverSpec::ConjugateGradient { preconditioner, .. } = solver {
            settings.preconditioner = match preconditioner {
                PreconditionerSpec::Auto => Preconditioner::Auto,
                PreconditionerSpec::BlockJacobi => Preconditioner::BlockJacobi,
                PreconditionerSpec::TwoLevel => Preconditioner::TwoLevel,
                PreconditionerSpec::Pieces => Preconditioner::Pieces,
            };
        }
        let plane_colliders: Vec<_> = constraints.planes.iter().map(|p| (p.point, p.normal)).collect();
        let rigid = match &scene.rigid_fragments {
            None => None,
            Some(spec) => {
                let positive = |what: &str, value: Real| {
                    if value.is_finite() && value > 0.0 {
                        Ok(value)
                    } else {
                        Err(build_error(format!("rigid_fragments.{what} must be finite and positive, got {value}")))
                    }
                };
                if spec.check_every == 0 {
                    return Err(build_error("`rigid_fragments.check_every` must be at least 1 step".into()));
                }
                let rules = RigidRules {
                    check_every: u64::from(spec.check_every),
                    max_strain_energy: positive("max_strain_energy", spec.max_strain_energy)?,
                    max_vibration_speed: positive("max_vibration_speed", spec.max_vibration_speed)?,
                    margin: positive("margin", spec.margin.unwrap_or(2.0 * element_size))?,
                    static_impacts: spec.impact == ImpactSpec::Static,
                };
                if !(0.0..=1.0).contains(&spec.restitution) {
                    return Err(build_error(format!(
                        "rigid_fragments.restitution must lie in [0, 1], got {}",
                        spec.restitution
                    )));
                }
                let mut obstacles: Vec<Obstacle> = constraints
                    .planes
                    .iter()
                    .map(|p| Obstacle::Plane { point: p.point, normal: p.normal, friction: p.friction })
                    .collect();
                obstacles.extend(collider_meshes.iter().zip(&collider_frictions).map(|(mesh, &friction)| {
                    Obstacle::Mesh { vertices: mesh.vertices.clone(), triangles: mesh.triangles.clone(), friction }
                }));
                let world_settings = WorldSettings {
                    gravity: settings.gravity,
                    time_step: settings.time_step,
                    damping: settings.rayleigh_alpha,
                    friction: constraints.surface_contact.as_ref().map_or(0.5, |c| c.friction),
                    return_speed: positive("return_speed", spec.return_speed)?,
                    impact: match spec.impact {
                        ImpactSpec::Dynamic => ImpactResponse::Return,
                        ImpactSpec::Static => ImpactResponse::Keep,
                    },
                    restitution: spec.restitution,
                };
                let world = RigidWorld::new(world_settings, &obstacles).map_err(|e| build_error(e.to_string()))?;
                Some(RigidHybrid::new(world, rules, constraints.pinned_dofs.clone()))
            }
        };
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
            fracture: scene.fracture.as_ref().zip(material.tensile_strength).map(|(f, strength)| FractureCheck {
                every: u64::from(f.every),
                strength,
                after_impacts: f.after_impacts.map(u64::from),
                until: 0,
            }),
            refinement: scene
                .refinement
                .as_ref()
                .map(|r| RefinementCheck { every: u64::from(r.every), stress: r.stress.0 }),
            input_surface,
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
            rigid,
            pin_velocities,
            pin_components,
            moving_dofs: Vec::new(),
        };
        simulation.resolve_moving_pins()?;
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
}

/// The DOFs pin regions hold when some hold only some components: each region's nodes, the
/// components it names.
pub(super) fn component_pins(
    registration: &dyn cleave_registry::Backend,
    discretization: &dyn Discretization,
    pins: &[Region],
    components: &[[bool; 3]],
) -> Result<Vec<usize>, String> {
    let mut dofs = Vec::new();
    for (region, held) in pins.iter().zip(components) {
        let resolved =
            registration.resolve_pins(discretization, std::slice::from_ref(region)).map_err(|e| e.to_string())?;
        if resolved.pinned_dofs.is_empty() && !resolved.extra_load.is_empty() {
            return Err("a pin holding some components needs a backend with nodal pins".into());
        }
        dofs.extend(resolved.pinned_dofs.into_iter().filter(|d| held[d % 3]));
    }
    dofs.sort_unstable();
    dofs.dedup();
    Ok(dofs)
}

/// Whether an OBJ must bound a solid.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Closed {
    /// The object: closed, manifold, outward (`TriangleMesh::validate_closed`).
    Required,
    /// Colliders and cut soups: any triangles.
    NotRequired,
}

/// The one OBJ loader of scenes: reads an OBJ named by a scene (relative to the scene file),
/// validates it as a closed surface when `closed` asks, and places it by `transform` (`lowest_z`:
/// its lowest vertex lands at that height). Errors name the scene, the mesh and `what` (the
/// field, if not the object).
pub(super) fn load_obj(
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
pub(super) fn surface_contact_on(settings: &SurfaceContact, surface: &EmbeddedSurface) -> SurfaceContact {
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

/// Line and column in the scene file of a position (1-based) inside `inner`, a slice of the
/// file's text (a backend's settings); falls back to the position within `inner`.
fn position_within(text: &str, inner: &str, line: usize, column: usize) -> (usize, usize) {
    let Some(offset) = text.find(inner) else { return (line, column) };
    let before = &text[..offset];
    let start_line = before.matches('\n').count() + 1;
    let start_column = offset - before.rfind('\n').map_or(0, |i| i + 1) + 1;
    if line <= 1 { (start_line, start_column + column - 1) } else { (start_line + line - 1, column) }
}
