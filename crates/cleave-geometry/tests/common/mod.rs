//! Shared test fixtures: the bunny, boxes, an icosphere and a small deterministic RNG.
#![allow(dead_code)]

use cleave_geometry::TriangleMesh;
use nalgebra::{Point3, Vector3};

/// The Stanford bunny from `scenes/meshes/bunny.obj`.
pub fn bunny() -> TriangleMesh {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../../scenes/meshes/bunny.obj");
    let text = std::fs::read_to_string(path).expect("read bunny.obj");
    TriangleMesh::from_obj_str(&text).expect("parse bunny.obj")
}

/// Signed volume of the bunny computed independently (node script summing
/// `a · (b × c) / 6` over the package's triangles).
pub const BUNNY_VOLUME: f64 = 194.2883718124191;

/// Surface area of the bunny computed independently (node script).
pub const BUNNY_AREA: f64 = 218.6892712868942;

/// Unit cube [0,1]^3, outward, with a fixed triangle order used by the validation tests.
pub fn unit_cube() -> TriangleMesh {
    let vertices = [
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [1.0, 1.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.0, 0.0, 1.0],
        [1.0, 0.0, 1.0],
        [1.0, 1.0, 1.0],
        [0.0, 1.0, 1.0],
    ]
    .map(Point3::from)
    .to_vec();
    let triangles = vec![
        [0, 3, 2],
        [0, 2, 1],
        [4, 5, 6],
        [4, 6, 7],
        [0, 1, 5],
        [0, 5, 4],
        [3, 7, 6],
        [3, 6, 2],
        [0, 4, 7],
        [0, 7, 3],
        [1, 2, 6],
        [1, 6, 5],
    ];
    TriangleMesh::new(vertices, triangles)
}

/// Axis-aligned box with minimum corner `min` and edge lengths `size`, 12 triangles.
pub fn box_mesh(min: [f64; 3], size: [f64; 3]) -> TriangleMesh {
    let min = Vector3::from(min);
    let size = Vector3::from(size);
    unit_cube().transformed(|p| Point3::from(min + p.coords.component_mul(&size)))
}

/// Reorients every triangle of a star-shaped mesh so its normal points away from `center`.
pub fn orient_away_from(mesh: &mut TriangleMesh, center: Point3<f64>) {
    for tri in &mut mesh.triangles {
        let [a, b, c] = tri.map(|i| mesh.vertices[i as usize]);
        if (b - a).cross(&(c - a)).dot(&(a - center)) < 0.0 {
            tri.swap(1, 2);
        }
    }
}

/// Icosphere with `levels` subdivisions, vertices on the sphere of `radius` about `center`.
pub fn icosphere(levels: u32, radius: f64, center: Point3<f64>) -> TriangleMesh {
    let t = (1.0 + 5f64.sqrt()) / 2.0;
    let mut verts: Vec<Vector3<f64>> = [
        [-1.0, t, 0.0],
        [1.0, t, 0.0],
        [-1.0, -t, 0.0],
        [1.0, -t, 0.0],
        [0.0, -1.0, t],
        [0.0, 1.0, t],
        [0.0, -1.0, -t],
        [0.0, 1.0, -t],
        [t, 0.0, -1.0],
        [t, 0.0, 1.0],
        [-t, 0.0, -1.0],
        [-t, 0.0, 1.0],
    ]
    .iter()
    .map(|v| Vector3::from(*v).normalize())
    .collect();
    let mut tris: Vec<[u32; 3]> = vec![
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    for _ in 0..levels {
        let mut midpoint = std::collections::HashMap::new();
        let mut mid = |a: u32, b: u32, verts: &mut Vec<Vector3<f64>>| -> u32 {
            *midpoint.entry((a.min(b), a.max(b))).or_insert_with(|| {
                let m = (verts[a as usize] + verts[b as usize]).normalize();
                verts.push(m);
                (verts.len() - 1) as u32
            })
        };
        let mut next = Vec::with_capacity(tris.len() * 4);
        for [a, b, c] in tris {
            let ab = mid(a, b, &mut verts);
            let bc = mid(b, c, &mut verts);
            let ca = mid(c, a, &mut verts);
            next.extend([[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]);
        }
        tris = next;
    }
    let mut mesh = TriangleMesh::new(verts.iter().map(|v| center + v * radius).collect(), tris);
    orient_away_from(&mut mesh, center);
    mesh
}

/// SplitMix64: a tiny deterministic generator for reproducible random tests.
pub struct Rng(pub u64);

impl Rng {
    /// Next 64 random bits.
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform in [0, 1).
    pub fn unit(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }

    /// Uniform in [lo, hi).
    pub fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.unit()
    }

    /// Uniform point in the box [lo, hi].
    pub fn point(&mut self, lo: &Point3<f64>, hi: &Point3<f64>) -> Point3<f64> {
        Point3::new(self.range(lo.x, hi.x), self.range(lo.y, hi.y), self.range(lo.z, hi.z))
    }
}

/// The plane `{p : p · normal = offset}` as three points, its right-hand normal along `normal`
/// (the form the cutting functions take).
pub fn plane(normal: Vector3<f64>, offset: f64) -> [Point3<f64>; 3] {
    let n = normal.normalize();
    let a = Point3::from(n * offset);
    let t = if n.x.abs() < 0.9 { Vector3::x() } else { Vector3::y() };
    let u = n.cross(&t).normalize();
    [a, a + u, a + n.cross(&u)]
}
