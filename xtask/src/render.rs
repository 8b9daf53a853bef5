//! `cargo xtask render`: recorded `/surface` frames drawn to PNG (and an animated GIF) with flat
//! shading in the recorded colours (cut faces red), the collider planes as a ground, mesh
//! colliders, the simulated time and the backend's name; `--grid` puts the same instants of
//! several recordings side by side.

use crate::animation::GifWriter;
use crate::plots::{FONT, register_font};
use crate::raster::{Camera, Canvas};
use crate::recording::{self, Frame, Recording, TriangleList, Vec3, cross, dot, normalized, sub};
use anyhow::{Context, Result, anyhow, bail};
use indicatif::{ProgressBar, ProgressStyle};
use plotters::prelude::*;
use std::path::PathBuf;
use std::time::Instant;

/// What `cargo xtask render` was asked for.
pub struct RenderArgs {
    pub files: Vec<PathBuf>,
    pub grid: bool,
    pub out: PathBuf,
    pub every: usize,
    /// Azimuth and elevation [degrees].
    pub camera: (f32, f32),
    /// Width and height of one picture [pixels].
    pub size: (usize, usize),
    pub gif: bool,
    pub quiet: bool,
}

const BACKGROUND: [u8; 3] = [250, 250, 250];
/// Light direction in the camera's frame (right, away from the viewer, up): from the upper
/// left, behind the viewer.
const LIGHT: Vec3 = [-0.38, -0.72, 0.58];
/// Brightness steps: flat shading in a few dozen levels keeps a frame's colours within a
/// GIF palette without dithering.
const SHADES: f32 = 24.0;

/// Parses "AZIMUTH,ELEVATION" in degrees.
pub fn parse_camera(text: &str) -> Result<(f32, f32)> {
    let parts: Vec<&str> = text.split(',').map(str::trim).collect();
    let error = || anyhow!("--camera takes AZIMUTH,ELEVATION in degrees (e.g. -60,20), got {text:?}");
    let [azimuth, elevation] = parts.as_slice() else { return Err(error()) };
    let (a, e): (f32, f32) = (azimuth.parse().map_err(|_| error())?, elevation.parse().map_err(|_| error())?);
    if !(a.is_finite() && e.is_finite()) {
        return Err(error());
    }
    Ok((a, e))
}

/// Parses "WIDTHxHEIGHT" in pixels.
pub fn parse_size(text: &str) -> Result<(usize, usize)> {
    let error = || anyhow!("--size takes WIDTHxHEIGHT in pixels, each 64 to 4096 (e.g. 480x360), got {text:?}");
    let (w, h) = text.split_once('x').ok_or_else(error)?;
    let (w, h): (usize, usize) = (w.trim().parse().map_err(|_| error())?, h.trim().parse().map_err(|_| error())?);
    if !((64..=4096).contains(&w) && (64..=4096).contains(&h)) {
        return Err(error());
    }
    Ok((w, h))
}

/// The frame shown at `time`: the last one at or before it (the first before the recording
/// starts, the last after it ends).
fn frame_at(recording: &Recording, time: f64) -> &Frame {
    let after = recording.frames.partition_point(|f| f.time <= time + 1e-9);
    &recording.frames[after.saturating_sub(1)]
}

/// The box around every drawn point of every frame (planes excepted: they are infinite), so
/// that the camera stays still.
fn bounds(recording: &Recording) -> (Vec3, Vec3) {
    let (mut lo, mut hi) = ([f32::MAX; 3], [f32::MIN; 3]);
    let lists = recording.frames.iter().flat_map(|f| &f.lists).chain(&recording.meshes);
    for p in lists.flat_map(|l| &l.points).filter(|p| p.iter().all(|c| c.is_finite())) {
        for k in 0..3 {
            lo[k] = lo[k].min(p[k]);
            hi[k] = hi[k].max(p[k]);
        }
    }
    if lo[0] > hi[0] { ([-0.5; 3], [0.5; 3]) } else { (lo, hi) }
}

/// Flat, two-sided Lambert shading of a world triangle in `color` (RGB in [0, 1]).
fn shaded(camera: &Camera, triangle: [Vec3; 3], color: Vec3) -> [u8; 3] {
    let normal = camera.view_of(cross(sub(triangle[1], triangle[0]), sub(triangle[2], triangle[0])));
    let length = (dot(normal, normal) * dot(LIGHT, LIGHT)).sqrt();
    let lambert = if length > 0.0 { (dot(normal, LIGHT) / length).abs() } else { 0.0 };
    let brightness = ((0.3 + 0.7 * lambert) * SHADES).round() / SHADES;
    color.map(|c| (255.0 * (c * brightness).clamp(0.0, 1.0)).round() as u8)
}

fn draw_list(canvas: &mut Canvas, camera: &Camera, list: &TriangleList) {
    for t in list.indices.chunks_exact(3) {
        let world = [0, 1, 2].map(|k| list.points[t[k] as usize]);
        canvas.fill_triangle(world.map(|p| camera.project(p)), shaded(camera, world, list.color));
    }
}

/// Each plane as a checkered square (cells of two shades of its colour, so that motion over it
/// shows) around the foot of the drawn box's centre, a little wider than the box.
fn draw_planes(canvas: &mut Canvas, camera: &Camera, recording: &Recording, (lo, hi): (Vec3, Vec3)) {
    const CELLS: usize = 12;
    let centre = [0, 1, 2].map(|k| 0.5 * (lo[k] + hi[k]));
    let half = 0.7 * dot(sub(hi, lo), sub(hi, lo)).sqrt().max(0.1);
    for plane in &recording.planes {
        let n = plane.normal;
        let foot = sub(centre, n.map(|c| c * dot(sub(centre, plane.point), n)));
        let helper = if n[0].abs() < 0.9 { [1.0, 0.0, 0.0] } else { [0.0, 1.0, 0.0] };
        let u = normalized(cross(n, helper));
        let v = cross(n, u);
        // Cell corner (a, b) of the CELLS × CELLS grid, projected.
        let corner = |a: usize, b: usize| {
            let (s, t) = (half * (2.0 * a as f32 / CELLS as f32 - 1.0), half * (2.0 * b as f32 / CELLS as f32 - 1.0));
            camera.project([0, 1, 2].map(|k| foot[k] + s * u[k] + t * v[k]))
        };
        for a in 0..CELLS {
            for b in 0..CELLS {
                let shade = if (a + b) % 2 == 0 { 1.0 } else { 0.92 };
                let color = plane.color.map(|c| (255.0 * (shade * c).clamp(0.0, 1.0)).round() as u8);
                let [c0, c1, c2, c3] = [corner(a, b), corner(a + 1, b), corner(a + 1, b + 1), corner(a, b + 1)];
                canvas.fill_triangle([c0, c1, c2], color);
                canvas.fill_triangle([c0, c2, c3], color);
            }
        }
    }
}

/// Writes text over an RGB picture with the bundled font.
fn draw_labels(rgb: &mut [u8], (width, height): (usize, usize), labels: &[(&str, (i32, i32))]) -> Result<()> {
    register_font();
    let area = BitMapBackend::with_buffer(rgb, (width as u32, height as u32)).into_drawing_area();
    let style = TextStyle::from((FONT, 15).into_font()).color(&BLACK);
    for (text, position) in labels {
        area.draw_text(text, &style, *position).map_err(|e| anyhow!("drawing text: {e:?}"))?;
    }
    area.present().map_err(|e| anyhow!("drawing text: {e:?}"))?;
    Ok(())
}

/// One recording at one instant: ground, colliders, surface, time and backend.
fn panel(
    recording: &Recording,
    time: f64,
    camera: &Camera,
    bounds: (Vec3, Vec3),
    size: (usize, usize),
) -> Result<Canvas> {
    let mut canvas = Canvas::new(size.0, size.1, BACKGROUND);
    draw_planes(&mut canvas, camera, recording, bounds);
    let frame = frame_at(recording, time);
    for list in recording.meshes.iter().chain(&frame.lists) {
        draw_list(&mut canvas, camera, list);
    }
    // A recording that ended before this instant holds its last frame, and says so.
    let ended = time > frame.time + 1e-6 && std::ptr::eq(frame, recording.frames.last().unwrap_or(frame));
    let clock = format!("t = {:.2} s{}", frame.time, if ended { " (ended)" } else { "" });
    let name = format!("{}: {}", recording.backend.as_deref().unwrap_or("backend not recorded"), recording.scene);
    draw_labels(&mut canvas.rgb, size, &[(&clock, (8, 6)), (&name, (8, size.1 as i32 - 22))])?;
    Ok(canvas)
}

fn write_png(path: &std::path::Path, rgb: &[u8], (width, height): (usize, usize)) -> Result<()> {
    let context = || format!("cannot write {}", path.display());
    let mut backend = BitMapBackend::new(path, (width as u32, height as u32));
    backend
        .blit_bitmap((0, 0), (width as u32, height as u32), rgb)
        .map_err(|e| anyhow!("{e:?}"))
        .with_context(context)?;
    backend.present().map_err(|e| anyhow!("{e:?}")).with_context(context)
}

/// Renders the recordings: PNGs in `out/<name>/`, and `out/<name>.gif` with `--gif` (name: the
/// first file's stem, with `_grid` after it for `--grid`).
pub fn render(args: RenderArgs) -> Result<()> {
    if args.files.len() > 1 && !args.grid {
        bail!("{} recordings given: use --grid to draw them side by side, or give one", args.files.len());
    }
    let clock = Instant::now();
    let recordings: Vec<Recording> = args.files.iter().map(|f| recording::read(f)).collect::<Result<_>>()?;
    let read_seconds = clock.elapsed().as_secs_f64();
    // The instants: every `every`-th frame of the recording that lasts longest (the others show
    // their last frame at or before each).
    let end = |r: &Recording| r.frames.last().map_or(0.0, |f| f.time);
    let longest = recordings.iter().max_by(|a, b| end(a).total_cmp(&end(b))).context("no recording given")?;
    let instants: Vec<f64> = longest.frames.iter().step_by(args.every.max(1)).map(|f| f.time).collect();
    let (width, height) = args.size;
    // Each recording fills its own picture (a drop from 0.3 m and a bunny standing on the ground
    // need different scales to show anything).
    let views: Vec<(Camera, (Vec3, Vec3))> = recordings
        .iter()
        .map(|r| {
            let (lo, hi) = bounds(r);
            (Camera::fitting(args.camera.0, args.camera.1, lo, hi, 0.06, width, height), (lo, hi))
        })
        .collect();

    let columns = if recordings.len() <= 3 { recordings.len() } else { recordings.len().div_ceil(2) };
    let rows = recordings.len().div_ceil(columns);
    let sheet_size = (columns * width, rows * height);
    let stem = args.files[0].file_stem().map_or_else(|| "render".into(), |s| s.to_string_lossy().into_owned());
    let name = if args.grid { format!("{stem}_grid") } else { stem };
    let png_dir = args.out.join(&name);
    std::fs::create_dir_all(&png_dir).with_context(|| format!("cannot create {}", png_dir.display()))?;
    // Frames of an earlier, longer render would otherwise mix with these: remove our own
    // `NNNN.png` names, nothing else.
    for entry in std::fs::read_dir(&png_dir).with_context(|| format!("cannot list {}", png_dir.display()))? {
        let path = entry?.path();
        let ours = path.extension().is_some_and(|e| e == "png")
            && path
                .file_stem()
                .and_then(|s| s.to_str())
                .is_some_and(|s| s.len() == 4 && s.bytes().all(|b| b.is_ascii_digit()));
        if ours {
            std::fs::remove_file(&path).with_context(|| format!("cannot remove the old frame {}", path.display()))?;
        }
    }
    let gif_path = args.out.join(format!("{name}.gif"));
    let mut gif = if args.gif { Some(GifWriter::create(&gif_path, sheet_size.0, sheet_size.1)?) } else { None };

    let bar = if args.quiet { ProgressBar::hidden() } else { ProgressBar::new(instants.len() as u64) };
    bar.set_style(
        ProgressStyle::with_template("{bar:40.cyan/blue} {pos}/{len} frames  {per_sec}  eta {eta}")
            .expect("static template")
            .progress_chars("=> "),
    );
    let mut sheet = BACKGROUND.repeat(sheet_size.0 * sheet_size.1);
    for (k, &time) in instants.iter().enumerate() {
        for (r, (recording, (camera, bounds))) in recordings.iter().zip(&views).enumerate() {
            let canvas = panel(recording, time, camera, *bounds, args.size)?;
            let (x0, y0) = (r % columns * width, r / columns * height);
            for y in 0..height {
                let row = 3 * ((y0 + y) * sheet_size.0 + x0);
                sheet[row..row + 3 * width].copy_from_slice(&canvas.rgb[3 * y * width..3 * (y + 1) * width]);
            }
        }
        write_png(&png_dir.join(format!("{k:04}.png")), &sheet, sheet_size)?;
        if let Some(gif) = gif.as_mut() {
            gif.add(&sheet, time)?;
        }
        bar.inc(1);
    }
    if let Some(gif) = gif {
        gif.finish()?;
    }
    bar.finish_and_clear();
    let seconds = clock.elapsed().as_secs_f64();
    eprintln!(
        "{} frames of {} × {} in {:.1} s ({:.1} s reading): {}/0000.png …",
        instants.len(),
        sheet_size.0,
        sheet_size.1,
        seconds,
        read_seconds,
        png_dir.display()
    );
    if args.gif {
        let bytes = std::fs::metadata(&gif_path).map(|m| m.len()).unwrap_or(0);
        eprintln!("{} ({} kB)", gif_path.display(), bytes / 1000);
    }
    for (file, recording) in args.files.iter().zip(&recordings) {
        if recording.planes.is_empty() {
            // Not an error: a scene may have no plane (a bowl), and older recordings kept none.
            eprintln!("note: {} records no plane collider, so no ground is drawn", file.display());
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use cleave_core::{Point3, Vector3};

    /// A recording of a 0.2 m square standing on the ground plane z = 0 in the plane y = 0 (one
    /// half an original face, the other a cut face), rising 0.1 m per frame.
    fn square_recording(dir: &std::path::Path, frames: usize) -> PathBuf {
        let path = dir.join("square.mcap");
        let mut recorder = cleave_scene::Recorder::create(&path, "square", "virtualnode", 1).unwrap();
        recorder.colliders(&[], &[(Point3::origin(), Vector3::z())]).unwrap();
        for k in 0..frames {
            let z = 0.1 * k as f64;
            let points = [(-0.1, z), (0.1, z), (0.1, z + 0.2), (-0.1, z + 0.2)].map(|(x, z)| Point3::new(x, 0.0, z));
            recorder.surface(0.5 * k as f64, &points, &[[0, 1, 2], [0, 2, 3]], &[false, true], &[]).unwrap();
        }
        recorder.finish().unwrap();
        path
    }

    fn shoelace(v: [Vec3; 3]) -> f32 {
        0.5 * ((v[1][0] - v[0][0]) * (v[2][1] - v[0][1]) - (v[2][0] - v[0][0]) * (v[1][1] - v[0][1])).abs()
    }

    #[test]
    fn cut_faces_original_faces_and_ground_each_show_in_their_colour() {
        let dir = tempfile::tempdir().unwrap();
        let recording = recording::read(&square_recording(dir.path(), 1)).unwrap();
        let (lo, hi) = bounds(&recording);
        let camera = Camera::fitting(-90.0, 30.0, lo, hi, 0.06, 200, 150);
        let canvas = panel(&recording, 0.0, &camera, (lo, hi), (200, 150)).unwrap();
        let pixels: Vec<[i32; 3]> = canvas.rgb.chunks_exact(3).map(|p| [0, 1, 2].map(|c| i32::from(p[c]))).collect();
        // Recorded colours: original (0.85, 0.62, 0.38), cut (0.80, 0.15, 0.15), ground grey.
        let red = pixels.iter().filter(|p| p[0] > 40 && p[1] * 3 < p[0]).count() as f32;
        let tan = pixels.iter().filter(|p| p[1] * 3 > p[0] && p[2] * 2 < p[1] + p[0] / 4 && p[0] > p[1]).count() as f32;
        let ground = pixels.iter().filter(|p| p[0] == p[1] && p[1] == p[2] && (150..=215).contains(&p[0])).count();
        // Each half of the square covers its projected area (an orthographic view keeps equal
        // areas of one plane equal).
        let corners = [[-0.1, 0.0, 0.0], [0.1, 0.0, 0.0], [0.1, 0.0, 0.2], [-0.1, 0.0, 0.2]].map(|p| camera.project(p));
        let area = shoelace([corners[0], corners[1], corners[2]]);
        assert!(area > 2000.0, "{area}");
        for (what, count) in [("cut", red), ("original", tan)] {
            assert!((count - area).abs() < 0.05 * area, "{what} face: {count} pixels, projected area {area}");
        }
        assert!(ground > 2000, "ground: {ground} pixels");
    }

    #[test]
    fn every_frame_becomes_a_png_and_a_gif_frame() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("render");
        let args = |files: Vec<PathBuf>, grid: bool| RenderArgs {
            files,
            grid,
            out: out.clone(),
            every: 1,
            camera: (-60.0, 25.0),
            size: (160, 120),
            gif: true,
            quiet: true,
        };
        // A longer earlier render's frames do not stay behind; other files do.
        render(args(vec![square_recording(dir.path(), 5)], false)).unwrap();
        std::fs::write(out.join("square").join("notes.txt"), "kept").unwrap();
        let path = square_recording(dir.path(), 3);
        render(args(vec![path.clone()], false)).unwrap();
        assert!(out.join("square").join("notes.txt").exists());
        std::fs::remove_file(out.join("square").join("notes.txt")).unwrap();
        render(args(vec![path.clone(), path.clone()], true)).unwrap();
        for (name, width) in [("square", 160), ("square_grid", 320)] {
            let pngs = std::fs::read_dir(out.join(name)).unwrap().count();
            assert_eq!(pngs, 3, "{name}");
            let mut decoder = gif::DecodeOptions::new()
                .read_info(std::fs::File::open(out.join(format!("{name}.gif"))).unwrap())
                .unwrap();
            assert_eq!((decoder.width(), decoder.height()), (width, 120));
            let mut frames = 0;
            while decoder.read_next_frame().unwrap().is_some() {
                frames += 1;
            }
            assert_eq!(frames, 3, "{name}");
        }
        let error = format!("{:#}", render(args(vec![path.clone(), path], false)).unwrap_err());
        assert!(error.contains("use --grid"), "{error}");
    }
}
