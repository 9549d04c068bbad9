//! Where the weights go: `vmc:[HOST:]PORT`, `livelink:[HOST:]PORT`, `stdout`; and the
//! recording (`--record DIR`).

use super::protocols::{
    livelink_packet, mirror_shapes, vmc_bundle, vmc_head, vmc_names, vmc_values,
};
use super::source::parse_address;
use keyshape_core::error::{setting, Error, Result};
use keyshape_rig::livelink::{column_sources, frame_values};
use keyshape_rig::Rig;
use std::io::Write;
use std::net::{SocketAddr, UdpSocket};
use std::path::{Path, PathBuf};

/// The VMC protocol's default port (a performer application's receiver).
pub const VMC_PORT: u16 = 39539;
/// Live Link Face's default port.
pub const LIVELINK_PORT: u16 = 11111;

/// A sink as `--to` names it.
#[derive(Debug, Clone, PartialEq)]
pub enum SinkSpec {
    /// VMC bundles (OSC over UDP) to this address.
    Vmc(SocketAddr),
    /// Live Link Face packets to this address.
    LiveLink(SocketAddr),
    /// Weights CSV lines on standard output.
    Stdout,
}

impl SinkSpec {
    /// Parses a comma-separated list of sinks (each named once).
    pub fn parse_list(s: &str) -> Result<Vec<SinkSpec>> {
        let mut out = Vec::new();
        for part in s.split(',').map(str::trim) {
            let (scheme, rest) = match part.split_once(':') {
                Some((a, b)) => (a, Some(b)),
                None => (part, None),
            };
            let what = format!("{} {part}", setting("to"));
            let sink = match scheme {
                "vmc" => SinkSpec::Vmc(parse_address(rest, "127.0.0.1", VMC_PORT, &what)?),
                "livelink" => {
                    SinkSpec::LiveLink(parse_address(rest, "127.0.0.1", LIVELINK_PORT, &what)?)
                }
                "stdout" if rest.is_none() => SinkSpec::Stdout,
                _ => {
                    return Err(Error::bad_setting(
                        "to",
                        part,
                        format!(
                    "{} '{part}': not a sink (vmc:[HOST:]PORT, livelink:[HOST:]PORT or stdout)",
                    setting("to")
                ),
                    ))
                }
            };
            if out.contains(&sink) {
                return Err(Error::bad_setting(
                    "to",
                    part,
                    format!("{} names {part} twice", setting("to")),
                ));
            }
            out.push(sink);
        }
        Ok(out)
    }
}

/// The CSV header of a weights table: `frame` and the rig's shape names (as `kslab rig`
/// writes it).
fn weights_header(rig: &Rig) -> Vec<String> {
    std::iter::once("frame".to_string())
        .chain(rig.names.iter().cloned())
        .collect()
}

/// One CSV line (the weights tables' dialect).
fn csv_line(fields: impl IntoIterator<Item = String>) -> std::io::Result<Vec<u8>> {
    let mut w = keyshape_io::csv_out::record_writer(Vec::new());
    w.write_record(fields)
        .map_err(keyshape_io::csv_out::io_error)?;
    w.into_inner().map_err(|e| e.into_error())
}

fn weights_line(number: i64, w: &[f64]) -> std::io::Result<Vec<u8>> {
    csv_line(std::iter::once(number.to_string()).chain(w.iter().map(|v| keyshape_io::fmt_num(*v))))
}

/// How the network sinks present the person.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SinkOptions {
    /// The avatar as the person's reflection: head turns and one-sided shapes flipped
    /// together (VMC and Live Link; standard output and the recording keep the person's
    /// own sides).
    pub mirror: bool,
    /// VMC's head bone: its local position (metres, Unity's axes; what
    /// `/VMC/Ext/Bone/Pos "Head"` carries and EVMC4U applies by default), or `None` to
    /// send no bone at all.
    pub head_position: Option<[f32; 3]>,
}

/// A typical humanoid's head bone above its neck (metres): what is sent as the head's local
/// position unless the user gives the avatar's own.
pub const HEAD_POSITION: [f32; 3] = [0.0, 0.1, 0.0];

impl Default for SinkOptions {
    fn default() -> Self {
        SinkOptions {
            mirror: false,
            head_position: Some(HEAD_POSITION),
        }
    }
}

/// The open sinks.
pub struct Sinks {
    options: SinkOptions,
    /// Per rig shape, its mirror image ([`mirror_shapes`]).
    twins: Vec<usize>,
    udp: Option<UdpSocket>,
    vmc: Vec<SocketAddr>,
    livelink: Vec<SocketAddr>,
    stdout: Option<Box<dyn Write + Send>>,
    sources: Vec<Vec<usize>>,
    vmc_names: Vec<String>,
    header: Vec<String>,
    wrote_header: bool,
    /// The frame rate before frames have come (the file's own, else 60).
    fps_hint: f64,
    /// The last frames' arrival instants, for the frame rate Live Link is told.
    arrivals: std::collections::VecDeque<std::time::Instant>,
    /// The Live Link device id: a UUID, as the app sends.
    device: String,
    /// Datagrams the network would not take (no receiver yet, say): counted, never fatal.
    pub send_errors: u64,
}

/// Arrivals the frame rate is measured over.
const RATE_WINDOW: usize = 61;
/// Gaps between arrivals the frame rate needs before it is measured.
pub const RATE_MIN_GAPS: usize = 15;

/// Frames per second from arrival instants: one over the median gap between consecutive
/// ones (a pause or a burst moves it little), rounded, within 1–1000; `None` for fewer
/// than [`RATE_MIN_GAPS`] gaps (one gap is one frame's jitter) or a median gap of 0.
pub fn arrival_rate(arrivals: &std::collections::VecDeque<std::time::Instant>) -> Option<i32> {
    let mut gaps: Vec<f64> = arrivals
        .iter()
        .zip(arrivals.iter().skip(1))
        .map(|(a, b)| b.saturating_duration_since(*a).as_secs_f64())
        .collect();
    if gaps.len() < RATE_MIN_GAPS {
        return None;
    }
    gaps.sort_by(f64::total_cmp);
    let mid = gaps[gaps.len() / 2];
    (mid > 0.0).then(|| (1.0 / mid).round().clamp(1.0, 1000.0) as i32)
}

impl Sinks {
    /// Opens `specs` for `rig`; `stdout` is where the `stdout` sink writes.
    pub fn open(
        specs: &[SinkSpec],
        rig: &Rig,
        stdout: Box<dyn Write + Send>,
        fps: f64,
        options: SinkOptions,
    ) -> Result<Sinks> {
        let vmc: Vec<SocketAddr> = specs
            .iter()
            .filter_map(|s| match s {
                SinkSpec::Vmc(a) => Some(*a),
                _ => None,
            })
            .collect();
        let livelink: Vec<SocketAddr> = specs
            .iter()
            .filter_map(|s| match s {
                SinkSpec::LiveLink(a) => Some(*a),
                _ => None,
            })
            .collect();
        let udp = if vmc.is_empty() && livelink.is_empty() {
            None
        } else {
            let v6 = vmc.iter().chain(&livelink).any(SocketAddr::is_ipv6);
            let any = if v6 { "[::]:0" } else { "0.0.0.0:0" };
            Some(UdpSocket::bind(any).map_err(|e| {
                Error::invalid(format!("{}: cannot open a UDP socket: {e}", setting("to")))
            })?)
        };
        let sources = column_sources(rig);
        Ok(Sinks {
            options,
            twins: mirror_shapes(&rig.names),
            udp,
            vmc,
            livelink,
            stdout: specs.contains(&SinkSpec::Stdout).then_some(stdout),
            vmc_names: vmc_names(&rig.names, &sources),
            sources,
            header: weights_header(rig),
            wrote_header: false,
            fps_hint: fps,
            arrivals: std::collections::VecDeque::with_capacity(RATE_WINDOW),
            device: super::protocols::device_uuid(
                std::time::SystemTime::now()
                    .duration_since(std::time::UNIX_EPOCH)
                    .map_or(0, |d| d.as_nanos())
                    ^ (u128::from(std::process::id()) << 96),
            ),
            send_errors: 0,
        })
    }

    /// The frame rate Live Link is told: measured from the frames' arrivals (a tracker
    /// pacing itself to 22 a second says 22; a file replayed at `--rate 60` says 60), the
    /// hint until two have come.
    pub fn fps(&self) -> i32 {
        arrival_rate(&self.arrivals)
            .unwrap_or_else(|| self.fps_hint.round().clamp(1.0, 1000.0) as i32)
    }

    /// The Live Link device id (a 36-character UUID).
    pub fn device(&self) -> &str {
        &self.device
    }

    /// Sends one solved frame, which arrived at `arrived`, to every sink; a frame that is
    /// not the `newest` (one of several that waited for a calibration) goes to standard
    /// output only, as an avatar shows the newest pose. Only standard output can fail (a
    /// reader that went away); the network's refusals are counted in `send_errors`.
    pub fn send(
        &mut self,
        number: i64,
        (w, head): (&[f64], [f64; 3]),
        arrived: std::time::Instant,
        newest: bool,
    ) -> std::io::Result<()> {
        if self.arrivals.len() == RATE_WINDOW {
            self.arrivals.pop_front();
        }
        self.arrivals.push_back(arrived);
        if let Some(udp) = self.udp.as_ref().filter(|_| newest) {
            let mirror = self.options.mirror;
            // The reflection: each shape takes its twin's value, the turn and tilt flip.
            let mirrored: Vec<f64>;
            let (net_w, net_head) = if mirror {
                mirrored = self.twins.iter().map(|&t| w[t]).collect();
                (&mirrored[..], [-head[0], head[1], -head[2]])
            } else {
                (w, head)
            };
            if !self.vmc.is_empty() {
                let bone = self
                    .options
                    .head_position
                    .map(|p| (p, vmc_head(head, mirror)));
                let bundle = vmc_bundle(&self.vmc_names, &vmc_values(&self.sources, net_w), bone);
                for a in &self.vmc {
                    if udp.send_to(&bundle, a).is_err() {
                        self.send_errors += 1;
                    }
                }
            }
            if !self.livelink.is_empty() {
                let values = frame_values(&self.sources, net_w, net_head);
                let packet =
                    livelink_packet(&self.device, "kslab", number as i32, self.fps(), &values);
                for a in &self.livelink {
                    if udp.send_to(&packet, a).is_err() {
                        self.send_errors += 1;
                    }
                }
            }
        }
        if let Some(out) = &mut self.stdout {
            if !self.wrote_header {
                out.write_all(&csv_line(self.header.iter().cloned())?)?;
                self.wrote_header = true;
            }
            out.write_all(&weights_line(number, w)?)?;
            out.flush()?;
        }
        Ok(())
    }
}

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

    /// The rate is the median gap's: a tracker at 22 a second with a pause and a burst
    /// says 22; nothing to measure says nothing.
    #[test]
    fn the_frame_rate_is_measured_from_the_arrivals() {
        let t0 = std::time::Instant::now();
        let at = |s: f64| t0 + std::time::Duration::from_secs_f64(s);
        let mut a: std::collections::VecDeque<_> = (0..20).map(|i| at(i as f64 / 22.0)).collect();
        assert_eq!(arrival_rate(&a), Some(22));
        a.push_back(at(3.0)); // a pause
        for k in 0..3 {
            a.push_back(at(3.0 + 1e-4 * f64::from(k))); // a burst
        }
        assert_eq!(arrival_rate(&a), Some(22));
        assert_eq!(arrival_rate(&[t0].into_iter().collect()), None);
        let few: std::collections::VecDeque<_> = (0..RATE_MIN_GAPS).map(|i| at(i as f64)).collect();
        assert_eq!(arrival_rate(&few), None, "too few gaps");
        let same: std::collections::VecDeque<_> = (0..20).map(|_| t0).collect();
        assert_eq!(arrival_rate(&same), None, "no gap");
        let fast: std::collections::VecDeque<_> = (0..20).map(|i| at(i as f64 * 1e-6)).collect();
        assert_eq!(arrival_rate(&fast), Some(1000), "clamped");
    }

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
