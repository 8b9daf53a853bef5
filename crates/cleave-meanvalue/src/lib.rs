//! cleave-meanvalue: the finite element method on convex polyhedra of Wicke, Botsch and Gross,
//! "A finite element method on convex polyhedra" (Eurographics 2007), with 3D mean value
//! coordinates as shape functions: a validated convex polyhedron that splits by planes
//! (`polyhedron`), the coordinates with their analytic gradients, robust up to and on the
//! boundary (`coordinates`), an element's integrals with the gradient correction that makes the
//! patch test exact (`element`), a corotated mesh behind `Discretization` (`mesh`), cutting by
//! splitting elements (`cut`, `cuttable`: `Cuttable` on `MeanValueMesh`), and a mesher for closed
//! surfaces (`mesher`). Registered as the backend `meanvalue` in `cleave-registry`.
//!
//! ```
//! # use cleave_meanvalue::{ConvexPolyhedron, Workspace, mean_value_coordinates};
//! # use nalgebra::Point3;
//! let cube = ConvexPolyhedron::cuboid(Point3::origin(), Point3::new(1.0, 1.0, 1.0)).unwrap();
//! let mut lambda = [0.0; 8];
//! mean_value_coordinates(&cube, &Point3::new(0.5, 0.5, 0.5), &mut lambda, None, &mut Workspace::default());
//! assert!(lambda.iter().all(|l| (l - 0.125).abs() < 1e-15));
//! ```

pub mod coordinates;
mod cut;
mod cuttable;
pub mod element;
pub mod mesh;
pub mod mesher;
pub mod polyhedron;

pub use coordinates::{BOUNDARY_TOLERANCE, GRADIENT_INSET, Workspace, mean_value_coordinates};
pub use cut::ON_PLANE_TOLERANCE;
pub use cuttable::{QUALITY_FLOOR, quality};
pub use element::{ElementIntegrals, quadrature};
pub use mesh::{CutReport, DEFAULT_REFINEMENT, MeanValueError, MeanValueMesh, SPLIT_NORMALS, SPLIT_SPACING};
pub use mesher::{MeshingReport, mesh_closed_surface};
pub use polyhedron::{ConvexPolyhedron, GEOMETRY_TOLERANCE, PolyhedronError};
