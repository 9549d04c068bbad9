//! The sources that read text or a file: a CSV table on standard input, JSON lines, a
//! file replayed at its own rate; and the check every frame's confidences pass.

use super::{frame_problem, json_points, Frame, Run};
use std::io::{BufRead, Read};
use std::sync::atomic::Ordering;
use std::time::{Duration, Instant};

/// What is wrong with a frame's per-point confidences, if anything: one per point, each
/// finite and ≥ 0.
pub(super) fn confidence_problem(c: &[f64], points: usize) -> Option<String> {
    if c.len() != points {
        return Some(format!("{} confidences for {points} points", c.len()));
    }
    c.iter()
        .enumerate()
        .find(|(_, v)| !(v.is_finite() && **v >= 0.0))
        .map(|(i, v)| format!("point {i}'s confidence is {v}: a confidence is finite and ≥ 0"))
}

impl Run<'_> {
    pub(super) fn table(&mut self, mut rows: keyshape_io::table::TableRows<Box<dyn Read + Send>>) {
        let mut errors_in_a_row = 0;
        while !self.stopped() {
            let next = rows.next_row();
            let arrived = Instant::now();
            match next {
                Ok(None) => return,
                Ok(Some(r)) => {
                    errors_in_a_row = 0;
                    if !r.tracked {
                        let frame = r.frame;
                        self.untracked(&format!(
                            "stdin: frame {frame} is marked untracked: skipped, the avatar holds its pose"
                        ));
                        continue;
                    }
                    let (number, time, coords) = (r.frame, r.time, r.coords.to_vec());
                    let time = time.unwrap_or(self.start.elapsed().as_secs_f64());
                    let confidence = (!r.confidence.is_empty()).then(|| r.confidence.to_vec());
                    self.deliver(number, time, (coords, confidence), arrived);
                }
                Err(e) => {
                    self.malformed(&format!("skipped a line: {e}"));
                    errors_in_a_row += 1;
                    if errors_in_a_row > 1000 {
                        (self.warn)("stdin: 1000 bad lines in a row; reading stops".into());
                        return;
                    }
                }
            }
        }
    }

    pub(super) fn json_lines(&mut self, mut r: Box<dyn BufRead + Send>, first: String) {
        let mut line = first.into_bytes();
        let mut n = 0i64;
        let mut line_no = 1u64;
        let mut arrived = Instant::now();
        loop {
            if self.stopped() {
                return;
            }
            match std::str::from_utf8(&line) {
                Err(_) => self.malformed(&format!("stdin line {line_no}: not UTF-8 text")),
                Ok(text) if text.trim().is_empty() => {}
                Ok(text) => match json_points(text) {
                    Ok((t, pts)) if pts.len() == 2 * self.layout => {
                        let t = t.unwrap_or(self.start.elapsed().as_secs_f64());
                        if self.deliver(n, t, (pts, None), arrived) {
                            n += 1;
                        }
                    }
                    Ok((_, pts)) => self.malformed(&format!(
                        "stdin line {line_no}: {} points, the stream has {}",
                        pts.len() / 2,
                        self.layout
                    )),
                    Err(e) => self.malformed(&format!("stdin line {line_no}: {e}")),
                },
            }
            line_no += 1;
            let read =
                keyshape_io::read_line_capped(&mut *r, &mut line, keyshape_io::MAX_LINE_BYTES);
            arrived = Instant::now();
            match read {
                Ok(keyshape_io::Line::End) => return,
                Ok(keyshape_io::Line::Read(_)) => {}
                Ok(keyshape_io::Line::TooLong) => {
                    self.malformed(&format!(
                        "stdin line {line_no}: longer than {} bytes",
                        keyshape_io::MAX_LINE_BYTES
                    ));
                    line.clear();
                }
                Err(e) => {
                    (self.warn)(format!("stdin: {e}"));
                    return;
                }
            }
        }
    }

    pub(super) fn file(&mut self, seq: &keyshape_core::sequence::Sequence, rate: f64) {
        let period = Duration::from_secs_f64(1.0 / rate);
        for c in 0..seq.n_frames() {
            if self.stopped() {
                return;
            }
            let due = self.start + period.mul_f64(c as f64);
            let now = Instant::now();
            if due > now {
                std::thread::sleep(due - now);
            }
            let time = seq.times.as_ref().map_or(c as f64 / rate, |t| t[c]);
            let points: Vec<f64> = seq.coords.column(c).iter().copied().collect();
            // (The image size was applied when the file was read.)
            if let Some(why) = frame_problem(time, &points) {
                self.malformed(&format!("frame {}: {why}", seq.frames[c]));
                continue;
            }
            self.counters.received.fetch_add(1, Ordering::Relaxed);
            self.queue.push(
                Frame {
                    number: seq.frames[c],
                    time,
                    points,
                    confidence: seq
                        .confidence
                        .as_ref()
                        .map(|m| m.column(c).iter().copied().collect()),
                    arrived: Instant::now(),
                    new_face: None,
                },
                self.counters,
            );
        }
    }
}
