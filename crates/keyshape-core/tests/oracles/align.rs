//! Alignment undoes similarity transforms and keeps the head motion it removed.

use keyshape_core::align::procrustes;
use nalgebra::DMatrix;
use proptest::prelude::*;

proptest! {
    #[test]
    fn alignment_undoes_a_random_similarity(
        pts in prop::collection::vec(-50.0f64..50.0, 2 * 12),
        wobble in prop::collection::vec(-1.0f64..1.0, 2 * 12),
        angle in -3.0f64..3.0, scale in 0.3f64..3.0, tx in -100.0f64..100.0, ty in -100.0f64..100.0,
    ) {
        let spread: f64 = pts.iter().map(|v| v * v).sum();
        prop_assume!(spread > 100.0);
        // Frame 0: a shape; frame 1: a slightly different shape; frame 2: frame 1 moved.
        let a = DMatrix::from_column_slice(24, 1, &pts);
        let b: Vec<f64> = pts.iter().zip(&wobble).map(|(p, w)| p + w).collect();
        let (s, c) = angle.sin_cos();
        let moved: Vec<f64> = b
            .chunks(2)
            .flat_map(|p| [scale * (c * p[0] - s * p[1]) + tx, scale * (s * p[0] + c * p[1]) + ty])
            .collect();
        let q = DMatrix::from_columns(&[a.column(0).clone_owned(), DMatrix::from_column_slice(24, 1, &b).column(0).clone_owned(), DMatrix::from_column_slice(24, 1, &moved).column(0).clone_owned()]);
        let al = procrustes(&q, 2).unwrap();
        // Frames 1 and 2 differ only by a similarity: aligned they coincide.
        let d = (al.coords.column(1) - al.coords.column(2)).amax();
        prop_assert!(d < 1e-8 * (1.0 + spread.sqrt()), "aligned frames differ by {d}");
        // Head motion puts every frame back where it was.
        for j in 0..3 {
            let back = al.head[j].apply(al.coords.column(j).as_slice(), 2);
            for (x, y) in back.iter().zip(q.column(j).iter()) {
                prop_assert!((x - y).abs() < 1e-8 * (1.0 + y.abs()));
            }
        }
        // The relative head motion of frame 2 against frame 1 is the applied transform.
        prop_assert!((al.head[2].scale / al.head[1].scale - scale).abs() < 1e-8 * scale);
    }
}

#[test]
fn three_d_tracks_align_in_the_image_plane_and_round_trip() {
    use keyshape_io::{read_sequence, ReadOptions};
    for (rel, points) in [
        ("pyfeat_samples/openface_test.csv", 68),
        ("mediapipe_face_tracks/liveportrait_d18.csv", 468),
    ] {
        let opts = ReadOptions {
            format: None,
            dims: 3,
        };
        let seq = read_sequence(&crate::common::shared(rel), &opts).unwrap();
        assert_eq!((seq.dims, seq.points), (3, points));
        let al = procrustes(&seq.coords, 3).unwrap();
        for j in [0, seq.n_frames() / 2, seq.n_frames() - 1] {
            let back = al.head[j].apply(al.coords.column(j).as_slice(), 3);
            let d = back
                .iter()
                .zip(seq.coords.column(j).iter())
                .map(|(a, b)| (a - b).abs())
                .fold(0.0, f64::max);
            assert!(d < 1e-9, "{rel} frame {j}: round trip off by {d}");
        }
    }
}
