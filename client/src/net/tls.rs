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

/// Reads every certificate of PEM text held in memory (`what` names it in
/// errors).
///
/// # Errors
/// [`TlsError::CertFile`] if the text holds no PEM certificate.
pub fn parse_certs(pem: &[u8], what: &str) -> Result<Vec<CertificateDer<'static>>, TlsError> {
    let err = |detail: String| TlsError::CertFile {
        path: what.to_owned(),
        detail,
    };
    let certs: Vec<_> = CertificateDer::pem_slice_iter(pem)
        .collect::<Result<_, _>>()
        .map_err(|e| err(e.to_string()))?;
    if certs.is_empty() {
        return Err(err("no certificate in the PEM text".into()));
    }
    Ok(certs)
}

/// Congestion window below which the controller never throttles: 32 KiB.
///
/// Lockstep traffic is paced by the tick clock, not by the network: a
/// player's datagrams in flight stay under ~8 KiB even with full redundancy
/// at a 100 ms round trip. Loss on a game link is mostly not congestion, yet
/// NewReno halves its window on every loss event down to two packets
/// (2.4 KB), which is *less* than one round trip of bundles at 60 Hz; quinn
/// then holds datagrams back and ticks arrive late. The floor keeps the
/// per-tick traffic flowing while bulk transfers (a large welcome scene)
/// remain congestion-controlled above it.
pub const MIN_CONGESTION_WINDOW: u64 = 32 * 1024;

/// NewReno with its window never below [`MIN_CONGESTION_WINDOW`].
#[derive(Debug, Default)]
struct FloorFactory(quinn::congestion::NewRenoConfig);

impl quinn::congestion::ControllerFactory for FloorFactory {
    fn build(
        self: Arc<Self>,
        now: std::time::Instant,
        current_mtu: u16,
    ) -> Box<dyn quinn::congestion::Controller> {
        let inner = Arc::new(self.0.clone()).build(now, current_mtu);
        Box::new(Floor(inner))
    }
}

struct Floor(Box<dyn quinn::congestion::Controller>);

impl quinn::congestion::Controller for Floor {
    fn on_sent(&mut self, now: std::time::Instant, bytes: u64, last_packet_number: u64) {
        self.0.on_sent(now, bytes, last_packet_number);
    }

    fn on_ack(
        &mut self,
        now: std::time::Instant,
        sent: std::time::Instant,
        bytes: u64,
        app_limited: bool,
        rtt: &quinn_proto::RttEstimator,
    ) {
        self.0.on_ack(now, sent, bytes, app_limited, rtt);
    }

    fn on_end_acks(
        &mut self,
        now: std::time::Instant,
        in_flight: u64,
        app_limited: bool,
        largest_packet_num_acked: Option<u64>,
    ) {
        self.0
            .on_end_acks(now, in_flight, app_limited, largest_packet_num_acked);
    }

    fn on_congestion_event(
        &mut self,
        now: std::time::Instant,
        sent: std::time::Instant,
        is_persistent_congestion: bool,
        lost_bytes: u64,
    ) {
        self.0
            .on_congestion_event(now, sent, is_persistent_congestion, lost_bytes);
    }

    fn on_mtu_update(&mut self, new_mtu: u16) {
        self.0.on_mtu_update(new_mtu);
    }

    fn window(&self) -> u64 {
        self.0.window().max(MIN_CONGESTION_WINDOW)
    }

    fn clone_box(&self) -> Box<dyn quinn::congestion::Controller> {
        Box::new(Floor(self.0.clone_box()))
    }

    fn initial_window(&self) -> u64 {
        self.0.initial_window().max(MIN_CONGESTION_WINDOW)
    }

    fn into_any(self: Box<Self>) -> Box<dyn std::any::Any> {
        self
    }
}

/// Transport settings of both sides: a 10 s idle timeout with 1 s
/// keep-alives (the room drops a silent player after 5 s on its own), at
/// most one bidirectional stream and no unidirectional ones (the protocol
/// uses exactly one stream), and datagram buffers for a few hundred
/// datagrams, and NewReno congestion control with a window floor of
/// [`MIN_CONGESTION_WINDOW`].
pub fn transport_config() -> quinn::TransportConfig {
    let mut t = quinn::TransportConfig::default();
    t.congestion_controller_factory(Arc::new(FloorFactory::default()));
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
