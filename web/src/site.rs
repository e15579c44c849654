//! Serving the browser client: the page and its script (embedded), the
//! viewer's renderer, and a game's browser module built by cargo. Used
//! natively, by `lockstep-server --demo --webtransport` and the browser
//! test; the page's routes run on the viewer's HTTP server
//! (`lockstep_view::http`).

use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::Arc;

use lockstep_view::http::{Query, Response, Routes};

/// The page.
pub const INDEX_HTML: &str = include_str!("../page/index.html");
/// The page's script: the worker, keys, drawing, status.
pub const CLIENT_JS: &str = include_str!("../page/client.js");
/// The worker's script: the module, WebTransport, the loop.
pub const WORKER_JS: &str = include_str!("../page/worker.js");
/// The browser target.
pub const WASM_TARGET: &str = "wasm32-unknown-unknown";

/// The routes of the browser client's site: `/` (the page), `/client.js`,
/// `/worker.js`, `/client.wasm` (the game's module); the viewer's server
/// adds `/render.js`.
pub struct ClientRoutes {
    wasm: Arc<[u8]>,
}

impl ClientRoutes {
    /// The routes serving `wasm` as the module.
    pub fn new(wasm: Vec<u8>) -> ClientRoutes {
        ClientRoutes { wasm: wasm.into() }
    }
}

impl Routes for ClientRoutes {
    fn get(&self, path: &str, _query: Query<'_>) -> Option<Response> {
        const JS: &str = "text/javascript; charset=utf-8";
        let (content_type, body): (&'static str, Arc<[u8]>) = match path {
            "/" | "/index.html" => ("text/html; charset=utf-8", INDEX_HTML.as_bytes().into()),
            "/client.js" => (JS, CLIENT_JS.as_bytes().into()),
            "/worker.js" => (JS, WORKER_JS.as_bytes().into()),
            "/client.wasm" => ("application/wasm", self.wasm.clone()),
            _ => return None,
        };
        Some(Response {
            status: 200,
            content_type,
            body,
        })
    }
}

/// Serves the browser client's site on `listener` until accepting fails
/// (a thread per connection; call it on a thread of its own).
///
/// # Errors
/// Only if accepting fails for good.
pub fn serve(listener: std::net::TcpListener, wasm: Vec<u8>) -> std::io::Result<()> {
    lockstep_view::http::serve(listener, Arc::new(ClientRoutes::new(wasm)))
}

/// A query value, percent-encoded (everything but `A-Z a-z 0-9 - _ . ~`).
pub fn encode_component(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for b in s.bytes() {
        if b.is_ascii_alphanumeric() || b"-_.~".contains(&b) {
            out.push(char::from(b));
        } else {
            out.push_str(&format!("%{b:02X}"));
        }
    }
    out
}

/// Where a page joins: what the page's query string carries.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct JoinLink {
    /// The server's WebTransport address.
    pub webtransport: SocketAddr,
    /// The session path (`/lockstep`).
    pub path: String,
    /// The SHA-256 of the server's development certificate, hex, which
    /// the page trusts by it (`serverCertificateHashes`); `None` for a
    /// certificate the browser trusts on its own (a CA's).
    pub cert_sha256: Option<String>,
    /// The room.
    pub room: String,
    /// The player's name.
    pub name: String,
    /// A join token, when the server wants one.
    pub token: Option<String>,
    /// `Some(seed)`: the game's bot plays until a key is pressed.
    pub bot: Option<u64>,
}

impl JoinLink {
    /// The page's URL on the site at `http`.
    pub fn url(&self, http: SocketAddr) -> String {
        let mut url = format!(
            "http://{http}/?server={}&room={}&name={}",
            encode_component(&format!("https://{}{}", self.webtransport, self.path)),
            encode_component(&self.room),
            encode_component(&self.name),
        );
        if let Some(hash) = &self.cert_sha256 {
            url.push_str(&format!("&cert={}", encode_component(hash)));
        }
        if let Some(t) = &self.token {
            url.push_str(&format!("&token={}", encode_component(t)));
        }
        if let Some(seed) = self.bot {
            url.push_str(&format!("&bot={seed}"));
        }
        url
    }
}

/// How to build a game's browser module with cargo: its `cdylib` package
/// for [`WASM_TARGET`], optimised, in a target directory of its own (so
/// that the build never waits for the cargo that runs the program).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ModuleBuild {
    /// The package's (or its workspace's) `Cargo.toml`.
    pub manifest: PathBuf,
    /// The package.
    pub package: String,
    /// The target directory.
    pub target_dir: PathBuf,
}

impl ModuleBuild {
    /// The demo's module (`web/demo`, package `lockstep-web-demo`), built
    /// into `web/` under this workspace's target directory
    /// (`CARGO_TARGET_DIR` if set).
    pub fn demo() -> ModuleBuild {
        let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
        let target =
            std::env::var_os("CARGO_TARGET_DIR").map_or_else(|| root.join("target"), PathBuf::from);
        ModuleBuild {
            manifest: root.join("web/demo/Cargo.toml"),
            package: "lockstep-web-demo".into(),
            target_dir: target.join("web"),
        }
    }

    /// The module file the build writes.
    pub fn output(&self) -> PathBuf {
        self.target_dir
            .join(WASM_TARGET)
            .join("release")
            .join(format!("{}.wasm", self.package.replace('-', "_")))
    }

    /// Builds the module (cargo does nothing when it is up to date) and
    /// returns its file. Adds the rustup target first if rustup is there
    /// and the target is missing. Cargo's progress goes to stderr.
    ///
    /// Release profile without debug information (a smaller module for
    /// the page to load).
    ///
    /// # Errors
    /// What failed: rustup, cargo, or the build.
    pub fn build(&self) -> Result<PathBuf, String> {
        ensure_target()?;
        let cargo = std::env::var_os("CARGO").unwrap_or_else(|| "cargo".into());
        let status = Command::new(&cargo)
            .args(["build", "--release", "--target", WASM_TARGET, "-p"])
            .arg(&self.package)
            .arg("--manifest-path")
            .arg(&self.manifest)
            .arg("--target-dir")
            .arg(&self.target_dir)
            .args(["--config", "profile.release.debug=false"])
            .status()
            .map_err(|e| format!("cannot run {}: {e}", Path::new(&cargo).display()))?;
        if !status.success() {
            return Err(format!(
                "building {} for {WASM_TARGET} failed ({status})",
                self.package
            ));
        }
        let out = self.output();
        if out.exists() {
            Ok(out)
        } else {
            Err(format!("the build wrote no {}", out.display()))
        }
    }
}

/// Adds the rustup target [`WASM_TARGET`] when rustup is installed and the
/// target is not (a toolchain without rustup must have it already).
fn ensure_target() -> Result<(), String> {
    let Ok(out) = Command::new("rustup")
        .args(["target", "list", "--installed"])
        .output()
    else {
        return Ok(());
    };
    let installed = String::from_utf8_lossy(&out.stdout);
    if !out.status.success() || installed.lines().any(|l| l.trim() == WASM_TARGET) {
        return Ok(());
    }
    eprintln!("adding the rustup target {WASM_TARGET} (once)");
    let status = Command::new("rustup")
        .args(["target", "add", WASM_TARGET])
        .status()
        .map_err(|e| format!("rustup: {e}"))?;
    if status.success() {
        Ok(())
    } else {
        Err(format!("rustup target add {WASM_TARGET} failed ({status})"))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_link_carries_everything_the_page_needs_encoded() {
        let link = JoinLink {
            webtransport: "127.0.0.1:4434".parse().unwrap(),
            path: "/lockstep".into(),
            cert_sha256: Some("ab01".into()),
            room: "my room".into(),
            name: "browser".into(),
            token: Some("0a0b".into()),
            bot: Some(3),
        };
        assert_eq!(
            link.url("127.0.0.1:8047".parse().unwrap()),
            "http://127.0.0.1:8047/?server=https%3A%2F%2F127.0.0.1%3A4434%2Flockstep\
             &room=my%20room&name=browser&cert=ab01&token=0a0b&bot=3"
        );
    }

    #[test]
    fn the_site_serves_the_page_the_script_and_the_module() {
        let routes = ClientRoutes::new(b"\0asm".to_vec());
        let get = |p| routes.get(p, Query(""));
        assert_eq!(&*get("/").unwrap().body, INDEX_HTML.as_bytes());
        assert_eq!(&*get("/client.js").unwrap().body, CLIENT_JS.as_bytes());
        assert_eq!(&*get("/worker.js").unwrap().body, WORKER_JS.as_bytes());
        let wasm = get("/client.wasm").unwrap();
        assert_eq!(wasm.content_type, "application/wasm");
        assert_eq!(&*wasm.body, b"\0asm");
        // The renderer is the viewer's server's own route.
        assert!(get("/render.js").is_none());
        assert!(INDEX_HTML.contains("/render.js") && INDEX_HTML.contains("/client.js"));
    }

    /// Over HTTP, on the viewer's server: every file of the page, with the
    /// headers that isolate it (the worker and the module load under them).
    #[test]
    fn the_site_answers_over_http_cross_origin_isolated() {
        use std::io::{Read, Write};
        let listener = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
        let addr = listener.local_addr().unwrap();
        std::thread::spawn(move || serve(listener, b"\0asm".to_vec()));
        for (path, body) in [
            ("/", INDEX_HTML.as_bytes()),
            ("/client.js", CLIENT_JS.as_bytes()),
            ("/worker.js", WORKER_JS.as_bytes()),
            ("/render.js", lockstep_view::http::RENDER_JS.as_bytes()),
            ("/client.wasm", b"\0asm"),
        ] {
            let mut s = std::net::TcpStream::connect(addr).unwrap();
            write!(s, "GET {path} HTTP/1.1\r\nHost: x\r\n\r\n").unwrap();
            let mut raw = Vec::new();
            s.read_to_end(&mut raw).unwrap();
            let split = raw.windows(4).position(|w| w == b"\r\n\r\n").unwrap();
            let head = String::from_utf8_lossy(&raw[..split]);
            assert!(head.starts_with("HTTP/1.1 200"), "{path}: {head}");
            assert!(
                head.contains("Cross-Origin-Embedder-Policy: require-corp"),
                "{head}"
            );
            assert!(
                head.contains("Cross-Origin-Opener-Policy: same-origin"),
                "{head}"
            );
            assert_eq!(&raw[split + 4..], body, "{path}");
        }
    }

    #[test]
    fn the_demo_module_is_built_from_this_workspace() {
        let b = ModuleBuild::demo();
        assert!(b.manifest.exists(), "{}", b.manifest.display());
        assert!(
            b.output()
                .ends_with("wasm32-unknown-unknown/release/lockstep_web_demo.wasm")
        );
    }
}
