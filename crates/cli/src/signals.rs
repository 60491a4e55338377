//! Ctrl-C and SIGTERM during a command that writes files: the temporary outputs and run files
//! registered with `pointlet_core::cleanup` are removed, then the process exits with 128 + the
//! signal number (130, 143), as a shell reports a process the signal ended.

use anyhow::{Context, Result};

/// Starts the thread that waits for SIGINT, SIGTERM or SIGHUP and cleans up.
#[cfg(unix)]
pub fn remove_temporaries_on_signals() -> Result<()> {
    use signal_hook::consts::{SIGHUP, SIGINT, SIGTERM};
    let mut signals = signal_hook::iterator::Signals::new([SIGINT, SIGTERM, SIGHUP])
        .context("installing the signal handlers")?;
    std::thread::Builder::new()
        .name("signals".into())
        .spawn(move || {
            if let Some(signal) = signals.forever().next() {
                eprintln!("\ninterrupted: temporary files removed");
                pointlet_core::cleanup::remove_all_and_exit(128 + signal);
            }
        })
        .context("starting the signal thread")?;
    Ok(())
}

#[cfg(not(unix))]
pub fn remove_temporaries_on_signals() -> Result<()> {
    Ok(())
}
