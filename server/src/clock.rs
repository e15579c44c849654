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
    /// Starts the clock thread, scheduled as `priority` asks; it ends when
    /// the handle is dropped.
    pub(crate) fn start(priority: Priority) -> std::io::Result<Clock> {
        let (tx, rx) = channel();
        std::thread::Builder::new()
            .name("lockstep-clock".into())
            .spawn(move || {
                let _ = priority.apply();
                run(rx)
            })?;
        Ok(Clock {
            tx: std::sync::Mutex::new(tx),
        })
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

/// How the clock thread and the rooms' threads ask the OS to run them.
///
/// On a busy box a ready thread can wait a whole scheduler slice (a few
/// milliseconds) behind the QUIC connection threads before it runs, and
/// that wait is the tick lateness. Two remedies:
///
/// - always (unprivileged, Linux): a timer slack of 1 ns, so the clock's
///   timed waits are not rounded up by the default 50 µs slack;
/// - with `realtime`: the `SCHED_FIFO` policy at priority [`FIFO_PRIORITY`],
///   so a tick that is due preempts the connection threads at once. This
///   needs `CAP_SYS_NICE` or a real-time priority limit (`RLIMIT_RTPRIO`)
///   of at least [`FIFO_PRIORITY`]. Without either the server logs a warning once and
///   runs at normal priority. The kernel's real-time throttling (by default
///   95 % of each second) still leaves the other threads some CPU if the
///   rooms ever spin.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(crate) struct Priority {
    /// Ask for `SCHED_FIFO`.
    pub(crate) realtime: bool,
}

/// The `SCHED_FIFO` priority of the clock and rooms' threads with
/// `--realtime-clock`: above every normal thread, below the kernel's
/// interrupt threads (50).
pub(crate) const FIFO_PRIORITY: i32 = 10;

/// Set once a refusal of real-time scheduling has been logged.
static REFUSAL_LOGGED: std::sync::atomic::AtomicBool = std::sync::atomic::AtomicBool::new(false);

impl Priority {
    /// Applies this to the calling thread; whether it now runs at
    /// real-time priority.
    fn apply(self) -> bool {
        match self.apply_here() {
            Err(e) => {
                if !REFUSAL_LOGGED.swap(true, std::sync::atomic::Ordering::Relaxed) {
                    tracing::warn!(
                        "real-time scheduling of the tick clock refused ({e}); running at \
                         normal priority (it needs CAP_SYS_NICE or an rtprio limit of 10)"
                    );
                }
                false
            }
            Ok(()) if self.realtime => {
                tracing::debug!("tick clock thread at SCHED_FIFO priority {FIFO_PRIORITY}");
                true
            }
            Ok(()) => false,
        }
    }

    #[cfg(target_os = "linux")]
    fn apply_here(self) -> std::io::Result<()> {
        // SAFETY: PR_SET_TIMERSLACK takes a plain integer and changes only
        // the calling thread's timer slack.
        unsafe { libc::prctl(libc::PR_SET_TIMERSLACK, 1 as libc::c_ulong, 0, 0, 0) };
        if self.realtime {
            let param = libc::sched_param {
                sched_priority: FIFO_PRIORITY,
            };
            // SAFETY: `param` is a valid sched_param that outlives the
            // call; pid 0 is the calling thread.
            if unsafe { libc::sched_setscheduler(0, libc::SCHED_FIFO, &param) } != 0 {
                return Err(std::io::Error::last_os_error());
            }
        }
        Ok(())
    }

    #[cfg(not(target_os = "linux"))]
    fn apply_here(self) -> std::io::Result<()> {
        if self.realtime {
            return Err(std::io::Error::other(
                "real-time scheduling is only implemented on Linux",
            ));
        }
        Ok(())
    }
}

/// The threads the rooms run on at real-time priority: single-threaded
/// tokio runtimes of their own, so a room whose tick is due preempts the
/// connection threads and runs as soon as the clock wakes it, instead of
/// waiting in the connection tasks' queue behind hundreds of QUIC drivers.
/// A room's work per tick is a few microseconds (more with `--verify`,
/// which re-simulates in the room), so one thread carries many rooms;
/// rooms are dealt to the threads in turn.
///
/// Only at real-time priority: at normal priority a thread of their own
/// made lateness worse, not better (256 players in rooms of 4: worst-room
/// p99 5–11 ms against 2.6–4.2 ms on the shared runtime), since each tick
/// then waits for that thread to get a core; the rooms then stay on the
/// server's runtime.
///
/// Single-threaded runtimes, not one work-stealing runtime: an idle
/// work-stealing worker spins a little while it looks for work, and at
/// real-time priority that spinning starves the connection threads
/// (measured: 256 players' worst-room p99 lateness went to 33 ms).
#[derive(Debug)]
pub(crate) struct RoomThreads {
    handles: Vec<tokio::runtime::Handle>,
    next: std::sync::atomic::AtomicUsize,
    stops: Vec<tokio::sync::oneshot::Sender<()>>,
}

impl RoomThreads {
    /// Starts `threads` threads (at least one) at real-time priority, or
    /// none (`None`) if `priority` does not ask for it or the OS refuses
    /// it. They end, cancelling what still runs on them, when this is
    /// dropped. Each owns its runtime, so dropping this from anywhere (even
    /// from a room task) never blocks.
    pub(crate) fn start(
        threads: usize,
        priority: Priority,
    ) -> std::io::Result<Option<RoomThreads>> {
        if !priority.realtime {
            return Ok(None);
        }
        let mut started = RoomThreads {
            handles: Vec::new(),
            next: std::sync::atomic::AtomicUsize::new(0),
            stops: Vec::new(),
        };
        for _ in 0..threads.max(1) {
            let (handle_tx, handle_rx) = channel();
            let (stop, stopped) = tokio::sync::oneshot::channel::<()>();
            std::thread::Builder::new()
                .name("lockstep-rooms".into())
                .spawn(move || {
                    if !priority.apply() {
                        let _ = handle_tx.send(Ok(None));
                        return;
                    }
                    let rt = match tokio::runtime::Builder::new_current_thread()
                        .enable_all()
                        .build()
                    {
                        Ok(rt) => rt,
                        Err(e) => {
                            let _ = handle_tx.send(Err(e));
                            return;
                        }
                    };
                    let _ = handle_tx.send(Ok(Some(rt.handle().clone())));
                    rt.block_on(async {
                        let _ = stopped.await;
                    });
                })?;
            let handle = handle_rx
                .recv()
                .map_err(|_| std::io::Error::other("a rooms' thread ended at start-up"))??;
            match handle {
                Some(handle) => {
                    started.handles.push(handle);
                    started.stops.push(stop);
                }
                // Refused: the threads started so far stop when `started`
                // drops.
                None => return Ok(None),
            }
        }
        Ok(Some(started))
    }

    /// Where the next room task is spawned.
    pub(crate) fn handle(&self) -> &tokio::runtime::Handle {
        let i = self.next.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        &self.handles[i % self.handles.len()]
    }
}

impl Drop for RoomThreads {
    fn drop(&mut self) {
        for stop in self.stops.drain(..) {
            let _ = stop.send(());
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Normal priority is always granted; real-time is either granted (the
    /// thread then runs SCHED_FIFO at FIFO_PRIORITY) or refused with the
    /// thread left as it was, never half-applied.
    #[cfg(target_os = "linux")]
    #[test]
    fn priority_is_applied_or_refused_cleanly() {
        let policy = || {
            // SAFETY: pid 0 is the calling thread; no pointers.
            unsafe { libc::sched_getscheduler(0) }
        };
        std::thread::spawn(move || {
            assert!(Priority { realtime: false }.apply_here().is_ok());
            assert_eq!(policy(), libc::SCHED_OTHER);
            match (Priority { realtime: true }).apply_here() {
                Ok(()) => {
                    assert_eq!(policy(), libc::SCHED_FIFO);
                    let mut param = libc::sched_param { sched_priority: 0 };
                    // SAFETY: `param` is a valid out-parameter.
                    assert_eq!(unsafe { libc::sched_getparam(0, &mut param) }, 0);
                    assert_eq!(param.sched_priority, FIFO_PRIORITY);
                }
                Err(e) => {
                    assert_eq!(e.kind(), std::io::ErrorKind::PermissionDenied, "{e}");
                    assert_eq!(policy(), libc::SCHED_OTHER);
                }
            }
        })
        .join()
        .unwrap();
    }

    /// Rooms get threads of their own only at real-time priority, and
    /// only when the OS grants it; a room task spawned there runs.
    #[test]
    fn room_threads_only_when_real_time_is_granted() {
        assert!(
            RoomThreads::start(2, Priority { realtime: false })
                .unwrap()
                .is_none()
        );
        let granted = std::thread::spawn(|| Priority { realtime: true }.apply_here().is_ok())
            .join()
            .unwrap();
        let threads = RoomThreads::start(2, Priority { realtime: true }).unwrap();
        assert_eq!(threads.is_some(), granted);
        if let Some(threads) = threads {
            let rt = tokio::runtime::Builder::new_current_thread()
                .enable_all()
                .build()
                .unwrap();
            for _ in 0..2 {
                let name = rt
                    .block_on(
                        threads
                            .handle()
                            .spawn(async { std::thread::current().name().map(str::to_owned) }),
                    )
                    .unwrap();
                assert_eq!(name.as_deref(), Some("lockstep-rooms"));
            }
        }
    }

    /// The clock wakes a registration at its instant, and in order, on a
    /// real-time clock thread as on a normal one.
    #[test]
    fn wakes_in_order_at_either_priority() {
        for realtime in [false, true] {
            let clock = Clock::start(Priority { realtime }).unwrap();
            let rt = tokio::runtime::Builder::new_current_thread()
                .enable_all()
                .build()
                .unwrap();
            rt.block_on(async {
                let start = Instant::now();
                let (a, b) = (Arc::new(Notify::new()), Arc::new(Notify::new()));
                clock.wake_at(start + std::time::Duration::from_millis(20), &b);
                clock.wake_at(start + std::time::Duration::from_millis(5), &a);
                a.notified().await;
                let at_a = start.elapsed();
                b.notified().await;
                let at_b = start.elapsed();
                assert!(at_a >= std::time::Duration::from_millis(5), "{at_a:?}");
                assert!(at_b >= std::time::Duration::from_millis(20), "{at_b:?}");
                assert!(at_a < at_b);
            });
        }
    }
}
