//! Writing CSV tables: a serde row struct per table, written through the `csv` crate (which
//! quotes a field only when it must), with every float as [`fmt_num`] writes it.
//!
//! ```
//! use keyshape_io::csv_out::{write_rows, Num};
//! use serde::Serialize;
//!
//! #[derive(Serialize, Default)]
//! struct Row<'a> {
//!     solver: &'a str,
//!     rms: Num,
//!     kkt: Option<Num>,
//! }
//! let mut out = Vec::new();
//! write_rows(&mut out, [Row { solver: "nnls, bounded", rms: Num(0.5), kkt: None }])?;
//! assert_eq!(String::from_utf8(out).unwrap(), "solver,rms,kkt\n\"nnls, bounded\",0.5,\n");
//! # Ok::<(), std::io::Error>(())
//! ```

use serde::{Serialize, Serializer};
use std::io::Write;

/// A float written the way every CSV of the lab writes floats ([`fmt_num`]): `123456`, not
/// `123456.0`; `1e-7`, not `0.0000001`.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Num(pub f64);

impl Serialize for Num {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        // No table carries a number a reader would refuse: a non-finite value is a bug
        // upstream, stopped here before it reaches a file.
        if !self.0.is_finite() {
            return Err(serde::ser::Error::custom(format!(
                "refusing to write the non-finite number {} into a table",
                self.0
            )));
        }
        s.serialize_str(&fmt_num(self.0))
    }
}

/// The head-pose columns a weights CSV ends with when head motion is applied: each frame's
/// similarity (scale, rotation in degrees, translation).
pub const POSE_COLUMNS: [&str; 4] = ["head_scale", "head_angle_deg", "head_tx", "head_ty"];

/// One frame's head pose as the [`POSE_COLUMNS`] cells.
pub fn pose_cells(h: &keyshape_core::align::Similarity) -> [String; 4] {
    [
        fmt_num(h.scale),
        fmt_num(h.angle.to_degrees()),
        fmt_num(h.t[0]),
        fmt_num(h.t[1]),
    ]
}

/// An optional float: empty when `None`.
pub fn opt(v: Option<f64>) -> Option<Num> {
    v.map(Num)
}

/// Writes `rows` under a header of the row struct's field names (serde's names, so
/// `#[serde(rename)]` applies). The header comes from `R::default()`, so a table without
/// rows still has its header.
pub fn write_rows<R, I>(w: &mut dyn Write, rows: I) -> std::io::Result<()>
where
    R: Serialize + Default,
    I: IntoIterator<Item = R>,
{
    let mut head = csv::WriterBuilder::new()
        .has_headers(true)
        .from_writer(Vec::new());
    head.serialize(R::default()).map_err(io_error)?;
    let head = head.into_inner().map_err(|e| e.into_error())?;
    let end = head.iter().position(|&b| b == b'\n').map_or(0, |i| i + 1);
    w.write_all(&head[..end])?;
    let mut out = csv::WriterBuilder::new().has_headers(false).from_writer(w);
    for r in rows {
        out.serialize(r).map_err(io_error)?;
    }
    out.flush()
}

/// Writes a table whose columns are known only at run time (one per action, per shape…):
/// the header, then each record.
pub fn write_records<H, R>(w: &mut dyn Write, header: H, records: R) -> std::io::Result<()>
where
    H: IntoIterator,
    H::Item: AsRef<[u8]>,
    R: IntoIterator,
    R::Item: IntoIterator,
    <R::Item as IntoIterator>::Item: AsRef<[u8]>,
{
    let mut out = record_writer(w);
    out.write_record(header).map_err(io_error)?;
    for r in records {
        out.write_record(r).map_err(io_error)?;
    }
    out.flush()
}

/// A `csv` error as the I/O error it carries, its kind kept: a reader that has gone is
/// `BrokenPipe`, which the command line stops on quietly (`kslab … | head`). The crate's own
/// conversion wraps every error as `Other`. Any other error (a row the crate cannot
/// serialise) is `Other`.
pub fn io_error(e: csv::Error) -> std::io::Error {
    if e.is_io_error() {
        if let csv::ErrorKind::Io(io) = e.into_kind() {
            return io;
        }
        return std::io::Error::other("CSV writer: I/O error");
    }
    std::io::Error::other(e)
}

/// A writer of records for a table written as it is computed (a streamed solve): the same
/// dialect as [`write_records`], no header of its own; `flush` it at the end.
pub fn record_writer<W: Write>(w: W) -> csv::Writer<W> {
    csv::WriterBuilder::new().has_headers(false).from_writer(w)
}

/// Formats a number for CSV output: shortest round-trip decimal, with an exponent for
/// magnitudes below 1e-4 or from 1e15 on (so 2.5e-12 does not print as 0.0000000000025).
pub fn fmt_num(v: f64) -> String {
    let a = v.abs();
    if v == 0.0 || (1e-4..1e15).contains(&a) || !v.is_finite() {
        format!("{v}")
    } else {
        format!("{v:e}")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Serialize, Default)]
    struct Row<'a> {
        name: &'a str,
        k: usize,
        #[serde(rename = "rms_iod")]
        rms: Num,
        kkt: Option<Num>,
        ok: bool,
    }

    fn text(rows: Vec<Row>) -> String {
        let mut out = Vec::new();
        write_rows(&mut out, rows).unwrap();
        String::from_utf8(out).unwrap()
    }

    #[test]
    fn floats_are_written_as_fmt_num_writes_them() {
        let t = text(vec![
            Row {
                name: "a",
                k: 3,
                rms: Num(123456.0),
                kkt: Some(Num(1e-7)),
                ok: true,
            },
            Row {
                name: "b",
                k: 0,
                rms: Num(0.25),
                kkt: None,
                ok: false,
            },
        ]);
        assert_eq!(
            t,
            "name,k,rms_iod,kkt,ok\na,3,123456,1e-7,true\nb,0,0.25,,false\n"
        );
    }

    #[test]
    fn an_optional_float_is_a_number_or_an_empty_field() {
        assert_eq!(opt(Some(0.5)), Some(Num(0.5)));
        assert_eq!(opt(None), None);
        let t = text(vec![Row {
            kkt: opt(Some(2.5)),
            ..Default::default()
        }]);
        assert_eq!(t.lines().nth(1).unwrap(), ",0,0,2.5,false");
    }

    /// A writer whose reader has gone.
    struct Closed;
    impl Write for Closed {
        fn write(&mut self, _: &[u8]) -> std::io::Result<usize> {
            Err(std::io::ErrorKind::BrokenPipe.into())
        }
        fn flush(&mut self) -> std::io::Result<()> {
            Err(std::io::ErrorKind::BrokenPipe.into())
        }
    }

    #[test]
    fn a_closed_pipe_stays_a_broken_pipe() {
        let e = write_rows(&mut Closed, vec![Row::default()]).unwrap_err();
        assert_eq!(e.kind(), std::io::ErrorKind::BrokenPipe);
        let e = write_records(&mut Closed, ["a"], [["1"]]).unwrap_err();
        assert_eq!(e.kind(), std::io::ErrorKind::BrokenPipe);
        let mut w = record_writer(Closed);
        let e = w.write_record(["a"]).and_then(|()| Ok(w.flush()?));
        assert_eq!(
            io_error(e.map_or_else(|e| e, |()| panic!("wrote to a closed pipe"))).kind(),
            std::io::ErrorKind::BrokenPipe
        );
    }

    #[test]
    fn an_empty_table_keeps_its_header() {
        assert_eq!(text(Vec::new()), "name,k,rms_iod,kkt,ok\n");
    }

    #[test]
    fn fields_with_commas_or_quotes_are_quoted() {
        let t = text(vec![Row {
            name: "temporal, λ=\"2\"",
            ..Default::default()
        }]);
        assert_eq!(
            t.lines().nth(1).unwrap(),
            "\"temporal, λ=\"\"2\"\"\",0,0,,false"
        );
    }

    #[test]
    fn records_take_a_header_known_at_run_time() {
        let mut out = Vec::new();
        write_records(
            &mut out,
            ["frame", "smile", "blink"],
            [["0", "0.5", "1"], ["1", "0", "0"]],
        )
        .unwrap();
        assert_eq!(
            String::from_utf8(out).unwrap(),
            "frame,smile,blink\n0,0.5,1\n1,0,0\n"
        );
    }
}
