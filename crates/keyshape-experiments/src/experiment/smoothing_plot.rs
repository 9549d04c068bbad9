//! The smoothing study's picture: jitter against error, one series per approach, each in
//! a colour and style of its own.

use super::smoothing::SmoothRow;
use keyshape_pictures::plot::{cut_at_x, PlotSpec, Series, Style};

/// Colour and style of each smoothing approach.
pub fn approach_style(approach: &str) -> ([u8; 3], Style) {
    match approach {
        "none" => ([20, 20, 20], Style::Marker),
        "prior offline order 1" => ([31, 90, 200], Style::Line),
        // Cyan, not a second blue beside order 1's.
        "prior offline order 2" => ([0, 190, 200], Style::Line),
        "prior causal order 1" => ([110, 20, 120], Style::Line),
        "moving-average" => ([30, 150, 60], Style::Dashed),
        "ema" => ([230, 140, 20], Style::Dashed),
        a if a.starts_with("one-euro") => {
            // One colour per beta band.
            let beta: f64 = a
                .rsplit(' ')
                .next()
                .and_then(|b| b.parse().ok())
                .unwrap_or(0.0);
            let colour = if beta < 0.1 {
                [220, 30, 30]
            } else if beta < 1.0 {
                // Olive, not a second red beside beta < 0.1's.
                [150, 150, 0]
            } else {
                [230, 60, 160]
            };
            (colour, Style::Dashed)
        }
        _ => ([150, 150, 150], Style::Dashed),
    }
}

/// The jitter-against-error trade-off of the smoothing study: one series per approach,
/// x the target jitter, y the target error against the clean reference (`clean`) or
/// against the warp of the tracked points.
pub fn smoothing_plot(rows: &[SmoothRow], title: &str, clean: bool) -> PlotSpec {
    let mut names: Vec<&str> = Vec::new();
    for r in rows {
        if !names.contains(&r.approach.as_str()) {
            names.push(&r.approach);
        }
    }
    // Nothing jitters more than no smoothing and is better for it: a setting past the
    // unsmoothed jitter (One Euro at a high β) is cut at 5 % beyond it, so it does not
    // squash the band where the approaches compete; its legend says how far it went.
    let x_cap = rows
        .iter()
        .find(|r| r.approach == "none")
        .map_or(f64::INFINITY, |r| 1.05 * r.jitter_target);
    let series = names
        .iter()
        .map(|n| {
            let (color, style) = approach_style(n);
            // Every curve starts at no smoothing, then its settings in their order (weakest
            // first), not sorted by jitter: a filter whose jitter does not fall with
            // strength shows it.
            let start = rows
                .iter()
                .find(|r| r.approach == "none")
                .filter(|_| *n != "none");
            let points: Vec<(f64, f64)> = start
                .into_iter()
                .chain(rows.iter().filter(|r| r.approach == *n))
                .map(|r| {
                    let y = if clean {
                        r.target_rms_clean
                    } else {
                        r.target_rms_tracked
                    };
                    (r.jitter_target, y)
                })
                .collect();
            let (points, left) = cut_at_x(points, x_cap);
            Series {
                name: match left {
                    Some(top) => format!("{n} (off right: jitter to {top:.2})"),
                    None => n.to_string(),
                },
                points,
                style,
                color,
            }
        })
        .collect();
    PlotSpec {
        title: title.to_string(),
        x_label: "jitter of the retargeted points: RMS second difference (px/frame²)".into(),
        y_label: if clean {
            "target RMS error vs the clean reference G(low-passed q) (px)".into()
        } else {
            "target RMS error vs the tracked reference G(q) (px)".into()
        },
        series,
        y_from_zero: true,
        y_at_least: None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The smoothing plot ends 5 % past the unsmoothed jitter: One Euro
    /// at β = 0.5 jittering more than no smoothing no longer squashes the band where the
    /// approaches compete, and its legend says where it went.
    #[test]
    fn the_smoothing_plot_ends_past_the_unsmoothed_jitter() {
        let row = |approach: &str, jitter: f64, err: f64| SmoothRow {
            approach: approach.into(),
            setting: String::new(),
            source_rms: 0.0,
            target_rms_tracked: err,
            target_rms_clean: err,
            jitter_target: jitter,
            jitter_weights: 0.0,
            lag_frames: 0,
            kkt: None,
        };
        let rows = [
            row("none", 1.4, 1.0),
            row("ema", 0.5, 2.0),
            row("one-euro beta 0.5", 1.2, 1.5),
            row("one-euro beta 0.5", 2.0, 8.0),
        ];
        let spec = super::smoothing_plot(&rows, "t", false);
        let ((_, x1), _) = spec.bounds().unwrap();
        assert!((x1 - 1.05 * 1.4).abs() < 1e-12, "{x1}");
        assert_eq!(
            spec.series[2].name,
            "one-euro beta 0.5 (off right: jitter to 2.00)"
        );
        assert_eq!(spec.series[1].name, "ema");
    }
}
