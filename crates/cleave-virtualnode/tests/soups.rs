//! Random and degenerate triangle soups — through nodes, along edges, in faces, coplanar
//! duplicates, zero area, tiny — never panic and never lose volume, in one tetrahedron and in a
//! carved block.

use cleave_core::{CutSurface, Cuttable, Discretization, Material, Point3, Real};
use cleave_geometry::arrangement::{Arrangement, Cover, REFUSED};
use cleave_testkit::Lcg;
use cleave_virtualnode::VirtualNodeMesh;
use std::sync::atomic::Ordering;

/// Draws soups of triangles, many of them degenerate relative to the given reference points
/// (tetrahedron corners or lattice nodes).
struct SoupGenerator {
    rng: Lcg,
    anchors: Vec<Point3<Real>>,
    lo: Point3<Real>,
    hi: Point3<Real>,
}

impl SoupGenerator {
    fn uniform(&mut self) -> Real {
        0.5 * (self.rng.next() + 1.0)
    }

    fn index(&mut self, n: usize) -> usize {
        ((self.uniform() * n as Real) as usize).min(n - 1)
    }

    fn anchor(&mut self) -> Point3<Real> {
        let i = self.index(self.anchors.len());
        self.anchors[i]
    }

    fn point(&mut self) -> Point3<Real> {
        match self.index(4) {
            0 => self.anchor(),
            1 => {
                // On the segment between two anchors at an exact binary fraction.
                let (a, b) = (self.anchor(), self.anchor());
                let t = [0.5, 0.25, 0.75, 0.125][self.index(4)];
                a + (b - a) * t
            }
            _ => Point3::from(
                self.lo.coords
                    + (self.hi - self.lo)
                        .component_mul(&Point3::new(self.uniform(), self.uniform(), self.uniform()).coords),
            ),
        }
    }

    fn triangle(&mut self, previous: Option<[Point3<Real>; 3]>) -> [Point3<Real>; 3] {
        match self.index(8) {
            // Coplanar duplicate of the previous triangle, or a piece of it.
            0 if previous.is_some() => {
                let t = previous.unwrap_or([Point3::origin(); 3]);
                let m = Point3::from((t[0].coords + t[1].coords) * 0.5);
                if self.index(2) == 0 { t } else { [t[0], m, t[2]] }
            }
            // Zero area: a repeated point or three collinear points.
            1 => {
                let (a, b) = (self.point(), self.point());
                if self.index(2) == 0 { [a, a, b] } else { [a, b, a + (b - a) * 2.0] }
            }
            // Tiny triangle around a point.
            2 => {
                let a = self.point();
                let e = 1e-10 * (self.hi - self.lo).norm();
                [a, a + cleave_core::Vector3::new(e, 0.0, 0.0), a + cleave_core::Vector3::new(0.0, e, e)]
            }
            // Three anchors: in a face, along an edge, through nodes.
            3 | 4 => [self.anchor(), self.anchor(), self.anchor()],
            // Large, to cut through.
            5 => {
                let c = self.point();
                let d = (self.hi - self.lo) * 2.0;
                let mut r =
                    || cleave_core::Vector3::new(self.rng.next() * d.x, self.rng.next() * d.y, self.rng.next() * d.z);
                [c + r(), c + r(), c + r()]
            }
            _ => [self.point(), self.point(), self.point()],
        }
    }

    fn soup(&mut self, max: usize) -> Vec<[Point3<Real>; 3]> {
        let n = 1 + self.index(max);
        let mut soup: Vec<[Point3<Real>; 3]> = Vec::with_capacity(n);
        for _ in 0..n {
            let t = self.triangle(soup.last().copied());
            soup.push(t);
        }
        soup
    }
}

#[test]
fn thousands_of_degenerate_soups_in_one_tetrahedron_conserve_its_volume() {
    let tets = [
        [
            Point3::new(0.0, 0.0, 0.0),
            Point3::new(1.0, 0.0, 0.0),
            Point3::new(0.0, 1.0, 0.0),
            Point3::new(0.0, 0.0, 1.0),
        ],
        // A BCC lattice tetrahedron off the origin with inexact coordinates.
        [
            Point3::new(0.15, 0.15, 0.15),
            Point3::new(0.45, 0.15, 0.15),
            Point3::new(0.3, 0.0, 0.3),
            Point3::new(0.3, 0.0, 0.0),
        ],
    ];
    let refused_before = REFUSED.load(Ordering::Relaxed);
    let (mut soups, mut triangles, mut max_regions, mut worst): (usize, usize, usize, Real) = (0, 0, 0, 0.0);
    for (k, corners) in tets.iter().enumerate() {
        let mut corners: [Point3<Real>; 4] = *corners;
        let exact = {
            let v: Real =
                (corners[1] - corners[0]).dot(&(corners[2] - corners[0]).cross(&(corners[3] - corners[0]))) / 6.0;
            if v < 0.0 {
                corners.swap(2, 3);
            }
            v.abs()
        };
        let mut anchors: Vec<Point3<Real>> = corners.to_vec();
        for i in 0..4 {
            for j in i + 1..4 {
                anchors.push(Point3::from((corners[i].coords + corners[j].coords) * 0.5));
            }
        }
        let (mut lo, mut hi) = (corners[0], corners[0]);
        for c in &corners {
            lo = lo.inf(c);
            hi = hi.sup(c);
        }
        let mut generator = SoupGenerator { rng: Lcg::new(17 + k as u64), anchors, lo, hi };
        for _ in 0..2000 {
            let soup = generator.soup(8);
            let mut a = Arrangement::tetrahedron(corners);
            for t in &soup {
                a.cut(t, Cover::Cut);
            }
            // Cut again through the regions, as a later cut through earlier ones would.
            let regions = a.regions();
            let mut total = 0.0;
            let second = generator.soup(3);
            for (cells, v) in &regions {
                assert!(*v > 0.0);
                let mut child = a.restricted(cells);
                for t in &second {
                    child.cut(t, Cover::Cut);
                }
                let sub = child.regions();
                let sum: Real = sub.iter().map(|r| r.1).sum();
                assert!((sum - v).abs() <= 1e-12 * exact, "a region's cut changed its volume: {sum} vs {v}");
                total += sum;
                max_regions = max_regions.max(sub.len());
            }
            worst = worst.max((total - exact).abs() / exact);
            soups += 1;
            triangles += soup.len() + second.len();
        }
    }
    let refused = REFUSED.load(Ordering::Relaxed) - refused_before;
    println!(
        "{soups} soups, {triangles} triangles: worst relative volume error {worst:.2e}, up to {max_regions} regions per region, {refused} refused splits"
    );
    assert!(worst < 1e-12, "{worst}");
}

#[test]
fn degenerate_soups_on_a_carved_block_conserve_volume_and_mass() {
    let material = Material::new(1e5, 0.3, 1000.0).unwrap();
    let (lo, hi) = (Point3::new(0.0, 0.0, 0.0), Point3::new(0.5, 0.25, 0.25));
    let h = 0.125;
    let exact: Real = 0.5 * 0.25 * 0.25;
    let mut mesh = VirtualNodeMesh::from_box(lo, hi, h, material).unwrap();
    // Lattice nodes (the origin is lo − h, nodes every h/2: exactly representable here).
    let mut anchors = Vec::new();
    for i in 0..=10 {
        for j in 0..=6 {
            for k in 0..=6 {
                anchors.push(Point3::new(
                    -0.125 + 0.0625 * i as Real,
                    -0.125 + 0.0625 * j as Real,
                    -0.125 + 0.0625 * k as Real,
                ));
            }
        }
    }
    let mut generator = SoupGenerator { rng: Lcg::new(99), anchors, lo, hi };
    let start = std::time::Instant::now();
    for round in 0..60 {
        let soup = generator.soup(6);
        let before = mesh.num_nodes();
        let change = mesh.cut(&CutSurface::Triangles(soup)).unwrap();
        if let cleave_core::DofRemap::Gather(src) = &change.remap {
            assert_eq!(src.len(), mesh.num_nodes());
            assert!(src.iter().all(|&s| (s as usize) < before));
        }
        let v = mesh.volume();
        assert!((v - exact).abs() < 1e-12 * exact, "round {round}: volume {v} vs {exact}");
        let m = mesh.mass().total();
        assert!((m - 1000.0 * exact).abs() < 1e-12 * 1000.0 * exact, "round {round}: mass {m}");
        let pieces: Real = mesh.pieces().iter().map(|p| p.volume).sum();
        assert!((pieces - exact).abs() < 1e-12 * exact);
    }
    println!(
        "60 soups: {} duplicates, {} nodes, {} pieces, {:.1} ms per cut",
        mesh.num_duplicates(),
        mesh.num_nodes(),
        mesh.pieces().len(),
        start.elapsed().as_secs_f64() * 1e3 / 60.0
    );
    // Non-finite input is an error, not a panic.
    let bad = vec![[Point3::new(Real::NAN, 0.0, 0.0), Point3::origin(), Point3::new(1.0, 1.0, 1.0)]];
    assert!(mesh.cut(&CutSurface::Triangles(bad)).is_err());
    assert!(mesh.cut(&CutSurface::Plane { point: Point3::origin(), normal: cleave_core::Vector3::zeros() }).is_err());
}
