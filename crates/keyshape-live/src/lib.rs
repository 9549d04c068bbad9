//! A running face tracker to an avatar (`kslab live`, `kslab tui --live`): frames arrive
//! from a source ([`source`]: OpenSeeFace's UDP datagrams, lines on standard input, a file
//! replayed in real time), pass a bounded queue ([`Queue`]: when the solve falls behind,
//! the oldest frames are dropped and counted), are solved by the rig's causal path
//! ([`keyshape_rig::live::LiveSolver`]) and leave through the sinks ([`sink`]: VMC bundles
//! over OSC, Live Link Face UDP packets, CSV lines on standard output), optionally
//! recorded as they go ([`sink::Recorder`]).

pub mod latency;
pub mod openseeface;
pub mod protocols;
pub mod session;
pub mod sink;
pub mod source;

use std::collections::VecDeque;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Condvar, Mutex};
use std::time::{Duration, Instant};

/// The largest time, in seconds, a frame may carry: a Unix time stamp (OpenSeeFace's,
/// about 1.8e9) with room to spare, far below where a timecode's hours overflow.
pub const MAX_TIME_S: f64 = 1e11;

/// Why a frame cannot be solved, if it cannot: a coordinate out of the readers' range
/// (non-finite, beyond ±1e30) or a time that is not finite or beyond ±[`MAX_TIME_S`].
/// Every source's frames are checked by this before they are queued.
pub fn frame_problem(time: f64, points: &[f64]) -> Option<String> {
    if !(time.is_finite() && time.abs() <= MAX_TIME_S) {
        return Some(format!(
            "time {time:e} s is not a time stamp (finite, within ±{MAX_TIME_S:e} s)"
        ));
    }
    points.iter().enumerate().find_map(|(i, &v)| {
        keyshape_core::sequence::coord_problem(v)
            .map(|why| format!("landmark {} {}: {why}", i / 2, ["x", "y"][i % 2]))
    })
}

/// `HOST:PORT`, `PORT` or nothing (the default port), host `default_host`; ports 1–65535.
pub fn parse_address(
    rest: Option<&str>,
    default_host: &str,
    default_port: u16,
    what: &str,
) -> keyshape_core::error::Result<std::net::SocketAddr> {
    let rest = rest.map(str::trim).filter(|r| !r.is_empty());
    let (host, port) = match rest {
        None => (default_host.to_string(), default_port.to_string()),
        Some(r) => match r.rsplit_once(':') {
            Some((h, p)) => (h.trim_matches(['[', ']']).to_string(), p.to_string()),
            None if r.bytes().all(|b| b.is_ascii_digit()) => {
                (default_host.to_string(), r.to_string())
            }
            None => (r.to_string(), default_port.to_string()),
        },
    };
    let port: u16 = port.parse().ok().filter(|&p| p > 0).ok_or_else(|| {
        keyshape_core::error::Error::invalid(format!(
            "{what}: port '{port}' is not a port number (1–65535)"
        ))
    })?;
    std::net::ToSocketAddrs::to_socket_addrs(&(host.as_str(), port))
        .map_err(|e| keyshape_core::error::Error::invalid(format!("{what}: host '{host}': {e}")))?
        .next()
        .ok_or_else(|| {
            keyshape_core::error::Error::invalid(format!("{what}: host '{host}' has no address"))
        })
}

/// One frame of landmarks as a source delivers it.
#[derive(Debug, Clone, PartialEq)]
pub struct Frame {
    /// The frame's number: the file's frame number, or the count of frames received.
    pub number: i64,
    /// Its time stamp (seconds): the tracker's, the file's, or the time since the start.
    pub time: f64,
    /// x then y of each of the layout's points (image pixels, y down).
    pub points: Vec<f64>,
    /// Per point, the tracker's confidence in it, when the source says (OpenSeeFace, a
    /// take recorded from it).
    pub confidence: Option<Vec<f64>>,
    /// When it was received (for the latency).
    pub arrived: Instant,
    /// The source saw another face begin with this frame — a tracker restarted (a new
    /// sender), another image size — and says so: the session recalibrates.
    pub new_face: Option<String>,
}

/// What the receiving side counts (shared with the solving side).
#[derive(Debug, Default)]
pub struct Counters {
    /// Frames received.
    pub received: AtomicU64,
    /// Datagrams or lines skipped as malformed.
    pub malformed: AtomicU64,
    /// Frames dropped because the solve fell behind.
    pub dropped: AtomicU64,
    /// Faces a source sent beside the one it follows (OpenSeeFace's other face ids):
    /// counted, not solved.
    pub other_faces: AtomicU64,
    /// Frames the tracker marked as failed (OpenSeeFace's `success` 0, a table row marked
    /// untracked): skipped, so the avatar holds its last pose.
    pub untracked: AtomicU64,
}

impl Counters {
    /// (received, malformed, dropped).
    pub fn get(&self) -> (u64, u64, u64) {
        (
            self.received.load(Ordering::Relaxed),
            self.malformed.load(Ordering::Relaxed),
            self.dropped.load(Ordering::Relaxed),
        )
    }
}

/// What [`Queue::pop`] found.
#[derive(Debug)]
pub enum Popped {
    /// A frame.
    Frame(Frame),
    /// Nothing within the wait.
    Idle,
    /// The source has ended and every frame was taken.
    Closed,
}

/// A bounded queue of frames between the receiving thread and the solve. A live source
/// never waits: when the queue is full the oldest frame is dropped (and counted), so the
/// solve always works on the newest frames and the backlog never grows. A file source
/// waits instead (`blocking`): a file can be read at the solve's pace.
pub struct Queue {
    inner: Mutex<(VecDeque<Frame>, bool)>,
    ready: Condvar,
    room: Condvar,
    capacity: usize,
    blocking: bool,
}

impl Queue {
    /// A queue of at most `capacity` frames (≥ 1).
    pub fn new(capacity: usize, blocking: bool) -> Queue {
        Queue {
            inner: Mutex::new((VecDeque::with_capacity(capacity.max(1)), false)),
            ready: Condvar::new(),
            room: Condvar::new(),
            capacity: capacity.max(1),
            blocking,
        }
    }

    /// Adds a frame: drops the oldest when full (counted in `counters.dropped`), or, for a
    /// blocking queue, waits for room.
    pub fn push(&self, frame: Frame, counters: &Counters) {
        let Ok(mut g) = self.inner.lock() else {
            return;
        };
        if self.blocking {
            while g.0.len() >= self.capacity && !g.1 {
                g = match self.room.wait(g) {
                    Ok(g) => g,
                    Err(_) => return,
                };
            }
        }
        while g.0.len() >= self.capacity {
            g.0.pop_front();
            counters.dropped.fetch_add(1, Ordering::Relaxed);
        }
        g.0.push_back(frame);
        self.ready.notify_one();
    }

    /// The source has ended: the frames still queued are taken, then [`Popped::Closed`].
    pub fn close(&self) {
        if let Ok(mut g) = self.inner.lock() {
            g.1 = true;
        }
        self.ready.notify_all();
        self.room.notify_all();
    }

    /// The oldest frame, waiting up to `wait` for one.
    pub fn pop(&self, wait: Duration) -> Popped {
        let Ok(mut g) = self.inner.lock() else {
            return Popped::Closed;
        };
        let deadline = Instant::now() + wait;
        loop {
            if let Some(f) = g.0.pop_front() {
                self.room.notify_one();
                return Popped::Frame(f);
            }
            if g.1 {
                return Popped::Closed;
            }
            let left = deadline.saturating_duration_since(Instant::now());
            if left.is_zero() {
                return Popped::Idle;
            }
            g = match self.ready.wait_timeout(g, left) {
                Ok((g, _)) => g,
                Err(_) => return Popped::Closed,
            };
        }
    }
}

/// A warning that says itself at most once a second, with the count of the ones it held
/// back (a stream of malformed datagrams is one line a second, not thousands).
pub struct RateLimited {
    last: Option<Instant>,
    held: u64,
}

impl Default for RateLimited {
    fn default() -> Self {
        RateLimited::new()
    }
}

impl RateLimited {
    /// Nothing said yet.
    pub fn new() -> RateLimited {
        RateLimited {
            last: None,
            held: 0,
        }
    }

    /// The message to say now, if a second has passed since the last ("(and 41 more)"
    /// appended when some were held back), or None.
    pub fn say(&mut self, msg: &str) -> Option<String> {
        let now = Instant::now();
        match self.last {
            Some(t) if now.duration_since(t) < Duration::from_secs(1) => {
                self.held += 1;
                None
            }
            _ => {
                self.last = Some(now);
                let held = std::mem::take(&mut self.held);
                Some(if held > 0 {
                    format!("{msg} (and {held} more like it in the last second)")
                } else {
                    msg.to_string()
                })
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn frame(n: i64) -> Frame {
        Frame {
            number: n,
            time: n as f64,
            points: Vec::new(),
            confidence: None,
            arrived: Instant::now(),
            new_face: None,
        }
    }

    #[test]
    fn a_full_queue_drops_its_oldest_frames_and_counts_them() {
        let q = Queue::new(3, false);
        let c = Counters::default();
        for n in 0..10 {
            q.push(frame(n), &c);
        }
        assert_eq!(c.get().2, 7);
        let mut got = Vec::new();
        while let Popped::Frame(f) = q.pop(Duration::ZERO) {
            got.push(f.number);
        }
        assert_eq!(got, [7, 8, 9], "the newest frames are kept, in order");
        q.close();
        assert!(matches!(q.pop(Duration::ZERO), Popped::Closed));
    }

    #[test]
    fn a_blocking_queue_loses_nothing() {
        let q = std::sync::Arc::new(Queue::new(2, true));
        let c = std::sync::Arc::new(Counters::default());
        let (q2, c2) = (q.clone(), c.clone());
        let t = std::thread::spawn(move || {
            for n in 0..50 {
                q2.push(frame(n), &c2);
            }
            q2.close();
        });
        let mut got = Vec::new();
        loop {
            match q.pop(Duration::from_millis(100)) {
                Popped::Frame(f) => got.push(f.number),
                Popped::Idle => {}
                Popped::Closed => break,
            }
        }
        t.join().unwrap();
        assert_eq!(got, (0..50).collect::<Vec<_>>());
        assert_eq!(c.get().2, 0);
    }

    #[test]
    fn a_warning_repeats_at_most_once_a_second() {
        let mut w = RateLimited::new();
        assert_eq!(w.say("bad").as_deref(), Some("bad"));
        assert_eq!(w.say("bad"), None);
        assert_eq!(w.say("bad"), None);
        w.last = Some(Instant::now() - Duration::from_secs(2));
        assert_eq!(
            w.say("bad").as_deref(),
            Some("bad (and 2 more like it in the last second)")
        );
    }

    /// One check for every source's frames: a coordinate the readers would refuse, or a
    /// time no clock shows, makes the frame malformed; the bounds themselves pass.
    #[test]
    fn a_frame_out_of_range_is_named_and_its_bounds_pass() {
        let ok = [1.0, -2.0, 1e30, -1e30];
        assert_eq!(frame_problem(0.0, &ok), None);
        assert_eq!(frame_problem(MAX_TIME_S, &ok), None);
        assert_eq!(frame_problem(-MAX_TIME_S, &ok), None);
        for t in [f64::NAN, f64::INFINITY, 1e308, -1.01e11] {
            let why = frame_problem(t, &ok).unwrap();
            assert!(why.starts_with("time "), "{t}: {why}");
        }
        for (at, v) in [(0, 1.1e30), (3, -1e200), (2, f64::NAN)] {
            let mut p = ok;
            p[at] = v;
            let why = frame_problem(0.0, &p).unwrap();
            let xy = ["x", "y"][at % 2];
            assert!(
                why.starts_with(&format!("landmark {} {xy}: ", at / 2)),
                "{why}"
            );
        }
    }
}
