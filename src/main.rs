//! `kslab`: the keyshape-lab command line.

mod cli;

fn main() -> std::process::ExitCode {
    cli::main()
}
