//! The export, the λ knob, the chart's clicks and the keys that do not apply.

use super::*;

#[test]
fn clicking_the_error_chart_picks_the_nearest_method_and_k() {
    let mut s = computed_state(Settings::default());
    let area = ratatui::layout::Rect::new(0, 0, 80, 24);
    let c = crate::charts::chart_area(area);
    // Bottom-right corner of the plot: the largest k, the lowest error.
    let (col, row) = (c.x + c.width - 2, c.y + c.height - 4);
    let (m, k) = view::chart_pick(area, &s, col, row).unwrap();
    assert_eq!(k, 24);
    let rows = s.curves.clone().unwrap();
    let lowest = rows
        .iter()
        .filter(|r| r.k == 24)
        .min_by(|a, b| a.rms.total_cmp(&b.rms))
        .unwrap();
    assert_eq!(m.name(), lowest.method);
    assert!(
        view::chart_pick(area, &s, 1, 1).is_none(),
        "a click outside the chart picks nothing"
    );
    let fx = update(&mut s, Action::Pick(m, k));
    assert_eq!(
        fx,
        vec![Effect::Compute(
            2,
            Settings {
                method: m,
                k,
                ..Settings::default()
            }
        )]
    );
}

/// A job that panics becomes that job's error, and the worker goes on: the next job is
/// answered (a dead worker left "computing…" spinning forever).
#[test]
fn a_panicking_job_does_not_kill_the_worker() {
    use crate::compute::{spawn, Job};
    use crate::state::Action;
    use std::time::Duration;
    let seq = builtin_sequence().unwrap();
    let (jobs, results) = spawn(seq, None);
    jobs.send(Job::Crash(7)).unwrap();
    match results.recv_timeout(Duration::from_secs(30)).unwrap() {
        Action::Failed(id, msg) => {
            assert_eq!(id, 7);
            assert!(
                msg.contains("internal error") && msg.contains("crashed on purpose"),
                "{msg}"
            );
        }
        other => panic!("expected the crash as an error, got {other:?}"),
    }
    jobs.send(Job::Load(8, "builtin".into())).unwrap();
    match results.recv_timeout(Duration::from_secs(30)).unwrap() {
        Action::Loaded(id, _, frames, _) => {
            assert_eq!(id, 8);
            assert_eq!(frames, 216);
        }
        other => panic!("the worker did not answer after a crash: {other:?}"),
    }
}

/// `e` writes head motion the way `kslab retarget --head-motion` does: with `apply` the CSV
/// carries each frame's pose (the similarity alignment removed) and the picture is drawn in
/// image coordinates; with `none`, neither. kmeansN-mean weights are named by cluster.
#[test]
fn export_applies_head_motion_or_not_and_names_mean_keys() {
    let seq = builtin_sequence().unwrap();
    let mut engine = Engine::new(seq);
    let mut s = state();
    let c = engine.compute(1, &Settings::default()).unwrap();
    let head = c.head.clone().unwrap();
    s.computed = Some(c);
    s.frame = 150;
    let dir = tempfile::tempdir().unwrap();
    let read =
        |sub: &str| std::fs::read_to_string(dir.path().join(sub).join("weights.csv")).unwrap();
    crate::export::export(&s, "builtin", &dir.path().join("apply")).unwrap();
    s.export_head_motion = false;
    crate::export::export(&s, "builtin", &dir.path().join("none")).unwrap();
    let (a, n) = (read("apply"), read("none"));
    assert!(a
        .lines()
        .next()
        .unwrap()
        .ends_with(",head_scale,head_angle_deg,head_tx,head_ty"));
    assert!(!n.contains("head_"));
    // Row of frame 150: the pose is the alignment's similarity for that frame.
    let row: Vec<f64> = a
        .lines()
        .nth(151)
        .unwrap()
        .split(',')
        .map(|v| v.parse().unwrap())
        .collect();
    let h = head[150];
    let pose = &row[row.len() - 4..];
    assert!((pose[0] - h.scale).abs() < 1e-9 && (pose[1] - h.angle.to_degrees()).abs() < 1e-9);
    assert!((pose[2] - h.t[0]).abs() < 1e-9 && (pose[3] - h.t[1]).abs() < 1e-9);
    assert_ne!(
        std::fs::read(dir.path().join("apply/view.png")).unwrap(),
        std::fs::read(dir.path().join("none/view.png")).unwrap(),
        "the picture follows the option"
    );
    // kmeans2-mean: weights belong to cluster means, not to frames.
    let m = Settings {
        method: keyshape_core::keyshapes::Method::parse("kmeans2-mean").unwrap(),
        ..Settings::default()
    };
    s.computed = Some(engine.compute(2, &m).unwrap());
    s.settings = m;
    crate::export::export(&s, "builtin", &dir.path().join("mean")).unwrap();
    let header = read("mean").lines().next().unwrap().to_string();
    assert!(
        header.contains(",w_mean0,") && !header.contains(",w_1"),
        "{header}"
    );
    let toml = std::fs::read_to_string(dir.path().join("mean/experiment.toml")).unwrap();
    assert!(
        toml.contains("\"kmeans2-mean\"") && !toml.contains("\n[retarget]"),
        "{toml}"
    );
}

/// `l` / `L`: λ in decades from off; each step recomputes, the weights are the library's
/// smoothed solve of the same keys, jitter falls, the header shows λ and jitter at 80
/// columns, and the export's `[smooth]` table reproduces the exported weights' errors.
#[test]
// One segment is written `&[0..t]`: a slice holding one range, as the API takes.
#[allow(clippy::single_range_in_vec_init)]
fn the_lambda_knob_smooths_the_weights_and_the_export_reproduces_them() {
    use crate::state::SMOOTH_STEPS;
    let mut s = state();
    s.start();
    assert!(
        update(&mut s, Action::Smooth(false)).is_empty(),
        "off is the bottom"
    );
    assert!(s.status.contains("already off"), "{}", s.status);
    let fx = update(&mut s, Action::Smooth(true));
    assert_eq!(
        fx,
        vec![Effect::Compute(
            2,
            Settings {
                smooth: 1.0,
                ..Settings::default()
            }
        )]
    );
    for _ in 0..20 {
        update(&mut s, Action::Smooth(true));
    }
    assert_eq!(s.settings.smooth, *SMOOTH_STEPS.last().unwrap());
    assert!(s.status.contains("largest"), "{}", s.status);
    update(&mut s, Action::Smooth(false));
    assert_eq!(s.settings.smooth, 1e5);

    let mut engine = Engine::new(builtin_sequence().unwrap());
    let plain = engine.compute(1, &Settings::default()).unwrap();
    let set = Settings {
        smooth: 1e4,
        ..Settings::default()
    };
    let smooth = engine.compute(2, &set).unwrap();
    let (p, q) = (&plain.views[0], &smooth.views[0]);
    assert!(
        q.target_jitter < 0.6 * p.target_jitter,
        "{} {}",
        q.target_jitter,
        p.target_jitter
    );
    assert!(q.source_rms > p.source_rms);
    // The same keys through the library's smoothed solve.
    let prep = keyshape_core::decompose::prepare(
        &builtin_sequence().unwrap(),
        &keyshape_core::decompose::PrepareOptions::group_aligned("lips"),
    )
    .unwrap();
    let sk = prep.seq.coords.select_columns(&smooth.keys);
    let r = keyshape_core::solve::temporal::solve_smooth(
        &sk,
        &prep.seq.coords,
        keyshape_core::solve::Solver::Nnls,
        &keyshape_core::solve::temporal::Smoothing {
            lambda: 1e4,
            order: 1,
            mode: keyshape_core::solve::temporal::SmoothMode::Offline,
        },
        &[0..prep.seq.coords.ncols()],
    )
    .unwrap();
    assert!((&r.weights - &q.weights).amax() < 1e-12);

    let mut t = state();
    t.settings = set.clone();
    t.request = 2;
    update(&mut t, Action::Computed(Box::new(smooth.clone())));
    let head = screen(&t, 80, 24).lines().next().unwrap().to_string();
    for part in [
        "nnls λ=1e4",
        "frame 0",
        "spread k=12",
        &format!("err {:.2} jit {:.2}", q.target_rms, q.target_jitter),
    ] {
        assert!(head.contains(part), "{part} not in {head:?}");
    }
    // That the export reproduces these numbers through `kslab run` is checked with the
    // binary: tests/it/tui.rs.
}

/// Keys that cannot apply say why instead of recomputing; the hull's k is the one it
/// picked; a long path in the prompt shows its end.
#[test]
fn keys_that_do_not_apply_say_why_and_the_hull_shows_its_k() {
    let mut s = state();
    s.start();
    s.target_keys = true;
    for a in [
        Action::Method(true),
        Action::K(1),
        Action::Pick(keyshape_core::keyshapes::Method::Random, 5),
    ] {
        s.status.clear();
        assert!(update(&mut s, a).is_empty());
        assert!(s.status.contains("come from --target"), "{}", s.status);
    }
    assert_eq!(s.settings, Settings::default());
    let hull = Settings {
        method: keyshape_core::keyshapes::Method::Hull,
        ..Settings::default()
    };
    let mut h = computed_state(hull.clone());
    assert!(update(&mut h, Action::K(1)).is_empty());
    assert!(h.status.contains("hull picks its own"), "{}", h.status);
    let n = h.computed.as_ref().unwrap().keys.len();
    let head = screen(&h, 80, 24).lines().next().unwrap().to_string();
    assert!(head.contains(&format!("hull k={n} (hull's own)")), "{head}");
    assert_ne!(n, 12, "the hull's k is its own, not the setting's");
    // The prompt.
    assert_eq!(view::prompt_line("ab", 10), "ab▏");
    let long = "/a/very/long/path/to/some/track.csv";
    let line = view::prompt_line(long, 12);
    assert_eq!(line, "…/track.csv▏");
    assert_eq!(line.chars().count(), 12);
}
