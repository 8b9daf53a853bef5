//! Voxel benches.
fn main() {}
