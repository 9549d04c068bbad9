//! One live session: frames from the queue through the causal solve to the sinks and the
//! recording, with the calibration and the latency kept.

use super::sink::{Recorder, Sinks};
use super::Frame;
use keyshape_core::error::{Error, Result};
use keyshape_rig::live::{Calibration, LiveFrame, LiveSolver};
use std::path::PathBuf;
use std::time::Instant;

/// What a frame did.
#[derive(Debug, Clone, PartialEq)]
pub enum Step {
    /// Collected towards the calibration (frames so far, frames needed).
    Collecting(usize, usize),
    /// The calibration completed: the lead-in's frames were solved and sent.
    Calibrated(usize),
    /// Solved and sent.
    Solved,
}

/// The session.
pub struct Session {
    /// The solve.
    pub solver: LiveSolver,
    sinks: Sinks,
    recorder: Option<Recorder>,
    /// Where a new calibration is saved (JSON), if anywhere.
    pub save_calibration: Option<PathBuf>,
    /// The lead-in's frames, waiting for the calibration.
    waiting: Vec<Frame>,
    /// Per frame solved on arrival, milliseconds from its arrival to its sending (the
    /// whole session's distribution and the last frames', in bounded memory).
    pub latencies: super::latency::Latencies,
    /// Frames solved and sent.
    pub solved: u64,
    /// Frames the solve refused (a degenerate frame).
    pub refused: u64,
    /// The last frame solved, with its input.
    pub last: Option<(Frame, LiveFrame)>,
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
    /// of the source).
    pub fn new(
        solver: LiveSolver,
        sinks: Sinks,
        recorder: Option<Recorder>,
        select: Vec<usize>,
    ) -> Session {
        Session {
            select,
            solver,
            sinks,
            recorder,
            save_calibration: None,
            waiting: Vec::new(),
            latencies: super::latency::Latencies::new(),
            solved: 0,
            refused: 0,
            last: None,
            last_iod: None,
            notices: Vec::new(),
            last_taken: Vec::new(),
            taken: 0,
        }
    }

    /// Per rig landmark, the source point it reads.
    pub fn selection(&self) -> &[usize] {
        &self.select
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
        self.sinks.send_errors
    }

    /// The next frames are the person's neutral again.
    pub fn recalibrate(&mut self) {
        self.solver.recalibrate();
        self.waiting.clear();
    }

    /// Uses a saved calibration.
    pub fn set_calibration(&mut self, c: Calibration) -> Result<()> {
        self.solver.set_calibration(c)?;
        self.waiting.clear();
        Ok(())
    }

    /// Ends the session: a recording that holds no frame is removed (nothing was taken).
    pub fn finish(&mut self) -> Result<()> {
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

    /// Takes one frame. A frame the solve refuses is counted in `refused` and changes
    /// nothing; an error is a sink or the recording that failed (the session ends).
    pub fn take(&mut self, frame: Frame) -> Result<Step> {
        // A frame too short for the rig's points (the source guarantees its layout, so
        // only a library caller's mistake) is refused like a degenerate one.
        if self.select.iter().any(|&p| 2 * p + 1 >= frame.points.len()) {
            self.refused += 1;
            return Ok(match self.solver.calibration() {
                Some(_) => Step::Solved,
                None => {
                    let (have, need) = self.solver.collected();
                    Step::Collecting(have, need)
                }
            });
        }
        let chosen: Vec<f64> = self
            .select
            .iter()
            .flat_map(|&p| [frame.points[2 * p], frame.points[2 * p + 1]])
            .collect();
        self.last_taken.clone_from(&chosen);
        self.taken += 1;
        // Another face: the calibration was the last one's.
        let jump = self.face_jump(&chosen);
        if let Some(why) = frame.new_face.clone().or(jump) {
            let had = self.solver.calibration().is_some() || !self.waiting.is_empty();
            if had {
                self.recalibrate();
                let (_, need) = self.solver.collected();
                self.notices.push(format!(
                    "{why}: recalibrating on the next {need} frames (look neutral)"
                ));
            }
        }
        let was_calibrated = self.solver.calibration().is_some();
        let solved = match self.solver.push(&chosen) {
            Ok(v) => v,
            Err(_) => {
                // Refused: the solver's state is as it was.
                self.refused += 1;
                if was_calibrated {
                    return Ok(Step::Solved);
                }
                let (have, need) = self.solver.collected();
                return Ok(Step::Collecting(have, need));
            }
        };
        if solved.is_empty() {
            // Collected; a lead-in the calibration could not use slid on by its oldest
            // frame, which leaves here too.
            self.waiting.push(frame);
            let (have, need) = self.solver.collected();
            let drop = self.waiting.len().saturating_sub(have);
            self.waiting.drain(..drop);
            return Ok(Step::Collecting(have, need));
        }
        let calibrated = !was_calibrated;
        let mut frames = std::mem::take(&mut self.waiting);
        frames.push(frame);
        if frames.len() != solved.len() {
            return Err(Error::invalid(format!(
                "live: {} frames solved for {} taken",
                solved.len(),
                frames.len()
            )));
        }
        if calibrated {
            if let (Some(p), Some(c)) = (&self.save_calibration, self.solver.calibration()) {
                let c = c.clone();
                keyshape_io::write_atomic(p, |w| {
                    serde_json::to_writer_pretty(&mut *w, &c).map_err(std::io::Error::other)?;
                    w.write_all(b"\n")
                })?;
            }
        }
        let n = solved.len();
        for (f, s) in frames.into_iter().zip(solved) {
            let head = s.head;
            self.sinks
                .send(f.number, &s.weights, head, f.arrived)
                .map_err(|e| Error::io("standard output", e))?;
            if let Some(r) = &mut self.recorder {
                r.record(f.number, f.time, &f.points, &s.weights, head)?;
            }
            if !calibrated {
                self.latencies
                    .record(Instant::now().duration_since(f.arrived).as_secs_f64() * 1e3);
            }
            self.solved += 1;
            self.last = Some((f, s));
        }
        Ok(if calibrated {
            Step::Calibrated(n)
        } else {
            Step::Solved
        })
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
