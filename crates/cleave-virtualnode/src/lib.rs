//! cleave-virtualnode: the generalized virtual node algorithm of Sifakis, Der and Fedkiw,
//! "Arbitrary cutting of deformable tetrahedralized objects" (SCA 2007), on a BCC lattice.
//! `docs/math/virtual-node.md` states what is decided exactly, what is rounded, and what the
//! tests measured.
//!
//! - [`lattice`]: the body-centred cubic tetrahedral lattice.
//! - `cleave_geometry::arrangement` (shared with the other polyhedral backends): the convex
//!   cells of one tetrahedron's material, split by cut triangles with exact side decisions, and
//!   its material regions.
//! - [`mesh`]: [`VirtualNodeMesh`], carving a closed surface out of the lattice, one duplicate
//!   per region, node copies identified across contiguous faces, the `Discretization` and
//!   `Cuttable` implementations.
//! - [`surface`]: the render surface (object surface and both sides of cuts), embedded.
//! - [`tet`]: linear tetrahedron shape functions, stiffness and quadrature.
//!
//! ```no_run
//! # use cleave_core::{Material, Point3, CutSurface, Cuttable, Vector3};
//! # use cleave_virtualnode::VirtualNodeMesh;
//! let material = Material::new(1e6, 0.3, 1000.0).unwrap();
//! let mut block = VirtualNodeMesh::from_box(Point3::origin(), Point3::new(1.0, 0.5, 0.5), 0.1, material).unwrap();
//! let change = block.cut(&CutSurface::Plane { point: Point3::new(0.53, 0.0, 0.0), normal: Vector3::x() }).unwrap();
//! assert_eq!(block.pieces().len(), 2);
//! ```

pub mod lattice;
pub mod mesh;
pub mod surface;
pub mod tet;

/// Hash maps of the cut path: keys are indices and float bits, built and dropped per cut, so a
/// fast fixed-seed hasher (deterministic iteration too) instead of SipHash.
pub(crate) type FastMap<K, V> = std::collections::HashMap<K, V, foldhash::fast::FixedState>;

pub use mesh::{CutStats, MassLumping, SPECK_VOLUME, VirtualNodeError, VirtualNodeMesh, box_surface};
pub use surface::{RenderSurface, SurfaceKind};
