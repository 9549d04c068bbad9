//! The output set as one mechanism: all or nothing at every step of the final renames,
//! targets checked again before the first, and what an output may be (no FIFO, no device
//! but /dev/null, no read-only file, no setuid result, no link planted by another user in a
//! shared sticky folder, one output per stream).
//!
//! A set belongs to the thread that opened it, and a deleted input's inode number, given to
//! a new file, no longer counts as that input: so these tests run in parallel, as the lab's
//! exports may.

// Test code: a failed unwrap is a failed test with its message.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use keyshape_io::atomic::{check_distinct, check_output, register_input};
use keyshape_io::{write_atomic, OutputSet};
use std::path::{Path, PathBuf};
use std::sync::{Arc, Barrier};

fn write(p: &Path, text: &str) -> keyshape_core::Result<()> {
    write_atomic(p, |w| w.write_all(text.as_bytes()))
}

/// Names in `dir`, sorted, the hidden ones included.
fn names(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .flatten()
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .collect();
    v.sort();
    v
}

/// Three outputs in two folders: two replace files, one is new.
fn three_targets(d: &Path) -> Vec<PathBuf> {
    std::fs::create_dir_all(d.join("sub")).unwrap();
    std::fs::write(d.join("a.csv"), "old a").unwrap();
    std::fs::write(d.join("sub/b.csv"), "old b").unwrap();
    vec![d.join("a.csv"), d.join("sub/b.csv"), d.join("c.csv")]
}

fn assert_untouched(d: &Path) {
    assert_eq!(std::fs::read_to_string(d.join("a.csv")).unwrap(), "old a");
    assert_eq!(
        std::fs::read_to_string(d.join("sub/b.csv")).unwrap(),
        "old b"
    );
    assert!(!d.join("c.csv").exists(), "a new output stayed");
    assert_eq!(names(d), ["a.csv", "sub"], "a staging folder stayed");
    assert_eq!(names(&d.join("sub")), ["b.csv"], "a staging folder stayed");
}

#[test]
fn a_rename_that_fails_at_any_position_leaves_every_output_as_it_was() {
    for fail_at in 0..3 {
        let tmp = tempfile::tempdir().unwrap();
        let d = tmp.path();
        let targets = three_targets(d);
        let set = OutputSet::begin();
        for (i, t) in targets.iter().enumerate() {
            write(t, &format!("new {i}")).unwrap();
        }
        // Nothing is visible before the commit.
        assert_eq!(std::fs::read_to_string(&targets[0]).unwrap(), "old a");
        let mut n = 0;
        let r = set.commit_with(&mut |from, to| {
            n += 1;
            if n - 1 == fail_at {
                Err(std::io::Error::other("injected"))
            } else {
                std::fs::rename(from, to)
            }
        });
        let e = r.expect_err("the injected failure must fail the commit");
        assert!(e.to_string().contains("injected"), "{e}");
        assert_untouched(d);
    }
    // And without a failure, all three land and nothing else stays.
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    let targets = three_targets(d);
    let set = OutputSet::begin();
    for (i, t) in targets.iter().enumerate() {
        write(t, &format!("new {i}")).unwrap();
    }
    let shown = set.commit().unwrap();
    assert_eq!(shown, targets);
    for (i, t) in targets.iter().enumerate() {
        assert_eq!(std::fs::read_to_string(t).unwrap(), format!("new {i}"));
    }
    assert_eq!(names(d), ["a.csv", "c.csv", "sub"]);
    assert_eq!(names(&d.join("sub")), ["b.csv"]);
}

#[test]
fn a_folder_planted_at_a_target_fails_the_set_before_any_rename() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    let targets = three_targets(d);
    let set = OutputSet::begin();
    for t in &targets {
        write(t, "new").unwrap();
    }
    std::fs::create_dir(d.join("c.csv")).unwrap();
    let e = set.commit().expect_err("a folder at c.csv");
    assert!(e.to_string().contains("is a directory"), "{e}");
    assert_eq!(std::fs::read_to_string(d.join("a.csv")).unwrap(), "old a");
    assert_eq!(
        std::fs::read_to_string(d.join("sub/b.csv")).unwrap(),
        "old b"
    );
    assert_eq!(names(d), ["a.csv", "c.csv", "sub"]);
}

#[test]
fn a_file_read_after_it_was_staged_as_an_output_is_not_replaced() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    std::fs::create_dir(d.join("rig")).unwrap();
    std::fs::write(d.join("rig/names.csv"), "rig data").unwrap();
    let set = OutputSet::begin();
    write(&d.join("rig/names.csv"), "trajectories").unwrap();
    write(&d.join("other.csv"), "x").unwrap();
    // The command reads the rig folder only after it staged its output (as `map --morph`
    // did): every file of the folder is an input.
    register_input(&d.join("rig")).unwrap();
    let e = set.commit().expect_err("an input");
    assert!(e.to_string().contains("this is the input file"), "{e}");
    assert_eq!(
        std::fs::read_to_string(d.join("rig/names.csv")).unwrap(),
        "rig data"
    );
    assert!(!d.join("other.csv").exists());
    assert_eq!(names(&d.join("rig")), ["names.csv"]);
    // The registry holds (device, inode): the folder stays for the rest of the process, so
    // that no later test's file reuses the inode of an input.
    std::mem::forget(tmp);
}

#[test]
fn a_dropped_set_removes_its_staging_folders_and_the_folders_it_made() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    {
        let _set = OutputSet::begin();
        keyshape_io::create_dir_all(&d.join("pd/deeper")).unwrap();
        for i in 0..30 {
            write(&d.join(format!("pd/deeper/f{i}.png")), "png").unwrap();
        }
        write(&d.join("w.csv"), "w").unwrap();
        // While staged: one staging folder per output folder, whatever the file count.
        assert_eq!(names(&d.join("pd/deeper")).len(), 1);
        assert!(names(&d.join("pd/deeper"))[0].starts_with(".kslab-staging-"));
    }
    assert_eq!(names(d), Vec::<String>::new());
}

#[cfg(unix)]
#[test]
fn special_files_read_only_files_and_setuid_bits() {
    use std::os::unix::fs::PermissionsExt;
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    // A FIFO is refused at once (it would block until a reader came).
    let fifo = d.join("fifo.csv");
    let ok = std::process::Command::new("mkfifo")
        .arg(&fifo)
        .status()
        .is_ok_and(|s| s.success());
    if ok {
        let e = check_output(&fifo, &[]).expect_err("a FIFO");
        assert!(e.to_string().contains("a FIFO"), "{e}");
        let e = write(&fifo, "x").expect_err("a FIFO");
        assert!(e.to_string().contains("a FIFO"), "{e}");
    }
    // A device is refused; /dev/null takes anything, any number of times.
    let e = check_output(Path::new("/dev/zero"), &[]).expect_err("a device");
    assert!(e.to_string().contains("a device"), "{e}");
    check_output(Path::new("/dev/null"), &[]).unwrap();
    check_distinct(&[Path::new("/dev/null"), Path::new("/dev/null")]).unwrap();
    write(Path::new("/dev/null"), "gone").unwrap();
    // A read-only file is refused, named, and left alone.
    let ro = d.join("ro.csv");
    std::fs::write(&ro, "keep").unwrap();
    std::fs::set_permissions(&ro, std::fs::Permissions::from_mode(0o444)).unwrap();
    let e = write(&ro, "new").expect_err("read-only");
    assert!(
        e.to_string()
            .contains("ro.csv: refusing to replace a read-only file (mode 444)"),
        "{e}"
    );
    assert_eq!(std::fs::read_to_string(&ro).unwrap(), "keep");
    // A setuid file's replacement keeps its permission bits but not setuid or setgid.
    let su = d.join("su.csv");
    std::fs::write(&su, "x").unwrap();
    std::fs::set_permissions(&su, std::fs::Permissions::from_mode(0o6755)).unwrap();
    write(&su, "y").unwrap();
    let mode = std::fs::metadata(&su).unwrap().permissions().mode() & 0o7777;
    assert_eq!(mode, 0o755);
}

#[test]
fn two_outputs_on_standard_output_are_refused() {
    let e = check_distinct(&[Path::new("-"), Path::new("-")]).expect_err("- twice");
    assert!(e.to_string().contains("standard output"), "{e}");
    // /dev/stdout is standard output too, unless standard output is /dev/null here.
    let null = std::fs::read_link("/proc/self/fd/1").is_ok_and(|l| l == Path::new("/dev/null"));
    if cfg!(target_os = "linux") && !null && Path::new("/proc/self/fd/1").exists() {
        let e = check_distinct(&[Path::new("/dev/stdout"), Path::new("-")])
            .expect_err("/dev/stdout and -");
        assert!(e.to_string().contains("standard output"), "{e}");
    }
}

/// The kernel's protected-symlinks rule, applied in user space: in a 1777 folder a link
/// owned by another user (not the folder's owner) is not followed. Needs root to give the
/// link away; elsewhere the test checks that a link of one's own is followed.
#[cfg(unix)]
#[test]
fn a_link_planted_by_another_user_in_a_sticky_folder_is_not_followed() {
    use std::os::unix::fs::PermissionsExt;
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    let victim = d.join("victim");
    std::fs::create_dir(&victim).unwrap();
    std::fs::write(victim.join("secret"), "secret").unwrap();
    let sticky = d.join("sticky");
    std::fs::create_dir(&sticky).unwrap();
    std::fs::set_permissions(&sticky, std::fs::Permissions::from_mode(0o1777)).unwrap();
    let link = sticky.join("w.csv");
    std::os::unix::fs::symlink(victim.join("secret"), &link).unwrap();
    let root = std::process::Command::new("id")
        .arg("-u")
        .output()
        .is_ok_and(|o| o.stdout.trim_ascii() == b"0");
    if root {
        // Give the link to `nobody`, as if that user had planted it.
        std::os::unix::fs::lchown(&link, Some(65534), Some(65534)).unwrap();
        let e = write(&link, "overwritten").expect_err("a planted link");
        assert!(
            e.to_string().contains("refusing to follow this link"),
            "{e}"
        );
        assert_eq!(
            std::fs::read_to_string(victim.join("secret")).unwrap(),
            "secret"
        );
        // A dangling one makes no file either.
        let dangling = sticky.join("d.csv");
        std::os::unix::fs::symlink(victim.join("new"), &dangling).unwrap();
        std::os::unix::fs::lchown(&dangling, Some(65534), Some(65534)).unwrap();
        assert!(write(&dangling, "x").is_err());
        assert!(!victim.join("new").exists());
    } else {
        write(&link, "mine").unwrap();
        assert_eq!(
            std::fs::read_to_string(victim.join("secret")).unwrap(),
            "mine"
        );
    }
}

/// A write that fails half way (a full disk while filling the second file) fails the
/// command: nothing of it is visible, the first file staged is gone with the set.
#[test]
fn a_write_that_fails_while_filling_leaves_nothing_behind() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    std::fs::write(d.join("a.csv"), "old a").unwrap();
    {
        let _set = OutputSet::begin();
        write(&d.join("a.csv"), "new a").unwrap();
        let e = write_atomic(&d.join("b.csv"), |w| {
            w.write_all(b"half")?;
            Err(std::io::Error::new(
                std::io::ErrorKind::StorageFull,
                "disk full",
            ))
        })
        .expect_err("the fill fails");
        assert!(e.to_string().contains("b.csv"), "{e}");
        // The set is dropped with the command's error.
    }
    assert_eq!(std::fs::read_to_string(d.join("a.csv")).unwrap(), "old a");
    assert_eq!(names(d), ["a.csv"]);
}

/// Two threads, each with a set open at once: one commits, the other is dropped. Each
/// thread's files follow its own set. (With one set for the process, the second thread's
/// file joined the first's set: its commit returned nothing written, and the first's drop
/// discarded it.) A write outside any set, from a third thread, is in place when it returns.
#[test]
fn each_thread_s_set_commits_or_discards_only_its_own_files() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path().to_path_buf();
    let both_open = Arc::new(Barrier::new(3));
    let first_done = Arc::new(Barrier::new(3));
    let spawn = |name: &'static str, commit: bool| {
        let (d, both_open, first_done) = (d.clone(), both_open.clone(), first_done.clone());
        std::thread::spawn(move || {
            let set = OutputSet::begin();
            write(&d.join(name), name).unwrap();
            both_open.wait();
            if commit {
                let out = set.commit().unwrap();
                first_done.wait();
                out
            } else {
                first_done.wait();
                drop(set);
                Vec::new()
            }
        })
    };
    let kept = spawn("kept.csv", true);
    let dropped = spawn("dropped.csv", false);
    both_open.wait();
    // While both are open, a write from a thread with no set of its own is not staged in
    // either.
    write(&d.join("alone.csv"), "alone").unwrap();
    assert_eq!(
        std::fs::read_to_string(d.join("alone.csv")).unwrap(),
        "alone"
    );
    first_done.wait();
    assert_eq!(kept.join().unwrap(), [d.join("kept.csv")]);
    assert!(dropped.join().unwrap().is_empty());
    assert_eq!(names(&d), ["alone.csv", "kept.csv"]);
    assert_eq!(
        std::fs::read_to_string(d.join("kept.csv")).unwrap(),
        "kept.csv"
    );
}
