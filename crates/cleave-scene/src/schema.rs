//! The RON scene schema (documented field by field in `docs/scene-format.md`). Every struct
//! denies unknown fields; values that can be checked alone (materials, time step, normals) are
//! checked while parsing, so their errors carry the file's line and column.

use cleave_core::{Material, Real};
use ron::value::RawValue;
use serde::Deserialize;
use std::collections::BTreeMap;

/// A whole scene.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Scene {
    /// Human-readable name (recorded in the MCAP).
    pub name: String,
    /// The solid.
    pub object: Object,
    /// Its material.
    pub material: ValidMaterial,
    /// The backend that runs by default (a name of `cleave_registry::names()`); `cargo xtask run
    /// --backend NAME` overrides it.
    pub backend: String,
    /// Per-backend settings keyed by backend name, `{ "voxel": (cell_size: 0.25), ... }`; each
    /// entry is read by its backend's registration (`docs/scene-format.md`). One scene carries
    /// the settings of every backend it runs on.
    pub settings: BTreeMap<String, Box<RawValue>>,
    /// Time step `h` [s].
    pub time_step: Positive,
    /// Number of steps to run.
    pub steps: u64,
    /// Gravity [m/s²]; default `(0, 0, -9.81)` (z up, as Foxglove).
    #[serde(default = "default_gravity")]
    pub gravity: [Real; 3],
    /// Linear solver; default CG.
    #[serde(default)]
    pub solver: SolverSpec,
    /// The linear solver of a backend that runs this scene, in place of `solver` (a voxel body
    /// of thousands of cubes solves faster by CG than a factorization a tetrahedral one likes).
    #[serde(default)]
    pub solver_for: BTreeMap<String, SolverSpec>,
    /// Remove the angular momentum the step's own elastic forces and contact couples add to a
    /// free piece (`Settings::conserve_angular_momentum`); default false.
    #[serde(default)]
    pub conserve_angular_momentum: bool,
    /// Solve a step again with the rotations of its solution when some element turns by more
    /// than this angle [rad] in it (`Settings::rotation_refresh_angle`); default: never.
    #[serde(default)]
    pub rotation_refresh_angle: Option<Positive>,
    /// Pinned regions.
    #[serde(default)]
    pub pins: Vec<PinSpec>,
    /// Colliders.
    #[serde(default)]
    pub colliders: Vec<ColliderSpec>,
    /// Contact of the body's surface with itself (between the pieces of a cut body and within
    /// one piece). Default: on for a backend that cuts, with the first collider's stiffness and
    /// damping; `Some((...))` sets it, `contact: None` turns it off.
    #[serde(default)]
    pub contact: Option<Option<ContactSpec>>,
    /// Material points whose positions are logged every step.
    #[serde(default)]
    pub probes: Vec<ProbeSpec>,
    /// Timed events (cuts and blades).
    #[serde(default)]
    pub timeline: Vec<EventSpec>,
    /// Stress fracture: when it is checked (needs the material's `tensile_strength`).
    #[serde(default)]
    pub fracture: Option<FractureSpec>,
    /// Stress-driven adaptive refinement (a backend that refines; how it splits is in its
    /// settings).
    #[serde(default)]
    pub refinement: Option<RefinementSpec>,
    /// Rigid fragments: free pieces that move as rigid bodies (rapier) until an impact.
    #[serde(default)]
    pub rigid_fragments: Option<RigidSpec>,
    /// Where and how often to record.
    #[serde(default)]
    pub output: OutputSpec,
}

fn default_gravity() -> [Real; 3] {
    [0.0, 0.0, -9.81]
}

/// A material validated while parsing.
#[derive(Clone, Copy, Debug, Deserialize)]
#[serde(try_from = "Material")]
pub struct ValidMaterial(pub Material);

impl TryFrom<Material> for ValidMaterial {
    type Error = cleave_core::MaterialError;
    fn try_from(material: Material) -> Result<Self, Self::Error> {
        material.validate().map(|()| Self(material))
    }
}

/// A finite number > 0.
#[derive(Clone, Copy, Debug, Deserialize)]
#[serde(try_from = "Real")]
pub struct Positive(pub Real);

impl TryFrom<Real> for Positive {
    type Error = String;
    fn try_from(value: Real) -> Result<Self, Self::Error> {
        if value.is_finite() && value > 0.0 {
            Ok(Self(value))
        } else {
            Err(format!("expected a finite number > 0, got {value}"))
        }
    }
}

/// A non-zero finite vector, normalized while parsing.
#[derive(Clone, Copy, Debug, Deserialize)]
#[serde(try_from = "[Real; 3]")]
pub struct Direction(pub [Real; 3]);

impl TryFrom<[Real; 3]> for Direction {
    type Error = String;
    fn try_from(v: [Real; 3]) -> Result<Self, Self::Error> {
        let norm = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
        if norm.is_finite() && norm > 0.0 {
            Ok(Self(v.map(|x| x / norm)))
        } else {
            Err(format!("expected a non-zero finite direction, got ({}, {}, {})", v[0], v[1], v[2]))
        }
    }
}

/// The solid being simulated.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub enum Object {
    /// A closed triangle mesh from an OBJ file (path relative to the scene file).
    Mesh {
        /// OBJ path.
        path: String,
        /// Placement of the mesh in the world.
        #[serde(default)]
        transform: Transform,
    },
    /// An axis-aligned box `[min, max]`.
    Box {
        /// minimum corner
        min: [Real; 3],
        /// maximum corner
        max: [Real; 3],
    },
}

/// `p ↦ translation + R (scale · p)`, then optionally lifted so its lowest point sits at `rest_on`.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Transform {
    /// Uniform scale.
    #[serde(default = "one")]
    pub scale: Real,
    /// Rotation as Euler angles in degrees about x, then y, then z (extrinsic).
    #[serde(default)]
    pub rotation_degrees: [Real; 3],
    /// Translation [m].
    #[serde(default)]
    pub translation: [Real; 3],
    /// If set, translate along z so the lowest vertex is at this height [m].
    #[serde(default)]
    pub lowest_z: Option<Real>,
}

fn one() -> Real {
    1.0
}

impl Default for Transform {
    fn default() -> Self {
        Self { scale: 1.0, rotation_degrees: [0.0; 3], translation: [0.0; 3], lowest_z: None }
    }
}

/// Linear solver.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub enum SolverSpec {
    /// Sparse Cholesky, symbolic factorization reused.
    Cholesky,
    /// Block-Jacobi preconditioned conjugate gradients, warm-started.
    ConjugateGradient {
        /// relative residual to reach (default 1e-6)
        #[serde(default = "default_tolerance")]
        tolerance: Positive,
        /// iteration limit (default 2000)
        #[serde(default = "default_iterations")]
        max_iterations: usize,
        /// assembled (`true`) or matrix-free (default)
        #[serde(default)]
        assembled: bool,
        /// preconditioner (default `Auto`)
        #[serde(default)]
        preconditioner: PreconditionerSpec,
    },
}

/// Preconditioner of the CG solver (`cleave_integrator::Preconditioner`).
#[derive(Clone, Copy, Debug, Default, Deserialize, PartialEq, Eq)]
#[serde(deny_unknown_fields)]
pub enum PreconditionerSpec {
    /// Two-level where the backend offers a small enough coarse space, else block-Jacobi.
    #[default]
    Auto,
    /// Inverse 3×3 diagonal node blocks.
    BlockJacobi,
    /// Block-Jacobi plus the backend's coarse space.
    TwoLevel,
    /// Cholesky of each piece without the contacts between pieces, plus the pieces' rigid
    /// motions with them: for bodies cut into many pieces.
    Pieces,
}

fn default_tolerance() -> Positive {
    Positive(1e-6)
}

fn default_iterations() -> usize {
    2000
}

impl Default for SolverSpec {
    fn default() -> Self {
        Self::ConjugateGradient {
            tolerance: default_tolerance(),
            max_iterations: default_iterations(),
            assembled: false,
            preconditioner: PreconditionerSpec::Auto,
        }
    }
}

/// When stress fracture is checked (the material's `tensile_strength` is the threshold).
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FractureSpec {
    /// Check after every this many steps (1: every step).
    #[serde(default = "one_u32")]
    pub every: u32,
    /// Check only in the first this many steps after a rigid fragment returned at an impact
    /// (the paper's hybrid: fracture at impacts, not under a resting load); needs
    /// `rigid_fragments`. Absent: check all the time.
    #[serde(default)]
    pub after_impacts: Option<u32>,
}

/// When and where the body refines: elements whose largest absolute principal stress exceeds
/// `stress` split (kaufmann2008 §10).
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RefinementSpec {
    /// The stress threshold [Pa].
    pub stress: Positive,
    /// Check after every this many steps (1: every step).
    #[serde(default = "one_u32")]
    pub every: u32,
}

/// When a free piece moves as a rigid body and when it returns (docs/math/rigid-fragments.md).
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RigidSpec {
    /// Pieces are checked for the rigid world after every this many steps.
    #[serde(default = "ten_u32")]
    pub check_every: u32,
    /// A piece goes rigid only with less elastic energy than this per unit mass [J/kg]; the
    /// default, 1e-2 J/kg, is the energy of lifting it by 1 mm.
    #[serde(default = "default_rigid_strain_energy")]
    pub max_strain_energy: Real,
    /// ... and with a vibration (the motion that is not rigid) whose root mean square speed is
    /// below this [m/s].
    #[serde(default = "default_rigid_vibration")]
    pub max_vibration_speed: Real,
    /// A rigid fragment whose contacts give it more than this velocity change in one step
    /// returns to the deformable body before that step [m/s].
    #[serde(default = "default_rigid_return_speed")]
    pub return_speed: Real,
    /// A rigid fragment returns when it comes this close to a deformable piece (and a piece
    /// goes rigid only four times as far from every deformable one) [m]; default: two element
    /// sizes.
    #[serde(default)]
    pub margin: Option<Real>,
    /// What an impact on a rigid fragment does (docs/math/rigid-fragments.md §2, §5).
    #[serde(default)]
    pub impact: ImpactSpec,
    /// Coefficient of restitution of the rigid world's contacts (0: no bounce, 1: elastic);
    /// the FE contact has none.
    #[serde(default)]
    pub restitution: Real,
}

/// What an impact on a rigid fragment does.
#[derive(Clone, Copy, Debug, Default, Deserialize, PartialEq, Eq)]
pub enum ImpactSpec {
    /// The fragment returns to the deformable body before the impact, which the FE model meets
    /// dynamically (and may fracture in, with `fracture`).
    #[default]
    Dynamic,
    /// The paper's pig (mueller2004 §2.4, §4): the fragment bounces as a rigid body, and a static
    /// FE analysis of the impact (its contact impulses over the step and the D'Alembert force
    /// they balance) gives the stress that `fracture`, when set, breaks it with; the pieces of
    /// a break return to the deformable body with the rigid motion after the bounce.
    Static,
}

fn default_rigid_strain_energy() -> Real {
    1e-2
}

fn default_rigid_vibration() -> Real {
    0.05
}

fn default_rigid_return_speed() -> Real {
    0.5
}

/// Pinned material.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub enum PinSpec {
    /// Every node whose rest position lies in the box `[min, max]` is held fixed.
    Region {
        /// minimum corner
        min: [Real; 3],
        /// maximum corner
        max: [Real; 3],
        /// The held nodes move at this constant velocity [m/s] (a pulled or pushed end);
        /// default: at rest.
        #[serde(default)]
        velocity: [Real; 3],
        /// Which components are held (x, y, z); default all three. A grip that holds only
        /// the pull's component leaves the sides free to contract (no stress concentration at
        /// the grip's edge from clamping the Poisson contraction).
        #[serde(default = "all_components")]
        components: [bool; 3],
    },
}

/// A collider.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub enum ColliderSpec {
    /// The half-space above a plane.
    Plane {
        /// a point on the plane
        point: [Real; 3],
        /// normal pointing into the allowed side
        normal: Direction,
        /// penalty stiffness per contact point [N/m]
        stiffness: Positive,
        /// normal damping per contact point [N·s/m]
        #[serde(default)]
        damping: Real,
        /// Coulomb friction coefficient μ (0: frictionless)
        #[serde(default = "default_friction")]
        friction: Real,
    },
    /// A static triangle mesh from an OBJ file (relative to the scene file): the allowed side
    /// is the one its triangles' right-hand normals point to.
    Mesh {
        /// path of the OBJ
        path: String,
        /// placement
        #[serde(default)]
        transform: Transform,
        /// penalty stiffness per contact point [N/m]
        stiffness: Positive,
        /// normal damping per contact point [N·s/m]
        #[serde(default)]
        damping: Real,
        /// Coulomb friction coefficient μ (0: frictionless)
        #[serde(default = "default_friction")]
        friction: Real,
        /// how deep behind the mesh a point is still pushed back, and how far in front of it (beyond
        /// its motion in the step) it is tested [m]; default: a tenth of the element size
        #[serde(default)]
        reach: Option<Real>,
    },
}

fn default_friction() -> Real {
    0.5
}

/// Contact of the body's surface with itself.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ContactSpec {
    /// penalty stiffness per surface point [N/m]
    pub stiffness: Positive,
    /// normal damping per surface point [N·s/m]
    #[serde(default)]
    pub damping: Real,
    /// Coulomb friction coefficient μ (0: frictionless)
    #[serde(default = "default_friction")]
    pub friction: Real,
    /// distance the surfaces are held apart [m]
    #[serde(default)]
    pub thickness: Real,
    /// how deep behind a triangle a point is still pushed back, and how far in front of it
    /// (beyond its motion in the step) it is tested [m]; default: a tenth of the element size
    #[serde(default)]
    pub reach: Option<Real>,
}

/// A logged material point.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ProbeSpec {
    /// Key in the stats channel.
    pub name: String,
    /// Rest position [m].
    pub position: [Real; 3],
}

/// A timed event.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub enum EventSpec {
    /// Cut the material along a surface (in rest space) at `time`.
    Cut {
        /// when [s]
        time: Real,
        /// the cut surface
        surface: CutSpec,
    },
    /// A blade: a planar polygon moved along a keyframed rigid path, cutting progressively
    /// between `start` and `end`: its polygon where it stands at `start` (an incision), then
    /// the surface its cutting edges sweep.
    Blade {
        /// first time it cuts [s]
        start: Real,
        /// last time it cuts [s]
        end: Real,
        /// the blade's face in its own frame (≥ 3 points, planar)
        polygon: Vec<[Real; 3]>,
        /// poses of its frame, times strictly increasing
        path: Vec<KeyframeSpec>,
        /// the edges that cut (edge `i` joins points `i` and `i + 1`); default: the edges that
        /// lead the motion within the polygon's plane
        #[serde(default)]
        cutting_edges: Option<Vec<usize>>,
    },
}

impl EventSpec {
    /// The time the event first acts.
    pub fn start(&self) -> Real {
        match self {
            EventSpec::Cut { time, .. } => *time,
            EventSpec::Blade { start, .. } => *start,
        }
    }
}

/// A cut surface of a `Cut` event, in rest space.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub enum CutSpec {
    /// The whole plane through `point` with normal `normal`.
    Plane {
        /// a point on the plane
        point: [Real; 3],
        /// its normal
        normal: Direction,
    },
    /// A triangle soup from an OBJ file (relative to the scene file), placed by `transform`.
    Obj {
        /// path of the OBJ
        path: String,
        /// placement
        #[serde(default)]
        transform: Transform,
    },
}

/// One pose of a blade.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct KeyframeSpec {
    /// time [s]
    pub time: Real,
    /// translation of the blade's frame [m]
    #[serde(default)]
    pub translation: [Real; 3],
    /// rotation of the blade's frame, degrees about x, then y, then z
    #[serde(default)]
    pub rotation_degrees: [Real; 3],
}

/// Recording options.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct OutputSpec {
    /// MCAP path (relative to the working directory); overridden by `--out`.
    #[serde(default)]
    pub mcap: Option<String>,
    /// Record the surface every this many steps.
    #[serde(default = "one_u32")]
    pub surface_every: u32,
    /// Flush (close a chunk and write it to disk) every this many steps.
    #[serde(default = "ten_u32")]
    pub flush_every: u32,
}

fn all_components() -> [bool; 3] {
    [true; 3]
}

fn one_u32() -> u32 {
    1
}

fn ten_u32() -> u32 {
    10
}

impl Default for OutputSpec {
    fn default() -> Self {
        Self { mcap: None, surface_every: 1, flush_every: 10 }
    }
}
