//! Every signal whose default action ends the process (INT, TERM, HUP, QUIT, USR1, USR2,
//! ALRM, VTALRM, PROF, IO, XCPU, XFSZ, PWR, STKFLT and the real-time signals) ends a
//! command as a failure does: its staged outputs and the folders it made are removed
//! ([`keyshape_io::atomic::abandon`]), then the signal takes its default course, so the
//! parent sees the process killed by it. (SIGUSR1 during `retarget --png-dir` left staging
//! folders when only INT, TERM and HUP were covered.) SIGKILL and SIGSTOP cannot be caught;
//! the faults (SEGV, BUS, ILL, FPE, ABRT, TRAP, SYS) are the program's own and keep their
//! default; SIGPIPE is ignored by the Rust runtime (a closed pipe is a write error).

/// The signals whose default action ends the process and that a handler may take.
#[cfg(unix)]
pub(crate) fn terminating() -> Vec<libc::c_int> {
    let mut v = vec![
        libc::SIGINT,
        libc::SIGTERM,
        libc::SIGHUP,
        libc::SIGQUIT,
        libc::SIGUSR1,
        libc::SIGUSR2,
        libc::SIGALRM,
        libc::SIGVTALRM,
        libc::SIGPROF,
        libc::SIGIO,
        libc::SIGXCPU,
        libc::SIGXFSZ,
    ];
    #[cfg(any(target_os = "linux", target_os = "android"))]
    {
        v.extend([libc::SIGPWR, libc::SIGSTKFLT]);
        v.extend(libc::SIGRTMIN()..=libc::SIGRTMAX());
    }
    v
}

/// Starts the thread that waits for the signals. Errors (no thread, no handler) leave the
/// default handling, under which a staging folder may be left behind.
pub(crate) fn install() {
    #[cfg(unix)]
    {
        let Ok(mut signals) = signal_hook::iterator::Signals::new(terminating()) else {
            return;
        };
        let _ = std::thread::Builder::new()
            .name("kslab-signals".into())
            .spawn(move || {
                if let Some(sig) = signals.forever().next() {
                    keyshape_io::atomic::abandon();
                    let _ = signal_hook::low_level::emulate_default_handler(sig);
                    std::process::exit(128 + sig);
                }
            });
    }
}
