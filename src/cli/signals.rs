//! SIGINT, SIGTERM and SIGHUP end a command as a failure does: its staged outputs and the
//! folders it made are removed ([`keyshape_io::atomic::abandon`]), then the signal takes
//! its default course, so the parent sees the process killed by it.

/// Starts the thread that waits for the signals. Errors (no thread, no handler) leave the
/// default handling, under which a staging folder may be left behind.
pub(crate) fn install() {
    #[cfg(unix)]
    {
        use signal_hook::consts::{SIGHUP, SIGINT, SIGTERM};
        let Ok(mut signals) = signal_hook::iterator::Signals::new([SIGINT, SIGTERM, SIGHUP]) else {
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
