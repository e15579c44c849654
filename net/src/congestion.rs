//! Congestion control for lockstep traffic: NewReno with a window floor.

use std::sync::Arc;

/// Congestion window below which the controller never throttles: 32 KiB.
///
/// Lockstep traffic is paced by the tick clock, not by the network: a
/// player's datagrams in flight stay under ~8 KiB even with full redundancy
/// at a 100 ms round trip. Loss on a game link is mostly not congestion, yet
/// NewReno halves its window on every loss event down to two packets
/// (2.4 KB), which is *less* than one round trip of bundles at 60 Hz; quinn
/// then holds datagrams back and ticks arrive late. The floor keeps the
/// per-tick traffic flowing while bulk transfers (a large welcome scene)
/// remain congestion-controlled above it.
pub const MIN_CONGESTION_WINDOW: u64 = 32 * 1024;

/// NewReno with its window never below [`MIN_CONGESTION_WINDOW`].
#[derive(Debug, Default)]
pub(crate) struct FloorFactory(quinn::congestion::NewRenoConfig);

impl quinn::congestion::ControllerFactory for FloorFactory {
    fn build(
        self: Arc<Self>,
        now: std::time::Instant,
        current_mtu: u16,
    ) -> Box<dyn quinn::congestion::Controller> {
        let inner = Arc::new(self.0.clone()).build(now, current_mtu);
        Box::new(Floor(inner))
    }
}

struct Floor(Box<dyn quinn::congestion::Controller>);

impl quinn::congestion::Controller for Floor {
    fn on_sent(&mut self, now: std::time::Instant, bytes: u64, last_packet_number: u64) {
        self.0.on_sent(now, bytes, last_packet_number);
    }

    fn on_ack(
        &mut self,
        now: std::time::Instant,
        sent: std::time::Instant,
        bytes: u64,
        app_limited: bool,
        rtt: &quinn_proto::RttEstimator,
    ) {
        self.0.on_ack(now, sent, bytes, app_limited, rtt);
    }

    fn on_end_acks(
        &mut self,
        now: std::time::Instant,
        in_flight: u64,
        app_limited: bool,
        largest_packet_num_acked: Option<u64>,
    ) {
        self.0
            .on_end_acks(now, in_flight, app_limited, largest_packet_num_acked);
    }

    fn on_congestion_event(
        &mut self,
        now: std::time::Instant,
        sent: std::time::Instant,
        is_persistent_congestion: bool,
        lost_bytes: u64,
    ) {
        self.0
            .on_congestion_event(now, sent, is_persistent_congestion, lost_bytes);
    }

    fn on_mtu_update(&mut self, new_mtu: u16) {
        self.0.on_mtu_update(new_mtu);
    }

    fn window(&self) -> u64 {
        self.0.window().max(MIN_CONGESTION_WINDOW)
    }

    fn clone_box(&self) -> Box<dyn quinn::congestion::Controller> {
        Box::new(Floor(self.0.clone_box()))
    }

    fn initial_window(&self) -> u64 {
        self.0.initial_window().max(MIN_CONGESTION_WINDOW)
    }

    fn into_any(self: Box<Self>) -> Box<dyn std::any::Any> {
        self
    }
}
