//! One frame's rig solve: the per-frame Gram blocks a rig reuses ([`blocks`]), and the
//! solver state carried from frame to frame (camera and weights by Gauss–Newton with the camera's
//! Schur complement, the weights under their bounds and priors).

use super::camera::Camera;
use super::{Rig, TAPER_STEPS, TAPER_TOLERANCE};
use keyshape_core::error::Result;
use keyshape_core::solve::active_set::{self, Bound, Gram, Workspace};
use keyshape_core::solve::chol::solve_spd;
use keyshape_core::solve::Solver;
mod blocks;
mod seen;
mod step;
use step::{camera_rows, pull_back, schur_complement};

pub(super) use blocks::{frame_depth, frame_points, Blocks};

/// One frame's solver state, reused from frame to frame (the warm start).
pub(super) struct FrameSolver<'a> {
    /// The person's rig: borrowed by a file's solve, owned by the live solve (which keeps
    /// its solver from frame to frame).
    pub(super) rig: std::borrow::Cow<'a, Rig>,
    pub(super) blocks: Blocks,
    /// The landmark weights the solve was made with (the options'), before a frame's
    /// confidences weigh them ([`FrameSolver::set_confidence`]).
    base_lw: Vec<f64>,
    /// Shapes solved for (not frozen), in rig order.
    pub(super) free: Vec<usize>,
    pub(super) solver: Solver,
    pub(super) max_steps: usize,
    pub(super) w: Vec<f64>,
    pub(super) state: Vec<Bound>,
    pub(super) ws: Workspace,
    pub(super) cam: Option<Camera>,
    /// The causal temporal prior: λ and the previous frame's weights (free shapes), which
    /// each frame's weights are pulled towards (`λ‖w − w_prev‖²` added to the error).
    pub(super) lambda: f64,
    pub(super) prev: Option<Vec<f64>>,
    /// The magnitude prior: per free shape, μᵢ in `Σ μᵢ wᵢ²` added to the error.
    pub(super) ridge: Vec<f64>,
    /// Mutually exclusive pairs (free indices a, b) and γ in `γ w_a w_b` added to the error:
    /// with γ ≤ 2√(μ_a μ_b) the pair's prior stays convex (at the bound it is
    /// `(√μ_a w_a + √μ_b w_b)²`), and shapes that undo each other (blink and wide) pay for
    /// being on together.
    pub(super) pairs: Vec<(usize, usize, f64)>,
    /// The frame's depth observations (towards the viewer, track units) when the track has
    /// depth (`--dims 3`): each landmark's third row, `s r₃·p + tz`, is fitted too.
    pub(super) depth: Option<Vec<f64>>,
    /// The depth offset (MediaPipe's z has its origin near the head's centre).
    pub(super) tz: f64,
    /// The weight of a depth row's squared error against an image row's.
    pub(super) depth_weight: f64,
    /// Per free shape, does the magnitude prior taper off ([`RigOptions::taper`])?
    pub(super) taper: Vec<bool>,
    /// The rig last posed, and the weights (every shape) it was posed by: a Gauss–Newton
    /// step poses the rig at the weights the line search has just posed it at.
    posed_at: std::cell::RefCell<Option<Pose>>,
}

/// Every shape's weights, and the rig's landmarks posed by them.
type Pose = (Vec<f64>, Vec<[f64; 3]>);

impl<'a> FrameSolver<'a> {
    pub(super) fn new(
        rig: impl Into<std::borrow::Cow<'a, Rig>>,
        free: Vec<usize>,
        solver: Solver,
        max_steps: usize,
        lw: &[f64],
    ) -> Self {
        let rig = rig.into();
        let sub: Vec<Vec<[f64; 3]>> = free.iter().map(|&s| rig.deltas[s].clone()).collect();
        let m = free.len();
        FrameSolver {
            rig,
            blocks: Blocks::new(&sub, lw),
            base_lw: lw.to_vec(),
            free,
            solver,
            max_steps,
            w: vec![0.0; m],
            state: vec![Bound::Lower; m],
            ws: Workspace::new(m),
            cam: None,
            lambda: 0.0,
            prev: None,
            ridge: vec![0.0; m],
            pairs: Vec::new(),
            depth: None,
            tz: 0.0,
            depth_weight: 1.0,
            posed_at: std::cell::RefCell::new(None),
            taper: vec![false; m],
        }
    }

    /// The depth rows' weight: `depth_weight` with depth, 0 without.
    pub(super) fn wz(&self) -> f64 {
        if self.depth.is_some() {
            self.depth_weight
        } else {
            0.0
        }
    }

    /// The depth residuals `d − (s r₃·p + tz)` of the posed landmarks `x` under `cam`.
    pub(super) fn depth_residuals(&self, cam: &Camera, x: &[[f64; 3]]) -> Option<Vec<f64>> {
        let d = self.depth.as_ref()?;
        Some(
            x.iter()
                .zip(d)
                .map(|(p, z)| z - (cam.depth(p) + self.tz))
                .collect(),
        )
    }

    /// The depth offset that best fits the current weights under `cam` (the mean residual).
    pub(super) fn fit_tz(&mut self, cam: &Camera) {
        self.tz = 0.0;
        let x = self.posed_now();
        if let Some(r) = self.depth_residuals(cam, &x) {
            self.tz = r.iter().sum::<f64>() / r.len().max(1) as f64;
        }
    }

    /// The rig posed by the current weights ([`Rig::posed`], the last one reused when the
    /// weights are the same to the bit).
    pub(super) fn posed_now(&self) -> Vec<[f64; 3]> {
        let w = self.full_weights();
        let mut cache = self.posed_at.borrow_mut();
        if let Some((at, x)) = cache.as_ref() {
            if at.iter().zip(&w).all(|(a, b)| a.to_bits() == b.to_bits()) {
                return x.clone();
            }
        }
        let x = self.rig.posed(&w);
        *cache = Some((w, x.clone()));
        x
    }

    pub(super) fn full_weights(&self) -> Vec<f64> {
        let mut w = vec![0.0; self.rig.k()];
        for (j, &s) in self.free.iter().enumerate() {
            w[s] = self.w[j];
        }
        w
    }

    /// The squared landmark error of the current weights under `cam`, each landmark's
    /// term weighted by `lw` (all 1: the plain error).
    pub(super) fn sq_error_with(&self, cam: &Camera, u: &[[f64; 2]], lw: &[f64]) -> f64 {
        let posed = self.posed_now();
        let image: f64 = posed
            .iter()
            .zip(u)
            .zip(lw)
            .map(|((p, q), wi)| {
                let e = cam.project(p);
                wi * ((e[0] - q[0]).powi(2) + (e[1] - q[1]).powi(2))
            })
            .sum();
        let depth = self.depth_residuals(cam, &posed).map_or(0.0, |r| {
            self.depth_weight * r.iter().zip(lw).map(|(e, wi)| wi * e * e).sum::<f64>()
        });
        image + depth
    }

    /// The plain squared landmark error (what is reported), over the landmarks the solve
    /// sees ([`FrameSolver::seen`]).
    pub(super) fn sq_error(&self, cam: &Camera, u: &[[f64; 2]]) -> f64 {
        let posed = self.posed_now();
        posed
            .iter()
            .zip(u)
            .zip(&self.blocks.lw)
            .filter(|(_, &w)| w > 0.0)
            .map(|((p, q), _)| {
                let e = cam.project(p);
                (e[0] - q[0]).powi(2) + (e[1] - q[1]).powi(2)
            })
            .sum()
    }

    /// What the steps minimise: the weighted squared landmark error plus the prior's term.
    pub(super) fn objective(&self, cam: &Camera, u: &[[f64; 2]]) -> f64 {
        let prior = match &self.prev {
            Some(p) if self.lambda > 0.0 => {
                self.lambda
                    * self
                        .w
                        .iter()
                        .zip(p)
                        .map(|(a, b)| (a - b).powi(2))
                        .sum::<f64>()
            }
            _ => 0.0,
        };
        let magnitude: f64 = self
            .w
            .iter()
            .zip(&self.ridge)
            .map(|(w, r)| r * w * w)
            .sum::<f64>()
            + self
                .pairs
                .iter()
                .map(|&(a, b, g)| g * self.w[a] * self.w[b])
                .sum::<f64>();
        self.sq_error_with(cam, u, &self.blocks.lw) + prior + magnitude
    }

    /// One Gauss–Newton step of camera and weights together, linearised at the current
    /// camera `cam` and weights: the camera's six parameters (scale, a small rotation ω with
    /// `R ← R exp([ω]×)`, translation) are eliminated by their Schur complement, the weights
    /// solved under their bounds on what is left (warm-started active set), then the camera
    /// step recovered. Returns the camera the full step reaches.
    pub(super) fn step(&mut self, cam: &Camera, u: &[[f64; 2]]) -> (Camera, f64) {
        let m = self.free.len();
        let x = self.posed_now();
        let n = u.len();
        let lw = &self.blocks.lw;
        // With depth, a third row per landmark (`s r₃·p + tz`) and a seventh camera
        // parameter, the depth offset tz.
        let dres = self.depth_residuals(cam, &self.rig.neutral);
        let np = if dres.is_some() { 7 } else { 6 };
        let wz = self.wz();
        // The model is linear in w: the right side is the residual plus A·w, and with
        // A·w = s R (x − N) that is the residual of the neutral, u − proj(N).
        //
        // Hcw = Jᵀ W A and bw = Aᵀ W r never form A (rows per landmark × m): each of the
        // camera's Jacobian rows, and the right side, is pulled back through s R onto the
        // rig's coordinates (`v`, np + 1 rows of 3 per landmark), and then met with every
        // shape's deltas in one contiguous dot product.
        let (hcc, bc, v) =
            camera_rows(cam, &x, &self.rig.neutral, u, (lw, wz), dres.as_deref(), np);
        let (hcw, mut bw) = pull_back(&self.blocks.d, &v, m, np, 3 * n);
        let mut g = vec![0.0; m * m];
        self.blocks.gram(cam, wz, &mut g);
        let Some(hinv) = hcc.try_inverse() else {
            return (*cam, self.tz);
        };
        schur_complement(&hinv, &hcw, &bc, &mut g, &mut bw);
        if m > 0 {
            self.solve_weights(g, bw);
        }
        // Camera step: Hcc δ = bc − Hcw w.
        let hw = &hcw * nalgebra::DVector::from_column_slice(&self.w);
        let delta = &hinv * (bc - hw);
        let omega = nalgebra::Vector3::new(delta[1], delta[2], delta[3]);
        let rot = nalgebra::Rotation3::new(omega);
        let tz = if np == 7 { self.tz + delta[6] } else { self.tz };
        (
            Camera {
                s: cam.s + delta[0],
                r: cam.r * rot.matrix(),
                t: [cam.t[0] + delta[4], cam.t[1] + delta[5]],
            },
            tz,
        )
    }

    /// The best weights for camera `cam` (the model is linear in them: exact), warm-started
    /// from the current ones, under the plain magnitude prior.
    pub(super) fn weights_for(&mut self, cam: &Camera, u: &[[f64; 2]]) {
        if let Some((g, b)) = self.normal_equations(cam, u) {
            self.solve_weights(g, b);
        }
    }

    /// [`FrameSolver::weights_for`] with the magnitude prior tapered where it does
    /// ([`RigOptions::taper`]; the plain solve where it does not).
    pub(super) fn tapered_weights_for(&mut self, cam: &Camera, u: &[[f64; 2]]) {
        if let Some((g, b)) = self.normal_equations(cam, u) {
            if self.taper.iter().any(|&t| t) {
                self.solve_tapered(g, b);
            } else {
                self.solve_weights(g, b);
            }
        }
    }

    /// The weights' normal equations `G w = b` at camera `cam` (without the priors), or
    /// `None` when no shape is free.
    pub(super) fn normal_equations(
        &self,
        cam: &Camera,
        u: &[[f64; 2]],
    ) -> Option<(Vec<f64>, Vec<f64>)> {
        let m = self.free.len();
        if m == 0 {
            return None;
        }
        let res: Vec<[f64; 2]> = self
            .rig
            .neutral
            .iter()
            .zip(u)
            .map(|(p, q)| {
                let e = cam.project(p);
                [q[0] - e[0], q[1] - e[1]]
            })
            .collect();
        let mut g = vec![0.0; m * m];
        let wz = self.wz();
        self.blocks.gram(cam, wz, &mut g);
        let mut b = vec![0.0; m];
        let dres = self.depth_residuals(cam, &self.rig.neutral);
        self.blocks
            .rhs(cam, &res, dres.as_deref().map(|d| (d, wz)), &mut b);
        Some((g, b))
    }

    /// [`FrameSolver::solve_weights`] with the tapered magnitude prior: the ridge of each
    /// tapering shape reweighted to `μ (1 − w)²` from the current weights and the weights
    /// solved again, [`TAPER_STEPS`] times (fewer when no weight moves by more than
    /// [`TAPER_TOLERANCE`]). Each step is the local linear approximation of the tapered
    /// penalty `μ w² (1 − 4w/3 + w²/2)`, whose gradient is `2μ w (1 − w)²`, at the last
    /// weights. Returns the ridge of the last solve (the weights meet its KKT conditions).
    pub(super) fn solve_tapered(&mut self, g: Vec<f64>, b: Vec<f64>) -> Vec<f64> {
        let base = self.ridge.clone();
        let mut used = base.clone();
        for _ in 0..TAPER_STEPS {
            for ((r, mu), (w, t)) in self
                .ridge
                .iter_mut()
                .zip(&base)
                .zip(self.w.iter().zip(&self.taper))
            {
                if *t {
                    *r = mu * (1.0 - w.clamp(0.0, 1.0)).powi(2);
                }
            }
            let before = self.w.clone();
            used.clone_from(&self.ridge);
            self.solve_weights(g.clone(), b.clone());
            let moved = before
                .iter()
                .zip(&self.w)
                .map(|(a, b)| (a - b).abs())
                .fold(0.0, f64::max);
            if moved <= TAPER_TOLERANCE {
                break;
            }
        }
        self.ridge = base;
        used
    }

    /// Solves `G w = b` under the solver's bounds into `self.w` (G gets a whisper of ridge,
    /// 1e-9 of its mean diagonal, far below any taken shape's curvature, so nearly dependent
    /// shapes stay solvable).
    pub(super) fn solve_weights(&mut self, mut g: Vec<f64>, mut b: Vec<f64>) {
        let m = self.free.len();
        let ridge = 1e-9 * (0..m).map(|i| g[i * m + i]).sum::<f64>() / m as f64;
        for i in 0..m {
            g[i * m + i] += ridge + self.ridge[i];
        }
        for &(a, b, gamma) in &self.pairs {
            g[a * m + b] += gamma / 2.0;
            g[b * m + a] += gamma / 2.0;
        }
        if let (Some(p), true) = (&self.prev, self.lambda > 0.0) {
            for i in 0..m {
                g[i * m + i] += self.lambda;
                b[i] += self.lambda * p[i];
            }
        }

        match self.solver {
            Solver::Ls => {
                if solve_spd(&mut g, m, &mut b) {
                    self.w.copy_from_slice(&b);
                }
            }
            Solver::Nnls | Solver::Bounded => {
                let upper = if self.solver == Solver::Bounded {
                    1.0
                } else {
                    f64::INFINITY
                };
                let gram = Gram::from_row_major(m, g, upper);
                // Each call has its own Gram: the workspace's cached factor is stale.
                self.ws.forget_factor();
                active_set::solve_frame(&gram, &b, &mut self.w, &mut self.state, &mut self.ws);
            }
        }
    }

    /// Camera and weights of frame `u` to convergence: from the previous frame's weights and
    /// a fresh camera fit, each step takes the camera's Gauss–Newton step of the joint
    /// problem ([`FrameSolver::step`]), backtracked until the error falls, with the weights
    /// solved exactly for each trial camera (variable projection: the error never rises);
    /// then, at the camera reached, the weights under the tapered prior where it tapers.
    /// Returns (steps, converged, squared error).
    pub(super) fn solve(&mut self, u: &[[f64; 2]]) -> Result<(u32, bool, f64)> {
        let (cam, it, ok) = self.gauss_newton(u)?;
        if self.taper.iter().any(|&t| t) {
            self.tapered_weights_for(&cam, u);
        }
        self.cam = Some(cam);
        Ok((it, ok, self.sq_error(&cam, u)))
    }

    /// [`FrameSolver::solve`]'s Gauss–Newton steps, under the plain magnitude prior:
    /// (camera, steps, converged).
    pub(super) fn gauss_newton(&mut self, u: &[[f64; 2]]) -> Result<(Camera, u32, bool)> {
        let mut cam = self.first_camera(u)?;
        self.fit_tz(&cam);
        self.weights_for(&cam, u);
        let mut err = self.objective(&cam, u);
        for it in 1..=self.max_steps {
            let (w0, state0, tz0) = (self.w.clone(), self.state.clone(), self.tz);
            let (full, tz_full) = self.step(&cam, u);
            let mut accepted = None;
            let mut alpha = 1.0;
            for _ in 0..12 {
                let trial = cam.toward(&full, alpha);
                self.w.copy_from_slice(&w0);
                self.state.copy_from_slice(&state0);
                self.tz = tz0 + alpha * (tz_full - tz0);
                self.weights_for(&trial, u);
                let e = self.objective(&trial, u);
                if e < err {
                    accepted = Some((trial, e));
                    break;
                }
                alpha *= 0.5;
            }
            let Some((next, e)) = accepted else {
                self.w = w0;
                self.state = state0;
                self.tz = tz0;
                return Ok((cam, it as u32, true));
            };
            let small = err - e <= 1e-12 * err;
            cam = next;
            err = e;
            if small {
                return Ok((cam, it as u32, true));
            }
        }
        Ok((cam, self.max_steps as u32, false))
    }
}

#[cfg(test)]
mod tests {
    /// The posed rig the solver reuses is the rig posed by its current weights, whichever
    /// of them changed (a free shape's weight, one by a bit, or back to an earlier set).
    #[test]
    fn the_reused_pose_is_the_pose_of_the_current_weights() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(7);
        let (n, k) = (6, 4);
        let rig = crate::Rig {
            names: (0..k).map(|s| format!("s{s}")).collect(),
            neutral: (0..n).map(|_| [rng.gen_range(-1.0..1.0); 3]).collect(),
            deltas: (0..k)
                .map(|_| (0..n).map(|_| [rng.gen_range(-1.0..1.0); 3]).collect())
                .collect(),
            points: (0..n).collect(),
            layout: n,
        };
        // Shapes 0, 2 and 3 free; shape 1 held at 0.
        let mut fs = super::FrameSolver::new(
            &rig,
            vec![0, 2, 3],
            keyshape_core::solve::Solver::Bounded,
            5,
            &vec![1.0; n],
        );
        let first = vec![0.3, 0.7, 0.1];
        for w in [
            first.clone(),
            first.clone(),
            vec![0.3, 0.7, f64::from_bits(0.1f64.to_bits() + 1)],
            vec![0.0, 0.7, 0.1],
            first,
        ] {
            fs.w.clone_from(&w);
            let full = [w[0], 0.0, w[1], w[2]];
            assert_eq!(fs.posed_now(), rig.posed(&full), "{w:?}");
        }
    }

    /// The tapered prior's weights meet the KKT conditions of the bounded problem with the
    /// ridge its last step used; that ridge is `μ (1 − w)²` of weights in [0, 1] for the
    /// tapering shapes (so never above μ) and μ for the others; and a shape the data clearly
    /// turns on comes nearer its full weight than under the plain ridge.
    #[test]
    fn the_tapered_prior_meets_its_kkt_conditions() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(39);
        let (n, m) = (8, 5);
        let rig = crate::Rig {
            names: (0..m).map(|s| format!("s{s}")).collect(),
            neutral: vec![[0.0; 3]; n],
            deltas: (0..m)
                .map(|_| (0..n).map(|_| [rng.gen_range(-1.0..1.0); 3]).collect())
                .collect(),
            points: (0..n).collect(),
            layout: n,
        };
        for trial in 0..200 {
            let mut fs = super::FrameSolver::new(
                &rig,
                (0..m).collect(),
                keyshape_core::solve::Solver::Bounded,
                50,
                &vec![1.0; n],
            );
            let a = nalgebra::DMatrix::<f64>::from_fn(2 * m, m, |_, _| rng.gen_range(-1.0..1.0));
            let gram = a.transpose() * &a;
            let g: Vec<f64> = (0..m * m).map(|k| gram[(k / m, k % m)]).collect();
            let truth: Vec<f64> = (0..m).map(|_| rng.gen_range(-0.3..1.3)).collect();
            let b: Vec<f64> = (0..m)
                .map(|i| (0..m).map(|j| gram[(i, j)] * truth[j]).sum())
                .collect();
            let mu = rng.gen_range(0.05..2.0);
            fs.ridge = vec![mu; m];
            fs.taper = (0..m).map(|j| j != m - 1).collect();
            fs.pairs = vec![(0, 1, 2.0 * mu)];
            let used = fs.solve_tapered(g.clone(), b.clone());
            assert_eq!(fs.ridge, vec![mu; m], "the base ridge is restored");
            assert_eq!(used[m - 1], mu, "a shape that does not taper keeps μ");
            for &r in &used[..m - 1] {
                assert!((0.0..=mu).contains(&r), "trial {trial}: {r} against μ {mu}");
            }
            // KKT of (G + diag(used) + pairs) w = b in the unit box.
            let w = fs.w.clone();
            let whisper = 1e-9 * (0..m).map(|i| g[i * m + i]).sum::<f64>() / m as f64;
            for i in 0..m {
                let mut h = -b[i] + (used[i] + whisper) * w[i];
                for j in 0..m {
                    h += g[i * m + j] * w[j];
                }
                h += match i {
                    0 => mu * w[1],
                    1 => mu * w[0],
                    _ => 0.0,
                };
                let v = if w[i] <= 1e-12 {
                    (-h).max(0.0)
                } else if w[i] >= 1.0 - 1e-12 {
                    h.max(0.0)
                } else {
                    h.abs()
                };
                assert!(v < 1e-9, "trial {trial}: shape {i} KKT violation {v}");
            }
        }
        // One shape the data puts at 1 (curvature 2, μ 1): the plain ridge leaves 2/3, the
        // taper's two steps μ(1 − 2/3)² → 0.947 and then 0.9986.
        let mut one = super::FrameSolver::new(
            &rig,
            vec![0],
            keyshape_core::solve::Solver::Bounded,
            50,
            &[1.0; 8],
        );
        one.ridge = vec![1.0];
        one.taper = vec![true];
        one.solve_weights(vec![2.0], vec![2.0]);
        assert!((one.w[0] - 2.0 / 3.0).abs() < 1e-6, "{}", one.w[0]);
        one.solve_tapered(vec![2.0], vec![2.0]);
        assert!((one.w[0] - 0.9986).abs() < 1e-3, "{}", one.w[0]);
    }
}
