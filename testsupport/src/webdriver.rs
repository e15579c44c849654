//! Headless Chromium for the browser tests, driven through ChromeDriver's
//! WebDriver HTTP interface with nothing but a TCP socket and JSON: the
//! viewer's test (`cli/tests/viewer.rs`) and the browser client's
//! (`tests/tests/browser.rs`) share it.
//!
//! Needs Debian's `chromium` and `chromium-driver` (or `LOCKSTEP_CHROMIUM`
//! and `LOCKSTEP_CHROMEDRIVER`). Where they are missing [`browser`] says
//! so and the tests pass, unless `LOCKSTEP_BROWSER_TESTS=require` (as
//! `.ci/run` sets), which makes a missing browser a failure.

use std::io::{Read, Write};
use std::net::{SocketAddr, TcpListener, TcpStream};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use serde_json::{Value, json};

/// Kills a child process when dropped.
#[derive(Debug)]
pub struct Guard(pub Child);

impl Drop for Guard {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// The browser and its driver, or None (with the reason printed) when they
/// are not installed and not required.
///
/// # Panics
/// When they are missing and `LOCKSTEP_BROWSER_TESTS=require`.
pub fn browser() -> Option<(PathBuf, PathBuf)> {
    let path = |var: &str, default: &str| {
        PathBuf::from(std::env::var_os(var).unwrap_or_else(|| default.into()))
    };
    let chromium = path("LOCKSTEP_CHROMIUM", "/usr/bin/chromium");
    let driver = path("LOCKSTEP_CHROMEDRIVER", "/usr/bin/chromedriver");
    if chromium.exists() && driver.exists() {
        return Some((chromium, driver));
    }
    assert!(
        !browser_required(),
        "LOCKSTEP_BROWSER_TESTS=require, but {} or {} is missing",
        chromium.display(),
        driver.display()
    );
    eprintln!(
        "skipping the browser test: {} or {} is missing (apt-get install chromium chromium-driver)",
        chromium.display(),
        driver.display()
    );
    None
}

/// Whether `LOCKSTEP_BROWSER_TESTS=require`: a browser test that cannot
/// run fails instead of passing.
pub fn browser_required() -> bool {
    std::env::var("LOCKSTEP_BROWSER_TESTS").is_ok_and(|v| v == "require")
}

/// A free TCP port on 127.0.0.1 (free when asked).
///
/// # Panics
/// If no port can be bound.
pub fn free_port() -> u16 {
    TcpListener::bind("127.0.0.1:0")
        .and_then(|l| l.local_addr())
        .expect("a free port")
        .port()
}

/// One HTTP/1.1 request with `Connection: close`; returns the status and
/// the body.
///
/// # Panics
/// If the connection fails or the answer is not HTTP.
pub fn http(addr: SocketAddr, method: &str, path: &str, body: Option<&Value>) -> (u16, Vec<u8>) {
    let mut s = TcpStream::connect(addr).expect("connect");
    s.set_read_timeout(Some(Duration::from_secs(120)))
        .expect("timeout");
    let body = body.map(|b| b.to_string()).unwrap_or_default();
    write!(
        s,
        "{method} {path} HTTP/1.1\r\nHost: {addr}\r\nContent-Type: application/json\r\n\
         Content-Length: {}\r\nConnection: close\r\n\r\n{body}",
        body.len()
    )
    .expect("write the request");
    // Read the head, then exactly the body its Content-Length gives (a
    // driver may keep the connection open), or to the end of a chunked
    // body, or to EOF.
    let mut raw = Vec::new();
    let mut buf = [0u8; 65536];
    let split = loop {
        if let Some(p) = raw.windows(4).position(|w| w == b"\r\n\r\n") {
            break p;
        }
        let n = s.read(&mut buf).expect("read the response");
        assert!(n > 0, "the connection closed before the response head");
        raw.extend_from_slice(&buf[..n]);
    };
    let head = String::from_utf8_lossy(&raw[..split]).to_ascii_lowercase();
    let status = head
        .split_whitespace()
        .nth(1)
        .and_then(|s| s.parse().ok())
        .expect("a status code");
    let length = head.lines().find_map(|l| {
        l.strip_prefix("content-length:")
            .and_then(|v| v.trim().parse::<usize>().ok())
    });
    let chunked = head.contains("transfer-encoding: chunked");
    let mut payload = raw[split + 4..].to_vec();
    loop {
        let done = match length {
            Some(n) => payload.len() >= n,
            None => chunked && payload.ends_with(b"0\r\n\r\n"),
        };
        if done {
            break;
        }
        let n = s.read(&mut buf).expect("read the body");
        if n == 0 {
            break;
        }
        payload.extend_from_slice(&buf[..n]);
    }
    if chunked {
        payload = unchunk(&payload);
    }
    (status, payload)
}

fn unchunk(mut b: &[u8]) -> Vec<u8> {
    let mut out = Vec::new();
    loop {
        let line_end = b
            .windows(2)
            .position(|w| w == b"\r\n")
            .expect("a chunk size line");
        let size = std::str::from_utf8(&b[..line_end])
            .ok()
            .and_then(|s| usize::from_str_radix(s.trim(), 16).ok())
            .expect("a chunk size");
        if size == 0 {
            return out;
        }
        out.extend_from_slice(&b[line_end + 2..line_end + 2 + size]);
        b = &b[line_end + 2 + size + 2..];
    }
}

/// The flags every test's Chromium runs with: headless, no sandbox (CI runs
/// as root), software WebGL, nothing in the background, a 1280×720 window.
/// QUIC stays on: WebTransport needs it (the viewer's test adds
/// `--disable-quic`).
pub const CHROMIUM_FLAGS: &[&str] = &[
    "--headless=new",
    "--no-sandbox",
    "--disable-gpu",
    "--use-angle=swiftshader",
    "--enable-unsafe-swiftshader",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--window-size=1280,720",
];

/// A WebDriver session on headless Chromium.
#[derive(Debug)]
pub struct Browser {
    driver: SocketAddr,
    session: String,
    _driver: Guard,
}

impl Browser {
    /// Starts ChromeDriver and a session on Chromium with
    /// [`CHROMIUM_FLAGS`], `extra` flags and a fresh profile in `profile`.
    ///
    /// # Panics
    /// If the driver does not start or refuses the session.
    pub fn start(chromium: &Path, chromedriver: &Path, profile: &Path, extra: &[&str]) -> Browser {
        let port = free_port();
        let child = Command::new(chromedriver)
            .arg(format!("--port={port}"))
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .expect("start chromedriver");
        let guard = Guard(child);
        let driver = SocketAddr::from(([127, 0, 0, 1], port));
        let deadline = Instant::now() + Duration::from_secs(30);
        while TcpStream::connect(driver).is_err() {
            assert!(Instant::now() < deadline, "chromedriver did not start");
            std::thread::sleep(Duration::from_millis(100));
        }
        let _ = std::fs::remove_dir_all(profile);
        let mut args: Vec<String> = CHROMIUM_FLAGS.iter().map(|s| (*s).to_owned()).collect();
        args.extend(extra.iter().map(|s| (*s).to_owned()));
        args.push(format!("--user-data-dir={}", profile.display()));
        let caps = json!({"capabilities": {"alwaysMatch": {
            "browserName": "chrome",
            "goog:chromeOptions": {
                "binary": chromium.to_str().expect("a UTF-8 path"),
                "args": args,
            }
        }}});
        let (status, body) = http(driver, "POST", "/session", Some(&caps));
        let v: Value = serde_json::from_slice(&body).expect("JSON");
        assert_eq!(status, 200, "new session: {v}");
        let session = v["value"]["sessionId"]
            .as_str()
            .expect("a session id")
            .to_owned();
        Browser {
            driver,
            session,
            _driver: guard,
        }
    }

    /// One WebDriver command on the session; returns its `value`.
    ///
    /// # Panics
    /// Unless the driver answers 200.
    pub fn call(&self, method: &str, path: &str, body: Option<&Value>) -> Value {
        let path = format!("/session/{}{path}", self.session);
        let (status, b) = http(self.driver, method, &path, body);
        let v: Value = serde_json::from_slice(&b).expect("JSON");
        assert_eq!(status, 200, "{method} {path}: {v}");
        v["value"].clone()
    }

    /// Navigates to `url`.
    pub fn open(&self, url: &str) {
        self.call("POST", "/url", Some(&json!({ "url": url })));
    }

    /// Runs `script` in the page (a function body) and returns what it
    /// returns.
    pub fn run(&self, script: &str) -> Value {
        self.call(
            "POST",
            "/execute/sync",
            Some(&json!({ "script": script, "args": [] })),
        )
    }

    /// Holds the keys of `value` (WebDriver key codes, e.g. `"\u{E014}"`
    /// for the right arrow) down, as a user's keyboard would, until
    /// [`Browser::release_keys`].
    pub fn hold(&self, value: &str) {
        let actions: Vec<Value> = value
            .chars()
            .map(|c| json!({"type": "keyDown", "value": c.to_string()}))
            .collect();
        self.call(
            "POST",
            "/actions",
            Some(&json!({"actions": [{"type": "key", "id": "keyboard", "actions": actions}]})),
        );
    }

    /// Releases every key and button held.
    pub fn release_keys(&self) {
        self.call("DELETE", "/actions", None);
    }

    /// The page as a PNG.
    ///
    /// # Panics
    /// If the driver's answer is not a PNG.
    pub fn screenshot(&self) -> Vec<u8> {
        let b64 = self.call("GET", "/screenshot", None);
        let png = base64(b64.as_str().expect("base64 text"));
        assert_eq!(&png[..8], b"\x89PNG\r\n\x1a\n", "a PNG");
        png
    }

    /// Writes a screenshot as `<prefix>-<name>.png` into `dir`, and into
    /// `LOCKSTEP_SCREENSHOT_DIR` when that is set (docs/img/ came from
    /// there).
    ///
    /// # Panics
    /// If a file cannot be written.
    pub fn save_screenshot(&self, dir: &Path, file: &str) {
        let png = self.screenshot();
        std::fs::write(dir.join(file), &png).expect("write the screenshot");
        if let Some(keep) = std::env::var_os("LOCKSTEP_SCREENSHOT_DIR") {
            std::fs::write(Path::new(&keep).join(file), &png).expect("keep the screenshot");
        }
    }
}

impl Drop for Browser {
    fn drop(&mut self) {
        let path = format!("/session/{}", self.session);
        let _ = std::panic::catch_unwind(|| http(self.driver, "DELETE", &path, None));
    }
}

/// Decodes standard base64 (what WebDriver's screenshots are).
///
/// # Panics
/// On a character outside the alphabet.
pub fn base64(s: &str) -> Vec<u8> {
    let val = |c: u8| match c {
        b'A'..=b'Z' => c - b'A',
        b'a'..=b'z' => c - b'a' + 26,
        b'0'..=b'9' => c - b'0' + 52,
        b'+' => 62,
        b'/' => 63,
        _ => panic!("not base64: {c}"),
    };
    let bytes: Vec<u8> = s.bytes().filter(|&c| c != b'=').collect();
    let mut out = Vec::with_capacity(bytes.len() * 3 / 4);
    for chunk in bytes.chunks(4) {
        let v: Vec<u32> = chunk.iter().map(|&c| u32::from(val(c))).collect();
        let n = v
            .iter()
            .enumerate()
            .fold(0, |acc, (i, &x)| acc | x << (18 - 6 * i));
        out.extend_from_slice(&n.to_be_bytes()[1..chunk.len()]);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn base64_decodes_padded_and_unpadded_text() {
        assert_eq!(base64("aGVsbG8="), b"hello");
        assert_eq!(base64("aGVsbG8h"), b"hello!");
        assert_eq!(base64("aA=="), b"h");
    }

    #[test]
    fn chunked_bodies_are_joined() {
        assert_eq!(unchunk(b"3\r\nabc\r\n2\r\nde\r\n0\r\n\r\n"), b"abcde");
    }
}
