//! Which columns of a landmark table hold what: per format, the coordinate columns in
//! point order and the per-point confidences.

use keyshape_core::error::{setting, Error, Result};
use keyshape_core::sequence::Format;
use std::collections::HashMap;
use std::path::Path;

/// Which columns a format keeps its data in.
pub(super) struct Columns {
    /// Coordinate column name prefixes, per axis (`x_`, `y_`, `z_` or `x`, `y`, `z`).
    pub(super) axes: [&'static str; 3],
    /// 1 = tracked, 0 = failed.
    pub(super) valid: Option<&'static str>,
    pub(super) frame: Option<&'static str>,
    pub(super) time: Option<&'static str>,
    pub(super) segment: Option<&'static str>,
    /// The per-point confidence column prefix (`c`: `c0, c1, …`), where the format has one.
    pub(super) confidence: Option<&'static str>,
}

/// The columns of `format` read at `dims` coordinates per point.
pub(super) fn columns(format: Format, dims: usize) -> Columns {
    match format {
        Format::Mediapipe => Columns {
            axes: ["x_", "y_", "z_"],
            valid: Some("detected"),
            frame: Some("frame"),
            time: Some("time_s"),
            segment: None,
            confidence: None,
        },
        // OpenFace: 2-D pixels in x_/y_, 3-D millimetres (camera frame) in X_/Y_/Z_.
        Format::Openface => Columns {
            axes: if dims == 3 {
                ["X_", "Y_", "Z_"]
            } else {
                ["x_", "y_", "z_"]
            },
            valid: Some("success"),
            frame: Some("frame"),
            time: Some("timestamp"),
            segment: None,
            confidence: None,
        },
        // py-feat frames count within a clip, so frames are numbered by row instead.
        Format::Pyfeat => Columns {
            axes: ["x_", "y_", "z_"],
            valid: None,
            frame: None,
            time: None,
            segment: Some("clip"),
            confidence: None,
        },
        _ => Columns {
            axes: ["x", "y", "z"],
            valid: None,
            frame: Some("frame"),
            time: Some("time_s"),
            segment: None,
            confidence: Some("c"),
        },
    }
}

/// Column indices in shape order: x0, y0, (z0), x1, y1, …
pub(super) fn coordinate_columns(
    path: &Path,
    index: &HashMap<&str, usize>,
    cols: &Columns,
    dims: usize,
    format: Format,
) -> Result<Vec<usize>> {
    let mut out = Vec::new();
    for p in 0.. {
        let Some(&x) = index.get(format!("{}{p}", cols.axes[0]).as_str()) else {
            break;
        };
        out.push(x);
        for axis in &cols.axes[1..dims] {
            let name = format!("{axis}{p}");
            match index.get(name.as_str()) {
                Some(&c) => out.push(c),
                None if dims == 3 && axis.starts_with(['z', 'Z']) && p == 0 => {
                    return Err(Error::parse(
                        path,
                        1,
                        x as u64 + 1,
                        format!("{dims} 3 needs a column '{name}' and the {format} header has none; use {dims} 2", dims = setting("dims")),
                    ))
                }
                None => {
                    return Err(Error::parse(
                        path,
                        1,
                        x as u64 + 1,
                        format!("header has '{}{p}' but no '{name}'", cols.axes[0]),
                    ))
                }
            }
        }
    }
    // Every other `<axis><n>` column is a gap or a renamed column: refuse rather than read
    // fewer points than the file has.
    let points = out.len() / dims;
    let mut stray: Vec<(usize, &str)> = index
        .iter()
        .filter(|(name, _)| {
            cols.axes[..dims].iter().any(|a| {
                name.strip_prefix(a).is_some_and(|n| {
                    !n.is_empty()
                        && n.bytes().all(|b| b.is_ascii_digit())
                        && n.parse::<usize>().map_or(true, |i| i >= points)
                })
            })
        })
        .map(|(name, &c)| (c, *name))
        .collect();
    stray.sort();
    if let Some(&(c, name)) = stray.first() {
        let missing = cols.axes[..dims]
            .iter()
            .map(|a| format!("{a}{points}"))
            .find(|n| !index.contains_key(n.as_str()))
            .unwrap_or_else(|| format!("{}{points}", cols.axes[0]));
        return Err(Error::parse(
            path,
            1,
            c as u64 + 1,
            format!(
                "header has '{name}' but no '{missing}': landmark columns must run without gaps from {}0 (read {points} points before the gap)",
                cols.axes[0]
            ),
        ));
    }
    if out.is_empty() {
        return Err(Error::parse(
            path,
            1,
            1,
            format!(
                "header has no landmark columns for format {format} (expected {}0, {}0, …)",
                cols.axes[0], cols.axes[1]
            ),
        ));
    }
    Ok(out)
}

/// The confidence columns `<prefix>0 … <prefix>(points − 1)` in point order, or None when
/// the header has none; a partial set (a gap, a column past the last point) is refused.
pub(super) fn confidence_columns(
    path: &Path,
    index: &HashMap<&str, usize>,
    prefix: &str,
    points: usize,
) -> Result<Option<Vec<usize>>> {
    let numbered = |name: &str| {
        name.strip_prefix(prefix)
            .filter(|n| !n.is_empty() && n.bytes().all(|b| b.is_ascii_digit()))
            .map(|n| n.parse::<usize>().unwrap_or(usize::MAX))
    };
    let mut found: Vec<(usize, usize)> = index
        .iter()
        .filter_map(|(name, &c)| numbered(name).map(|p| (p, c)))
        .collect();
    if found.is_empty() {
        return Ok(None);
    }
    found.sort();
    if let Some(&(p, c)) = found
        .iter()
        .enumerate()
        .find_map(|(i, pc)| (pc.0 != i).then_some(pc))
    {
        let missing = (0..points)
            .find(|i| !found.iter().any(|f| f.0 == *i))
            .unwrap_or(points);
        return Err(Error::parse(
            path,
            1,
            c as u64 + 1,
            format!("header has '{prefix}{p}' but no '{prefix}{missing}': confidence columns run without gaps from {prefix}0, one per point"),
        ));
    }
    if found.len() != points {
        let (p, c) = found.last().copied().unwrap_or((0, 0));
        return Err(Error::parse(
            path,
            1,
            c as u64 + 1,
            format!("header has confidences {prefix}0..{prefix}{p} for {points} points: one confidence column per point"),
        ));
    }
    Ok(Some(found.into_iter().map(|(_, c)| c).collect()))
}
