//! TLS and QUIC transport settings shared by the client and the server.

use std::path::Path;
use std::sync::Arc;
use std::time::Duration;

use rustls::pki_types::CertificateDer;
use rustls::pki_types::pem::PemObject;
use thiserror::Error;

use super::ALPN;

/// Why a TLS configuration could not be built.
#[derive(Debug, Error)]
pub enum TlsError {
    /// The certificate file could not be read or holds no PEM certificate.
    #[error("{path}: {detail}")]
    CertFile {
        /// The file.
        path: String,
        /// What went wrong.
        detail: String,
    },
    /// rustls refused the configuration.
    #[error("tls: {0}")]
    Rustls(#[from] rustls::Error),
    /// quinn refused the rustls configuration (no TLS 1.3 suite).
    #[error("quic crypto: {0}")]
    Quic(String),
}

/// Reads every certificate of a PEM file.
///
/// # Errors
/// [`TlsError::CertFile`] if the file cannot be read or holds none.
pub fn load_certs(path: &Path) -> Result<Vec<CertificateDer<'static>>, TlsError> {
    let err = |detail: String| TlsError::CertFile {
        path: path.display().to_string(),
        detail,
    };
    let certs: Vec<_> = CertificateDer::pem_file_iter(path)
        .map_err(|e| err(e.to_string()))?
        .collect::<Result<_, _>>()
        .map_err(|e| err(e.to_string()))?;
    if certs.is_empty() {
        return Err(err("no certificate in the file".into()));
    }
    Ok(certs)
}

/// Transport settings of both sides: a 10 s idle timeout with 1 s
/// keep-alives (the room drops a silent player after 5 s on its own), at
/// most one bidirectional stream and no unidirectional ones (the protocol
/// uses exactly one stream), and datagram buffers for a few hundred
/// datagrams.
pub fn transport_config() -> quinn::TransportConfig {
    let mut t = quinn::TransportConfig::default();
    // 10 s fits in a VarInt; the conversion cannot fail.
    if let Ok(idle) = quinn::IdleTimeout::try_from(Duration::from_secs(10)) {
        t.max_idle_timeout(Some(idle));
    }
    t.keep_alive_interval(Some(Duration::from_secs(1)));
    t.max_concurrent_bidi_streams(1u8.into());
    t.max_concurrent_uni_streams(0u8.into());
    t.datagram_receive_buffer_size(Some(512 * 1024));
    t.datagram_send_buffer_size(512 * 1024);
    t
}

/// A quinn client configuration that trusts exactly `roots` (the server's
/// dev certificate, or a CA) and speaks only [`ALPN`].
///
/// # Errors
/// [`TlsError`] if rustls or quinn refuse the configuration.
pub fn client_config(roots: &[CertificateDer<'static>]) -> Result<quinn::ClientConfig, TlsError> {
    let mut store = rustls::RootCertStore::empty();
    for c in roots {
        store.add(c.clone())?;
    }
    let provider = Arc::new(rustls::crypto::ring::default_provider());
    let mut tls = rustls::ClientConfig::builder_with_provider(provider)
        .with_protocol_versions(&[&rustls::version::TLS13])?
        .with_root_certificates(store)
        .with_no_client_auth();
    tls.alpn_protocols = vec![ALPN.to_vec()];
    let crypto = quinn::crypto::rustls::QuicClientConfig::try_from(tls)
        .map_err(|e| TlsError::Quic(e.to_string()))?;
    let mut cfg = quinn::ClientConfig::new(Arc::new(crypto));
    cfg.transport_config(Arc::new(transport_config()));
    Ok(cfg)
}
