//! Animated GIF output for `cargo xtask render`: each frame stores only the rectangle that
//! changed since the previous one (unchanged pixels transparent), with its own palette of the
//! colours it uses, so a still ground and background cost nothing after the first frame.

use anyhow::{Context, Result};
use std::collections::HashMap;
use std::fs::File;
use std::io::BufWriter;
use std::path::{Path, PathBuf};

/// Palette index of "unchanged since the previous frame".
const TRANSPARENT: u8 = 255;
/// How long the last frame stays before the loop starts again [1/100 s].
const HOLD_LAST: u16 = 150;

/// Writes RGB frames with their simulated times into a looping GIF played in real time.
pub struct GifWriter {
    path: PathBuf,
    encoder: gif::Encoder<BufWriter<File>>,
    width: usize,
    height: usize,
    previous: Option<Vec<u8>>,
    /// The last frame, written once the next one's time gives its delay.
    pending: Option<(gif::Frame<'static>, f64)>,
}

impl GifWriter {
    /// Creates the file for `width` × `height` frames.
    pub fn create(path: &Path, width: usize, height: usize) -> Result<Self> {
        let context = || format!("cannot write {}", path.display());
        let (w, h) = (u16::try_from(width).with_context(context)?, u16::try_from(height).with_context(context)?);
        let file = File::create(path).with_context(context)?;
        let mut encoder = gif::Encoder::new(BufWriter::new(file), w, h, &[]).with_context(context)?;
        encoder.set_repeat(gif::Repeat::Infinite).with_context(context)?;
        Ok(Self { path: path.to_path_buf(), encoder, width, height, previous: None, pending: None })
    }

    /// Adds a frame (row-major RGB) shown at simulated time `time` [s].
    pub fn add(&mut self, rgb: &[u8], time: f64) -> Result<()> {
        let frame = changed_part(rgb, self.previous.as_deref(), self.width, self.height);
        if let Some((mut pending, start)) = self.pending.take() {
            // Rounded on the time line, not per frame, so that delays do not drift; browsers slow
            // delays under 2/100 s down to 10/100 s, so none is shorter.
            pending.delay = ((100.0 * time).round() - (100.0 * start).round()).clamp(2.0, 6000.0) as u16;
            self.encoder.write_frame(&pending).with_context(|| format!("cannot write {}", self.path.display()))?;
        }
        self.pending = Some((frame, time));
        self.previous = Some(rgb.to_vec());
        Ok(())
    }

    /// Writes the last frame and closes the file.
    pub fn finish(mut self) -> Result<()> {
        if let Some((mut last, _)) = self.pending.take() {
            last.delay = HOLD_LAST;
            self.encoder.write_frame(&last).with_context(|| format!("cannot write {}", self.path.display()))?;
        }
        self.encoder.into_inner().with_context(|| format!("cannot finish {}", self.path.display()))?;
        Ok(())
    }
}

/// The bounding rectangle of the pixels that differ from `previous` (everything without one),
/// indexed into a palette of its colours: the 255 most used exactly, any others as the nearest
/// of those.
fn changed_part(rgb: &[u8], previous: Option<&[u8]>, width: usize, height: usize) -> gif::Frame<'static> {
    let pixel = |k: usize| [rgb[3 * k], rgb[3 * k + 1], rgb[3 * k + 2]];
    let changed = |k: usize| previous.is_none_or(|p| p[3 * k..3 * k + 3] != rgb[3 * k..3 * k + 3]);
    let (mut x0, mut y0, mut x1, mut y1) = (width, height, 0, 0);
    for y in 0..height {
        for x in 0..width {
            if changed(y * width + x) {
                (x0, y0, x1, y1) = (x0.min(x), y0.min(y), x1.max(x + 1), y1.max(y + 1));
            }
        }
    }
    if x0 >= x1 {
        // Nothing changed: one transparent pixel carries the frame's delay.
        (x0, y0, x1, y1) = (0, 0, 1, 1);
    }
    let mut counts: HashMap<[u8; 3], usize> = HashMap::new();
    for y in y0..y1 {
        for x in x0..x1 {
            if changed(y * width + x) {
                *counts.entry(pixel(y * width + x)).or_default() += 1;
            }
        }
    }
    let mut colors: Vec<([u8; 3], usize)> = counts.into_iter().collect();
    colors.sort_by(|a, b| b.1.cmp(&a.1).then(a.0.cmp(&b.0)));
    let kept: Vec<[u8; 3]> = colors.iter().take(TRANSPARENT as usize).map(|c| c.0).collect();
    let distance =
        |a: [u8; 3], b: [u8; 3]| a.iter().zip(b).map(|(&a, b)| (i32::from(a) - i32::from(b)).pow(2)).sum::<i32>();
    let index: HashMap<[u8; 3], u8> = colors
        .iter()
        .map(|&(color, _)| {
            let nearest = (0..kept.len()).min_by_key(|&i| distance(kept[i], color)).unwrap_or(0);
            (color, nearest as u8)
        })
        .collect();
    let mut buffer = Vec::with_capacity((x1 - x0) * (y1 - y0));
    for y in y0..y1 {
        for x in x0..x1 {
            let k = y * width + x;
            buffer.push(if changed(k) { index[&pixel(k)] } else { TRANSPARENT });
        }
    }
    let mut palette: Vec<u8> = kept.concat();
    palette.resize(3 * 256, 0);
    gif::Frame {
        left: x0 as u16,
        top: y0 as u16,
        width: (x1 - x0) as u16,
        height: (y1 - y0) as u16,
        buffer: buffer.into(),
        palette: Some(palette),
        transparent: Some(TRANSPARENT),
        dispose: gif::DisposalMethod::Keep,
        ..gif::Frame::default()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Decodes a GIF by painting every frame's opaque pixels over the canvas, as a viewer does.
    fn decode(path: &Path) -> Vec<(Vec<u8>, u16)> {
        let mut options = gif::DecodeOptions::new();
        options.set_color_output(gif::ColorOutput::RGBA);
        let mut decoder = options.read_info(File::open(path).unwrap()).unwrap();
        let (w, h) = (decoder.width() as usize, decoder.height() as usize);
        let mut canvas = vec![0u8; 3 * w * h];
        let mut frames = Vec::new();
        while let Some(frame) = decoder.read_next_frame().unwrap() {
            for y in 0..frame.height as usize {
                for x in 0..frame.width as usize {
                    let s = &frame.buffer[4 * (y * frame.width as usize + x)..][..4];
                    if s[3] != 0 {
                        let k = (y + frame.top as usize) * w + x + frame.left as usize;
                        canvas[3 * k..3 * k + 3].copy_from_slice(&s[..3]);
                    }
                }
            }
            frames.push((canvas.clone(), frame.delay));
        }
        frames
    }

    #[test]
    fn frames_come_back_exactly_with_real_time_delays() {
        let (w, h) = (40, 30);
        let mut first = vec![0u8; 3 * w * h];
        for (k, p) in first.chunks_exact_mut(3).enumerate() {
            p.copy_from_slice(&[(k % 7 * 30) as u8, (k % 5 * 50) as u8, 200]);
        }
        let mut second = first.clone();
        for y in 10..14 {
            for x in 20..25 {
                second[3 * (y * w + x)..][..3].copy_from_slice(&[255, 0, 0]);
            }
        }
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("a.gif");
        let mut writer = GifWriter::create(&path, w, h).unwrap();
        for (rgb, time) in [(&first, 0.0), (&second, 0.1), (&second, 0.35)] {
            writer.add(rgb, time).unwrap();
        }
        writer.finish().unwrap();
        let frames = decode(&path);
        assert_eq!(frames.len(), 3);
        assert!(frames[0].0 == first && frames[1].0 == second && frames[2].0 == second);
        assert_eq!(frames.iter().map(|f| f.1).collect::<Vec<_>>(), [10, 25, HOLD_LAST]);
        // Only the changed 5 × 4 rectangle is stored for the second frame.
        let part = changed_part(&second, Some(&first), w, h);
        assert_eq!((part.left, part.top, part.width, part.height), (20, 10, 5, 4));
    }

    #[test]
    fn more_than_255_colours_fall_to_the_nearest_kept_one() {
        // 300 colours: (g, 0, 0) for g < 256 and (g − 256, 100, 0) above; those under 255 are
        // used twice and kept. (255, 0, 0) is nearest to (254, 0, 0); (g − 256, 100, 0) to
        // (g − 256, 0, 0), 100 away, every other kept colour being farther.
        let color = |g: usize| if g < 256 { [g as u8, 0, 0] } else { [(g - 256) as u8, 100, 0] };
        let mut rgb = Vec::new();
        for g in 0..300 {
            for _ in 0..if g < 255 { 2 } else { 1 } {
                rgb.extend(color(g));
            }
        }
        let part = changed_part(&rgb, None, rgb.len() / 3, 1);
        let palette = part.palette.as_ref().unwrap();
        let shown: Vec<[u8; 3]> = part.buffer.iter().map(|&i| [0, 1, 2].map(|c| palette[3 * i as usize + c])).collect();
        let expected: Vec<[u8; 3]> = (0..300)
            .flat_map(|g| vec![color(g); if g < 255 { 2 } else { 1 }])
            .map(|c| if c == [255, 0, 0] { [254, 0, 0] } else { [c[0], 0, 0] })
            .collect();
        assert_eq!(shown, expected);
    }
}
