//! The "Where things live" chapter names real places: every path it names exists, and every
//! source file of the workspace is named, itself or (for a folder of one file each) by the
//! folder that holds it.

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

const CHAPTER: &str = "docs/src/where-things-live.md";

/// The top-level folders a path in the chapter may start from.
const ROOTS: [&str; 12] = [
    "crates/",
    "src/",
    "tests/",
    "tools/",
    "assets/",
    "docs/",
    "examples/",
    "experiments/",
    "fuzz/",
    "deploy/",
    "mutants/",
    "snapshots/",
];

/// Every backticked token of `text` that names a file (`.rs`, `.py`) or a folder (ends in
/// `/`), in order; placeholders (`<command>.rs`) are left out.
fn path_tokens(text: &str) -> Vec<String> {
    text.split('`')
        .skip(1)
        .step_by(2)
        .filter(|t| !t.contains('<') && !t.contains(' '))
        .filter(|t| t.ends_with(".rs") || t.ends_with(".py") || t.ends_with('/'))
        .map(str::to_string)
        .collect()
}

/// Each path token of the chapter resolved against the repository: a token from a root
/// folder as it is; a shorter one (`mod.rs`, `frame/blocks.rs`, `rig/`) within the folder
/// of the last full path before it, or a folder above that one. `Err` names a token that
/// resolves nowhere.
fn resolved(text: &str) -> Vec<Result<PathBuf, String>> {
    let root = root();
    let mut base: Option<PathBuf> = None;
    let mut out = Vec::new();
    for t in path_tokens(text) {
        if ROOTS.iter().any(|r| t.starts_with(r)) {
            let p = root.join(&t);
            base = Some(if t.ends_with('/') {
                p.clone()
            } else {
                p.parent().map_or(root.clone(), Path::to_path_buf)
            });
            out.push(if p.exists() { Ok(p) } else { Err(t) });
            continue;
        }
        let mut dir = base.clone();
        let mut found = None;
        while let Some(d) = dir {
            if !d.starts_with(&root) || d == root {
                break;
            }
            if d.join(&t).exists() {
                found = Some(d.join(&t));
                break;
            }
            dir = d.parent().map(Path::to_path_buf);
        }
        if let Some(d) = found.as_ref().filter(|d| d.is_dir()) {
            base = Some(d.clone());
        }
        out.push(found.ok_or(t));
    }
    out
}

/// The workspace's Rust sources: every `.rs` file under `crates/*/src` and `src/`.
fn sources() -> Vec<PathBuf> {
    fn walk(dir: &Path, out: &mut Vec<PathBuf>) {
        for e in std::fs::read_dir(dir).unwrap().flatten() {
            let p = e.path();
            if p.is_dir() {
                walk(&p, out);
            } else if p.extension().is_some_and(|x| x == "rs") {
                out.push(p);
            }
        }
    }
    let mut out = Vec::new();
    walk(&root().join("src"), &mut out);
    for c in std::fs::read_dir(root().join("crates")).unwrap().flatten() {
        walk(&c.path().join("src"), &mut out);
    }
    out.sort();
    out
}

#[test]
fn every_path_the_chapter_names_exists() {
    let text = std::fs::read_to_string(root().join(CHAPTER)).unwrap();
    let missing: Vec<String> = resolved(&text)
        .into_iter()
        .filter_map(Result::err)
        .collect();
    assert!(
        missing.is_empty(),
        "{CHAPTER} names paths that do not exist: {missing:?}"
    );
    // The oracle of the resolver itself: a made-up name is caught, a short name is found.
    let made_up = "`crates/keyshape-core/src/` (`pca.rs`, `nowhere.rs`)";
    let r = resolved(made_up);
    assert!(r[0].is_ok() && r[1].is_ok(), "{r:?}");
    assert_eq!(r[2], Err("nowhere.rs".to_string()));
}

/// The files of `sources` the chapter does not name: a file is named itself, or by its
/// folder when the chapter names that folder and none of the files in it (a folder of one
/// file each, such as `keyshapes/`), or when it is the folder's own module (`mod.rs`,
/// `lib.rs`). Where the chapter lists some of a folder's files, it
/// must list them all: a new module beside them is not found by looking there.
fn unnamed(named: &BTreeSet<PathBuf>, sources: &[PathBuf]) -> Vec<PathBuf> {
    // A folder's own module (`mod.rs`, a crate's `lib.rs`) goes with the folder.
    let root_module = |f: &Path| {
        f.file_name()
            .is_some_and(|n| n == "mod.rs" || n == "lib.rs")
    };
    let listed = |d: &Path| {
        named
            .iter()
            .any(|n| n.is_file() && n.parent() == Some(d) && !root_module(n))
    };
    sources
        .iter()
        .filter(|f| {
            !named.contains(*f)
                && !f
                    .parent()
                    .is_some_and(|d| named.contains(d) && (root_module(f) || !listed(d)))
        })
        .cloned()
        .collect()
}

#[test]
fn every_source_file_is_named_by_the_chapter() {
    let text = std::fs::read_to_string(root().join(CHAPTER)).unwrap();
    let named: BTreeSet<PathBuf> = resolved(&text).into_iter().flatten().collect();
    let missing: Vec<String> = unnamed(&named, &sources())
        .iter()
        .map(|f| f.strip_prefix(root()).unwrap().display().to_string())
        .collect();
    assert!(
        missing.is_empty(),
        "{CHAPTER} names neither these files nor their folders: {missing:?}"
    );
    // The rule itself, on the core's files: a folder alone covers them; a folder with one
    // of its files listed covers none of the others.
    let core = root().join("crates/keyshape-core/src");
    let files = vec![core.join("pca.rs"), core.join("rbf.rs")];
    let folder: BTreeSet<PathBuf> = [core.clone()].into();
    assert!(unnamed(&folder, &files).is_empty());
    let one: BTreeSet<PathBuf> = [core.clone(), core.join("pca.rs")].into();
    assert_eq!(unnamed(&one, &files), vec![core.join("rbf.rs")]);
}
