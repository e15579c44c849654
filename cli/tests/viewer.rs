//! `lockstep view` in a real browser: headless Chromium, driven through
//! ChromeDriver's WebDriver HTTP interface, opens the viewer on a scene, a
//! replay and a desync bundle, waits for the first frame, checks from the
//! page's own state and its pixels that every body is drawn, moves the
//! tick slider and checks that the world moved to the exact state the
//! viewer serves for that tick.
//!
//! The WebDriver helpers are `lockstep_testsupport::webdriver`, shared
//! with the browser client's test (`tests/tests/browser.rs`): it says
//! what is needed and when a missing browser fails the test.
//! LOCKSTEP_SCREENSHOT_DIR keeps the screenshots (docs/img/viewer-*.png
//! came from here).

use std::io::{BufRead, BufReader};
use std::net::{SocketAddr, TcpStream};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use lockstep_testsupport::webdriver::{self, Guard, free_port, http};
use serde_json::Value;

fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// The shared WebDriver session, with what the viewer's page offers.
struct Browser(webdriver::Browser);

impl std::ops::Deref for Browser {
    type Target = webdriver::Browser;
    fn deref(&self) -> &webdriver::Browser {
        &self.0
    }
}

impl Browser {
    fn start(chromium: &Path, chromedriver: &Path, profile: &Path) -> Browser {
        // The viewer needs no QUIC (only the browser client's WebTransport
        // does): keep Chromium from trying it.
        Browser(webdriver::Browser::start(
            chromium,
            chromedriver,
            profile,
            &["--disable-quic"],
        ))
    }

    fn status(&self) -> Value {
        self.run("return window.lockstepViewer ? window.lockstepViewer.status() : null")
    }

    /// Waits until the page has drawn a frame (or reported an error).
    fn wait_ready(&self) -> Value {
        let deadline = Instant::now() + Duration::from_secs(90);
        loop {
            let s = self.status();
            assert!(s["error"].is_null(), "the page reported: {s}");
            if s["ready"] == true && s["framesDrawn"].as_u64() >= Some(1) {
                return s;
            }
            assert!(Instant::now() < deadline, "no frame drawn: {s}");
            std::thread::sleep(Duration::from_millis(200));
        }
    }

    /// Moves the slider as a user does (value, then an input event) and
    /// waits for the frame to be drawn.
    fn slide_to(&self, frame: usize) -> Value {
        let before = self.status()["framesDrawn"].as_u64().unwrap();
        self.run(&format!(
            "const s = document.getElementById('slider'); s.value = {frame}; \
             s.dispatchEvent(new Event('input')); return null"
        ));
        let deadline = Instant::now() + Duration::from_secs(30);
        loop {
            let s = self.status();
            if s["framesDrawn"].as_u64().unwrap() > before {
                assert_eq!(s["frame"].as_u64(), Some(frame as u64), "{s}");
                return s;
            }
            assert!(
                Instant::now() < deadline,
                "no frame drawn after the slider moved"
            );
            std::thread::sleep(Duration::from_millis(100));
        }
    }

    fn pose(&self, body: i64) -> Vec<f64> {
        self.run(&format!("return window.lockstepViewer.pose({body})"))
            .as_array()
            .unwrap()
            .iter()
            .map(|x| x.as_f64().unwrap())
            .collect()
    }

    fn screenshot(&self, name: &str) {
        self.save_screenshot(
            Path::new(env!("CARGO_TARGET_TMPDIR")),
            &format!("viewer-{name}.png"),
        );
    }
}

/// A running `lockstep view` and its URL.
struct Viewer {
    url: String,
    addr: SocketAddr,
    _child: Guard,
}

fn view(args: &[&str]) -> Viewer {
    let mut child = Command::new(env!("CARGO_BIN_EXE_lockstep"))
        .arg("view")
        .args(args)
        .current_dir(repo())
        .stdout(Stdio::piped())
        .stderr(Stdio::inherit())
        .spawn()
        .unwrap();
    let mut line = String::new();
    BufReader::new(child.stdout.take().unwrap())
        .read_line(&mut line)
        .unwrap();
    let url = line
        .split_whitespace()
        .find(|w| w.starts_with("http://"))
        .unwrap_or_else(|| panic!("no URL in {line:?}"))
        .to_owned();
    let addr = url
        .trim_start_matches("http://")
        .trim_end_matches('/')
        .parse()
        .unwrap();
    Viewer {
        url,
        addr,
        _child: Guard(child),
    }
}

fn exact_state(v: &Viewer, frame: usize, body: i64) -> Value {
    let (status, b) = http(
        v.addr,
        "GET",
        &format!("/state?frame={frame}&body={body}"),
        None,
    );
    assert_eq!(status, 200);
    serde_json::from_slice(&b).unwrap()
}

fn body_count(scene: &str) -> u64 {
    let text = std::fs::read_to_string(repo().join(scene)).unwrap();
    let world = lockstep_core::scene::load_world(&text, scene).unwrap();
    world.body_handles().count() as u64
}

/// Checks that the page drew every body and lit a good part of the view.
fn check_drawn(b: &Browser, s: &Value, bodies: u64) {
    assert_eq!(s["bodies"].as_u64(), Some(bodies), "{s}");
    assert_eq!(s["bodiesDrawn"].as_u64(), Some(bodies), "{s}");
    let lit = b
        .run("return window.lockstepViewer.litPixels()")
        .as_u64()
        .unwrap();
    assert!(lit > 20_000, "only {lit} pixels differ from the background");
}

/// Moves the slider from `from` to `to` and checks that `body` moved to
/// the exact state the viewer serves for that frame.
fn check_slider_moves(b: &Browser, v: &Viewer, body: i64, from: usize, to: usize) {
    b.slide_to(from);
    let p0 = b.pose(body);
    let s = b.slide_to(to);
    let p1 = b.pose(body);
    assert_ne!(
        p0, p1,
        "body {body} did not move between frames {from} and {to}"
    );
    let exact = exact_state(v, to, body);
    assert_eq!(exact["tick"], s["tick"]);
    for k in 0..3 {
        let want: f64 = exact["position"][k].as_str().unwrap().parse().unwrap();
        assert!(
            (p1[k] - want).abs() < 1e-4,
            "axis {k}: drawn {} exact {want}",
            p1[k]
        );
    }
}

#[test]
fn the_viewer_draws_a_scene_and_its_slider_moves_the_world() {
    let Some((chromium, driver)) = webdriver::browser() else {
        return;
    };
    let tmp = PathBuf::from(env!("CARGO_TARGET_TMPDIR"));
    let v = view(&["scenes/shapes.toml", "--ticks", "240"]);
    let b = Browser::start(&chromium, &driver, &tmp.join("chromium-scene"));
    b.open(&v.url);
    let s = b.wait_ready();
    assert_eq!(s["kind"], "scene");
    assert_eq!(s["frames"].as_u64(), Some(241));
    check_drawn(&b, &s, body_count("scenes/shapes.toml"));
    let ball = b
        .run("return window.lockstepViewer.bodyIndex('ball')")
        .as_i64()
        .unwrap();
    assert!(ball >= 0);
    check_slider_moves(&b, &v, ball, 0, 45);
    // The overlays draw without errors.
    b.run(
        "for (const id of ['ov-contacts', 'ov-aabbs', 'ov-names']) { \
         const c = document.getElementById(id); c.checked = true; c.dispatchEvent(new Event('change')); } \
         return null",
    );
    b.slide_to(200);
    assert!(b.status()["error"].is_null());
    // Picking a body from the list shows its exact state for the tick.
    let crate_ = b
        .run("return window.lockstepViewer.bodyIndex('crate')")
        .as_i64()
        .unwrap();
    b.run(&format!(
        "document.querySelector('#bodies div[data-i=\"{crate_}\"]').click(); return null"
    ));
    let exact = exact_state(&v, 200, crate_);
    let deadline = Instant::now() + Duration::from_secs(30);
    loop {
        let panel = b.run("return document.getElementById('state').textContent");
        let panel = panel.as_str().unwrap();
        if panel.contains("\"crate\"") {
            for k in 0..3 {
                let want = exact["position"][k].as_str().unwrap();
                assert!(panel.contains(want), "{want} in {panel}");
            }
            break;
        }
        assert!(Instant::now() < deadline, "no exact state shown: {panel}");
        std::thread::sleep(Duration::from_millis(100));
    }
    assert_eq!(b.status()["picked"].as_i64(), Some(crate_));
    b.screenshot("scene");
}

/// An empty directory under the test target's temporary directory.
fn fresh_dir(name: &str) -> PathBuf {
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(name);
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// A short demo match in `dir` in which one bot nudges a body before tick
/// 40: its replay and its desync bundle.
fn demo_match(dir: &Path) -> (String, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_lockstep-server"))
        .args([
            "--demo",
            "--duration",
            "1.5",
            "--bots",
            "3",
            "--diverge-at",
            "40",
        ])
        .env("LOCKSTEP_REPLAY_DIR", dir.join("replays"))
        .env("LOCKSTEP_CERT_OUT", dir.join("dev-cert.pem"))
        .current_dir(dir)
        .output()
        .unwrap();
    assert_eq!(
        out.status.code(),
        Some(1),
        "the demo reports its desync: {out:?}"
    );
    let files: Vec<PathBuf> = std::fs::read_dir(dir.join("replays"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    let find = |ext: &str| {
        files
            .iter()
            .find(|p| p.extension().is_some_and(|e| e == ext))
            .unwrap_or_else(|| panic!("no .{ext} in {files:?}"))
            .to_str()
            .unwrap()
            .to_owned()
    };
    (find("replay"), find("bundle"))
}

fn world_of(v: &Viewer) -> Value {
    let (status, body) = http(v.addr, "GET", "/world", None);
    assert_eq!(status, 200);
    serde_json::from_slice(&body).unwrap()
}

/// No browser needed: `--from` and `--ticks` pick the frames of a replay,
/// and a bundle's frames always end at its desync tick.
#[test]
fn view_shows_a_window_of_a_replay_and_a_bundle_ends_at_its_desync() {
    let dir = fresh_dir("viewer-window");
    let (replay, bundle) = demo_match(&dir);
    let w = world_of(&view(&[&replay, "--from", "30", "--ticks", "20"]));
    assert_eq!(w["kind"], "replay");
    assert_eq!(
        (w["first_tick"].as_u64(), w["frames"].as_u64()),
        (Some(30), Some(20))
    );
    let w = world_of(&view(&[&bundle, "--ticks", "10"]));
    assert_eq!(w["kind"], "bundle");
    let desync = w["desync"]["tick"].as_u64().unwrap();
    assert_eq!(w["frames"].as_u64(), Some(10));
    assert_eq!(w["first_tick"].as_u64(), Some(desync - 9));
    assert_eq!(w["desync"]["frame"].as_u64(), Some(9));
    // A scene or replay that does not exist is a clear error, status 2.
    let out = Command::new(env!("CARGO_BIN_EXE_lockstep"))
        .args(["view", "no/such.replay"])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("no/such.replay"));
}

#[test]
fn the_viewer_plays_a_replay_and_shows_a_bundles_diverging_bodies() {
    let Some((chromium, driver)) = webdriver::browser() else {
        return;
    };
    let dir = fresh_dir("viewer-match");
    let (replay, bundle) = demo_match(&dir);
    let demo_bodies = body_count("scenes/demo.toml");

    let b = Browser::start(&chromium, &driver, &dir.join("chromium"));
    let v = view(&[&replay]);
    b.open(&v.url);
    let s = b.wait_ready();
    assert_eq!(s["kind"], "replay");
    assert!(s["frames"].as_u64().unwrap() > 60, "{s}");
    check_drawn(&b, &s, demo_bodies);
    let player = b
        .run("return window.lockstepViewer.bodyIndex('player0')")
        .as_i64()
        .unwrap();
    let mover = if player >= 0 {
        player
    } else {
        // Any body that moves between the two frames.
        b.run(
            "const v = window.lockstepViewer; v.setFrame(0); const a = []; \
             for (let i = 0; i < v.status().bodies; i++) a.push(v.pose(i)); v.setFrame(60); \
             for (let i = 0; i < a.length; i++) if (v.pose(i).some((x, k) => x !== a[i][k])) return i; \
             return -1",
        )
        .as_i64()
        .unwrap()
    };
    assert!(mover >= 0, "nothing moves in the replay");
    check_slider_moves(&b, &v, mover, 0, 60);

    let v = view(&[&bundle]);
    b.open(&v.url);
    let s = b.wait_ready();
    assert_eq!(s["kind"], "bundle");
    let diverging = s["diverging"].as_array().unwrap();
    assert!(
        !diverging.is_empty(),
        "the bundle's diverging bodies are lit: {s}"
    );
    assert_eq!(
        s["frame"].as_u64().unwrap() + 1,
        s["frames"].as_u64().unwrap()
    );
    check_drawn(&b, &s, demo_bodies);
    let panel = b.run("return document.getElementById('desync').textContent");
    assert!(
        panel.as_str().unwrap().contains("first differing field"),
        "{panel}"
    );
    b.screenshot("bundle");
    // Overlaid: one view, the diverging player's poses as ghosts.
    let before = b.status()["framesDrawn"].as_u64().unwrap();
    b.run(
        "const r = document.querySelector('input[name=mode][value=overlay]'); r.checked = true; \
         r.dispatchEvent(new Event('change')); return null",
    );
    let deadline = Instant::now() + Duration::from_secs(30);
    while b.status()["framesDrawn"].as_u64().unwrap() <= before {
        assert!(Instant::now() < deadline, "no frame drawn overlaid");
        std::thread::sleep(Duration::from_millis(100));
    }
    let s = b.status();
    assert!(s["error"].is_null(), "{s}");
    check_drawn(&b, &s, demo_bodies);
}

fn metric(addr: SocketAddr, name: &str) -> Option<u64> {
    let (_, body) = http(addr, "GET", "/metrics", None);
    String::from_utf8_lossy(&body)
        .lines()
        .find_map(|l| l.strip_prefix(&format!("{name} "))?.trim().parse().ok())
}

#[test]
fn the_viewer_follows_a_live_room_that_pays_nothing_until_watched() {
    let Some((chromium, driver)) = webdriver::browser() else {
        return;
    };
    let dir = fresh_dir("viewer-live");
    let (view_port, metrics_port) = (free_port(), free_port());
    let server = Command::new(env!("CARGO_BIN_EXE_lockstep-server"))
        .args(["--demo", "--duration", "10", "--bots", "3"])
        .args(["--view", &format!("127.0.0.1:{view_port}")])
        .args(["--metrics", &format!("127.0.0.1:{metrics_port}")])
        .env("LOCKSTEP_REPLAY_DIR", dir.join("replays"))
        .env("LOCKSTEP_CERT_OUT", dir.join("dev-cert.pem"))
        .current_dir(&dir)
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let mut server = Guard(server);
    let live: SocketAddr = format!("127.0.0.1:{view_port}").parse().unwrap();
    let metrics: SocketAddr = format!("127.0.0.1:{metrics_port}").parse().unwrap();
    // Wait for the room to play a second with nobody watching.
    let deadline = Instant::now() + Duration::from_secs(60);
    loop {
        if TcpStream::connect(live).is_ok() {
            let (_, body) = http(live, "GET", "/world", None);
            let w: Value = serde_json::from_slice(&body).unwrap();
            if w["rooms"][0]["ticks"].as_u64().is_some_and(|t| t >= 60) {
                assert_eq!(w["kind"], "rooms");
                assert_eq!(w["rooms"][0]["name"], "demo");
                break;
            }
        }
        assert!(Instant::now() < deadline, "the demo room did not start");
        std::thread::sleep(Duration::from_millis(100));
    }
    assert_eq!(
        metric(metrics, "lockstep_view_ticks_simulated_total"),
        Some(0),
        "nothing is re-simulated while nobody watches"
    );
    // Spectators only read.
    for method in ["POST", "PUT", "DELETE"] {
        assert_eq!(http(live, method, "/frames?room=demo", None).0, 405);
    }

    let b = Browser::start(&chromium, &driver, &dir.join("chromium"));
    b.open(&format!("http://{live}/?room=demo"));
    let s = b.wait_ready();
    assert_eq!(s["kind"], "live");
    assert_eq!(s["live"], true);
    assert_eq!(s["following"], true);
    check_drawn(&b, &s, body_count("scenes/demo.toml"));
    let first = s["tick"].as_u64().unwrap();
    std::thread::sleep(Duration::from_secs(1));
    let later = b.status();
    assert!(
        later["tick"].as_u64().unwrap() >= first + 30,
        "the page follows the match: {first} then {later}"
    );
    assert!(metric(metrics, "lockstep_view_ticks_simulated_total").unwrap() >= first);
    // The exact state a spectator sees, to compare with the replay's.
    let tick = later["tick"].as_u64().unwrap();
    let player = b
        .run("return window.lockstepViewer.bodyIndex('player0')")
        .as_i64()
        .unwrap();
    let (status, live_state) = http(
        live,
        "GET",
        &format!("/state?room=demo&tick={tick}&body={player}"),
        None,
    );
    assert_eq!(status, 200);
    let live_state: Value = serde_json::from_slice(&live_state).unwrap();
    b.screenshot("live");
    drop(b);
    // The watched match ends as an unwatched one does: the bots agree on
    // every tick and the replay verifies (the demo's exit status says so).
    let deadline = Instant::now() + Duration::from_secs(60);
    let status = loop {
        if let Some(s) = server.0.try_wait().unwrap() {
            break s;
        }
        assert!(Instant::now() < deadline, "the demo did not end");
        std::thread::sleep(Duration::from_millis(100));
    };
    assert!(status.success(), "{status:?}");
    // What the spectator saw is what the players simulated: the replay,
    // re-simulated offline, has the same exact state at that tick.
    let replay = std::fs::read_dir(dir.join("replays"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .find(|p| p.extension().is_some_and(|e| e == "replay"))
        .unwrap();
    let v = view(&[replay.to_str().unwrap()]);
    let offline = exact_state(&v, tick as usize, player);
    assert_eq!(offline["tick"], tick);
    for field in [
        "position",
        "rotation (x, y, z, w)",
        "linear_velocity",
        "angular_velocity",
    ] {
        assert_eq!(offline[field], live_state[field], "{field} at tick {tick}");
    }
}
