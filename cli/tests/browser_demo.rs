//! The README's browser demo, `lockstep-server --demo --webtransport ADDR`,
//! in headless Chromium: the demo builds the browser module, serves the
//! page, prints its URL and waits for the browser; the page joins beside
//! the bots and the match ends with every hash agreeing and the replay
//! re-verified (the demo's exit status), the browser player in the
//! summary. The WebDriver helpers and the rules about a missing browser
//! are `lockstep_testsupport::webdriver`'s.

use std::io::{BufRead, BufReader};
use std::path::PathBuf;
use std::process::{Command, Stdio};
use std::sync::mpsc;
use std::time::{Duration, Instant};

use lockstep_testsupport::webdriver::{self, Browser, Guard};

#[test]
fn the_demo_serves_a_browser_client_that_plays_beside_its_bots() {
    let Some((chromium, driver)) = webdriver::browser() else {
        return;
    };
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("browser-demo");
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let mut child = Command::new(env!("CARGO_BIN_EXE_lockstep-server"))
        .args(["--demo", "--bots", "2", "--duration", "3"])
        .args([
            "--webtransport",
            "127.0.0.1:0",
            "--web-listen",
            "127.0.0.1:0",
        ])
        .env("LOCKSTEP_REPLAY_DIR", dir.join("replays"))
        .env("LOCKSTEP_CERT_OUT", dir.join("dev-cert.pem"))
        .current_dir(&dir)
        .stdout(Stdio::piped())
        .stderr(Stdio::inherit())
        .spawn()
        .unwrap();
    let stdout = child.stdout.take().unwrap();
    let mut demo = Guard(child);
    let (tx, lines) = mpsc::channel();
    std::thread::spawn(move || {
        for line in BufReader::new(stdout).lines().map_while(Result::ok) {
            println!("{line}");
            if tx.send(line).is_err() {
                break;
            }
        }
    });
    // The first build of the module takes minutes.
    let url = loop {
        let line = lines
            .recv_timeout(Duration::from_secs(600))
            .expect("the demo prints the page's URL");
        if let Some(u) = line.trim().strip_prefix("http://") {
            break format!("http://{u}");
        }
    };
    assert!(url.contains("cert=") && url.contains("room=demo"), "{url}");
    let b = Browser::start(&chromium, &driver, &dir.join("chromium"), &[]);
    // The demo's bot plays in the page (a seed in the URL).
    b.open(&format!("{url}&bot=9"));
    let deadline = Instant::now() + Duration::from_secs(60);
    let state = loop {
        let s = b.run("return window.lockstep ? window.lockstep.state() : null");
        assert!(
            s["pageError"].is_null() && s["workerError"].is_null(),
            "{s}"
        );
        if s["ended"]["kind"] == "closed" {
            break s;
        }
        assert!(Instant::now() < deadline, "the page did not finish: {s}");
        std::thread::sleep(Duration::from_millis(200));
    };
    assert_eq!(state["ticksApplied"].as_u64(), Some(180), "{state}");
    assert_eq!(state["reportsSent"].as_u64(), Some(180), "{state}");
    let deadline = Instant::now() + Duration::from_secs(60);
    let status = loop {
        if let Some(s) = demo.0.try_wait().unwrap() {
            break s;
        }
        assert!(Instant::now() < deadline, "the demo did not end");
        std::thread::sleep(Duration::from_millis(100));
    };
    let out: Vec<String> = lines.try_iter().collect();
    assert!(
        status.success(),
        "the demo reports a problem ({status}): {out:#?}"
    );
    let has = |s: &str| out.iter().any(|l| l.contains(s));
    assert!(has("ticks played: 180") && has("players: 3"), "{out:#?}");
    assert!(has("180 ticks compared, 0 mismatched"), "{out:#?}");
    assert!(
        has("browser"),
        "the browser player in the summary: {out:#?}"
    );
    assert!(has("replay check: OK"), "{out:#?}");
}
