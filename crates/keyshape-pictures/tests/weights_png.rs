//! The weights-over-time picture (`solve --png`, `retarget --png`): each cell's colour is
//! the diverging scale at that weight, a one-frame spike survives when frames outnumber
//! pixels, and the commands write it (and refuse to write it over their input).
//! (What runs the `kslab` binary is in `tests/it/weights_png.rs`.)

// Test code: a failed unwrap is a failed test with its message.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use keyshape_pictures::render::weights::{diverging, weights_picture};
use nalgebra::DMatrix;
fn pixel(pm: &tiny_skia::Pixmap, x: u32, y: u32) -> [u8; 3] {
    let p = pm.pixel(x, y).unwrap();
    [p.red(), p.green(), p.blue()]
}

#[test]
fn cells_carry_the_diverging_colour_of_their_weight() {
    assert_eq!(diverging(0.0, 1.0), [255, 255, 255]);
    assert_eq!(diverging(1.0, 1.0), [20, 70, 190]);
    assert_eq!(diverging(-1.0, 1.0), [200, 20, 20]);
    assert_eq!(diverging(-5.0, 1.0), [200, 20, 20], "clamped");
    // Two keys, 2,200 frames (two frames a pixel column): key 0 is 0.5 everywhere but one
    // frame at −1; key 1 is 0 but a spike of 1 at frame 2,000.
    let n = 2200;
    let mut w = DMatrix::from_fn(2, n, |i, _| if i == 0 { 0.5 } else { 0.0 });
    w[(0, 1000)] = -1.0;
    w[(1, 2000)] = 1.0;
    let labels = vec!["w_3".to_string(), "w_40".to_string()];
    let frames: Vec<i64> = (0..n as i64).collect();
    let pm = weights_picture(&w, &labels, &frames, "test").unwrap();
    // Layout: plot from x = 110, 1,100 px wide; rows from y = 46, 28 px each (2 keys).
    let (left, top, row) = (110u32, 46u32, 28u32);
    let col = |t: usize| left + (t * 1100 / n) as u32;
    assert_eq!(pixel(&pm, col(10), top + row / 2), diverging(0.5, 1.0));
    assert_eq!(pixel(&pm, col(1000), top + row / 2), diverging(-1.0, 1.0));
    assert_eq!(pixel(&pm, col(10), top + row + row / 2), [255, 255, 255]);
    assert_eq!(
        pixel(&pm, col(2000), top + row + row / 2),
        diverging(1.0, 1.0)
    );
    assert!(weights_picture(&w, &labels[..1], &frames, "t").is_err());
}

/// NNLS / bounded weights have no negative half: the scale runs 0 … max, and the key frames
/// are marked on the time axis.
#[test]
fn nonnegative_weights_get_a_one_sided_scale_and_marked_key_frames() {
    use keyshape_pictures::render::weights::weights_picture_marked;
    let n = 1100;
    let w = DMatrix::from_fn(2, n, |i, t| if (t / 100) % 2 == i { 1.0 } else { 0.0 });
    let labels = vec!["w_3".to_string(), "w_550".to_string()];
    let frames: Vec<i64> = (0..n as i64).collect();
    let pm = weights_picture_marked(&w, &labels, &frames, "t", &[3, 550]).unwrap();
    // Layout: plot from x = 110, 1,100 px wide; rows from y = 46, 28 px each; the axis at
    // y = 46 + 56; the scale 400 px wide, centred under the plot, 52 px below the axis.
    let (left, axis) = (110u32, 46u32 + 56);
    let x = |t: u32| left + t;
    assert_eq!(
        pixel(&pm, x(550), axis + 4),
        [230, 120, 0],
        "key frame 550 marked"
    );
    assert_eq!(
        pixel(&pm, x(3), axis + 4),
        [230, 120, 0],
        "key frame 3 marked"
    );
    assert_ne!(
        pixel(&pm, x(300), axis + 4),
        [230, 120, 0],
        "no mark elsewhere"
    );
    let (sx, sy) = (left + 550 - 200, axis + 52 + 7);
    assert_eq!(
        pixel(&pm, sx, sy),
        [255, 255, 255],
        "the scale starts at 0 (white)"
    );
    assert_eq!(
        pixel(&pm, sx + 399, sy),
        diverging(1.0, 1.0),
        "and ends at the largest weight"
    );
    // With a negative weight the scale is two-sided again: red at its left end.
    let mut neg = w.clone();
    neg[(0, 10)] = -1.0;
    let pm = weights_picture_marked(&neg, &labels, &frames, "t", &[]).unwrap();
    assert_eq!(pixel(&pm, sx, sy), diverging(-1.0, 1.0));
}
