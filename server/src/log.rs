//! Logging through `tracing`: the server emits events (level info, unless
//! said otherwise) inside a span per room (`room`) and per connection
//! (`conn`, with the peer's address and, once seated, its slot). The
//! binaries install a subscriber (`RUST_LOG` filters it); a program that
//! installs none hears nothing.

use std::sync::OnceLock;
use std::time::Instant;

static START: OnceLock<Instant> = OnceLock::new();

/// Seconds since the first call, for readable timelines.
pub fn uptime() -> f64 {
    START.get_or_init(Instant::now).elapsed().as_secs_f64()
}

/// Logs one event at info level, formatted like `format!`.
#[macro_export]
macro_rules! log {
    ($($arg:tt)*) => {
        ::tracing::info!("{}", format_args!($($arg)*))
    };
}
