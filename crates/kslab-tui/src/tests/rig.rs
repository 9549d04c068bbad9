//! The rig view: its panels, its worker, its λ, and the prompt, split view and narrow
//! screens around it.

use super::*;

/// `kslab tui --rig DIR` — the track solved onto the ICT rig when the lab
/// opens; `r` shows the tracked landmarks with the posed rig and the rig's weights as named
/// bars, largest first (on frame 150, the scream, jawOpen among the first). Without a rig,
/// `r` says how to get one.
#[test]
fn the_rig_view_names_the_largest_weights_and_r_toggles_it() {
    let rig = keyshape_rig::correspondence::RigSource::new(super::shared("ict_facekit_face"));
    let view = crate::rig::rig_view(&builtin_sequence().unwrap(), &rig).unwrap();
    let mut s = computed_state(Settings::default());
    update(&mut s, Action::Rig);
    assert!(s.status.contains("open the lab with --rig"), "{}", s.status);
    s.rig = Some(std::sync::Arc::new(view.clone()));
    s.frame = 150;
    update(&mut s, Action::Rig);
    assert!(s.show_rig);
    let text = screen(&s, 80, 24);
    assert!(text.contains("track + posed rig"), "{text}");
    assert!(text.contains("of 55 active"), "{text}");
    // The bars are the frame's largest weights, in order, each with its name.
    let w = &view.weights[150];
    let mut order: Vec<usize> = (0..w.len()).collect();
    order.sort_by(|&a, &b| w[b].abs().total_cmp(&w[a].abs()).then(a.cmp(&b)));
    let first: Vec<&str> = order[..5].iter().map(|&i| view.names[i].as_str()).collect();
    assert!(first.contains(&"jawOpen"), "{first:?}");
    let pos: Vec<usize> = first
        .iter()
        .map(|n| text.find(&format!("{n} ")).unwrap())
        .collect();
    assert!(
        pos.windows(2).all(|p| p[0] < p[1]),
        "bars out of order: {first:?}"
    );
    // The lower panels describe the rig solve too: the frame's largest
    // weights and the landmark error over time, with no key-shape chart, bars or key marks.
    // Its title names the frame's largest weights, in order, each cut to the room it has
    // (at the scream the smiles that stretch the mouth's corners, the lower lip, jawOpen).
    let over = text.find("over time: ").unwrap();
    let named: Vec<&str> = text[over + "over time: ".len()..]
        .split_whitespace()
        .take(3)
        .collect();
    for (token, full) in named.iter().zip(&first) {
        let room = token.chars().count();
        assert_eq!(
            crate::rig_panels::abbreviate(full, room),
            *token,
            "{first:?}\n{text}"
        );
    }
    assert!(text.contains("landmark RMS over time"), "{text}");
    for key_shape_only in ["E(k)", "key frames", "◆"] {
        assert!(
            !text.contains(key_shape_only),
            "{key_shape_only} in\n{text}"
        );
    }
    assert_screen(&text, "tui_rig_80x24.txt");
    // `e` in the rig view exports the rig's weights on screen, not the key-shape solve's
    // (round three).
    let dir = tempfile::tempdir().unwrap();
    let files = crate::export::export(&s, "builtin", dir.path()).unwrap();
    assert!(files[0].ends_with("rig_weights.csv"), "{files:?}");
    let text_csv = std::fs::read_to_string(&files[0]).unwrap();
    let mut lines = text_csv.lines();
    let head: Vec<&str> = lines.next().unwrap().split(',').collect();
    assert_eq!(head[..2], ["frame", "rms"]);
    assert_eq!(
        head[2..],
        view.names.iter().map(String::as_str).collect::<Vec<_>>()[..]
    );
    let rows: Vec<&str> = lines.collect();
    assert_eq!(rows.len(), view.weights.len());
    let row150: Vec<f64> = rows[150]
        .split(',')
        .skip(2)
        .map(|v| v.parse().unwrap())
        .collect();
    assert_eq!(row150, view.weights[150]);
    assert!(std::path::Path::new(&files[1]).exists());
    update(&mut s, Action::Rig);
    assert!(!s.show_rig);
    let text = screen(&s, 80, 24);
    assert!(text.contains("key frames") && text.contains("◆"), "{text}");
}

/// In the open prompt a space is part of the path, not play / pause (`o`
/// dropped spaces from a path).
#[test]
fn a_space_in_the_open_prompt_is_part_of_the_path() {
    use crate::interpret;
    use crossterm::event::{KeyCode, KeyEvent, KeyModifiers};
    let mut s = State::new("builtin", 216, 30.0);
    let key = |c: KeyCode| KeyEvent::new(c, KeyModifiers::NONE);
    // Outside a prompt, space plays.
    assert!(matches!(
        interpret(&s, key(KeyCode::Char(' '))),
        Some(Action::TogglePlay)
    ));
    update(&mut s, Action::Open);
    for c in "my tracks/a b.csv".chars() {
        let a = interpret(&s, key(KeyCode::Char(c))).unwrap();
        update(&mut s, a);
    }
    assert!(!s.playing, "the space toggled playback");
    let effects = update(&mut s, Action::Enter);
    assert_eq!(effects.len(), 1);
    assert!(
        matches!(&effects[0], Effect::Load(_, p) if p == "my tracks/a b.csv"),
        "{effects:?}"
    );
}

/// A sequence opened with `o` in a lab started with `--rig` is solved onto the rig too
/// (the rig was forgotten), and a track the rig cannot take says why.
#[test]
fn the_rig_stays_with_the_lab_when_another_sequence_is_opened() {
    use crate::compute::{spawn_with_rig, Job};
    let rig = std::sync::Arc::new(keyshape_rig::correspondence::RigSource::new(super::shared(
        "ict_facekit_face",
    )));
    let (jobs, results) = spawn_with_rig(builtin_sequence().unwrap(), None, Some(rig));
    let d18 = super::shared("mediapipe_face_tracks/liveportrait_d18.csv");
    jobs.send(Job::Load(3, d18.display().to_string())).unwrap();
    let mut s = State::new("builtin", 216, 30.0);
    s.request = 3;
    // The rig solves on its own worker, each step named, until its answer to request 3.
    let mut got = Vec::new();
    let mut steps = Vec::new();
    loop {
        let a = results.recv_timeout(Duration::from_secs(60)).unwrap();
        got.push(format!("{a:?}").chars().take(12).collect::<String>());
        let done = matches!(a, Action::RigSolved(3, _));
        if let Action::RigStep(3, step) = &a {
            steps.push(step.clone());
        }
        update(&mut s, a);
        if done {
            break;
        }
    }
    assert!(
        s.rig.is_some() && s.show_rig,
        "{got:?}: the new track is not on the rig"
    );
    assert!(s.rig_step.is_none(), "{:?}", s.rig_step);
    assert!(
        steps.iter().any(|t| t.starts_with("choosing the neutral"))
            && steps.iter().any(|t| t.starts_with("solving 216 frames")),
        "{steps:?}"
    );
    // A track of no layout the rig knows: the key-shape view, and the reason.
    let d = tempfile::tempdir().unwrap();
    let plain = d.path().join("three.csv");
    std::fs::write(
        &plain,
        "frame,x0,y0,x1,y1,x2,y2\n0,0,0,1,0,0,1\n1,0,0,2,0,0,1\n",
    )
    .unwrap();
    jobs.send(Job::Load(4, plain.display().to_string()))
        .unwrap();
    s.request = 4;
    loop {
        let a = results.recv_timeout(Duration::from_secs(60)).unwrap();
        let done = matches!(a, Action::RigSolved(4, _));
        update(&mut s, a);
        if done {
            break;
        }
    }
    assert!(s.rig.is_none() && !s.show_rig);
    assert!(s.status.starts_with("rig: "), "{}", s.status);
}

/// `l` steers the rig view too: a request with λ solves the rig again with
/// the offline temporal prior at that λ — a larger λ, smoother weights — and the screen says
/// which prior it shows; an older request's rig is dropped.
#[test]
fn l_solves_the_rig_view_again_with_the_offline_prior() {
    use crate::compute::{spawn_with_rig, Job};
    let rig = std::sync::Arc::new(keyshape_rig::correspondence::RigSource::new(super::shared(
        "ict_facekit_face",
    )));
    let (jobs, results) = spawn_with_rig(builtin_sequence().unwrap(), None, Some(rig.clone()));
    let plain = crate::rig::rig_view(&builtin_sequence().unwrap(), &rig).unwrap();
    let mut s = State::new("builtin", 216, 30.0);
    s.rig = Some(std::sync::Arc::new(plain.clone()));
    s.show_rig = true;
    let solve_at = |s: &mut State, presses: usize| {
        let mut last = None;
        for _ in 0..presses {
            last = update(s, Action::Smooth(true)).into_iter().next();
        }
        let Some(Effect::Compute(id, settings)) = last else {
            panic!("l asks for no computation");
        };
        jobs.send(Job::Compute(id, settings.clone())).unwrap();
        loop {
            let a = results.recv_timeout(Duration::from_secs(120)).unwrap();
            let got = match &a {
                Action::RigSmoothed(i, v) => Some((*i, v.clone().unwrap())),
                _ => None,
            };
            update(s, a);
            if let Some((i, v)) = got {
                assert_eq!(i, id);
                assert_eq!(v.smooth, settings.smooth);
                assert!(std::sync::Arc::ptr_eq(s.rig.as_ref().unwrap(), &v));
                return (id, v);
            }
        }
    };
    let jitter = |r: &crate::rig::RigView| {
        let w = nalgebra::DMatrix::from_fn(r.names.len(), r.weights.len(), |i, f| r.weights[f][i]);
        keyshape_core::solve::jitter::weight_jitter(&w, std::slice::from_ref(&(0..r.weights.len())))
    };
    let (_, v100) = solve_at(&mut s, 3);
    assert_eq!(v100.smooth, 100.0);
    assert_ne!(v100.weights, plain.weights);
    let top = screen(&s, 80, 24);
    assert!(top.contains("bounded λ100"), "{top}");
    let (id, v1000) = solve_at(&mut s, 1);
    assert!(
        jitter(&v1000) < jitter(&v100),
        "{} vs {}",
        jitter(&v1000),
        jitter(&v100)
    );
    // A rig answer for an older request is dropped.
    update(
        &mut s,
        Action::RigSmoothed(id - 1, Ok(std::sync::Arc::new(plain))),
    );
    assert!(std::sync::Arc::ptr_eq(s.rig.as_ref().unwrap(), &v1000));
}

/// The worker's first answer is what the screen shows; the split view's solvers follow and
/// join the same request, and a stale answer is dropped.
#[test]
fn the_split_view_follows_the_first_answer_and_joins_its_request() {
    let mut engine = Engine::new(builtin_sequence().unwrap());
    let mut s = State::new("builtin", 216, 30.0);
    s.request = 1;
    let shown = engine.compute_shown(1, &Settings::default()).unwrap();
    assert_eq!(shown.views.len(), 1);
    update(&mut s, Action::Computed(Box::new(shown)));
    s.split = true;
    assert!(screen(&s, 100, 30).contains("computing LS and NNLS for the split view"));
    let rest = engine.split_views(1).unwrap();
    assert_eq!(rest.len(), 1, "nnls is shown: ls follows");
    // A stale request's views are dropped.
    update(&mut s, Action::SplitViews(0, rest.clone()));
    assert_eq!(s.computed.as_ref().unwrap().views.len(), 1);
    update(&mut s, Action::SplitViews(1, rest));
    assert_eq!(s.computed.as_ref().unwrap().views.len(), 2);
    let whole = Engine::new(builtin_sequence().unwrap())
        .compute(1, &Settings::default())
        .unwrap();
    let c = s.computed.as_ref().unwrap();
    for (a, b) in c.views.iter().zip(&whole.views) {
        assert_eq!((a.solver, &a.weights), (b.solver, &b.weights));
    }
    assert!(!screen(&s, 100, 30).contains("computing LS and NNLS"));
}

/// At 80 × 24: the chart's legend names every method, the header keeps
/// a long file name, and at k ≥ 15 every key still shows its weight as a shade and a value.
#[test]
fn eighty_columns_keep_the_legend_the_file_name_and_the_weights() {
    let legend = crate::charts::legend_labels("nnls", 40);
    assert_eq!(legend.1.len(), 8);
    assert!(legend.0.chars().count() + legend.1.iter().map(|n| n.len() + 1).sum::<usize>() <= 40);
    assert_eq!(crate::charts::legend_labels("nnls", 80).0, "E(k) nnls: ");
    let mut s = computed_state(Settings {
        k: 16,
        ..Settings::default()
    });
    s.source = "/home/someone/tracks/liveportrait_d18.csv".into();
    let text = screen(&s, 80, 24);
    let header = text.lines().next().unwrap();
    // The name, shortened from the left when the settings need the room.
    assert!(header.contains("d18.csv"), "{header}");
    assert!(
        header.contains("spread k=16") && header.contains("err "),
        "{header}"
    );
    let chart_row = text.lines().find(|l| l.contains("km2m")).unwrap();
    for name in ["spr", "km2", "km3", "km2m", "km3m", "hull", "grd", "rnd"] {
        assert!(chart_row.contains(name), "{name} missing: {chart_row}");
    }
    // The weights panel: 16 keys, each with a shade and a value.
    let panel: Vec<&str> = text.lines().skip(15).take(6).collect();
    let shaded = panel
        .iter()
        .map(|l| l.split("││").nth(1).unwrap_or(""))
        .map(|l| l.chars().filter(|c| "░▒▓█".contains(*c)).count())
        .sum::<usize>();
    assert!(shaded >= 1, "no weight shown as a shade: {text}");
    // The split view's source title keeps both numbers whole ("NNLS 0.3" was cut).
    s.split = true;
    let text = screen(&s, 80, 24);
    let title = text.lines().nth(1).unwrap();
    let nnls = title.split("NNLS ").nth(1).unwrap();
    let num: String = nnls
        .chars()
        .take_while(|c| c.is_ascii_digit() || *c == '.')
        .collect();
    // Whole: three significant digits, then the border.
    let digits = num.trim_start_matches(['0', '.']).len();
    assert_eq!(digits, 3, "{title}");
    assert!(nnls[num.len()..].starts_with('─'), "{title}");
}

/// The README's and the book's picture of the lab (100×30, frame 150) is the lab's screen,
/// so it cannot drift from the code (round three: "rms 0.42" there while the lab showed
/// 0.417).
#[test]
fn the_readme_screen_is_the_labs_screen() {
    let mut s = computed_state(Settings::default());
    s.source = "builtin:liveportrait_d18".into();
    let want = screen(&s, 100, 30);
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    for doc in ["README.md", "docs/src/introduction.md"] {
        let text = std::fs::read_to_string(root.join(doc)).unwrap();
        let start = text
            .find("```text\n kslab ")
            .expect("the lab's screen block")
            + 8;
        let end = start + text[start..].find("```").unwrap();
        let got: Vec<&str> = text[start..end].lines().map(str::trim_end).collect();
        let want: Vec<&str> = want.lines().map(str::trim_end).collect();
        if std::env::var_os("UPDATE_SNAPSHOTS").is_some() && got != want[..got.len()] {
            let block = want[..got.len()].join("\n") + "\n";
            std::fs::write(
                root.join(doc),
                format!("{}{block}{}", &text[..start], &text[end..]),
            )
            .unwrap();
            continue;
        }
        assert_eq!(
            got,
            want[..got.len()],
            "{doc}: its screen block is not the lab's (UPDATE_SNAPSHOTS=1 rewrites it)"
        );
    }
}

/// The rig solves on a worker of its own, so the lab opens at once: while it solves, the
/// header names the step, `r` says the view is coming, and a new λ reuses the neutral of the
/// last solve — the same weights as a solve that searches for it again, without the search.
#[test]
fn the_rig_solves_in_the_background_and_names_its_steps() {
    let rig = keyshape_rig::correspondence::RigSource::new(super::shared("ict_facekit_face"));
    let seq = builtin_sequence().unwrap();
    let mut s = computed_state(Settings::default());
    let (request, loaded) = (s.request, s.loaded);
    update(
        &mut s,
        Action::RigStep(
            request,
            "choosing the neutral: 48 candidate frames, each scored on 64".into(),
        ),
    );
    let text = screen(&s, 120, 30);
    assert!(text.contains("rig: choosing the neutral"), "{text}");
    update(&mut s, Action::Rig);
    assert!(
        s.status.contains("the rig is still solving"),
        "{}",
        s.status
    );
    assert!(!s.show_rig);
    // A λ with the neutral of the first solve: the same as searching again.
    let mut steps = Vec::new();
    let first =
        crate::rig::rig_view_observed(&seq, &rig, 0.0, None, &mut |t| steps.push(t)).unwrap();
    assert!(
        steps.iter().any(|t| t.starts_with("choosing the neutral")),
        "{steps:?}"
    );
    let mut again = Vec::new();
    let hinted =
        crate::rig::rig_view_observed(&seq, &rig, 100.0, first.neutral, &mut |t| again.push(t))
            .unwrap();
    assert!(
        !again.iter().any(|t| t.starts_with("choosing the neutral")),
        "{again:?}"
    );
    let searched = crate::rig::rig_view_smoothed(&seq, &rig, 100.0).unwrap();
    assert_eq!(hinted.neutral, searched.neutral);
    assert_eq!(hinted.weights, searched.weights);
    // Its answer ends the step.
    update(
        &mut s,
        Action::RigSolved(loaded, Ok(std::sync::Arc::new(first))),
    );
    assert!(s.rig_step.is_none() && s.show_rig);
}

/// A newly loaded track's first frame shows before the take is solved: the worker sends a
/// one-frame preview (its neutral searched on the 68-point map) and then the take, which
/// replaces it. The preview opens the rig view, says what it is, refuses `e`, and never
/// replaces a take already solved. On the built-in sequence its neutral is the take's and
/// its weights are the take's first frame within 0.1 (the take smooths over time and fits
/// the identity's depth; measured 0.068).
#[test]
fn a_new_track_s_first_frame_shows_before_the_take_and_the_take_replaces_it() {
    use std::sync::mpsc::channel;
    let rig = std::sync::Arc::new(keyshape_rig::correspondence::RigSource::new(super::shared(
        "ict_facekit_face",
    )));
    let seq = std::sync::Arc::new(builtin_sequence().unwrap());
    let (tx, rx) = channel();
    let _jobs = crate::rig_worker::spawn(rig, seq, tx);
    let (mut preview, mut solved, mut steps) = (None, None, Vec::new());
    while solved.is_none() {
        match rx
            .recv_timeout(std::time::Duration::from_secs(120))
            .unwrap()
        {
            Action::RigStep(0, step) => steps.push(step),
            Action::RigPreview(0, v) => {
                assert!(solved.is_none(), "the preview came after the take");
                preview = Some(v);
            }
            Action::RigSolved(0, r) => solved = Some(r.unwrap()),
            other => panic!("{other:?}"),
        }
    }
    let (preview, solved) = (preview.expect("no preview"), solved.unwrap());
    assert!(
        steps
            .iter()
            .any(|s| s.contains("first frame alone, its neutral searched on 68 points")),
        "{steps:?}"
    );
    assert_eq!(preview.preview, Some(0));
    assert_eq!(solved.preview, None);
    assert_eq!(preview.weights.len(), 1);
    assert_eq!(preview.neutral, solved.neutral);
    let worst = preview.weights[0]
        .iter()
        .zip(&solved.weights[0])
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f64::max);
    assert!(worst < 0.1, "preview against the take: {worst}");
    assert_eq!(preview.tracked[0], solved.tracked[0]);

    let mut s = computed_state(Settings::default());
    s.loaded = 0;
    s.rig_step = Some("solving 216 frames".into());
    update(&mut s, Action::RigPreview(0, preview.clone()));
    assert!(s.show_rig);
    s.frame = 100;
    let text = screen(&s, 100, 30);
    for said in [
        "first frame alone · rms",
        "shapes, preview",
        "rig: preview",
        "solving 216 frames",
    ] {
        assert!(text.contains(said), "{said} in\n{text}");
    }
    assert_screen(&screen(&s, 80, 24), "tui_rig_preview_80x24.txt");
    let dir = tempfile::tempdir().unwrap();
    let e = crate::export::export(&s, "builtin", dir.path()).unwrap_err();
    assert!(e.to_string().contains("still solving"), "{e}");
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);
    update(&mut s, Action::RigSolved(0, Ok(solved.clone())));
    assert_eq!(s.rig.as_ref().unwrap().preview, None);
    // A late preview (an older load's) does not replace the take.
    update(&mut s, Action::RigPreview(0, preview));
    assert_eq!(s.rig.as_ref().unwrap().preview, None);
    let text = screen(&s, 100, 30);
    assert!(text.contains("track + posed rig"), "{text}");
}
