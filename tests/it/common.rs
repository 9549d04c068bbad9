//! Helpers shared by the integration tests.

use std::path::PathBuf;

/// `../shared/data/<rel>` next to this repository.
pub fn shared(rel: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../shared/data")
        .join(rel)
}

/// Runs the Khronos glTF validator (npm `gltf-validator`, installed into `tools/gltf` by
/// `.ci/run`, or by hand: `cd tools/gltf && npm install`) on `glb` and asserts it reports no
/// errors. A missing validator fails the test: a test that cannot check must not pass.
pub fn assert_valid_gltf(glb: &std::path::Path) {
    let tool = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tools/gltf");
    assert!(
        tool.join("node_modules/gltf-validator").exists(),
        "the glTF validator is not installed: run `cd tools/gltf && npm install` (.ci/run does)"
    );
    let out = std::process::Command::new("node")
        .arg(tool.join("validate.js"))
        .arg(glb)
        .output()
        .expect("node is needed to run the glTF validator");
    let report = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "validator: {report} {}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(report.contains("\"errors\":0"), "{report}");
}

/// What a run of the real binary gave.
pub struct Run {
    pub code: i32,
    pub stdout: String,
    pub stderr: String,
}

/// A library error as the command line prints it: each setting it names as the flag
/// (`dims` → `--dims`), as `kslab` spells them.
pub fn as_cli(e: &keyshape_core::Error) -> String {
    e.render(&|n| format!("--{}", n.replace('_', "-")))
}

/// Runs the `kslab` binary with `args`.
pub fn kslab(args: &[&str]) -> Run {
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_kslab"))
        .args(args)
        .output()
        .unwrap();
    Run {
        code: out.status.code().unwrap_or(-1),
        stdout: String::from_utf8_lossy(&out.stdout).into_owned(),
        stderr: String::from_utf8_lossy(&out.stderr).into_owned(),
    }
}

/// Runs each command of `cases` and checks it is refused (exit 1) with its reason on
/// standard error.
pub fn assert_refused(cases: &[(Vec<&str>, &str)]) {
    for (args, needle) in cases {
        let r = kslab(args);
        assert_eq!(r.code, 1, "{args:?}: {}", r.stderr);
        assert!(r.stderr.contains(needle), "{args:?}: {}", r.stderr);
    }
}
