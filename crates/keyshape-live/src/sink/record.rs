//! The recording (`--record DIR`): a take written as it happens, each frame whole in every
//! file however the session ends, and each calibration taken into use.

use super::{csv_line, weights_header, weights_line};
use keyshape_core::error::{Error, Result};
use keyshape_rig::livelink::column_sources;
use keyshape_rig::Rig;
use std::io::Write;
use std::path::{Path, PathBuf};

/// A calibration as a take records it: the frame numbers of the first frame solved with
/// it and of its lead-in (None: a saved calibration), and the calibration.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RecordedCalibration {
    /// The first frame (its number in the take) solved with it.
    pub from: i64,
    /// The first and last frame of its lead-in.
    pub lead_in: Option<[i64; 2]>,
    /// The calibration.
    pub calibration: keyshape_rig::live::Calibration,
}

/// A take written as it happens: `track.csv` (the input, as solved: `frame,time_s,x0,y0,…`
/// in image pixels, which the readers read back), `weights.csv` (as `kslab rig` writes it)
/// and `livelink.csv` (Live Link Face CSV). Each line is flushed as it is written, so the
/// files are whole up to the last frame however the session ends.
pub struct Recorder {
    dir: PathBuf,
    track: std::fs::File,
    weights: std::fs::File,
    livelink: std::fs::File,
    sources: Vec<Vec<usize>>,
    fps: f64,
    t0: Option<f64>,
    /// Each file's length after its last whole row.
    lengths: [u64; 3],
    /// Whether the folder was made for this take (not an empty one given).
    made_dir: bool,
    /// `calibrations.jsonl`, made with the first calibration.
    calibrations: Option<std::fs::File>,
    /// The track keeps each point's confidence.
    confidence: bool,
}

impl Recorder {
    /// The recording's files.
    pub const FILES: [&'static str; 3] = ["track.csv", "weights.csv", "livelink.csv"];

    /// Each calibration taken into use, one JSON object a line
    /// ([`RecordedCalibration`]): what `kslab rig --live --calibrations` replays.
    pub const CALIBRATIONS: &'static str = "calibrations.jsonl";

    /// Makes `dir` (it must not exist, or be an empty folder: a recording never replaces a
    /// file) and writes each file's header; `layout` points per frame, with the tracker's
    /// confidence in each (`c0, c1, …` after the points) when `confidence`.
    pub fn create(
        dir: &Path,
        rig: &Rig,
        (layout, confidence): (usize, bool),
        fps: f64,
    ) -> Result<Recorder> {
        let mut made_dir = false;
        match std::fs::read_dir(dir) {
            Ok(mut entries) => {
                if entries.next().is_some() {
                    return Err(Error::file(dir, "is not empty: a recording goes into a new or empty folder, so no earlier take is replaced"));
                }
            }
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
                std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
                made_dir = true;
            }
            Err(e) => return Err(Error::io(dir, e)),
        }
        let make = |name: &str| -> Result<std::fs::File> {
            let p = dir.join(name);
            std::fs::OpenOptions::new()
                .write(true)
                .create_new(true)
                .open(&p)
                .map_err(|e| Error::io(&p, e))
        };
        let mut r = Recorder {
            dir: dir.to_path_buf(),
            track: make(Self::FILES[0])?,
            weights: make(Self::FILES[1])?,
            livelink: make(Self::FILES[2])?,
            sources: column_sources(rig),
            fps,
            t0: None,
            lengths: [0; 3],
            made_dir,
            calibrations: None,
            confidence,
        };
        let track_header = ["frame".to_string(), "time_s".to_string()]
            .into_iter()
            .chain((0..layout).flat_map(|i| [format!("x{i}"), format!("y{i}")]))
            .chain((0..if confidence { layout } else { 0 }).map(|i| format!("c{i}")));
        let io = |e| Error::io(dir, e);
        let headers = [
            csv_line(track_header).map_err(io)?,
            csv_line(weights_header(rig)).map_err(io)?,
            csv_line(keyshape_rig::livelink::header().map(String::from)).map_err(io)?,
        ];
        r.write_rows([&headers[0], &headers[1], &headers[2]])?;
        Ok(r)
    }

    /// Removes the take's files (and its folder, when it was made for the take): a session
    /// that ended before its first frame leaves things as they were.
    pub fn remove(self) -> Result<()> {
        if self.calibrations.is_some() {
            let p = self.dir.join(Self::CALIBRATIONS);
            std::fs::remove_file(&p).map_err(|e| Error::io(&p, e))?;
        }
        for name in Self::FILES {
            let p = self.dir.join(name);
            std::fs::remove_file(&p).map_err(|e| Error::io(&p, e))?;
        }
        if self.made_dir {
            std::fs::remove_dir(&self.dir).map_err(|e| Error::io(&self.dir, e))?;
        }
        Ok(())
    }

    fn file(&mut self, which: usize) -> &mut std::fs::File {
        match which {
            0 => &mut self.track,
            1 => &mut self.weights,
            _ => &mut self.livelink,
        }
    }

    /// Writes one row to each file, whole or not at all: a write that fails part way (a
    /// full disk) is cut back, in every file, to the end of the last whole frame, so a take
    /// ends at a frame however the session ends.
    fn write_rows(&mut self, rows: [&[u8]; 3]) -> Result<()> {
        use std::io::Seek;
        for (which, row) in rows.iter().enumerate() {
            let f = self.file(which);
            if let Err(e) = f.write_all(row).and_then(|()| f.flush()) {
                for back in 0..=which {
                    let len = self.lengths[back];
                    let f = self.file(back);
                    let _ = f
                        .set_len(len)
                        .and_then(|()| f.seek(std::io::SeekFrom::Start(len)));
                }
                return Err(Error::io(self.dir.join(Self::FILES[which]), e));
            }
        }
        for (len, row) in self.lengths.iter_mut().zip(rows) {
            *len += row.len() as u64;
        }
        Ok(())
    }

    /// Records a calibration taken into use (a line of [`Recorder::CALIBRATIONS`]).
    pub fn calibration(&mut self, c: &RecordedCalibration) -> Result<()> {
        let p = self.dir.join(Self::CALIBRATIONS);
        if self.calibrations.is_none() {
            let f = std::fs::OpenOptions::new()
                .append(true)
                .create_new(true)
                .open(&p)
                .map_err(|e| Error::io(&p, e))?;
            self.calibrations = Some(f);
        }
        let mut line =
            serde_json::to_vec(c).map_err(|e| Error::io(&p, std::io::Error::other(e)))?;
        line.push(b'\n');
        let f = self
            .calibrations
            .as_mut()
            .ok_or_else(|| Error::invalid("no calibrations file"))?;
        f.write_all(&line)
            .and_then(|()| f.flush())
            .map_err(|e| Error::io(&p, e))
    }

    /// Records one solved frame: its input `points` (and the tracker's confidence in
    /// each, when the take keeps them), weights `w` and head angles.
    pub fn record(
        &mut self,
        number: i64,
        time: f64,
        (points, confidence): (&[f64], Option<&[f64]>),
        w: &[f64],
        head: [f64; 3],
    ) -> Result<()> {
        let io = |e| Error::io(&self.dir, e);
        let track = csv_line(
            [number.to_string(), format!("{time}")]
                .into_iter()
                .chain(points.iter().map(|v| format!("{v}")))
                .chain(
                    // A frame without confidences in a take that keeps them: every point seen.
                    (0..if self.confidence { points.len() / 2 } else { 0 }).map(|i| {
                        format!(
                            "{}",
                            confidence.and_then(|c| c.get(i)).copied().unwrap_or(1.0)
                        )
                    }),
                ),
        )
        .map_err(io)?;
        let weights = weights_line(number, w).map_err(io)?;
        let t0 = *self.t0.get_or_insert(time);
        let ll = csv_line(keyshape_rig::livelink::record(
            &self.sources,
            w,
            head,
            time - t0,
            self.fps,
            "61",
        ))
        .map_err(io)?;
        self.write_rows([&track, &weights, &ll])
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    /// A write that fails part way (a full disk: `/dev/full`) leaves every file of the take
    /// ending at the last whole frame, and the take reads back. (A disk filling up left
    /// half a row, and the take was unreadable: "ragged row".)
    #[cfg(target_os = "linux")]
    #[test]
    fn a_full_disk_leaves_the_take_whole_up_to_its_last_frame() {
        let shared = keyshape_io::shared_data("ict_facekit_face").unwrap();
        let (_, _, rig) = keyshape_rig::correspondence::read_rig(&shared, 68, None).unwrap();
        let dir = tempfile::tempdir().unwrap();
        let take = dir.path().join("take");
        let mut r = Recorder::create(&take, &rig, (68, false), 30.0).unwrap();
        let points: Vec<f64> = (0..136).map(|i| 100.0 + i as f64).collect();
        let w = vec![0.25; rig.k()];
        for f in 0..3 {
            r.record(f, f as f64 / 30.0, (&points, None), &w, [0.0; 3])
                .unwrap();
        }
        let whole: Vec<Vec<u8>> = Recorder::FILES
            .iter()
            .map(|f| std::fs::read(take.join(f)).unwrap())
            .collect();
        // The track's row is written, then the weights' fails.
        r.weights = std::fs::OpenOptions::new()
            .write(true)
            .open("/dev/full")
            .unwrap();
        let e = r.record(3, 0.1, (&points, None), &w, [0.0; 3]).unwrap_err();
        assert!(e.to_string().contains("weights.csv"), "{e}");
        for (f, before) in Recorder::FILES.iter().zip(&whole) {
            assert_eq!(&std::fs::read(take.join(f)).unwrap(), before, "{f}");
        }
        let seq = keyshape_io::read_sequence(
            &take.join("track.csv"),
            &keyshape_io::ReadOptions::default(),
        )
        .unwrap();
        assert_eq!(seq.n_frames(), 3);
        assert!(seq.notes.is_empty());
    }
}
