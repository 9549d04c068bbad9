//! `kslab`: the keyshape-lab command line.

mod cli;

/// mimalloc keeps freed memory for reuse: the temporal prior's active-set iterations
/// allocate and drop factorisations of ~100 MB each, and glibc's allocator returns each to
/// the system and takes it back page fault by page fault (`kslab bench smooth`: 15× → see
/// BENCHMARKS.md). The library leaves the choice of allocator to its callers.
#[global_allocator]
static GLOBAL: mimalloc::MiMalloc = mimalloc::MiMalloc;

fn main() -> std::process::ExitCode {
    cli::main()
}
