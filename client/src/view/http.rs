//! The viewer's HTTP server: a few read-only GET routes on a local socket,
//! with the page and its script embedded in the binary (no JavaScript
//! toolchain is needed to build or run it).
//!
//! | route | what |
//! |---|---|
//! | `/` | the page |
//! | `/viewer.js` | its script (a small WebGL2 renderer) |
//! | `/world` | JSON: the bodies and their geometry, the desync of a bundle |
//! | `/frames` | binary: every frame's poses and contacts ([`super::encode_frames`]) |
//! | `/state?frame=F&body=B` | JSON: one body's exact state at one frame |
//!
//! Nothing a browser sends can change the data: every route only reads.

use std::io::{self, Read, Write};
use std::net::{TcpListener, TcpStream};
use std::sync::Arc;
use std::time::Duration;

use super::{ViewData, encode_frames, state_json, world_json};

/// The page.
pub const INDEX_HTML: &str = include_str!("page/index.html");
/// The page's script.
pub const VIEWER_JS: &str = include_str!("page/viewer.js");

/// The largest request head read (a browser's GET is well under it).
const MAX_REQUEST: usize = 16 * 1024;

/// What the routes serve, encoded once.
struct Content {
    data: ViewData,
    world: String,
    frames: Vec<u8>,
}

/// Serves `data` on `listener` until the process ends, one thread per
/// connection.
///
/// # Errors
/// Only if accepting fails for good; a broken connection is dropped.
pub fn serve(listener: TcpListener, data: ViewData) -> io::Result<()> {
    let content = Arc::new(Content {
        world: world_json(&data),
        frames: encode_frames(&data),
        data,
    });
    for stream in listener.incoming() {
        let stream = match stream {
            Ok(s) => s,
            Err(e) if e.kind() == io::ErrorKind::ConnectionAborted => continue,
            Err(e) => return Err(e),
        };
        let content = Arc::clone(&content);
        std::thread::spawn(move || {
            let _ = handle(stream, &content);
        });
    }
    Ok(())
}

fn handle(mut stream: TcpStream, content: &Content) -> io::Result<()> {
    stream.set_read_timeout(Some(Duration::from_secs(10)))?;
    let mut buf = Vec::with_capacity(1024);
    let mut chunk = [0u8; 1024];
    while !buf.windows(4).any(|w| w == b"\r\n\r\n") {
        if buf.len() > MAX_REQUEST {
            return respond(&mut stream, 431, "text/plain", b"request too large");
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
        return respond(&mut stream, 405, "text/plain", b"the viewer only reads");
    }
    let (path, query) = target.split_once('?').unwrap_or((target, ""));
    let (status, ctype, body): (u16, &str, &[u8]) = match path {
        "/" | "/index.html" => (200, "text/html; charset=utf-8", INDEX_HTML.as_bytes()),
        "/viewer.js" => (200, "text/javascript; charset=utf-8", VIEWER_JS.as_bytes()),
        "/world" => (200, "application/json", content.world.as_bytes()),
        "/frames" => (200, "application/octet-stream", &content.frames),
        "/state" => {
            let arg = |k: &str| {
                query
                    .split('&')
                    .filter_map(|kv| kv.split_once('='))
                    .find(|(key, _)| *key == k)
                    .and_then(|(_, v)| v.parse::<usize>().ok())
            };
            let json = arg("frame")
                .zip(arg("body"))
                .and_then(|(f, b)| state_json(&content.data, f, b));
            return match json {
                Some(j) => respond(&mut stream, 200, "application/json", j.as_bytes()),
                None => respond(&mut stream, 404, "text/plain", b"no such frame or body"),
            };
        }
        _ => (404, "text/plain", b"not found"),
    };
    let body = if method == "HEAD" { &[][..] } else { body };
    respond(&mut stream, status, ctype, body)
}

fn respond(stream: &mut TcpStream, status: u16, ctype: &str, body: &[u8]) -> io::Result<()> {
    let reason = match status {
        200 => "OK",
        404 => "Not Found",
        405 => "Method Not Allowed",
        _ => "Request Header Fields Too Large",
    };
    let head = format!(
        "HTTP/1.1 {status} {reason}\r\nContent-Type: {ctype}\r\nContent-Length: {}\r\n\
         Cache-Control: no-store\r\nConnection: close\r\n\r\n",
        body.len()
    );
    stream.write_all(head.as_bytes())?;
    stream.write_all(body)?;
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

    #[test]
    fn every_route_answers_and_nothing_writes() {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes/spin.toml");
        let data = super::super::load_view(&path, &crate::game::Demo, 5).unwrap();
        let frames = encode_frames(&data);
        let listener = TcpListener::bind("127.0.0.1:0").unwrap();
        let addr = listener.local_addr().unwrap();
        std::thread::spawn(move || serve(listener, data));
        let req = |line: &str| get(addr, &format!("{line} HTTP/1.1\r\nHost: x\r\n\r\n"));

        let (head, body) = req("GET /");
        assert!(head.starts_with("HTTP/1.1 200"), "{head}");
        assert_eq!(body, INDEX_HTML.as_bytes());
        let (_, body) = req("GET /viewer.js");
        assert_eq!(body, VIEWER_JS.as_bytes());
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
}
