//! The room's search for where a desync lies: probes to the reference and
//! the suspects, first for body hashes, then for the differing bodies'
//! fields; and, for the desync bundle, the reference's snapshot of the last
//! agreed tick. One search at a time; a notice raised while one runs is not
//! searched (it is still announced).

use std::time::Duration;

use crate::forensics::{
    BodyDiff, BodyDump, DesyncReport, FieldDump, Probe, ProbeAnswer, ProbeAsk, ProbeReply,
    ProbeStatus, SuspectReport,
};
use crate::forensics::{field_diffs, list_diffs};
use crate::limits::{MAX_PROBE_BODIES, MAX_REPORT_FIELDS};
use crate::message::{DesyncNotice, Slot, Verdict};

/// What the search asks the room to do.
#[derive(Debug)]
pub(crate) enum Output {
    /// Send this probe to this player.
    Probe(Slot, Probe),
    /// The search is over: announce, log and record this report.
    Report(DesyncReport),
    /// The reference's snapshot after `tick` arrived whole.
    Snapshot {
        /// Its tick (the one before the desync).
        tick: u64,
        /// The agreed hash of that tick, if the room knew it.
        agreed_hash: Option<u64>,
        /// Who sent it.
        from: Slot,
        /// The snapshot.
        bytes: Vec<u8>,
    },
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum PeerState {
    /// Waiting for a body-hash chunk.
    Hashes,
    /// Hashes complete; waiting for the next stage.
    HashesDone,
    /// Waiting for field dumps.
    Fields,
    /// Every answer came.
    Done,
    Unavailable,
    NoAnswer,
}

#[derive(Debug)]
struct Peer {
    slot: Slot,
    state: PeerState,
    total: Option<u32>,
    contacts: u64,
    game: u64,
    hashes: Vec<u64>,
    dumps: Vec<BodyDump>,
    game_fields: Vec<FieldDump>,
}

impl Peer {
    fn new(slot: Slot) -> Self {
        Self {
            slot,
            state: PeerState::Hashes,
            total: None,
            contacts: 0,
            game: 0,
            hashes: Vec::new(),
            dumps: Vec::new(),
            game_fields: Vec::new(),
        }
    }

    fn has_hashes(&self) -> bool {
        matches!(
            self.state,
            PeerState::HashesDone | PeerState::Fields | PeerState::Done
        )
    }

    fn status(&self) -> ProbeStatus {
        match self.state {
            PeerState::Unavailable => ProbeStatus::Unavailable,
            PeerState::Done | PeerState::HashesDone => ProbeStatus::Complete,
            _ => ProbeStatus::NoAnswer,
        }
    }
}

#[derive(Debug)]
struct SnapshotFetch {
    slot: Slot,
    tick: u64,
    agreed_hash: Option<u64>,
    total: Option<u32>,
    bytes: Vec<u8>,
}

#[derive(Debug)]
struct Search {
    tick: u64,
    deadline: Duration,
    majority: bool,
    /// `peers[0]` is the reference.
    peers: Vec<Peer>,
    /// The bodies whose fields were asked for, ascending.
    bodies: Vec<u32>,
    snapshot: Option<SnapshotFetch>,
}

/// One search at a time, with its deadline.
#[derive(Debug)]
pub(crate) struct Locator {
    search: Option<Search>,
    timeout: Duration,
    /// Most bodies whose hashes are pulled from one player.
    pub(crate) max_bodies: u32,
}

impl Locator {
    pub(crate) fn new(timeout: Duration) -> Self {
        Self {
            search: None,
            timeout,
            max_bodies: u32::MAX,
        }
    }

    /// When the running search gives up waiting.
    pub(crate) fn deadline(&self) -> Option<Duration> {
        self.search.as_ref().map(|s| s.deadline)
    }

    /// Starts a search for `notice` unless one runs (returns whether it
    /// started). `agreed_before` is the agreed hash of the tick before, if
    /// the room knows it: the snapshot of that tick is fetched from the
    /// reference for the desync bundle.
    pub(crate) fn start(
        &mut self,
        now: Duration,
        notice: &DesyncNotice,
        agreed_before: Option<u64>,
        out: &mut Vec<Output>,
    ) -> bool {
        if self.search.is_some() {
            return false;
        }
        let reported: Vec<(Slot, u64)> = notice
            .hashes
            .iter()
            .filter_map(|p| p.hash.map(|h| (p.slot, h)))
            .collect();
        let reference = match &notice.verdict {
            Verdict::Majority { majority_hash, .. }
            | Verdict::Verified {
                hash: majority_hash,
                ..
            } => reported.iter().find(|(_, h)| h == majority_hash).copied(),
            Verdict::Undecided => reported.first().copied(),
        };
        let Some((reference, reference_hash)) = reference else {
            return false;
        };
        let mut peers = vec![Peer::new(reference)];
        peers.extend(
            reported
                .iter()
                .filter(|(_, h)| *h != reference_hash)
                .map(|&(s, _)| Peer::new(s)),
        );
        if peers.len() < 2 {
            return false;
        }
        for p in &peers {
            out.push(Output::Probe(
                p.slot,
                Probe {
                    tick: notice.tick,
                    ask: ProbeAsk::BodyHashes { from: 0 },
                },
            ));
        }
        let snapshot = notice.tick.checked_sub(1).map(|tick| {
            out.push(Output::Probe(
                reference,
                Probe {
                    tick,
                    ask: ProbeAsk::Snapshot { offset: 0 },
                },
            ));
            SnapshotFetch {
                slot: reference,
                tick,
                agreed_hash: agreed_before,
                total: None,
                bytes: Vec::new(),
            }
        });
        self.search = Some(Search {
            tick: notice.tick,
            deadline: now.saturating_add(self.timeout),
            majority: !matches!(notice.verdict, Verdict::Undecided),
            peers,
            bodies: Vec::new(),
            snapshot,
        });
        true
    }

    /// Takes a player's answer. Answers to no running probe are ignored; an
    /// answer that does not fit what was asked ends that player's part.
    pub(crate) fn on_reply(&mut self, slot: Slot, reply: ProbeReply, out: &mut Vec<Output>) {
        let Some(s) = &mut self.search else {
            return;
        };
        if let Some(f) = &mut s.snapshot
            && f.slot == slot
            && f.tick == reply.tick
            && matches!(
                reply.answer,
                ProbeAnswer::Snapshot { .. } | ProbeAnswer::Unavailable
            )
        {
            match reply.answer {
                ProbeAnswer::Snapshot {
                    total,
                    offset,
                    bytes,
                } if f.total.is_none_or(|t| t == total)
                    && offset as usize == f.bytes.len()
                    && (!bytes.is_empty() || total == 0)
                    && f.bytes.len() + bytes.len() <= total as usize =>
                {
                    f.total = Some(total);
                    f.bytes.extend_from_slice(&bytes);
                    if f.bytes.len() == total as usize {
                        out.push(Output::Snapshot {
                            tick: f.tick,
                            agreed_hash: f.agreed_hash,
                            from: f.slot,
                            bytes: std::mem::take(&mut f.bytes),
                        });
                        s.snapshot = None;
                    } else {
                        out.push(Output::Probe(
                            slot,
                            Probe {
                                tick: f.tick,
                                ask: ProbeAsk::Snapshot {
                                    offset: f.bytes.len() as u32,
                                },
                            },
                        ));
                    }
                }
                _ => s.snapshot = None,
            }
            self.advance(out);
            return;
        }
        if reply.tick != s.tick {
            return;
        }
        let Some(p) = s.peers.iter_mut().find(|p| p.slot == slot) else {
            return;
        };
        match (p.state, reply.answer) {
            (PeerState::Hashes | PeerState::Fields, ProbeAnswer::Unavailable) => {
                p.state = PeerState::Unavailable;
            }
            (
                PeerState::Hashes,
                ProbeAnswer::BodyHashes {
                    total,
                    from,
                    contacts,
                    game,
                    hashes,
                },
            ) if p.total.is_none_or(|t| t == total)
                && total <= self.max_bodies
                && from as usize == p.hashes.len()
                && p.hashes.len() + hashes.len() <= total as usize
                && (!hashes.is_empty() || total as usize == p.hashes.len()) =>
            {
                p.total = Some(total);
                p.contacts = contacts;
                p.game = game;
                p.hashes.extend_from_slice(&hashes);
                if p.hashes.len() == total as usize {
                    p.state = PeerState::HashesDone;
                } else {
                    out.push(Output::Probe(
                        slot,
                        Probe {
                            tick: s.tick,
                            ask: ProbeAsk::BodyHashes {
                                from: p.hashes.len() as u32,
                            },
                        },
                    ));
                }
            }
            (PeerState::Fields, ProbeAnswer::Fields { bodies, game }) => {
                let asked = &s.bodies;
                let fits = bodies.windows(2).all(|w| w[0].index < w[1].index)
                    && bodies.iter().all(|b| asked.contains(&b.index));
                p.dumps = if fits { bodies } else { Vec::new() };
                p.game_fields = if fits { game } else { Vec::new() };
                p.state = if fits {
                    PeerState::Done
                } else {
                    PeerState::NoAnswer
                };
            }
            (PeerState::Hashes | PeerState::Fields, _) => p.state = PeerState::NoAnswer,
            _ => {}
        }
        self.advance(out);
    }

    /// A reply of `slot` for `tick` came over the byte budget: if it
    /// answers a running probe, that player's part of the search (or the
    /// snapshot fetch) ends, unread; otherwise it is ignored.
    pub(crate) fn reply_too_large(&mut self, slot: Slot, tick: u64, out: &mut Vec<Output>) {
        let Some(s) = &mut self.search else {
            return;
        };
        if s.snapshot
            .as_ref()
            .is_some_and(|f| f.slot == slot && f.tick == tick)
        {
            s.snapshot = None;
        } else if tick == s.tick {
            for p in s.peers.iter_mut().filter(|p| p.slot == slot) {
                if matches!(p.state, PeerState::Hashes | PeerState::Fields) {
                    p.state = PeerState::NoAnswer;
                }
            }
        }
        self.advance(out);
    }

    /// A player left: its part of the search ends.
    pub(crate) fn player_left(&mut self, slot: Slot, out: &mut Vec<Output>) {
        let Some(s) = &mut self.search else {
            return;
        };
        if s.snapshot.as_ref().is_some_and(|f| f.slot == slot) {
            s.snapshot = None;
        }
        for p in s.peers.iter_mut().filter(|p| p.slot == slot) {
            if matches!(p.state, PeerState::Hashes | PeerState::Fields) {
                p.state = PeerState::NoAnswer;
            }
        }
        self.advance(out);
    }

    /// Ends a search past its deadline with what it has.
    pub(crate) fn on_timeout(&mut self, now: Duration, out: &mut Vec<Output>) {
        let Some(s) = &mut self.search else {
            return;
        };
        if now < s.deadline {
            return;
        }
        s.snapshot = None;
        for p in &mut s.peers {
            if matches!(p.state, PeerState::Hashes | PeerState::Fields) {
                p.state = PeerState::NoAnswer;
            }
        }
        self.advance(out);
    }

    /// Moves to the field stage once every hash list is in, and reports
    /// once every dump is in.
    fn advance(&mut self, out: &mut Vec<Output>) {
        let Some(s) = &mut self.search else {
            return;
        };
        if s.peers.iter().any(|p| p.state == PeerState::Hashes) {
            return;
        }
        if s.peers.iter().any(|p| p.state == PeerState::HashesDone) {
            // Every hash list is in: pick the bodies to dump.
            let mut bodies: Vec<u32> = Vec::new();
            if s.peers[0].has_hashes() {
                let reference = &s.peers[0].hashes;
                for p in s.peers[1..].iter().filter(|p| p.has_hashes()) {
                    bodies.extend(differing(reference, &p.hashes).take(MAX_PROBE_BODIES));
                }
            }
            bodies.sort_unstable();
            bodies.dedup();
            bodies.truncate(MAX_PROBE_BODIES);
            s.bodies = bodies;
            // The game state's fields come with the bodies' (all of them:
            // they are few), asked for when any suspect's game hash differs.
            let game_differs = s.peers[0].has_hashes()
                && s.peers[1..]
                    .iter()
                    .any(|p| p.has_hashes() && p.game != s.peers[0].game);
            for p in &mut s.peers {
                if p.state == PeerState::HashesDone {
                    if s.bodies.is_empty() && !game_differs {
                        p.state = PeerState::Done;
                    } else {
                        p.state = PeerState::Fields;
                        out.push(Output::Probe(
                            p.slot,
                            Probe {
                                tick: s.tick,
                                ask: ProbeAsk::Fields {
                                    bodies: s.bodies.clone(),
                                },
                            },
                        ));
                    }
                }
            }
        }
        // The report comes last, after the snapshot arrived or failed, so
        // a bundle written on the report has its snapshot.
        if s.snapshot.is_some() || s.peers.iter().any(|p| p.state == PeerState::Fields) {
            return;
        }
        out.push(Output::Report(report(s)));
        self.search = None;
    }
}

/// Indices whose hashes differ (a body only one side has differs).
fn differing<'a>(a: &'a [u64], b: &'a [u64]) -> impl Iterator<Item = u32> + 'a {
    (0..a.len().max(b.len()))
        .filter(move |&i| a.get(i) != b.get(i))
        .map(|i| i as u32)
}

fn report(s: &Search) -> DesyncReport {
    let reference = &s.peers[0];
    let mut budget = MAX_REPORT_FIELDS;
    let mut omitted = 0u32;
    let suspects = s.peers[1..]
        .iter()
        .map(|p| {
            let both = reference.has_hashes() && p.has_hashes();
            let differ: Vec<u32> = if both {
                differing(&reference.hashes, &p.hashes).collect()
            } else {
                Vec::new()
            };
            let bodies = differ
                .iter()
                .filter(|i| s.bodies.contains(i))
                .map(|&index| {
                    let r = reference.dumps.iter().find(|b| b.index == index);
                    let g = p.dumps.iter().find(|b| b.index == index);
                    let named = r.or(g);
                    let mut fields = match (r, g) {
                        (Some(r), Some(g)) => field_diffs(r, g),
                        _ => Vec::new(),
                    };
                    if fields.len() > budget {
                        omitted += (fields.len() - budget) as u32;
                        fields.truncate(budget);
                    }
                    budget -= fields.len();
                    BodyDiff {
                        index,
                        handle: named.map_or(u32::MAX, |b| b.handle),
                        generation: named.map_or(0, |b| b.generation),
                        name: named.map(|b| b.name.clone()).unwrap_or_default(),
                        fields,
                    }
                })
                .collect();
            SuspectReport {
                slot: p.slot,
                status: p.status(),
                bodies_differing: differ.len() as u32,
                contacts_differ: both && reference.contacts != p.contacts,
                game_differs: both && reference.game != p.game,
                game: if both && reference.game != p.game {
                    let mut fields = list_diffs(&reference.game_fields, &p.game_fields);
                    if fields.len() > budget {
                        omitted += (fields.len() - budget) as u32;
                        fields.truncate(budget);
                    }
                    budget -= fields.len();
                    fields
                } else {
                    Vec::new()
                },
                bodies,
            }
        })
        .collect();
    DesyncReport {
        tick: s.tick,
        reference: reference.slot,
        majority: s.majority,
        reference_status: reference.status(),
        suspects,
        fields_omitted: omitted,
        inputs: Vec::new(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::forensics::FieldKind;
    use crate::message::PlayerHash;

    fn field(name: &str, w: u64) -> FieldDump {
        FieldDump {
            name: name.into(),
            kind: FieldKind::Int,
            words: vec![w],
        }
    }

    /// A suspect that claims more bodies than the bound is not asked for
    /// the rest of its hashes: its part ends unread (no answer), and the
    /// reference's part goes on.
    #[test]
    fn a_claim_of_more_bodies_than_the_bound_is_not_pulled() {
        let mut l = Locator::new(Duration::from_secs(5));
        l.max_bodies = 100;
        let mut out = Vec::new();
        let notice = DesyncNotice {
            tick: 10,
            hashes: (0..2u8)
                .map(|s| PlayerHash {
                    slot: Slot(s),
                    hash: Some(u64::from(s)),
                })
                .collect(),
            verdict: Verdict::Undecided,
        };
        assert!(l.start(Duration::ZERO, &notice, None, &mut out));
        out.clear();
        let liar = ProbeReply {
            tick: 10,
            answer: ProbeAnswer::BodyHashes {
                total: 1 << 20,
                from: 0,
                contacts: 1,
                game: 1,
                hashes: vec![3; 4096],
            },
        };
        l.on_reply(Slot(1), liar, &mut out);
        assert!(
            !out.iter().any(|o| matches!(o, Output::Probe(Slot(1), _))),
            "the liar is not asked for more"
        );
        let s = l.search.as_ref().expect("the search goes on");
        assert_eq!(s.peers[1].state, PeerState::NoAnswer);
        assert!(s.peers[1].hashes.is_empty());
    }

    /// A reply over the byte budget to a running probe ends its sender's
    /// part unread; the snapshot fetch from the reference likewise; a
    /// reply for another tick changes nothing.
    #[test]
    fn a_reply_over_the_byte_budget_ends_its_sender_s_part() {
        let mut l = Locator::new(Duration::from_secs(5));
        let mut out = Vec::new();
        let notice = DesyncNotice {
            tick: 10,
            hashes: (0..3u8)
                .map(|s| PlayerHash {
                    slot: Slot(s),
                    hash: Some(if s == 0 { 7 } else { u64::from(s) }),
                })
                .collect(),
            verdict: Verdict::Verified {
                hash: 7,
                wrong: vec![Slot(1), Slot(2)],
            },
        };
        assert!(l.start(Duration::ZERO, &notice, Some(5), &mut out));
        out.clear();
        l.reply_too_large(Slot(1), 99, &mut out);
        assert_eq!(l.search.as_ref().unwrap().peers[1].state, PeerState::Hashes);
        l.reply_too_large(Slot(1), 10, &mut out);
        let s = l.search.as_ref().unwrap();
        assert_eq!(s.peers[1].state, PeerState::NoAnswer);
        assert_eq!(s.peers[2].state, PeerState::Hashes);
        assert!(s.snapshot.is_some());
        // The reference's snapshot of tick 9, over the budget.
        l.reply_too_large(Slot(0), 9, &mut out);
        let s = l.search.as_ref().unwrap();
        assert!(s.snapshot.is_none());
        assert_eq!(s.peers[0].state, PeerState::Hashes);
        assert!(out.is_empty(), "{out:?}");
    }

    /// Two players whose bodies agree and whose game states differ in one
    /// field: the room asks for the fields (with no body) and the report
    /// names the game-state field.
    #[test]
    fn a_game_state_difference_is_located_to_its_field() {
        let mut l = Locator::new(Duration::from_secs(5));
        let mut out = Vec::new();
        let notice = DesyncNotice {
            tick: 10,
            hashes: (0..3u8)
                .map(|s| PlayerHash {
                    slot: Slot(s),
                    hash: Some(if s == 2 { 9 } else { 7 }),
                })
                .collect(),
            verdict: Verdict::Majority {
                majority_hash: 7,
                wrong: vec![Slot(2)],
            },
        };
        assert!(l.start(Duration::ZERO, &notice, None, &mut out));
        out.clear();
        for (s, game) in [(0u8, 5u64), (2, 6)] {
            let reply = ProbeReply {
                tick: 10,
                answer: ProbeAnswer::BodyHashes {
                    total: 2,
                    from: 0,
                    contacts: 1,
                    game,
                    hashes: vec![3, 4],
                },
            };
            l.on_reply(Slot(s), reply, &mut out);
        }
        let asked: Vec<_> = out
            .drain(..)
            .filter_map(|o| match o {
                Output::Probe(s, p) => Some((s, p.ask)),
                _ => None,
            })
            .collect();
        assert_eq!(
            asked,
            [
                (Slot(0), ProbeAsk::Fields { bodies: vec![] }),
                (Slot(2), ProbeAsk::Fields { bodies: vec![] })
            ]
        );
        for (s, score) in [(0u8, 3), (2, 4)] {
            let reply = ProbeReply {
                tick: 10,
                answer: ProbeAnswer::Fields {
                    bodies: vec![],
                    game: vec![field("round", 1), field("score", score)],
                },
            };
            l.on_reply(Slot(s), reply, &mut out);
        }
        // The bundle's snapshot of tick 9 is not available: the report
        // comes without it.
        let unavailable = ProbeReply {
            tick: 9,
            answer: ProbeAnswer::Unavailable,
        };
        l.on_reply(Slot(0), unavailable, &mut out);
        let Some(Output::Report(r)) = out.pop() else {
            panic!("no report: {out:?}");
        };
        let s = &r.suspects[0];
        assert_eq!(s.slot, Slot(2));
        assert!(s.game_differs && !s.contacts_differ);
        assert_eq!(s.bodies_differing, 0);
        assert_eq!(s.game.len(), 1);
        assert_eq!(
            (
                s.game[0].name.as_str(),
                &s.game[0].expected[..],
                &s.game[0].got[..]
            ),
            ("score", &[3][..], &[4][..])
        );
        let text = r.to_string();
        assert!(
            text.contains("slot 2 (Complete): 0 bodies differ, the game state differs"),
            "{text}"
        );
        assert!(text.contains("game state score:"), "{text}");
    }
}
