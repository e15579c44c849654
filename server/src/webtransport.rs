//! The WebTransport endpoint (`ServerConfig::webtransport`): HTTP/3 on its
//! own UDP address, for browsers, into the same rooms as native QUIC.
//!
//! It is a quinn endpoint like the native one (the same transport
//! settings, with the streams HTTP/3 needs; ALPN `h3`); `web-transport-quinn`
//! does the HTTP/3 part: the SETTINGS exchange and the CONNECT request that
//! opens a session, on a connection the server accepted itself, so the
//! accept loop's limits apply before any handshake. A session on
//! [`WEBTRANSPORT_PATH`] is then a [`Link`](lockstep_net::Link) like a
//! native connection, served by the same code (`conn`).
//!
//! The certificate: the configured files when there are some (a real
//! certificate: browsers check it against their CA roots), otherwise one
//! generated at start for development, which a browser accepts only
//! through `serverCertificateHashes`: ECDSA P-256, valid 13 days (the
//! option allows at most 14), for `localhost`, `127.0.0.1` and `::1`. Its
//! SHA-256 is logged and reported ([`ServerEvent::WebTransportListening`]).

use std::net::SocketAddr;
use std::time::{Duration, SystemTime};

use lockstep_net::{WEBTRANSPORT_ALPN, WEBTRANSPORT_PATH, webtransport_transport_config};
use rustls::pki_types::{CertificateDer, PrivateKeyDer};
use sha2::{Digest, Sha256};
use web_transport_quinn::http::StatusCode;

use crate::tls::{CertifiedKey, load_files, quic_server_config, tls_err};
use crate::{ServerConfig, ServerError, ServerEvent, TlsSource};

/// How long the development certificate is valid from its start: browsers
/// take a certificate by its hash only for at most 14 days.
pub const DEV_CERT_VALIDITY: Duration = Duration::from_secs(13 * 24 * 3600);

/// How far before now the development certificate's validity starts, for
/// a browser whose clock is a little behind (counted in the 14 days).
const DEV_CERT_BACKDATE: Duration = Duration::from_secs(3600);

/// The bound WebTransport endpoint.
pub(crate) struct Bound {
    pub(crate) endpoint: quinn::Endpoint,
    pub(crate) addr: SocketAddr,
    pub(crate) cert_sha256: [u8; 32],
}

impl Bound {
    /// The event that reports it.
    pub(crate) fn event(&self) -> ServerEvent {
        ServerEvent::WebTransportListening {
            addr: self.addr,
            cert_sha256: self.cert_sha256,
        }
    }
}

/// A self-signed ECDSA P-256 certificate for `localhost`, `127.0.0.1` and
/// `::1`, valid from an hour ago for [`DEV_CERT_VALIDITY`]: what a browser
/// accepts through `serverCertificateHashes`.
///
/// # Errors
/// [`ServerError::Tls`] if it cannot be made.
fn dev_certificate() -> Result<CertifiedKey, ServerError> {
    let names = vec!["localhost".into(), "127.0.0.1".into(), "::1".into()];
    let mut params = rcgen::CertificateParams::new(names).map_err(tls_err)?;
    params.distinguished_name.push(
        rcgen::DnType::CommonName,
        "lockstep development (WebTransport)",
    );
    let now = SystemTime::now();
    params.not_before = time::OffsetDateTime::from(now - DEV_CERT_BACKDATE);
    params.not_after = time::OffsetDateTime::from(now + DEV_CERT_VALIDITY);
    let key = rcgen::KeyPair::generate_for(&rcgen::PKCS_ECDSA_P256_SHA256).map_err(tls_err)?;
    let cert = params.self_signed(&key).map_err(tls_err)?;
    let key = PrivateKeyDer::try_from(key.serialize_der()).map_err(tls_err)?;
    Ok((vec![cert.der().clone()], key))
}

/// The SHA-256 of a certificate's DER: what `serverCertificateHashes`
/// names it by.
pub fn cert_sha256(cert: &CertificateDer<'_>) -> [u8; 32] {
    Sha256::digest(cert.as_ref()).into()
}

/// Lower-case hex, for the log line.
fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

/// Binds the WebTransport endpoint, if configured, and logs its address
/// and certificate hash.
///
/// # Errors
/// [`ServerError::Tls`] for a certificate that cannot be made or loaded,
/// [`ServerError::BindWebTransport`] if the address cannot be bound.
pub(crate) fn bind(config: &ServerConfig) -> Result<Option<Bound>, ServerError> {
    let Some(listen) = config.webtransport else {
        return Ok(None);
    };
    let (certified, generated) = match &config.tls {
        TlsSource::Files { cert, key } => (load_files(cert, key)?, false),
        TlsSource::SelfSigned { .. } => (dev_certificate()?, true),
    };
    let cert_sha256 = cert_sha256(&certified.0[0]);
    let server_config = quic_server_config(
        certified,
        WEBTRANSPORT_ALPN,
        webtransport_transport_config(),
    )?;
    let endpoint = quinn::Endpoint::server(server_config, listen)
        .map_err(|e| ServerError::BindWebTransport(listen, e))?;
    let addr = endpoint
        .local_addr()
        .map_err(|e| ServerError::BindWebTransport(listen, e))?;
    // One line in a fixed form, for scripts that read the hash from it.
    crate::log!(
        "webtransport on {addr} (path {WEBTRANSPORT_PATH}), certificate sha-256 {}",
        hex(&cert_sha256)
    );
    if generated {
        crate::log!(
            "webtransport: that certificate was generated (ECDSA P-256, valid 13 days, for localhost, 127.0.0.1 and ::1); browsers accept it through serverCertificateHashes"
        );
    }
    Ok(Some(Bound {
        endpoint,
        addr,
        cert_sha256,
    }))
}

/// Opens the WebTransport session of an accepted connection: the HTTP/3
/// SETTINGS exchange and the CONNECT request, answered 200 on
/// [`WEBTRANSPORT_PATH`] and 404 on any other path.
///
/// # Errors
/// Why no session was opened, as a sentence for the log (counted as a
/// handshake refusal in the metrics, as a failed QUIC handshake is).
pub(crate) async fn open_session(
    conn: quinn::Connection,
) -> Result<web_transport_quinn::Session, String> {
    let request = web_transport_quinn::Request::accept(conn.clone())
        .await
        .map_err(|e| format!("WebTransport handshake failed: {e}"))?;
    let path = request.url.path().to_owned();
    if path != WEBTRANSPORT_PATH {
        let _ = request.reject(StatusCode::NOT_FOUND).await;
        // Give the client a moment to read the answer and close itself.
        let _ = tokio::time::timeout(Duration::from_secs(1), conn.closed()).await;
        return Err(format!(
            "WebTransport handshake: no session on path {path:?} (404; the path is {WEBTRANSPORT_PATH})"
        ));
    }
    request
        .ok()
        .await
        .map_err(|e| format!("WebTransport handshake: the session's answer failed: {e}"))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The development certificate is what browsers accept by hash:
    /// ECDSA P-256 signed with SHA-256, valid at most 14 days, for the
    /// loopback names.
    #[test]
    fn the_dev_certificate_is_ecdsa_p256_valid_13_days_for_loopback() {
        use x509_parser::extensions::GeneralName;
        let (chain, key) = dev_certificate().unwrap();
        assert_eq!(chain.len(), 1);
        let key = rcgen::KeyPair::try_from(key.secret_der()).expect("a PKCS#8 key");
        assert_eq!(key.algorithm(), &rcgen::PKCS_ECDSA_P256_SHA256);
        let (_, cert) = x509_parser::parse_x509_certificate(&chain[0]).unwrap();
        let spki = &cert.public_key().algorithm;
        assert_eq!(spki.algorithm.to_id_string(), "1.2.840.10045.2.1"); // EC
        let curve = spki.parameters.as_ref().unwrap().as_oid().unwrap();
        assert_eq!(curve.to_id_string(), "1.2.840.10045.3.1.7"); // P-256
        // ecdsa-with-SHA256
        assert_eq!(
            cert.signature_algorithm.algorithm.to_id_string(),
            "1.2.840.10045.4.3.2"
        );
        let validity = cert.validity();
        let seconds = validity.not_after.timestamp() - validity.not_before.timestamp();
        assert!(seconds <= 14 * 24 * 3600, "{seconds} s");
        assert!(seconds >= 13 * 24 * 3600, "{seconds} s");
        let now = SystemTime::now()
            .duration_since(SystemTime::UNIX_EPOCH)
            .unwrap()
            .as_secs() as i64;
        assert!(validity.not_before.timestamp() <= now);
        assert!(validity.not_after.timestamp() >= now + 13 * 24 * 3600 - 60);
        let sans = cert.subject_alternative_name().unwrap().unwrap();
        let names: Vec<String> = sans
            .value
            .general_names
            .iter()
            .map(|n| match n {
                GeneralName::DNSName(d) => (*d).to_owned(),
                GeneralName::IPAddress(ip) => match ip.len() {
                    4 => std::net::Ipv4Addr::from(<[u8; 4]>::try_from(*ip).unwrap()).to_string(),
                    _ => std::net::Ipv6Addr::from(<[u8; 16]>::try_from(*ip).unwrap()).to_string(),
                },
                other => format!("{other:?}"),
            })
            .collect();
        assert_eq!(names, ["localhost", "127.0.0.1", "::1"]);
        // The hash is the DER's SHA-256 (FIPS 180-2's "abc" example).
        let abc = CertificateDer::from(b"abc".to_vec());
        assert_eq!(
            hex(&cert_sha256(&abc)),
            "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad"
        );
    }
}
