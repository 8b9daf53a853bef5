//! Wavefront OBJ loading: a line-numbering pre-scan plus `tobj` for the faces.
//!
//! `tobj` reports errors without line numbers and can panic on some out-of-range index
//! components, so the text is scanned first: every problem this scan finds is reported with
//! its 1-based line number before `tobj` sees the text. `tobj` numbers vertices per
//! object in order of first use; the positions read by the scan map them back to file
//! order.

use std::collections::HashMap;
use std::str::SplitWhitespace;

use nalgebra::Point3;

use crate::{GeometryError, TriangleMesh};

/// Parses OBJ text given as bytes; see [`TriangleMesh::from_obj_reader`].
pub(crate) fn parse_obj_bytes(bytes: &[u8]) -> Result<TriangleMesh, GeometryError> {
    let text = std::str::from_utf8(bytes).map_err(|e| {
        let line = bytes[..e.valid_up_to()].iter().filter(|&&b| b == b'\n').count() + 1;
        GeometryError::ObjLine { line, message: "invalid UTF-8".to_owned() }
    })?;
    let positions = prescan(text)?;
    let mesh = load_with_tobj(text, &positions)?;
    if mesh.triangles.is_empty() {
        return Err(GeometryError::NoTriangles);
    }
    Ok(mesh)
}

fn line_error(line: usize, message: String) -> GeometryError {
    GeometryError::ObjLine { line, message }
}

/// Number of `v`, `vt` and `vn` lines.
#[derive(Default, Clone, Copy)]
struct Counts {
    v: usize,
    vt: usize,
    vn: usize,
}

/// Checks every line `tobj` interprets and returns the vertex positions in file order.
fn prescan(text: &str) -> Result<Vec<Point3<f64>>, GeometryError> {
    let mut total = Counts::default();
    for line in text.lines() {
        match line.split_whitespace().next() {
            Some("v") => total.v += 1,
            Some("vt") => total.vt += 1,
            Some("vn") => total.vn += 1,
            _ => {}
        }
    }
    let mut so_far = Counts::default();
    let mut positions = Vec::with_capacity(total.v);
    // Line of the first vertex with colours and of the first vertex without.
    let mut colored: Option<usize> = None;
    let mut uncolored: Option<usize> = None;
    for (n, line) in text.lines().enumerate() {
        let line_no = n + 1;
        let mut words = line.split_whitespace();
        match words.next() {
            Some("v") => {
                let (p, has_color) = parse_position(&mut words).map_err(|m| line_error(line_no, m))?;
                if !p.iter().all(|x| x.is_finite()) {
                    return Err(line_error(
                        line_no,
                        format!("vertex {} has a non-finite position {p:?}", so_far.v + 1),
                    ));
                }
                let slot = if has_color { &mut colored } else { &mut uncolored };
                slot.get_or_insert(line_no);
                if let (Some(a), Some(b)) = (colored, uncolored) {
                    return Err(line_error(
                        a.max(b),
                        "vertex colours are given for some vertices but not for others".to_owned(),
                    ));
                }
                positions.push(Point3::from(p));
                so_far.v += 1;
            }
            Some("vt") => {
                check_floats(&mut words, 2, "texture coordinate").map_err(|m| line_error(line_no, m))?;
                so_far.vt += 1;
            }
            Some("vn") => {
                check_floats(&mut words, 3, "normal").map_err(|m| line_error(line_no, m))?;
                so_far.vn += 1;
            }
            Some(kind @ ("f" | "l")) => {
                check_face(kind, words, so_far, total).map_err(|m| line_error(line_no, m))?;
            }
            Some("usemtl") if line.split_once(' ').is_none_or(|(_, r)| r.trim().is_empty()) => {
                return Err(line_error(line_no, "usemtl without a name".to_owned()));
            }
            _ => {}
        }
    }
    Ok(positions)
}

/// Parses the words after `v` the way `tobj` does: `x y z`, `x y z w` (divided by `w`)
/// or `x y z r g b`. Returns the position and whether colours were given.
fn parse_position(words: &mut SplitWhitespace) -> Result<([f64; 3], bool), String> {
    let mut p = [0.0; 3];
    for x in &mut p {
        let w = words.next().ok_or_else(|| "a vertex needs three coordinates".to_owned())?;
        *x = w.parse().map_err(|_| format!("invalid vertex coordinate '{w}'"))?;
    }
    let extra: Vec<&str> = words.collect();
    match extra.as_slice() {
        [] => Ok((p, false)),
        [w] => {
            let w: f64 = w.parse().map_err(|_| format!("invalid vertex weight '{w}'"))?;
            if w == 0.0 {
                return Err("vertex weight w is 0".to_owned());
            }
            for x in &mut p {
                *x /= w;
            }
            Ok((p, false))
        }
        [_, _, _] => Ok((p, true)),
        _ => {
            Err(format!("a vertex has {} values; expected 3 (x y z), 4 (x y z w) or 6 (x y z r g b)", 3 + extra.len()))
        }
    }
}

/// Requires at least `n` numbers (`tobj` checks the first `n`).
fn check_floats(words: &mut SplitWhitespace, n: usize, what: &str) -> Result<(), String> {
    for i in 0..n {
        let w = words.next().ok_or_else(|| format!("a {what} needs {n} numbers, found {i}"))?;
        w.parse::<f64>().map_err(|_| format!("invalid {what} component '{w}'"))?;
    }
    Ok(())
}

/// Checks the index tokens of an `f` or `l` line.
fn check_face(kind: &str, words: SplitWhitespace, so_far: Counts, total: Counts) -> Result<(), String> {
    let tokens: Vec<&str> = words.collect();
    if tokens.is_empty() {
        return Err(format!("'{kind}' line without vertices"));
    }
    if kind == "l" && tokens.len() > 2 {
        return Err(format!(
            "polyline ('l') with {} vertices is not supported (tobj would read it as a polygon)",
            tokens.len()
        ));
    }
    for tok in tokens {
        let parts: Vec<&str> = tok.split('/').collect();
        if parts.len() > 3 {
            return Err(format!("face vertex '{tok}' has more than three indices"));
        }
        for (slot, part) in parts.iter().enumerate() {
            let (what, before, all) = match slot {
                0 => ("vertex", so_far.v, total.v),
                1 => ("texture coordinate", so_far.vt, total.vt),
                _ => ("normal", so_far.vn, total.vn),
            };
            if part.is_empty() {
                if slot == 0 {
                    return Err(format!("face vertex '{tok}' has no position index"));
                }
                continue;
            }
            let x: isize = part.parse().map_err(|_| format!("invalid index '{part}' in face vertex '{tok}'"))?;
            // tobj ignores texture-coordinate and normal indices when the file has none.
            if slot > 0 && all == 0 {
                continue;
            }
            let ok = match x {
                0 => false,
                x if x < 0 => x.unsigned_abs() <= before,
                x => x.unsigned_abs() <= all,
            };
            if !ok {
                let defined = if x < 0 { before } else { all };
                return Err(format!(
                    "face vertex '{tok}' refers to {what} {x}, but {defined} {what}s are defined{}",
                    if x < 0 { " before this line" } else { "" }
                ));
            }
        }
    }
    Ok(())
}

/// Key for exact position matching (`-0.0` and `0.0` are the same point).
fn key(p: [f64; 3]) -> [u64; 3] {
    p.map(|x| (x + 0.0).to_bits())
}

/// Loads the faces with `tobj` and renumbers vertices to file order.
fn load_with_tobj(text: &str, positions: &[Point3<f64>]) -> Result<TriangleMesh, GeometryError> {
    // `..Default::default()` keeps this compiling if another crate enables tobj features
    // that add fields.
    #[allow(clippy::needless_update)]
    let options = tobj::LoadOptions {
        single_index: true,
        triangulate: true,
        ignore_points: true,
        ignore_lines: true,
        ..Default::default()
    };
    let (models, _materials) = tobj::load_obj_buf(&mut text.as_bytes(), &options, |_path| {
        // Materials are irrelevant here and no file may be opened.
        Err(tobj::LoadError::OpenFileFailed)
    })
    .map_err(|e| GeometryError::Obj { message: e.to_string() })?;

    // First file index of every distinct position.
    let mut first_index: HashMap<[u64; 3], usize> = HashMap::with_capacity(positions.len());
    for (i, p) in positions.iter().enumerate() {
        first_index.entry(key(p.coords.into())).or_insert(i);
    }
    // Positions tobj produced that the scan did not see (not expected) are appended.
    let mut extra: Vec<Point3<f64>> = Vec::new();
    let mut corners: Vec<usize> = Vec::new();
    for model in &models {
        let mesh = &model.mesh;
        let local: Vec<usize> = mesh
            .positions
            .chunks_exact(3)
            .map(|c| {
                let p = [c[0], c[1], c[2]];
                *first_index.entry(key(p)).or_insert_with(|| {
                    extra.push(Point3::from(p));
                    positions.len() + extra.len() - 1
                })
            })
            .collect();
        for tri in mesh.indices.chunks_exact(3) {
            for &i in tri {
                let global = local.get(i as usize).copied().ok_or_else(|| GeometryError::Obj {
                    message: format!("tobj produced an out-of-range vertex index {i}"),
                })?;
                corners.push(global);
            }
        }
    }

    // Keep referenced vertices, in file order.
    let all_count = positions.len() + extra.len();
    let mut referenced = vec![false; all_count];
    for &c in &corners {
        referenced[c] = true;
    }
    let mut new_index = vec![u32::MAX; all_count];
    let mut vertices = Vec::new();
    for (i, slot) in new_index.iter_mut().enumerate() {
        if referenced[i] {
            let p = if i < positions.len() { positions[i] } else { extra[i - positions.len()] };
            *slot = u32::try_from(vertices.len())
                .map_err(|_| GeometryError::Obj { message: "more than 2^32 vertices".to_owned() })?;
            vertices.push(p);
        }
    }
    let triangles = corners.chunks_exact(3).map(|t| [new_index[t[0]], new_index[t[1]], new_index[t[2]]]).collect();
    Ok(TriangleMesh { vertices, triangles })
}
