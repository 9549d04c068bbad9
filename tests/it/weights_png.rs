//! The weights-over-time picture (`solve --png`, `retarget --png`): each cell's colour is
//! the diverging scale at that weight, a one-frame spike survives when frames outnumber
//! pixels, and the commands write it (and refuse to write it over their input).
//! Here: what runs the `kslab` binary; the library's own tests are in `crates/keyshape-pictures/tests/weights_png.rs`.

#[test]
fn solve_and_retarget_write_the_picture_and_never_over_their_input() {
    let dir = tempfile::tempdir().unwrap();
    let run = |args: &[&str]| {
        std::process::Command::new(env!("CARGO_BIN_EXE_kslab"))
            .args(args)
            .output()
            .unwrap()
    };
    let png = dir.path().join("w.png");
    let o = run(&[
        "solve",
        "--keys",
        "0,50,100",
        "--png",
        png.to_str().unwrap(),
        "--json",
        "-q",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let bytes = std::fs::read(&png).unwrap();
    assert_eq!(&bytes[1..4], b"PNG");
    let png2 = dir.path().join("r.png");
    let o = run(&[
        "retarget",
        "--points",
        "lips",
        "--method",
        "spread",
        "--k",
        "6",
        "--png",
        png2.to_str().unwrap(),
        "-q",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(png2.is_file());
    // Onto the input: refused before any work, the input untouched.
    let input = dir.path().join("t.csv");
    std::fs::copy(
        crate::common::shared("pyfeat_samples/news_sample_compact.csv"),
        &input,
    )
    .unwrap();
    let before = std::fs::read(&input).unwrap();
    let o = run(&[
        "solve",
        input.to_str().unwrap(),
        "--keys",
        "0,40",
        "--png",
        input.to_str().unwrap(),
        "--json",
    ]);
    assert_eq!(o.status.code(), Some(1));
    assert_eq!(std::fs::read(&input).unwrap(), before);
}
