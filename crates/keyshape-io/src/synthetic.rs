//! Long synthetic tracks for scale tests and `kslab bench scale`: real shapes of
//! the built-in sequence (216 frames of MediaPipe's 468 points, or the 68 iBUG points read
//! through the built-in 468 → 68 correspondence), strung together smoothly for as many
//! frames as asked. Every 12 frames the track heads for another real frame (a smoothstep
//! blend between them), under a slow head drift (±12 px, ±4°, ±4 % scale) and Gaussian
//! tracking noise of 0.3 px. Written row by row, so a 300,000-frame file never sits in
//! memory.

use keyshape_core::error::{Error, Result};
use rand::{Rng, SeedableRng};
use std::io::Write;

/// Frames between the real shapes the track passes through.
const KNOT: usize = 12;

/// Writes a `frames`-frame track of `points` (68 or 468) points in the plain CSV format
/// (`frame,time_s,x0,y0,…`, 30 fps) to `w`, seeded.
pub fn write_long_track(w: &mut dyn Write, frames: usize, points: usize, seed: u64) -> Result<()> {
    let seq = super::builtin_sequence()?;
    let pick: Vec<usize> = match points {
        468 => (0..468).collect(),
        68 => keyshape_core::sequence::mediapipe_to_ibug68()?,
        _ => {
            return Err(Error::bad_setting(
                "points",
                points,
                format!("a generated track has 68 or 468 points, not {points}"),
            ))
        }
    };
    let real = seq.coords.ncols();
    let shape = |c: usize| -> Vec<[f64; 2]> {
        pick.iter()
            .map(|&p| [seq.coords[(2 * p, c)], seq.coords[(2 * p + 1, c)]])
            .collect()
    };
    let centre: [f64; 2] = {
        let s = shape(0);
        let n = s.len() as f64;
        [
            s.iter().map(|p| p[0]).sum::<f64>() / n,
            s.iter().map(|p| p[1]).sum::<f64>() / n,
        ]
    };
    let mut rng = rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(seed);
    let gauss = move |rng: &mut rand_xoshiro::Xoshiro256PlusPlus| {
        // Box–Muller.
        let (u, v): (f64, f64) = (rng.gen_range(f64::EPSILON..1.0), rng.gen());
        (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
    };
    // Slow drift: a sum of three sinusoids per parameter with random phases.
    let phases: Vec<f64> = (0..12)
        .map(|_| rng.gen_range(0.0..std::f64::consts::TAU))
        .collect();
    let drift = |t: f64, i: usize| {
        ((t / 997.0 + phases[3 * i]).sin()
            + 0.5 * (t / 251.0 + phases[3 * i + 1]).sin()
            + 0.25 * (t / 61.0 + phases[3 * i + 2]).sin())
            / 1.75
    };
    let failed = |e: std::io::Error| Error::invalid(format!("writing the track: {e}"));
    let mut out = crate::csv_out::record_writer(w);
    let header = ["frame".to_string(), "time_s".to_string()]
        .into_iter()
        .chain((0..points).flat_map(|p| [format!("x{p}"), format!("y{p}")]));
    out.write_record(header)
        .map_err(|e| failed(crate::csv_out::io_error(e)))?;
    // One field buffer reused for every value: a 300,000-frame track has 41 million.
    let mut field = String::with_capacity(32);
    let mut put = |out: &mut csv::Writer<&mut dyn Write>, v: std::fmt::Arguments| {
        field.clear();
        // Formatting into a String cannot fail.
        let _ = std::fmt::Write::write_fmt(&mut field, v);
        out.write_field(&field)
    };
    let (mut from, mut to) = (shape(rng.gen_range(0..real)), shape(rng.gen_range(0..real)));
    for f in 0..frames {
        if f > 0 && f % KNOT == 0 {
            from = std::mem::replace(&mut to, shape(rng.gen_range(0..real)));
        }
        let s = (f % KNOT) as f64 / KNOT as f64;
        let a = s * s * (3.0 - 2.0 * s);
        let t = f as f64;
        let (tx, ty) = (12.0 * drift(t, 0), 12.0 * drift(t, 1));
        let (angle, scale) = (4f64.to_radians() * drift(t, 2), 1.0 + 0.04 * drift(t, 3));
        let (sn, cs) = angle.sin_cos();
        let mut row = || -> csv::Result<()> {
            put(&mut out, format_args!("{f}"))?;
            put(&mut out, format_args!("{}", super::fmt_num(t / 30.0)))?;
            for p in 0..points {
                let x = (1.0 - a) * from[p][0] + a * to[p][0] - centre[0];
                let y = (1.0 - a) * from[p][1] + a * to[p][1] - centre[1];
                let gx = centre[0] + scale * (cs * x - sn * y) + tx + 0.3 * gauss(&mut rng);
                let gy = centre[1] + scale * (sn * x + cs * y) + ty + 0.3 * gauss(&mut rng);
                put(&mut out, format_args!("{gx:.3}"))?;
                put(&mut out, format_args!("{gy:.3}"))?;
            }
            out.write_record(None::<&[u8]>)
        };
        row().map_err(|e| failed(crate::csv_out::io_error(e)))?;
    }
    out.flush().map_err(failed)
}
