//! Reading and writing length-prefixed protocol messages on a stream: a
//! QUIC stream, a WebTransport stream ([`LinkRecv`](crate::LinkRecv),
//! [`LinkSend`](crate::LinkSend)), or anything else that reads and writes
//! bytes in order.

use lockstep_proto::{DecodeError, EncodeError, FRAME_HEADER_BYTES, encode_frame, frame_length};
use thiserror::Error;
use tokio::io::{AsyncRead, AsyncReadExt, AsyncWrite, AsyncWriteExt};

/// Why a frame could not be read or written.
#[derive(Debug, Error)]
pub enum FrameError {
    /// The length prefix is out of bounds (oversized, or shorter than a
    /// version header): the peer is refused before its payload is read.
    #[error("bad frame length: {0}")]
    Length(#[source] DecodeError),
    /// The stream ended inside a frame.
    #[error("stream ended inside a frame")]
    Truncated,
    /// The stream failed (connection lost, reset by the peer).
    #[error("stream read failed: {0}")]
    Read(#[source] std::io::Error),
    /// Writing failed.
    #[error("stream write failed: {0}")]
    Write(#[source] std::io::Error),
    /// The message could not be framed.
    #[error("cannot frame message: {0}")]
    Encode(#[source] EncodeError),
}

/// Fills `buf` from `recv`; returns how many bytes came before the stream
/// ended (`buf.len()` when it did not).
async fn read_full<R: AsyncRead + Unpin + ?Sized>(
    recv: &mut R,
    buf: &mut [u8],
) -> Result<usize, FrameError> {
    let mut filled = 0;
    while filled < buf.len() {
        match recv.read(&mut buf[filled..]).await {
            Ok(0) => break,
            Ok(n) => filled += n,
            Err(e) => return Err(FrameError::Read(e)),
        }
    }
    Ok(filled)
}

/// Reads one frame's payload (an encoded message). `Ok(None)` when the peer
/// finished the stream cleanly between frames.
///
/// The length is checked with [`frame_length`] before anything is
/// allocated, so an oversized frame costs the reader four bytes.
///
/// # Errors
/// [`FrameError`]; the caller closes the connection.
pub async fn read_frame<R: AsyncRead + Unpin + ?Sized>(
    recv: &mut R,
) -> Result<Option<Vec<u8>>, FrameError> {
    let mut header = [0u8; FRAME_HEADER_BYTES];
    match read_full(recv, &mut header).await? {
        0 => return Ok(None),
        FRAME_HEADER_BYTES => {}
        _ => return Err(FrameError::Truncated),
    }
    let len = frame_length(header).map_err(FrameError::Length)?;
    let mut payload = vec![0u8; len];
    if read_full(recv, &mut payload).await? < len {
        return Err(FrameError::Truncated);
    }
    Ok(Some(payload))
}

/// Frames an encoded message and writes it.
///
/// # Errors
/// [`FrameError::Encode`] if it is too large, [`FrameError::Write`] if the
/// stream failed.
pub async fn write_frame<W: AsyncWrite + Unpin + ?Sized>(
    send: &mut W,
    message: &[u8],
) -> Result<(), FrameError> {
    let framed = encode_frame(message).map_err(FrameError::Encode)?;
    send.write_all(&framed).await.map_err(FrameError::Write)
}
