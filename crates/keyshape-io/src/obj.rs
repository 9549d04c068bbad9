//! Wavefront OBJ meshes: positions and faces. Other lines (normals, UVs, groups,
//! materials) are skipped on reading; face entries `p`, `p/t`, `p/t/n`, `p//n` keep the
//! position index. Errors name the file, line and column.

use keyshape_core::error::{Error, Result};
use std::io::Write;
use std::path::Path;

/// A polygon mesh.
#[derive(Debug, Clone, PartialEq)]
pub struct Mesh {
    /// Vertex positions.
    pub positions: Vec<[f64; 3]>,
    /// Faces as 0-based vertex indices (triangles, quads, …).
    pub faces: Vec<Vec<usize>>,
}

/// Reads an OBJ file.
pub fn read_obj(path: &Path) -> Result<Mesh> {
    let text = crate::read_text(path)?;
    parse_obj(path, &text)
}

/// Parses OBJ text (`path` names the file in errors).
pub fn parse_obj(path: &Path, text: &str) -> Result<Mesh> {
    let mut positions = Vec::new();
    let mut faces = Vec::new();
    for (i, raw) in text.lines().enumerate() {
        let line_no = i as u64 + 1;
        let line = raw.split('#').next().unwrap_or("");
        let mut toks = line.split_whitespace();
        match toks.next() {
            Some("v") => positions.push(vertex(path, raw, line_no, &mut toks)?),
            Some("f") => faces.push((line_no, face(path, raw, line_no, toks, positions.len())?)),
            _ => {}
        }
    }
    let n = positions.len();
    let mut out = Vec::with_capacity(faces.len());
    for (line_no, f) in faces {
        if let Some(&bad) = f.iter().find(|&&v| v >= n) {
            return Err(Error::parse(
                path,
                line_no,
                1,
                format!(
                    "face refers to vertex {} but the file has {n} vertices",
                    bad + 1
                ),
            ));
        }
        out.push(f);
    }
    if n == 0 {
        return Err(Error::file(path, "no vertices ('v' lines)"));
    }
    Ok(Mesh {
        positions,
        faces: out,
    })
}

/// A `v` line's three coordinates (`toks`: the tokens after `v`; `raw`, line `line_no`).
fn vertex<'a>(
    path: &Path,
    raw: &str,
    line_no: u64,
    toks: &mut impl Iterator<Item = &'a str>,
) -> Result<[f64; 3]> {
    let col_of = |tok: &str| raw.find(tok).map_or(1, |c| c as u64 + 1);
    let mut p = [0.0; 3];
    for (d, slot) in p.iter_mut().enumerate() {
        let tok = toks.next().ok_or_else(|| {
            Error::parse(
                path,
                line_no,
                raw.len() as u64 + 1,
                format!("vertex needs 3 coordinates, found {d}"),
            )
        })?;
        let v: f64 = tok.parse().map_err(|_| {
            Error::parse(path, line_no, col_of(tok), format!("not a number: '{tok}'"))
        })?;
        if !v.is_finite() {
            return Err(Error::parse(
                path,
                line_no,
                col_of(tok),
                format!("non-finite coordinate '{tok}'"),
            ));
        }
        // The limit every reader keeps: a 1e308 vertex was read, to fail later
        // in a camera fit that could not name the file.
        if let Some(why) = keyshape_core::sequence::coord_problem(v) {
            return Err(Error::parse(path, line_no, col_of(tok), why));
        }
        *slot = v;
    }
    Ok(p)
}

/// An `f` line's vertex indices, 0-based (`toks`: the tokens after `f`; `raw`, line
/// `line_no`; `n` vertices read so far, which a negative index counts back from).
fn face<'a>(
    path: &Path,
    raw: &str,
    line_no: u64,
    toks: impl Iterator<Item = &'a str>,
    n: usize,
) -> Result<Vec<usize>> {
    let col_of = |tok: &str| raw.find(tok).map_or(1, |c| c as u64 + 1);
    let mut face = Vec::new();
    for tok in toks {
        let first = tok.split('/').next().unwrap_or("");
        let idx: i64 = first.parse().map_err(|_| {
            Error::parse(
                path,
                line_no,
                col_of(tok),
                format!("bad face index '{tok}'"),
            )
        })?;
        // 1-based; negative counts back from the last vertex read so far.
        let n = n as i64;
        let zero = if idx > 0 { idx - 1 } else { n + idx };
        if idx == 0 || zero < 0 {
            return Err(Error::parse(
                path,
                line_no,
                col_of(tok),
                format!("face index {idx} is not a vertex (1..={n})"),
            ));
        }
        face.push(zero as usize);
    }
    if face.len() < 3 {
        return Err(Error::parse(
            path,
            line_no,
            1,
            format!("a face needs 3 or more vertices, found {}", face.len()),
        ));
    }
    Ok(face)
}

/// Writes positions (`v`) and faces (`f`, 1-based) with a comment line.
pub fn write_obj(
    w: &mut dyn Write,
    positions: &[[f64; 3]],
    faces: &[Vec<usize>],
    comment: &str,
) -> std::io::Result<()> {
    writeln!(w, "# {comment}")?;
    for p in positions {
        writeln!(w, "v {:.5} {:.5} {:.5}", p[0], p[1], p[2])?;
    }
    for f in faces {
        write!(w, "f")?;
        for v in f {
            write!(w, " {}", v + 1)?;
        }
        writeln!(w)?;
    }
    Ok(())
}
