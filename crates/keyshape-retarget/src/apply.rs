//! The retargeting itself: the key plan and the target, the weights solved on the source key
//! shapes, and the target key shapes they drive (paper 000 Eq. 2, per region or whole).

use crate::regions::RegionPlan;
use crate::result::Retargeted;
use keyshape_core::error::{setting, Error, Result};
use keyshape_core::rbf::Rbf;
use keyshape_core::solve::{solve_batch, SolveOptions, Solver};
use nalgebra::{DMatrix, DVector};

/// Where the target key shapes come from.
#[derive(Debug, Clone)]
pub enum Target {
    /// A smooth warp G of source points (the built-in cartoon): `Bᵢ = G(Sᵢ) + εᵢ`, and
    /// `G(Q_t)` is a ground truth in the target domain. `εᵢ` models an artist tracing each
    /// key shape by hand (paper 000 §4.1: "the traced shapes closely match the tracked
    /// contours, \[but\] they are not identical"): independent Gaussian offsets of standard
    /// deviation `trace_noise` (input units) per coordinate, seeded by the key's frame
    /// column, so the same key always gets the same tracing.
    Warp {
        /// The warp G.
        g: Rbf,
        /// Tracing noise σ (0 = exact G(Sᵢ)).
        trace_noise: f64,
    },
    /// Given shapes, one column per key (in key order), with an optional neutral.
    Shapes {
        /// n_t × k.
        keys: DMatrix<f64>,
        /// The target neutral, for delta mode.
        neutral: Option<DVector<f64>>,
    },
}

/// Which key shapes, with which weights.
#[derive(Debug, Clone)]
pub enum KeyPlan {
    /// One set of key columns for every point.
    Global(Vec<usize>),
    /// Per region: its key columns, with the region plan.
    Regions(RegionPlan, Vec<Vec<usize>>),
    /// Key shapes that are not frames (`kmeansN-mean`: cluster means), one per column, for
    /// every point; only a [`Target::Warp`] can map them (a drawn target has shapes for
    /// frames). [`Retargeted::keys`] is then empty.
    Shapes(DMatrix<f64>),
}

/// What a retargeting run solves and drives: the key plan, the target, the solver and, when
/// asked, a neutral frame (delta mode), `G(Q)` computed beforehand and a temporal prior.
///
/// ```
/// use keyshape_core::decompose::{prepare, PrepareOptions};
/// use keyshape_core::solve::temporal::{segments, SmoothMode, Smoothing};
/// use keyshape_core::solve::Solver;
/// use keyshape_retarget::{setup::builtin_target, KeyPlan, RetargetParams, Target};
///
/// let seq = keyshape_io::builtin_sequence()?;
/// let prep = prepare(&seq, &PrepareOptions::group_aligned("lips"))?;
/// let (g, _) = builtin_target(&seq, &prep)?;
/// let target = Target::Warp { g, trace_noise: 0.0 };
/// let plan = KeyPlan::Global(vec![0, 60, 120, 180, 215]);
/// let smoothing = Smoothing { lambda: 10.0, order: 1, mode: SmoothMode::Offline };
/// let segs = segments(&prep.seq.frames, prep.seq.segments.as_deref());
/// let r = RetargetParams::new(&plan, &target, Solver::Nnls)
///     .smoothed(&smoothing, &segs)
///     .run(&prep.seq.coords, prep.seq.dims)?;
/// assert_eq!(r.weights[0].ncols(), prep.seq.n_frames());
/// assert!(r.weights[0].iter().all(|&w| w >= 0.0));
/// # Ok::<(), keyshape_core::Error>(())
/// ```
#[derive(Debug, Clone, Copy)]
pub struct RetargetParams<'a> {
    plan: &'a KeyPlan,
    target: &'a Target,
    solver: Solver,
    neutral: Option<usize>,
    truth: Option<&'a DMatrix<f64>>,
    smoothing: Option<(
        &'a keyshape_core::solve::temporal::Smoothing,
        &'a [std::ops::Range<usize>],
    )>,
}

impl<'a> RetargetParams<'a> {
    /// The key plan, the target and the solver; absolute shapes, no prior.
    pub fn new(plan: &'a KeyPlan, target: &'a Target, solver: Solver) -> Self {
        RetargetParams {
            plan,
            target,
            solver,
            neutral: None,
            truth: None,
            smoothing: None,
        }
    }

    /// Delta mode from this neutral frame column (`None`: absolute shapes).
    pub fn neutral(mut self, neutral: Option<usize>) -> Self {
        self.neutral = neutral;
        self
    }

    /// `G(Q)` already computed for a warp target (it costs a pass of the RBF over every
    /// point of every frame, which an interactive caller computes once).
    pub fn truth(mut self, truth: &'a DMatrix<f64>) -> Self {
        self.truth = Some(truth);
        self
    }

    /// The weights solved under a temporal prior ([`keyshape_core::solve::temporal`]) over
    /// `segments` (frame column ranges); λ = 0 is the plain solve.
    pub fn smoothed(
        mut self,
        smoothing: &'a keyshape_core::solve::temporal::Smoothing,
        segments: &'a [std::ops::Range<usize>],
    ) -> Self {
        self.smoothing = Some((smoothing, segments));
        self
    }

    /// Retargets every frame of `q` (aligned shapes, `dims` per point).
    pub fn run(&self, q: &DMatrix<f64>, dims: usize) -> Result<Retargeted> {
        retarget_impl(q, dims, self, true)
    }

    /// As [`RetargetParams::run`], keeping only the weights and the per-frame errors:
    /// [`Retargeted::source`] and [`Retargeted::target`] are 0 × frames and
    /// [`Retargeted::truth`] is `None`. The frames are reconstructed (and `G(Q)` evaluated)
    /// a chunk at a time, so on a long track this holds the weights and one chunk instead
    /// of three more copies of the sequence. The weights and errors are those of `run`,
    /// bit for bit (tested).
    pub fn errors_only(&self, q: &DMatrix<f64>, dims: usize) -> Result<Retargeted> {
        retarget_impl(q, dims, self, false)
    }
}

/// Retargets every frame of `q` (aligned shapes, `dims` per point): [`RetargetParams::run`]
/// with a neutral frame or none.
pub fn retarget(
    q: &DMatrix<f64>,
    dims: usize,
    plan: &KeyPlan,
    target: &Target,
    neutral: Option<usize>,
    solver: Solver,
) -> Result<Retargeted> {
    RetargetParams::new(plan, target, solver)
        .neutral(neutral)
        .run(q, dims)
}

/// As [`retarget`], keeping only the weights and the per-frame errors
/// ([`RetargetParams::errors_only`]).
pub fn retarget_errors(
    q: &DMatrix<f64>,
    dims: usize,
    plan: &KeyPlan,
    target: &Target,
    neutral: Option<usize>,
    solver: Solver,
) -> Result<Retargeted> {
    RetargetParams::new(plan, target, solver)
        .neutral(neutral)
        .errors_only(q, dims)
}

fn retarget_impl(
    q: &DMatrix<f64>,
    dims: usize,
    params: &RetargetParams,
    keep: bool,
) -> Result<Retargeted> {
    let n = q.nrows();
    let points = n / dims;
    let (regions, key_sets) = key_sets(params.plan, params.target, n)?;
    let given = match params.plan {
        KeyPlan::Shapes(m) => Some(m),
        _ => None,
    };
    let n_t = match params.target {
        Target::Warp { .. } => n,
        Target::Shapes { keys, .. } => keys.nrows(),
    };
    // Per region: its rows, weights and (delta-mode) key shapes; then the frames are
    // reconstructed in chunks, so only what the caller keeps is ever whole.
    let mut parts: Vec<Part> = Vec::with_capacity(key_sets.len());
    let mut unconverged = 0;
    for keys in key_sets.iter() {
        let rows: Vec<usize> = match regions {
            None => (0..n).collect(),
            Some(p) => p.members[parts.len()]
                .iter()
                .flat_map(|&i| (0..dims).map(move |d| i * dims + d))
                .collect(),
        };
        let s_full = match given {
            Some(m) => m.clone(),
            None => q.select_columns(keys),
        };
        let (part, missed) = solve_part(q, keys, &rows, s_full, regions.is_some(), params)?;
        unconverged += missed;
        parts.push(part);
    }
    let rec = reconstruct_frames(q, params, &parts, regions, dims, n_t, keep);
    Ok(Retargeted {
        unconverged,
        keys: if given.is_some() {
            Vec::new()
        } else {
            key_sets
        },
        weights: parts.into_iter().map(|p| p.w).collect(),
        source: rec.source,
        target: rec.target,
        truth: rec.truth,
        source_sq: rec.source_sq,
        target_sq: rec.target_sq,
        points,
        target_points: n_t / dims,
    })
}

/// The regions (if any) and each one's key columns, with the plan checked against the
/// target and the frames' `n` values.
fn key_sets<'p>(
    plan: &'p KeyPlan,
    target: &Target,
    n: usize,
) -> Result<(Option<&'p RegionPlan>, Vec<Vec<usize>>)> {
    let (regions, key_sets): (Option<&RegionPlan>, Vec<Vec<usize>>) = match plan {
        KeyPlan::Global(k) => (None, vec![k.clone()]),
        KeyPlan::Regions(p, k) => (Some(p), k.clone()),
        KeyPlan::Shapes(m) => {
            if !matches!(target, Target::Warp { .. }) {
                return Err(Error::invalid(
                    "key shapes that are not frames (cluster means) need the built-in target: a drawn target has shapes for key frames",
                ));
            }
            if m.nrows() != n || m.ncols() == 0 {
                return Err(Error::invalid(format!(
                    "{} key shapes of {} values for frames of {n}",
                    m.ncols(),
                    m.nrows()
                )));
            }
            (None, vec![(0..m.ncols()).collect()])
        }
    };
    if let (Some(_), Target::Shapes { keys, .. }) = (regions, target) {
        if keys.nrows() != n {
            return Err(Error::invalid(
                "regions need target shapes with the source's points",
            ));
        }
    }
    Ok((regions, key_sets))
}

/// The target key shapes for the source key shapes `s_full` (key columns `keys`): the
/// warp of each, traced with noise, or the target set's own.
fn target_keys(target: &Target, s_full: &DMatrix<f64>, keys: &[usize]) -> Result<DMatrix<f64>> {
    match target {
        Target::Warp { g, trace_noise } => {
            let mut b = g.apply_all(s_full);
            for (j, &c) in keys.iter().enumerate() {
                add_tracing(b.column_mut(j).as_mut_slice(), *trace_noise, c);
            }
            Ok(b)
        }
        Target::Shapes { keys: b, .. } => {
            if b.ncols() != keys.len() {
                return Err(Error::invalid(format!(
                    "{} target shapes for {} key shapes",
                    b.ncols(),
                    keys.len()
                )));
            }
            Ok(b.clone())
        }
    }
}

/// The source's and the target's neutral shapes.
type Bases = (Option<DVector<f64>>, Option<DVector<f64>>);

/// Delta mode's neutrals: the source's frame column `neutral` and the target's neutral
/// (its warp, traced, or the set's own); none in absolute mode.
fn neutral_bases(q: &DMatrix<f64>, target: &Target, neutral: Option<usize>) -> Result<Bases> {
    let Some(c) = neutral else {
        return Ok((None, None));
    };
    let nq = q.column(c).clone_owned();
    let nb = match target {
        Target::Warp { g, trace_noise } => {
            let mut v = g.apply(nq.as_slice());
            add_tracing(&mut v, *trace_noise, c);
            DVector::from_vec(v)
        }
        Target::Shapes {
            neutral: Some(v), ..
        } => v.clone(),
        Target::Shapes { neutral: None, .. } => {
            return Err(Error::invalid(format!(
                "delta mode ({}) needs a neutral shape in the target set",
                setting("neutral")
            )))
        }
    };
    Ok((Some(nq), Some(nb)))
}

/// `m` with `base` taken from every column (unchanged without a base).
fn delta(m: &DMatrix<f64>, base: &Option<DVector<f64>>) -> DMatrix<f64> {
    let mut m = m.clone();
    if let Some(b) = base {
        for mut c in m.column_iter_mut() {
            c -= b;
        }
    }
    m
}

/// One region's solve (the whole face without regions): its key shapes and target key
/// shapes in delta mode or not, and the weights of every frame's `rows` on them, plain or
/// under the temporal prior. Also the frames whose solve hit the iteration cap.
fn solve_part(
    q: &DMatrix<f64>,
    keys: &[usize],
    rows: &[usize],
    s_full: DMatrix<f64>,
    regional: bool,
    params: &RetargetParams,
) -> Result<(Part, usize)> {
    let b_full = target_keys(params.target, &s_full, keys)?;
    let (src_base, tgt_base) = neutral_bases(q, params.target, params.neutral)?;
    let s_d = delta(&s_full, &src_base);
    let b_d = delta(&b_full, &tgt_base);
    // The frames as solved: borrowed when they need no change (no neutral, every row).
    let q_d: std::borrow::Cow<DMatrix<f64>> = match &src_base {
        None => std::borrow::Cow::Borrowed(q),
        Some(_) => std::borrow::Cow::Owned(delta(q, &src_base)),
    };
    let s_r = s_d.select_rows(rows);
    let q_r: std::borrow::Cow<DMatrix<f64>> = if !regional {
        q_d
    } else {
        std::borrow::Cow::Owned(q_d.select_rows(rows))
    };
    let solver = params.solver;
    let sol = solve_batch(&s_r, &q_r, &SolveOptions::new(solver))?;
    let (w, unconverged) = match params.smoothing {
        Some((sm, segs)) if sm.lambda > 0.0 => {
            let r =
                keyshape_core::solve::temporal::smooth_from(&s_r, &q_r, &sol, solver, sm, segs)?;
            (r.weights, r.unconverged)
        }
        _ => (sol.weights, sol.unconverged),
    };
    let part = Part {
        s_d,
        b_d,
        bases: src_base.zip(tgt_base),
        w,
    };
    Ok((part, unconverged))
}

/// The frames rebuilt from the weights, source and target, with each frame's squared
/// error (the target's against `G(Q)` for a warp target); the shapes and `G(Q)` kept whole
/// only when `keep`.
struct Reconstruction {
    source: DMatrix<f64>,
    target: DMatrix<f64>,
    truth: Option<DMatrix<f64>>,
    source_sq: Vec<f64>,
    target_sq: Option<Vec<f64>>,
}

/// [`Reconstruction`] of every frame, a chunk of [`RECON_CHUNK`] frames at a time.
fn reconstruct_frames(
    q: &DMatrix<f64>,
    params: &RetargetParams,
    parts: &[Part],
    regions: Option<&RegionPlan>,
    dims: usize,
    n_t: usize,
    keep: bool,
) -> Reconstruction {
    let (n, frames) = q.shape();
    let mut source = DMatrix::zeros(if keep { n } else { 0 }, frames);
    let mut out = DMatrix::zeros(if keep { n_t } else { 0 }, frames);
    let mut source_sq = vec![0.0; frames];
    let warp = match params.target {
        Target::Warp { g, .. } => Some(g),
        Target::Shapes { .. } => None,
    };
    let given_truth = params
        .truth
        .filter(|t| warp.is_some() && t.shape() == q.shape());
    // The whole G(Q) only when it is kept; otherwise chunk by chunk.
    let truth = match (keep, given_truth, warp) {
        (true, Some(t), _) => Some(t.clone()),
        (true, None, Some(g)) => Some(g.apply_all(q)),
        _ => None,
    };
    let mut target_sq = warp.map(|_| vec![0.0; frames]);
    for c0 in (0..frames).step_by(RECON_CHUNK) {
        let len = RECON_CHUNK.min(frames - c0);
        let (rec_s, rec_t) = reconstruct(parts, regions, dims, n, n_t, c0, len);
        for t in 0..len {
            source_sq[c0 + t] = (q.column(c0 + t) - rec_s.column(t)).norm_squared();
        }
        if let Some(sq) = target_sq.as_mut() {
            let chunk_truth;
            let tr = match (&truth, given_truth, warp) {
                (Some(tr), _, _) => tr.columns(c0, len),
                (None, Some(tr), _) => tr.columns(c0, len),
                (None, None, Some(g)) => {
                    chunk_truth = g.apply_all(&q.columns(c0, len).clone_owned());
                    chunk_truth.columns(0, len)
                }
                (None, None, None) => unreachable!("target_sq exists only for a warp"),
            };
            for t in 0..len {
                sq[c0 + t] = (tr.column(t) - rec_t.column(t)).norm_squared();
            }
        }
        if keep {
            source.columns_mut(c0, len).copy_from(&rec_s);
            out.columns_mut(c0, len).copy_from(&rec_t);
        }
    }
    Reconstruction {
        source,
        target: out,
        truth,
        source_sq,
        target_sq,
    }
}

/// Frames reconstructed per chunk (source and target), so a run that keeps only the
/// errors holds a chunk of them, not the whole sequence.
const RECON_CHUNK: usize = 4096;

/// One region's solve: its key shapes (minus the neutral in delta mode), the neutrals,
/// and the weights.
struct Part {
    s_d: DMatrix<f64>,
    b_d: DMatrix<f64>,
    bases: Option<(DVector<f64>, DVector<f64>)>,
    w: DMatrix<f64>,
}

/// Source and target reconstructions of frames `c0..c0 + len`: each region's
/// `S_d w + base`, blended over regions (or the one region's, whole).
fn reconstruct(
    parts: &[Part],
    regions: Option<&RegionPlan>,
    dims: usize,
    n: usize,
    n_t: usize,
    c0: usize,
    len: usize,
) -> (DMatrix<f64>, DMatrix<f64>) {
    let one = |p: &Part| {
        let w = p.w.columns(c0, len);
        let mut rec_s = &p.s_d * w;
        let mut rec_t = &p.b_d * w;
        if let Some((sb, tb)) = &p.bases {
            for mut c in rec_s.column_iter_mut() {
                c += sb;
            }
            for mut c in rec_t.column_iter_mut() {
                c += tb;
            }
        }
        (rec_s, rec_t)
    };
    let Some(plan) = regions else {
        return one(&parts[0]);
    };
    let mut source = DMatrix::zeros(n, len);
    let mut out = DMatrix::zeros(n_t, len);
    for (r, p) in parts.iter().enumerate() {
        let (rec_s, rec_t) = one(p);
        for i in 0..n / dims {
            let bw = plan.blend[(i, r)];
            if bw == 0.0 {
                continue;
            }
            for d in 0..dims {
                let row = i * dims + d;
                for t in 0..len {
                    source[(row, t)] += bw * rec_s[(row, t)];
                    out[(row, t)] += bw * rec_t[(row, t)];
                }
            }
        }
    }
    (source, out)
}

/// Adds the seeded tracing offsets of key column `key` (see [`Target::Warp`]).
fn add_tracing(shape: &mut [f64], sigma: f64, key: usize) {
    use rand::{Rng, SeedableRng};
    if sigma <= 0.0 {
        return;
    }
    let mut rng = rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(
        0x7ACE ^ (key as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15),
    );
    for v in shape.iter_mut() {
        // Box–Muller.
        let (u1, u2): (f64, f64) = (rng.gen_range(f64::EPSILON..1.0), rng.gen());
        *v += sigma * (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos();
    }
}
