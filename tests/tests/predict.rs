//! Prediction and rollback end to end: bots that predict, with no input
//! delay felt, through a 100 ± 20 ms round trip with 5% loss, play 1,200
//! ticks of the demo and of the example game. The confirmed path is
//! unchanged: every confirmed tick's hash agrees and the replay
//! re-verifies. Beside it each bot ran ahead of the confirmed ticks and
//! rolled back when a confirmed tick differed from its prediction; every
//! predicted tick whose inputs the server confirmed hashed exactly as the
//! confirmed tick did (the state after rolling back and re-simulating is
//! the state of a client that never predicted).

use std::path::PathBuf;
use std::sync::Arc;
use std::time::Duration;

use lockstep_client::bot::{BotOptions, run_bots};
use lockstep_client::game::{Demo, RulesFactory};
use lockstep_tests::harness::{TestServer, assert_same_hashes, bots_ok};
use lockstep_tests::link::{LinkConditioner, LinkConfig};
use lockstep_tools::verify_replay_file;

const TICKS: usize = 1200;

async fn predicting_match(
    name: &str,
    game: Arc<dyn RulesFactory>,
    scene: &'static str,
    bots: usize,
) {
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(format!("predict-{name}"));
    let rules = game.rules_id();
    let mut server = TestServer::start(dir, |c| {
        c.scene = scene.into();
        c.rules = rules;
        c.room.start_players = bots as u8;
        c.room.match_ticks = Some(TICKS as u64);
        c.room.input_delay = 0;
    })
    .await;
    let link = LinkConditioner::start(
        server.addr,
        LinkConfig {
            latency: Duration::from_millis(50),
            jitter: Duration::from_millis(10),
            loss: 0.05,
            duplicate: 0.0,
            reorder: 0.0,
            seed: 0x9e3d,
        },
    )
    .await
    .expect("link conditioner");
    let mut options =
        BotOptions::for_game(link.local_addr(), &server.cert, name, bots, game.clone());
    options.predict = true;
    let bots_task = tokio::spawn(async move { run_bots(&options, std::future::pending()).await });
    let reports = bots_ok(bots_task.await.expect("bots"));
    let ended = server.match_end(Duration::from_secs(10)).await;
    link.stop().await;
    server.shutdown().await;
    assert_same_hashes(&reports, TICKS);
    assert!(ended.desyncs.is_empty(), "{:?}", ended.desyncs);
    assert_eq!(ended.mismatched_ticks, 0);
    for b in &reports {
        let (p, l) = (b.prediction, b.input_latency);
        println!(
            "{name} slot {}: {} rollbacks (deepest {}, {} predicted ticks thrown away), {} ticks simulated ahead, \
             {} predictions confirmed bit for bit; input to effect {:.1} ms predicted, {:.1} ms confirmed",
            b.slot.0,
            p.rollbacks,
            p.max_depth,
            p.discarded,
            p.simulated,
            p.confirmed_right,
            l.predicted.mean().as_secs_f64() * 1e3,
            l.confirmed.mean().as_secs_f64() * 1e3,
        );
        assert!(p.rollbacks > 0, "slot {}: {p:?}", b.slot.0);
        assert_eq!(p.state_wrong, 0, "slot {}: {p:?}", b.slot.0);
        assert!(
            p.confirmed_right > TICKS as u64 / 2,
            "slot {}: {p:?}",
            b.slot.0
        );
        // The predicted world shows an input long before the confirmed
        // one can: at least a round trip sooner.
        assert!(l.predicted.count > 0 && l.confirmed.count > 0);
        assert!(
            l.predicted.mean() + Duration::from_millis(90) < l.confirmed.mean(),
            "slot {}: {l:?}",
            b.slot.0
        );
    }
    let check =
        verify_replay_file(ended.replay.as_ref().unwrap(), &*game).expect("replay verifies");
    assert_eq!((check.ticks, check.checked), (TICKS as u64, TICKS as u64));
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn predicting_demo_bots_at_no_input_delay_roll_back_and_agree_over_a_bad_link() {
    predicting_match(
        "demo",
        Arc::new(Demo),
        lockstep_client::game::DemoGame::SCENE,
        4,
    )
    .await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn predicting_example_game_bots_roll_back_and_agree_over_a_bad_link() {
    predicting_match(
        "table",
        Arc::new(lockstep_example_game::PaddleGame),
        lockstep_example_game::SCENE,
        4,
    )
    .await;
}
