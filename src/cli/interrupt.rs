//! SIGINT, SIGTERM and SIGHUP during a render: the first one asks the render to stop after the
//! pass in flight (the image so far and its checkpoint are written, and the command exits with
//! 128 + the signal's number, as a shell reports a process the signal killed); a second one ends
//! the process at once, for a user who will not wait for the pass.

use std::sync::atomic::{AtomicBool, AtomicUsize};

use signal_hook::consts::{SIGHUP, SIGINT, SIGTERM};

/// The number of the signal that asked the render to stop (0: none yet).
static STOP: AtomicUsize = AtomicUsize::new(0);
/// Set by the first signal: the next one exits at once.
static ARMED: AtomicBool = AtomicBool::new(false);

/// The signals a render stops for.
pub const SIGNALS: [i32; 3] = [SIGINT, SIGTERM, SIGHUP];

/// Installs the handlers (once per process; later calls add nothing) and returns the flag
/// the render loop reads between passes.
pub fn install() -> std::io::Result<&'static AtomicUsize> {
    static INSTALLED: std::sync::OnceLock<std::io::Result<()>> = std::sync::OnceLock::new();
    let installed = INSTALLED.get_or_init(|| {
        for sig in SIGNALS {
            // the exit must be registered first: it runs before the handler that arms it
            signal_hook::flag::register_conditional_shutdown(sig, 128 + sig, &ARMED)?;
            signal_hook::flag::register(sig, &ARMED)?;
            signal_hook::flag::register_usize(sig, &STOP, sig as usize)?;
        }
        Ok(())
    });
    match installed {
        Ok(()) => Ok(&STOP),
        Err(e) => Err(std::io::Error::new(e.kind(), e.to_string())),
    }
}

/// The conventional name of a signal the render stops for.
pub fn name(sig: i32) -> &'static str {
    match sig {
        SIGINT => "SIGINT",
        SIGTERM => "SIGTERM",
        SIGHUP => "SIGHUP",
        _ => "a signal",
    }
}
