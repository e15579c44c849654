//! The QUIC transport settings of both sides.

use std::sync::Arc;
use std::time::Duration;

use crate::congestion::FloorFactory;

/// Transport settings of both sides: a 10 s idle timeout with 1 s
/// keep-alives (the room drops a silent player after 5 s on its own), at
/// most one bidirectional stream and no unidirectional ones (the protocol
/// uses exactly one stream), and datagram buffers for a few hundred
/// datagrams, and NewReno congestion control with a window floor of
/// [`MIN_CONGESTION_WINDOW`](crate::MIN_CONGESTION_WINDOW).
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

/// [`transport_config`] for a WebTransport endpoint or client: HTTP/3
/// needs more streams under the one the protocol uses. A client opens the
/// session's CONNECT request (a bidirectional stream) before the
/// protocol's own stream, and its HTTP/3 control and QPACK streams
/// (unidirectional); the server opens its control stream. So two
/// bidirectional streams and a few unidirectional ones (8: browsers may
/// add reserved "grease" streams); the server reads only the first
/// WebTransport stream, as over QUIC.
pub fn webtransport_transport_config() -> quinn::TransportConfig {
    let mut t = transport_config();
    t.max_concurrent_bidi_streams(2u8.into());
    t.max_concurrent_uni_streams(8u8.into());
    t
}
