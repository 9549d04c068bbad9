//! One live session: frames from the queue through the causal solve to the sinks and the
//! recording, with the calibration and the latency kept.

use super::sink::{RecordedCalibration, Recorder, Sinks};
use super::Frame;
use keyshape_core::error::{Error, Result};
use keyshape_rig::live::{
    Calibration, CalibrationDone, CalibrationEvent, LiveFrame, LiveSolver, Observation,
};
use std::collections::VecDeque;
use std::path::PathBuf;
use std::time::Instant;

/// What a frame did.
#[derive(Debug, Clone, PartialEq)]
pub enum Step {
    /// Collected towards the calibration (frames so far, frames needed); during a
    /// recalibration the frame was also solved with the old calibration and sent.
    Collecting(usize, usize),
    /// A calibration was taken into use; this many frames waited for it and were solved and
    /// sent (the lead-in and the frames held while it was made, or none: a recalibration
    /// solves with the old calibration meanwhile).
    Calibrated(usize),
    /// Solved and sent.
    Solved,
}

/// What [`Session::serve`] did.
#[derive(Debug, Clone, PartialEq)]
pub enum Served {
    /// A frame was taken.
    Took(Step),
    /// No frame came, but a calibration made meanwhile was taken into use (this many
    /// frames had waited for it).
    Calibrated(usize),
    /// No frame came within the wait.
    Idle,
    /// The source has ended and every frame was taken.
    Closed,
}

/// Frames the solve took and has not yet solved, kept while they wait (the lead-in, the
/// frames held while the calibration is made) and their numbers a while longer, so a
/// calibration's lead-in can be named in the take.
const NUMBERS_KEPT: usize = 4096;

/// The session.
pub struct Session {
    /// The solve.
    solver: LiveSolver,
    sinks: Sinks,
    recorder: Option<Recorder>,
    /// Where a new calibration is saved (JSON), if anywhere.
    save_calibration: Option<PathBuf>,
    /// The frames taken and not yet solved, by the solver's frame index.
    waiting: VecDeque<(u64, Frame)>,
    /// The frame numbers of the last frames taken, by index.
    numbers: VecDeque<(u64, i64)>,
    /// The next frame's index (the solver's count of frames taken).
    next_index: u64,
    /// The calibration being made on another thread.
    job: Option<std::thread::JoinHandle<CalibrationDone>>,
    /// Calibrations taken into use whose first frame is not yet recorded.
    events: Vec<CalibrationEvent>,
    /// Per frame sent, milliseconds from its arrival to its hand-off to the sinks (the
    /// whole session's distribution and the last frames', in bounded memory).
    latencies: super::latency::Latencies,
    /// Frames solved and sent.
    solved: u64,
    /// Frames the solve refused (a degenerate frame).
    refused: u64,
    /// The last frame solved, with its input.
    last: Option<(Frame, LiveFrame)>,
    /// When the frames of the last second were taken (the rate), and the last one.
    window: VecDeque<Instant>,
    /// Per rig landmark, the source point it reads.
    select: Vec<usize>,
    /// The last frame's eye-corner distance (source units), to see another face begin.
    last_iod: Option<f64>,
    /// What the session did that the terminal should say (a recalibration on a new face).
    notices: Vec<String>,
    /// The last frame taken (solved or collected), the rig's landmarks of it (x then y).
    last_taken: Vec<f64>,
    /// Frames taken so far.
    taken: u64,
}

/// A face whose eye-corner distance changes by more than this factor from one frame to the
/// next is another face (a tracker restarted on another person, or at another distance).
pub const FACE_JUMP: f64 = 1.6;

impl Session {
    /// A session solving with `solver` into `sinks`, recording into `recorder`; `select`
    /// names, per rig landmark, the source point it reads (the recording keeps every point
    /// of the source). Calibrations are made on a thread of their own, so frames keep
    /// flowing meanwhile.
    pub fn new(
        mut solver: LiveSolver,
        sinks: Sinks,
        recorder: Option<Recorder>,
        select: Vec<usize>,
    ) -> Session {
        solver.set_background(true);
        let mut s = Session {
            select,
            solver,
            sinks,
            recorder,
            save_calibration: None,
            waiting: VecDeque::new(),
            numbers: VecDeque::new(),
            next_index: 0,
            job: None,
            events: Vec::new(),
            latencies: super::latency::Latencies::new(),
            solved: 0,
            refused: 0,
            last: None,
            window: VecDeque::new(),
            last_iod: None,
            notices: Vec::new(),
            last_taken: Vec::new(),
            taken: 0,
        };
        s.events = s.solver.take_events();
        s
    }

    /// Per rig landmark, the source point it reads.
    pub fn selection(&self) -> &[usize] {
        &self.select
    }

    /// The solve (its rig, calibration, λ).
    pub fn solver(&self) -> &LiveSolver {
        &self.solver
    }

    /// The causal temporal prior's λ from now on (see [`LiveSolver::set_smooth`]).
    pub fn set_smooth(&mut self, lambda: f64) -> Result<()> {
        self.solver.set_smooth(lambda)
    }

    /// Saves each calibration made from now on to `path` (JSON, written whole).
    pub fn save_calibrations_to(&mut self, path: Option<PathBuf>) {
        self.save_calibration = path;
    }

    /// Where calibrations are saved, if anywhere.
    pub fn saves_calibrations_to(&self) -> Option<&std::path::Path> {
        self.save_calibration.as_deref()
    }

    /// The latencies from arrival to the sinks' hand-off (milliseconds).
    pub fn latencies(&self) -> &super::latency::Latencies {
        &self.latencies
    }

    /// The last frames' latency (milliseconds, arrival to the sinks): p50 and p99.
    pub fn recent_latency(&self) -> (Option<f64>, Option<f64>) {
        let recent: Vec<f64> = self.latencies.recent().iter().copied().collect();
        (quantile(&recent, 0.5), quantile(&recent, 0.99))
    }

    /// Frames solved and sent.
    pub fn solved(&self) -> u64 {
        self.solved
    }

    /// Frames the solve refused.
    pub fn refused(&self) -> u64 {
        self.refused
    }

    /// The last frame solved, with its input.
    pub fn last(&self) -> Option<&(Frame, LiveFrame)> {
        self.last.as_ref()
    }

    /// Frames taken in the last second.
    pub fn rate(&mut self) -> usize {
        while self
            .window
            .front()
            .is_some_and(|t| t.elapsed() > std::time::Duration::from_secs(1))
        {
            self.window.pop_front();
        }
        self.window.len()
    }

    /// Takes the next frame from `queue` (waiting up to `wait` for one) through the
    /// session; while none comes, a calibration made meanwhile is taken into use. What the
    /// command line and the lab both run, a call at a time.
    pub fn serve(&mut self, queue: &super::Queue, wait: std::time::Duration) -> Result<Served> {
        Ok(match queue.pop(wait) {
            super::Popped::Closed => Served::Closed,
            super::Popped::Idle => match self.poll()? {
                Some(n) => Served::Calibrated(n),
                None => Served::Idle,
            },
            super::Popped::Frame(f) => {
                let step = self.take(f)?;
                self.window.push_back(Instant::now());
                Served::Took(step)
            }
        })
    }

    /// What looked wrong with the lead-in of the calibration in use (the head turned, the
    /// lips parted), if anything.
    pub fn calibration_warning(&self) -> Option<&str> {
        self.solver.calibration_warning()
    }

    /// Why the last full lead-in could not be calibrated on, while collecting.
    pub fn lead_in_failure(&self) -> Option<&str> {
        self.solver.lead_in_failure()
    }

    /// Datagrams the network would not take.
    pub fn send_errors(&self) -> u64 {
        self.sinks.refused()
    }

    /// Frames a sink missed because it was behind (its hand-off full).
    pub fn sinks_behind(&self) -> u64 {
        self.sinks.behind()
    }

    /// The next frames are the person's neutral again; the calibration in use solves them
    /// meanwhile (the avatar keeps moving).
    pub fn recalibrate(&mut self) {
        self.restart(true);
    }

    /// A new calibration: `same_face` keeps solving with the old one meanwhile.
    fn restart(&mut self, same_face: bool) {
        self.solver.recalibrate(same_face);
        self.job = None;
        self.waiting.clear();
    }

    /// Uses a saved calibration.
    pub fn set_calibration(&mut self, c: Calibration) -> Result<()> {
        self.solver.set_calibration(c)?;
        self.job = None;
        self.waiting.clear();
        self.events.extend(self.solver.take_events());
        Ok(())
    }

    /// Ends the session: waits for a calibration being made (its frames are sent and
    /// recorded); a recording that holds no frame is removed (nothing was taken).
    pub fn finish(&mut self) -> Result<()> {
        if let Some(h) = self.job.take() {
            let done = h
                .join()
                .map_err(|_| Error::invalid("live: the calibration's thread panicked"))?;
            self.install(done)?;
        }
        // Every sink sends what it holds (standard output whole) before the session ends.
        self.sinks.close()?;
        match self.recorder.take() {
            Some(r) if self.solved == 0 => r.remove(),
            _ => Ok(()),
        }
    }

    /// The last frame taken — solved, or collected towards the calibration — as the rig's
    /// landmarks (x then y, image axes), and how many frames have been taken: what a screen
    /// draws while the person is told to look neutral.
    pub fn last_taken(&self) -> (&[f64], u64) {
        (&self.last_taken, self.taken)
    }

    /// What happened that the terminal should say (drained).
    pub fn notices(&mut self) -> Vec<String> {
        std::mem::take(&mut self.notices)
    }

    /// Why `chosen` (the rig's landmarks of a frame) begins another face, if it does: its
    /// eye-corner distance [`FACE_JUMP`] times the last frame's, or less by as much.
    fn face_jump(&mut self, chosen: &[f64]) -> Option<String> {
        let [a, b] = self.solver.rig().eyes()?;
        let iod = (chosen[2 * a] - chosen[2 * b]).hypot(chosen[2 * a + 1] - chosen[2 * b + 1]);
        let last = self.last_iod.replace(iod)?;
        let ratio = iod / last;
        (!(1.0 / FACE_JUMP..=FACE_JUMP).contains(&ratio)).then(|| {
            format!("the face's eye corners jumped from {last:.1} to {iod:.1} apart: another face")
        })
    }

    /// Collecting (a lead-in, or a recalibration's while the old calibration solves), or
    /// solved.
    fn step_now(&self) -> Step {
        if self.solver.calibrating() {
            let (have, need) = self.solver.collected();
            Step::Collecting(have, need)
        } else {
            Step::Solved
        }
    }

    /// Takes a calibration made on its thread into use, when it is ready: its waiting
    /// frames solved, sent and recorded. Call it between frames too (a session idle on
    /// its source). `Some(frames sent)` when one was taken into use.
    pub fn poll(&mut self) -> Result<Option<usize>> {
        if let Some(job) = self.solver.take_job() {
            self.job = Some(std::thread::spawn(move || job.run()));
        }
        if !self.job.as_ref().is_some_and(|h| h.is_finished()) {
            return Ok(None);
        }
        let Some(h) = self.job.take() else {
            return Ok(None);
        };
        let done = h
            .join()
            .map_err(|_| Error::invalid("live: the calibration's thread panicked"))?;
        self.install(done)
    }

    /// Takes a finished calibration into use (see [`Session::poll`]).
    fn install(&mut self, done: CalibrationDone) -> Result<Option<usize>> {
        let out = self.solver.install(done);
        let calibrated = self.solver.take_events();
        if calibrated.is_empty() {
            return Ok(None); // the lead-in slid on (or the job was stale)
        }
        let n = out.len();
        self.events.extend(calibrated);
        self.emit(out)?;
        if let (Some(p), Some(c)) = (&self.save_calibration, self.solver.calibration()) {
            let c = c.clone();
            keyshape_io::write_atomic(p, |w| {
                serde_json::to_writer_pretty(&mut *w, &c).map_err(std::io::Error::other)?;
                w.write_all(b"\n")
            })?;
        }
        Ok(Some(n))
    }

    /// Takes one frame. A frame the solve refuses is counted in `refused` and changes
    /// nothing; an error is a sink or the recording that failed (the session ends).
    pub fn take(&mut self, frame: Frame) -> Result<Step> {
        let done = self.poll()?;
        // A frame too short for the rig's points (the source guarantees its layout, so
        // only a library caller's mistake) is refused like a degenerate one.
        if self.select.iter().any(|&p| 2 * p + 1 >= frame.points.len()) {
            self.refused += 1;
            return Ok(self.step_now());
        }
        let chosen: Vec<f64> = self
            .select
            .iter()
            .flat_map(|&p| [frame.points[2 * p], frame.points[2 * p + 1]])
            .collect();
        let confidence = frame.confidence.as_ref().and_then(|c| {
            self.select
                .iter()
                .map(|&p| c.get(p).copied())
                .collect::<Option<Vec<f64>>>()
        });
        self.last_taken.clone_from(&chosen);
        self.taken += 1;
        // Another face: the calibration was the last one's.
        let jump = self.face_jump(&chosen);
        if let Some(why) = frame.new_face.clone().or(jump) {
            if self.solver.calibration().is_some()
                || self.solver.calibrating() && self.next_index > 0
            {
                self.restart(false);
                let (_, need) = self.solver.collected();
                self.notices.push(format!(
                    "{why}: recalibrating on the next {need} frames (look neutral)"
                ));
            }
        }
        let obs = Observation {
            points: chosen,
            confidence,
            time: Some(frame.time),
        };
        let out = match self.solver.push_observed(obs) {
            Ok(v) => v,
            Err(_) => {
                // Refused: the solver's state is as it was.
                self.refused += 1;
                return Ok(self.step_now());
            }
        };
        let index = self.next_index;
        self.next_index += 1;
        self.numbers.push_back((index, frame.number));
        if self.numbers.len() > NUMBERS_KEPT {
            self.numbers.pop_front();
        }
        self.waiting.push_back((index, frame));
        self.events.extend(self.solver.take_events());
        self.emit(out)?;
        let later = self.poll()?;
        Ok(match done.or(later) {
            Some(k) => Step::Calibrated(k),
            None => self.step_now(),
        })
    }

    /// The frame number of frame index `i`, while it is kept.
    fn number_of(&self, i: u64) -> Option<i64> {
        self.numbers.iter().find(|(j, _)| *j == i).map(|(_, n)| *n)
    }

    /// Records the solved frames `out` (their inputs waiting here), each calibration
    /// recorded before the first frame it solves, and sends the newest: frames that waited
    /// for a calibration are recorded, not sent in a burst (a receiver shows the newest).
    fn emit(&mut self, out: Vec<LiveFrame>) -> Result<()> {
        let newest = out.len().saturating_sub(1);
        for (k, s) in out.into_iter().enumerate() {
            // Frames before it that were never solved (a lead-in that slid on) leave.
            while self.waiting.front().is_some_and(|(i, _)| *i < s.index) {
                self.waiting.pop_front();
            }
            let Some((_, f)) = self.waiting.pop_front() else {
                return Err(Error::invalid(format!(
                    "live: frame index {} solved but not taken",
                    s.index
                )));
            };
            self.record_events(s.index, f.number)?;
            let head = s.head;
            self.sinks
                .send(f.number, (&s.weights, head), f.arrived, k == newest)?;
            if k == newest {
                self.latencies
                    .record(Instant::now().duration_since(f.arrived).as_secs_f64() * 1e3);
            }
            if let Some(r) = &mut self.recorder {
                r.record(
                    f.number,
                    f.time,
                    (&f.points, f.confidence.as_deref()),
                    &s.weights,
                    head,
                )?;
            }
            self.solved += 1;
            self.last = Some((f, s));
        }
        Ok(())
    }

    /// Records the calibrations that take effect by frame index `i` (number `number`).
    fn record_events(&mut self, i: u64, number: i64) -> Result<()> {
        let due: Vec<CalibrationEvent> = {
            let (now, later): (Vec<_>, Vec<_>) = std::mem::take(&mut self.events)
                .into_iter()
                .partition(|e| e.from <= i);
            self.events = later;
            now
        };
        for e in due {
            let lead_in = e.lead_in.map(|[a, b]| {
                [
                    self.number_of(a).unwrap_or(number),
                    self.number_of(b).unwrap_or(number),
                ]
            });
            if let Some(r) = &mut self.recorder {
                r.calibration(&RecordedCalibration {
                    from: number,
                    lead_in,
                    calibration: e.calibration,
                })?;
            }
        }
        Ok(())
    }
}

/// The `q`-quantile (0–1) of `v` (nearest rank), or None when empty.
pub fn quantile(v: &[f64], q: f64) -> Option<f64> {
    if v.is_empty() {
        return None;
    }
    let mut s = v.to_vec();
    s.sort_by(f64::total_cmp);
    let i = ((q * s.len() as f64).ceil() as usize).clamp(1, s.len()) - 1;
    Some(s[i])
}

#[cfg(test)]
mod tests {
    #[test]
    fn quantiles_by_nearest_rank() {
        let v: Vec<f64> = (1..=100).map(f64::from).collect();
        assert_eq!(super::quantile(&v, 0.5), Some(50.0));
        assert_eq!(super::quantile(&v, 0.99), Some(99.0));
        assert_eq!(super::quantile(&[], 0.5), None);
        assert_eq!(super::quantile(&[3.0], 0.99), Some(3.0));
    }
}
