//! The rig accuracy benchmark: performances rendered through a rig from known
//! weights — another person's neutral, a neutral lead-in, a moving head, landmark noise — are
//! solved back, and every shape's weights are measured against the truth: Pearson r, MAE,
//! RMSE, peak reach, twin leakage, idle activation, jitter and lag.
//!
//! Ground truth is the yardstick: nobody publishes per-blendshape accuracy against it, and
//! agreement with another estimator (py-feat) is not it.

use super::camera::Camera;
use super::refine::{refine_map, Refinement};
use super::{solve_rig, Rig, RigOptions};
use keyshape_core::error::{Error, Result};
use nalgebra::DMatrix;
use rand::{Rng, SeedableRng};
use serde::Serialize;

mod measure;
mod person;

pub use measure::{measure, twin, MapTruth, NeutralTruth, ShapeAccuracy, Summary};
use person::deepen;
pub use person::other_person;

/// The kind of performance rendered.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Kind {
    /// A dozen shapes active as smooth bumps of random width, height and time, overlapping.
    Smooth,
    /// One-sided expressions and winks: each one-sided shape alone to 1.0 in turn.
    Winks,
    /// Both eyes blinking to 1.0, briefly and often, over a mild smile.
    Blinks,
    /// Fast jaw motion like speech (3–6 opening cycles a second), with lip rounding.
    Speech,
}

impl Kind {
    /// Every kind, in the order reports list them.
    pub const ALL: [Kind; 4] = [Kind::Smooth, Kind::Winks, Kind::Blinks, Kind::Speech];

    /// The kind's name on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Kind::Smooth => "smooth",
            Kind::Winks => "winks",
            Kind::Blinks => "blinks",
            Kind::Speech => "speech",
        }
    }

    /// Parses a kind's name.
    pub fn parse(s: &str) -> Result<Kind> {
        Kind::ALL
            .into_iter()
            .find(|k| k.name() == s)
            .ok_or_else(|| {
                Error::bad_setting(
                    "performance",
                    s,
                    format!("'{s}' is not a performance kind (smooth, winks, blinks, speech)"),
                )
            })
    }
}

/// The shapes the smooth performance drives: among them those a 2-D solve most often loses
/// (jawRight, mouthFrown_L, mouthLowerDown_L, mouthUpperUp_L, eyeWide_L, mouthPucker).
pub const SMOOTH_SHAPES: [&str; 12] = [
    "jawOpen",
    "jawRight",
    "mouthSmile_L",
    "mouthSmile_R",
    "mouthFrown_L",
    "mouthLowerDown_L",
    "mouthUpperUp_L",
    "mouthPucker",
    "eyeBlink_R",
    "eyeWide_L",
    "browDown_R",
    "browInnerUp_L",
];

/// The one-sided shapes the wink performance raises alone, in turn.
pub const WINK_SHAPES: [&str; 6] = [
    "eyeBlink_L",
    "mouthSmile_L",
    "browDown_L",
    "eyeBlink_R",
    "mouthSmile_R",
    "browDown_R",
];

/// A benchmark track's settings.
#[derive(Debug, Clone, Serialize)]
pub struct Settings {
    /// The performance.
    pub kind: Kind,
    /// Frames of performance (after the lead-in).
    pub frames: usize,
    /// Neutral frames before the performance (the head moves; no shape is active).
    pub lead_in: usize,
    /// Landmark noise σ in pixels.
    pub noise_px: f64,
    /// The inter-ocular distance (outer eye corners) the face is drawn at, in pixels.
    pub iod_px: f64,
    /// Another person's neutral face (a seeded deformation of the rig's), or the rig's own.
    pub other_person: bool,
    /// Head yaw and pitch ranges, ± degrees.
    pub yaw_deg: f64,
    /// See `yaw_deg`.
    pub pitch_deg: f64,
    /// Seed of the performance, the person and the noise.
    pub seed: u64,
    /// Render each landmark's depth too, as MediaPipe gives it: a third row per landmark,
    /// in the x axis's pixels, more negative closer to the camera, its origin an arbitrary
    /// offset (here 40 px), with the same noise as x and y.
    pub depth: bool,
    /// With `other_person`, the other face's depth differs too: its depth about the face's
    /// mean depth scaled by a seeded 0.8–0.9 or 1.1–1.2 (a flatter or deeper face, a nose
    /// shorter or longer), which a frontal view barely shows and a turned head does.
    pub other_depth: bool,
    /// A held expression on every frame, the lead-in too, so no frame is neutral: a seeded
    /// mix of [`HOLD_SHAPES`] whose weights sum to `hold`, breathing slowly between 70 % and
    /// 100 % of it (the least expressive frame still holds 0.7 × `hold`). 0: none.
    pub hold: f64,
}

/// The shapes a held expression ([`Settings::hold`]) is mixed from: a face's resting
/// habits (a half smile, pressed lips, a squint, a raised inner brow), none of them a shape
/// the performances move.
pub const HOLD_SHAPES: [&str; 8] = [
    "mouthSmile_L",
    "mouthPress_L",
    "mouthPress_R",
    "cheekSquint_L",
    "cheekSquint_R",
    "eyeSquint_R",
    "browInnerUp_L",
    "mouthDimple_R",
];

impl Default for Settings {
    fn default() -> Self {
        Settings {
            kind: Kind::Smooth,
            frames: 300,
            lead_in: 20,
            noise_px: 0.5,
            iod_px: 107.0,
            other_person: true,
            yaw_deg: 18.0,
            pitch_deg: 9.0,
            seed: 7,
            depth: false,
            other_depth: false,
            hold: 0.0,
        }
    }
}

impl Settings {
    /// The hardest render for the neutral: another person whose face is deeper or flatter
    /// than the rig's (`--person deep`), no lead-in, the head turning ±35° yaw and ±20°
    /// pitch, 120 frames of `kind` (`kslab rig-accuracy --person deep --lead-in 0 --yaw 35
    /// --pitch 20 --frames 120`), so turned frames are among the neutral's candidates.
    pub fn turned_head(kind: Kind, seed: u64) -> Settings {
        Settings {
            kind,
            frames: 120,
            lead_in: 0,
            yaw_deg: 35.0,
            pitch_deg: 20.0,
            other_depth: true,
            seed,
            ..Settings::default()
        }
    }

    /// Refuses settings no track can be made from.
    pub fn check(&self) -> Result<()> {
        let bad =
            |what: &str, v: f64| Error::bad_setting(what, v, format!("{what} {v} is not allowed"));
        if self.frames < 2 || self.frames > 1_000_000 {
            return Err(bad("frames", self.frames as f64));
        }
        if self.lead_in > 1_000_000 {
            return Err(bad("lead-in", self.lead_in as f64));
        }
        keyshape_core::limits::NOISE_PX.check("noise", self.noise_px)?;
        for (what, v, hi) in [
            ("inter-ocular distance (px)", self.iod_px, 1e6),
            ("yaw (°)", self.yaw_deg, 80.0),
            ("pitch (°)", self.pitch_deg, 80.0),
        ] {
            if v.is_nan() || v < 0.0 || v > hi {
                return Err(Error::bad_setting(
                    what,
                    v,
                    format!("{what} {v} is not allowed: give a number in [0, {hi}]"),
                ));
            }
        }
        if self.iod_px <= 0.0 {
            return Err(bad("inter-ocular distance (px)", self.iod_px));
        }
        if !(self.hold.is_finite() && (0.0..=3.0).contains(&self.hold)) {
            return Err(Error::bad_setting(
                "hold",
                self.hold,
                format!(
                    "a held expression of {} is not allowed: give its total weight in [0, 3]",
                    self.hold
                ),
            ));
        }
        Ok(())
    }
}

/// A rendered benchmark track: the truth and what a tracker would see.
#[derive(Debug, Clone)]
pub struct Track {
    /// True weights, k × frames (rig order), the lead-in first.
    pub truth: DMatrix<f64>,
    /// The landmarks (image axes, y down), 2 rows each (x, y) or with `depth` 3 (x, y, z),
    /// noise included.
    pub points: DMatrix<f64>,
    /// The person whose face was rendered (the rig with another neutral, or the rig).
    pub person: Rig,
    /// Per frame, the camera.
    pub cameras: Vec<Camera>,
}

fn index(rig: &Rig, name: &str) -> Result<usize> {
    rig.names
        .iter()
        .position(|n| n == name)
        .ok_or_else(|| Error::invalid(format!("the rig has no shape '{name}'")))
}

/// A raised-cosine bump of `height` centred at `c`, `width` frames wide at its base.
fn bump(t: f64, c: f64, width: f64, height: f64) -> f64 {
    let x = (t - c) / (width / 2.0);
    if x.abs() >= 1.0 {
        0.0
    } else {
        height * 0.5 * (1.0 + (std::f64::consts::PI * x).cos())
    }
}

/// The true weights of a performance (without lead-in), k × frames.
pub fn performance(
    rig: &Rig,
    kind: Kind,
    frames: usize,
    rng: &mut impl Rng,
) -> Result<DMatrix<f64>> {
    let mut w: DMatrix<f64> = DMatrix::zeros(rig.k(), frames);
    let n = frames as f64;
    match kind {
        Kind::Smooth => {
            for name in SMOOTH_SHAPES {
                let s = index(rig, name)?;
                // About one bump per 100 frames per shape, at least two.
                let bumps = ((n / 100.0).round() as usize).max(2);
                for _ in 0..bumps {
                    let (c, width, h) = (
                        rng.gen_range(0.0..n),
                        rng.gen_range(20.0..80.0),
                        rng.gen_range(0.3..1.0),
                    );
                    for f in 0..frames {
                        w[(s, f)] = (w[(s, f)] + bump(f as f64, c, width, h)).min(1.0);
                    }
                }
            }
            // A weight that two bumps carry past 1 is held at 1: a flat top is a peak too.
        }
        Kind::Winks => {
            let ids: Vec<usize> = WINK_SHAPES
                .iter()
                .map(|s| index(rig, s))
                .collect::<Result<_>>()?;
            let slot = n / ids.len() as f64;
            for (j, &s) in ids.iter().enumerate() {
                let c = slot * (j as f64 + 0.5);
                for f in 0..frames {
                    // A plateau at 1.0 for a third of the bump, so peaks are held.
                    let v = bump(f as f64, c, 0.8 * slot, 1.5).min(1.0);
                    w[(s, f)] = v;
                }
            }
        }
        Kind::Blinks => {
            let (l, r, sl, sr) = (
                index(rig, "eyeBlink_L")?,
                index(rig, "eyeBlink_R")?,
                index(rig, "mouthSmile_L")?,
                index(rig, "mouthSmile_R")?,
            );
            let mut c = rng.gen_range(10.0..30.0);
            while c < n {
                for f in 0..frames {
                    let v = bump(f as f64, c, 10.0, 1.6).min(1.0);
                    if v > 0.0 {
                        w[(l, f)] = v;
                        w[(r, f)] = v;
                    }
                }
                c += rng.gen_range(25.0..70.0);
            }
            for f in 0..frames {
                let v = 0.3 + 0.1 * (f as f64 / 40.0).sin();
                w[(sl, f)] = v;
                w[(sr, f)] = v;
            }
        }
        Kind::Speech => {
            let (jaw, funnel, pucker) = (
                index(rig, "jawOpen")?,
                index(rig, "mouthFunnel")?,
                index(rig, "mouthPucker")?,
            );
            let mut phase = 0.0f64;
            let mut rate = rng.gen_range(3.0..6.0);
            for f in 0..frames {
                if f % 30 == 0 {
                    rate = rng.gen_range(3.0..6.0);
                }
                phase += std::f64::consts::TAU * rate / 30.0;
                w[(jaw, f)] = 0.35 * (1.0 - phase.cos());
            }
            for (s, every) in [(funnel, 90.0), (pucker, 130.0)] {
                let mut c = rng.gen_range(0.0..every);
                while c < n {
                    for f in 0..frames {
                        w[(s, f)] = (w[(s, f)] + bump(f as f64, c, 24.0, 0.7)).min(1.0);
                    }
                    c += every;
                }
            }
        }
    }
    Ok(w)
}

/// Adds a held expression summing to `total` ([`Settings::hold`]) to every frame of
/// `truth`, each weight held at most 1.
fn hold_expression(
    rig: &Rig,
    truth: &mut DMatrix<f64>,
    total: f64,
    rng: &mut impl Rng,
) -> Result<()> {
    // Three of the shapes, their shares seeded; a share past 1 is spread no further.
    let mut picks: Vec<usize> = Vec::new();
    while picks.len() < 3 {
        let s = index(rig, HOLD_SHAPES[rng.gen_range(0..HOLD_SHAPES.len())])?;
        if !picks.contains(&s) {
            picks.push(s);
        }
    }
    let shares: Vec<f64> = (0..3).map(|_| rng.gen_range(0.5..1.0)).collect();
    let sum: f64 = shares.iter().sum();
    let phase = rng.gen_range(0.0..std::f64::consts::TAU);
    for f in 0..truth.ncols() {
        let breath = 0.85 + 0.15 * (std::f64::consts::TAU * f as f64 / 150.0 + phase).sin();
        for (&s, share) in picks.iter().zip(&shares) {
            let v = truth[(s, f)] + total * share / sum * breath;
            truth[(s, f)] = v.min(1.0);
        }
    }
    Ok(())
}

/// Renders the benchmark track of `st` through `rig`.
pub fn render(rig: &Rig, st: &Settings) -> Result<Track> {
    st.check()?;
    let Some([ea, eb]) = rig.eyes() else {
        return Err(Error::invalid(
            "the benchmark draws the face at an inter-ocular distance: the rig must read both outer eye corners",
        ));
    };
    let mut rng = rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(st.seed);
    let perf = performance(rig, st.kind, st.frames, &mut rng)?;
    let total = st.lead_in + st.frames;
    let mut truth = DMatrix::zeros(rig.k(), total);
    truth.columns_mut(st.lead_in, st.frames).copy_from(&perf);
    if st.hold > 0.0 {
        hold_expression(rig, &mut truth, st.hold, &mut rng)?;
    }
    let person = if st.other_person {
        let mut p = other_person(rig, st.seed);
        if st.other_depth {
            deepen(&mut p, st.seed);
        }
        p
    } else {
        rig.clone()
    };
    let iod = {
        let (a, b) = (rig.neutral[ea], rig.neutral[eb]);
        ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2)).sqrt()
    };
    if iod.is_nan() || iod <= 0.0 {
        return Err(Error::unfit("the rig's outer eye corners coincide"));
    }
    let scale = st.iod_px / iod;
    let cameras: Vec<Camera> = (0..total)
        .map(|f| {
            let t = f as f64 / 30.0;
            Camera::from_angles(
                scale,
                st.yaw_deg.to_radians() * (std::f64::consts::TAU * t / 7.3).sin(),
                st.pitch_deg.to_radians() * (std::f64::consts::TAU * t / 5.1 + 1.0).sin(),
                4f64.to_radians() * (std::f64::consts::TAU * t / 9.7 + 2.0).sin(),
                [320.0, -240.0],
            )
        })
        .collect();
    let mut points = if st.depth {
        let n = person.landmarks();
        let mut out = DMatrix::zeros(3 * n, total);
        for f in 0..total {
            let w: Vec<f64> = truth.column(f).iter().copied().collect();
            let c = &cameras[f];
            for (i, p) in person.posed(&w).iter().enumerate() {
                let u = c.project(p);
                let z = c.depth(p);
                out[(3 * i, f)] = u[0];
                out[(3 * i + 1, f)] = -u[1];
                out[(3 * i + 2, f)] = -(z + 40.0);
            }
        }
        out
    } else {
        person.render(&truth, &cameras)
    };
    if st.noise_px > 0.0 {
        for v in points.iter_mut() {
            let (u1, u2): (f64, f64) = (rng.gen_range(f64::EPSILON..1.0), rng.gen());
            *v += st.noise_px * (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos();
        }
    }
    Ok(Track {
        truth,
        points,
        person,
        cameras,
    })
}

/// Renders the track of `st`, solves it with `opts` and measures every shape.
pub fn run(
    rig: &Rig,
    st: &Settings,
    opts: &RigOptions,
) -> Result<(Track, DMatrix<f64>, Vec<ShapeAccuracy>, Summary)> {
    run_mapped(rig, rig, st, opts)
}

/// [`run`], rendering through `render_rig` (the same shapes and track points as `rig`, its
/// landmarks elsewhere: [`mapped_elsewhere`]) and solving with `rig`.
pub fn run_mapped(
    rig: &Rig,
    render_rig: &Rig,
    st: &Settings,
    opts: &RigOptions,
) -> Result<(Track, DMatrix<f64>, Vec<ShapeAccuracy>, Summary)> {
    solve_rendered(rig, render_rig, st, &mut |track| {
        Ok((solve_rig(rig, &track.points, &[], opts)?, None))
    })
}

/// [`run_mapped`], solving with the map refined from the track ([`refine_map`] over the
/// mesh `positions` with shapes `morph`), and measuring the refined map against the one the
/// track was rendered through ([`Summary::map`]).
pub fn run_refined(
    rig: &Rig,
    render_rig: &Rig,
    mesh: (&[[f64; 3]], &keyshape_io::morph::MorphTargets),
    refinement: Refinement,
    st: &Settings,
    opts: &RigOptions,
) -> Result<(Track, DMatrix<f64>, Vec<ShapeAccuracy>, Summary)> {
    let positions = mesh.0;
    solve_rendered(rig, render_rig, st, &mut |track| {
        let refined = refine_map(mesh, rig, &track.points, &[], opts, refinement, &mut |_| {})?;
        let truth = MapTruth::of(positions, render_rig, rig, &refined.rig, &refined.moved);
        Ok((refined.solve, Some(truth)))
    })
}

/// A rendered track's solve, and how the map it solved with compares with the render's.
type Solved = (crate::RigSolve, Option<MapTruth>);

/// Renders `st` through `render_rig`, solves it with `solve` (the solve, and how the map
/// it solved with compares with the render's) and measures it.
fn solve_rendered(
    rig: &Rig,
    render_rig: &Rig,
    st: &Settings,
    solve: &mut dyn FnMut(&Track) -> Result<Solved>,
) -> Result<(Track, DMatrix<f64>, Vec<ShapeAccuracy>, Summary)> {
    if render_rig.names != rig.names || render_rig.points != rig.points {
        return Err(Error::invalid(
            "the rendering rig must have the solving rig's shapes and track points",
        ));
    }
    let track = render(render_rig, st)?;
    let (solved, map) = solve(&track)?;
    let (rows, mut summary) = measure(&rig.names, &track.truth, &solved.weights);
    summary.neutral = solved.neutral_views.first().map(|v| NeutralTruth {
        frame: v.frame,
        true_expression: track.truth.column(v.frame).sum(),
        true_turn: track.cameras[v.frame].r[(2, 2)]
            .clamp(-1.0, 1.0)
            .acos()
            .to_degrees(),
        view: *v,
    });
    summary.map = map;
    Ok((track, solved.weights, rows, summary))
}

/// The rig as a tracker whose points are not where the landmark map says would render it:
/// each landmark of `rig` moved to a random vertex of the mesh (`positions`, with the
/// shapes `morph`) within `radius` (rig units; the ICT face is in cm) of the map's vertex,
/// seeded — the benchmark's `--map-noise`. A landmark that is no mesh vertex (a virtual
/// iris) is refused.
pub fn mapped_elsewhere(
    positions: &[[f64; 3]],
    morph: &keyshape_io::morph::MorphTargets,
    rig: &Rig,
    radius: f64,
    seed: u64,
) -> Result<Rig> {
    if !(radius.is_finite() && radius >= 0.0) {
        return Err(Error::bad_setting(
            "map_noise",
            radius,
            format!("a landmark map error of {radius} is not allowed: give a distance ≥ 0"),
        ));
    }
    let mut rng = rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(seed ^ 0x0a11_ce55);
    let d2 = |a: &[f64; 3], b: &[f64; 3]| (0..3).map(|k| (a[k] - b[k]).powi(2)).sum::<f64>();
    let mut pairs = Vec::with_capacity(rig.landmarks());
    for (l, p) in rig.neutral.iter().enumerate() {
        let Some(v) = positions.iter().position(|q| q == p) else {
            return Err(Error::invalid(format!(
                "track point {} is no vertex of the rig's mesh (a virtual point): its map cannot be perturbed",
                rig.points[l]
            )));
        };
        let near: Vec<usize> = (0..positions.len())
            .filter(|&u| d2(&positions[u], &positions[v]) <= radius * radius)
            .collect();
        pairs.push((rig.points[l], near[rng.gen_range(0..near.len())]));
    }
    Rig::from_correspondence(positions, morph, rig.layout, &pairs)
}
