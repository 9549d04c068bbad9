//! Where the shared data lives (`../shared/data` or `KSLAB_SHARED`).

use keyshape_core::error::{Error, Result};
use std::path::Path;

/// A file of the shared data folder (`shared/data/<rel>`, the tracks and meshes beside the
/// repository), found without depending on the current directory: in `$KSLAB_SHARED/data`
/// when that variable is set (it names the folder holding `data/`), else in `../shared/data`
/// beside the repository this binary was built from, else beside the repository the
/// running binary sits in (`<repo>/target/<profile>/kslab`). The error names every path
/// tried.
pub fn shared_data(rel: &str) -> Result<std::path::PathBuf> {
    use std::path::PathBuf;
    let mut tried = Vec::new();
    if let Some(dir) = std::env::var_os("KSLAB_SHARED") {
        let p = PathBuf::from(dir).join("data").join(rel);
        if p.exists() {
            return Ok(p);
        }
        // An explicit setting that does not hold the file is an error, not a fallback.
        return Err(Error::invalid(format!(
            "{} not found (KSLAB_SHARED is set to the folder that should hold data/{rel})",
            p.display()
        )));
    }
    // This crate sits at <repo>/crates/keyshape-io.
    let mut roots: Vec<PathBuf> = Path::new(env!("CARGO_MANIFEST_DIR"))
        .ancestors()
        .nth(2)
        .map(Path::to_path_buf)
        .into_iter()
        .collect();
    if let Some(repo) = std::env::current_exe()
        .ok()
        .and_then(|e| e.ancestors().nth(3).map(Path::to_path_buf))
    {
        roots.push(repo);
    }
    for root in roots {
        let p = root.join("../shared/data").join(rel);
        if p.exists() {
            return Ok(p);
        }
        let shown = p.display().to_string();
        if !tried.contains(&shown) {
            tried.push(shown);
        }
    }
    Err(Error::invalid(format!(
        "shared data file data/{rel} not found: tried {} (set KSLAB_SHARED to the folder holding data/, or give the file explicitly)",
        tried.join(" and ")
    )))
}
