//! Ctrl-C (SIGINT) and SIGTERM for long runs: a flag to poll instead of a dead process.
//!
//! A long command (a stream, a calibration, a sweep, a served board) installs the handler once
//! ([`install`]) and polls [`requested`] between its steps; on a request it stops what it is
//! doing the way a finished run would (the board told, files completed, the summary printed)
//! and exits with [`crate::exit::INTERRUPTED`] (130, what a shell reports for a process killed
//! by Ctrl-C), through [`crate::Failure::Interrupted`] or the CLI's own error carrying it.
//!
//! The handler only stores to an atomic, the one thing a signal handler may do safely. It is
//! installed with `SA_RESETHAND`: a second Ctrl-C gets the default action and ends the process
//! at once, for a run that does not stop when asked. Without `SA_RESTART` a blocking read
//! returns `EINTR` at once, which the links treat as "nothing yet".

use std::sync::atomic::{AtomicBool, Ordering};

static REQUESTED: AtomicBool = AtomicBool::new(false);

extern "C" fn on_signal(_signal: libc::c_int) {
    REQUESTED.store(true, Ordering::SeqCst);
}

/// Routes SIGINT and SIGTERM to the flag (idempotent); returns the flag.
pub fn install() -> &'static AtomicBool {
    for signal in [libc::SIGINT, libc::SIGTERM] {
        // SAFETY: a zeroed sigaction is valid (empty mask, no flags); the handler is async-
        // signal-safe (one atomic store); sigaction with a null old-action pointer is allowed.
        unsafe {
            let mut action: libc::sigaction = std::mem::zeroed();
            action.sa_sigaction = on_signal as extern "C" fn(libc::c_int) as libc::sighandler_t;
            action.sa_flags = libc::SA_RESETHAND;
            libc::sigemptyset(&mut action.sa_mask);
            libc::sigaction(signal, &action, std::ptr::null_mut());
        }
    }
    &REQUESTED
}

/// Whether SIGINT or SIGTERM arrived since [`install`].
pub fn requested() -> bool {
    REQUESTED.load(Ordering::SeqCst)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A SIGTERM to this process sets the flag and does not end the process.
    #[test]
    fn a_signal_sets_the_flag() {
        let flag = install();
        // SAFETY: raising a signal whose handler is installed above.
        unsafe { libc::raise(libc::SIGTERM) };
        assert!(flag.load(Ordering::SeqCst) && requested());
    }
}
