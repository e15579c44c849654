//! A player's connection, over native QUIC or over WebTransport: one type
//! for the code that serves (or drives) a peer, whichever way it came.
//!
//! Both carry the protocol the same way: the client opens one
//! bidirectional stream and writes framed messages on it
//! ([`read_frame`](crate::read_frame), [`write_frame`](crate::write_frame)),
//! and the unreliable messages go as datagrams, one message each. What
//! differs is below the protocol: WebTransport runs over HTTP/3 (ALPN `h3`,
//! a CONNECT request opens the session), its datagrams carry the session's
//! id in front (1 byte; [`Link::send_datagram`] and
//! [`Link::read_datagram`] add and strip it), and its close is a
//! `CLOSE_WEBTRANSPORT_SESSION` capsule with a `u32` code and a UTF-8 reason
//! (at most 1024 bytes), which a browser reads from `WebTransport.closed`.

use std::io;
use std::net::SocketAddr;
use std::pin::Pin;
use std::task::{Context, Poll};
use std::time::Duration;

use bytes::Bytes;
use thiserror::Error;
use tokio::io::{AsyncRead, AsyncWrite, ReadBuf};

/// The URL path of the server's WebTransport sessions: a CONNECT to any
/// other path is refused with HTTP status 404.
pub const WEBTRANSPORT_PATH: &str = "/lockstep";

/// The ALPN of WebTransport (HTTP/3).
pub const WEBTRANSPORT_ALPN: &[u8] = b"h3";

/// Why an operation on a [`Link`] failed.
#[derive(Debug, Error)]
pub enum LinkError {
    /// The QUIC connection is lost or closed.
    #[error("{0}")]
    Quic(#[from] quinn::ConnectionError),
    /// A datagram could not be sent (too large, not supported, lost
    /// connection).
    #[error("{0}")]
    SendDatagram(#[from] quinn::SendDatagramError),
    /// The WebTransport session is lost or closed, or a datagram could not
    /// be sent on it.
    #[error("{0}")]
    WebTransport(web_transport_quinn::SessionError),
    /// A datagram named another WebTransport session than this one's: the
    /// peer broke the WebTransport framing (the session goes on).
    #[error("a datagram for another WebTransport session")]
    ForeignDatagram,
    /// The stream was already finished or reset.
    #[error("the stream is closed")]
    StreamClosed,
}

impl From<web_transport_quinn::SessionError> for LinkError {
    fn from(e: web_transport_quinn::SessionError) -> Self {
        match e {
            web_transport_quinn::SessionError::WebTransportError(
                web_transport_quinn::WebTransportError::UnknownSession,
            ) => LinkError::ForeignDatagram,
            e => LinkError::WebTransport(e),
        }
    }
}

/// A peer's connection: a native QUIC connection (ALPN
/// [`ALPN`](crate::ALPN)) or a WebTransport session. Cloning it is cheap
/// and shares the connection.
#[derive(Clone, Debug)]
pub enum Link {
    /// Native QUIC.
    Quic(quinn::Connection),
    /// A WebTransport session (HTTP/3), owning its QUIC connection (boxed:
    /// a session is some 800 bytes, a connection a pointer).
    WebTransport(Box<web_transport_quinn::Session>),
}

impl Link {
    /// `"QUIC"` or `"WebTransport"`, for messages.
    pub fn kind(&self) -> &'static str {
        match self {
            Link::Quic(_) => "QUIC",
            Link::WebTransport(_) => "WebTransport",
        }
    }

    /// The QUIC connection underneath (a WebTransport session's own).
    pub fn quic(&self) -> &quinn::Connection {
        match self {
            Link::Quic(c) => c,
            Link::WebTransport(s) => s,
        }
    }

    /// Waits for the peer to open a bidirectional stream.
    ///
    /// # Errors
    /// [`LinkError`] if the connection ends first.
    pub async fn accept_bi(&self) -> Result<(LinkSend, LinkRecv), LinkError> {
        Ok(match self {
            Link::Quic(c) => {
                let (s, r) = c.accept_bi().await?;
                (LinkSend::Quic(s), LinkRecv::Quic(r))
            }
            Link::WebTransport(w) => {
                let (s, r) = w.accept_bi().await?;
                (LinkSend::WebTransport(s), LinkRecv::WebTransport(r))
            }
        })
    }

    /// Opens a bidirectional stream.
    ///
    /// # Errors
    /// [`LinkError`] if the connection ended.
    pub async fn open_bi(&self) -> Result<(LinkSend, LinkRecv), LinkError> {
        Ok(match self {
            Link::Quic(c) => {
                let (s, r) = c.open_bi().await?;
                (LinkSend::Quic(s), LinkRecv::Quic(r))
            }
            Link::WebTransport(w) => {
                let (s, r) = w.open_bi().await?;
                (LinkSend::WebTransport(s), LinkRecv::WebTransport(r))
            }
        })
    }

    /// Sends one datagram (one message), without waiting.
    ///
    /// # Errors
    /// [`LinkError`] if it is larger than [`max_datagram_size`](Self::max_datagram_size)
    /// or the connection ended.
    pub fn send_datagram(&self, data: Bytes) -> Result<(), LinkError> {
        match self {
            Link::Quic(c) => Ok(c.send_datagram(data)?),
            Link::WebTransport(w) => Ok(w.send_datagram(data)?),
        }
    }

    /// The next datagram from the peer (its message, without WebTransport's
    /// session id).
    ///
    /// # Errors
    /// [`LinkError::ForeignDatagram`] for a WebTransport datagram of
    /// another session; otherwise the connection ended.
    pub async fn read_datagram(&self) -> Result<Bytes, LinkError> {
        match self {
            Link::Quic(c) => Ok(c.read_datagram().await?),
            Link::WebTransport(w) => Ok(w.read_datagram().await?),
        }
    }

    /// The largest message a datagram can carry now (`None`: the peer
    /// takes no datagrams).
    pub fn max_datagram_size(&self) -> Option<usize> {
        match self {
            Link::Quic(c) => c.max_datagram_size(),
            Link::WebTransport(w) => Some(w.max_datagram_size()).filter(|&n| n > 0),
        }
    }

    /// Closes the connection with an application `code` and `reason`. A
    /// WebTransport session sends them in its close capsule first (the
    /// browser's `WebTransport.closed` resolves with them), then closes its
    /// QUIC connection.
    pub fn close(&self, code: u32, reason: &[u8]) {
        match self {
            Link::Quic(c) => c.close(code.into(), reason),
            Link::WebTransport(w) => w.close(code, reason),
        }
    }

    /// Resolves once the connection has closed, from either side.
    pub async fn closed(&self) {
        let _ = self.quic().closed().await;
    }

    /// Whether this is a WebTransport session.
    pub fn is_webtransport(&self) -> bool {
        matches!(self, Link::WebTransport(_))
    }

    /// Why the connection ended, if it did.
    pub fn close_reason(&self) -> Option<String> {
        match self {
            Link::Quic(c) => c.close_reason().map(|e| e.to_string()),
            Link::WebTransport(w) => w.close_reason().map(|e| e.to_string()),
        }
    }

    /// The peer's address.
    pub fn remote_address(&self) -> SocketAddr {
        self.quic().remote_address()
    }

    /// The smoothed round trip.
    pub fn rtt(&self) -> Duration {
        self.quic().rtt()
    }

    /// The QUIC connection's counters (UDP bytes each way, ...).
    pub fn stats(&self) -> quinn::ConnectionStats {
        self.quic().stats()
    }
}

/// The sending half of a [`Link`]'s stream.
#[derive(Debug)]
pub enum LinkSend {
    /// A QUIC stream.
    Quic(quinn::SendStream),
    /// A WebTransport stream.
    WebTransport(web_transport_quinn::SendStream),
}

impl LinkSend {
    /// Ends the stream once what was written is delivered.
    ///
    /// # Errors
    /// [`LinkError::StreamClosed`] if it was already finished or reset.
    pub fn finish(&mut self) -> Result<(), LinkError> {
        match self {
            LinkSend::Quic(s) => s.finish().map_err(|_| LinkError::StreamClosed),
            LinkSend::WebTransport(s) => s.finish().map_err(|_| LinkError::StreamClosed),
        }
    }

    /// Resolves once the peer has every byte of the finished stream, or
    /// stopped it, or the connection is lost.
    pub async fn stopped(&self) {
        match self {
            LinkSend::Quic(s) => {
                let _ = s.stopped().await;
            }
            LinkSend::WebTransport(s) => {
                let _ = s.stopped().await;
            }
        }
    }
}

impl AsyncWrite for LinkSend {
    fn poll_write(
        self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        buf: &[u8],
    ) -> Poll<io::Result<usize>> {
        match self.get_mut() {
            LinkSend::Quic(s) => AsyncWrite::poll_write(Pin::new(s), cx, buf),
            LinkSend::WebTransport(s) => AsyncWrite::poll_write(Pin::new(s), cx, buf),
        }
    }

    fn poll_flush(self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<io::Result<()>> {
        match self.get_mut() {
            LinkSend::Quic(s) => AsyncWrite::poll_flush(Pin::new(s), cx),
            LinkSend::WebTransport(s) => AsyncWrite::poll_flush(Pin::new(s), cx),
        }
    }

    fn poll_shutdown(self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<io::Result<()>> {
        match self.get_mut() {
            LinkSend::Quic(s) => AsyncWrite::poll_shutdown(Pin::new(s), cx),
            LinkSend::WebTransport(s) => AsyncWrite::poll_shutdown(Pin::new(s), cx),
        }
    }
}

/// The receiving half of a [`Link`]'s stream.
#[derive(Debug)]
pub enum LinkRecv {
    /// A QUIC stream.
    Quic(quinn::RecvStream),
    /// A WebTransport stream.
    WebTransport(web_transport_quinn::RecvStream),
}

impl AsyncRead for LinkRecv {
    fn poll_read(
        self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        buf: &mut ReadBuf<'_>,
    ) -> Poll<io::Result<()>> {
        match self.get_mut() {
            LinkRecv::Quic(s) => AsyncRead::poll_read(Pin::new(s), cx, buf),
            LinkRecv::WebTransport(s) => AsyncRead::poll_read(Pin::new(s), cx, buf),
        }
    }
}
