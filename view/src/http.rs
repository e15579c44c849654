//! The viewer's HTTP server: read-only GET routes on a socket, with the page
//! and its script embedded in the binary (no JavaScript toolchain is needed
//! to build or run it).
//!
//! The page (`/`), its script (`/viewer.js`) and the renderer it shares
//! with the browser client (`/render.js`) are served here unless the
//! [`Routes`] answer the path themselves; every other route is answered by
//! the [`Routes`]: [`FileRoutes`] for a file loaded up front, the server's
//! live rooms for `lockstep-server --view`, the browser client's page and
//! module for `--demo --webtransport` (crate `lockstep-web`). The routes
//! and formats are documented in docs/viewer.md. Nothing a browser sends
//! can change anything: only GET and HEAD are answered.
//!
//! Every answer is sent cross-origin isolated (`Cross-Origin-Opener-Policy:
//! same-origin`, `Cross-Origin-Embedder-Policy: require-corp`): the pages
//! load only from their own origin, and an isolated page's
//! `performance.now()` has its fine resolution (the browser client times
//! each step with it).

use std::io::{self, Read, Write};
use std::net::{TcpListener, TcpStream};
use std::sync::Arc;
use std::time::Duration;

use super::{ViewData, encode_frames, state_json, world_json};

/// The page.
pub const INDEX_HTML: &str = include_str!("page/index.html");
/// The page's script.
pub const VIEWER_JS: &str = include_str!("page/viewer.js");
/// The WebGL2 renderer the viewer and the browser client share.
pub const RENDER_JS: &str = include_str!("page/render.js");

/// The largest request head read (a browser's GET is well under it).
pub const MAX_REQUEST: usize = 16 * 1024;

/// An answer to a data route.
#[derive(Clone, Debug)]
pub struct Response {
    /// HTTP status (200, 404, ...).
    pub status: u16,
    /// Content type.
    pub content_type: &'static str,
    /// The body.
    pub body: Arc<[u8]>,
}

impl Response {
    /// 200 with a JSON body.
    pub fn json(body: impl Into<Arc<[u8]>>) -> Response {
        Response {
            status: 200,
            content_type: "application/json",
            body: body.into(),
        }
    }

    /// 200 with a binary body.
    pub fn binary(body: impl Into<Arc<[u8]>>) -> Response {
        Response {
            status: 200,
            content_type: "application/octet-stream",
            body: body.into(),
        }
    }

    /// An error status with a plain-text reason.
    pub fn error(status: u16, reason: &str) -> Response {
        Response {
            status,
            content_type: "text/plain; charset=utf-8",
            body: reason.as_bytes().into(),
        }
    }
}

/// A request's query string.
#[derive(Clone, Copy, Debug)]
pub struct Query<'a>(pub &'a str);

impl Query<'_> {
    /// The percent-decoded value of `key`, if present.
    pub fn get(&self, key: &str) -> Option<String> {
        self.0
            .split('&')
            .filter_map(|kv| kv.split_once('='))
            .find(|(k, _)| *k == key)
            .map(|(_, v)| percent_decode(v))
    }

    /// `key` as a number, if present and valid.
    pub fn number(&self, key: &str) -> Option<u64> {
        self.get(key)?.parse().ok()
    }
}

fn percent_decode(s: &str) -> String {
    let b = s.as_bytes();
    let mut out = Vec::with_capacity(b.len());
    let mut i = 0;
    while i < b.len() {
        let hex = |c: u8| (c as char).to_digit(16);
        match b[i] {
            b'%' if i + 2 < b.len() => match (hex(b[i + 1]), hex(b[i + 2])) {
                (Some(h), Some(l)) => {
                    out.push((h * 16 + l) as u8);
                    i += 3;
                    continue;
                }
                _ => out.push(b'%'),
            },
            b'+' => out.push(b' '),
            c => out.push(c),
        }
        i += 1;
    }
    String::from_utf8_lossy(&out).into_owned()
}

/// What answers the data routes.
pub trait Routes: Send + Sync + 'static {
    /// The answer to a GET of `path`, or None: then the viewer's own
    /// files (`/`, `/viewer.js`, `/render.js`) or "not found".
    fn get(&self, path: &str, query: Query<'_>) -> Option<Response>;
}

/// The routes of a file loaded up front (`lockstep view FILE`):
/// `/world`, `/frames` and `/state?frame=F&body=B`.
pub struct FileRoutes {
    data: ViewData,
    world: Arc<[u8]>,
    frames: Arc<[u8]>,
}

impl FileRoutes {
    /// Encodes `data` once for serving.
    pub fn new(data: ViewData) -> FileRoutes {
        FileRoutes {
            world: world_json(&data).into_bytes().into(),
            frames: encode_frames(&data).into(),
            data,
        }
    }
}

impl Routes for FileRoutes {
    fn get(&self, path: &str, query: Query<'_>) -> Option<Response> {
        match path {
            "/world" => Some(Response::json(self.world.clone())),
            "/frames" => Some(Response::binary(self.frames.clone())),
            "/state" => {
                let frame = usize::try_from(query.number("frame")?).ok()?;
                let body = usize::try_from(query.number("body")?).ok()?;
                state_json(&self.data, frame, body).map(|j| Response::json(j.into_bytes()))
            }
            _ => None,
        }
    }
}

/// Serves `routes` on `listener` until accepting fails for good, one
/// thread per connection (a viewer is a handful of connections).
///
/// # Errors
/// Only if accepting fails for good; a broken connection is dropped.
pub fn serve(listener: TcpListener, routes: Arc<dyn Routes>) -> io::Result<()> {
    for stream in listener.incoming() {
        let stream = match stream {
            Ok(s) => s,
            Err(e) if e.kind() == io::ErrorKind::ConnectionAborted => continue,
            Err(e) => return Err(e),
        };
        let routes = Arc::clone(&routes);
        std::thread::spawn(move || {
            let _ = handle(stream, &*routes);
        });
    }
    Ok(())
}

/// Serves a file's view ([`FileRoutes`]).
///
/// # Errors
/// See [`serve`].
pub fn serve_data(listener: TcpListener, data: ViewData) -> io::Result<()> {
    serve(listener, Arc::new(FileRoutes::new(data)))
}

fn handle(mut stream: TcpStream, routes: &dyn Routes) -> io::Result<()> {
    stream.set_read_timeout(Some(Duration::from_secs(10)))?;
    let mut buf = Vec::with_capacity(1024);
    let mut chunk = [0u8; 1024];
    while !buf.windows(4).any(|w| w == b"\r\n\r\n") {
        if buf.len() > MAX_REQUEST {
            return respond(
                &mut stream,
                &Response::error(431, "request too large"),
                false,
            );
        }
        let n = stream.read(&mut chunk)?;
        if n == 0 {
            return Ok(());
        }
        buf.extend_from_slice(&chunk[..n]);
    }
    let head = String::from_utf8_lossy(&buf);
    let mut parts = head.lines().next().unwrap_or("").split_whitespace();
    let (method, target) = (parts.next().unwrap_or(""), parts.next().unwrap_or(""));
    if method != "GET" && method != "HEAD" {
        return respond(
            &mut stream,
            &Response::error(405, "the viewer only reads"),
            false,
        );
    }
    let (path, query) = target.split_once('?').unwrap_or((target, ""));
    let response = routes
        .get(path, Query(query))
        .or_else(|| builtin(path))
        .unwrap_or_else(|| Response::error(404, "not found"));
    respond(&mut stream, &response, method == "HEAD")
}

/// The viewer's own files.
fn builtin(path: &str) -> Option<Response> {
    let (content_type, body) = match path {
        "/" | "/index.html" => ("text/html; charset=utf-8", INDEX_HTML),
        "/viewer.js" => ("text/javascript; charset=utf-8", VIEWER_JS),
        "/render.js" => ("text/javascript; charset=utf-8", RENDER_JS),
        _ => return None,
    };
    Some(Response {
        status: 200,
        content_type,
        body: body.as_bytes().into(),
    })
}

fn respond(stream: &mut TcpStream, r: &Response, head_only: bool) -> io::Result<()> {
    let reason = match r.status {
        200 => "OK",
        400 => "Bad Request",
        404 => "Not Found",
        405 => "Method Not Allowed",
        431 => "Request Header Fields Too Large",
        503 => "Service Unavailable",
        _ => "Error",
    };
    let head = format!(
        "HTTP/1.1 {} {reason}\r\nContent-Type: {}\r\nContent-Length: {}\r\n\
         Cache-Control: no-store\r\nCross-Origin-Opener-Policy: same-origin\r\n\
         Cross-Origin-Embedder-Policy: require-corp\r\nConnection: close\r\n\r\n",
        r.status,
        r.content_type,
        r.body.len()
    );
    stream.write_all(head.as_bytes())?;
    if !head_only {
        stream.write_all(&r.body)?;
    }
    stream.flush()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn get(addr: std::net::SocketAddr, request: &str) -> (String, Vec<u8>) {
        let mut s = TcpStream::connect(addr).unwrap();
        s.write_all(request.as_bytes()).unwrap();
        let mut raw = Vec::new();
        s.read_to_end(&mut raw).unwrap();
        let split = raw.windows(4).position(|w| w == b"\r\n\r\n").unwrap();
        (
            String::from_utf8_lossy(&raw[..split]).into_owned(),
            raw[split + 4..].to_vec(),
        )
    }

    fn spin(ticks: u64) -> ViewData {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes/spin.toml");
        let text = std::fs::read_to_string(&path).unwrap();
        let mut world = lockstep_core::scene::load_world(&text, "spin.toml").unwrap();
        let mut rec = crate::Recorder::new(crate::ViewKind::Scene, "spin".into(), &world);
        rec.record(&world, 0);
        for _ in 0..ticks {
            let r = world.step();
            rec.record(&world, r.tick);
        }
        rec.finish()
    }

    #[test]
    fn every_route_answers_and_nothing_writes() {
        let data = spin(5);
        let frames = encode_frames(&data);
        let listener = TcpListener::bind("127.0.0.1:0").unwrap();
        let addr = listener.local_addr().unwrap();
        std::thread::spawn(move || serve_data(listener, data));
        let req = |line: &str| get(addr, &format!("{line} HTTP/1.1\r\nHost: x\r\n\r\n"));

        let (head, body) = req("GET /");
        assert!(head.starts_with("HTTP/1.1 200"), "{head}");
        assert_eq!(body, INDEX_HTML.as_bytes());
        let (_, body) = req("GET /viewer.js");
        assert_eq!(body, VIEWER_JS.as_bytes());
        let (head, body) = req("GET /render.js");
        assert!(
            head.contains("Cross-Origin-Embedder-Policy: require-corp"),
            "{head}"
        );
        assert_eq!(body, RENDER_JS.as_bytes());
        let (head, body) = req("GET /world");
        assert!(head.contains("application/json"));
        let w: serde_json::Value = serde_json::from_slice(&body).unwrap();
        assert_eq!(w["kind"], "scene");
        assert_eq!(w["frames"], 6);
        let (_, body) = req("GET /frames");
        assert_eq!(body, frames);
        let (head, body) = req("GET /state?frame=5&body=0");
        assert!(head.starts_with("HTTP/1.1 200"), "{head}");
        let s: serde_json::Value = serde_json::from_slice(&body).unwrap();
        assert_eq!(s["tick"], 5);
        let (head, body) = req("HEAD /frames");
        assert!(head.contains(&format!("Content-Length: {}", frames.len())));
        assert!(body.is_empty());
        for bad in [
            "GET /state?frame=6&body=0",
            "GET /state?frame=x",
            "GET /nothing",
        ] {
            assert!(req(bad).0.starts_with("HTTP/1.1 404"), "{bad}");
        }
        for write in ["POST /world", "PUT /frames", "DELETE /"] {
            assert!(req(write).0.starts_with("HTTP/1.1 405"), "{write}");
        }
        // A head that never ends is cut off, not buffered without bound.
        let big = format!("GET /{} HTTP/1.1\r\n", "a".repeat(MAX_REQUEST + 10));
        let mut s = TcpStream::connect(addr).unwrap();
        s.write_all(big.as_bytes()).unwrap();
        let mut raw = Vec::new();
        let _ = s.read_to_end(&mut raw);
        assert!(String::from_utf8_lossy(&raw).starts_with("HTTP/1.1 431"));
    }

    #[test]
    fn query_values_are_percent_decoded() {
        let q = Query("room=my%20room&after=12&x=%zz&plus=a+b&tail=%4");
        assert_eq!(q.get("room").as_deref(), Some("my room"));
        assert_eq!(q.number("after"), Some(12));
        assert_eq!(q.get("x").as_deref(), Some("%zz"));
        assert_eq!(q.get("plus").as_deref(), Some("a b"));
        assert_eq!(q.get("tail").as_deref(), Some("%4"));
        assert_eq!(q.get("missing"), None);
        assert_eq!(q.number("room"), None);
    }
}
