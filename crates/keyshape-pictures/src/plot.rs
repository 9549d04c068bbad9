//! Plot descriptions as plain data: what to draw, not how. The PNG renderer
//! ([`crate::render`]) and the terminal chart both draw from a [`PlotSpec`]. The studies
//! make their own plots from these parts (the smoothing study's trade-off is in
//! keyshape-experiments).

use keyshape_core::keyshapes::curves::CurveRow;
use keyshape_core::keyshapes::Method;

/// How a series is drawn.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Style {
    /// A solid polyline with small markers.
    Line,
    /// A dashed polyline with small markers.
    Dashed,
    /// Markers only (a single large dot for one point, like the paper's hull).
    Marker,
    /// A shaded interval: the points run along its upper edge and back along its lower
    /// edge, and the closed polygon is filled lightly in the colour. Not in the legend.
    Band,
    /// A thin polyline without markers, one of many (one per person, say). Not in the
    /// legend.
    Thin,
}

/// One named series.
#[derive(Debug, Clone, PartialEq)]
pub struct Series {
    /// Legend label.
    pub name: String,
    /// (x, y) points in drawing order.
    pub points: Vec<(f64, f64)>,
    /// Line style.
    pub style: Style,
    /// RGB colour.
    pub color: [u8; 3],
}

/// A 2-D line plot.
#[derive(Debug, Clone, PartialEq)]
pub struct PlotSpec {
    /// Title above the plot.
    pub title: String,
    /// x-axis title.
    pub x_label: String,
    /// y-axis title.
    pub y_label: String,
    /// The series, drawn in order; the legend lists them in order.
    pub series: Vec<Series>,
    /// Start the y axis at zero.
    pub y_from_zero: bool,
    /// Extend the y axis to at least this value (to share an axis between panels).
    pub y_at_least: Option<f64>,
}

impl PlotSpec {
    /// Data bounds over all series: ((xmin, xmax), (ymin, ymax)).
    pub fn bounds(&self) -> Option<((f64, f64), (f64, f64))> {
        let pts = self
            .series
            .iter()
            .flat_map(|s| s.points.iter())
            .filter(|p| p.0.is_finite() && p.1.is_finite());
        let mut b: Option<((f64, f64), (f64, f64))> = None;
        for &(x, y) in pts {
            b = Some(match b {
                None => ((x, x), (y, y)),
                Some(((x0, x1), (y0, y1))) => ((x0.min(x), x1.max(x)), (y0.min(y), y1.max(y))),
            });
        }
        b.map(|(x, (y0, y1))| {
            let y1 = self.y_at_least.map_or(y1, |m| y1.max(m));
            (x, (if self.y_from_zero { y0.min(0.0) } else { y0 }, y1))
        })
    }

    /// The y axis is logarithmic when the data (all positive) span a decade or more, as
    /// LS error curves do: on a linear axis everything past the first few k sits on the
    /// floor (at 94× every LS curve from k ≥ 10 lay flat on zero). Then the axis runs over
    /// the data, not from zero.
    pub fn log_y(&self) -> bool {
        let ys = self
            .series
            .iter()
            .flat_map(|s| s.points.iter())
            .map(|p| p.1)
            .filter(|y| y.is_finite());
        let (lo, hi) = ys.fold((f64::INFINITY, 0.0f64), |(a, b), y| (a.min(y), b.max(y)));
        let hi = self.y_at_least.map_or(hi, |m| hi.max(m));
        lo > 0.0 && lo.is_finite() && hi / lo >= LOG_SPAN
    }
}

/// The span (largest over smallest value) from which a chart's y axis is logarithmic.
pub const LOG_SPAN: f64 = 10.0;

/// Colour and style of each key-shape method, after paper 000 Fig. 6 (spread solid blue,
/// k-means dashed green / magenta, hull a red dot) plus ours; the k-means centre-of-mass
/// variants (`kmeansN-mean`) solid in a darker shade of their k-means colour. Keyed on
/// [`Method`], with no default: a new method does not compile until it has its style.
pub fn method_style(method: &Method) -> ([u8; 3], Style) {
    match *method {
        Method::Spread => ([31, 90, 200], Style::Line),
        Method::KMeans {
            pcs: 2,
            mean: false,
        } => ([30, 150, 60], Style::Dashed),
        Method::KMeans {
            pcs: 3,
            mean: false,
        } => ([190, 40, 190], Style::Dashed),
        Method::KMeans { pcs: 2, mean: true } => ([10, 90, 30], Style::Line),
        Method::KMeans { pcs: 3, mean: true } => ([110, 20, 120], Style::Line),
        // k-means on another count of components (`kmeans4`, `kmeans4-mean`).
        Method::KMeans { .. } => ([230, 140, 20], Style::Dashed),
        Method::Hull => ([220, 30, 30], Style::Marker),
        Method::Greedy => ([20, 20, 20], Style::Line),
        Method::Random => ([150, 150, 150], Style::Dashed),
    }
}

/// [`method_style`] of a method named as the curves' rows name it; a name that is no
/// method (a hand-edited report) is drawn grey and dotted, apart from every method.
pub fn named_style(name: &str) -> ([u8; 3], Style) {
    Method::parse(name).map_or(([120, 120, 120], Style::Marker), |m| method_style(&m))
}

/// The error-curve plot (per-point RMS against k) for one solver's rows.
pub fn curves_plot(rows: &[CurveRow], solver: &str, title: &str, units: &str) -> PlotSpec {
    let mut methods: Vec<&str> = Vec::new();
    for r in rows.iter().filter(|r| r.solver == solver) {
        if !methods.contains(&r.method.as_str()) {
            methods.push(&r.method);
        }
    }
    let series = methods
        .iter()
        .map(|m| {
            let (color, style) = named_style(m);
            let mut points: Vec<(f64, f64)> = rows
                .iter()
                .filter(|r| r.solver == solver && r.method == *m)
                .map(|r| (r.k as f64, r.rms))
                .collect();
            points.sort_by(|a, b| a.0.total_cmp(&b.0));
            let style = if points.len() == 1 {
                Style::Marker
            } else {
                style
            };
            Series {
                name: m.to_string(),
                points,
                style,
                color,
            }
        })
        .collect();
    PlotSpec {
        title: title.to_string(),
        x_label: "number of key shapes k".into(),
        y_label: format!("RMS error per point ({units}), {solver}"),
        series,
        y_from_zero: true,
        y_at_least: None,
    }
}

/// A polyline cut where it first passes `x = cap` (the crossing kept, interpolated), and the
/// largest x it reached beyond the cap, if it passed it.
pub fn cut_at_x(points: Vec<(f64, f64)>, cap: f64) -> (Vec<(f64, f64)>, Option<f64>) {
    let Some(i) = points.iter().position(|p| p.0 > cap) else {
        return (points, None);
    };
    let top = points[i..]
        .iter()
        .map(|p| p.0)
        .fold(f64::NEG_INFINITY, f64::max);
    let mut kept = points[..i].to_vec();
    if let Some(&(x0, y0)) = kept.last() {
        let (x1, y1) = points[i];
        let u = (cap - x0) / (x1 - x0);
        kept.push((cap, y0 + u * (y1 - y0)));
    }
    (kept, Some(top))
}

/// One method's mean curve across a corpus with its 95 % interval: `(k, mean, lo, hi)`.
pub type IntervalCurve = (String, Vec<(f64, f64, f64, f64)>);

/// Mean curves across a corpus, each over its shaded 95 % interval (bands first, so no band
/// hides a line).
pub fn interval_plot(
    curves: &[IntervalCurve],
    title: &str,
    x_label: &str,
    y_label: &str,
) -> PlotSpec {
    let mut bands = Vec::new();
    let mut lines = Vec::new();
    for (name, pts) in curves {
        let (color, style) = named_style(name);
        let mut pts = pts.clone();
        pts.sort_by(|a, b| a.0.total_cmp(&b.0));
        let mut edge: Vec<(f64, f64)> = pts.iter().map(|p| (p.0, p.3)).collect();
        edge.extend(pts.iter().rev().map(|p| (p.0, p.2)));
        bands.push(Series {
            name: format!("{name} 95 %"),
            points: edge,
            style: Style::Band,
            color,
        });
        lines.push(Series {
            name: name.clone(),
            points: pts.iter().map(|p| (p.0, p.1)).collect(),
            style: if pts.len() == 1 { Style::Marker } else { style },
            color,
        });
    }
    bands.extend(lines);
    PlotSpec {
        title: title.to_string(),
        x_label: x_label.to_string(),
        y_label: y_label.to_string(),
        series: bands,
        y_from_zero: true,
        y_at_least: None,
    }
}

#[cfg(test)]
mod cut_tests {
    use super::cut_at_x;

    /// A curve that runs past the cap stops at the crossing; one that does not is whole.
    #[test]
    fn a_curve_is_cut_where_it_first_passes_the_cap() {
        let (kept, top) = cut_at_x(vec![(1.0, 1.0), (0.5, 2.0), (2.0, 5.0), (3.0, 9.0)], 1.0);
        assert_eq!(kept, vec![(1.0, 1.0), (0.5, 2.0), (1.0, 3.0)]);
        assert_eq!(top, Some(3.0));
        let whole = vec![(1.0, 1.0), (0.5, 2.0)];
        assert_eq!(cut_at_x(whole.clone(), 1.0), (whole, None));
    }
}

#[cfg(test)]
mod style_tests {
    use super::{method_style, named_style};
    use keyshape_core::keyshapes::Method;

    /// Every method of the plots is drawn its own way, found again from its name; a name
    /// that is no method is drawn apart from all of them.
    #[test]
    fn each_method_has_a_style_of_its_own_found_from_its_name() {
        let styles: Vec<_> = Method::ALL.iter().map(method_style).collect();
        for (i, a) in styles.iter().enumerate() {
            for b in &styles[..i] {
                assert_ne!(a, b);
            }
        }
        for (m, s) in Method::ALL.iter().zip(&styles) {
            assert_eq!(named_style(&m.name()), *s, "{m:?}");
        }
        assert!(!styles.contains(&named_style("no-such-method")));
    }
}
