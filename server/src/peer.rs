//! What a connection task and its room share: the room's handle on the
//! connection, the commands each sends the other, and closes. Neither
//! imports the other for these.

use std::net::SocketAddr;

use lockstep_net::close_code_for;
use lockstep_proto::{Channel, ClientMessage, Close, CloseReason, Join, PlayerId, ServerMessage};
use tokio::sync::{mpsc, oneshot};

/// What the room asks a connection's writer to do.
#[derive(Debug)]
pub(crate) enum WriterCmd {
    /// Write one encoded message as a frame.
    Frame(Vec<u8>),
    /// Finish the stream once written, then close the connection.
    Close {
        /// Application close code (QUIC's, or the WebTransport session's).
        code: u32,
        /// Reason text.
        reason: String,
    },
}

/// The room's handle on a connection (native QUIC or WebTransport).
#[derive(Debug, Clone)]
pub(crate) struct Peer {
    pub(crate) connection: lockstep_net::Link,
    pub(crate) writer: mpsc::Sender<WriterCmd>,
    pub(crate) remote: SocketAddr,
}

/// Commands from connection tasks to their room.
#[derive(Debug)]
pub(crate) enum RoomCmd {
    /// Seat a player; the room answers and sends the welcome or the refusal.
    Join {
        join: Join,
        /// The join's verified token, if any.
        ticket: Option<lockstep_proto::token::Ticket>,
        /// The refusal of the join's token, held back because the join
        /// carries a rejoin credential: sent unless the room knows it.
        token_refusal: Option<Close>,
        peer: Peer,
        reply: oneshot::Sender<Result<PlayerId, Close>>,
    },
    /// A decoded message on the right channel.
    Message {
        id: PlayerId,
        msg: ClientMessage,
        len: usize,
        channel: Channel,
    },
    /// The client broke the protocol below the room's level.
    Misbehaved { id: PlayerId, detail: String },
    /// The connection ended.
    Gone { id: PlayerId, why: String },
    /// Datagrams dropped over the connection's rate limit since the last
    /// such report (at most one a second).
    Throttled { id: PlayerId, dropped: u64 },
}

/// Queues a close message and the connection close on a writer.
pub(crate) fn send_close(writer: &mpsc::Sender<WriterCmd>, close: &Close) {
    if let Ok(bytes) = ServerMessage::Close(close.clone()).encode() {
        let _ = writer.try_send(WriterCmd::Frame(bytes));
    }
    let _ = writer.try_send(close_cmd(close));
}

/// The writer command that closes a client after `close` was queued.
pub(crate) fn close_cmd(close: &Close) -> WriterCmd {
    WriterCmd::Close {
        code: close_code_for(close.reason),
        reason: format!("{:?}: {}", close.reason, close.detail),
    }
}

/// A close for a reason the room does not produce itself.
pub(crate) fn close_of(reason: CloseReason, detail: impl Into<String>) -> Close {
    let mut detail: String = detail.into();
    let max = lockstep_proto::MAX_DETAIL_BYTES;
    if detail.len() > max {
        let mut cut = max;
        while !detail.is_char_boundary(cut) {
            cut -= 1;
        }
        detail.truncate(cut);
    }
    Close { reason, detail }
}
