//! A minimal logger: one line per event on stderr, prefixed with the seconds
//! since the process started, so a match's log reads as a timeline.

use std::sync::OnceLock;
use std::time::Instant;

static START: OnceLock<Instant> = OnceLock::new();

/// Seconds since the first log line (or the first call), for prefixes.
pub fn uptime() -> f64 {
    START.get_or_init(Instant::now).elapsed().as_secs_f64()
}

/// Logs one line to stderr: `[  12.345] message`.
#[macro_export]
macro_rules! log {
    ($($arg:tt)*) => {
        eprintln!("[{:9.3}] {}", $crate::log::uptime(), format_args!($($arg)*))
    };
}
