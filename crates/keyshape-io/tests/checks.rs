//! What an output may be, checked in the crate (`cargo mutants` on `atomic/check.rs` found
//! these reached only through the command line's tests): a read-only file, a folder that
//! is a file, a probe name already taken, links of one's own, two outputs that are one.

// Test code: a failed unwrap is a failed test with its message.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use keyshape_io::atomic::check_distinct;
use keyshape_io::{check_output, check_output_dir};
use std::path::Path;

fn err(r: keyshape_core::error::Result<()>) -> String {
    r.unwrap_err().to_string()
}

#[cfg(unix)]
#[test]
fn a_file_without_a_write_bit_is_refused_naming_its_mode() {
    use std::os::unix::fs::PermissionsExt;
    let d = tempfile::tempdir().unwrap();
    let f = d.path().join("w.csv");
    std::fs::write(&f, "old").unwrap();
    std::fs::set_permissions(&f, std::fs::Permissions::from_mode(0o444)).unwrap();
    let e = err(check_output(&f, &[]));
    assert!(e.contains("read-only file (mode 444)"), "{e}");
    for mode in [0o644, 0o600, 0o200, 0o020, 0o002] {
        std::fs::set_permissions(&f, std::fs::Permissions::from_mode(mode)).unwrap();
        // The owner's bit for the owner; as root (CI), any write bit.
        let me_root = unsafe_free_is_root();
        let ok = check_output(&f, &[]).is_ok();
        if me_root || mode & 0o200 != 0 {
            assert!(ok, "mode {mode:o}");
        }
    }
    assert_eq!(
        std::fs::read_to_string(&f).unwrap(),
        "old",
        "a check writes nothing"
    );
}

#[cfg(unix)]
fn unsafe_free_is_root() -> bool {
    use std::os::unix::fs::MetadataExt;
    // A file this process makes is owned by its effective user.
    let d = tempfile::tempdir().unwrap();
    let f = d.path().join("me");
    std::fs::write(&f, "").unwrap();
    std::fs::metadata(&f).unwrap().uid() == 0
}

#[test]
fn an_output_under_a_file_is_refused_and_a_new_folder_is_not() {
    let d = tempfile::tempdir().unwrap();
    let file = d.path().join("f.txt");
    std::fs::write(&file, "x").unwrap();
    let e = err(check_output(&file.join("w.csv"), &[]));
    assert!(e.contains("is not a directory"), "{e}");
    let e = err(check_output_dir(&file.join("pngs")));
    assert!(
        e.contains("cannot make this directory") && e.contains("is a file"),
        "{e}"
    );
    let e = err(check_output_dir(&file));
    assert!(e.contains("is a file"), "{e}");
    // Folders that do not exist yet, however deep, under a folder that takes files.
    check_output_dir(&d.path().join("a/b/c")).unwrap();
    check_output_dir(d.path()).unwrap();
    assert!(!d.path().join("a").exists(), "a check makes nothing");
    // A bare relative name: its folder is the current one.
    check_output_dir(Path::new("kslab-no-such-folder-here")).unwrap();
    check_output(Path::new("kslab-no-such-file-here.csv"), &[]).unwrap();
}

#[test]
fn a_probe_name_already_taken_still_lets_the_folder_take_files() {
    let d = tempfile::tempdir().unwrap();
    let probe = d
        .path()
        .join(format!(".kslab-probe-{}", std::process::id()));
    std::fs::write(&probe, "someone's").unwrap();
    check_output(&d.path().join("w.csv"), &[]).unwrap();
    assert_eq!(std::fs::read_to_string(&probe).unwrap(), "someone's");
}

#[cfg(unix)]
#[test]
fn ones_own_links_are_followed_in_a_sticky_folder_and_in_anothers() {
    use std::os::unix::fs::PermissionsExt;
    let d = tempfile::tempdir().unwrap();
    let target = d.path().join("target.csv");
    std::fs::write(&target, "t").unwrap();
    // A sticky, world-writable folder: a link of one's own is followed.
    let sticky = d.path().join("sticky");
    std::fs::create_dir(&sticky).unwrap();
    std::fs::set_permissions(&sticky, std::fs::Permissions::from_mode(0o1777)).unwrap();
    std::os::unix::fs::symlink(&target, sticky.join("w.csv")).unwrap();
    check_output(&sticky.join("w.csv"), &[]).unwrap();
    // A folder of another user's, not sticky: a link of one's own is followed too.
    if unsafe_free_is_root() {
        let theirs = d.path().join("theirs");
        std::fs::create_dir(&theirs).unwrap();
        std::os::unix::fs::symlink(&target, theirs.join("w.csv")).unwrap();
        let ok = std::process::Command::new("chown")
            .args(["65534", theirs.to_str().unwrap()])
            .status()
            .unwrap();
        assert!(ok.success());
        check_output(&theirs.join("w.csv"), &[]).unwrap();
    }
}

#[test]
fn two_outputs_that_are_one_are_named() {
    let d = tempfile::tempdir().unwrap();
    let w = d.path().join("w.csv");
    let e = err(check_distinct(&[Path::new("-"), Path::new("-")]));
    assert!(e.contains("both would go to standard output"), "{e}");
    let e = err(check_distinct(&[&w, &w]));
    assert!(e.ends_with("named as two outputs"), "{e}");
    // Another name of the same file (a hard link).
    std::fs::write(&w, "x").unwrap();
    let other = d.path().join("link.csv");
    std::fs::hard_link(&w, &other).unwrap();
    let e = err(check_distinct(&[&w, &other]));
    assert!(
        e.contains("named as two outputs") && !e.ends_with("named as two outputs"),
        "{e}"
    );
    check_distinct(&[&w, &d.path().join("v.csv"), Path::new("-")]).unwrap();
    check_distinct(&[Path::new("/dev/null"), Path::new("/dev/null")]).unwrap();
}
