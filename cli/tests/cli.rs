//! The `lockstep` binary as a user runs it.

mod common;

use common::{lockstep, scene, temp_dir};

#[test]
fn sim_prints_one_hash_line_per_hashed_tick() {
    let out = lockstep()
        .args(["sim", "--scene"])
        .arg(scene("shapes.toml"))
        .args(["--ticks", "120", "--hash-every", "30"])
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = String::from_utf8(out.stdout).unwrap();
    let lines: Vec<&str> = text.lines().collect();
    assert_eq!(lines.len(), 4);
    for (i, line) in lines.iter().enumerate() {
        let parts: Vec<&str> = line.split(' ').collect();
        assert_eq!(parts[0], "tick");
        assert_eq!(parts[1], ((i + 1) * 30).to_string());
        assert_eq!(parts[2].len(), 16);
        assert!(parts[2].chars().all(|c| c.is_ascii_hexdigit()));
    }
    // The same run twice prints the same thing.
    let again = lockstep()
        .args(["sim", "--scene"])
        .arg(scene("shapes.toml"))
        .args(["--ticks", "120", "--hash-every", "30"])
        .output()
        .unwrap();
    assert_eq!(String::from_utf8(again.stdout).unwrap(), text);
}

#[test]
fn dump_state_writes_exact_decimals_for_every_body() {
    let dir = temp_dir("cli", "dump");
    let dump = dir.join("state.json");
    let out = lockstep()
        .args(["sim", "--scene"])
        .arg(scene("spin.toml"))
        .args(["--ticks", "60", "--hash-every", "60", "--dump-state"])
        .arg(&dump)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&dump).unwrap()).unwrap();
    assert_eq!(json["tick"], 60);
    let printed_hash = String::from_utf8(out.stdout).unwrap();
    assert_eq!(
        printed_hash.trim(),
        format!("tick 60 {}", json["state_hash"].as_str().unwrap())
    );
    let bodies = json["bodies"].as_array().unwrap();
    assert!(!bodies.is_empty());
    for b in bodies {
        for key in ["position", "linear_velocity", "angular_velocity"] {
            let v = b[key].as_array().unwrap();
            assert_eq!(v.len(), 3);
            for c in v {
                // Exact decimals parse back to a fixed-point value.
                let s = c.as_str().unwrap();
                assert!(s.parse::<lockstep_core::Scalar>().is_ok(), "{s}");
            }
        }
        assert_eq!(b["rotation"].as_array().unwrap().len(), 4);
        assert!(b["name"].is_string() && b["kind"].is_string() && b["asleep"].is_boolean());
    }
    std::fs::remove_dir_all(dir).ok();
}

#[test]
fn a_bad_scene_file_is_a_clear_error_with_file_line_and_column() {
    let dir = temp_dir("cli", "bad");
    let bad = dir.join("bad.toml");
    std::fs::write(&bad, "[world]\ntick_rate = 60\n\n[[bodies]]\nname = \"ball\"\nkind = \"dynamic\"\n[[bodies.shapes]]\nkind = \"sphere\"\nradius = -1\n").unwrap();
    let out = lockstep()
        .args(["sim", "--scene"])
        .arg(&bad)
        .args(["--ticks", "10"])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8(out.stderr).unwrap();
    assert!(err.starts_with("lockstep sim: error: "), "{err}");
    assert!(err.contains("bad.toml:9:"), "{err}");
    assert!(err.contains("radius"), "{err}");
    assert!(out.stdout.is_empty());

    let missing = lockstep()
        .args(["sim", "--scene", "/nonexistent/scene.toml", "--ticks", "1"])
        .output()
        .unwrap();
    assert_eq!(missing.status.code(), Some(2));
    assert!(
        String::from_utf8(missing.stderr)
            .unwrap()
            .contains("/nonexistent/scene.toml")
    );

    let zero = lockstep()
        .args(["sim", "--scene"])
        .arg(scene("spin.toml"))
        .args(["--ticks", "1", "--hash-every", "0"])
        .output()
        .unwrap();
    assert_eq!(zero.status.code(), Some(2));
    std::fs::remove_dir_all(dir).ok();
}

/// `lockstep-server token` prints a token the server's check accepts for
/// that room and seat; a short secret is refused with its reason.
#[test]
fn the_token_subcommand_prints_a_token_that_verifies() {
    let dir = std::path::PathBuf::from(env!("CARGO_TARGET_TMPDIR"));
    let secret = dir.join("token-secret");
    std::fs::write(&secret, b"a secret of more than sixteen bytes").unwrap();
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_lockstep-server"))
        .args([
            "token", "--room", "arena", "--seat", "2", "--player", "alice",
        ])
        .arg("--secret-file")
        .arg(&secret)
        .output()
        .unwrap();
    assert!(out.status.success(), "{out:?}");
    let token = String::from_utf8(out.stdout).unwrap();
    let now = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .unwrap()
        .as_secs();
    let ticket = lockstep_proto::token::verify(
        b"a secret of more than sixteen bytes",
        token.trim(),
        "arena",
        now,
    )
    .unwrap();
    assert_eq!(ticket.claims.seat, Some(lockstep_proto::Slot(2)));
    assert_eq!(ticket.claims.player, "alice");
    // Valid 10 minutes by default (a token is for the first join; the
    // rejoin credential lasts the match).
    assert!(ticket.claims.expires <= now + 600);
    assert!(ticket.claims.expires >= now + 500);
    std::fs::write(&secret, b"short").unwrap();
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_lockstep-server"))
        .args(["token", "--room", "arena", "--player", "alice"])
        .arg("--secret-file")
        .arg(&secret)
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    assert!(
        String::from_utf8_lossy(&out.stderr).contains("shorter than 16 bytes"),
        "{out:?}"
    );
}

/// `RUST_LOG=debug` shows each room's events inside its span, and the
/// connection's with its peer and slot. Flags also come from the
/// environment (`LOCKSTEP_<FLAG>`).
#[test]
fn debug_logging_shows_per_room_and_per_connection_spans() {
    let dir = std::path::PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("spans");
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_lockstep-server"))
        .args(["--demo"])
        .env("LOCKSTEP_DURATION", "1")
        .env("LOCKSTEP_BOTS", "2")
        .env("RUST_LOG", "debug")
        .current_dir(&dir)
        .output()
        .unwrap();
    assert!(out.status.success(), "{out:?}");
    let log = String::from_utf8_lossy(&out.stderr);
    assert!(
        log.contains("room{room=demo}: room demo: match started"),
        "{log}"
    );
    assert!(log.contains("slot=1}: seated"), "{log}");
    assert!(!log.contains('\u{1b}'), "no colour codes off a terminal");
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(text.contains("2 bots, 60 ticks at 60 Hz"), "{text}");
}

/// The container files name only real flags: every `LOCKSTEP_*` variable
/// in the Dockerfile and the Kubernetes and Agones manifests is one `lockstep-server
/// --help` lists; the image runs as a non-root user and exposes QUIC on UDP.
#[test]
fn the_container_files_use_real_flags_and_a_non_root_user() {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let help = std::process::Command::new(env!("CARGO_BIN_EXE_lockstep-server"))
        .arg("--help")
        .output()
        .unwrap();
    let help = String::from_utf8_lossy(&help.stdout).into_owned();
    let docker = std::fs::read_to_string(root.join("Dockerfile")).unwrap();
    let k8s = std::fs::read_to_string(root.join("deploy/kubernetes.yaml")).unwrap();
    let agones = std::fs::read_to_string(root.join("deploy/agones.yaml")).unwrap();
    assert!(agones.contains("kind: Fleet") && agones.contains("kind: GameServerAllocation"));
    let mut named = 0;
    for text in [&docker, &k8s, &agones] {
        for word in text.split(|c: char| !(c.is_ascii_alphanumeric() || c == '_')) {
            if let Some(flag) = word.strip_prefix("LOCKSTEP_") {
                assert!(
                    help.contains(&format!("env: LOCKSTEP_{flag}")),
                    "LOCKSTEP_{flag} is no flag's variable"
                );
                named += 1;
            }
        }
        // Flags on the lines that run something (not in comments).
        let code: String = text
            .lines()
            .filter(|l| !l.trim_start().starts_with('#'))
            .collect::<Vec<_>>()
            .join("\n");
        for arg in code
            .split_whitespace()
            .filter(|w| w.trim_matches(['"', '[', ',', ']']).starts_with("--"))
        {
            let flag = arg.trim_matches(['"', '[', ',', ']']);
            if flag == "---"
                || flag.starts_with("--bin")
                || flag.starts_with("--release")
                || flag.starts_with("--locked")
                || ["--system", "--uid", "--no-create-home", "--shell", "--from"]
                    .iter()
                    .any(|d| flag.starts_with(d))
            {
                continue;
            }
            assert!(
                help.contains(&format!("{flag} ")) || help.contains(&format!("{flag}\n")),
                "{flag} is not a flag"
            );
        }
    }
    assert!(named >= 8, "{named}");
    let runtime = docker.rsplit("FROM ").next().unwrap();
    assert!(runtime.contains("USER 10001"));
    assert!(runtime.contains("EXPOSE 4433/udp"));
    for bin in ["lockstep-server", "lockstep-bot", "lockstep"] {
        assert!(docker.contains(&format!("--bin {bin}")), "{bin} is built");
    }
}

/// With the replay directory and the certificate pointed at a volume, the
/// server writes nothing in its working directory (a read-only root file
/// system works).
#[test]
fn the_server_writes_only_where_it_is_told() {
    let base = std::path::PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("readonly");
    let _ = std::fs::remove_dir_all(&base);
    let (cwd, data) = (base.join("cwd"), base.join("data"));
    std::fs::create_dir_all(&cwd).unwrap();
    std::fs::create_dir_all(&data).unwrap();
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_lockstep-server"))
        .args(["--demo", "--duration", "0.5", "--bots", "2"])
        .env("LOCKSTEP_REPLAY_DIR", data.join("replays"))
        .env("LOCKSTEP_CERT_OUT", data.join("dev-cert.pem"))
        .current_dir(&cwd)
        .output()
        .unwrap();
    assert!(out.status.success(), "{out:?}");
    assert_eq!(
        std::fs::read_dir(&cwd).unwrap().count(),
        0,
        "nothing in the working directory"
    );
    assert!(data.join("dev-cert.pem").exists());
    assert_eq!(std::fs::read_dir(data.join("replays")).unwrap().count(), 1);
}
