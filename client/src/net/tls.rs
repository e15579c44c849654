//! The client's TLS configuration: trusting a certificate (or a CA) from
//! PEM, or exactly one certificate by its SHA-256 (what a browser's
//! `serverCertificateHashes` does), for native QUIC or WebTransport.

use std::sync::Arc;

use lockstep_net::{
    ALPN, TlsError, WEBTRANSPORT_ALPN, transport_config, webtransport_transport_config,
};
use rustls::client::danger::{HandshakeSignatureValid, ServerCertVerified, ServerCertVerifier};
use rustls::crypto::CryptoProvider;
use rustls::pki_types::{CertificateDer, ServerName, UnixTime};
use sha2::{Digest, Sha256};

use super::TrustedCert;

/// A quinn client configuration that trusts exactly `roots` (the server's
/// dev certificate, or a CA) and speaks only [`ALPN`].
///
/// # Errors
/// [`TlsError`] if rustls or quinn refuse the configuration.
pub fn client_config(roots: &[CertificateDer<'static>]) -> Result<quinn::ClientConfig, TlsError> {
    config_for(Trust::Roots(roots), false)
}

/// The quinn client configuration for `cert`, over native QUIC (ALPN
/// [`ALPN`]) or WebTransport (ALPN `h3`, with the streams HTTP/3 needs).
pub(crate) fn config_for_options(
    cert: &TrustedCert,
    webtransport: bool,
) -> Result<quinn::ClientConfig, TlsError> {
    match cert {
        TrustedCert::Sha256(hash) => config_for(Trust::Sha256(*hash), webtransport),
        _ => config_for(Trust::Roots(&cert.load()?), webtransport),
    }
}

/// What a client trusts.
enum Trust<'a> {
    /// These certificates as roots.
    Roots(&'a [CertificateDer<'static>]),
    /// Exactly the certificate of this SHA-256.
    Sha256([u8; 32]),
}

fn config_for(trust: Trust<'_>, webtransport: bool) -> Result<quinn::ClientConfig, TlsError> {
    let provider = Arc::new(rustls::crypto::ring::default_provider());
    let builder = rustls::ClientConfig::builder_with_provider(provider.clone())
        .with_protocol_versions(&[&rustls::version::TLS13])?;
    let mut tls = match trust {
        Trust::Roots(roots) => {
            let mut store = rustls::RootCertStore::empty();
            for c in roots {
                store.add(c.clone())?;
            }
            builder.with_root_certificates(store).with_no_client_auth()
        }
        Trust::Sha256(sha256) => builder
            .dangerous()
            .with_custom_certificate_verifier(Arc::new(CertHash { sha256, provider }))
            .with_no_client_auth(),
    };
    tls.alpn_protocols = vec![
        if webtransport {
            WEBTRANSPORT_ALPN
        } else {
            ALPN
        }
        .to_vec(),
    ];
    let crypto = quinn::crypto::rustls::QuicClientConfig::try_from(tls)
        .map_err(|e| TlsError::Quic(e.to_string()))?;
    let mut cfg = quinn::ClientConfig::new(Arc::new(crypto));
    let transport = if webtransport {
        webtransport_transport_config()
    } else {
        transport_config()
    };
    cfg.transport_config(Arc::new(transport));
    Ok(cfg)
}

/// Trusts exactly the certificate whose DER has this SHA-256, whatever
/// its names and issuer, as a browser given `serverCertificateHashes`
/// (which also insists on ECDSA and at most 14 days of validity: the
/// server's generated certificate is both). The handshake's signature is
/// still checked against that certificate's key.
#[derive(Debug)]
struct CertHash {
    sha256: [u8; 32],
    provider: Arc<CryptoProvider>,
}

impl ServerCertVerifier for CertHash {
    fn verify_server_cert(
        &self,
        end_entity: &CertificateDer<'_>,
        _intermediates: &[CertificateDer<'_>],
        _server_name: &ServerName<'_>,
        _ocsp_response: &[u8],
        _now: UnixTime,
    ) -> Result<ServerCertVerified, rustls::Error> {
        let got: [u8; 32] = Sha256::digest(end_entity.as_ref()).into();
        if got == self.sha256 {
            Ok(ServerCertVerified::assertion())
        } else {
            Err(rustls::Error::InvalidCertificate(
                rustls::CertificateError::ApplicationVerificationFailure,
            ))
        }
    }

    fn verify_tls12_signature(
        &self,
        message: &[u8],
        cert: &CertificateDer<'_>,
        dss: &rustls::DigitallySignedStruct,
    ) -> Result<HandshakeSignatureValid, rustls::Error> {
        rustls::crypto::verify_tls12_signature(
            message,
            cert,
            dss,
            &self.provider.signature_verification_algorithms,
        )
    }

    fn verify_tls13_signature(
        &self,
        message: &[u8],
        cert: &CertificateDer<'_>,
        dss: &rustls::DigitallySignedStruct,
    ) -> Result<HandshakeSignatureValid, rustls::Error> {
        rustls::crypto::verify_tls13_signature(
            message,
            cert,
            dss,
            &self.provider.signature_verification_algorithms,
        )
    }

    fn supported_verify_schemes(&self) -> Vec<rustls::SignatureScheme> {
        self.provider
            .signature_verification_algorithms
            .supported_schemes()
    }
}
