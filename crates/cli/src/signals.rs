//! Ctrl-C (SIGINT), SIGTERM and SIGHUP end the process without running destructors, which
//! would leave a build's hidden `.froct-*.tmp` output and `.froct-spill-*` directory behind.
//! A thread waits for those signals (through `signal-hook`, which keeps the handler itself
//! to the async-signal-safe minimum), removes every temporary path the libraries registered
//! ([`froctomap_core::cleanup`]), then ends the process by the same signal with its default
//! action, so that the parent sees it killed by the signal (the shell's 128 + n).

use signal_hook::consts::{SIGHUP, SIGINT, SIGTERM};

/// Starts the thread; without it (it could not be started) signals act as they would anyway.
pub fn clean_up_on_signals() {
    let Ok(mut signals) = signal_hook::iterator::Signals::new([SIGINT, SIGTERM, SIGHUP]) else {
        return;
    };
    let started = std::thread::Builder::new()
        .name("signals".into())
        .spawn(move || {
            if let Some(signal) = signals.forever().next() {
                end_by(signal);
            }
        });
    drop(started);
}

/// Removes the registered temporary paths and ends the process by `signal`.
pub fn end_by(signal: i32) -> ! {
    froctomap_core::cleanup::remove_registered();
    // Ends the process by the signal; should that fail, exit as a shell would.
    let _ = signal_hook::low_level::emulate_default_handler(signal);
    std::process::exit(128 + signal);
}
