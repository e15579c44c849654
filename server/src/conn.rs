//! One connection: handshake, join, then forwarding the client's stream
//! frames and datagrams to its room, and writing what the room sends.
//!
//! A native QUIC connection and a WebTransport session are served by the
//! same code: after the handshake (and, for WebTransport, the HTTP/3
//! session's CONNECT, `webtransport::open_session`) both are a
//! [`Link`], and everything from the join on is the same.
//!
//! The task validates everything before the room sees it: frame lengths
//! (before reading the payload), decoding, and the channel each message must
//! use. Anything wrong is reported to the room, which removes the player
//! with a logged reason; other players are never affected.

use std::sync::Arc;
use std::time::Duration;

use lockstep_net::{
    FrameError, Link, LinkError, LinkRecv, LinkSend, close_code, read_frame, write_frame,
};
use lockstep_proto::{Channel, ClientMessage, Close, CloseReason, PlayerId};
use tokio::sync::{mpsc, oneshot};

use crate::Shared;
use crate::peer::{Peer, RoomCmd, WriterCmd, close_of, send_close};
use crate::{room, webtransport};

/// Which endpoint a connection came in on.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Via {
    /// The native QUIC endpoint (ALPN `lockstep/1`).
    Quic,
    /// The WebTransport endpoint (HTTP/3).
    WebTransport,
}

impl Via {
    /// For logs.
    pub(crate) fn name(self) -> &'static str {
        match self {
            Via::Quic => "quic",
            Via::WebTransport => "webtransport",
        }
    }
}

/// How long a client has to complete the handshake and send its join.
const JOIN_TIMEOUT: Duration = Duration::from_secs(5);

/// Frames queued for one client's stream before it counts as not reading.
pub(crate) const WRITER_QUEUE: usize = 512;

/// Serves one incoming connection to its end; logs instead of failing.
pub(crate) async fn serve(shared: Arc<Shared>, incoming: quinn::Incoming, via: Via) {
    let remote = incoming.remote_address();
    let mut shutdown = shared.shutdown.clone();
    let deadline = tokio::time::Instant::now() + JOIN_TIMEOUT;
    // The handshake and the join share one deadline; the connection is kept
    // outside the timed part, so a client that never joins is refused with
    // the reason rather than dropped without one.
    let handshake = tokio::select! {
        r = tokio::time::timeout_at(deadline, incoming) => match r {
            Ok(Ok(c)) => Ok(c),
            Ok(Err(e)) => Err(format!("handshake failed: {e}")),
            Err(_) => Err("no handshake within 5 s".to_owned()),
        },
        _ = shutdown.wait_for(|s| *s) => Err("server shutting down".to_owned()),
    };
    let connection = match handshake {
        Ok(c) => c,
        Err(reason) => {
            shared.refused(remote, reason);
            return;
        }
    };
    // A WebTransport session is opened (its CONNECT answered) within the
    // same deadline.
    let link = match via {
        Via::Quic => Ok(Link::Quic(connection.clone())),
        Via::WebTransport => tokio::select! {
            r = tokio::time::timeout_at(deadline, webtransport::open_session(connection.clone())) => {
                match r {
                    Ok(Ok(session)) => Ok(Link::WebTransport(Box::new(session))),
                    Ok(Err(reason)) => Err(reason),
                    Err(_) => Err("no WebTransport handshake within 5 s".to_owned()),
                }
            }
            _ = shutdown.wait_for(|s| *s) => Err("server shutting down".to_owned()),
        },
    };
    let connection = match link {
        Ok(l) => l,
        Err(reason) => {
            connection.close(close_code::REFUSED.into(), truncate(&reason).as_bytes());
            shared.refused(remote, reason);
            return;
        }
    };
    let joined = tokio::select! {
        r = tokio::time::timeout_at(deadline, join(&shared, connection.clone())) => match r {
            Ok(r) => r,
            Err(_) => Err(("no join within 5 s".to_owned(), Some(connection.clone()), None)),
        },
        _ = shutdown.wait_for(|s| *s) => {
            Err(("server shutting down".to_owned(), Some(connection.clone()), None))
        }
    };
    let (connection, recv, id, room_tx, writer) = match joined {
        Ok(v) => v,
        Err((reason, connection, writer)) => {
            shared.refused(remote, reason.clone());
            match writer {
                // The room queued the close message and the close itself.
                Some(w) => {
                    let _ = w.await;
                }
                None => {
                    if let Some(c) = connection {
                        c.close(close_code::REFUSED, truncate(&reason).as_bytes());
                    }
                }
            }
            return;
        }
    };
    tracing::Span::current().record("slot", id.slot.0);
    tracing::debug!(slot = id.slot.0, "seated");
    let rate = shared.config.room.max_messages_per_second;
    read_loop(&connection, recv, id, &room_tx, rate).await;
    let _ = writer.await;
}

type Joined = (
    Link,
    LinkRecv,
    PlayerId,
    mpsc::Sender<RoomCmd>,
    tokio::task::JoinHandle<()>,
);

type Refusal = (String, Option<Link>, Option<tokio::task::JoinHandle<()>>);

/// Completes the handshake of a connection over a limit (and opens its
/// WebTransport session) only to close it with the overloaded code and
/// `reason` (within 2 s, or not at all).
pub(crate) async fn refuse(incoming: quinn::Incoming, reason: &str, via: Via) {
    let Ok(connecting) = incoming.accept() else {
        return;
    };
    let opened = tokio::time::timeout(Duration::from_secs(2), async {
        let c = connecting.await.ok()?;
        Some(match via {
            Via::Quic => Link::Quic(c),
            Via::WebTransport => {
                Link::WebTransport(Box::new(webtransport::open_session(c).await.ok()?))
            }
        })
    })
    .await;
    if let Ok(Some(link)) = opened {
        link.close(close_code::OVERLOADED, truncate(reason).as_bytes());
    }
}

/// The first stream, the join frame, and a seat.
async fn join(shared: &Arc<Shared>, connection: Link) -> Result<Joined, Refusal> {
    let fail = |reason: String| (reason, Some(connection.clone()), None);
    let (send, mut recv) = connection
        .accept_bi()
        .await
        .map_err(|e| fail(format!("no stream opened: {e}")))?;
    let frame = match read_frame(&mut recv).await {
        Ok(Some(f)) => Ok(f),
        Ok(None) => return Err(fail("stream ended before the join".into())),
        Err(e) => Err(format!("before joining: {e}")),
    };
    let join = frame
        .map_err(|detail| (CloseReason::ProtocolViolation, detail))
        .and_then(|f| match ClientMessage::decode(&f) {
            Ok(ClientMessage::Join(j)) => Ok(j),
            Ok(other) => Err((
                CloseReason::ProtocolViolation,
                format!("{} before joining", other.kind()),
            )),
            // A client of another protocol version is told so (the QUIC
            // close code and reason text are readable to it); a header
            // that names no plausible version (garbage) is a violation.
            Err(lockstep_proto::DecodeError::WrongVersion { found, expected }) if found <= 255 => {
                Err((
                    CloseReason::VersionMismatch,
                    format!("client protocol version {found}, server {expected}"),
                ))
            }
            Err(e) => Err((
                CloseReason::ProtocolViolation,
                format!("undecodable join: {e}"),
            )),
        });
    let (writer_tx, writer_rx) = mpsc::channel(WRITER_QUEUE);
    let writer = tokio::spawn(write_loop(connection.clone(), send, writer_rx));
    let join = match join {
        Ok(j) => j,
        Err((reason, detail)) => {
            // A broken first frame is a protocol violation like any other:
            // the client is told why, with its close code.
            let close = close_of(reason, detail);
            send_close(&writer_tx, &close);
            let why = match reason {
                CloseReason::VersionMismatch => format!("join refused: {}", close.detail),
                _ => format!("protocol violation: {}", close.detail),
            };
            return Err((why, Some(connection), Some(writer)));
        }
    };
    let peer = Peer {
        connection: connection.clone(),
        writer: writer_tx.clone(),
        remote: connection.remote_address(),
    };
    let allocated = check_allocation(shared, &join.room);
    let token =
        check_token(shared, &join).map_err(|e| close_of(CloseReason::BadToken, e.to_string()));
    // A join carrying a rejoin credential goes to its room even if its
    // token no longer verifies (expired since the first join): the room
    // knows the credential, or refuses with the token's reason.
    let (ticket, token_refusal) = match (allocated, token) {
        (Err(close), _) => (Err(close), None),
        (Ok(()), Ok(t)) => (Ok(t), None),
        (Ok(()), Err(close)) if join.rejoin.is_some() => (Ok(None), Some(close)),
        (Ok(()), Err(close)) => (Err(close), None),
    };
    let ticket = match ticket {
        Ok(t) => t,
        Err(close) => {
            send_close(&writer_tx, &close);
            let why = format!(
                "join of {:?} to room {:?} refused: {}",
                join.player_name, join.room, close.detail
            );
            return Err((why, Some(connection), Some(writer)));
        }
    };
    let room_tx = match room::find_or_open(shared, &join.room) {
        Ok(tx) => tx,
        Err(close) => {
            send_close(&writer_tx, &close);
            return Err((close.detail, Some(connection), Some(writer)));
        }
    };
    let (reply_tx, reply_rx) = oneshot::channel();
    let request = RoomCmd::Join {
        ticket,
        token_refusal,
        join: join.clone(),
        peer,
        reply: reply_tx,
    };
    if room_tx.send(request).await.is_err() {
        let close = close_of(CloseReason::RoomClosed, "the room closed");
        send_close(&writer_tx, &close);
        return Err((close.detail, Some(connection), Some(writer)));
    }
    match reply_rx.await {
        Ok(Ok(id)) => Ok((connection, recv, id, room_tx, writer)),
        // The room already queued the close on the writer.
        Ok(Err(close)) => Err((
            format!(
                "join of {:?} to room {:?} refused: {}",
                join.player_name, join.room, close.detail
            ),
            Some(connection),
            Some(writer),
        )),
        Err(_) => {
            let close = close_of(CloseReason::RoomClosed, "the room closed");
            send_close(&writer_tx, &close);
            Err((close.detail, Some(connection), Some(writer)))
        }
    }
}

/// A token bucket over a connection's messages: `rate` a second, and as
/// many in a burst. Past it, datagrams are dropped and counted and stream
/// frames wait (the stream's flow control then slows the sender).
struct RateLimit {
    rate: f64,
    tokens: f64,
    last: tokio::time::Instant,
    /// Datagrams dropped since the room was last told.
    dropped: u64,
    told: tokio::time::Instant,
}

impl RateLimit {
    fn new(rate: u32) -> RateLimit {
        let now = tokio::time::Instant::now();
        let rate = f64::from(rate.max(1));
        RateLimit {
            rate,
            tokens: rate,
            last: now,
            dropped: 0,
            told: now,
        }
    }

    fn refill(&mut self) {
        let now = tokio::time::Instant::now();
        let dt = now.duration_since(self.last).as_secs_f64();
        self.last = now;
        self.tokens = (self.tokens + dt * self.rate).min(self.rate);
    }

    /// Takes a token if there is one.
    fn take(&mut self) -> bool {
        self.refill();
        if self.tokens >= 1.0 {
            self.tokens -= 1.0;
            true
        } else {
            false
        }
    }

    /// How long until a token is free.
    fn wait(&mut self) -> Duration {
        self.refill();
        Duration::from_secs_f64(((1.0 - self.tokens) / self.rate).max(0.0))
    }

    /// The drops to report, at most once a second.
    fn report(&mut self) -> Option<u64> {
        let now = tokio::time::Instant::now();
        if self.dropped == 0 || now.duration_since(self.told) < Duration::from_secs(1) {
            return None;
        }
        self.told = now;
        Some(std::mem::take(&mut self.dropped))
    }
}

/// Forwards the client's frames and datagrams to the room until the
/// connection ends or the client misbehaves.
async fn read_loop(
    connection: &Link,
    mut recv: LinkRecv,
    id: PlayerId,
    room_tx: &mpsc::Sender<RoomCmd>,
    rate: u32,
) {
    let mut limit = RateLimit::new(rate);
    // Frames are read by their own task so a frame is never cut in half
    // when a datagram wins the select.
    let (frames_tx, mut frames_rx) = mpsc::channel(64);
    let frames = tokio::spawn(async move {
        loop {
            let r = read_frame(&mut recv).await;
            let end = !matches!(r, Ok(Some(_)));
            if frames_tx.send(r).await.is_err() || end {
                break;
            }
        }
    });
    loop {
        let cmd = tokio::select! {
            frame = frames_rx.recv() => match frame {
                Some(Ok(Some(bytes))) => {
                    if !limit.take() {
                        tokio::time::sleep(limit.wait()).await;
                        limit.take();
                    }
                    checked(id, &bytes, Channel::Reliable)
                }
                Some(Ok(None)) | None => RoomCmd::Gone { id, why: "stream finished".into() },
                Some(Err(FrameError::Length(e))) => RoomCmd::Misbehaved {
                    id,
                    detail: format!("bad frame: {e}"),
                },
                Some(Err(e)) => RoomCmd::Gone { id, why: e.to_string() },
            },
            datagram = connection.read_datagram() => match datagram {
                Ok(_) if !limit.take() => {
                    limit.dropped += 1;
                    match limit.report() {
                        Some(dropped) => RoomCmd::Throttled { id, dropped },
                        None => continue,
                    }
                }
                Ok(bytes) => checked(id, &bytes, Channel::Datagram),
                Err(e @ LinkError::ForeignDatagram) => RoomCmd::Misbehaved {
                    id,
                    detail: format!("bad datagram: {e}"),
                },
                Err(e) => RoomCmd::Gone { id, why: e.to_string() },
            },
        };
        let cmd = match (limit.report(), cmd) {
            // Drops not yet told go to the room before the next message.
            (Some(dropped), cmd @ RoomCmd::Message { .. }) => {
                if room_tx
                    .send(RoomCmd::Throttled { id, dropped })
                    .await
                    .is_err()
                {
                    break;
                }
                cmd
            }
            (_, cmd) => cmd,
        };
        let last = !matches!(cmd, RoomCmd::Message { .. } | RoomCmd::Throttled { .. });
        if room_tx.send(cmd).await.is_err() || last {
            break;
        }
    }
    frames.abort();
}

/// Decodes a client message and checks its channel.
fn checked(id: PlayerId, bytes: &[u8], channel: Channel) -> RoomCmd {
    let what = match channel {
        Channel::Reliable => "frame",
        Channel::Datagram => "datagram",
    };
    match ClientMessage::decode(bytes) {
        Ok(msg) if msg.channel() == channel => RoomCmd::Message {
            id,
            msg,
            len: bytes.len(),
            channel,
        },
        Ok(msg) => RoomCmd::Misbehaved {
            id,
            detail: format!("{} sent as a {what}", msg.kind()),
        },
        Err(e) => RoomCmd::Misbehaved {
            id,
            detail: format!("bad {what} of {} bytes: {e}", bytes.len()),
        },
    }
}

/// How long a WebTransport peer gets to read the close message and close
/// the session itself before the server closes it (the page closes 0.5 s
/// after reading it).
const PAGE_CLOSE_GRACE: Duration = Duration::from_secs(2);

/// Writes the room's frames in order; on a close command, finishes the
/// stream, gives the client a moment to read it, and closes the connection.
async fn write_loop(connection: Link, mut send: LinkSend, mut rx: mpsc::Receiver<WriterCmd>) {
    while let Some(cmd) = rx.recv().await {
        match cmd {
            WriterCmd::Frame(bytes) => {
                if write_frame(&mut send, &bytes).await.is_err() {
                    break;
                }
            }
            WriterCmd::Close { code, reason } => {
                let _ = send.finish();
                // Resolves once the client has every byte of the stream (or
                // stopped it): the close message is then delivered.
                let _ = tokio::time::timeout(Duration::from_millis(500), send.stopped()).await;
                if connection.is_webtransport() {
                    // Acknowledged is not read: a browser drops a stream's
                    // unread bytes when the session closes, so the page
                    // may lose the close message to our close. The page
                    // closes the session itself once it has read it; wait
                    // for that, a bounded time.
                    tokio::time::timeout(PAGE_CLOSE_GRACE, connection.closed())
                        .await
                        .ok();
                }
                connection.close(code, truncate(&reason).as_bytes());
                return;
            }
        }
    }
    connection.close(close_code::NORMAL, b"");
}

/// Close reasons go into one QUIC packet; keep them short (a WebTransport
/// session's, at most 1024 bytes, gets the same text).
fn truncate(s: &str) -> &str {
    let mut end = s.len().min(200);
    while !s.is_char_boundary(end) {
        end -= 1;
    }
    &s[..end]
}

/// In Agones mode, joins wait for the allocation and name its room.
fn check_allocation(shared: &Shared, room: &str) -> Result<(), Close> {
    use crate::agones::AllocationState;
    let state = shared.allocation.read().unwrap_or_else(|e| e.into_inner());
    match &*state {
        AllocationState::Off => Ok(()),
        AllocationState::Waiting => Err(close_of(
            CloseReason::WrongRoom,
            "this game server is not allocated yet",
        )),
        AllocationState::Allocated(a) => match &a.room {
            Some(r) if r != room => Err(close_of(
                CloseReason::WrongRoom,
                format!("this game server hosts room {r:?} only"),
            )),
            _ => Ok(()),
        },
        AllocationState::Unusable(why) => Err(close_of(CloseReason::WrongRoom, why.clone())),
    }
}

/// The join's token, verified when the server has a secret: `None` when it
/// carries none (allowed unless tokens are required) or the server has no
/// secret (development: tokens are not checked). An Agones allocation's
/// secret replaces the configured one and makes tokens required.
fn check_token(
    shared: &Shared,
    join: &lockstep_proto::Join,
) -> Result<Option<lockstep_proto::token::Ticket>, lockstep_proto::token::TokenError> {
    use lockstep_proto::token::{TokenError, verify};
    let allocated = match &*shared.allocation.read().unwrap_or_else(|e| e.into_inner()) {
        crate::agones::AllocationState::Allocated(a) => a.token_secret.clone(),
        _ => None,
    };
    let required = shared.config.require_tokens || allocated.is_some();
    let Some(secret) = allocated.as_ref().or(shared.config.token_secret.as_ref()) else {
        return Ok(None);
    };
    match &join.token {
        None if required => Err(TokenError::Missing),
        None => Ok(None),
        Some(t) => {
            let now = std::time::SystemTime::now()
                .duration_since(std::time::UNIX_EPOCH)
                .map_or(0, |d| d.as_secs());
            verify(secret, t, &join.room, now).map(Some)
        }
    }
}
