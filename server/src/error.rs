//! Why the server could not run.

use std::net::SocketAddr;
use std::path::PathBuf;

use thiserror::Error;

use crate::agones;

/// Why the server could not run.
#[derive(Debug, Error)]
pub enum ServerError {
    /// The scene does not build.
    #[error("scene {name}: {detail}")]
    Scene {
        /// Its name.
        name: String,
        /// What is wrong.
        detail: String,
    },
    /// The room settings are incoherent.
    #[error("room settings: {0}")]
    Config(String),
    /// The certificate could not be made or loaded.
    #[error("tls: {0}")]
    Tls(String),
    /// A file or directory could not be written.
    #[error("{0}: {1}")]
    Io(PathBuf, #[source] std::io::Error),
    /// The Agones SDK could not be reached or refused a call.
    #[error("agones: {0}")]
    Agones(#[from] agones::AgonesError),
    /// The UDP socket could not be bound.
    #[error("bind {0}: {1}")]
    Bind(SocketAddr, #[source] std::io::Error),
    /// The WebTransport endpoint's UDP socket could not be bound.
    #[error("bind the WebTransport endpoint on {0}: {1}")]
    BindWebTransport(SocketAddr, #[source] std::io::Error),
    /// The clock's or the rooms' threads could not be started.
    #[error("start the tick clock's threads: {0}")]
    Thread(#[source] std::io::Error),
}
