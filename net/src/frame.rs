//! Reading and writing length-prefixed protocol messages on a QUIC stream.

use lockstep_proto::{DecodeError, EncodeError, FRAME_HEADER_BYTES, encode_frame, frame_length};
use thiserror::Error;

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
    Read(#[source] quinn::ReadError),
    /// Writing failed.
    #[error("stream write failed: {0}")]
    Write(#[source] quinn::WriteError),
    /// The message could not be framed.
    #[error("cannot frame message: {0}")]
    Encode(#[source] EncodeError),
}

fn map_read(e: quinn::ReadExactError) -> FrameError {
    match e {
        quinn::ReadExactError::FinishedEarly(_) => FrameError::Truncated,
        quinn::ReadExactError::ReadError(e) => FrameError::Read(e),
    }
}

/// Reads one frame's payload (an encoded message). `Ok(None)` when the peer
/// finished the stream cleanly between frames.
///
/// The length is checked with [`frame_length`] before anything is
/// allocated, so an oversized frame costs the reader four bytes.
///
/// # Errors
/// [`FrameError`]; the caller closes the connection.
pub async fn read_frame(recv: &mut quinn::RecvStream) -> Result<Option<Vec<u8>>, FrameError> {
    let mut header = [0u8; FRAME_HEADER_BYTES];
    match recv.read_exact(&mut header).await {
        Ok(()) => {}
        Err(quinn::ReadExactError::FinishedEarly(0)) => return Ok(None),
        Err(e) => return Err(map_read(e)),
    }
    let len = frame_length(header).map_err(FrameError::Length)?;
    let mut payload = vec![0u8; len];
    recv.read_exact(&mut payload).await.map_err(map_read)?;
    Ok(Some(payload))
}

/// Frames an encoded message and writes it.
///
/// # Errors
/// [`FrameError::Encode`] if it is too large, [`FrameError::Write`] if the
/// stream failed.
pub async fn write_frame(send: &mut quinn::SendStream, message: &[u8]) -> Result<(), FrameError> {
    let framed = encode_frame(message).map_err(FrameError::Encode)?;
    send.write_all(&framed).await.map_err(FrameError::Write)
}
