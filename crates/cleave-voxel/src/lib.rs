//! cleave-voxel: the voxel cube FEM of Müller, Teschner and Gross, "Physically-based simulation
//! of objects represented by surface meshes" (CGI 2004): a surface mesh voxelized into equal
//! cubes, one closed-form 24×24 stiffness for all of them, warped per cube, and the surface
//! carried along by trilinear embedding; cut across the faces whose dual edge a cut surface
//! crosses (`Cuttable`, in `cut`).
//!
//! ```no_run
//! # use cleave_core::{Material, Point3};
//! # use cleave_voxel::VoxelMesh;
//! let material = Material::new(1e6, 0.3, 1000.0).unwrap();
//! let beam = VoxelMesh::from_box(material, Point3::origin(), 0.25, [16, 4, 4]).unwrap();
//! ```

mod closing;
mod cut;
pub mod mesh;
pub mod stiffness;
pub mod surface;

pub use closing::{ClosingRefusal, ClosingReport};
pub use mesh::{CubeFace, VoxelError, VoxelMesh};
