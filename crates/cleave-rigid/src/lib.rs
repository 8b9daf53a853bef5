//! Rigid fragments (mueller2004 §2.4): a free piece of a deformable body handed to a rigid body
//! on `rapier3d-f64` and back, exact in linear and angular momentum and never adding kinetic
//! energy (docs/math/rigid-fragments.md). The scene runner decides when (the switching rules);
//! this crate does the hand-off and owns the rigid world. It knows no backend: a piece is a list
//! of nodes with lumped masses, as `Cuttable::pieces` gives it.

use cleave_core::{Point3, Real, Vector3};
use nalgebra::Matrix3;
use rapier3d_f64::math::Vector as DVec3;
use rapier3d_f64::math::{Pose, Vector};
use rapier3d_f64::prelude::{
    ColliderBuilder, ColliderHandle, MassProperties, PhysicsWorld, RigidBodyBuilder, RigidBodyHandle, SharedShape,
};

/// The rigid motion that carries the same linear and angular momentum as a piece's nodes.
#[derive(Clone, Debug, PartialEq)]
pub struct RigidFit {
    /// Total mass [kg].
    pub mass: Real,
    /// Centre of mass [m].
    pub centre: Point3<Real>,
    /// Velocity of the centre of mass [m/s].
    pub velocity: Vector3<Real>,
    /// Angular momentum about the centre of mass [kg·m²/s].
    pub angular_momentum: Vector3<Real>,
    /// Inertia tensor about the centre of mass, in the current configuration [kg·m²].
    pub inertia: Matrix3<Real>,
    /// `inertia⁻¹ · angular_momentum` [rad/s].
    pub angular_velocity: Vector3<Real>,
    /// Kinetic energy of the nodes' velocities [J].
    pub kinetic_energy: Real,
    /// Kinetic energy of the rigid motion, `½ m |v|² + ½ ω·L` (never more than
    /// `kinetic_energy`: the rigid field is the velocity field of least kinetic energy with the
    /// nodes' momenta) [J].
    pub rigid_kinetic_energy: Real,
}

impl RigidFit {
    /// The rigid fit of `nodes` (node indices into `x` and `v`, three DOFs each) with lumped
    /// masses `mass_diagonal` (one per DOF, as `Mass::diagonal`; a node's three entries are
    /// taken to be equal, as every nodal backend's are, and its x entry is read). `None` for a piece without
    /// mass or whose inertia is singular (all its nodes on one line).
    pub fn of(nodes: &[u32], mass_diagonal: &[Real], x: &[Real], v: &[Real]) -> Option<Self> {
        let at = |values: &[Real], n: u32| {
            let i = 3 * n as usize;
            Vector3::new(values[i], values[i + 1], values[i + 2])
        };
        let node_mass = |n: u32| mass_diagonal[3 * n as usize];
        let mass: Real = nodes.iter().map(|&n| node_mass(n)).sum();
        if mass.is_nan() || mass <= 0.0 {
            return None;
        }
        let (mut first, mut momentum) = (Vector3::zeros(), Vector3::zeros());
        let mut kinetic_energy = 0.0;
        for &n in nodes {
            let (m, vn) = (node_mass(n), at(v, n));
            first += m * at(x, n);
            momentum += m * vn;
            kinetic_energy += 0.5 * m * vn.norm_squared();
        }
        let centre = first / mass;
        let velocity = momentum / mass;
        let (mut angular_momentum, mut inertia) = (Vector3::zeros(), Matrix3::zeros());
        for &n in nodes {
            let (m, r) = (node_mass(n), at(x, n) - centre);
            angular_momentum += m * r.cross(&(at(v, n) - velocity));
            inertia += m * (Matrix3::identity() * r.norm_squared() - r * r.transpose());
        }
        // A singular inertia (collinear nodes) has no unique angular velocity.
        let scale = inertia.trace().max(Real::MIN_POSITIVE);
        let eigenvalues = inertia.symmetric_eigenvalues();
        if eigenvalues.min() <= 1e-12 * scale {
            return None;
        }
        let angular_velocity = inertia.cholesky()?.solve(&angular_momentum);
        let rigid_kinetic_energy = 0.5 * mass * velocity.norm_squared() + 0.5 * angular_velocity.dot(&angular_momentum);
        Some(Self {
            mass,
            centre: Point3::from(centre),
            velocity,
            angular_momentum,
            inertia,
            angular_velocity,
            kinetic_energy,
            rigid_kinetic_energy,
        })
    }

    /// Kinetic energy per unit mass of the motion that is not rigid (vibration) [J/kg].
    pub fn vibration_energy_per_mass(&self) -> Real {
        (self.kinetic_energy - self.rigid_kinetic_energy).max(0.0) / self.mass
    }
}

/// A static obstacle the rigid fragments touch, the same ones the deformable body touches.
#[derive(Clone, Debug)]
pub enum Obstacle {
    /// A plane through `point` whose `normal` points to the allowed side.
    Plane {
        /// a point on the plane [m]
        point: Point3<Real>,
        /// unit outward normal
        normal: Vector3<Real>,
        /// Coulomb friction coefficient
        friction: Real,
    },
    /// A fixed triangle mesh.
    Mesh {
        /// vertices [m]
        vertices: Vec<Point3<Real>>,
        /// triangles, right-hand normals to the allowed side
        triangles: Vec<[u32; 3]>,
        /// Coulomb friction coefficient
        friction: Real,
    },
}

/// What the rigid world is built with.
#[derive(Clone, Debug)]
pub struct WorldSettings {
    /// Gravity [m/s²].
    pub gravity: Vector3<Real>,
    /// Time step [s] (the integrator's).
    pub time_step: Real,
    /// Mass-proportional damping α [1/s] (the integrator's Rayleigh α: the same decay of a rigid
    /// motion in both worlds).
    pub damping: Real,
    /// Friction between two fragments.
    pub friction: Real,
    /// A fragment whose contacts in one step change its velocity by more than `return_speed`
    /// [m/s] (net impulse over mass) is returned to the deformable body before that step (an impact the FEM must
    /// resolve and may fracture at).
    pub return_speed: Real,
    /// What an impact does (one beyond `return_speed`).
    pub impact: ImpactResponse,
    /// Coefficient of restitution of every contact in the rigid world (fragments with each
    /// other and with the obstacles): the ratio of the normal separating speed to the
    /// approaching one. 0: no bounce.
    pub restitution: Real,
}

/// What the rigid world does with a fragment hit beyond `return_speed`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum ImpactResponse {
    /// The step is rolled back and the fragment returns to the deformable body, which meets
    /// the impact dynamically.
    #[default]
    Return,
    /// The step is kept (the fragment bounces as a rigid body) and the impact's contact
    /// impulses are reported ([`RigidWorld::impacts`]) for a static FE analysis, as the
    /// paper's pig (mueller2004 §4).
    Keep,
}

/// One fragment's contacts in a step that hit it beyond `return_speed`
/// ([`ImpactResponse::Keep`]): where and how hard, in the fragment's own frame (the world frame
/// at its hand-off, origin at its centre of mass, where its nodes' offsets live).
#[derive(Clone, Debug, PartialEq)]
pub struct Impact {
    /// Index of the fragment in [`RigidWorld::fragments`].
    pub fragment: usize,
    /// Per contact point: the point on the fragment and the normal impulse it received [N·s].
    pub contacts: Vec<(Point3<Real>, Vector3<Real>)>,
    /// The speed at which its centre of mass approached along the net impulse before the step,
    /// `max(0, −v_c · J / |J|)` [m/s].
    pub approach_speed: Real,
}

/// The collider of a fragment, in world coordinates at the hand-off.
#[derive(Clone, Copy, Debug)]
pub enum FragmentShape<'a> {
    /// The convex hull of these points.
    Hull(&'a [Point3<Real>]),
    /// This closed triangle mesh (the piece's render surface): exact, so fragments that fit
    /// into each other along a crack do not overlap as their hulls would.
    Surface {
        /// vertices
        vertices: &'a [Point3<Real>],
        /// outward triangles
        triangles: &'a [[u32; 3]],
    },
}

/// A piece moving as a rigid body.
#[derive(Clone, Debug)]
pub struct Fragment {
    /// Its nodes (indices into the body's DOF vector / 3), ascending.
    pub nodes: Vec<u32>,
    /// Each node's offset from the centre of mass at the hand-off (world frame then, which is
    /// the body's local frame).
    offsets: Vec<Vector3<Real>>,
    /// Mass [kg].
    pub mass: Real,
    body: RigidBodyHandle,
    collider: ColliderHandle,
}

impl Fragment {
    /// Each node's offset from the centre of mass at the hand-off: its position in the
    /// fragment's own frame.
    pub fn offsets(&self) -> &[Vector3<Real>] {
        &self.offsets
    }
}

/// The rigid fragments and the rapier world they move in.
pub struct RigidWorld {
    world: PhysicsWorld,
    /// The obstacles' planes (point, unit normal) and the meshes' boxes (min, max), for the
    /// look-ahead of [`RigidWorld::about_to_hit`].
    planes: Vec<(Point3<Real>, Vector3<Real>)>,
    mesh_boxes: Vec<(Point3<Real>, Point3<Real>)>,
    fragments: Vec<Fragment>,
    settings: WorldSettings,
    /// Each fragment's pose and velocities before the step (the roll-back of an impact).
    saved: Vec<(Pose, DVec3, DVec3)>,
    /// The impacts of the last step ([`ImpactResponse::Keep`]).
    impacts: Vec<Impact>,
}

fn to_glam(v: &Vector3<Real>) -> Vector {
    DVec3::new(v.x, v.y, v.z)
}

fn from_glam(v: Vector) -> Vector3<Real> {
    Vector3::new(v.x, v.y, v.z)
}

/// Why a piece could not be made rigid.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum HandOffError {
    /// No mass or a singular inertia.
    #[error("the piece has no mass or all its nodes lie on one line")]
    Degenerate,
    /// Its convex hull could not be built (fewer than four points not in one plane).
    #[error("the piece's points span no volume, so they have no convex hull")]
    NoHull,
    /// A mesh (an obstacle's or a fragment's surface) that rapier refuses.
    #[error("triangle mesh: {0}")]
    Mesh(String),
}

impl RigidWorld {
    /// An empty world with the scene's obstacles as fixed colliders.
    pub fn new(settings: WorldSettings, obstacles: &[Obstacle]) -> Result<Self, HandOffError> {
        let mut world = PhysicsWorld::default();
        let (mut planes, mut mesh_boxes) = (Vec::new(), Vec::new());
        for obstacle in obstacles {
            match obstacle {
                Obstacle::Plane { point, normal, .. } => planes.push((*point, normal.normalize())),
                Obstacle::Mesh { vertices, .. } => {
                    let (mut lo, mut hi) = (Point3::from([Real::MAX; 3]), Point3::from([Real::MIN; 3]));
                    for p in vertices {
                        lo = lo.inf(p);
                        hi = hi.sup(p);
                    }
                    mesh_boxes.push((lo, hi));
                }
            }
        }
        world.gravity = to_glam(&settings.gravity);
        world.integration_parameters.dt = settings.time_step;
        // Fragments handed over while pressed together by the FE contact overlap a little;
        // rapier's default push-out (up to 3 m/s) would read as an impact. At a tenth of the
        // return speed it separates them gently and stays below the impact rule.
        world.integration_parameters.normalized_max_corrective_velocity = 0.1 * settings.return_speed;
        // A fragment's trimesh has many triangles within the prediction distance of the ground;
        // merged into one manifold of a few points, the points kept are not the lowest, and a
        // resting pile jitters and sinks (measured: 1.6 mm in 0.5 s on the shattered bunny).
        world.integration_parameters.contact_clustering = false;
        for obstacle in obstacles {
            let (collider, point) = match obstacle {
                Obstacle::Plane { point, normal, friction } => {
                    let normal = to_glam(&normal.normalize());
                    (ColliderBuilder::new(SharedShape::halfspace(normal)).friction(*friction), point.coords)
                }
                Obstacle::Mesh { vertices, triangles, friction } => {
                    let vertices = vertices.iter().map(|p| to_glam(&p.coords)).collect();
                    let builder = ColliderBuilder::trimesh(vertices, triangles.clone())
                        .map_err(|e| HandOffError::Mesh(e.to_string()))?;
                    (builder.friction(*friction), Vector3::zeros())
                }
            };
            let body = world.insert_body(RigidBodyBuilder::fixed().translation(to_glam(&point)));
            let collider = collider.restitution(settings.restitution).build();
            world.colliders.insert_with_parent(collider, body, &mut world.bodies);
        }
        Ok(Self { world, planes, mesh_boxes, fragments: Vec::new(), settings, saved: Vec::new(), impacts: Vec::new() })
    }

    /// The fragments now.
    pub fn fragments(&self) -> &[Fragment] {
        &self.fragments
    }

    /// Whether no fragment is rigid.
    pub fn is_empty(&self) -> bool {
        self.fragments.is_empty()
    }

    /// Makes `nodes` a rigid body: its shape the nodes' current positions, its collider
    /// `shape`, its mass and inertia the nodes' lumped masses, and its velocity the rigid fit of
    /// theirs (same momenta). Returns the fit.
    pub fn add(
        &mut self,
        nodes: Vec<u32>,
        mass_diagonal: &[Real],
        x: &[Real],
        v: &[Real],
        shape: FragmentShape<'_>,
    ) -> Result<RigidFit, HandOffError> {
        let fit = RigidFit::of(&nodes, mass_diagonal, x, v).ok_or(HandOffError::Degenerate)?;
        let local =
            |points: &[Point3<Real>]| -> Vec<Vector> { points.iter().map(|p| to_glam(&(p - fit.centre))).collect() };
        let builder = match shape {
            FragmentShape::Hull(points) => ColliderBuilder::convex_hull(&local(points)).ok_or(HandOffError::NoHull)?,
            FragmentShape::Surface { vertices, triangles } => {
                ColliderBuilder::trimesh(local(vertices), triangles.to_vec())
                    .map_err(|e| HandOffError::Mesh(e.to_string()))?
            }
        };
        let collider =
            builder.density(0.0).friction(self.settings.friction).restitution(self.settings.restitution).build();
        let i = &fit.inertia;
        let inertia = rapier3d_f64::math::Matrix::from_cols(
            DVec3::new(i[(0, 0)], i[(1, 0)], i[(2, 0)]),
            DVec3::new(i[(0, 1)], i[(1, 1)], i[(2, 1)]),
            DVec3::new(i[(0, 2)], i[(1, 2)], i[(2, 2)]),
        );
        let body = RigidBodyBuilder::dynamic()
            .translation(to_glam(&fit.centre.coords))
            .additional_mass_properties(MassProperties::with_inertia_matrix(DVec3::ZERO, fit.mass, inertia))
            .linvel(to_glam(&fit.velocity))
            .angvel(to_glam(&fit.angular_velocity))
            .linear_damping(self.settings.damping)
            .angular_damping(self.settings.damping)
            .build();
        let body = self.world.insert_body(body);
        let collider = self.world.colliders.insert_with_parent(collider, body, &mut self.world.bodies);
        // Rapier sums a body's mass properties at its next step; now, so that they are there
        // to read before it.
        self.world.bodies[body].recompute_mass_properties_from_colliders(&self.world.colliders);
        let offsets = nodes
            .iter()
            .map(|&n| {
                let k = 3 * n as usize;
                Vector3::new(x[k], x[k + 1], x[k + 2]) - fit.centre.coords
            })
            .collect();
        self.fragments.push(Fragment { nodes, offsets, mass: fit.mass, body, collider });
        Ok(fit)
    }

    /// Removes fragment `index` from the rigid world (its nodes' motion is whatever
    /// [`write_motion`](Self::write_motion) last wrote: the rigid field of its body), and
    /// forgets the last step's impacts.
    pub fn remove(&mut self, index: usize) -> Fragment {
        // The impacts name fragments by index.
        self.impacts.clear();
        let fragment = self.fragments.swap_remove(index);
        self.world.remove_body_with_colliders(fragment.body, true);
        fragment
    }

    /// Removes every fragment.
    pub fn clear(&mut self) {
        while !self.fragments.is_empty() {
            self.remove(self.fragments.len() - 1);
        }
    }

    /// Advances the rigid world by one step. Fragments whose contacts gave them more than
    /// `return_speed × mass` of net contact impulse are taken out and returned (indices in the fragment
    /// list before the step, which they leave): the world is rolled back to before the step and
    /// stepped again without them, so the deformable body meets the impact from the velocities
    /// before it. Fragments near a returned one are not returned here (the caller's proximity
    /// rule does that).
    ///
    /// With [`ImpactResponse::Keep`] nothing is returned: the step stands, and the fragments hit
    /// are listed in [`RigidWorld::impacts`].
    pub fn step(&mut self) -> Vec<Fragment> {
        let mut returned = Vec::new();
        self.impacts.clear();
        if self.fragments.is_empty() {
            return returned;
        }
        if self.settings.impact == ImpactResponse::Keep {
            // Velocities and turns before the step: the contacts are found at the poses the
            // step starts from, so their world normals are turned into a fragment's frame by
            // its rotation then.
            let before: Vec<(Vector3<Real>, rapier3d_f64::math::Rotation)> = self
                .fragments
                .iter()
                .map(|f| {
                    let body = &self.world.bodies[f.body];
                    (from_glam(body.linvel()), body.position().rotation)
                })
                .collect();
            self.world.step();
            for i in 0..self.fragments.len() {
                if self.contact_impulse(i) > self.settings.return_speed * self.fragments[i].mass {
                    let rotation = before[i].1;
                    let contacts = self.contact_points(i, rotation);
                    let net = contacts.iter().map(|(_, j)| j).sum::<Vector3<Real>>();
                    let net = from_glam(rotation * to_glam(&net));
                    let approach_speed = (-before[i].0.dot(&net) / net.norm().max(Real::MIN_POSITIVE)).max(0.0);
                    self.impacts.push(Impact { fragment: i, contacts, approach_speed });
                }
            }
            return returned;
        }
        loop {
            self.saved.clear();
            for f in &self.fragments {
                let body = &self.world.bodies[f.body];
                self.saved.push((*body.position(), body.linvel(), body.angvel()));
            }
            self.world.step();
            let hit: Vec<usize> = (0..self.fragments.len())
                .filter(|&i| self.contact_impulse(i) > self.settings.return_speed * self.fragments[i].mass)
                .collect();
            if hit.is_empty() {
                return returned;
            }
            for (f, (pose, linvel, angvel)) in self.fragments.iter().zip(&self.saved) {
                let body = &mut self.world.bodies[f.body];
                body.set_position(*pose, true);
                body.set_linvel(*linvel, true);
                body.set_angvel(*angvel, true);
            }
            for &i in hit.iter().rev() {
                returned.push(self.remove(i));
            }
            if self.fragments.is_empty() {
                return returned;
            }
        }
    }

    /// Fragments about to hit an obstacle fast ([`RigidWorld::approaching`]), from the nodes'
    /// motion as last written (`x`, `v`). They are to return before the impact, so that the FE
    /// model meets the approach as it would have without the rigid world (its contact sees
    /// only what is within its reach at the start of a step).
    pub fn about_to_hit(&self, x: &[Real], v: &[Real], margin: Real, steps: Real) -> Vec<usize> {
        (0..self.fragments.len()).filter(|&i| self.approaching(&self.fragments[i].nodes, x, v, margin, steps)).collect()
    }

    /// Whether `nodes`, moving on at their velocities for `steps` steps, come within `margin` of
    /// an obstacle's plane while approaching it faster than `return_speed`; for a mesh
    /// obstacle (conservatively), whether their box swept over those steps and widened by
    /// `margin` meets the mesh's box while some node moves faster than `return_speed`.
    pub fn approaching(&self, nodes: &[u32], x: &[Real], v: &[Real], margin: Real, steps: Real) -> bool {
        let lookahead = steps * self.settings.time_step;
        let fast = self.settings.return_speed;
        let node = |values: &[Real], n: u32| {
            let k = 3 * n as usize;
            Vector3::new(values[k], values[k + 1], values[k + 2])
        };
        let near_plane = self.planes.iter().any(|(point, normal)| {
            nodes.iter().any(|&n| {
                let approach = -node(v, n).dot(normal);
                let gap = (node(x, n) - point.coords).dot(normal);
                approach > fast && gap - approach * lookahead < margin
            })
        });
        near_plane
            || (!self.mesh_boxes.is_empty() && {
                let (mut lo, mut hi, mut speed) = (Vector3::repeat(Real::MAX), Vector3::repeat(Real::MIN), 0.0);
                for &n in nodes {
                    let (p, u) = (node(x, n), node(v, n));
                    let q = p + lookahead * u;
                    lo = lo.inf(&p.inf(&q));
                    hi = hi.sup(&p.sup(&q));
                    speed = Real::max(speed, u.norm());
                }
                speed > fast
                    && self
                        .mesh_boxes
                        .iter()
                        .any(|(a, b)| (0..3).all(|k| lo[k] - margin <= b[k] && a[k] - margin <= hi[k]))
            })
    }

    /// The net contact impulse fragment `index` received in the last step beyond what holds it
    /// against gravity, `max(0, |J| − M |g| h)` [N·s]: at rest `J` is the support `−M g h`
    /// (zero), in free fall there is none (zero), an impact exceeds it. A net impulse, not a
    /// sum of magnitudes: a chip wedged under a heavy fragment is pressed from above and below,
    /// which cancels. Normal impulses only (rapier's `total_impulse`); the normal points from
    /// the pair's first collider to its second, whose body receives the impulse along it.
    fn contact_impulse(&self, index: usize) -> Real {
        let fragment = &self.fragments[index];
        let collider = fragment.collider;
        let net = self.world.narrow_phase.contact_pairs_with(collider).fold(DVec3::ZERO, |sum, pair| {
            if pair.collider2 == collider { sum + pair.total_impulse() } else { sum - pair.total_impulse() }
        });
        (net.length() - fragment.mass * self.settings.time_step * self.settings.gravity.norm()).max(0.0)
    }

    /// The impacts of the last [`step`](Self::step) ([`ImpactResponse::Keep`]; empty otherwise).
    pub fn impacts(&self) -> &[Impact] {
        &self.impacts
    }

    /// Fragment `index`'s contact points in the last step with the normal impulse each gave it,
    /// in its own frame (see [`Impact`]), `rotation` its turn when the contacts were found.
    /// Rapier's manifolds hold each point in its collider's frame, which for a fragment is its
    /// body's (the collider has no offset).
    fn contact_points(
        &self,
        index: usize,
        rotation: rapier3d_f64::math::Rotation,
    ) -> Vec<(Point3<Real>, Vector3<Real>)> {
        let fragment = &self.fragments[index];
        let mut contacts = Vec::new();
        for pair in self.world.narrow_phase.contact_pairs_with(fragment.collider) {
            let first = pair.collider1 == fragment.collider;
            for manifold in pair.solver_manifolds() {
                // The normal points from the first collider to the second, whose body the
                // impulse pushes along it.
                let normal = rotation.inverse() * manifold.data.normal;
                let normal = if first { -normal } else { normal };
                for point in manifold.points.iter().filter(|p| p.data.impulse > 0.0) {
                    let local = if first { point.local_p1 } else { point.local_p2 };
                    contacts.push((Point3::from(from_glam(local)), from_glam(normal * point.data.impulse)));
                }
            }
        }
        contacts
    }

    /// Writes each fragment's rigid motion into its nodes: `x = c + R r`, `v = v_c + ω × (x − c)`.
    pub fn write_motion(&self, x: &mut [Real], v: &mut [Real]) {
        for f in &self.fragments {
            let body = &self.world.bodies[f.body];
            let (pose, linvel, angvel) = (body.position(), from_glam(body.linvel()), from_glam(body.angvel()));
            let centre = from_glam(pose.translation);
            for (&n, offset) in f.nodes.iter().zip(&f.offsets) {
                let r = from_glam(pose.rotation * to_glam(offset));
                let (p, u) = (centre + r, linvel + angvel.cross(&r));
                let k = 3 * n as usize;
                x[k..k + 3].copy_from_slice(p.as_slice());
                v[k..k + 3].copy_from_slice(u.as_slice());
            }
        }
    }

    /// Linear and angular momentum (about the origin) of fragment `index` as rapier holds it.
    pub fn momenta(&self, index: usize) -> (Vector3<Real>, Vector3<Real>) {
        let f = &self.fragments[index];
        let body = &self.world.bodies[f.body];
        let centre = from_glam(body.position().translation);
        let linear = f.mass * from_glam(body.linvel());
        // L = R I₀ Rᵀ ω + c × p, with I₀ the inertia at the hand-off (the body's local frame).
        let rotation = body.position().rotation;
        let omega_local = from_glam(rotation.inverse() * body.angvel());
        let inertia_local = body.mass_properties().local_mprops.reconstruct_inertia_matrix();
        let inertia_local = Matrix3::new(
            inertia_local.x_axis.x,
            inertia_local.y_axis.x,
            inertia_local.z_axis.x,
            inertia_local.x_axis.y,
            inertia_local.y_axis.y,
            inertia_local.z_axis.y,
            inertia_local.x_axis.z,
            inertia_local.y_axis.z,
            inertia_local.z_axis.z,
        );
        let spin = from_glam(rotation * to_glam(&(inertia_local * omega_local)));
        (linear, spin + centre.cross(&linear))
    }
}

#[cfg(test)]
mod tests;
