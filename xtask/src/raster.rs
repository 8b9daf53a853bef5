//! A small software rasterizer for `cargo xtask render`: an orthographic camera and a canvas
//! that fills triangles with a depth buffer (RGB, 8 bits per channel).

use crate::recording::{Vec3, cross, dot, normalized};

/// An orthographic camera looking at `target` from azimuth and elevation, `scale` pixels per
/// metre, the target at the middle of a `width` × `height` picture.
#[derive(Debug, Clone, Copy)]
pub struct Camera {
    /// Unit vectors of the picture's right, the view direction (away from the viewer) and up.
    right: Vec3,
    forward: Vec3,
    up: Vec3,
    target: Vec3,
    scale: f32,
    width: usize,
    height: usize,
}

impl Camera {
    /// The viewer stands at `azimuth` (from +x towards +y) and `elevation` (above the x–y
    /// plane) in degrees, world z up; elevation is kept within ±89° so that "up" exists.
    pub fn new(azimuth: f32, elevation: f32, target: Vec3, scale: f32, width: usize, height: usize) -> Self {
        let (a, e) = (azimuth.to_radians(), elevation.clamp(-89.0, 89.0).to_radians());
        let forward = [-e.cos() * a.cos(), -e.cos() * a.sin(), -e.sin()];
        let right = normalized(cross(forward, [0.0, 0.0, 1.0]));
        let up = cross(right, forward);
        Self { right, forward, up, target, scale, width, height }
    }

    /// The camera that fits the box `lo`–`hi` into the picture with a margin of `margin`
    /// (a fraction of each side).
    pub fn fitting(azimuth: f32, elevation: f32, lo: Vec3, hi: Vec3, margin: f32, width: usize, height: usize) -> Self {
        let centre = [0, 1, 2].map(|k| 0.5 * (lo[k] + hi[k]));
        let unit = Self::new(azimuth, elevation, centre, 1.0, width, height);
        let (mut half_w, mut half_h) = (1e-6f32, 1e-6f32);
        for corner in 0..8 {
            let p = [0, 1, 2].map(|k| if corner >> k & 1 == 1 { hi[k] } else { lo[k] });
            let d = [0, 1, 2].map(|k| p[k] - centre[k]);
            half_w = half_w.max(dot(d, unit.right).abs());
            half_h = half_h.max(dot(d, unit.up).abs());
        }
        let scale = (0.5 * (1.0 - 2.0 * margin) * (width as f32 / half_w).min(height as f32 / half_h)).max(1e-6);
        Self { scale, ..unit }
    }

    /// Picture coordinates of a world point: x right and y down in pixels (pixel (i, j) spans
    /// [i, i + 1] × [j, j + 1]), and the depth along the view direction [m].
    pub fn project(&self, p: Vec3) -> Vec3 {
        let d = [0, 1, 2].map(|k| p[k] - self.target[k]);
        [
            0.5 * self.width as f32 + self.scale * dot(d, self.right),
            0.5 * self.height as f32 - self.scale * dot(d, self.up),
            dot(d, self.forward),
        ]
    }

    /// A world direction in the camera's frame (right, away from the viewer, up).
    pub fn view_of(&self, v: Vec3) -> Vec3 {
        [dot(v, self.right), dot(v, self.forward), dot(v, self.up)]
    }
}

/// An RGB picture with a depth per pixel.
pub struct Canvas {
    pub width: usize,
    pub height: usize,
    /// Row-major RGB, 3 bytes per pixel.
    pub rgb: Vec<u8>,
    depth: Vec<f32>,
}

/// Twice the signed area of (a, b, p): positive when p lies left of a→b in a y-down picture
/// seen as y-up, i.e. the sign tells the side.
fn edge(a: Vec3, b: Vec3, p: [f32; 2]) -> f32 {
    (b[0] - a[0]) * (p[1] - a[1]) - (b[1] - a[1]) * (p[0] - a[0])
}

impl Canvas {
    /// A canvas of one colour, every depth at infinity.
    pub fn new(width: usize, height: usize, background: [u8; 3]) -> Self {
        Self { width, height, rgb: background.repeat(width * height), depth: vec![f32::INFINITY; width * height] }
    }

    /// Fills the triangle of picture-space vertices (x, y in pixels, depth) with `color`
    /// wherever it is nearer than what is drawn: a pixel is covered when its centre lies inside
    /// or on an edge. Degenerate and non-finite triangles draw nothing.
    pub fn fill_triangle(&mut self, v: [Vec3; 3], color: [u8; 3]) {
        let area = edge(v[0], v[1], [v[2][0], v[2][1]]);
        if area == 0.0 || !area.is_finite() {
            return;
        }
        let (xs, ys) = (v.map(|p| p[0]), v.map(|p| p[1]));
        let lo = |c: [f32; 3]| c.iter().copied().fold(f32::MAX, f32::min);
        let hi = |c: [f32; 3]| c.iter().copied().fold(f32::MIN, f32::max);
        // Pixels whose centre (i + ½) can lie within [lo, hi].
        let i0 = (lo(xs) - 0.5).ceil().max(0.0) as usize;
        let j0 = (lo(ys) - 0.5).ceil().max(0.0) as usize;
        let i1 = ((hi(xs) - 0.5).floor() + 1.0).clamp(0.0, self.width as f32) as usize;
        let j1 = ((hi(ys) - 0.5).floor() + 1.0).clamp(0.0, self.height as f32) as usize;
        let inverse = 1.0 / area;
        for j in j0..j1 {
            for i in i0..i1 {
                let p = [i as f32 + 0.5, j as f32 + 0.5];
                // Barycentric weights; all of one sign (that of the area) inside.
                let w = [edge(v[1], v[2], p) * inverse, edge(v[2], v[0], p) * inverse, edge(v[0], v[1], p) * inverse];
                if w.iter().any(|&w| w < 0.0) {
                    continue;
                }
                let depth = w[0] * v[0][2] + w[1] * v[1][2] + w[2] * v[2][2];
                let k = j * self.width + i;
                if depth < self.depth[k] {
                    self.depth[k] = depth;
                    self.rgb[3 * k..3 * k + 3].copy_from_slice(&color);
                }
            }
        }
    }

    /// How many pixels have exactly this colour.
    #[cfg(test)]
    pub fn count(&self, color: [u8; 3]) -> usize {
        self.rgb.chunks_exact(3).filter(|p| *p == color).count()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const WHITE: [u8; 3] = [255; 3];
    const RED: [u8; 3] = [255, 0, 0];
    const BLUE: [u8; 3] = [0, 0, 255];

    #[test]
    fn a_right_triangle_covers_half_its_legs_product() {
        // Corners off the pixel grid: the count of pixel centres inside differs from the area
        // ab/2 only through the pixels the boundary crosses, well within half the perimeter
        // (covering the bounding box, ab, or nothing would be off by ab/2, far more).
        for (a, b, corner) in [(60.0f32, 40.0f32, [10.3f32, 7.7f32]), (25.0, 90.0, [3.1, 2.6]), (7.0, 5.0, [0.5, 0.5])]
        {
            let mut canvas = Canvas::new(128, 128, WHITE);
            let [x, y] = corner;
            canvas.fill_triangle([[x, y, 0.0], [x + a, y, 0.0], [x, y + b, 0.0]], RED);
            let covered = canvas.count(RED) as f32;
            let tolerance = 0.5 * (a + b + (a * a + b * b).sqrt()) + 1.0;
            assert!(
                (covered - 0.5 * a * b).abs() <= tolerance,
                "legs {a} × {b}: {covered} pixels, expected ≈ {}",
                0.5 * a * b
            );
        }
    }

    #[test]
    fn a_triangle_on_pixel_centres_covers_the_exact_staircase() {
        // Legs of n pixels from the centre of pixel (0, 0): the centres (i + ½, j + ½) inside are
        // those with i + j ≤ n, i.e. (n + 1)(n + 2)/2 pixels, counted without the area formula.
        let n = 20usize;
        let mut canvas = Canvas::new(64, 64, WHITE);
        let (c, m) = (0.5, n as f32);
        canvas.fill_triangle([[c, c, 1.0], [c, c + m, 1.0], [c + m, c, 1.0]], RED);
        assert_eq!(canvas.count(RED), (n + 1) * (n + 2) / 2);
    }

    #[test]
    fn a_triangle_behind_another_covers_nothing() {
        let small = [[20.0, 20.0, 2.0], [40.0, 20.0, 2.0], [20.0, 40.0, 2.0]];
        let large = [[10.0, 10.0, 1.0], [60.0, 10.0, 1.0], [10.0, 60.0, 1.0]];
        // Either order: the depth test, not the drawing order, decides.
        for near_first in [true, false] {
            let mut canvas = Canvas::new(64, 64, WHITE);
            if near_first {
                canvas.fill_triangle(large, BLUE);
                canvas.fill_triangle(small, RED);
            } else {
                canvas.fill_triangle(small, RED);
                canvas.fill_triangle(large, BLUE);
            }
            assert_eq!(canvas.count(RED), 0, "near first: {near_first}");
            assert!(canvas.count(BLUE) > 1000);
        }
    }

    #[test]
    fn a_triangle_in_front_covers_what_it_would_alone() {
        let mut alone = Canvas::new(64, 64, WHITE);
        let front = [[20.0, 20.0, 0.5], [40.0, 20.0, 0.5], [20.0, 40.0, 0.5]];
        alone.fill_triangle(front, RED);
        let mut canvas = Canvas::new(64, 64, WHITE);
        canvas.fill_triangle([[10.0, 10.0, 1.0], [60.0, 10.0, 1.0], [10.0, 60.0, 1.0]], BLUE);
        canvas.fill_triangle(front, RED);
        assert_eq!(canvas.count(RED), alone.count(RED));
        assert!(alone.count(RED) > 150);
    }

    #[test]
    fn a_triangle_outside_the_picture_covers_nothing() {
        let mut canvas = Canvas::new(32, 32, WHITE);
        canvas.fill_triangle([[40.0, 5.0, 0.0], [80.0, 5.0, 0.0], [40.0, 30.0, 0.0]], RED);
        canvas.fill_triangle([[-50.0, -5.0, 0.0], [-10.0, -5.0, 0.0], [-50.0, -30.0, 0.0]], RED);
        assert_eq!(canvas.count(RED), 0);
        // Half inside: the left 16 columns of a 32-wide, 32-tall rectangle (two triangles).
        canvas.fill_triangle([[-16.0, 0.0, 0.0], [16.0, 0.0, 0.0], [16.0, 32.0, 0.0]], RED);
        canvas.fill_triangle([[-16.0, 0.0, 0.0], [16.0, 32.0, 0.0], [-16.0, 32.0, 0.0]], RED);
        assert_eq!(canvas.count(RED), 16 * 32);
    }

    #[test]
    fn the_camera_maps_world_axes_as_seen_from_the_front() {
        // From azimuth −90° (on −y looking towards +y), elevation 0: x is to the right, z up,
        // +y away from the viewer.
        let camera = Camera::new(-90.0, 0.0, [0.0; 3], 10.0, 100, 80);
        let close = |a: Vec3, b: Vec3| a.iter().zip(b).all(|(x, y)| (x - y).abs() < 1e-4);
        assert!(close(camera.project([0.0; 3]), [50.0, 40.0, 0.0]));
        assert!(close(camera.project([1.0, 0.0, 0.0]), [60.0, 40.0, 0.0]));
        assert!(close(camera.project([0.0, 0.0, 1.0]), [50.0, 30.0, 0.0]));
        assert!(close(camera.project([0.0, 2.0, 0.0]), [50.0, 40.0, 2.0]));
        // Fitting a 2 m cube seen from the front: its 2 m height fills 80 % of 80 pixels.
        let fitted = Camera::fitting(-90.0, 0.0, [-1.0; 3], [1.0; 3], 0.1, 100, 80);
        assert!(close(fitted.project([0.0, 0.0, 1.0]), [50.0, 40.0 - 32.0, 0.0]));
    }
}
