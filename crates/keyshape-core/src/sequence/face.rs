//! The face check: whether a frame can be a face that a neutral or a calibration is made
//! from.

use super::{degenerate_shape, spread_and_size, MIN_SPREAD};

/// A landmark further from the face's centroid than this many times the median landmark's
/// distance is not on the face: on the shipped tracks (MediaPipe's 468, the 68 iBUG points,
/// OpenFace, py-feat) the ratio stays below 3.
pub const MAX_FACE_SPREAD_RATIO: f64 = 20.0;

/// Below this ratio of the smaller to the larger principal variance, a face's points lie on
/// a line (a face's is about 0.3 to 1).
pub const MIN_FACE_ASPECT: f64 = 1e-4;

/// Why a 2-D frame (`dims` values a point; x and y are read) cannot be a face that a neutral
/// or a calibration is made from, if it cannot: its points coincide
/// ([`degenerate_shape`]), lie on a line, or one lies far off the rest (a landmark at 1e15
/// on one frame became the automatic neutral and moved every other frame's weights by up to
/// 1). Every path that makes a neutral or a calibration from a frame asks this.
pub fn face_problem(shape: &[f64], dims: usize) -> Option<String> {
    let dims = dims.max(1);
    let n = shape.len() / dims;
    if degenerate_shape(shape, dims) {
        return Some(if n == 0 {
            "it has no points".to_string()
        } else {
            let (spread, size) = spread_and_size(shape, dims);
            // (Points that coincide up to rounding spread over a few ulps of their size.)
            if spread >= MIN_SPREAD && spread > 1e-14 * size {
                format!("its {n} points lie beyond what 64-bit numbers resolve from the origin")
            } else {
                format!("all its {n} points coincide")
            }
        });
    }
    if dims < 2 || n < 3 {
        return None;
    }
    let (mut cx, mut cy) = (0.0, 0.0);
    for p in shape.chunks(dims) {
        cx += p[0] / n as f64;
        cy += p[1] / n as f64;
    }
    let mut radii: Vec<f64> = shape
        .chunks(dims)
        .map(|p| (p[0] - cx).hypot(p[1] - cy))
        .collect();
    let (far, far_at) =
        radii
            .iter()
            .enumerate()
            .fold((0.0f64, 0), |b, (i, &r)| if r > b.0 { (r, i) } else { b });
    radii.sort_by(f64::total_cmp);
    let median = radii[n / 2];
    // (Written so that a NaN is refused too.)
    if !matches!(
        far.partial_cmp(&(MAX_FACE_SPREAD_RATIO * median)),
        Some(std::cmp::Ordering::Less | std::cmp::Ordering::Equal)
    ) {
        return Some(format!(
            "landmark {far_at} lies {:.3e} from the face's centre, more than {MAX_FACE_SPREAD_RATIO} times the median landmark's {median:.3e}: it is not on the face",
            far
        ));
    }
    // The principal variances of the points (their ratio is scale-free; coordinates within
    // ±1e30 and spread beyond 1e-100 square without overflow or underflow).
    let (mut sxx, mut syy, mut sxy) = (0.0, 0.0, 0.0);
    for p in shape.chunks(dims) {
        let (x, y) = (p[0] - cx, p[1] - cy);
        sxx += x * x;
        syy += y * y;
        sxy += x * y;
    }
    let mean = 0.5 * (sxx + syy);
    let half = (0.25 * (sxx - syy).powi(2) + sxy * sxy).sqrt();
    let (big, small) = (mean + half, (mean - half).max(0.0));
    if !matches!(
        small.partial_cmp(&(MIN_FACE_ASPECT * big)),
        Some(std::cmp::Ordering::Greater | std::cmp::Ordering::Equal)
    ) {
        return Some(format!("its {n} points lie on a line"));
    }
    None
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    /// An ellipse of 68 points: a face's spread.
    fn face() -> Vec<f64> {
        (0..68)
            .flat_map(|i| {
                let a = i as f64 * 0.37;
                [100.0 + 40.0 * a.cos(), 100.0 + 50.0 * a.sin()]
            })
            .collect()
    }

    /// The face check at its thresholds' ends: a landmark just inside the spread ratio
    /// passes and just beyond is named; a thin ellipse passes and a line is refused;
    /// coincident points and a face beyond 64-bit resolution are told apart.
    #[test]
    fn the_face_check_holds_at_its_thresholds() {
        let f = face();
        assert_eq!(face_problem(&f, 2), None);
        // The 3-D layout reads x and y.
        let f3: Vec<f64> = f.chunks(2).flat_map(|p| [p[0], p[1], 7.0]).collect();
        assert_eq!(face_problem(&f3, 3), None);
        let median = {
            let (cx, cy) = (100.0, 100.0);
            let mut r: Vec<f64> = f.chunks(2).map(|p| (p[0] - cx).hypot(p[1] - cy)).collect();
            r.sort_by(f64::total_cmp);
            r[34]
        };
        let mut near = f.clone();
        // Far out along x, the centroid moves too: ratio measured, not assumed.
        near[0] = 100.0 + 15.0 * median;
        assert_eq!(face_problem(&near, 2), None, "ratio 15");
        let mut far = f.clone();
        far[0] = 100.0 + 40.0 * median;
        assert!(face_problem(&far, 2)
            .unwrap()
            .starts_with("landmark 0 lies"));
        // A thin face (aspect 1e-3 in variance) passes; flatter than 1e-4 is a line.
        let thin: Vec<f64> = f
            .chunks(2)
            .flat_map(|p| [p[0], 100.0 + (p[1] - 100.0) * 0.04])
            .collect();
        assert_eq!(face_problem(&thin, 2), None);
        let flat: Vec<f64> = f
            .chunks(2)
            .flat_map(|p| [p[0], 100.0 + (p[1] - 100.0) * 0.005])
            .collect();
        assert!(face_problem(&flat, 2).unwrap().contains("on a line"));
        // A line in any direction (the cross term counts), in 2-D and 3-D, of three points.
        for slope in [0.5, 2.0, -3.0] {
            let line: Vec<f64> = (0..68)
                .flat_map(|i| [i as f64, 1.0 + slope * i as f64])
                .collect();
            assert!(
                face_problem(&line, 2).unwrap().contains("on a line"),
                "{slope}"
            );
            // Nearly a line, across the diagonal: a face this thin still passes.
            let thin: Vec<f64> = line
                .chunks(2)
                .enumerate()
                .flat_map(|(i, p)| {
                    // 3 units across a line 68 long (variance ratio about 1e-2).
                    let w = 3.0 * (i as f64 * 0.37).sin() / (1.0 + slope * slope).sqrt();
                    [p[0] - slope * w, p[1] + w]
                })
                .collect();
            assert_eq!(face_problem(&thin, 2), None, "{slope}");
        }
        let line3: Vec<f64> = (0..68)
            .flat_map(|i| [i as f64, 2.0 * i as f64, 5.0])
            .collect();
        assert!(face_problem(&line3, 3).unwrap().contains("on a line"));
        assert!(face_problem(&[0.0, 0.0, 1.0, 2.0, 2.0, 4.0], 2)
            .unwrap()
            .contains("on a line"));
        assert!(face_problem(&[3.0; 136], 2).unwrap().contains("coincide"));
        // Coincident up to rounding (a few ulps apart, far from the origin) is "coincide";
        // a real spread lost next to the offset is the offset's.
        let ulps: Vec<f64> = (0..136).map(|i| 1e6 + f64::from(i % 3) * 1.2e-10).collect();
        assert!(face_problem(&ulps, 2).unwrap().contains("coincide"));
        let offset: Vec<f64> = f.iter().map(|v| v + 1e15).collect();
        assert!(face_problem(&offset, 2).unwrap().contains("64-bit"));
        assert!(face_problem(&[], 2).unwrap().contains("no points"));
        // Fewer than three points: only coincidence is checked.
        assert_eq!(face_problem(&[0.0, 0.0, 1.0, 5.0], 2), None);
    }
}
