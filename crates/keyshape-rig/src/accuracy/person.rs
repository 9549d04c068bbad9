//! The benchmark's other person: the rig's neutral face deformed by a seeded, documented
//! amount, and made flatter or deeper (`Settings::other_depth`).

use super::Rig;
use rand::{Rng, SeedableRng};

/// Another person's neutral face: the rig's landmarks with a seeded, documented deformation —
/// the face 8 % wider, the mouth 3 % of the face height lower, the eyes 4 % of the
/// inter-ocular distance further apart, and three smooth bumps of up to 2 % of the face
/// width over the face. The rig's shape offsets are kept (the person moves as the rig does).
pub fn other_person(rig: &Rig, seed: u64) -> Rig {
    let mut rng = rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(seed ^ 0x5eed_face);
    let n = &rig.neutral;
    let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
    for p in n {
        for a in 0..3 {
            lo[a] = lo[a].min(p[a]);
            hi[a] = hi[a].max(p[a]);
        }
    }
    let (width, height) = (hi[0] - lo[0], hi[1] - lo[1]);
    let cx = (lo[0] + hi[0]) / 2.0;
    let iod = rig
        .eyes()
        .map_or(0.3 * width, |[a, b]| (n[b][0] - n[a][0]).abs());
    let (mouth, eyes) = parts(rig);
    let bumps: Vec<([f64; 2], f64, f64)> = (0..3)
        .map(|_| {
            (
                [rng.gen_range(lo[0]..hi[0]), rng.gen_range(lo[1]..hi[1])],
                rng.gen_range(0.15..0.3) * width,
                rng.gen_range(-0.02..0.02) * width,
            )
        })
        .collect();
    let mut neutral = n.clone();
    for (i, p) in neutral.iter_mut().enumerate() {
        p[0] = cx + 1.08 * (p[0] - cx);
        if mouth[i] {
            p[1] -= 0.03 * height;
        }
        if eyes[i] {
            p[0] += 0.02 * iod * (p[0] - cx).signum();
        }
        for (c, r, a) in &bumps {
            let d2 = ((p[0] - c[0]).powi(2) + (p[1] - c[1]).powi(2)) / (r * r);
            let g = a * (-d2).exp();
            p[0] += g;
            p[1] += 0.5 * g;
        }
    }
    Rig {
        neutral,
        ..rig.clone()
    }
}

/// `Settings::other_depth`: `person`'s depth about its mean scaled by a seeded factor,
/// 0.8–0.9 or 1.1–1.2.
pub(super) fn deepen(person: &mut Rig, seed: u64) {
    let mut rng = rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(seed ^ 0xdee9_face);
    let k = if rng.gen_bool(0.5) {
        rng.gen_range(0.8..0.9)
    } else {
        rng.gen_range(1.1..1.2)
    };
    let n = person.neutral.len().max(1) as f64;
    let mz = person.neutral.iter().map(|p| p[2]).sum::<f64>() / n;
    for p in person.neutral.iter_mut() {
        p[2] = mz + k * (p[2] - mz);
    }
}

/// Per landmark of `rig`: is it on the lips, is it on an eye (lids, corners, irises)? From
/// the track layout: iBUG 48–67 and 36–47; MediaPipe's `lips`, eye and iris groups.
fn parts(rig: &Rig) -> (Vec<bool>, Vec<bool>) {
    let layout = keyshape_core::sequence::Layout::for_points(rig.layout);
    let group = |names: &[&str]| -> Vec<usize> {
        layout.as_ref().map_or(Vec::new(), |l| {
            names
                .iter()
                .filter_map(|n| l.groups.get(*n))
                .flat_map(|g| g.points.iter().copied())
                .collect()
        })
    };
    let (lips, eyes) = if rig.layout == 68 {
        ((48..68).collect(), (36..48).collect())
    } else {
        (
            group(&["lips"]),
            group(&["left_eye", "right_eye", "left_iris", "right_iris"]),
        )
    };
    (
        rig.points.iter().map(|p| lips.contains(p)).collect(),
        rig.points.iter().map(|p| eyes.contains(p)).collect(),
    )
}
