//! What a signal handler calls: `abandon` removes the open set's staged files, staging
//! folders and made folders, and refuses every write after it. (A binary of its own: it
//! ends the process's ability to write.)

// Test code: a failed unwrap is a failed test with its message.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use keyshape_io::{write_atomic, OutputSet};

#[test]
fn abandon_removes_what_was_staged_and_refuses_later_writes() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    std::fs::write(d.join("w.csv"), "old").unwrap();
    let set = OutputSet::begin();
    keyshape_io::create_dir_all(&d.join("pd")).unwrap();
    for i in 0..5 {
        write_atomic(&d.join(format!("pd/{i}.png")), |w| w.write_all(b"png")).unwrap();
    }
    write_atomic(&d.join("w.csv"), |w| w.write_all(b"new")).unwrap();
    // Another thread's open set goes too: a signal ends every command of the process.
    let (staged, abandoned) = (
        std::sync::Arc::new(std::sync::Barrier::new(2)),
        std::sync::Arc::new(std::sync::Barrier::new(2)),
    );
    let other = {
        let (d, staged, abandoned) = (d.to_path_buf(), staged.clone(), abandoned.clone());
        std::thread::spawn(move || {
            let set = OutputSet::begin();
            write_atomic(&d.join("other.csv"), |w| w.write_all(b"other")).unwrap();
            staged.wait();
            abandoned.wait();
            set.commit()
        })
    };
    staged.wait();
    keyshape_io::atomic::abandon();
    abandoned.wait();
    assert!(
        other.join().unwrap().is_err(),
        "the other thread's set commits"
    );
    let left: Vec<_> = std::fs::read_dir(d)
        .unwrap()
        .flatten()
        .map(|e| e.file_name())
        .collect();
    assert_eq!(left, ["w.csv"]);
    assert_eq!(std::fs::read_to_string(d.join("w.csv")).unwrap(), "old");
    let e = write_atomic(&d.join("x.csv"), |w| w.write_all(b"x")).expect_err("after abandon");
    assert!(e.to_string().contains("the command was stopped"), "{e}");
    assert!(set.commit().is_err());
    assert!(!d.join("x.csv").exists());
}
