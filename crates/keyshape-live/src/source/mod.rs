//! Where frames come from: `openseeface:[HOST:]PORT`, `stdin`, `file:TRACK`.
//!
//! A source is opened before anything starts ([`open`]: the socket bound, the first line
//! read, the file read), so a bad option or an unreadable input fails at once and the
//! layout (68, 468 or 478 points) is known when the rig is read. Then it runs on its own
//! thread ([`Opened::spawn`]), pushing frames into the [`Queue`].

use super::{frame_problem, Counters, Frame, Queue, RateLimited};

mod json;
mod readers;
use json::json_points;
use keyshape_core::error::{setting, Error, Result};
use keyshape_core::sequence::Format;
use readers::confidence_problem;
use std::io::{BufRead, Read};
use std::net::{SocketAddr, UdpSocket};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

/// OpenSeeFace's default port.
pub const OPENSEEFACE_PORT: u16 = 11573;

/// A source as `--from` names it.
#[derive(Debug, Clone, PartialEq)]
pub enum SourceSpec {
    /// OpenSeeFace's datagrams, received on this address.
    OpenSeeFace(SocketAddr),
    /// Lines on standard input: a table (header, then rows) or JSON lines.
    Stdin,
    /// A track file replayed in real time.
    File(PathBuf),
}

pub use super::parse_address;

impl SourceSpec {
    /// Parses `openseeface[:[HOST:]PORT]`, `stdin` or `file:TRACK`.
    pub fn parse(s: &str) -> Result<SourceSpec> {
        let (scheme, rest) = match s.split_once(':') {
            Some((a, b)) => (a, Some(b)),
            None => (s, None),
        };
        match scheme.trim() {
            "openseeface" => Ok(SourceSpec::OpenSeeFace(parse_address(
                rest,
                "127.0.0.1",
                OPENSEEFACE_PORT,
                &format!("{} {s}", setting("from")),
            )?)),
            "stdin" if rest.is_none() => Ok(SourceSpec::Stdin),
            "file" => match rest.filter(|r| !r.is_empty()) {
                Some(p) => Ok(SourceSpec::File(PathBuf::from(p))),
                None => Err(Error::bad_setting(
                    "from",
                    s,
                    format!("{} file: name the track, file:TRACK", setting("from")),
                )),
            },
            _ => Err(Error::bad_setting(
                "from",
                s,
                format!(
                    "{} '{s}': not a source (openseeface:[HOST:]PORT, stdin or file:TRACK)",
                    setting("from")
                ),
            )),
        }
    }
}

/// How a source reads its frames.
#[derive(Debug, Clone, Default)]
pub struct SourceOptions {
    /// OpenSeeFace: the face id to follow [default: the first seen].
    pub face: Option<i32>,
    /// A file: frames per second to replay at [default: the file's own rate, else 30].
    pub rate: Option<f64>,
    /// The video's size, for normalised coordinates (every x and y in [0, 1]).
    pub image_size: Option<(f64, f64)>,
    /// A table's format [default: detected from the header].
    pub format: Option<Format>,
}

/// What a source reads, before its thread starts.
enum Reader {
    OpenSeeFace(UdpSocket),
    Table(Box<keyshape_io::table::TableRows<Box<dyn Read + Send>>>),
    JsonLines(Box<dyn BufRead + Send>, String),
    File(Box<keyshape_core::sequence::Sequence>, f64),
}

/// An opened source.
pub struct Opened {
    reader: Reader,
    /// Points per frame (68, 468, 478).
    pub layout: usize,
    /// The name messages use.
    pub name: String,
    /// Does the queue wait for the solve (a file) rather than drop frames (a live source)?
    pub blocking: bool,
    /// A note for the terminal (normalised coordinates without an image size).
    pub note: Option<String>,
    /// The source's own frame rate, when it has one (a file with time stamps).
    pub fps: Option<f64>,
    /// Its frames carry the tracker's confidence in each point (OpenSeeFace, a take
    /// recorded from it).
    pub confidence: bool,
    options: SourceOptions,
}

/// Opens `spec` (standard input is `stdin`; tests give another reader).
pub fn open(
    spec: &SourceSpec,
    options: &SourceOptions,
    stdin: Box<dyn BufRead + Send>,
) -> Result<Opened> {
    let options = options.clone();
    if let Some(r) = options.rate {
        keyshape_core::limits::LIVE_RATE.check("rate", r)?;
        if !matches!(spec, SourceSpec::File(_)) {
            return Err(Error::invalid(format!(
                "{} applies to a file source (file:TRACK); a live source sends at its own rate",
                setting("rate")
            )));
        }
    }
    if options.face.is_some() && !matches!(spec, SourceSpec::OpenSeeFace(_)) {
        return Err(Error::invalid(format!(
            "{} applies to an OpenSeeFace source, which may send several faces",
            setting("face")
        )));
    }
    match spec {
        SourceSpec::OpenSeeFace(addr) => {
            if options.image_size.is_some() || options.format.is_some() {
                return Err(Error::invalid(format!(
                    "{} and {} apply to stdin and file sources; OpenSeeFace sends pixels in its own layout",
                    setting("image_size"),
                    setting("format")
                )));
            }
            let sock = UdpSocket::bind(addr).map_err(|e| {
                Error::invalid(format!("openseeface: cannot listen on {addr}: {e}"))
            })?;
            sock.set_read_timeout(Some(Duration::from_millis(200)))
                .map_err(|e| Error::invalid(format!("openseeface: {e}")))?;
            Ok(Opened {
                reader: Reader::OpenSeeFace(sock),
                layout: super::openseeface::IBUG70_POINTS,
                name: format!("openseeface:{addr}"),
                blocking: false,
                note: None,
                fps: None,
                confidence: true,
                options,
            })
        }
        SourceSpec::Stdin => open_stdin(stdin, options),
        SourceSpec::File(path) => open_file(path, options),
    }
}

fn open_file(path: &Path, options: SourceOptions) -> Result<Opened> {
    let mut seq = keyshape_io::read_sequence(
        path,
        &keyshape_io::ReadOptions {
            format: options.format,
            dims: 2,
        },
    )?;
    keyshape_io::atomic::register_input(path)?;
    let mut note = (!seq.notes.is_empty()).then(|| format!("warning: {}", seq.notes.join("; ")));
    match options.image_size {
        Some((w, h)) => seq.scale_to_image(w, h)?,
        None if seq.is_normalised() => {
            let n = normalised_note(&path.display().to_string());
            note = Some(note.map_or(n.clone(), |cut| format!("{cut}\n{n}")));
        }
        None => {}
    }
    let rate = options.rate.or(seq.fps()).unwrap_or(30.0);
    Ok(Opened {
        fps: seq.fps(),
        confidence: seq.confidence.is_some(),
        layout: seq.points,
        reader: Reader::File(Box::new(seq), rate),
        name: path.display().to_string(),
        blocking: true,
        note,
        options,
    })
}

fn normalised_note(name: &str) -> String {
    format!("note: {name}: every x and y lies in [0, 1]: normalised image coordinates (MediaPipe's default); x and y are on different scales unless the video is square: give {} WIDTHxHEIGHT", setting("image_size"))
}

/// One line of standard input before the session starts (the header, the first row):
/// bounded in length and UTF-8, or an error naming the line; `None` at the end.
fn stdin_line(r: &mut dyn BufRead, at: &Path, line: u64) -> Result<Option<String>> {
    let mut bytes = Vec::new();
    match keyshape_io::read_line_capped(r, &mut bytes, keyshape_io::MAX_LINE_BYTES)
        .map_err(|e| Error::io(at, e))?
    {
        keyshape_io::Line::End => Ok(None),
        keyshape_io::Line::TooLong => Err(Error::parse(
            at,
            line,
            0,
            format!("line is longer than {} bytes", keyshape_io::MAX_LINE_BYTES),
        )),
        keyshape_io::Line::Read(_) => String::from_utf8(bytes)
            .map(Some)
            .map_err(|_| Error::parse(at, line, 0, "not UTF-8 text")),
    }
}

fn open_stdin(mut stdin: Box<dyn BufRead + Send>, options: SourceOptions) -> Result<Opened> {
    let at = Path::new("stdin");
    let mut line_no = 0u64;
    let first = loop {
        line_no += 1;
        match stdin_line(&mut *stdin, at, line_no)? {
            None => {
                return Err(Error::file(
                    at,
                    "ended before its first line (a table header or a JSON line)",
                ))
            }
            Some(l) if !l.trim().is_empty() => break l,
            Some(_) => {}
        }
    };
    if first.trim_start().starts_with('{') {
        if options.format.is_some() {
            return Err(Error::invalid(format!(
                "{} applies to a table on stdin; these are JSON lines",
                setting("format")
            )));
        }
        let (_, pts) = json_points(&first).map_err(|e| Error::parse(at, 1, 1, e))?;
        let layout = pts.len() / 2;
        let mut note = None;
        let normalised = pts.iter().all(|v| (0.0..=1.0).contains(v));
        match options.image_size {
            Some(_) if !normalised => {
                return Err(Error::parse(at, 1, 1, "an image size applies to normalised coordinates (every x and y in [0, 1]); this line's are not"))
            }
            None if normalised => note = Some(normalised_note("stdin")),
            _ => {}
        }
        // The first line is a frame too: the thread starts with it.
        return Ok(Opened {
            reader: Reader::JsonLines(stdin, first),
            layout,
            name: "stdin".into(),
            blocking: false,
            note,
            fps: None,
            confidence: false,
            options,
        });
    }
    let format = match options.format {
        Some(f) => f,
        None => keyshape_io::detect_format(at, &first)?,
    };
    // The first row too, read here: an image size for a table in pixels (or none for a
    // normalised one) is said before anything starts.
    let mut row = String::new();
    while row.trim().is_empty() {
        line_no += 1;
        match stdin_line(&mut *stdin, at, line_no)? {
            Some(l) => row = l,
            None => break,
        }
    }
    let mut note = None;
    {
        let probe = format!("{first}{row}");
        let mut rows =
            keyshape_io::table::TableRows::new(at, std::io::Cursor::new(probe), format, 2)?;
        if let Some(r) = rows.next_row()?.filter(|r| r.tracked) {
            let normalised = r.coords.iter().all(|v| (0.0..=1.0).contains(v));
            match options.image_size {
                Some(_) if !normalised => {
                    return Err(Error::parse(at, r.line, 1, "an image size applies to normalised coordinates (every x and y in [0, 1]); this row's are not"))
                }
                None if normalised => note = Some(normalised_note("stdin")),
                _ => {}
            }
        }
    }
    let head: Box<dyn Read + Send> =
        Box::new(std::io::Cursor::new(format!("{first}{row}").into_bytes()).chain(stdin));
    let rows = keyshape_io::table::TableRows::new(at, head, format, 2)?;
    Ok(Opened {
        confidence: rows.has_confidence(),
        layout: rows.points(),
        reader: Reader::Table(Box::new(rows)),
        name: "stdin".into(),
        blocking: false,
        note,
        fps: None,
        options,
    })
}

impl Opened {
    /// The address a network source listens on (the port the system chose for port 0).
    pub fn address(&self) -> Option<SocketAddr> {
        match &self.reader {
            Reader::OpenSeeFace(sock) => sock.local_addr().ok(),
            _ => None,
        }
    }
}

/// Reports from the receiving thread (malformed input, rate-limited by the caller).
pub type Warn = Box<dyn FnMut(String) + Send>;

impl Opened {
    /// Starts the receiving thread: frames into `queue` until the source ends (then the
    /// queue is closed) or `stop` is set.
    pub fn spawn(
        self,
        queue: Arc<Queue>,
        counters: Arc<Counters>,
        stop: Arc<AtomicBool>,
        warn: Warn,
    ) -> std::thread::JoinHandle<()> {
        std::thread::spawn(move || {
            let mut run = Run {
                queue: &queue,
                counters: &counters,
                stop: &stop,
                warn,
                limit: RateLimited::new(),
                start: Instant::now(),
                options: self.options,
                layout: self.layout,
                new_face: None,
            };
            match self.reader {
                Reader::OpenSeeFace(sock) => run.openseeface(&sock),
                Reader::Table(rows) => run.table(*rows),
                Reader::JsonLines(r, first) => run.json_lines(r, first),
                Reader::File(seq, rate) => run.file(&seq, rate),
            }
            queue.close();
        })
    }
}

struct Run<'a> {
    queue: &'a Queue,
    counters: &'a Counters,
    stop: &'a AtomicBool,
    warn: Warn,
    limit: RateLimited,
    start: Instant,
    options: SourceOptions,
    layout: usize,
    /// A new face begins with the next frame delivered (why).
    new_face: Option<String>,
}

impl Run<'_> {
    fn stopped(&self) -> bool {
        self.stop.load(Ordering::Relaxed)
    }

    fn malformed(&mut self, msg: &str) {
        self.counters.malformed.fetch_add(1, Ordering::Relaxed);
        if let Some(m) = self.limit.say(msg) {
            (self.warn)(m);
        }
    }

    /// Counts a frame the tracker marked as failed (skipped: the avatar holds its pose).
    fn untracked(&mut self, msg: &str) {
        self.counters.untracked.fetch_add(1, Ordering::Relaxed);
        if let Some(m) = self.limit.say(msg) {
            (self.warn)(m);
        }
    }

    /// Queues a frame received at `arrived`, or counts it malformed (and says why) when a
    /// value is out of range: every source's frames pass this one check, the bound the
    /// file readers keep ([`keyshape_core::sequence::coord_problem`]) and a time that a
    /// clock can show ([`frame_problem`]). Whether the frame was queued.
    fn deliver(
        &mut self,
        number: i64,
        time: f64,
        (mut points, confidence): (Vec<f64>, Option<Vec<f64>>),
        arrived: Instant,
    ) -> bool {
        let new_face = self.new_face.take();
        if let Some((w, h)) = self.options.image_size {
            for p in points.chunks_mut(2) {
                p[0] *= w;
                p[1] *= h;
            }
        }
        if let Some(why) = frame_problem(time, &points).or_else(|| {
            confidence
                .as_deref()
                .and_then(|c| confidence_problem(c, points.len() / 2))
        }) {
            self.malformed(&format!("frame {number}: {why}"));
            return false;
        }
        self.counters.received.fetch_add(1, Ordering::Relaxed);
        self.queue.push(
            Frame {
                number,
                time,
                points,
                confidence,
                arrived,
                new_face,
            },
            self.counters,
        );
        true
    }

    fn openseeface(&mut self, sock: &UdpSocket) {
        let mut buf = vec![0u8; 65_536];
        let mut follow = self.options.face;
        let mut n = 0i64;
        let mut said_pupils = false;
        let mut seen: Option<(SocketAddr, [f32; 2])> = None;
        while !self.stopped() {
            let (len, from, arrived) = match sock.recv_from(&mut buf) {
                Ok((len, from)) => (len, from, Instant::now()),
                Err(e)
                    if matches!(
                        e.kind(),
                        std::io::ErrorKind::WouldBlock
                            | std::io::ErrorKind::TimedOut
                            | std::io::ErrorKind::Interrupted
                    ) =>
                {
                    continue
                }
                Err(e) => {
                    self.malformed(&format!("openseeface: {e}"));
                    continue;
                }
            };
            match super::openseeface::decode(&buf[..len]) {
                Err(e) => self.malformed(&format!("openseeface: skipped a datagram: {e}")),
                Ok(faces) => {
                    let id = *follow.get_or_insert(faces[0].id);
                    let others = faces.iter().filter(|f| f.id != id).count() as u64;
                    self.counters
                        .other_faces
                        .fetch_add(others, Ordering::Relaxed);
                    if let Some(f) = faces.into_iter().find(|f| f.id == id) {
                        // The same face id from another sender, or another image size:
                        // another tracker (restarted, perhaps on another person).
                        let why = match seen {
                            Some((was, _)) if was != from => Some(format!(
                                "face {id} now comes from {from} (it came from {was}): another tracker"
                            )),
                            Some((_, size)) if size != f.size => Some(format!(
                                "the image size changed from {}x{} to {}x{}",
                                size[0], size[1], f.size[0], f.size[1]
                            )),
                            _ => None,
                        };
                        seen = Some((from, f.size));
                        if why.is_some() {
                            self.new_face = why;
                        }
                        if !f.success {
                            self.untracked(&format!(
                                "openseeface: the tracker's own 3-D fit failed on face {id} (success 0): frame skipped, the avatar holds its pose"
                            ));
                            continue;
                        }
                        let (points, pupils) = f.ibug70();
                        if pupils.iter().any(|&u| u) && !said_pupils {
                            said_pupils = true;
                            (self.warn)("openseeface: a pupil was not tracked (confidence below 0.2 or the eye nearly closed; all frames with --gaze-tracking 0): it is left out of the solve (the eyes look ahead) and drawn at its eye's centre".into());
                        }
                        let confidence = Some(f.confidence70());
                        if self.deliver(n, f.time, (points, confidence), arrived) {
                            n += 1;
                        }
                    }
                }
            }
        }
    }
}
