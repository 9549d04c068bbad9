//! What `kslab rig` says when it is done: the summary line (or `--json`), the refined
//! map, the plausibility report, and a warning when the neutral frame does not look
//! neutral.

use super::RigArgs;
use anyhow::Result;
use keyshape_core::sequence::Sequence;
use keyshape_core::solve::temporal::SmoothMode;
use keyshape_rig::{Identity, Neutral, RigOptions};
use serde_json::json;

/// What the solve gave, for the summary.
pub(super) struct Done<'a> {
    pub(super) seq: &'a Sequence,
    pub(super) rig: &'a keyshape_rig::Rig,
    pub(super) r: &'a keyshape_rig::RigSolve,
    pub(super) opts: &'a RigOptions,
    /// The refined map: (landmark, vertex) pairs, landmarks moved per round, moved in all.
    pub(super) refined: Option<&'a Refined>,
    pub(super) plausible: Option<&'a keyshape_rig::plausibility::Plausibility>,
}

/// The refined map's pairs, moves per round and landmarks moved.
pub(super) type Refined = (Vec<(usize, usize)>, Vec<usize>, usize);

/// The `--json` summary.
pub(super) fn summary_json(
    a: &RigArgs,
    d: &Done,
    dir: &std::path::Path,
    per_clip: bool,
) -> serde_json::Value {
    let (seq, rig, r, opts) = (d.seq, d.rig, d.r, d.opts);
    let neutral = opts.neutral;
    let neutral_frames: Vec<i64> = r.neutrals.iter().map(|&c| seq.frames[c]).collect();
    let mean_rms = r.rms.iter().sum::<f64>() / r.rms.len() as f64;
    let (refined, plausible) = (d.refined, d.plausible);
    json!({
        "frames": seq.n_frames(),
        "rig": dir.display().to_string(),
        "shapes": rig.k(),
        "solver": a.solver.name(),
        "identity": a.identity.name(),
        "identity_per": if per_clip { "clip" } else { "track" },
        "neutral": match (a.identity, neutral) {
            (Identity::None, _) => None,
            (_, Neutral::Auto) => Some("auto".to_string()),
            (_, Neutral::LeastActive) => Some("least-active".to_string()),
            (_, Neutral::Column(c)) => Some(seq.frames[c].to_string()),
            (_, Neutral::Span(x, y)) => Some(format!("{}-{}", seq.frames[x], seq.frames[y - 1])),
        },
        "neutral_frames": neutral_frames,
        "neutral_views": r.neutral_views.iter().map(|v| json!({
            "frame": seq.frames[v.frame],
            "yaw": v.yaw_pitch_roll[0],
            "pitch": v.yaw_pitch_roll[1],
            "roll": v.yaw_pitch_roll[2],
            "turn": v.turn,
            "lip_gap": (!v.lip_gap.is_nan()).then_some(v.lip_gap),
            "looks_neutral": v.looks_neutral,
            "activity": v.activity,
            "rule": v.rule,
        })).collect::<Vec<_>>(),
        "layout": rig.layout,
        "landmarks": rig.landmarks(),
        "irises": rig.sees_pupils(),
        "landmark_weights": opts.landmark_weights.to_vec(),
        "smooth": opts.smooth,
        // The live path's default λ is a share of the squared inter-ocular distance.
        "lambda_px2": r.lambda,
        "smooth_unit": match opts.smooth_unit {
            keyshape_rig::SmoothUnit::Pixels => "px²",
            keyshape_rig::SmoothUnit::Iod => "iod²",
        },
        "smooth_mode": opts.smooth_mode.name(),
        "sweeps": r.sweeps,
        "sweeps_unconverged": r.sweeps_unconverged,
        "prior": opts.prior,
        "prior_taper": opts.taper,
        "zero_phase": opts.zero_phase,
        "mean_rms": mean_rms,
        "unconverged": r.unconverged,
        "mean_steps": r.steps.iter().map(|&x| f64::from(x)).sum::<f64>() / r.steps.len() as f64,
        "min_determination": a.min_determination,
        "plausibility": plausible,
        "refined_map": refined.as_ref().map(|(pairs, moved, changed)| json!({
            "landmarks": pairs.len(),
            "moved": changed,
            "moved_per_round": moved,
        })),
        "identifiability": r.shapes.iter().map(|s| json!({
            "shape": s.name,
            "image_motion": s.image_motion,
            "determination": s.determination,
            "frozen": s.frozen,
        })).collect::<Vec<_>>(),
    })
}

/// The summary on standard error (or standard output when the weights did not take it).
pub(super) fn print_summary(a: &RigArgs, d: &Done, taken: bool) -> Result<()> {
    let (seq, rig, r, opts) = (d.seq, d.rig, d.r, d.opts);
    let neutral_frames: Vec<i64> = r.neutrals.iter().map(|&c| seq.frames[c]).collect();
    let mean_rms = r.rms.iter().sum::<f64>() / r.rms.len() as f64;
    let frozen: Vec<&str> = r
        .shapes
        .iter()
        .filter(|s| s.frozen)
        .map(|s| s.name.as_str())
        .collect();
    sayln!(
        taken,
        "{} frames onto {} shapes ({}, prior {}, zero-phase σ {}{}), identity {}{}: RMS landmark error {:.3}, {} frozen{}, {} frames unconverged",
        seq.n_frames(),
        rig.k(),
        a.solver.name(),
        opts.prior,
        opts.zero_phase,
        if r.lambda > 0.0 {
            format!(
                ", {} temporal prior λ {:.1} px²",
                match opts.smooth_mode {
                    SmoothMode::Causal => "causal",
                    SmoothMode::Offline => "offline",
                },
                r.lambda
            )
        } else {
            String::new()
        },
        a.identity.name(),
        match (neutral_frames.len(), r.neutral_views.first()) {
            (0, _) => String::new(),
            (1, Some(v)) => format!(
                " from frame {} (yaw {:.0}°, pitch {:.0}°{})",
                neutral_frames[0],
                v.yaw_pitch_roll[0],
                v.yaw_pitch_roll[1],
                if v.rule == keyshape_rig::NeutralRule::OwnFace {
                    format!(
                        "; the least active frame: the rig reads as the performer's own face, its first pass summing to {:.2}",
                        v.activity
                    )
                } else {
                    String::new()
                }
            ),
            (1, None) => format!(" from frame {}", neutral_frames[0]),
            (n, _) => format!(" per clip ({n} neutral frames)"),
        },
        mean_rms,
        frozen.len(),
        if frozen.is_empty() {
            String::new()
        } else {
            format!(" ({})", frozen.join(" "))
        },
        r.unconverged
    );
    if let Some((pairs, moved, changed)) = d.refined {
        sayln!(
            taken,
            "landmark map refined from the track: {changed} of {} landmarks on another vertex (moved per round: {}){}",
            pairs.len(),
            moved
                .iter()
                .map(usize::to_string)
                .collect::<Vec<_>>()
                .join(", "),
            a.save_landmarks.as_ref().map_or(String::new(), |p| format!(
                "; saved to {} (solve the next take with --rig-landmarks {})",
                p.display(),
                p.display()
            )),
        );
    }
    if let Some(p) = d.plausible {
        for line in plausibility_lines(p) {
            sayln!(taken, "{line}");
        }
    }
    Ok(())
}

/// `--plausibility`'s report, line by line.
fn plausibility_lines(p: &keyshape_rig::plausibility::Plausibility) -> Vec<String> {
    let mut out = vec![format!(
        "plausibility over {} frames (the track's own geometry; no ground truth):",
        p.frames
    )];
    for g in &p.agreements {
        out.push(format!(
            "  {:<15} r {:>6.3} against {} (range {:.3} of the eye-corner distance)",
            g.weights, g.r, g.geometry, g.geometry_range
        ));
    }
    let mut twins: Vec<_> = p.twins.iter().collect();
    twins.sort_by(|a, b| b.mean_gap.total_cmp(&a.mean_gap));
    out.push(format!(
        "  twins on symmetric frames, mean |L − R| (largest): {}",
        twins
            .iter()
            .take(4)
            .map(|t| format!("{} {:.2} ({:.2})", t.pair, t.mean_gap, t.max_gap))
            .collect::<Vec<_>>()
            .join(", ")
    ));
    let mut on: Vec<_> = p.on_rate.iter().filter(|x| x.1 > 0.2).collect();
    on.sort_by(|a, b| b.1.total_cmp(&a.1));
    out.push(format!(
        "  on (> {}) on more than 20 % of frames: {}",
        keyshape_rig::plausibility::ON,
        if on.is_empty() {
            "none".to_string()
        } else {
            on.iter()
                .map(|(n, v)| format!("{n} {:.0} %", 100.0 * v))
                .collect::<Vec<_>>()
                .join(", ")
        }
    ));
    out
}

/// A warning on stderr for each neutral frame that does not look neutral (a turned head,
/// parted lips): what was seen and what to do.
pub(super) fn warn_unneutral(r: &keyshape_rig::RigSolve, seq: &Sequence, neutral: Neutral) {
    let searched = matches!(neutral, Neutral::Auto | Neutral::LeastActive);
    for v in r.neutral_views.iter().filter(|v| !v.looks_neutral) {
        let mut what = Vec::new();
        if v.turn > keyshape_rig::NEUTRAL_TURN_WARN_DEG {
            what.push(format!(
                "the head is turned {:.0}° (yaw {:.0}°, pitch {:.0}°)",
                v.turn, v.yaw_pitch_roll[0], v.yaw_pitch_roll[1]
            ));
        }
        if v.lip_gap > keyshape_rig::NEUTRAL_LIPS_WARN {
            what.push(format!(
                "the lips are parted ({:.0} % of the eye-corner distance)",
                100.0 * v.lip_gap
            ));
        }
        let advice = if searched {
            "no candidate frame looked neutral: record a second or two of a relaxed, frontal face at the start of a take and name it with --neutral FIRST-LAST"
        } else {
            "an identity taken from it reads the difference as expression: name a relaxed, frontal frame or stretch with --neutral"
        };
        errln!(
            "warning: neutral frame {}: {}; {advice}",
            seq.frames[v.frame],
            what.join(", ")
        );
    }
}
