//! The lab's binary in tmux. The lab's own tests (update, screens, loop, export, rig view)
//! are in its crate: `crates/kslab-tui/src/tests/`.

use keyshape_io::builtin_sequence;
use kslab_tui::{update, Action, Engine, Settings, State};
use std::time::Duration;

/// The real binary in tmux: start, step, change k, toggle solver, quit.
#[test]
fn the_binary_runs_in_tmux() {
    use std::process::Command;
    assert!(
        Command::new("tmux").arg("-V").output().is_ok(),
        "tmux is needed for this test: install it (.ci/run does)"
    );
    let name = format!("kslab-test-{}", std::process::id());
    let tmux = |args: &[&str]| Command::new("tmux").args(args).output().unwrap();
    let bin = env!("CARGO_BIN_EXE_kslab");
    let out = tmux(&[
        "new-session",
        "-d",
        "-s",
        &name,
        "-x",
        "100",
        "-y",
        "30",
        bin,
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let capture =
        || String::from_utf8_lossy(&tmux(&["capture-pane", "-t", &name, "-p"]).stdout).into_owned();
    let wait_for = |needle: &str| {
        for _ in 0..100 {
            let screen = capture();
            if screen.contains(needle) {
                return screen;
            }
            std::thread::sleep(Duration::from_millis(100));
        }
        let screen = capture();
        tmux(&["kill-session", "-t", &name]);
        panic!("'{needle}' never appeared:\n{screen}");
    };
    wait_for("key frames:");
    tmux(&["send-keys", "-t", &name, "Right", "Right", "Right"]);
    wait_for("frame 3 ");
    tmux(&["send-keys", "-t", &name, "+"]);
    wait_for("k=13");
    // k = 24: every key's frame number is in the weights panel (columns when the rows run
    // out), each once. The keys are the engine's for the same settings.
    for _ in 0..11 {
        tmux(&["send-keys", "-t", &name, "+"]);
    }
    wait_for("k=24");
    let want: std::collections::BTreeSet<String> = {
        let settings = Settings {
            k: 24,
            ..Settings::default()
        };
        let c = Engine::new(builtin_sequence().unwrap())
            .compute(1, &settings)
            .unwrap();
        c.keys.iter().map(|&k| c.frames[k].to_string()).collect()
    };
    let mut got = std::collections::BTreeSet::new();
    for _ in 0..300 {
        let screen = capture();
        let panel: Vec<String> = screen
            .lines()
            .skip_while(|l| !l.contains("key frames:"))
            .skip(1)
            // The panel's rows are the lines where it meets the panel on its left
            // ("││"); its bottom border does not. (Not "up to the first '└'": the
            // E(k) plot's axis corner can share a line with the last row.)
            .take_while(|l| l.contains("││"))
            .filter_map(|l| {
                l.rsplit_once("││")
                    .map(|(_, r)| r.trim_end_matches('│').to_string())
            })
            .collect();
        // Frame numbers are the integer tokens; weights are printed with a point.
        got = panel
            .iter()
            .flat_map(|l| l.split(|c: char| !(c.is_ascii_digit() || c == '.' || c == '-')))
            .filter(|t| !t.is_empty() && t.chars().all(|c| c.is_ascii_digit()))
            .map(str::to_string)
            .collect();
        if got == want {
            break;
        }
        std::thread::sleep(Duration::from_millis(100));
    }
    assert_eq!(got, want, "the weights panel at k = 24:\n{}", capture());
    tmux(&["send-keys", "-t", &name, "s"]);
    let screen = wait_for("· ls ·");
    assert!(screen.contains("E(k) ls:"));
    tmux(&["send-keys", "-t", &name, "q"]);
    for _ in 0..50 {
        if !tmux(&["has-session", "-t", &name]).status.success() {
            return;
        }
        std::thread::sleep(Duration::from_millis(100));
    }
    tmux(&["kill-session", "-t", &name]);
    panic!("kslab did not quit on q");
}

/// The lab's export reproduces its smoothed weights: `kslab run` on the exported
/// experiment gives the error and jitter the lab showed for λ = 1e4.
#[test]
fn the_exported_smoothing_reproduces_the_labs_numbers() {
    let mut engine = Engine::new(builtin_sequence().unwrap());
    let set = Settings {
        smooth: 1e4,
        ..Settings::default()
    };
    let smooth = engine.compute(2, &set).unwrap();
    let q = &smooth.views[0];
    let mut t = State::new("builtin", 216, 30.0);
    t.settings = set.clone();
    t.request = 2;
    update(&mut t, Action::Computed(Box::new(smooth.clone())));
    let dir = tempfile::tempdir().unwrap();
    kslab_tui::export(&t, "builtin", dir.path()).unwrap();
    let out = dir.path().join("run");
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_kslab"))
        .args(["run", dir.path().join("experiment.toml").to_str().unwrap()])
        .args(["--out", out.to_str().unwrap(), "-q"])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let csv = std::fs::read_to_string(out.join("smoothing.csv")).unwrap();
    let row: Vec<f64> = csv
        .lines()
        .find(|l| l.starts_with("prior offline order 1,λ 10000,"))
        .unwrap()
        .split(',')
        .skip(2)
        .take(4)
        .map(|v| v.parse().unwrap())
        .collect();
    // source RMS, target RMS against G(q), …, target-point jitter.
    assert!(
        (row[0] - q.source_rms).abs() < 1e-9,
        "{row:?} {}",
        q.source_rms
    );
    assert!(
        (row[1] - q.target_rms).abs() < 1e-9,
        "{row:?} {}",
        q.target_rms
    );
    assert!(
        (row[3] - q.target_jitter).abs() < 1e-9,
        "{row:?} {}",
        q.target_jitter
    );
}
