//! The last pass of a streamed solve: frames solved a chunk at a time, exactly as the
//! in-memory solve chunks them.

use super::{FrameWeights, StreamOptions};
use keyshape_core::error::{Error, Result};
use keyshape_core::solve::temporal::CausalShared;
use keyshape_core::solve::{residuals, solve_batch};
use nalgebra::DMatrix;

/// The last pass's solver: each chunk of frames solved as the in-memory solve chunks them
/// (with the causal prior carried across chunks, restarted at a new segment), its weights
/// handed on, and the summary's sums kept.
pub(super) struct Chunks<'a> {
    s: &'a DMatrix<f64>,
    st: DMatrix<f64>,
    opts: &'a StreamOptions,
    causal: Option<&'a CausalShared>,
    state: Option<keyshape_core::solve::temporal::CausalState>,
    /// The step between frame numbers within a segment.
    step: i64,
    points: usize,
    /// The last frame solved and its segment label.
    last: Option<(i64, Option<String>)>,
    wbuf: Vec<f64>,
    pub(super) unconverged: usize,
    pub(super) total: f64,
    pub(super) rms_sum: f64,
    pub(super) wmax: f64,
}

impl<'a> Chunks<'a> {
    /// A solver for the key shapes `s`, the causal prior when there is one, segments of
    /// frame step `step` (1 when unknown), errors per point over `points`.
    pub(super) fn new(
        s: &'a DMatrix<f64>,
        opts: &'a StreamOptions,
        causal: Option<&'a CausalShared>,
        step: Option<i64>,
        points: usize,
    ) -> Self {
        Chunks {
            s,
            st: s.transpose(),
            opts,
            causal,
            state: causal.map(|c| c.start()),
            step: step.unwrap_or(1),
            points,
            last: None,
            wbuf: vec![0.0; s.ncols()],
            unconverged: 0,
            total: 0.0,
            rms_sum: 0.0,
            wmax: 0.0,
        }
    }

    /// Solves the `frames.len()` frames at the front of `chunk` and hands each frame's
    /// weights to `sink`; non-finite weights or errors stop the stream, naming the frame.
    pub(super) fn flush(
        &mut self,
        chunk: &DMatrix<f64>,
        frames: &[i64],
        labels: &[Option<String>],
        sink: &mut dyn FnMut(FrameWeights<'_>) -> Result<()>,
    ) -> Result<()> {
        let m = frames.len();
        let q = chunk.columns(0, m).clone_owned();
        let mut sol = solve_batch(self.s, &q, &self.opts.solve)?;
        if let (Some(cs), Some(stt)) = (self.causal, self.state.as_mut()) {
            let b = &self.st * &q;
            for t in 0..m {
                let here = (frames[t], labels[t].clone());
                let new_segment = match self.last.as_ref() {
                    None => false,
                    Some((f, l)) => *l != here.1 || frames[t] - f != self.step,
                };
                if new_segment {
                    *stt = cs.start();
                }
                let before = stt.unconverged;
                cs.step(stt, b.column(t).as_slice(), &mut self.wbuf);
                self.unconverged += stt.unconverged - before;
                sol.weights.column_mut(t).copy_from_slice(&self.wbuf);
                self.last = Some(here);
            }
        } else {
            self.unconverged += sol.unconverged;
        }
        let err = residuals(self.s, &sol.weights, &q);
        for t in 0..m {
            let w = sol.weights.column(t);
            if !err[t].is_finite() || w.iter().any(|x| !x.is_finite()) {
                return Err(Error::unfit(format!(
                    "the solve gave non-finite weights or error at frame {} (coordinates too large or degenerate key shapes); nothing written",
                    frames[t]
                )));
            }
            self.total += err[t];
            let rms = (err[t] / self.points as f64).sqrt();
            self.rms_sum += rms;
            self.wmax = w.iter().fold(self.wmax, |m, x| m.max(x.abs()));
            sink(FrameWeights {
                frame: frames[t],
                rms,
                weights: w.as_slice(),
            })?;
        }
        Ok(())
    }
}
