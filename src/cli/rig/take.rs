//! `kslab rig --live`: a track solved as `kslab live` solves it, through the live solve's
//! replay — the calibrations a take recorded (`--calibrations`), or the `--neutral`
//! lead-in; each frame weighed by the tracker's confidence where the track has it, and
//! started afresh after a gap in its time stamps.

use super::RigArgs;
use anyhow::{Context, Result};
use keyshape_core::sequence::Sequence;
use keyshape_live::sink::RecordedCalibration;
use keyshape_rig::live::{Replay, ReplayEvent};
use keyshape_rig::{Neutral, Rig, RigOptions, RigSolve};

/// The calibrations a `--live` solve replays (None without --live).
pub(super) fn events(
    a: &RigArgs,
    seq: &Sequence,
    neutral: Neutral,
) -> Result<Option<Vec<ReplayEvent>>> {
    if !a.live {
        if a.calibrations.is_some() {
            anyhow::bail!("--calibrations replays a live take's calibrations: it needs --live");
        }
        return Ok(None);
    }
    if seq.dims != 2 {
        anyhow::bail!(
            "--live solves image points as `kslab live` does: read the track with --dims 2"
        );
    }
    let Some(path) = &a.calibrations else {
        let lead_in = match neutral {
            Neutral::Span(x, y) => x..y,
            Neutral::Column(c) => c..c + 1,
            Neutral::Auto | Neutral::LeastActive => 0..1,
        };
        return Ok(Some(vec![ReplayEvent {
            from: 0,
            lead_in: Some(lead_in),
            calibration: None,
        }]));
    };
    if a.neutral.is_some() {
        anyhow::bail!("--calibrations holds each calibration's lead-in: --neutral does not apply");
    }
    let text = keyshape_io::read_text(path)?;
    let mut out = Vec::new();
    for (i, line) in text
        .lines()
        .enumerate()
        .filter(|(_, l)| !l.trim().is_empty())
    {
        let at = || format!("{}: line {}", path.display(), i + 1);
        let r: RecordedCalibration = serde_json::from_str(line)
            .map_err(|e| anyhow::anyhow!("{}, column {}: {e}", at(), e.column()))?;
        let column = |f: i64| {
            seq.column_of_frame(f)
                .with_context(|| format!("{}: the calibration names frame {f}", at()))
        };
        let lead_in = match r.lead_in {
            Some([x, y]) => {
                let (cx, cy) = (column(x)?, column(y)?);
                if cx > cy {
                    anyhow::bail!("{}: its lead-in runs from frame {x} back to {y}", at());
                }
                Some(cx..cy + 1)
            }
            None => None,
        };
        out.push(ReplayEvent {
            from: column(r.from)?,
            lead_in,
            calibration: Some(r.calibration),
        });
    }
    if out.is_empty() {
        anyhow::bail!("{}: holds no calibration", path.display());
    }
    Ok(Some(out))
}

/// The track replayed through `events` as the live solve solved it.
pub(super) fn replay(
    rig: &Rig,
    seq: &Sequence,
    opts: &RigOptions,
    events: &[ReplayEvent],
) -> Result<RigSolve> {
    let take = Replay {
        track: &seq.coords,
        confidence: seq.confidence.as_ref(),
        times: seq.times.as_deref(),
        events,
    };
    Ok(keyshape_rig::live::replay(rig, opts, &take)?)
}
