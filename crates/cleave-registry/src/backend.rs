//! The one registration of a backend ([`Backend`]): how a scene builds it from its own RON
//! settings, how its pins are resolved on a (possibly cut) discretization, and, through its
//! supertrait [`CompareBackend`], its name and comparison variants. Its capabilities are read off
//! a small solid it builds (`as_cuttable`, `as_fracturable`, `as_refinable`), not declared. The
//! scene runner and `cargo xtask compare`/`stability` go through this trait only, so a new
//! backend is one file here and one line in [`crate::registered`].

use cleave_core::{Discretization, Point3, Real};
use cleave_geometry::TriangleMesh;
use cleave_testkit::compare::CompareBackend;
use serde::de::DeserializeOwned;

/// An axis-aligned box in rest space (pins are kept as regions and resolved again after every
/// topology change).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Region {
    /// Minimum corner.
    pub min: [Real; 3],
    /// Maximum corner.
    pub max: [Real; 3],
}

impl Region {
    /// Whether `p` lies in the region (closed, with a 1e-9 tolerance for points on its faces).
    pub fn contains(&self, p: &[Real]) -> bool {
        (0..3).all(|a| p[a] >= self.min[a] - 1e-9 && p[a] <= self.max[a] + 1e-9)
    }
}

/// The solid a scene asks for.
#[derive(Clone, Copy, Debug)]
pub enum Shape<'a> {
    /// A closed surface mesh (already transformed into place).
    Surface(&'a TriangleMesh),
    /// An axis-aligned box.
    Box {
        /// Minimum corner.
        min: [Real; 3],
        /// Maximum corner.
        max: [Real; 3],
    },
}

/// What a scene asks a backend to build.
#[derive(Clone, Copy, Debug)]
pub struct SolidRequest<'a> {
    /// The solid.
    pub shape: Shape<'a>,
    /// Its material.
    pub material: cleave_core::Material,
    /// Pinned regions.
    pub pins: &'a [Region],
}

/// Pins resolved on a discretization: strongly pinned DOFs and/or a weak boundary load.
#[derive(Clone, Debug, Default)]
pub struct ResolvedPins {
    /// Scalar DOFs held fixed.
    pub pinned_dofs: Vec<usize>,
    /// A constant load of weakly imposed data (empty = none).
    pub extra_load: Vec<Real>,
}

/// A built solid.
pub struct BuiltSolid {
    /// The discretization.
    pub discretization: Box<dyn Discretization>,
    /// Elements (cubes, polyhedra, tetrahedra).
    pub elements: usize,
    /// Characteristic element size [m].
    pub element_size: Real,
    /// The pins, resolved.
    pub pins: ResolvedPins,
    /// The surface to render in rest space (the input mesh, or the box's boundary).
    pub surface: TriangleMesh,
}

/// What a backend can do beyond simulating.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Capabilities {
    /// It can be cut (`Discretization::as_cuttable`).
    pub cut: bool,
    /// It fractures (`Discretization::as_fracturable`).
    pub fracture: bool,
    /// It refines (`Discretization::as_refinable`).
    pub refine: bool,
}

/// Why a backend could not build a scene's solid.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum BackendError {
    /// The backend's settings in the scene are malformed; the position is within the settings'
    /// own RON text (1-based).
    #[error("{line}:{column}: {message}")]
    Settings {
        /// line within the settings text
        line: usize,
        /// column within the settings text
        column: usize,
        /// what is wrong
        message: String,
    },
    /// The settings are well formed but the solid cannot be built with them.
    #[error("{0}")]
    Build(String),
    /// The scene's surface mesh cannot be discretized (it encloses no volume, it is too large
    /// for the cell size, slicing or carving it failed): the scene names the mesh file.
    #[error("{0}")]
    Mesh(String),
}

/// Parses a backend's settings from its RON text (`implicit_some`, so `cell_size: 0.25` fills an
/// `Option`), with the error's position inside that text.
pub fn parse_settings<T: DeserializeOwned>(text: &str) -> Result<T, BackendError> {
    let options = ron::Options::default().with_default_extension(ron::extensions::Extensions::IMPLICIT_SOME);
    options.from_str::<T>(text).map_err(|error| BackendError::Settings {
        line: error.span.start.line,
        column: error.span.start.col,
        message: error.code.to_string(),
    })
}

/// One registration per backend: scenes through this trait, comparisons through its supertrait
/// (whose `name` is the one in scenes and `--backend`: "voxel", "dg", "virtualnode").
pub trait Backend: CompareBackend + Send + Sync {
    /// One line for `--backend` listings: method and paper.
    fn summary(&self) -> &str;

    /// What it can do, read off the box of its first comparison variant (two cells along x, one
    /// across, pinned nowhere): whether that discretization answers `as_cuttable`,
    /// `as_fracturable` and `as_refinable`. A box it cannot build can do nothing.
    fn capabilities(&self) -> Capabilities {
        let Some(variant) = self.variants().into_iter().next() else { return Capabilities::default() };
        let Ok(material) = cleave_core::Material::new(1e5, 0.3, 1000.0) else { return Capabilities::default() };
        let grid = cleave_testkit::compare::BoxGrid { origin: Point3::origin(), h: 0.5, dims: [2, 1, 1] };
        match self.build_box(&variant, &material, &grid, &cleave_testkit::compare::DirichletSpec::none()) {
            Ok(mut built) => {
                let d = built.discretization.as_mut();
                Capabilities {
                    cut: d.as_cuttable().is_some(),
                    fracture: d.as_fracturable().is_some(),
                    refine: d.as_refinable().is_some(),
                }
            }
            Err(_) => Capabilities::default(),
        }
    }

    /// Builds the scene's solid from this backend's settings (`settings` is the RON text of the
    /// scene's entry for this backend, e.g. `(cell_size: 0.25)`).
    fn build_solid(&self, settings: &str, request: &SolidRequest) -> Result<BuiltSolid, BackendError>;

    /// Resolves the pin regions on `discretization` (after a topology change, pins are resolved
    /// again here). The default pins every node whose rest position lies in a region, right for
    /// nodal backends.
    fn resolve_pins(&self, discretization: &dyn Discretization, pins: &[Region]) -> Result<ResolvedPins, BackendError> {
        nodal_pins(discretization, pins)
    }
}

/// The nodes `Discretization::dirichlet_nodes` holds for each region (every node whose rest
/// position lies in it, for nodal bases; more for carved ones), all three components; an error
/// names a region that holds no node.
pub fn nodal_pins(discretization: &dyn Discretization, pins: &[Region]) -> Result<ResolvedPins, BackendError> {
    let mut pinned_dofs = Vec::new();
    for (index, region) in pins.iter().enumerate() {
        let nodes = discretization.dirichlet_nodes(&|p: &Point3<Real>| region.contains(p.coords.as_slice()));
        if nodes.is_empty() {
            return Err(BackendError::Build(format!(
                "pins[{index}]: the region {:?}..{:?} contains no node",
                region.min, region.max
            )));
        }
        pinned_dofs.extend(nodes.iter().flat_map(|&n| 3 * n as usize..3 * n as usize + 3));
    }
    pinned_dofs.sort_unstable();
    pinned_dofs.dedup();
    Ok(ResolvedPins { pinned_dofs, extra_load: Vec::new() })
}

/// Cells per axis of a box of cell size `h`, or why it is not a whole number of cells.
pub fn box_dims(min: &[Real; 3], max: &[Real; 3], h: Real) -> Result<[usize; 3], BackendError> {
    let dims: Vec<usize> = (0..3).map(|a| ((max[a] - min[a]) / h).round().max(0.0) as usize).collect();
    if dims.contains(&0) || (0..3).any(|a| ((max[a] - min[a]) - dims[a] as Real * h).abs() > 1e-9 * h.max(1.0)) {
        return Err(BackendError::Build(format!(
            "the box {min:?}..{max:?} is not a whole number of cells of size {h}"
        )));
    }
    Ok([dims[0], dims[1], dims[2]])
}

/// A cell size giving about `target` elements: start from volume/target and correct by the
/// cube root of the measured count ratio a few times (`count` discretizes `mesh`: its errors
/// are the mesh's).
pub fn cell_size_for(
    mesh: &TriangleMesh,
    target: usize,
    tolerance: Real,
    count: impl Fn(Real) -> Result<usize, String>,
) -> Result<Real, BackendError> {
    let volume = mesh.signed_volume();
    if volume.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) || target == 0 {
        return Err(BackendError::Mesh(format!("cannot size {target} elements in an enclosed volume of {volume}")));
    }
    let mut h = (volume / target as Real).cbrt();
    for _ in 0..4 {
        let ratio = count(h).map_err(BackendError::Mesh)? as Real / target as Real;
        if (ratio - 1.0).abs() < tolerance {
            break;
        }
        h *= ratio.cbrt();
    }
    Ok(h)
}

/// The cell size of settings that give exactly one of `cell_size` and a target count.
pub fn one_size(
    backend: &str,
    cell_size: Option<Real>,
    target: Option<usize>,
    target_name: &str,
    from_target: impl FnOnce(usize) -> Result<Real, BackendError>,
) -> Result<Real, BackendError> {
    match (cell_size, target) {
        (Some(h), None) if h.is_finite() && h > 0.0 => Ok(h),
        (None, Some(t)) if t > 0 => from_target(t),
        _ => Err(BackendError::Build(format!(
            "{backend} needs exactly one of `cell_size` (> 0) and `{target_name}` (> 0)"
        ))),
    }
}
