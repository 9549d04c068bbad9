//! Where the weights go: `vmc:[HOST:]PORT`, `livelink:[HOST:]PORT`, `stdout` — each a
//! [`Sink`] on a thread of its own behind a bounded hand-off, so a receiver or a reader
//! that stalls never stalls the solve — and the recording (`--record DIR`).

use super::source::parse_address;
use keyshape_core::error::{setting, Error, Result};
use keyshape_rig::Rig;
use std::io::Write;
use std::net::SocketAddr;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::mpsc::{sync_channel, SyncSender, TrySendError};
use std::sync::{Arc, Mutex};

mod outputs;
mod record;
pub use outputs::{LiveLinkSink, TableSink, VmcSink};
pub use record::{RecordedCalibration, Recorder};

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
pub(crate) fn weights_header(rig: &Rig) -> Vec<String> {
    std::iter::once("frame".to_string())
        .chain(rig.names.iter().cloned())
        .collect()
}

/// One CSV line (the weights tables' dialect).
pub(crate) fn csv_line(fields: impl IntoIterator<Item = String>) -> std::io::Result<Vec<u8>> {
    let mut w = keyshape_io::csv_out::record_writer(Vec::new());
    w.write_record(fields)
        .map_err(keyshape_io::csv_out::io_error)?;
    w.into_inner().map_err(|e| e.into_error())
}

pub(crate) fn weights_line(number: i64, w: &[f64]) -> std::io::Result<Vec<u8>> {
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
    /// A sink that falls behind holds the solve until it has taken the frame (a file
    /// replayed: nothing is lost), rather than missing the frame and counting it (a live
    /// source: the solve keeps the tracker's pace).
    pub wait: bool,
}

/// A typical humanoid's head bone above its neck (metres): what is sent as the head's local
/// position unless the user gives the avatar's own.
pub const HEAD_POSITION: [f32; 3] = [0.0, 0.1, 0.0];

impl Default for SinkOptions {
    fn default() -> Self {
        SinkOptions {
            mirror: false,
            head_position: Some(HEAD_POSITION),
            wait: false,
        }
    }
}

/// A solved frame as the sinks take it.
#[derive(Debug, Clone, PartialEq)]
pub struct Sent {
    /// The frame's number.
    pub number: i64,
    /// The weights, in the rig's shape order.
    pub weights: Vec<f64>,
    /// The head's yaw, pitch and roll relative to the calibration (radians).
    pub head: [f64; 3],
    /// The frame rate measured from the frames' arrivals ([`arrival_rate`]).
    pub fps: i32,
}

/// Where solved frames go. [`Sinks`] runs each on a thread of its own behind a bounded
/// hand-off; a new receiver is one more implementation.
pub trait Sink: Send {
    /// What messages call it (`vmc:127.0.0.1:39539`, `standard output`).
    fn name(&self) -> String;
    /// Whether it takes every frame (a table), or only the newest of frames that waited
    /// for a calibration (an avatar shows the newest pose).
    fn every_frame(&self) -> bool;
    /// Sends one frame. An error ends the session (a table whose reader went away); a
    /// refusal that is no reason to stop (a UDP receiver not there yet) is counted in
    /// [`Sink::refused`] instead.
    fn send(&mut self, f: &Sent) -> std::io::Result<()>;
    /// Frames the receiver refused so far.
    fn refused(&self) -> u64 {
        0
    }
}

/// Frames a sink's hand-off holds before it is behind.
pub const HAND_OFF: usize = 64;

/// What a sink's thread tells the solving side.
#[derive(Default)]
struct Shared {
    /// Why the sink stopped, once it has.
    failed: Mutex<Option<std::io::Error>>,
    /// Frames the receiver refused.
    refused: AtomicU64,
}

/// One sink on its thread.
struct HandOff {
    name: String,
    every_frame: bool,
    tx: Option<SyncSender<Arc<Sent>>>,
    thread: Option<std::thread::JoinHandle<()>>,
    shared: Arc<Shared>,
    /// Frames missed because the sink was behind (its hand-off full).
    behind: u64,
}

impl HandOff {
    fn start(mut sink: Box<dyn Sink>) -> HandOff {
        let (tx, rx) = sync_channel::<Arc<Sent>>(HAND_OFF);
        let shared = Arc::new(Shared::default());
        let (name, every_frame) = (sink.name(), sink.every_frame());
        let theirs = shared.clone();
        let thread = std::thread::Builder::new()
            .name(format!("kslab-sink {name}"))
            .spawn(move || {
                for f in rx {
                    let r = sink.send(&f);
                    theirs.refused.store(sink.refused(), Ordering::Relaxed);
                    if let Err(e) = r {
                        if let Ok(mut slot) = theirs.failed.lock() {
                            *slot = Some(e);
                        }
                        return;
                    }
                }
            })
            .ok();
        HandOff {
            name,
            every_frame,
            tx: Some(tx),
            thread,
            shared,
            behind: 0,
        }
    }

    /// The sink's failure, once (taken).
    fn failure(&self) -> Option<Error> {
        let e = self.shared.failed.lock().ok()?.take()?;
        Some(Error::io(&self.name, e))
    }

    /// Ends the thread once it has sent what it holds.
    fn close(&mut self) -> Option<Error> {
        self.tx = None;
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
        self.failure()
    }
}

/// The open sinks.
pub struct Sinks {
    outs: Vec<HandOff>,
    wait: bool,
    /// The frame rate before frames have come (the file's own, else 60).
    fps_hint: f64,
    /// The last frames' arrival instants, for the frame rate Live Link is told.
    arrivals: std::collections::VecDeque<std::time::Instant>,
    /// The Live Link device id: a UUID, as the app sends.
    device: String,
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
        let device = super::protocols::device_uuid(
            std::time::SystemTime::now()
                .duration_since(std::time::UNIX_EPOCH)
                .map_or(0, |d| d.as_nanos())
                ^ (u128::from(std::process::id()) << 96),
        );
        let mut sinks: Vec<Box<dyn Sink>> = Vec::new();
        let mut stdout = Some(stdout);
        for s in specs {
            sinks.push(match s {
                SinkSpec::Vmc(a) => Box::new(VmcSink::open(*a, rig, options)?),
                SinkSpec::LiveLink(a) => {
                    Box::new(LiveLinkSink::open(*a, rig, options, device.clone())?)
                }
                SinkSpec::Stdout => match stdout.take() {
                    Some(out) => Box::new(TableSink::new(out, rig)),
                    None => continue,
                },
            });
        }
        Ok(Sinks::with(sinks, fps, options.wait, device))
    }

    /// Sinks of the caller's own ([`Sink`]), each on its thread; `wait` as
    /// [`SinkOptions::wait`].
    pub fn with(sinks: Vec<Box<dyn Sink>>, fps: f64, wait: bool, device: String) -> Sinks {
        Sinks {
            outs: sinks.into_iter().map(HandOff::start).collect(),
            wait,
            fps_hint: fps,
            arrivals: std::collections::VecDeque::with_capacity(RATE_WINDOW),
            device,
        }
    }

    /// The frame rate Live Link is told: measured from the frames' arrivals (a tracker
    /// pacing itself to 22 a second says 22; a file replayed at `--rate 60` says 60), the
    /// hint until enough have come.
    pub fn fps(&self) -> i32 {
        arrival_rate(&self.arrivals)
            .unwrap_or_else(|| self.fps_hint.round().clamp(1.0, 1000.0) as i32)
    }

    /// The Live Link device id (a 36-character UUID).
    pub fn device(&self) -> &str {
        &self.device
    }

    /// Frames the receivers refused (datagrams the network would not take: no receiver
    /// yet, say): counted, never fatal.
    pub fn refused(&self) -> u64 {
        self.outs
            .iter()
            .map(|o| o.shared.refused.load(Ordering::Relaxed))
            .sum()
    }

    /// Frames missed because a sink was behind (its hand-off of [`HAND_OFF`] full; only
    /// without [`SinkOptions::wait`]).
    pub fn behind(&self) -> u64 {
        self.outs.iter().map(|o| o.behind).sum()
    }

    /// Hands one solved frame, which arrived at `arrived`, to every sink; a frame that is
    /// not the `newest` (one of several that waited for a calibration) goes only to the
    /// sinks that take every frame. An error is a sink that stopped (standard output's
    /// reader went away): the session ends.
    pub fn send(
        &mut self,
        number: i64,
        (w, head): (&[f64], [f64; 3]),
        arrived: std::time::Instant,
        newest: bool,
    ) -> Result<()> {
        if self.arrivals.len() == RATE_WINDOW {
            self.arrivals.pop_front();
        }
        self.arrivals.push_back(arrived);
        let f = Arc::new(Sent {
            number,
            weights: w.to_vec(),
            head,
            fps: self.fps(),
        });
        for o in &mut self.outs {
            if let Some(e) = o.failure() {
                return Err(e);
            }
            if !(newest || o.every_frame) {
                continue;
            }
            let Some(tx) = &o.tx else { continue };
            let gone = if self.wait {
                tx.send(f.clone()).is_err()
            } else {
                match tx.try_send(f.clone()) {
                    Ok(()) => false,
                    Err(TrySendError::Full(_)) => {
                        o.behind += 1;
                        false
                    }
                    Err(TrySendError::Disconnected(_)) => true,
                }
            };
            if gone {
                if let Some(t) = o.thread.take() {
                    let _ = t.join();
                }
                return Err(o.failure().unwrap_or_else(|| {
                    Error::invalid(format!("live: the sink {} stopped", o.name))
                }));
            }
        }
        Ok(())
    }

    /// Waits for every sink to send what it holds, and ends their threads; the first
    /// failure, if one stopped.
    pub fn close(&mut self) -> Result<()> {
        let mut first = None;
        for o in &mut self.outs {
            if let Some(e) = o.close() {
                first.get_or_insert(e);
            }
        }
        first.map_or(Ok(()), Err)
    }
}

impl Drop for Sinks {
    fn drop(&mut self) {
        let _ = self.close();
    }
}

#[cfg(test)]
mod tests {
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
}
