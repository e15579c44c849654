//! The client's TLS configuration.

use std::sync::Arc;

use lockstep_net::{ALPN, TlsError, transport_config};
use rustls::pki_types::CertificateDer;

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
