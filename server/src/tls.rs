//! The server's certificate: a self-signed one generated for development and
//! written to a file clients can trust, or a real certificate and key.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use lockstep_net::{ALPN, load_certs, transport_config};
use rustls::pki_types::PrivateKeyDer;
use rustls::pki_types::pem::PemObject;

use crate::ServerError;

/// Where the server's certificate comes from.
#[derive(Clone, Debug)]
pub enum TlsSource {
    /// Generate a fresh self-signed certificate for `names` at start-up and
    /// write it as PEM to `cert_out`, for clients to trust (`--cert` of
    /// `lockstep-bot`). The key never leaves the process.
    SelfSigned {
        /// Where the certificate is written.
        cert_out: PathBuf,
        /// DNS names (or IP literals) the certificate is valid for.
        names: Vec<String>,
    },
    /// A real certificate chain and its private key, PEM files.
    Files {
        /// Certificate chain.
        cert: PathBuf,
        /// Private key (PKCS#8, PKCS#1 or SEC1).
        key: PathBuf,
    },
}

impl TlsSource {
    /// A self-signed certificate for `localhost` and `127.0.0.1`, written to
    /// `cert_out`.
    pub fn dev(cert_out: impl Into<PathBuf>) -> Self {
        Self::SelfSigned {
            cert_out: cert_out.into(),
            names: vec!["localhost".into(), "127.0.0.1".into()],
        }
    }
}

pub(crate) fn tls_err(what: impl std::fmt::Display) -> ServerError {
    ServerError::Tls(what.to_string())
}

fn write_cert(path: &Path, pem: &str) -> Result<(), ServerError> {
    if let Some(dir) = path.parent()
        && !dir.as_os_str().is_empty()
    {
        std::fs::create_dir_all(dir).map_err(|e| ServerError::Io(dir.to_path_buf(), e))?;
    }
    std::fs::write(path, pem).map_err(|e| ServerError::Io(path.to_path_buf(), e))
}

/// A certificate chain and its private key.
pub(crate) type CertifiedKey = (
    Vec<rustls::pki_types::CertificateDer<'static>>,
    PrivateKeyDer<'static>,
);

/// Reads a certificate chain and its key from PEM files.
pub(crate) fn load_files(cert: &Path, key: &Path) -> Result<CertifiedKey, ServerError> {
    let chain = load_certs(cert).map_err(tls_err)?;
    let key = PrivateKeyDer::from_pem_file(key)
        .map_err(|e| tls_err(format!("{}: {e}", key.display())))?;
    Ok((chain, key))
}

/// The quinn server configuration of a certificate: TLS 1.3 only, `alpn`
/// required, `transport` settings.
pub(crate) fn quic_server_config(
    (chain, key): CertifiedKey,
    alpn: &[u8],
    transport: quinn::TransportConfig,
) -> Result<quinn::ServerConfig, ServerError> {
    let provider = Arc::new(rustls::crypto::ring::default_provider());
    let mut tls = rustls::ServerConfig::builder_with_provider(provider)
        .with_protocol_versions(&[&rustls::version::TLS13])
        .map_err(tls_err)?
        .with_no_client_auth()
        .with_single_cert(chain, key)
        .map_err(tls_err)?;
    tls.alpn_protocols = vec![alpn.to_vec()];
    let crypto = quinn::crypto::rustls::QuicServerConfig::try_from(tls).map_err(tls_err)?;
    let mut config = quinn::ServerConfig::with_crypto(Arc::new(crypto));
    config.transport_config(Arc::new(transport));
    Ok(config)
}

/// Builds the quinn server configuration (TLS 1.3 only, [`ALPN`] required)
/// and returns the path of the certificate clients should trust, if one was
/// generated.
pub(crate) fn server_config(
    source: &TlsSource,
) -> Result<(quinn::ServerConfig, Option<PathBuf>), ServerError> {
    let (certified, written) = match source {
        TlsSource::SelfSigned { cert_out, names } => {
            let ck = rcgen::generate_simple_self_signed(names.clone()).map_err(tls_err)?;
            write_cert(cert_out, &ck.cert.pem())?;
            let key = PrivateKeyDer::try_from(ck.signing_key.serialize_der()).map_err(tls_err)?;
            ((vec![ck.cert.der().clone()], key), Some(cert_out.clone()))
        }
        TlsSource::Files { cert, key } => (load_files(cert, key)?, None),
    };
    let config = quic_server_config(certified, ALPN, transport_config())?;
    Ok((config, written))
}
