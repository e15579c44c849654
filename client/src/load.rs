//! Relays: light players for load tests. A relay plays the protocol (joins,
//! sends an input every tick, acknowledges bundles, answers pings, reports
//! a hash every tick) without simulating: its "state" is a hash chain over
//! the bundles it applied, which every honest relay of a room shares. One
//! process drives hundreds of them; the server cannot tell them from real
//! players, so its lateness and bandwidth under load are what they would be.

use std::net::SocketAddr;
use std::time::{Duration, Instant};

use bytes::Bytes;
use lockstep_proto::{
    Channel, ClientMessage, Close, ServerMessage, Session, SessionEvent, TickBundle,
};
use tokio::sync::mpsc;

use crate::net::{ClientError, TrustedCert, client_config, read_frame, write_frame};

/// What one relay saw.
#[derive(Clone, Debug, Default)]
pub struct RelayReport {
    /// Ticks applied.
    pub ticks: u64,
    /// The chain hash after the last tick.
    pub last_hash: u64,
    /// Desync notices received.
    pub desyncs: u64,
    /// Bundles in which its own input was substituted.
    pub substituted: u64,
    /// The server's close, if it closed the relay.
    pub close: Option<Close>,
    /// Protocol bytes received (datagrams and frames).
    pub bytes_down: u64,
    /// Protocol bytes sent.
    pub bytes_up: u64,
    /// From the welcome to the end.
    pub played_for: Duration,
    /// UDP bytes received (QUIC included) from the first bundle to the
    /// end: the steady state, without the handshake, the welcome and the
    /// lobby.
    pub udp_down_playing: u64,
    /// UDP bytes sent over the same time.
    pub udp_up_playing: u64,
    /// From the first bundle to the end.
    pub playing_for: Duration,
}

/// The relays' state: a hash chain over every applied bundle's bytes.
pub fn chain(state: u64, bundle: &TickBundle) -> u64 {
    let mut h = state ^ bundle.tick.wrapping_mul(0x9E37_79B9_7F4A_7C15);
    for p in &bundle.inputs {
        for &b in [p.slot.0, u8::from(p.substituted)].iter().chain(&p.input) {
            h = (h ^ u64::from(b)).wrapping_mul(0x100_0000_01B3);
        }
    }
    h ^ (h >> 31)
}

/// A QUIC endpoint for relays: one UDP socket shared by many connections.
///
/// # Errors
/// The certificate cannot be loaded or the socket opened.
pub fn relay_endpoint(cert: &TrustedCert) -> Result<quinn::Endpoint, ClientError> {
    let config = client_config(&cert.load()?)?;
    let mut endpoint = quinn::Endpoint::client(SocketAddr::from(([0, 0, 0, 0], 0)))
        .map_err(ClientError::Socket)?;
    endpoint.set_default_client_config(config);
    Ok(endpoint)
}

/// Plays one relay in `room` until the server closes it.
///
/// # Errors
/// [`ClientError`] if connecting or joining fails, or the connection breaks
/// before a close.
pub async fn run_relay(
    endpoint: &quinn::Endpoint,
    server: SocketAddr,
    room: &str,
    name: &str,
) -> Result<RelayReport, ClientError> {
    let connection = endpoint
        .connect(server, "localhost")
        .map_err(|e| ClientError::Connect(e.to_string()))?
        .await
        .map_err(|e| ClientError::Connect(e.to_string()))?;
    let (mut send, mut recv) = connection
        .open_bi()
        .await
        .map_err(|e| ClientError::ConnectionLost(e.to_string()))?;
    let join = Session::join_message(room, name)
        .encode()
        .map_err(|e| ClientError::Connect(e.to_string()))?;
    let mut report = RelayReport {
        bytes_up: join.len() as u64,
        ..RelayReport::default()
    };
    write_frame(&mut send, &join).await?;
    let Some(frame) = read_frame(&mut recv).await? else {
        return Err(ClientError::ConnectionLost("no welcome".into()));
    };
    report.bytes_down += frame.len() as u64;
    let welcome = match ServerMessage::decode(&frame)? {
        ServerMessage::Welcome(w) => w,
        ServerMessage::Close(c) => {
            return Err(ClientError::Refused {
                reason: c.reason,
                detail: c.detail,
            });
        }
        other => return Err(ClientError::Unexpected(other.kind())),
    };
    let mut session = Session::new(&welcome)?;
    let slot = session.slot();
    // Frames are read by their own task: a read cut by `select!` would
    // lose half a frame.
    let (frames_tx, mut frames) = mpsc::unbounded_channel::<Vec<u8>>();
    let reader = tokio::spawn(async move {
        while let Ok(Some(f)) = read_frame(&mut recv).await {
            if frames_tx.send(f).is_err() {
                break;
            }
        }
    });
    let base = Instant::now();
    let mut state = 0u64;
    let mut stream_open = true;
    let mut playing_from: Option<(Instant, quinn::ConnectionStats)> = None;
    let result = loop {
        let now = base.elapsed();
        if session.poll_timeout().is_some_and(|t| t <= now) {
            session.handle_timeout(now);
        }
        while session.wants_input(now) {
            if session.submit_input(vec![0, 0, 0]).is_err() {
                break;
            }
        }
        while let Some(b) = session.poll_bundle() {
            if playing_from.is_none() {
                playing_from = Some((Instant::now(), connection.stats()));
            }
            report.substituted +=
                u64::from(b.inputs.iter().any(|p| p.slot == slot && p.substituted));
            state = chain(state, &b);
            report.ticks += 1;
            if b.tick >= session.start_tick() && session.report_hash(b.tick, state, None).is_err() {
                break;
            }
        }
        report.last_hash = state;
        while let Some(e) = session.poll_event() {
            match e {
                SessionEvent::Desync { .. } => report.desyncs += 1,
                SessionEvent::Closed(c) => report.close = Some(c),
                SessionEvent::Probe(p) => {
                    // A relay keeps no states to answer from.
                    let _ = session.reply_probe(lockstep_proto::ProbeReply {
                        tick: p.tick,
                        answer: lockstep_proto::ProbeAnswer::Unavailable,
                    });
                }
                SessionEvent::DesyncLocated(_) => {}
            }
        }
        while let Some(m) = session.poll_transmit() {
            let Ok(bytes) = m.encode() else { continue };
            report.bytes_up += bytes.len() as u64;
            match m.channel() {
                Channel::Datagram => {
                    let _ = connection.send_datagram(Bytes::from(bytes));
                }
                Channel::Reliable => {
                    if write_frame(&mut send, &bytes).await.is_err() {
                        stream_open = false;
                    }
                }
            }
            if matches!(m, ClientMessage::Leave) {
                let _ = send.finish();
            }
        }
        if session.is_closed() || !stream_open {
            break Ok(());
        }
        let wake = session
            .poll_timeout()
            .unwrap_or(now + Duration::from_millis(100));
        let wake = tokio::time::Instant::from_std(base + wake);
        tokio::select! {
            d = connection.read_datagram() => match d {
                Ok(d) => {
                    report.bytes_down += d.len() as u64;
                    if let Ok(m) = ServerMessage::decode(&d) {
                        let _ = session.handle_message(base.elapsed(), m);
                    }
                }
                Err(e) => break Err(ClientError::ConnectionLost(e.to_string())),
            },
            f = frames.recv() => match f {
                Some(f) => {
                    report.bytes_down += f.len() as u64;
                    if let Ok(m) = ServerMessage::decode(&f) {
                        let _ = session.handle_message(base.elapsed(), m);
                    }
                }
                None => {
                    // The stream ended: take what the session still holds.
                    while let Some(e) = session.poll_event() {
                        if let SessionEvent::Closed(c) = e {
                            report.close = Some(c);
                        }
                    }
                    break Ok(());
                }
            },
            () = tokio::time::sleep_until(wake) => {}
        }
    };
    reader.abort();
    report.played_for = base.elapsed();
    if let Some((at, from)) = playing_from {
        let to = connection.stats();
        report.udp_down_playing = to.udp_rx.bytes - from.udp_rx.bytes;
        report.udp_up_playing = to.udp_tx.bytes - from.udp_tx.bytes;
        report.playing_for = at.elapsed();
    }
    connection.close(0u32.into(), b"relay done");
    match result {
        Err(_) if report.close.is_some() => Ok(report),
        r => r.map(|()| report),
    }
}
