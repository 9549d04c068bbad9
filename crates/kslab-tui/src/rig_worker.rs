//! The rig view's own worker thread: the track solved onto the lab's `--rig` in the
//! background, so the lab opens and the key-shape view answers while the rig solves (the
//! neutral search and the frames take seconds on a long 468-point track). Each step is
//! named to the screen as it starts ([`Action::RigStep`]); a new λ reuses the neutral of
//! the last solve of the same track, so `l` skips the search. A newly loaded track's first
//! frame is previewed before the take's solve ([`Action::RigPreview`]): solved alone, its
//! neutral searched on the 68-point view, in a fraction of the take's time.

use super::rig::{prepare_with_search, rig_preview, rig_view_prepared, RigView};
use super::Action;
use keyshape_core::sequence::Sequence;
use keyshape_rig::correspondence::RigSource;
use std::sync::mpsc::{channel, Receiver, Sender};
use std::sync::Arc;

/// The rig worker thread's name (the lab's panic hook leaves the terminal alone there too).
pub const RIG_THREAD: &str = "kslab-rig";

/// A job for the rig worker.
#[derive(Debug, Clone)]
pub enum RigJob {
    /// Solve this track (the request that loaded it), λ 0: answered by
    /// [`Action::RigSolved`].
    Load(u64, Arc<Sequence>),
    /// Solve the current track again with the offline temporal prior λ (the request that
    /// asked): answered by [`Action::RigSmoothed`].
    Smooth(u64, f64),
}

/// What one round of the worker does after draining its queue: the newest load (if any)
/// replaces the track, the newest λ after it applies.
#[derive(Debug, Clone, PartialEq)]
pub struct Round {
    /// The request to answer, and whether it is a load (RigSolved) or a λ (RigSmoothed).
    pub reply: (u64, bool),
    /// The λ to solve with.
    pub smooth: f64,
}

/// Folds a drained queue into one round: a load resets λ to 0 (as the key-shape worker
/// does), a λ after it applies to it, and older jobs are dropped. `None` for an empty
/// queue.
pub fn fold(jobs: &[RigJob]) -> Option<Round> {
    let mut round: Option<Round> = None;
    for j in jobs {
        round = Some(match (j, round) {
            (RigJob::Load(id, _), _) => Round {
                reply: (*id, true),
                smooth: 0.0,
            },
            // A λ after a load in the same queue: the load's answer, with that λ.
            (
                RigJob::Smooth(_, l),
                Some(Round {
                    reply: (id, true), ..
                }),
            ) => Round {
                reply: (id, true),
                smooth: *l,
            },
            (RigJob::Smooth(id, l), _) => Round {
                reply: (*id, false),
                smooth: *l,
            },
        });
    }
    round
}

/// Starts the rig worker for `rig`, solving `first` (request 0) at once; results go to `out`.
pub fn spawn(rig: Arc<RigSource>, first: Arc<Sequence>, out: Sender<Action>) -> Sender<RigJob> {
    let (tx, rx) = channel::<RigJob>();
    let _ = tx.send(RigJob::Load(0, first));
    let failed = out.clone();
    let run = move || worker(&rig, &rx, &out);
    if let Err(e) = std::thread::Builder::new()
        .name(RIG_THREAD.into())
        .spawn(run)
    {
        // No rig thread: the lab runs on without its rig view, and says why.
        let _ = failed.send(Action::RigSolved(
            0,
            Err(format!("cannot start the rig's worker: {e}")),
        ));
    }
    tx
}

fn worker(rig: &RigSource, rx: &Receiver<RigJob>, out: &Sender<Action>) {
    // The current track and the neutral its last solve used.
    let mut track: Option<Arc<Sequence>> = None;
    let mut neutral: Option<usize> = None;
    while let Ok(first) = rx.recv() {
        let mut jobs = vec![first];
        jobs.extend(rx.try_iter());
        let Some(round) = fold(&jobs) else { continue };
        if let Some(RigJob::Load(_, seq)) =
            jobs.iter().rev().find(|j| matches!(j, RigJob::Load(..)))
        {
            track = Some(seq.clone());
            neutral = None;
        }
        let Some(seq) = track.clone() else { continue };
        let (id, load) = round.reply;
        let step = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
            let say = |s: String| {
                let _ = out.send(Action::RigStep(id, s));
            };
            say("reading the rig".into());
            let p = prepare_with_search(&seq, rig)?;
            // A new track: its first frame alone first (a failure here is the take's too,
            // and the take's solve reports it).
            if load && neutral.is_none() {
                say(format!(
                    "the first frame alone{}",
                    if p.search.is_some() {
                        ", its neutral searched on 68 points"
                    } else {
                        ""
                    }
                ));
                if let Ok(v) = rig_preview(&p, 0) {
                    let _ = out.send(Action::RigPreview(id, Arc::new(v)));
                }
            }
            rig_view_prepared(&p, round.smooth, neutral, &mut |s| say(s))
        }));
        let v: Result<Arc<RigView>, String> = match step {
            Ok(Ok(v)) => {
                neutral = v.neutral;
                Ok(Arc::new(v))
            }
            Ok(Err(e)) => Err(e.to_string()),
            Err(p) => Err(format!(
                "internal error (please report): {}",
                p.downcast_ref::<&str>()
                    .map(|s| s.to_string())
                    .or_else(|| p.downcast_ref::<String>().cloned())
                    .unwrap_or_else(|| "unknown cause".into())
            )),
        };
        let _ = out.send(if load {
            Action::RigSolved(id, v)
        } else {
            Action::RigSmoothed(id, v)
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn seq() -> Arc<Sequence> {
        Arc::new(keyshape_io::builtin_sequence().unwrap())
    }

    #[test]
    fn a_drained_queue_answers_its_newest_load_or_lambda() {
        let s = seq();
        assert_eq!(fold(&[]), None);
        // λ alone: a smoothed answer to the newest request.
        let r = fold(&[RigJob::Smooth(3, 10.0), RigJob::Smooth(4, 100.0)]).unwrap();
        assert_eq!(
            r,
            Round {
                reply: (4, false),
                smooth: 100.0
            }
        );
        // A load resets λ; a λ after it is the load's answer with that λ.
        let r = fold(&[RigJob::Smooth(3, 10.0), RigJob::Load(5, s.clone())]).unwrap();
        assert_eq!(
            r,
            Round {
                reply: (5, true),
                smooth: 0.0
            }
        );
        let r = fold(&[RigJob::Load(5, s.clone()), RigJob::Smooth(6, 10.0)]).unwrap();
        assert_eq!(
            r,
            Round {
                reply: (5, true),
                smooth: 10.0
            }
        );
        // A load after a load: the newer.
        let r = fold(&[RigJob::Load(5, s.clone()), RigJob::Load(7, s)]).unwrap();
        assert_eq!(r.reply, (7, true));
    }
}
