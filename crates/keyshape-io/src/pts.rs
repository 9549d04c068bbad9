//! iBUG `.pts` files: `version: 1`, `n_points: N`, `{`, N lines of `x y`, `}`.
//! A directory of them is a sequence, one file per frame, in natural order
//! (`frame2.pts` before `frame10.pts`).

use keyshape_core::error::{setting, Error, Result};
use keyshape_core::sequence::{Format, Sequence};
use nalgebra::DMatrix;
use std::path::{Path, PathBuf};

/// Parses one `.pts` file's text into its flat 2-D shape.
fn parse(path: &Path, text: &str) -> Result<Vec<f64>> {
    let mut n_points = None;
    let mut out = Vec::new();
    let mut in_body = false;
    let mut closed = false;
    for (i, raw) in text.lines().enumerate() {
        let line_no = i as u64 + 1;
        let line = raw.trim();
        if line.is_empty() {
            continue;
        }
        if !in_body {
            if let Some(v) = line.strip_prefix("n_points:") {
                let n: usize = v.trim().parse().map_err(|_| {
                    Error::parse(
                        path,
                        line_no,
                        10,
                        format!("n_points is not a count: '{}'", v.trim()),
                    )
                })?;
                n_points = Some(n);
            } else if line == "{" {
                in_body = true;
            } else if !line.starts_with("version:") {
                return Err(Error::parse(
                    path,
                    line_no,
                    1,
                    format!("unexpected line '{line}' before '{{'"),
                ));
            }
            continue;
        }
        if closed {
            return Err(Error::parse(
                path,
                line_no,
                1,
                format!("'{line}' after the closing '}}': a .pts file ends there"),
            ));
        }
        if line == "}" {
            closed = true;
            continue;
        }
        let mut col = 1u64;
        let mut count = 0;
        for tok in raw.split_whitespace() {
            col = raw.find(tok).map_or(col, |c| c as u64 + 1);
            let v: f64 = tok
                .parse()
                .map_err(|_| Error::parse(path, line_no, col, format!("not a number: '{tok}'")))?;
            if !v.is_finite() {
                return Err(Error::parse(
                    path,
                    line_no,
                    col,
                    format!("non-finite value '{tok}'"),
                ));
            }
            if let Some(why) = keyshape_core::sequence::coord_problem(v) {
                return Err(Error::parse(path, line_no, col, why));
            }
            out.push(v);
            count += 1;
        }
        if count != 2 {
            return Err(Error::parse(
                path,
                line_no,
                1,
                format!("expected 'x y', got {count} values"),
            ));
        }
    }
    let n = n_points.ok_or_else(|| Error::file(path, "no 'n_points:' line"))?;
    if !closed {
        return Err(Error::file(path, "no closing '}'"));
    }
    if out.len() != 2 * n {
        return Err(Error::file(
            path,
            format!("n_points says {n}, the body has {} points", out.len() / 2),
        ));
    }
    Ok(out)
}

fn build(source: &Path, points: usize, shapes: Vec<f64>, n: usize) -> Sequence {
    Sequence {
        source: source.display().to_string(),
        format: Format::Pts,
        dims: 2,
        points,
        coords: DMatrix::from_vec(2 * points, n, shapes),
        frames: (0..n as i64).collect(),
        times: None,
        segments: None,
        confidence: None,
        failed: Vec::new(),
        notes: Vec::new(),
    }
}

fn check_dims(path: &Path, dims: usize) -> Result<()> {
    if dims != 2 {
        return Err(Error::file(
            path,
            format!(".pts files hold 2-D points; use {} 2", setting("dims")),
        ));
    }
    Ok(())
}

/// One `.pts` file as a one-frame sequence.
pub(super) fn read_file(path: &Path, text: &str, dims: usize) -> Result<Sequence> {
    check_dims(path, dims)?;
    let shape = parse(path, text)?;
    Ok(build(path, shape.len() / 2, shape, 1))
}

/// A directory of `.pts` files, one per frame, in natural order.
pub(super) fn read_dir(dir: &Path, dims: usize) -> Result<Sequence> {
    check_dims(dir, dims)?;
    let mut files: Vec<PathBuf> = std::fs::read_dir(dir)
        .map_err(|e| Error::io(dir, e))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|e| e.eq_ignore_ascii_case("pts")))
        .collect();
    if files.is_empty() {
        return Err(Error::file(dir, "directory holds no .pts files"));
    }
    files.sort_by(|a, b| natural_cmp(&a.to_string_lossy(), &b.to_string_lossy()));
    let mut data = Vec::new();
    let mut points = None;
    for f in &files {
        let text = super::read_text(f)?;
        let shape = parse(f, &text)?;
        let n = shape.len() / 2;
        match points {
            None => points = Some(n),
            Some(p) if p != n => {
                return Err(Error::file(
                    f,
                    format!("has {n} points, the first file has {p}"),
                ));
            }
            _ => {}
        }
        data.extend(shape);
    }
    Ok(build(dir, points.unwrap_or(0), data, files.len()))
}

/// Natural order: runs of digits compare as numbers.
pub fn natural_cmp(a: &str, b: &str) -> std::cmp::Ordering {
    let (mut a, mut b) = (a.as_bytes(), b.as_bytes());
    loop {
        match (a.first(), b.first()) {
            (None, None) => return std::cmp::Ordering::Equal,
            (None, _) => return std::cmp::Ordering::Less,
            (_, None) => return std::cmp::Ordering::Greater,
            (Some(x), Some(y)) if x.is_ascii_digit() && y.is_ascii_digit() => {
                let da = a.iter().take_while(|c| c.is_ascii_digit()).count();
                let db = b.iter().take_while(|c| c.is_ascii_digit()).count();
                let na = std::str::from_utf8(&a[..da])
                    .unwrap_or("0")
                    .trim_start_matches('0');
                let nb = std::str::from_utf8(&b[..db])
                    .unwrap_or("0")
                    .trim_start_matches('0');
                let ord = na.len().cmp(&nb.len()).then_with(|| na.cmp(nb));
                if ord != std::cmp::Ordering::Equal {
                    return ord;
                }
                a = &a[da..];
                b = &b[db..];
            }
            (Some(x), Some(y)) => {
                if x != y {
                    return x.cmp(y);
                }
                a = &a[1..];
                b = &b[1..];
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn natural_order_compares_digit_runs_as_numbers() {
        let mut v = vec!["f10.pts", "f2.pts", "f1.pts", "f02b.pts"];
        v.sort_by(|a, b| natural_cmp(a, b));
        assert_eq!(v, ["f1.pts", "f2.pts", "f02b.pts", "f10.pts"]);
    }

    #[test]
    fn pts_body_errors_name_line_and_column() {
        let text = "version: 1\nn_points: 2\n{\n1 2\n3 x\n}\n";
        let e = parse(Path::new("a.pts"), text).unwrap_err().to_string();
        assert_eq!(e, "a.pts:5:3: not a number: 'x'");
    }
}
