//! Measures where faer's parallel Cholesky kernels start to pay on this machine: 3D grids of
//! 8-node cells (3 DOFs per node, `Laplacian ⊗ B` plus a shift), each factorized and solved
//! sequentially and on every thread of the pool, with the factorization's flop count. The
//! crossover sets `cleave_core::cholesky::PARALLEL_FACTOR_FLOPS`.
//!
//! Run: `cargo run --release -p cleave-core --example cholesky_threads`

use cleave_core::assembly::AssemblyPattern;
use cleave_core::cholesky::{PARALLEL_FACTOR_FLOPS, SparseCholesky};
use nalgebra::Matrix3;
use std::time::Instant;

fn grid(n: u32) -> (AssemblyPattern, Vec<f64>) {
    let node = |x: u32, y: u32, z: u32| x + n * (y + n * z);
    let cells: Vec<[u32; 8]> = (0..n - 1)
        .flat_map(|z| (0..n - 1).flat_map(move |y| (0..n - 1).map(move |x| (x, y, z))))
        .map(|(x, y, z)| [0, 1, 2, 3, 4, 5, 6, 7].map(|c| node(x + (c & 1), y + ((c >> 1) & 1), z + ((c >> 2) & 1))))
        .collect();
    let nodes = (n * n * n) as usize;
    let pattern = AssemblyPattern::from_groups(nodes, cells.iter().map(|c| &c[..]));
    let mut values = vec![0.0; pattern.nnz()];
    let b = Matrix3::new(2.0, 0.5, 0.0, 0.5, 3.0, 0.25, 0.0, 0.25, 1.5);
    for cell in &cells {
        for &i in cell {
            for &j in cell {
                let weight = if i == j { 7.0 } else { -1.0 };
                pattern.add_block(&mut values, pattern.rank(i, j).unwrap(), j, &b, weight);
            }
        }
    }
    for j in 0..nodes as u32 {
        pattern.add_block(&mut values, pattern.rank(j, j).unwrap(), j, &Matrix3::identity(), 0.5);
    }
    (pattern, values)
}

fn main() {
    println!("threshold {PARALLEL_FACTOR_FLOPS:.1e} flops, {} threads", rayon::current_num_threads());
    println!("| nodes | DOFs | factor nnz | flops | sequential [ms] | parallel [ms] | chosen |");
    println!("|---|---|---|---|---|---|---|");
    for n in [8, 10, 12, 13, 18, 26] {
        let (pattern, values) = grid(n);
        let mut cholesky = SparseCholesky::new(&pattern).unwrap();
        let chosen = if cholesky.is_parallel() { "parallel" } else { "sequential" };
        let mut rhs = vec![1.0; pattern.dim()];
        let mut best = [f64::INFINITY; 2];
        for round in 0..4 {
            for (k, parallel) in [false, true].into_iter().enumerate() {
                cholesky.set_parallel(parallel);
                let start = Instant::now();
                cholesky.factorize(&values).unwrap();
                cholesky.solve_in_place(&mut rhs);
                if round > 0 {
                    best[k] = best[k].min(start.elapsed().as_secs_f64() * 1e3);
                }
            }
        }
        println!(
            "| {} | {} | {} | {:.2e} | {:.1} | {:.1} | {chosen} |",
            n * n * n,
            pattern.dim(),
            cholesky.factor_nnz(),
            cholesky.factor_flops(),
            best[0],
            best[1]
        );
    }
}
