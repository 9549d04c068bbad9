//! The book cannot drift from the code.
//!
//! - Every number the book quotes from a command sits under the command in a `sh` block as a
//!   `# → …` line; this test runs the command and finds each such line in what it printed
//!   (round three found rig.md's "3.5 → 2.2 px" at 3.941 → 2.796, its neutral frame 253
//!   at 446).
//! - `commands.md` lists every option of every subcommand: its options reference is made
//!   from the command line's own `--help` and compared here (`UPDATE_SNAPSHOTS=1` rewrites
//!   it; `rig-accuracy --landmarks`, `rig --landmark-weight` and `bench kmeans` were
//!   missing).

use std::path::PathBuf;
use std::process::Command;

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// (file, command words, expected fragments) of every checked command in the book.
fn quoted_commands() -> Vec<(String, Vec<String>, Vec<String>)> {
    let mut out = Vec::new();
    let mut docs: Vec<PathBuf> = std::fs::read_dir(root().join("docs/src"))
        .unwrap()
        .flatten()
        .map(|e| e.path())
        .filter(|p| p.extension().is_some_and(|e| e == "md"))
        .collect();
    docs.push(root().join("README.md"));
    docs.sort();
    for doc in docs {
        let text = std::fs::read_to_string(&doc).unwrap();
        let mut in_sh = false;
        let mut cmd: Option<(Vec<String>, Vec<String>)> = None;
        let mut pending = String::new();
        let mut flush = |cmd: &mut Option<(Vec<String>, Vec<String>)>| {
            if let Some((words, want)) = cmd.take() {
                if !want.is_empty() {
                    out.push((doc.display().to_string(), words, want));
                }
            }
        };
        for line in text.lines() {
            if line.starts_with("```") {
                flush(&mut cmd);
                in_sh = line.trim() == "```sh";
                continue;
            }
            if !in_sh {
                continue;
            }
            if let Some(w) = line.strip_prefix("# → ") {
                if let Some((_, want)) = cmd.as_mut() {
                    want.push(w.to_string());
                }
                continue;
            }
            if !pending.is_empty() || line.starts_with("kslab ") {
                pending.push_str(line.trim_end_matches('\\'));
                pending.push(' ');
                if line.ends_with('\\') {
                    continue;
                }
                flush(&mut cmd);
                let words: Vec<String> = pending
                    .split_whitespace()
                    .skip(1)
                    .map(String::from)
                    .collect();
                pending.clear();
                cmd = Some((words, Vec::new()));
            } else if !line.starts_with('#') {
                flush(&mut cmd);
            }
        }
        flush(&mut cmd);
    }
    out
}

#[test]
fn every_output_the_book_quotes_is_what_the_command_prints() {
    let shared = root().join("../shared");
    let cases = quoted_commands();
    assert!(
        cases.len() >= 4,
        "{} checked commands in the book",
        cases.len()
    );
    let mut failures = Vec::new();
    for (doc, words, want) in cases {
        let d = tempfile::tempdir().unwrap();
        // Paths as the book writes them (from the repository) made absolute; outputs go to
        // a scratch folder.
        let args: Vec<String> = words
            .iter()
            .map(|w| {
                if let Some(rest) = w.strip_prefix("../shared/") {
                    shared.join(rest).display().to_string()
                } else if !w.starts_with('-') && root().join(w).exists() {
                    root().join(w).display().to_string()
                } else {
                    w.clone()
                }
            })
            .collect();
        let out = Command::new(env!("CARGO_BIN_EXE_kslab"))
            .args(&args)
            .arg("-q")
            .current_dir(d.path())
            .output()
            .unwrap();
        let said = format!(
            "{}{}",
            String::from_utf8_lossy(&out.stdout),
            String::from_utf8_lossy(&out.stderr)
        );
        if !out.status.success() {
            failures.push(format!("{doc}: kslab {}: failed: {said}", words.join(" ")));
            continue;
        }
        for w in want {
            if !said.contains(&w) {
                failures.push(format!(
                    "{doc}: kslab {}\n  quotes: {w}\n  printed: {said}",
                    words.join(" ")
                ));
            }
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// The text up to the first ". " that ends a sentence (not "e.g. " or "i.e. ").
fn first_sentence(text: &str) -> &str {
    let mut from = 0;
    while let Some(i) = text[from..].find(". ") {
        let end = from + i;
        let before = &text[..end];
        if before.ends_with("e.g") || before.ends_with("i.e") || before.ends_with("cf") {
            from = end + 2;
            continue;
        }
        return &text[..end];
    }
    text.trim_end_matches('.')
}

/// Every subcommand's (and `bench`'s) options as `--help` lists them, one line each:
/// `--name <VALUE>  first sentence of its help`.
fn options_reference() -> String {
    let help = |args: &[&str]| -> String {
        let out = Command::new(env!("CARGO_BIN_EXE_kslab"))
            .args(args)
            .arg("--help")
            .output()
            .unwrap();
        String::from_utf8_lossy(&out.stdout).into_owned()
    };
    let commands = |text: &str| -> Vec<String> {
        text.split("Commands:")
            .nth(1)
            .unwrap_or("")
            .split("Options:")
            .next()
            .unwrap_or("")
            .lines()
            .filter_map(|l| l.split_whitespace().next().map(String::from))
            .filter(|c| c != "help")
            .collect()
    };
    let mut out = String::new();
    for sub in commands(&help(&[])) {
        let mut paths = vec![vec![sub.clone()]];
        let h = help(&[&sub]);
        for inner in commands(&h) {
            paths.push(vec![sub.clone(), inner]);
        }
        for path in paths {
            let args: Vec<&str> = path.iter().map(String::as_str).collect();
            let text = help(&args);
            let opts: Vec<String> = text
                .split("Options:")
                .nth(1)
                .unwrap_or("")
                .lines()
                .filter_map(|l| {
                    let t = l.trim_start();
                    if !t.starts_with('-') {
                        return None;
                    }
                    // "  -q, --quiet  No progress bar …" → the flag part and the first sentence.
                    let (flag, rest) = match t.find("  ") {
                        Some(i) => (&t[..i], t[i..].trim()),
                        None => (t, ""),
                    };
                    if flag.contains("--help") || flag.contains("--quiet") {
                        return None;
                    }
                    let first = first_sentence(rest.split(" [default").next().unwrap_or(""));
                    Some(format!(
                        "| `{}` | {} |",
                        flag.replace('|', "\\|"),
                        first.replace('|', "\\|")
                    ))
                })
                .collect();
            out.push_str(&format!("\n### kslab {}\n\n", path.join(" ")));
            if opts.is_empty() {
                out.push_str("No options of its own.\n");
            } else {
                out.push_str("| option | what it sets |\n| --- | --- |\n");
                for o in opts {
                    out.push_str(&o);
                    out.push('\n');
                }
            }
        }
    }
    out
}

#[test]
fn commands_md_lists_every_option_the_command_line_has() {
    let path = root().join("docs/src/commands.md");
    let text = std::fs::read_to_string(&path).unwrap();
    let (begin, end) = ("<!-- options:begin -->", "<!-- options:end -->");
    let want = options_reference();
    let (Some(b), Some(e)) = (text.find(begin), text.find(end)) else {
        panic!("commands.md has no {begin} … {end} section");
    };
    let got = &text[b + begin.len()..e];
    if got.trim() != want.trim() {
        if std::env::var_os("UPDATE_SNAPSHOTS").is_some() {
            let new = format!("{}{begin}\n{}\n{}", &text[..b], want.trim(), &text[e..]);
            std::fs::write(&path, new).unwrap();
            return;
        }
        panic!(
            "commands.md's options reference is not the command line's (UPDATE_SNAPSHOTS=1 rewrites it):\n{}",
            want
        );
    }
    for must in [
        "--landmarks",
        "--landmark-weight",
        "### kslab bench kmeans",
        "--image-size",
    ] {
        assert!(got.contains(must), "{must}");
    }
}
