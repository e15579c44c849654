//! A precise wake-up for the rooms' tick clocks. tokio's timer has 1 ms
//! resolution and rounds up, so a room sleeping until a tick's deadline
//! closes it 0–1.3 ms late. This thread sleeps with the OS's
//! high-resolution timer instead (a timed wait on a channel) and wakes the
//! room's task at the deadline itself.
//!
//! A room registers its next wake-up (instant and [`Notify`]); the thread
//! notifies it when that instant passes. A stale registration only causes
//! an early wake-up, which the room treats as "nothing due yet".

use std::cmp::Reverse;
use std::collections::BinaryHeap;
use std::sync::Arc;
use std::sync::mpsc::{Receiver, RecvTimeoutError, Sender, channel};
use std::time::Instant;

use tokio::sync::Notify;

/// One pending wake-up.
struct Wake {
    at: Instant,
    seq: u64,
    notify: Arc<Notify>,
}

impl PartialEq for Wake {
    fn eq(&self, o: &Self) -> bool {
        (self.at, self.seq) == (o.at, o.seq)
    }
}
impl Eq for Wake {}
impl PartialOrd for Wake {
    fn partial_cmp(&self, o: &Self) -> Option<std::cmp::Ordering> {
        Some(self.cmp(o))
    }
}
impl Ord for Wake {
    fn cmp(&self, o: &Self) -> std::cmp::Ordering {
        (self.at, self.seq).cmp(&(o.at, o.seq))
    }
}

/// The handle rooms register their wake-ups with.
#[derive(Debug)]
pub(crate) struct Clock {
    tx: std::sync::Mutex<Sender<(Instant, Arc<Notify>)>>,
}

impl Clock {
    /// Starts the clock thread; it ends when the handle is dropped.
    pub(crate) fn start() -> Clock {
        let (tx, rx) = channel();
        std::thread::Builder::new()
            .name("lockstep-clock".into())
            .spawn(move || run(rx))
            .expect("spawn the clock thread");
        Clock {
            tx: std::sync::Mutex::new(tx),
        }
    }

    /// Wakes `notify` at `at` (at once if it has passed).
    pub(crate) fn wake_at(&self, at: Instant, notify: &Arc<Notify>) {
        if let Ok(tx) = self.tx.lock() {
            let _ = tx.send((at, notify.clone()));
        }
    }
}

fn run(rx: Receiver<(Instant, Arc<Notify>)>) {
    let mut heap: BinaryHeap<Reverse<Wake>> = BinaryHeap::new();
    let mut seq = 0u64;
    loop {
        let now = Instant::now();
        while heap.peek().is_some_and(|w| w.0.at <= now) {
            if let Some(Reverse(w)) = heap.pop() {
                w.notify.notify_one();
            }
        }
        let next = match heap.peek() {
            Some(w) => rx.recv_timeout(w.0.at.saturating_duration_since(now)),
            None => rx.recv().map_err(|_| RecvTimeoutError::Disconnected),
        };
        match next {
            Ok((at, notify)) => {
                seq += 1;
                heap.push(Reverse(Wake { at, seq, notify }));
            }
            Err(RecvTimeoutError::Timeout) => {}
            Err(RecvTimeoutError::Disconnected) => return,
        }
    }
}
