//! Fill-reducing orderings side by side (issue 35, item 5): AMD against nested dissection on
//! kaufmann2008 Table 1's DG grids (10 × 10 × 10 cells, four variants) and the static voxel
//! cantilever at n = 16 (64 × 16 × 16 cubes): factor nonzeros and operations, the time of the
//! ordering with its symbolic analysis, and of a numeric factorization (best of three). The
//! matrices are the stiffness at rest plus a small diagonal shift (the free body's `K` is
//! singular; the shift changes no structure).
//!
//! ```text
//! cargo run --release -p cleave-benches --example orderings
//! ```

use cleave_core::{AssemblyPattern, BlockRanks, FillOrdering, Matrix3, Point3, Real, SparseCholesky, Vector3};
use cleave_testkit::compare::{BoxGrid, CompareBackend, DirichletSpec};
use std::time::Instant;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let backends = cleave_registry::registered();
    let find = |name: &str| backends.iter().find(|b| b.name() == name).expect("registered backend");
    let material = cleave_core::Material::new(1e6, 0.3, 1000.0)?;
    let nowhere = |_: &Point3<Real>| false;
    let zero = |_: &Point3<Real>| Vector3::zeros();
    let table1 = BoxGrid { origin: Point3::origin(), h: 0.1, dims: [10, 10, 10] };
    let cantilever = BoxGrid { origin: Point3::origin(), h: 1.0 / 16.0, dims: [64, 16, 16] };
    let cases: [(&str, &dyn CompareBackend, &str, &BoxGrid); 5] = [
        ("Table 1, dg/bz-1", find("dg").as_ref(), "bz-1", &table1),
        ("Table 1, dg/ip-1", find("dg").as_ref(), "ip-1", &table1),
        ("Table 1, dg/bz-2", find("dg").as_ref(), "bz-2", &table1),
        ("Table 1, dg/ip-2", find("dg").as_ref(), "ip-2", &table1),
        ("cantilever n = 16, voxel", find("voxel").as_ref(), "trilinear", &cantilever),
    ];
    println!(
        "| problem | DOFs | ordering | factor nonzeros | factor operations | ordering + symbolic [ms] | numeric factorization [ms] |"
    );
    println!("|---|---|---|---|---|---|---|");
    for (label, backend, variant, grid) in cases {
        let built = backend
            .build_box(variant, &material, grid, &DirichletSpec { region: &nowhere, value: &zero })
            .map_err(|e| format!("{label}: {e}"))?;
        let d = built.discretization.as_ref();
        let pattern = AssemblyPattern::from_groups(d.num_nodes(), d.blocks().node_groups());
        let ranks = BlockRanks::new(d.blocks(), &pattern);
        let mut values = pattern.new_values();
        let identity = vec![Matrix3::identity(); d.num_frames()];
        d.blocks().add_to_matrix(&identity, 1.0, &pattern, &ranks, &mut values);
        let largest = values.iter().fold(0.0, |m: Real, v| m.max(v.abs()));
        for node in 0..d.num_nodes() as u32 {
            let rank = pattern.rank(node, node).expect("the diagonal is in the pattern");
            for a in 0..3 {
                values[pattern.position(rank, node, a, a)] += 1e-6 * largest;
            }
        }
        for ordering in [FillOrdering::Amd, FillOrdering::NestedDissection] {
            let clock = Instant::now();
            let mut cholesky = SparseCholesky::with_ordering(&pattern, ordering)?;
            let symbolic = clock.elapsed().as_secs_f64();
            let mut numeric = Real::INFINITY;
            for _ in 0..3 {
                let clock = Instant::now();
                cholesky.factorize(&values)?;
                numeric = numeric.min(clock.elapsed().as_secs_f64());
            }
            println!(
                "| {label} | {} | {ordering:?} | {} | {:.3e} | {:.1} | {:.1} |",
                pattern.dim(),
                cholesky.factor_nnz(),
                cholesky.factor_flops(),
                1e3 * symbolic,
                1e3 * numeric
            );
        }
    }
    Ok(())
}
