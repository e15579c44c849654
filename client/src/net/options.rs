//! How a client connects: the certificate it trusts, its options, and
//! where it keeps its rejoin credential.

use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use lockstep_proto::RejoinCredential;

use lockstep_net::{TlsError, load_certs, parse_certs};

/// The certificate (or CA) a client trusts: a PEM file, or PEM text held in
/// memory (a game that ships its server's certificate inside the binary),
/// or exactly one certificate named by its SHA-256.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum TrustedCert {
    /// A PEM file: the dev certificate the server wrote, or a real one.
    File(PathBuf),
    /// PEM text.
    Pem(Vec<u8>),
    /// Exactly the certificate whose DER has this SHA-256, whatever its
    /// names and issuer: what a browser's `serverCertificateHashes` does,
    /// for the WebTransport endpoint's generated certificate
    /// (`ServerEvent::WebTransportListening`'s `cert_sha256`, or the hash
    /// in the server's log).
    Sha256([u8; 32]),
}

impl TrustedCert {
    /// The certificates to trust.
    ///
    /// # Errors
    /// [`TlsError::CertFile`] if the file cannot be read or no PEM
    /// certificate is in it, or for [`TrustedCert::Sha256`] (a hash names a
    /// certificate it does not hold).
    pub fn load(&self) -> Result<Vec<rustls::pki_types::CertificateDer<'static>>, TlsError> {
        match self {
            TrustedCert::File(path) => load_certs(path),
            TrustedCert::Pem(bytes) => parse_certs(bytes, "PEM bytes"),
            TrustedCert::Sha256(_) => Err(TlsError::CertFile {
                path: "a SHA-256".into(),
                detail: "a certificate hash holds no certificate".into(),
            }),
        }
    }
}

impl From<PathBuf> for TrustedCert {
    fn from(p: PathBuf) -> Self {
        TrustedCert::File(p)
    }
}

impl From<&PathBuf> for TrustedCert {
    fn from(p: &PathBuf) -> Self {
        TrustedCert::File(p.clone())
    }
}

impl From<&Path> for TrustedCert {
    fn from(p: &Path) -> Self {
        TrustedCert::File(p.to_path_buf())
    }
}

/// How to reach the server and what to do there.
#[derive(Clone, Debug)]
pub struct ClientOptions {
    /// The server's UDP address (with [`webtransport`](Self::webtransport),
    /// its WebTransport endpoint's).
    pub server: SocketAddr,
    /// Join over WebTransport (HTTP/3, a session on `/lockstep`, what a
    /// browser speaks) instead of native QUIC: the same messages, rooms and
    /// tokens. Default false.
    pub webtransport: bool,
    /// The name the server's certificate is checked against (`localhost`
    /// for the dev certificate).
    pub server_name: String,
    /// The certificate (or CA) to trust, as a file or as PEM bytes.
    pub cert: TrustedCert,
    /// Room to join.
    pub room: String,
    /// Display name.
    pub player_name: String,
    /// Leave after applying this many ticks (`None`: play until the server
    /// closes the match or the application leaves).
    pub max_ticks: Option<u64>,
    /// Also send every body's hash with the report of every K-th tick
    /// (0: never, the default). 8 bytes per body per report (about
    /// 55 kB/s upstream for 100 bodies at 60 Hz with K = 1, twenty times the
    /// rest of the traffic). The server writes the agreed body hashes into
    /// the replay, so a replay check can name the bodies that diverge.
    pub body_hashes_every: u64,
    /// How long connecting and joining may take.
    pub connect_timeout: Duration,
    /// Ticks of past states kept to answer the room's probes when a desync
    /// is located (one snapshot per tick: about 27 kB and 30 µs for the
    /// demo's 66 bodies; memory grows with the scene). 0: keep none, and
    /// answer every probe as unavailable. Default 64 (about 1 s at 60 Hz,
    /// longer than a report's round trip).
    pub forensics_ticks: usize,
    /// The join token to present (`lockstep-server token`, or a
    /// matchmaker's), for servers that require one. It seats a player once
    /// per match; to come back, the client presents the rejoin credential
    /// its welcome gave ([`ClientOptions::rejoin`]).
    pub token: Option<String>,
    /// Where this client keeps the rejoin credential of its seat: the
    /// welcome's credential is stored here, and the next connect with
    /// these options (or a clone of them: clones share the store)
    /// presents it, taking the seat back (a token alone is refused once
    /// used). Empty at first.
    pub rejoin: RejoinStore,
    /// Predict (see [`super::predict`]): run a second world ahead of the
    /// confirmed ticks, to the tick of the last input this client chose,
    /// with the other players' inputs guessed; draw
    /// [`LiveClient::predicted_world`](super::LiveClient::predicted_world). Default off.
    pub predict: bool,
    /// How many ticks the predicted world may run ahead of the last
    /// confirmed one. Default 8.
    pub max_prediction: u64,
    /// Test hook (feature `test-hooks`): every snapshot this client gives
    /// a player joining the running match has its bytes inverted, so it
    /// does not restore. Default off.
    #[cfg(feature = "test-hooks")]
    pub corrupt_snapshots: bool,
    /// Test hook (feature `test-hooks`): the client simulates every tick
    /// right but reports a wrong hash for every even tick (a liar that
    /// raises a new divergence every other tick). Default off.
    #[cfg(feature = "test-hooks")]
    pub lie_on_even_ticks: bool,
}

impl ClientOptions {
    /// Options for the server at `server` trusting `cert`, joining `room`
    /// as `player_name`, with the defaults of each field.
    pub fn new(
        server: SocketAddr,
        cert: impl Into<TrustedCert>,
        room: impl Into<String>,
        player_name: impl Into<String>,
    ) -> Self {
        Self {
            server,
            webtransport: false,
            server_name: "localhost".into(),
            cert: cert.into(),
            room: room.into(),
            player_name: player_name.into(),
            max_ticks: None,
            body_hashes_every: 0,
            connect_timeout: Duration::from_secs(10),
            forensics_ticks: 64,
            token: None,
            rejoin: RejoinStore::default(),
            predict: false,
            max_prediction: 8,
            #[cfg(feature = "test-hooks")]
            corrupt_snapshots: false,
            #[cfg(feature = "test-hooks")]
            lie_on_even_ticks: false,
        }
    }
}

/// The rejoin credential a client keeps for its seat
/// ([`ClientOptions::rejoin`]); clones share it.
#[derive(Clone, Debug, Default)]
pub struct RejoinStore(Arc<Mutex<Option<RejoinCredential>>>);

impl RejoinStore {
    /// The credential held, if any.
    pub fn get(&self) -> Option<RejoinCredential> {
        *self.0.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// Holds `credential` (or forgets the one held).
    pub fn set(&self, credential: Option<RejoinCredential>) {
        *self.0.lock().unwrap_or_else(|e| e.into_inner()) = credential;
    }
}
