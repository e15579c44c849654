//! The browser client beside the demo (`--demo --webtransport ADDR`): the
//! game's browser module, built with cargo (or read from a file), and the
//! page that plays it, served over HTTP on `--web-listen`
//! (docs/browser.md).

use std::net::{SocketAddr, TcpListener};
use std::path::PathBuf;

use lockstep_web::site::{JoinLink, ModuleBuild};

/// Where the browser module comes from.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum ModuleSource {
    /// Built with cargo when the demo starts (nothing to do when it is up
    /// to date): the demo's `lockstep-web-demo`, or a game's own.
    Build(ModuleBuild),
    /// A module built beforehand (`--web-module FILE`).
    File(PathBuf),
}

impl ModuleSource {
    /// The module's bytes, building it first if need be.
    ///
    /// # Errors
    /// The build failed or the file cannot be read.
    pub fn load(&self) -> Result<Vec<u8>, String> {
        let path = match self {
            ModuleSource::Build(b) => b.build()?,
            ModuleSource::File(p) => p.clone(),
        };
        std::fs::read(&path).map_err(|e| format!("{}: {e}", path.display()))
    }
}

/// The browser client's part of the demo.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct WebDemo {
    /// Where the page is served (port 0: any free one).
    pub listen: SocketAddr,
    /// The module.
    pub module: ModuleSource,
    /// Players in browsers the match waits for before it starts.
    pub players: u8,
}

/// Serves the page and `module` on `listen`, on a thread of its own;
/// returns the address bound.
///
/// # Errors
/// The address cannot be bound.
pub fn start_site(listen: SocketAddr, module: Vec<u8>) -> Result<SocketAddr, String> {
    let listener = TcpListener::bind(listen).map_err(|e| format!("--web-listen {listen}: {e}"))?;
    let addr = listener
        .local_addr()
        .map_err(|e| format!("--web-listen {listen}: {e}"))?;
    std::thread::Builder::new()
        .name("web-client".into())
        .spawn(move || {
            if let Err(e) = lockstep_web::site::serve(listener, module) {
                tracing::warn!("the browser client's site stopped: {e}");
            }
        })
        .map_err(|e| format!("cannot start the site's thread: {e}"))?;
    Ok(addr)
}

/// The page's URL for a player called `name` in `room`, joining the
/// WebTransport endpoint at `webtransport` whose certificate hashes to
/// `cert_sha256`.
pub fn page_url(
    site: SocketAddr,
    webtransport: SocketAddr,
    cert_sha256: &str,
    room: &str,
    name: &str,
) -> String {
    JoinLink {
        webtransport,
        path: lockstep_server::WEBTRANSPORT_PATH.into(),
        cert_sha256: Some(cert_sha256.to_owned()),
        room: room.to_owned(),
        name: name.to_owned(),
        token: None,
        bot: None,
    }
    .url(site)
}
