//! Morph targets as sparse offsets from a neutral mesh (the ICT face's expression shapes,
//! a glTF rig's targets): read from CSV, checked, blended (`E = N + Σ wᵢ dᵢ`, w in [0, 1])
//! and written as GLB. Paper 002 §3.3 (Eq. 8) drives them from action trajectories
//! (`keyshape_actions::morph`); the rig solves for their weights (`keyshape_rig`).

use keyshape_core::error::{Error, Result};
use std::path::Path;

/// The most a shape may move a vertex, in extents of the mesh.
pub const MAX_OFFSET_EXTENTS: f64 = 100.0;

/// A shape name must be one field of a CSV and one column of a weights file: not empty, no
/// comma, quote or line break, and not a name already taken.
pub fn check_name(name: &str, taken: &[String]) -> std::result::Result<(), String> {
    if name.is_empty() {
        return Err("a shape has an empty name".into());
    }
    if name.contains([',', '"', '\n', '\r']) {
        return Err(format!(
            "shape name '{name}' holds a comma, quote or line break (it names a CSV column)"
        ));
    }
    if taken.iter().any(|t| t == name) {
        return Err(format!("shape name '{name}' is given twice"));
    }
    Ok(())
}

/// Per shape, its (vertex, offset) pairs.
type Offsets = Vec<Vec<(usize, [f64; 3])>>;

/// The per-shape offsets of `expression_deltas.csv` (shape_id, vertex, dx, dy, dz) for
/// `shapes` shapes on a mesh of `vertices`: each error names its line and column.
fn read_deltas(deltas: &Path, shapes: usize, vertices: usize) -> Result<Offsets> {
    // (shape, vertex) → the line that gave it: a second row for one would be summed by
    // nobody and silently win.
    let mut given = Given::new(shapes, vertices);
    let mut out = vec![Vec::new(); shapes];
    let text = super::read_text(deltas)?;
    let mut rdr = csv::Reader::from_reader(text.as_bytes());
    let mut lines = crate::csv_error::LineCounter::new(text.as_bytes());
    // One record reused, its fields read as bytes (200,000 rows on the ICT face).
    let mut r = csv::ByteRecord::new();
    while rdr
        .read_byte_record(&mut r)
        .map_err(|e| crate::csv_error::csv_error_in(deltas, &e, text.as_bytes()))?
    {
        let line = r.position().map_or(0, |p| lines.line_at(p.byte()));
        let field = |c: usize| std::str::from_utf8(r.get(c).unwrap_or(b"")).ok();
        let shown = |c: usize| String::from_utf8_lossy(r.get(c).unwrap_or(b"")).into_owned();
        let num = |c: usize| -> Result<f64> {
            field(c).and_then(|t| t.parse::<f64>().ok()).ok_or_else(|| {
                Error::parse(
                    deltas,
                    line,
                    c as u64 + 1,
                    format!("not a number: '{}'", shown(c)),
                )
            })
        };
        let index = |c: usize| -> Result<usize> {
            field(c)
                .and_then(|t| t.trim().parse::<usize>().ok())
                .ok_or_else(|| {
                    Error::parse(
                        deltas,
                        line,
                        c as u64 + 1,
                        format!("not an index: '{}'", shown(c)),
                    )
                })
        };
        let (s, v) = (index(0)?, index(1)?);
        let o = [num(2)?, num(3)?, num(4)?];
        if let Some(c) = o.iter().position(|x| !x.is_finite()) {
            return Err(Error::parse(
                deltas,
                line,
                c as u64 + 3,
                format!("offset is not finite: '{}'", shown(c + 2)),
            ));
        }
        if s >= shapes || v >= vertices {
            return Err(Error::parse(
                deltas,
                line,
                1,
                format!(
                    "shape {s} / vertex {v} out of range ({} shapes, {vertices} vertices)",
                    shapes
                ),
            ));
        }
        if let Some(first) = given.insert(s, v, line) {
            return Err(Error::parse(
                deltas,
                line,
                1,
                format!("shape {s} / vertex {v} is given twice (first on line {first})"),
            ));
        }
        out[s].push((v, o));
    }
    if given.rows == 0 {
        return Err(Error::file(
            deltas,
            "holds no offsets: every shape would be the neutral face",
        ));
    }
    Ok(out)
}

/// The line each (shape, vertex) of a deltas file was given on: a table of every pair
/// when there are at most [`Given::DENSE_MAX`] (the ICT face's 55 × 9,409; a hash map was
/// most of the read's time), a hash map beyond.
struct Given {
    /// Per shape × vertex, the line (0: not given yet; lines count from 1).
    dense: Vec<u64>,
    sparse: std::collections::HashMap<(usize, usize), u64>,
    vertices: usize,
    /// Rows recorded.
    rows: usize,
}

impl Given {
    /// The most pairs kept in a table (32 MB of line numbers).
    const DENSE_MAX: usize = 1 << 22;

    fn new(shapes: usize, vertices: usize) -> Given {
        let pairs = shapes.saturating_mul(vertices);
        Given {
            dense: if pairs <= Self::DENSE_MAX {
                vec![0; pairs]
            } else {
                Vec::new()
            },
            sparse: std::collections::HashMap::new(),
            vertices,
            rows: 0,
        }
    }

    /// Records that (`s`, `v`) (in range) was given on `line`; the earlier line when it
    /// already was.
    fn insert(&mut self, s: usize, v: usize, line: u64) -> Option<u64> {
        let line = line.max(1);
        let earlier = if self.dense.is_empty() {
            self.sparse.insert((s, v), line)
        } else {
            let slot = &mut self.dense[s * self.vertices + v];
            let was = *slot;
            *slot = line;
            (was != 0).then_some(was)
        };
        self.rows += usize::from(earlier.is_none());
        earlier
    }
}

/// A named morph target as dense per-vertex offsets.
pub type DenseTarget = (String, Vec<[f64; 3]>);

/// Morph targets as sparse offsets from the neutral mesh.
#[derive(Debug, Clone)]
pub struct MorphTargets {
    /// Shape names, in id order.
    pub names: Vec<String>,
    /// Per shape: (vertex, offset).
    pub deltas: Vec<Vec<(usize, [f64; 3])>>,
}

impl MorphTargets {
    /// Reads `expressions.csv` (id, name, …) and `expression_deltas.csv` (shape_id, vertex,
    /// dx, dy, dz); vertices must be below `vertices`.
    pub fn read(expressions: &Path, deltas: &Path, vertices: usize) -> Result<MorphTargets> {
        let mut names = Vec::new();
        let text = super::read_text(expressions)?;
        let mut rdr = csv::Reader::from_reader(text.as_bytes());
        let mut lines = crate::csv_error::LineCounter::new(text.as_bytes());
        for r in rdr.records() {
            let r =
                r.map_err(|e| crate::csv_error::csv_error_in(expressions, &e, text.as_bytes()))?;
            let line = r.position().map_or(0, |p| lines.line_at(p.byte()));
            let id: usize = r
                .get(0)
                .unwrap_or("")
                .parse()
                .map_err(|_| Error::parse(expressions, line, 1, "shape id is not a number"))?;
            if id != names.len() {
                return Err(Error::parse(
                    expressions,
                    line,
                    1,
                    format!("shape ids must run 0, 1, …; found {id}"),
                ));
            }
            let name = r.get(1).unwrap_or("").trim();
            check_name(name, &names).map_err(|m| Error::parse(expressions, line, 2, m))?;
            names.push(name.to_string());
        }
        if names.is_empty() {
            return Err(Error::file(expressions, "names no shapes"));
        }
        let out = read_deltas(deltas, names.len(), vertices)?;
        Ok(MorphTargets { names, deltas: out })
    }

    /// Refuses offsets out of all proportion to the mesh (`positions`): beyond
    /// [`MAX_OFFSET_EXTENTS`] times its extent, a shape's landmarks would swamp every solve
    /// (an offset of 1e40 zeroed every weight) or overflow a glTF's 32-bit floats.
    pub fn check_scale(&self, positions: &[[f64; 3]]) -> Result<()> {
        let mut lo = [f64::INFINITY; 3];
        let mut hi = [f64::NEG_INFINITY; 3];
        for p in positions {
            for k in 0..3 {
                lo[k] = lo[k].min(p[k]);
                hi[k] = hi[k].max(p[k]);
            }
        }
        let extent = (0..3).map(|k| hi[k] - lo[k]).fold(0.0, f64::max);
        if !(extent.is_finite() && extent > 0.0) {
            return Err(Error::unfit("the mesh has no extent"));
        }
        for (s, d) in self.deltas.iter().enumerate() {
            for &(v, o) in d {
                let m = o.iter().fold(0.0f64, |a, c| a.max(c.abs()));
                if m.is_nan() || m > MAX_OFFSET_EXTENTS * extent {
                    return Err(Error::invalid(format!(
                        "shape '{}' moves vertex {v} by {m:e}, over {MAX_OFFSET_EXTENTS} times the mesh's extent {extent:.4}: not a shape of this mesh",
                        self.names[s]
                    )));
                }
            }
        }
        Ok(())
    }

    /// The shapes with any nonzero weight in `weights` (shapes × frames), as (name, dense
    /// per-vertex offsets), with their weight rows — what a glTF export needs.
    pub fn used_dense(
        &self,
        weights: &nalgebra::DMatrix<f64>,
        vertices: usize,
    ) -> (Vec<DenseTarget>, nalgebra::DMatrix<f64>) {
        let used: Vec<usize> = (0..self.names.len())
            .filter(|&s| weights.row(s).iter().any(|v| *v > 0.0))
            .collect();
        let dense = used
            .iter()
            .map(|&s| {
                let mut d = vec![[0.0; 3]; vertices];
                for &(v, o) in &self.deltas[s] {
                    d[v] = o;
                }
                (self.names[s].clone(), d)
            })
            .collect();
        (dense, weights.select_rows(&used))
    }

    /// Writes `mesh` animated by `weights` (shapes × frames) as GLB at `path` (atomically):
    /// only the shapes with a nonzero weight, densified, as morph targets; `rotations` (one
    /// `[x, y, z, w]` quaternion per frame) animate the node's rotation too.
    pub fn write_used_glb(
        &self,
        path: &Path,
        mesh: &super::obj::Mesh,
        weights: &nalgebra::DMatrix<f64>,
        fps: f64,
        rotations: Option<&[[f64; 4]]>,
    ) -> Result<()> {
        self.check_scale(&mesh.positions)?;
        let (dense, used) = self.used_dense(weights, mesh.positions.len());
        super::write_atomic(path, |f| {
            super::gltf::write_morph_glb_posed(
                f,
                &mesh.positions,
                &mesh.faces,
                &dense,
                &used,
                fps,
                rotations,
            )
        })
    }

    /// Eq. (8) into `out` (starting from `neutral`), weights clamped to [0, 1].
    pub fn blend(&self, neutral: &[[f64; 3]], weights: &[f64], out: &mut [[f64; 3]]) {
        out.copy_from_slice(neutral);
        for (s, &w) in weights.iter().enumerate() {
            let w = w.clamp(0.0, 1.0);
            if w == 0.0 {
                continue;
            }
            for &(v, d) in &self.deltas[s] {
                for k in 0..3 {
                    out[v][k] += w * d[k];
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::Given;

    /// The table and the hash map (a mesh beyond the table's size) find the same second
    /// rows, with the line of the first, and count the rows alike.
    #[test]
    fn the_table_and_the_map_find_the_same_repeated_pairs() {
        let table = Given::new(3, 5);
        assert!(!table.dense.is_empty());
        let map = Given::new(Given::DENSE_MAX, 2);
        assert!(map.dense.is_empty());
        for mut g in [table, map] {
            let rows = [(0, 4, 2), (2, 0, 3), (0, 4, 9), (1, 1, 10), (2, 0, 11)];
            let got: Vec<Option<u64>> = rows.iter().map(|&(s, v, l)| g.insert(s, v, l)).collect();
            assert_eq!(got, [None, None, Some(2), None, Some(3)]);
            assert_eq!(g.rows, 3);
        }
    }
}
