//! `lockstep-server` refuses what would mislabel a match or degrade
//! quietly: a scene its rules do not accept without another game's rules
//! id, and `--verify` or `--view` with rules it does not have. The
//! `lockstep` tool's `synctest` on the demo.

mod common;

use std::process::Command;

use common::{lockstep, scene, temp_dir};

fn server() -> Command {
    Command::new(env!("CARGO_BIN_EXE_lockstep-server"))
}

fn run(cmd: &mut Command) -> (i32, String) {
    let out = cmd.output().expect("runs");
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    (out.status.code().unwrap_or(-1), text)
}

#[test]
fn a_scene_the_demo_rules_refuse_needs_the_game_s_rules_id() {
    let dir = temp_dir("server-rules", "scene");
    let (code, text) = run(server()
        .args(["--listen", "127.0.0.1:0", "--scene"])
        .arg(scene("pyramid.toml"))
        .arg("--cert-out")
        .arg(dir.join("cert.pem")));
    assert_eq!(code, 2, "{text}");
    assert!(
        text.contains("the rules of lockstep-demo v3 refuse it"),
        "{text}"
    );
    assert!(
        text.contains("give --rules-id and --rules-version"),
        "{text}"
    );
}

#[test]
fn verify_and_view_with_rules_the_program_does_not_have_refuse_to_start() {
    let dir = temp_dir("server-rules", "verify");
    for flag in [&["--verify"][..], &["--view", "127.0.0.1:0"][..]] {
        let (code, text) = run(server()
            .args(["--listen", "127.0.0.1:0", "--scene"])
            .arg(scene("pyramid.toml"))
            .args(["--rules-id", "pyramid-game", "--rules-version", "1"])
            .args(flag)
            .arg("--cert-out")
            .arg(dir.join("cert.pem")));
        assert_eq!(code, 2, "{flag:?}: {text}");
        assert!(
            text.contains("re-simulate with this program's rules (lockstep-demo v3)"),
            "{text}"
        );
        assert!(text.contains("played with pyramid-game v1"), "{text}");
    }
}

#[test]
fn synctest_passes_on_the_demo_and_says_what_it_checked() {
    let (code, text) = run(lockstep().args(["synctest", "--ticks", "120", "--players", "3"]));
    assert_eq!(code, 0, "{text}");
    assert!(
        text.starts_with("OK: lockstep-demo v3 (demo) deterministic over 120 ticks with 3 players"),
        "{text}"
    );
    let (code, text) = run(lockstep().args(["synctest", "--scene", "/no/such.toml"]));
    assert_eq!(code, 2, "{text}");
    assert!(text.contains("/no/such.toml"), "{text}");
}
