//! Voxelization bench: the Stanford bunny of `scenes/meshes/bunny.obj` (as parsed, unscaled)
//! voxelized at h = 0.29 (about 10k cells) and h = 0.14 (about 80k cells), throughput in cells.
//! The wall-clock check that used to sit in `crates/cleave-geometry/tests/voxelize.rs` (80k cells
//! in under a second) lives here as a measurement.

use cleave_geometry::{TriangleMesh, voxelize};
use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use std::hint::black_box;

fn bunny() -> TriangleMesh {
    let text = include_str!("../../scenes/meshes/bunny.obj");
    TriangleMesh::from_obj_str(text).expect("bunny parses")
}

fn voxelize_bunny(c: &mut Criterion) {
    let mesh = bunny();
    let mut group = c.benchmark_group("voxelize_bunny");
    group.sample_size(10);
    for h in [0.29, 0.14] {
        let cells = voxelize(&mesh, h).expect("bunny voxelizes").len();
        group.throughput(Throughput::Elements(cells as u64));
        group.bench_with_input(BenchmarkId::new("cells", cells), &h, |b, &h| {
            b.iter(|| black_box(voxelize(black_box(&mesh), h).expect("bunny voxelizes")))
        });
    }
    group.finish();
}

criterion_group!(benches, voxelize_bunny);
criterion_main!(benches);
