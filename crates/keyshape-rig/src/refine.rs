//! A landmark map refined from the performance itself: a tracker's points are not where
//! any fixed map says (the built-in 468 → ICT map and another careful derivation agree on
//! the vertex for 44 of 468 points), and a map wrong by millimetres turns into false
//! expressions.
//!
//! The refinement alternates the solve and the map. The solve weighs landmarks robustly
//! ([`RigOptions::robust`]), so the few the map gets badly wrong do not drag the weights and
//! cameras with them. Then each landmark, on its own, moves to the mesh vertex within a
//! radius of the map's that best explains its track over the frames under those weights and
//! cameras: the vertex's neutral position plus its shape offsets posed by each frame's
//! weights, projected by each frame's camera, with a constant 3-D offset per clip fitted
//! freely (the identity's share, which the person's neutral takes up anyway). What tells
//! vertices apart is how they move, not where they rest. A landmark moves only when the
//! best vertex explains its track clearly better ([`MOVE_GAIN`]) than where it sits, so
//! landmarks on parts no shape moves stay where the map put them.
//!
//! What it finds (`rig-accuracy --map-noise 3 --refine-landmarks`): without landmark noise,
//! the vertices the track was rendered through (153 → 341 of 462). At 0.5 px, a map that
//! moves as the track does under the shapes the performance uses, not the tracker's true
//! points — the weights come back (468 points, speech: mean r 0.956 robust → 0.976 refined,
//! 0.987 with the right map), yet on speech the moved landmarks end farther from the
//! render's vertices more often than nearer. A map refined on one take fits that take's
//! expressions.

use super::camera::Camera;
use super::{solve_rig_observed, Rig, RigOptions, RigSolve};
use keyshape_core::error::{Error, Result};
use keyshape_io::morph::MorphTargets;
use nalgebra::{DMatrix, Matrix3, Vector3};
use rayon::prelude::*;
use std::ops::Range;

/// A landmark moves only when the best vertex's residual is below this share of its
/// current vertex's. Tuned on `rig-accuracy --map-noise 3 --refine-landmarks` (468 points,
/// seeds 1–10): 0.8 moves landmarks that explain the weights' own errors on speech (mean r
/// 0.937, below the robust solve's 0.956); 0.3 gives 0.976 there and keeps smooth at 0.990.
pub const MOVE_GAIN: f64 = 0.3;

/// Residuals (squared image units summed over the frames) closer than this are a tie.
const TIE_PX2: f64 = 1e-9;

/// The refinement's settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Refinement {
    /// How far (rig units: the ICT face is in centimetres) a landmark may move from the
    /// map's vertex.
    pub radius: f64,
    /// Rounds of solve-then-move.
    pub rounds: usize,
}

impl Default for Refinement {
    fn default() -> Self {
        Refinement {
            radius: 1.0,
            rounds: 3,
        }
    }
}

/// A refined map, the rig read through it and the track solved with it.
#[derive(Debug, Clone)]
pub struct Refined {
    /// The rig with its landmarks on the refined vertices (virtual points unchanged).
    pub rig: Rig,
    /// The track solved with `rig` (robust landmark weights).
    pub solve: RigSolve,
    /// (track point, vertex) of every landmark that is a mesh vertex, in the rig's order.
    pub pairs: Vec<(usize, usize)>,
    /// Per round, the landmarks it moved.
    pub moved: Vec<usize>,
    /// Landmarks on a vertex other than the map's at the end.
    pub changed: usize,
}

/// Solves `track` with `rig` (as [`solve_rig_observed`], landmarks weighed robustly), then
/// refines the map `rounds` times: every landmark that is a vertex of the rig's `mesh`
/// (positions, and the shapes' morph targets) moves to the vertex within `radius` of the map's that best
/// explains its track, and the track is solved again.
pub fn refine_map(
    mesh: (&[[f64; 3]], &MorphTargets),
    rig: &Rig,
    track: &DMatrix<f64>,
    clips: &[Range<usize>],
    opts: &RigOptions,
    settings: Refinement,
    step: &mut dyn FnMut(String),
) -> Result<Refined> {
    let (positions, morph) = mesh;
    check(rig, morph, opts, &settings)?;
    let opts = RigOptions {
        robust: true,
        ..*opts
    };
    let (start, candidates) = start_and_candidates(rig, positions, settings.radius)?;
    let offsets = vertex_offsets(morph, positions.len(), &candidates);
    let image = image_rows(track, rig.landmarks());
    let mut current = start.clone();
    let mut rig_now = rig.clone();
    let mut moved = Vec::new();
    // The solve of the map as it stands, when no landmark has moved since.
    let mut settled = None;
    for round in 1..=settings.rounds {
        step(format!(
            "refining the landmark map (round {round} of {}): solving",
            settings.rounds
        ));
        let solve = solve_rig_observed(&rig_now, track, clips, &opts, &mut |_| {})?;
        step(format!(
            "refining the landmark map (round {round} of {}): each landmark's vertex",
            settings.rounds
        ));
        let fit = Fit {
            image: &image,
            weights: &solve.weights,
            cameras: &solve.cameras,
            clips: solve.people.iter().map(|p| p.0.clone()).collect(),
        };
        let next: Vec<Option<usize>> = (0..rig.landmarks())
            .into_par_iter()
            .map(|l| Some(fit.next_vertex(l, current[l]?, &candidates[l], positions, &offsets)))
            .collect();
        let n_moved = next.iter().zip(&current).filter(|(a, b)| a != b).count();
        moved.push(n_moved);
        if n_moved == 0 {
            settled = Some(solve);
            break;
        }
        current = next;
        rig_now = with_vertices(rig, positions, &offsets, &current);
    }
    let solve = match settled {
        Some(solve) => solve,
        None => {
            step("refining the landmark map: the last solve".to_string());
            solve_rig_observed(&rig_now, track, clips, &opts, &mut |_| {})?
        }
    };
    let pairs = current
        .iter()
        .enumerate()
        .filter_map(|(l, v)| v.map(|v| (rig.points[l], v)))
        .collect();
    let changed = current.iter().zip(&start).filter(|(a, b)| a != b).count();
    Ok(Refined {
        rig: rig_now,
        solve,
        pairs,
        moved,
        changed,
    })
}

/// What the refinement refuses: a radius that is no distance, no round, a causal solve,
/// and shapes that are not the rig's.
fn check(rig: &Rig, morph: &MorphTargets, opts: &RigOptions, settings: &Refinement) -> Result<()> {
    if !(settings.radius.is_finite() && settings.radius > 0.0) {
        return Err(Error::bad_setting(
            "refine_radius",
            settings.radius,
            format!(
                "the landmark refinement's radius must be a distance > 0, not {}",
                settings.radius
            ),
        ));
    }
    if settings.rounds == 0 {
        return Err(Error::bad_setting(
            "refine_rounds",
            0,
            "the landmark refinement needs at least one round",
        ));
    }
    if opts.causal {
        return Err(Error::invalid(
            "a causal solve cannot refine the landmark map: that measures each landmark over the whole track",
        ));
    }
    if morph.names != rig.names {
        return Err(Error::invalid(
            "the landmark refinement's shapes must be the rig's",
        ));
    }
    Ok(())
}

/// Each landmark's vertex in the map (None for a landmark on no vertex), and the vertices
/// within `radius` of it, its candidates.
#[allow(clippy::type_complexity)]
fn start_and_candidates(
    rig: &Rig,
    positions: &[[f64; 3]],
    radius: f64,
) -> Result<(Vec<Option<usize>>, Vec<Vec<usize>>)> {
    let start: Vec<Option<usize>> = rig
        .neutral
        .iter()
        .map(|p| positions.iter().position(|q| q == p))
        .collect();
    if start.iter().all(Option::is_none) {
        return Err(Error::unfit(
            "no landmark of the rig is a vertex of the mesh: there is no map to refine",
        ));
    }
    let r2 = radius * radius;
    let candidates: Vec<Vec<usize>> = start
        .par_iter()
        .map(|v| match v {
            Some(v) => (0..positions.len())
                .filter(|&u| d2(&positions[u], &positions[*v]) <= r2)
                .collect(),
            None => Vec::new(),
        })
        .collect();
    Ok((start, candidates))
}

/// The squared distance between two points.
fn d2(a: &[f64; 3], b: &[f64; 3]) -> f64 {
    (0..3).map(|k| (a[k] - b[k]).powi(2)).sum::<f64>()
}

/// The image rows (x, y per landmark) of a track with 2 or 3 rows per landmark.
fn image_rows(track: &DMatrix<f64>, n: usize) -> DMatrix<f64> {
    if track.nrows() == 3 * n {
        let xy: Vec<usize> = (0..n).flat_map(|i| [3 * i, 3 * i + 1]).collect();
        track.select_rows(&xy)
    } else {
        track.clone()
    }
}

/// Per vertex, its offset in each shape (only for the vertices some landmark may take;
/// empty for the rest).
fn vertex_offsets(
    morph: &MorphTargets,
    vertices: usize,
    candidates: &[Vec<usize>],
) -> Vec<Vec<[f64; 3]>> {
    let mut out = vec![Vec::new(); vertices];
    for &v in candidates.iter().flatten() {
        out[v] = vec![[0.0; 3]; morph.names.len()];
    }
    for (s, d) in morph.deltas.iter().enumerate() {
        for &(v, o) in d {
            if let Some(slot) = out.get_mut(v).filter(|x| !x.is_empty()) {
                slot[s] = o;
            }
        }
    }
    out
}

/// `rig` with landmark `l` on vertex `vertices[l]` (None: unchanged).
fn with_vertices(
    rig: &Rig,
    positions: &[[f64; 3]],
    offsets: &[Vec<[f64; 3]>],
    vertices: &[Option<usize>],
) -> Rig {
    let mut out = rig.clone();
    for (l, v) in vertices.iter().enumerate() {
        if let Some(v) = *v {
            out.neutral[l] = positions[v];
            for (s, d) in out.deltas.iter_mut().enumerate() {
                d[l] = offsets[v][s];
            }
        }
    }
    out
}

/// A solve's weights and cameras, against which a landmark's candidate vertices are scored.
struct Fit<'a> {
    image: &'a DMatrix<f64>,
    weights: &'a DMatrix<f64>,
    cameras: &'a [Camera],
    clips: Vec<Range<usize>>,
}

impl Fit<'_> {
    /// The vertex landmark `l` takes next, from `cur` among its `candidates`: the one whose
    /// residual is least, when it leaves less than [`MOVE_GAIN`] of the current vertex's;
    /// of vertices that explain the track equally well (a tie, as between vertices no shape
    /// moves), the landmark's own, or else the nearest to it.
    fn next_vertex(
        &self,
        l: usize,
        cur: usize,
        candidates: &[usize],
        positions: &[[f64; 3]],
        offsets: &[Vec<[f64; 3]>],
    ) -> usize {
        let now = self.residual(l, positions[cur], &offsets[cur]);
        let scored: Vec<(usize, f64)> = candidates
            .iter()
            .map(|&v| (v, self.residual(l, positions[v], &offsets[v])))
            .collect();
        let least = scored.iter().map(|c| c.1).fold(f64::INFINITY, f64::min);
        let tie = least * (1.0 + 1e-9) + TIE_PX2;
        if now <= tie {
            return cur;
        }
        let best = scored
            .iter()
            .filter(|c| c.1 <= tie)
            .min_by(|a, b| {
                d2(&positions[a.0], &positions[cur])
                    .total_cmp(&d2(&positions[b.0], &positions[cur]))
            })
            .copied();
        match best {
            Some(best) if best.1 < MOVE_GAIN * now => best.0,
            _ => cur,
        }
    }

    /// The squared 2-D residual, summed over the frames, of landmark `l` read from a vertex
    /// at `neutral` with shape offsets `offsets`, after the best constant 3-D offset per
    /// clip.
    fn residual(&self, l: usize, neutral: [f64; 3], offsets: &[[f64; 3]]) -> f64 {
        let active: Vec<(usize, [f64; 3])> = offsets
            .iter()
            .copied()
            .enumerate()
            .filter(|(_, o)| o.iter().any(|c| *c != 0.0))
            .collect();
        let mut total = 0.0;
        for clip in &self.clips {
            let mut m = Matrix3::zeros();
            let mut b = Vector3::zeros();
            let mut c = 0.0;
            for f in clip.clone() {
                let mut p = neutral;
                for &(s, o) in &active {
                    let w = self.weights[(s, f)];
                    for k in 0..3 {
                        p[k] += w * o[k];
                    }
                }
                let cam = &self.cameras[f];
                let u = [self.image[(2 * l, f)], -self.image[(2 * l + 1, f)]];
                let e = cam.project(&p);
                let e = Vector3::new(e[0] - u[0], e[1] - u[1], 0.0);
                // The camera's linear part, s R₂ (2 × 3), as the top rows of a 3 × 3.
                let mut a = cam.r * cam.s;
                a.row_mut(2).fill(0.0);
                m += a.transpose() * a;
                b += a.transpose() * e;
                c += e.norm_squared();
            }
            // The best constant offset o minimises |A o + e|² summed: c − bᵀ(M + εI)⁻¹b. A
            // frontal clip does not see depth; ε keeps M invertible there.
            let eps = 1e-9 * m.trace().max(f64::MIN_POSITIVE);
            let reg = m + Matrix3::identity() * eps;
            let gain = reg.cholesky().map_or(0.0, |ch| b.dot(&ch.solve(&b)));
            total += (c - gain).max(0.0);
        }
        total
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::Camera;

    /// A flat grid of vertices; shape 0 moves the vertices right of x = 1 up by x − 1 (so
    /// each moves its own amount), shape 1 moves every vertex left of x = 1 towards +x.
    fn mesh() -> (Vec<[f64; 3]>, MorphTargets) {
        let mut pos = Vec::new();
        for i in 0..5 {
            for j in 0..5 {
                pos.push([
                    f64::from(i) * 0.5,
                    f64::from(j) * 0.5,
                    0.04 * f64::from(i * i),
                ]);
            }
        }
        let up = pos
            .iter()
            .enumerate()
            .filter(|(_, p)| p[0] > 1.0)
            .map(|(v, p)| (v, [0.0, p[0] - 1.0, 0.0]))
            .collect();
        let side = pos
            .iter()
            .enumerate()
            .filter(|(_, p)| p[0] < 1.0)
            .map(|(v, p)| (v, [0.3 + p[1], 0.0, 0.0]))
            .collect();
        let morph = MorphTargets {
            names: vec!["up".into(), "side".into()],
            deltas: vec![up, side],
        };
        (pos, morph)
    }

    /// A track with depth gives its x and y rows per landmark; a 2-D track is itself.
    #[test]
    fn image_rows_take_x_and_y_of_each_landmark() {
        let t = DMatrix::from_fn(9, 2, |r, c| (10 * r + c) as f64);
        let xy = image_rows(&t, 3);
        assert_eq!(xy.nrows(), 6);
        for (i, r) in [0, 1, 3, 4, 6, 7].into_iter().enumerate() {
            assert_eq!(xy.row(i), t.row(r));
        }
        let flat = DMatrix::from_fn(6, 2, |r, c| (r + c) as f64);
        assert_eq!(image_rows(&flat, 3), flat);
    }

    /// Rendered through one map and solved through another, noise-free: the refinement
    /// moves the landmarks whose vertices move differently to the render's vertices, and a
    /// landmark no shape tells apart stays where the map put it.
    #[test]
    fn the_refinement_finds_the_render_s_vertices_and_refuses_what_cannot_work() {
        let (pos, morph) = mesh();
        // Track points 0..8 on the map's vertices (vertex 5i + j sits at x 0.5i, y 0.5j);
        // the render reads one of them elsewhere.
        let map: Vec<(usize, usize)> = [0, 6, 12, 17, 9, 21, 2, 14]
            .iter()
            .enumerate()
            .map(|(l, &v)| (l, v))
            .collect();
        let mut truth = map.clone();
        truth[3].1 = 22; // x 1.5 → 2.0: moves up 1.0, not 0.5
        let rig = Rig::from_correspondence(&pos, &morph, 68, &map).unwrap();
        let render = Rig::from_correspondence(&pos, &morph, 68, &truth).unwrap();
        let frames = 40;
        let weights = DMatrix::from_fn(2, frames, |s, f| {
            let t = f as f64 / frames as f64;
            if s == 0 {
                (t * 7.0).sin().abs()
            } else {
                (t * 3.0).sin().abs() * 0.5
            }
        });
        let cams: Vec<Camera> = (0..frames)
            .map(|f| {
                let f = f as f64;
                Camera::from_angles(40.0, 0.015 * f, -0.005 * f, 0.0, [100.0, -80.0])
            })
            .collect();
        let track = render.render(&weights, &cams);
        // The neutral at frame 0, where both weights are 0.
        let opts = RigOptions {
            neutral: crate::Neutral::Column(0),
            min_determination: 0.0,
            ..RigOptions::default()
        };
        let settings = Refinement {
            radius: 0.6,
            rounds: 3,
        };
        let done = refine_map(
            (&pos, &morph),
            &rig,
            &track,
            &[],
            &opts,
            settings,
            &mut |_| {},
        )
        .unwrap();
        assert_eq!(done.pairs[3], (3, 22), "{:?}", done.pairs);
        // Landmark 2 (vertex 12, x 1.0): no shape moves it or its neighbours, so every
        // vertex in reach explains its track as well, and it stays where the map put it.
        assert_eq!(done.pairs[2], (2, 12), "{:?}", done.pairs);
        assert_eq!(done.changed, 1, "{:?}", done.pairs);
        assert_eq!(done.moved[0], 1);
        // The weights: the truth's, where through the map as it was they are not.
        let worst = |w: &DMatrix<f64>| (w - &weights).amax();
        let unrefined = crate::solve_rig(
            &rig,
            &track,
            &[],
            &RigOptions {
                robust: true,
                ..opts
            },
        )
        .unwrap();
        assert!(
            worst(&done.solve.weights) < 1e-4,
            "{}",
            worst(&done.solve.weights)
        );
        assert!(
            worst(&unrefined.weights) > 0.01,
            "{} against {}",
            worst(&unrefined.weights),
            worst(&done.solve.weights)
        );
        // Another person: each landmark's rest position moved in the face's plane, by as
        // much as the shapes move it. The vertex search's per-landmark offset takes that up
        // and the same vertices are found (scored without the offset, they are not).
        let mut person = render.clone();
        for (l, p) in person.neutral.iter_mut().enumerate() {
            let l = l as f64;
            p[0] += 0.4 * (l * 1.7).sin();
            p[1] += 0.3 * (l * 2.3).cos();
        }
        let theirs = person.render(&weights, &cams);
        let found = refine_map(
            (&pos, &morph),
            &rig,
            &theirs,
            &[],
            &opts,
            settings,
            &mut |_| {},
        )
        .unwrap();
        assert_eq!(found.pairs, done.pairs);
        // The radius binds: at 0.45 the render's vertex (0.57 away) is out of reach, and
        // nothing moves.
        let near = Refinement {
            radius: 0.45,
            rounds: 3,
        };
        let kept = refine_map((&pos, &morph), &rig, &track, &[], &opts, near, &mut |_| {}).unwrap();
        assert_eq!(kept.changed, 0, "{:?}", kept.pairs);
        let refuse = |settings: Refinement, opts: &RigOptions, needle: &str| {
            let e = refine_map(
                (&pos, &morph),
                &rig,
                &track,
                &[],
                opts,
                settings,
                &mut |_| {},
            )
            .unwrap_err()
            .to_string();
            assert!(e.contains(needle), "{e}");
        };
        for r in [0.0, -1.0, f64::NAN, f64::INFINITY] {
            refuse(
                Refinement {
                    radius: r,
                    rounds: 1,
                },
                &opts,
                "radius must be a distance",
            );
        }
        refuse(
            Refinement {
                radius: 0.5,
                rounds: 0,
            },
            &opts,
            "at least one round",
        );
        let causal = RigOptions {
            causal: true,
            ..opts
        };
        refuse(settings, &causal, "a causal solve cannot refine");
    }
}
