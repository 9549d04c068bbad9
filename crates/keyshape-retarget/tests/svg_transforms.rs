//! A redrawn template is read as drawn: every transform on a key group, on a nested group or
//! on a path changes the key shape read back (a `scale(…)` on the group was
//! read as if it were not there). Checked on hand-made edits with exact expectations and on
//! a file saved by Inkscape 1.2.2 (tests/data/README.md says how it was made).

// Test code: a failed unwrap is a failed test with its message.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use keyshape_retarget::svg::{parse_template, read_template};
use keyshape_retarget::target::TargetSet;
use std::path::{Path, PathBuf};
fn data(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../tests/data")
        .join(name)
}

fn shape(set: &TargetSet, frame: i64) -> Vec<[f64; 2]> {
    set.keys
        .iter()
        .find(|k| k.frame == frame)
        .unwrap_or_else(|| panic!("no key {frame}"))
        .coords
        .chunks(2)
        .map(|p| [p[0], p[1]])
        .collect()
}

fn centroid(s: &[[f64; 2]]) -> [f64; 2] {
    let n = s.len() as f64;
    let (x, y) = s.iter().fold((0.0, 0.0), |a, p| (a.0 + p[0], a.1 + p[1]));
    [x / n, y / n]
}

/// Asserts `b[i] ≈ f(a[i])` for every point.
fn assert_map(a: &[[f64; 2]], b: &[[f64; 2]], f: impl Fn([f64; 2]) -> [f64; 2], what: &str) {
    assert_eq!(a.len(), b.len());
    for (i, (p, q)) in a.iter().zip(b).enumerate() {
        let e = f(*p);
        let tol = 2e-3 * (1.0 + e[0].abs().max(e[1].abs()));
        assert!(
            (e[0] - q[0]).abs() < tol && (e[1] - q[1]).abs() < tol,
            "{what}: point {i}: expected {e:?}, read {q:?}"
        );
    }
}

fn edited(svg: &str, from: &str, to: &str) -> TargetSet {
    assert!(svg.contains(from), "the template lacks {from}");
    parse_template(Path::new("edited.svg"), &svg.replacen(from, to, 1)).unwrap()
}

/// The group's original `transform="translate(ox oy)"` attribute of key `frame`.
fn group_transform(svg: &str, frame: i64) -> (String, f64, f64) {
    let tag = format!("<g id=\"key-{frame}\" transform=\"translate(");
    let start = svg.find(&tag).unwrap() + tag.len();
    let end = start + svg[start..].find(')').unwrap();
    let nums: Vec<f64> = svg[start..end]
        .split_whitespace()
        .map(|v| v.parse().unwrap())
        .collect();
    (
        format!("transform=\"translate({})\"", &svg[start..end]),
        nums[0],
        nums[1],
    )
}

#[test]
fn transforms_added_to_a_template_change_the_shape_read() {
    let path = data("template_lips3.svg");
    let svg = std::fs::read_to_string(&path).unwrap();
    let base = read_template(&path).unwrap();
    let (attr, ox, oy) = group_transform(&svg, 134);
    let a = shape(&base, 134);

    // scale on the group (about the template's origin for the key: shape × 1.5)
    let s = edited(
        &svg,
        &attr,
        &format!("transform=\"translate({ox} {oy}) scale(1.5)\""),
    );
    assert_map(&a, &shape(&s, 134), |p| [1.5 * p[0], 1.5 * p[1]], "scale");
    // the other keys are untouched
    assert_map(&shape(&base, 102), &shape(&s, 102), |p| p, "untouched key");

    // a translation by (10, −4)
    let s = edited(
        &svg,
        &attr,
        &format!("transform=\"translate({} {})\"", ox + 10.0, oy - 4.0),
    );
    assert_map(
        &a,
        &shape(&s, 134),
        |p| [p[0] + 10.0, p[1] - 4.0],
        "translate",
    );

    // a matrix: x × 1.2, y × 0.8, shear 0.1
    let s = edited(
        &svg,
        &attr,
        &format!("transform=\"matrix(1.2 0 0.1 0.8 {ox} {oy})\""),
    );
    assert_map(
        &a,
        &shape(&s, 134),
        |p| [1.2 * p[0] + 0.1 * p[1], 0.8 * p[1]],
        "matrix",
    );

    // a nested group scaling by 2 inside the key group
    let open = format!("<g id=\"key-134\" {attr}><title>key frame 134</title>");
    let s = parse_template(
        Path::new("nested.svg"),
        &svg.replacen(&open, &format!("{open}<g transform=\"scale(2)\">"), 1)
            .replacen("</g>\n<g id=\"key-102\"", "</g></g>\n<g id=\"key-102\"", 1),
    )
    .unwrap();
    assert_map(
        &a,
        &shape(&s, 134),
        |p| [2.0 * p[0], 2.0 * p[1]],
        "nested group",
    );

    // a transform on one path moves only that contour's points
    let s = edited(
        &svg,
        "<polyline id=\"key-134-c0\"",
        "<polyline transform=\"translate(0 5)\" id=\"key-134-c0\"",
    );
    let b = shape(&s, 134);
    let moved = a
        .iter()
        .zip(&b)
        .filter(|(p, q)| ((q[1] - p[1]) - 5.0).abs() < 1e-3 && (q[0] - p[0]).abs() < 1e-3)
        .count();
    let still = a
        .iter()
        .zip(&b)
        .filter(|(p, q)| (q[1] - p[1]).abs() < 1e-3 && (q[0] - p[0]).abs() < 1e-3)
        .count();
    assert_eq!(moved + still, a.len(), "points moved by other than (0, 5)");
    assert!(moved >= 10 && still >= 10, "moved {moved}, still {still}");

    // a NaN coordinate is named as such, not as a missing contour
    let e = parse_template(
        Path::new("nan.svg"),
        &svg.replacen("-0.4115133769293212,", "NaN,", 1),
    )
    .unwrap_err()
    .to_string();
    assert!(
        e.contains("key-134-c0")
            && (e.contains("could not be read") || e.contains("not a finite number")),
        "{e}"
    );
    assert!(!e.contains("is missing"), "{e}");
}

#[test]
fn a_template_saved_by_inkscape_is_read_as_drawn() {
    let base = read_template(&data("template_lips3.svg")).unwrap();
    let ink = read_template(&data("template_lips3_inkscape.svg")).unwrap();
    // key-26 was not touched: the same shape (to usvg's single precision).
    assert_map(
        &shape(&base, 26),
        &shape(&ink, 26),
        |p| p,
        "untouched key-26",
    );
    // key-134 was rotated by 30° about some point: a rigid motion by ±30°.
    let (a, b) = (shape(&base, 134), shape(&ink, 134));
    let (ca, cb) = (centroid(&a), centroid(&b));
    let mut angle = 0.0;
    for (p, q) in a.iter().zip(&b) {
        let (u, v) = ([p[0] - ca[0], p[1] - ca[1]], [q[0] - cb[0], q[1] - cb[1]]);
        let (nu, nv) = (u[0].hypot(u[1]), v[0].hypot(v[1]));
        assert!(
            (nu - nv).abs() < 2e-3 * (1.0 + nu),
            "not rigid: {nu} vs {nv}"
        );
        if nu > 1.0 {
            angle = (u[0] * v[1] - u[1] * v[0])
                .atan2(u[0] * v[0] + u[1] * v[1])
                .to_degrees();
            assert!((angle.abs() - 30.0).abs() < 0.05, "rotation {angle}°");
        }
    }
    assert!(angle != 0.0);
    // key-102 was scaled up uniformly: one factor > 1 for every point.
    let (a, b) = (shape(&base, 102), shape(&ink, 102));
    let (ca, cb) = (centroid(&a), centroid(&b));
    let factor = {
        let (p, q) = (a[0], b[0]);
        (q[0] - cb[0]).hypot(q[1] - cb[1]) / (p[0] - ca[0]).hypot(p[1] - ca[1])
    };
    assert!(factor > 1.05, "scale factor {factor}");
    assert_map(
        &a,
        &b,
        |p| {
            [
                cb[0] + factor * (p[0] - ca[0]),
                cb[1] + factor * (p[1] - ca[1]),
            ]
        },
        "uniform scale",
    );
}

/// A key panel deleted or scaled to nothing was read as one key fewer, exit 0, and a
/// coordinate an SVG cannot hold was "not a number?".
#[test]
fn a_missing_or_vanished_key_and_an_impossible_coordinate_are_named() {
    let path = data("template_lips3.svg");
    let svg = std::fs::read_to_string(&path).unwrap();
    let err = |text: &str| {
        parse_template(Path::new("edited.svg"), text)
            .unwrap_err()
            .to_string()
    };
    // Scaled to zero.
    let (attr, ox, oy) = group_transform(&svg, 102);
    let zero = svg.replacen(
        &attr,
        &format!("transform=\"translate({ox} {oy}) scale(0)\""),
        1,
    );
    let e = err(&zero);
    assert!(e.contains("key-102 is missing or draws nothing"), "{e}");
    assert!(e.contains("2 of 3 here"), "{e}");
    // Deleted: the panel's group renamed away stands for a deletion (its ids go with it).
    let gone = svg.replace("id=\"key-102", "id=\"gone-102");
    let e = err(&gone);
    assert!(e.contains("key-102 is missing"), "{e}");
    // A coordinate of 1e300.
    let tag = "<polyline id=\"key-102-c0\"";
    let at = svg.find(tag).unwrap();
    let p = at + svg[at..].find("points=\"").unwrap() + "points=\"".len();
    let end = p + svg[p..].find([',', ' ']).unwrap();
    let big = format!("{}1e300{}", &svg[..p], &svg[end..]);
    let e = err(&big);
    assert!(
        e.contains("contour 'key-102-c0'")
            && e.contains("coordinate 1e300 is beyond what an SVG holds"),
        "{e}"
    );
}
