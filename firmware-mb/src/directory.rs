//! Plug and play on the motherboard (`docs/protocol.md`, "Addresses over the bus"): which
//! boards are known by their unique ID, where they are, whether they answer, which address an
//! unaddressed board is given, and which collisions were seen. Pure bookkeeping (no waiting,
//! no I/O): the routing feeds it `boot` and `announce` events, the dispatcher takes its work
//! (an `assign` to send, the next address of the start-up sweep) and reports boards that
//! stopped answering.
//!
//! The entries live in storage the image gives ([`crate::Motherboard::with_directory`]): a
//! motherboard without one knows no board by its ID, answers no announce and sweeps nothing
//! (so a motherboard with little RAM, like the Cortex-M0 test suite's, pays nothing for it).

use x10_hal::time::Instant;
use x10_microcode::{Address, BoardKind, BootInfo, Identity, Op, Uid};

use crate::config::{PinBy, PinnedAddress};

/// Two different IDs heard from one address within this many µs (1 s) are a collision: two
/// boards answer there (see [`Directory::seen`]).
pub const COLLISION_WINDOW_US: u64 = 1_000_000;

/// What the motherboard knows of one board (an entry of [`crate::X10::boards`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct KnownBoard {
    /// Its unique ID.
    pub uid: Uid,
    /// Where it is (or was last).
    pub address: Address,
    /// Its kind, from its `boot` or `announce` event.
    pub kind: BoardKind,
    /// Sensor ports.
    pub sensor_ports: u8,
    /// Actuator ports.
    pub actuator_ports: u8,
    /// Firmware version: major, minor, patch.
    pub firmware: [u8; 3],
    /// It answered last time: false once a request to it went unanswered (NACK), true again
    /// at its next `boot` or `announce`.
    pub present: bool,
    /// Another board announced itself from the same address (see [`Directory::seen`]).
    pub collided: bool,
    /// The motherboard gave it its address and has yet to send the `assign`.
    assign_pending: bool,
    /// When it was last heard (µs since start).
    seen_us: u64,
}

impl KnownBoard {
    /// An unused entry (what the storage given to [`crate::Motherboard::with_directory`] is
    /// filled with).
    pub const EMPTY: KnownBoard = KnownBoard {
        uid: Uid([0; Uid::LEN]),
        address: Address::UNADDRESSED,
        kind: BoardKind::UNKNOWN,
        sensor_ports: 0,
        actuator_ports: 0,
        firmware: [0; 3],
        present: false,
        collided: false,
        assign_pending: false,
        seen_us: 0,
    };

    fn from_boot(address: Address, info: &BootInfo, uid: Uid, now: Instant) -> KnownBoard {
        KnownBoard {
            uid,
            address,
            kind: info.identity.board,
            sensor_ports: info.identity.sensor_ports,
            actuator_ports: info.identity.actuator_ports,
            firmware: info.identity.firmware,
            present: true,
            collided: false,
            assign_pending: false,
            seen_us: now.0,
        }
    }
}

/// How a robot program names the board it waits for ([`crate::X10::wait_for_board`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum BoardQuery {
    /// The board at this address.
    Address(Address),
    /// A board of this kind (the first known).
    Kind(BoardKind),
    /// The board with this ID.
    Uid(Uid),
}

impl BoardQuery {
    fn matches(&self, b: &KnownBoard) -> bool {
        match *self {
            BoardQuery::Address(a) => b.address == a,
            BoardQuery::Kind(k) => b.kind == k,
            BoardQuery::Uid(u) => b.uid == u,
        }
    }
}

/// What the motherboard does after an event (see [`Directory::seen`] and
/// [`Directory::announced`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Heard {
    /// A board it did not know.
    New,
    /// A board it knew.
    Known,
    /// A second ID from an address another board announced from within
    /// [`COLLISION_WINDOW_US`]: the two are not merged, both are marked `collided`.
    Collision,
    /// An unaddressed board that is given `address` (an `assign` is now pending); `new` when
    /// its ID was not known before.
    Assign {
        /// Its address.
        address: Address,
        /// First heard now.
        new: bool,
    },
    /// An unaddressed board for which no address is free, or no entry: dropped.
    NoRoom,
}

/// Why [`crate::X10::assign`] did not give a board the address asked for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum AssignError {
    /// The motherboard knows no board with that unique ID.
    UnknownUid,
    /// The address is not one a board may take: outside `0x08..=0x76`, the motherboard's own,
    /// or `0x64` (where an STM32 ROM bootloader answers during an update).
    Reserved,
    /// Another board is there (known by its ID, present or being assigned; known without an
    /// ID), or the address is pinned to another board (`MbConfig::pinned`).
    Taken,
    /// The board shares its address with another board (a collision): `set_address` there
    /// would move both, and `assign` reaches only unaddressed boards.
    Collided,
    /// The board did not confirm: its `set_address` failed (the error), or it was not heard
    /// from the new address in time (`Timeout`).
    NotConfirmed(x10_devices::LinkError),
}

/// How [`crate::X10::assign`] reaches the board (from [`Directory::assign_plan`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum AssignPlan {
    /// It is there already: nothing to send.
    Already,
    /// It answers at this address: `set_address` to it.
    SetAddress(Address),
    /// It does not answer at an address (unaddressed, its `assign` pending or lost; or gone):
    /// an `assign` with its ID, written to `0x77`.
    Assign,
}

/// The boards known by their ID, in the image's storage.
pub(crate) struct Directory {
    entries: &'static mut [KnownBoard],
    len: usize,
    /// The next address the start-up sweep probes (`who_is_there`); `None` when done.
    sweep: Option<u8>,
    /// No board that stopped answering is asked again before this (µs since start).
    recheck_after: u64,
    /// Where the round of those boards goes on.
    recheck_next: usize,
}

/// How often a board that stopped answering ([`Directory::lost`]) is asked `who_is_there`
/// again: one such board per second, in turn. Its `announce` makes it present again.
pub const RECHECK_US: u64 = 1_000_000;

impl Directory {
    /// No storage: nothing is known, nothing is swept.
    pub(crate) const fn new() -> Directory {
        Directory {
            entries: &mut [],
            len: 0,
            sweep: None,
            recheck_after: 0,
            recheck_next: 0,
        }
    }

    /// Takes `entries` as storage (their contents are ignored) and starts the sweep (when
    /// there is room for at least one board).
    pub(crate) fn set_storage(&mut self, entries: &'static mut [KnownBoard]) {
        self.sweep = (!entries.is_empty()).then_some(Address::MIN_EXTERNAL);
        self.entries = entries;
        self.len = 0;
    }

    pub(crate) fn known(&self) -> &[KnownBoard] {
        self.entries.get(..self.len).unwrap_or(&[])
    }

    fn known_mut(&mut self) -> &mut [KnownBoard] {
        self.entries.get_mut(..self.len).unwrap_or(&mut [])
    }

    /// The entry of `uid`, adding one if there is room.
    fn entry(&mut self, uid: Uid) -> Option<&mut KnownBoard> {
        let i = match self.known().iter().position(|b| b.uid == uid) {
            Some(i) => i,
            None => {
                let i = self.len;
                *self.entries.get_mut(i)? = KnownBoard::EMPTY;
                self.len += 1;
                i
            }
        };
        self.entries.get_mut(i)
    }

    /// The first known board that `q` names, present or not.
    pub(crate) fn find(&self, q: BoardQuery) -> Option<KnownBoard> {
        self.known().iter().find(|b| q.matches(b)).copied()
    }

    /// A `boot` event or an `announce` from `source` (an address, not
    /// [`Address::UNADDRESSED`]) carrying `info` with an ID. The board is recorded there,
    /// present. If another ID was heard from `source` within [`COLLISION_WINDOW_US`] and its
    /// board is still taken to be there, both are marked `collided` and the answer is
    /// [`Heard::Collision`].
    pub(crate) fn seen(&mut self, source: Address, info: &BootInfo, now: Instant) -> Heard {
        let Some(uid) = info.uid else {
            return Heard::Known;
        };
        let clash = self.known_mut().iter_mut().find(|b| {
            b.uid != uid
                && b.address == source
                && b.present
                && now.0.saturating_sub(b.seen_us) < COLLISION_WINDOW_US
        });
        let collided = clash.is_some();
        if let Some(other) = clash {
            other.collided = true;
        }
        let new = !self.known().iter().any(|b| b.uid == uid);
        let Some(e) = self.entry(uid) else {
            return if collided {
                Heard::Collision
            } else {
                Heard::NoRoom
            };
        };
        let was_collided = e.collided && e.address == source;
        *e = KnownBoard {
            collided: collided || was_collided,
            ..KnownBoard::from_boot(source, info, uid, now)
        };
        if collided {
            Heard::Collision
        } else if new {
            Heard::New
        } else {
            Heard::Known
        }
    }

    /// An `announce` from an unaddressed board: an address is chosen ([`choose_address`]),
    /// kept for its ID, and an `assign` is pending until [`Directory::take_assign`].
    /// `in_use` says whether an address is taken by a board known otherwise (its port counts
    /// were learnt without an ID).
    pub(crate) fn announced(
        &mut self,
        info: &BootInfo,
        pinned: &[PinnedAddress],
        mb: Address,
        in_use: impl Fn(Address) -> bool,
        now: Instant,
    ) -> Heard {
        let Some(uid) = info.uid else {
            return Heard::NoRoom;
        };
        let Some(address) =
            choose_address(uid, info.identity.board, self.known(), pinned, mb, in_use)
        else {
            return Heard::NoRoom;
        };
        let new = !self.known().iter().any(|b| b.uid == uid);
        let Some(e) = self.entry(uid) else {
            return Heard::NoRoom;
        };
        *e = KnownBoard {
            present: false,
            assign_pending: true,
            ..KnownBoard::from_boot(address, info, uid, now)
        };
        Heard::Assign { address, new }
    }

    /// The next `assign` to send: (ID, address). It stays pending until the board's `boot`
    /// event from its new address arrives (an `assign` lost on the way is sent again at the
    /// board's next announce).
    pub(crate) fn take_assign(&mut self) -> Option<(Uid, Address)> {
        let e = self.known_mut().iter_mut().find(|b| b.assign_pending)?;
        e.assign_pending = false;
        Some((e.uid, e.address))
    }

    /// Work taken by [`Directory::take_assign`] or [`Directory::next_sweep`] that could not go
    /// out (its write lost arbitration): it is taken again next.
    pub(crate) fn put_back(&mut self, op: &Op<'_>) {
        match *op {
            Op::Assign { uid, .. } => {
                if let Some(e) = self.known_mut().iter_mut().find(|b| b.uid == uid) {
                    e.assign_pending = true;
                }
            }
            Op::WhoIsThere => {
                self.sweep = self
                    .sweep
                    .map_or(Some(Address::UNADDRESSED.get() - 1), |a| {
                        Some(a.saturating_sub(1))
                    });
            }
            _ => {}
        }
    }

    /// The next address for the start-up sweep, once each.
    pub(crate) fn next_sweep(&mut self, mb: Address) -> Option<Address> {
        loop {
            let a = self.sweep?;
            self.sweep = (a < Address::UNADDRESSED.get() - 1).then_some(a + 1);
            if a != mb.get() && a != Address::STM32_BOOTLOADER {
                return Address::assignable(a).ok();
            }
        }
    }

    /// The address of the next board that stopped answering to ask `who_is_there` again,
    /// when [`RECHECK_US`] have passed since the last one asked; one at a time, in turn. A
    /// board whose address another board present is known at is not asked (that one would
    /// answer).
    pub(crate) fn next_recheck(&mut self, now: Instant) -> Option<Address> {
        if now.0 < self.recheck_after {
            return None;
        }
        let known = self.known();
        let n = known.len();
        let lost = (0..n)
            .map(|k| (self.recheck_next + k) % n.max(1))
            .find(|&i| {
                known.get(i).is_some_and(|b| {
                    !b.present
                        && !b.collided
                        && !b.address.is_internal()
                        && !b.address.is_unaddressed()
                        && !known.iter().any(|o| o.present && o.address == b.address)
                })
            })?;
        let address = known.get(lost)?.address;
        self.recheck_next = lost + 1;
        self.recheck_after = now.0.saturating_add(RECHECK_US);
        Some(address)
    }

    /// When [`Directory::next_recheck`] may have work: `None` while every known board is
    /// present.
    pub(crate) fn recheck_at(&self) -> Option<Instant> {
        self.known()
            .iter()
            .any(|b| {
                !b.present && !b.collided && !b.address.is_internal() && !b.address.is_unaddressed()
            })
            .then_some(Instant(self.recheck_after))
    }

    /// A request to `address` went unanswered: a board known there is no longer present.
    /// True when one was (the caller counts and logs it).
    pub(crate) fn lost(&mut self, address: Address) -> bool {
        let mut any = false;
        for b in self.known_mut().iter_mut() {
            if b.address == address && b.present {
                b.present = false;
                any = true;
            }
        }
        any
    }

    /// A reply with the right sequence number came from `address`: the one board known there
    /// (its entry alone at that address, not `collided`) is present again, after a request
    /// to it went unanswered ([`Directory::lost`]: a loose contact, a burst of noise) or
    /// after it moved there. True when it was not present before.
    pub(crate) fn answered(&mut self, address: Address) -> bool {
        let mut there = self.known_mut().iter_mut().filter(|b| b.address == address);
        match (there.next(), there.next()) {
            (Some(b), None) if !b.present && !b.collided => {
                b.present = true;
                true
            }
            _ => false,
        }
    }

    /// `identify` answered from `address`: the one board present there (not `collided`)
    /// runs what it says. Its `boot` event says the same, unless that event was lost: after
    /// an update the new version is then known all the same, and the board is not updated
    /// again.
    pub(crate) fn identified(&mut self, address: Address, id: &Identity) {
        let mut there = self
            .known_mut()
            .iter_mut()
            .filter(|b| b.address == address && b.present && !b.collided);
        if let (Some(b), None) = (there.next(), there.next()) {
            b.kind = id.board;
            b.firmware = id.firmware;
            b.sensor_ports = id.sensor_ports;
            b.actuator_ports = id.actuator_ports;
        }
    }

    /// Whether the board `uid` may be given `to`, and how (the laptop's assign, issue 26): `to`
    /// must be assignable, not `mb`'s, not `0x64`; free as [`choose_address`] counts it (no
    /// other board known there present or being assigned, not pinned to another board, not
    /// `in_use`); the board not in a collision. Pure: nothing changes.
    pub(crate) fn assign_plan(
        &self,
        uid: Uid,
        to: Address,
        mb: Address,
        pinned: &[PinnedAddress],
        in_use: impl Fn(Address) -> bool,
    ) -> Result<AssignPlan, AssignError> {
        let raw = to.get();
        if Address::assignable(raw).is_err() || to == mb || raw == Address::STM32_BOOTLOADER {
            return Err(AssignError::Reserved);
        }
        let b = self
            .known()
            .iter()
            .find(|b| b.uid == uid)
            .ok_or(AssignError::UnknownUid)?;
        if b.collided {
            return Err(AssignError::Collided);
        }
        if b.address == to && b.present {
            return Ok(AssignPlan::Already);
        }
        let other_there = self
            .known()
            .iter()
            .any(|o| o.uid != uid && o.address == to && (o.present || o.assign_pending));
        let pinned_to_other = pinned
            .iter()
            .any(|p| p.address == to && p.by != PinBy::Uid(uid));
        if other_there || pinned_to_other || (b.address != to && in_use(to)) {
            return Err(AssignError::Taken);
        }
        Ok(if b.present {
            AssignPlan::SetAddress(b.address)
        } else {
            AssignPlan::Assign
        })
    }

    /// The board `uid` is to take `to` from an `assign` (the laptop's, through
    /// [`Directory::assign_plan`]): it is recorded there, not present, its `assign` pending
    /// (sent by the dispatcher, again at its next announce until its `boot` comes from `to`).
    pub(crate) fn reassign(&mut self, uid: Uid, to: Address) {
        if let Some(b) = self.known_mut().iter_mut().find(|b| b.uid == uid) {
            b.address = to;
            b.present = false;
            b.assign_pending = true;
        }
    }

    /// The board at `from` confirmed `set_address(to)`: it is at `to` once its `boot`
    /// arrives from there.
    pub(crate) fn moved(&mut self, from: Address, to: Address) {
        for b in self.known_mut().iter_mut() {
            if b.address == from {
                b.address = to;
                b.present = false;
                b.collided = false;
            }
        }
    }
}

/// The address an unaddressed board with ID `uid` and kind `kind` gets, first match wins:
///
/// 1. an address pinned to its ID;
/// 2. an address pinned to its kind, when no other board of that kind is known;
/// 3. the address the motherboard gave this ID before (while no other board is present
///    there);
/// 4. the first free address from `0x08 + uid.hash32() % 111` upwards (wrapping), where free
///    means: not the motherboard's, not pinned to anyone, no other known board there, and not
///    `in_use` (a board the motherboard knows without an ID).
///
/// `None` when every address is taken.
pub fn choose_address(
    uid: Uid,
    kind: BoardKind,
    known: &[KnownBoard],
    pinned: &[PinnedAddress],
    mb: Address,
    in_use: impl Fn(Address) -> bool,
) -> Option<Address> {
    let others = || known.iter().filter(move |b| b.uid != uid);
    if let Some(p) = pinned.iter().find(|p| p.by == PinBy::Uid(uid)) {
        return Some(p.address);
    }
    let kind_alone = !others().any(|b| b.kind == kind);
    if let Some(p) = pinned.iter().find(|p| p.by == PinBy::Kind(kind)) {
        if kind_alone {
            return Some(p.address);
        }
    }
    let taken_by_id = |a: Address| {
        a == mb
            || pinned.iter().any(|p| p.address == a)
            || others().any(|b| b.address == a && (b.present || b.assign_pending))
    };
    let taken = |a: Address| taken_by_id(a) || in_use(a);
    // Its address from before, even though the motherboard still knows a board there (its
    // port counts): that board was this one (it restarted unaddressed, e.g. after a power cut
    // that cleared a record kept in RAM).
    if let Some(before) = known.iter().find(|b| b.uid == uid) {
        if Address::assignable(before.address.get()).is_ok() && !taken_by_id(before.address) {
            return Some(before.address);
        }
    }
    let span = u32::from(Address::UNADDRESSED.get() - Address::MIN_EXTERNAL);
    let start = uid.hash32() % span;
    (0..span)
        .map(|k| (start + k) % span + u32::from(Address::MIN_EXTERNAL))
        .filter_map(|raw| u8::try_from(raw).ok())
        .filter(|&raw| raw != Address::STM32_BOOTLOADER)
        .filter_map(|raw| Address::assignable(raw).ok())
        .find(|&a| !taken(a))
}

#[cfg(test)]
mod tests {
    extern crate std;
    use std::boxed::Box;
    use std::vec;
    use std::vec::Vec;

    use super::*;
    use x10_microcode::{Capabilities, Identity, ResetReason};

    fn a(raw: u8) -> Address {
        Address::new(raw).unwrap()
    }

    fn uid(n: u8) -> Uid {
        Uid([n, 1, 2, 3, 4, 5, 6, 7])
    }

    fn info(u: Uid, kind: BoardKind) -> BootInfo {
        BootInfo {
            identity: Identity {
                protocol_version: 1,
                firmware: [0, 1, 0],
                board: kind,
                sensor_ports: 4,
                actuator_ports: 2,
                capabilities: Capabilities(0),
                adc_bits: 12,
            },
            reset_reason: ResetReason::PowerOn,
            uid: Some(u),
        }
    }

    fn dir(n: usize) -> Directory {
        let mut d = Directory::new();
        d.set_storage(Box::leak(vec![KnownBoard::EMPTY; n].into_boxed_slice()));
        d
    }

    const MB: u8 = 0x08;

    fn hashed(u: Uid) -> u8 {
        0x08 + (u.hash32() % 111) as u8
    }

    #[test]
    fn a_board_lost_then_answering_is_present_again_unless_another_is_known_there() {
        let mut d = dir(4);
        let now = Instant(0);
        d.seen(a(0x20), &info(uid(1), BoardKind::PICO), now);
        assert!(d.lost(a(0x20)));
        assert!(!d.find(BoardQuery::Uid(uid(1))).unwrap().present);
        assert!(d.answered(a(0x20)));
        assert!(d.find(BoardQuery::Uid(uid(1))).unwrap().present);
        assert!(!d.answered(a(0x20)), "present already");
        // Two entries at one address: which one answered is not known.
        d.seen(a(0x20), &info(uid(2), BoardKind::PICO), now);
        d.lost(a(0x20));
        assert!(!d.answered(a(0x20)));
        assert!(d.known().iter().all(|b| !b.present));
    }

    #[test]
    fn boards_that_stopped_answering_are_asked_again_one_per_second_in_turn() {
        let mut d = dir(4);
        let t0 = Instant(5_000_000);
        for (n, at) in [(1, 0x20), (2, 0x21), (3, 0x22)] {
            d.seen(a(at), &info(uid(n), BoardKind::PICO), t0);
        }
        assert_eq!(d.recheck_at(), None, "every board present");
        assert_eq!(d.next_recheck(t0), None);
        d.lost(a(0x20));
        d.lost(a(0x22));
        assert_eq!(d.recheck_at(), Some(Instant(0)));
        assert_eq!(d.next_recheck(t0), Some(a(0x20)));
        assert_eq!(d.recheck_at(), Some(Instant(t0.0 + RECHECK_US)));
        assert_eq!(d.next_recheck(Instant(t0.0 + RECHECK_US - 1)), None);
        assert_eq!(d.next_recheck(Instant(t0.0 + RECHECK_US)), Some(a(0x22)));
        assert_eq!(
            d.next_recheck(Instant(t0.0 + 2 * RECHECK_US)),
            Some(a(0x20))
        );
        // 0x22 answered (its announce): only 0x20 is left.
        d.seen(a(0x22), &info(uid(3), BoardKind::PICO), t0);
        assert_eq!(
            d.next_recheck(Instant(t0.0 + 3 * RECHECK_US)),
            Some(a(0x20))
        );
        // Another board is known present at 0x20 now: it would answer, 0x20 is not asked.
        d.seen(
            a(0x20),
            &info(uid(4), BoardKind::PICO),
            Instant(t0.0 + 4 * COLLISION_WINDOW_US),
        );
        assert_eq!(d.next_recheck(Instant(t0.0 + 9 * RECHECK_US)), None);
    }

    #[test]
    fn identify_updates_the_one_board_present_there_and_no_collided_one() {
        let mut d = dir(4);
        let now = Instant(0);
        d.seen(a(0x20), &info(uid(1), BoardKind::PICO), now);
        let mut newer = info(uid(1), BoardKind::PICO).identity;
        newer.firmware = [0, 2, 0];
        newer.sensor_ports = 3;
        d.identified(a(0x20), &newer);
        let b = d.find(BoardQuery::Uid(uid(1))).unwrap();
        assert_eq!(
            (b.firmware, b.sensor_ports, b.actuator_ports),
            ([0, 2, 0], 3, 2)
        );
        // Nobody known at 0x21: nothing changes.
        d.identified(a(0x21), &info(uid(9), BoardKind::G431).identity);
        assert_eq!(d.known().len(), 1);
        // Two IDs from one address (collided): which one answered is not known.
        d.seen(a(0x20), &info(uid(2), BoardKind::PICO), now);
        d.identified(a(0x20), &info(uid(3), BoardKind::G431).identity);
        assert!(d.known().iter().all(|b| b.kind == BoardKind::PICO));
    }

    #[test]
    fn the_first_free_address_from_the_hash_skipping_what_is_taken() {
        let u = uid(1);
        let h = hashed(u);
        assert_ne!(h, MB);
        let none = |_: Address| false;
        assert_eq!(
            choose_address(u, BoardKind::PICO, &[], &[], a(MB), none),
            Some(a(h))
        );
        // Taken by a board known without an ID, by a present board, or pinned: the next.
        let taken_by_old = |x: Address| x == a(h);
        assert_eq!(
            choose_address(u, BoardKind::PICO, &[], &[], a(MB), taken_by_old),
            Some(a(if h == 0x76 { 0x09 } else { h + 1 }))
        );
        let pinned = [PinnedAddress {
            by: PinBy::Uid(uid(9)),
            address: a(h),
        }];
        assert_ne!(
            choose_address(u, BoardKind::PICO, &[], &pinned, a(MB), none),
            Some(a(h))
        );
        // Every address taken: none.
        let all = |_: Address| true;
        assert_eq!(
            choose_address(u, BoardKind::PICO, &[], &[], a(MB), all),
            None
        );
        // Never the MB's, never 0x77, never the STM32 ROM bootloader's 0x64: over all IDs of
        // one byte (some of which hash to 0x64 itself: they get the next address).
        let mut hashed_to_rom = 0;
        for n in 0..=255u8 {
            for m in 0..4u8 {
                let u = Uid([n, m, 2, 3, 4, 5, 6, 7]);
                let got = choose_address(u, BoardKind::PICO, &[], &[], a(MB), none).unwrap();
                assert!((0x09..=0x76).contains(&got.get()), "{n} {m}: {got}");
                assert_ne!(got.get(), Address::STM32_BOOTLOADER, "{n} {m}");
                if u.hash32() % 0x6f + 0x08 == u32::from(Address::STM32_BOOTLOADER) {
                    hashed_to_rom += 1;
                    assert_eq!(got.get(), 0x65, "{n} {m}");
                }
            }
        }
        assert!(hashed_to_rom > 0);
    }

    #[test]
    fn pinned_by_id_then_by_the_only_board_of_a_kind_then_remembered() {
        let none = |_: Address| false;
        let pinned = [
            PinnedAddress {
                by: PinBy::Uid(uid(1)),
                address: a(0x30),
            },
            PinnedAddress {
                by: PinBy::Kind(BoardKind::G431),
                address: a(0x31),
            },
        ];
        assert_eq!(
            choose_address(uid(1), BoardKind::PICO, &[], &pinned, a(MB), none),
            Some(a(0x30))
        );
        // The only G431: its kind's address; with another G431 known: not.
        assert_eq!(
            choose_address(uid(2), BoardKind::G431, &[], &pinned, a(MB), none),
            Some(a(0x31))
        );
        let mut other = KnownBoard::EMPTY;
        other.uid = uid(3);
        other.kind = BoardKind::G431;
        other.address = a(0x40);
        other.present = true;
        let got = choose_address(uid(2), BoardKind::G431, &[other], &pinned, a(MB), none);
        assert!(!matches!(got, Some(x) if x == a(0x31) || x == a(0x30)));
        // Remembered: the address this ID had, unless another present board is there now.
        let mut before = KnownBoard::EMPTY;
        before.uid = uid(4);
        before.address = a(0x50);
        assert_eq!(
            choose_address(uid(4), BoardKind::PICO, &[before], &[], a(MB), none),
            Some(a(0x50))
        );
        let mut squatter = other;
        squatter.address = a(0x50);
        assert_ne!(
            choose_address(
                uid(4),
                BoardKind::PICO,
                &[before, squatter],
                &[],
                a(MB),
                none
            ),
            Some(a(0x50))
        );
        // Its own address back although the motherboard still knows a board's ports there
        // (it was this board, restarted unaddressed); a fresh ID is kept off such an address.
        let ports_known_at_50 = |x: Address| x == a(0x50);
        assert_eq!(
            choose_address(
                uid(4),
                BoardKind::PICO,
                &[before],
                &[],
                a(MB),
                ports_known_at_50
            ),
            Some(a(0x50))
        );
        assert_ne!(
            choose_address(
                uid(5),
                BoardKind::PICO,
                &[before],
                &[],
                a(MB),
                ports_known_at_50
            ),
            Some(a(0x50))
        );
    }

    #[test]
    fn announce_assign_boot_and_the_same_address_again_after_a_reannounce() {
        let mut d = dir(4);
        let t = Instant(1_000);
        let h = d.announced(&info(uid(1), BoardKind::PICO), &[], a(MB), |_| false, t);
        let want = a(hashed(uid(1)));
        assert_eq!(
            h,
            Heard::Assign {
                address: want,
                new: true
            }
        );
        assert_eq!(d.take_assign(), Some((uid(1), want)));
        assert_eq!(d.take_assign(), None);
        // The assign was lost: the board announces again and gets the same address.
        let h = d.announced(&info(uid(1), BoardKind::PICO), &[], a(MB), |_| false, t);
        assert_eq!(
            h,
            Heard::Assign {
                address: want,
                new: false
            }
        );
        assert_eq!(d.take_assign(), Some((uid(1), want)));
        // Its boot from there: known, present.
        assert_eq!(
            d.seen(want, &info(uid(1), BoardKind::PICO), t),
            Heard::Known
        );
        let b = d.find(BoardQuery::Uid(uid(1))).unwrap();
        assert!(b.present && !b.collided);
        assert_eq!(
            (b.sensor_ports, b.actuator_ports, b.firmware),
            (4, 2, [0, 1, 0])
        );
    }

    #[test]
    fn two_ids_from_one_address_within_the_window_are_a_collision() {
        let mut d = dir(4);
        let x = a(0x20);
        assert_eq!(
            d.seen(x, &info(uid(1), BoardKind::PICO), Instant(0)),
            Heard::New
        );
        assert_eq!(
            d.seen(x, &info(uid(2), BoardKind::PICO), Instant(5_000)),
            Heard::Collision
        );
        let both: Vec<KnownBoard> = d.known().to_vec();
        assert_eq!(both.len(), 2);
        assert!(both.iter().all(|b| b.collided && b.address == x));
        // A board replaced after the window is no collision.
        let mut d = dir(4);
        d.seen(x, &info(uid(1), BoardKind::PICO), Instant(0));
        assert_eq!(
            d.seen(
                x,
                &info(uid(2), BoardKind::PICO),
                Instant(COLLISION_WINDOW_US)
            ),
            Heard::New
        );
        // Nor is one that was reported gone first.
        let mut d = dir(4);
        d.seen(x, &info(uid(1), BoardKind::PICO), Instant(0));
        assert!(d.lost(x));
        assert!(!d.lost(x));
        assert_eq!(
            d.seen(x, &info(uid(2), BoardKind::PICO), Instant(10)),
            Heard::New
        );
    }

    #[test]
    fn without_storage_or_room_nothing_is_known_and_nothing_swept() {
        let mut d = Directory::new();
        assert_eq!(d.next_sweep(a(MB)), None);
        assert_eq!(
            d.announced(
                &info(uid(1), BoardKind::PICO),
                &[],
                a(MB),
                |_| false,
                Instant(0)
            ),
            Heard::NoRoom
        );
        assert_eq!(
            d.seen(a(0x20), &info(uid(1), BoardKind::PICO), Instant(0)),
            Heard::NoRoom
        );
        let mut d = dir(1);
        d.seen(a(0x20), &info(uid(1), BoardKind::PICO), Instant(0));
        assert_eq!(
            d.seen(a(0x21), &info(uid(2), BoardKind::PICO), Instant(0)),
            Heard::NoRoom
        );
        // An announce without an ID gets nothing.
        let mut no_id = info(uid(3), BoardKind::PICO);
        no_id.uid = None;
        assert_eq!(
            dir(2).announced(&no_id, &[], a(MB), |_| false, Instant(0)),
            Heard::NoRoom
        );
    }

    #[test]
    fn the_sweep_visits_every_address_once_but_the_mb_s_and_0x77() {
        let mut d = dir(1);
        let swept: Vec<u8> = core::iter::from_fn(|| d.next_sweep(a(0x30)))
            .map(Address::get)
            .collect();
        let want: Vec<u8> = (0x08..=0x76).filter(|&x| x != 0x30 && x != 0x64).collect();
        assert_eq!(swept, want);
        assert_eq!(d.next_sweep(a(0x30)), None);
        // A probe that lost arbitration is taken again next, around the MB's address too.
        let mut d = dir(1);
        for _ in 0..0x28 {
            d.next_sweep(a(0x30));
        }
        assert_eq!(d.next_sweep(a(0x30)), Some(a(0x31)));
        d.put_back(&Op::WhoIsThere);
        assert_eq!(d.next_sweep(a(0x30)), Some(a(0x31)));
        let rest: Vec<u8> = core::iter::from_fn(|| d.next_sweep(a(0x30)))
            .map(Address::get)
            .collect();
        assert_eq!(rest.last(), Some(&0x76));
        d.put_back(&Op::WhoIsThere);
        assert_eq!(d.next_sweep(a(0x30)), Some(a(0x76)));
        assert_eq!(d.next_sweep(a(0x30)), None);
        // An assign put back is pending again.
        let mut d = dir(2);
        d.announced(
            &info(uid(1), BoardKind::PICO),
            &[],
            a(MB),
            |_| false,
            Instant(0),
        );
        let (u, to) = d.take_assign().unwrap();
        d.put_back(&Op::Assign {
            uid: u,
            address: to,
        });
        assert_eq!(d.take_assign(), Some((u, to)));
    }

    #[test]
    fn a_moved_board_is_found_at_its_new_address() {
        let mut d = dir(2);
        d.seen(a(0x20), &info(uid(1), BoardKind::PICO), Instant(0));
        d.moved(a(0x20), a(0x40));
        let b = d.find(BoardQuery::Uid(uid(1))).unwrap();
        assert_eq!((b.address, b.present), (a(0x40), false));
        assert_eq!(
            d.seen(a(0x40), &info(uid(1), BoardKind::PICO), Instant(9)),
            Heard::Known
        );
        assert!(d.find(BoardQuery::Address(a(0x40))).unwrap().present);
        assert!(d.find(BoardQuery::Kind(BoardKind::PICO)).is_some());
        assert!(d.find(BoardQuery::Kind(BoardKind::G431)).is_none());
    }

    #[test]
    fn the_laptops_assign_is_refused_or_planned_exactly() {
        let mut d = dir(4);
        let now = Instant(0);
        let mb = a(MB);
        let none = |_: Address| false;
        d.seen(a(0x20), &info(uid(1), BoardKind::PICO), now);
        d.seen(a(0x21), &info(uid(2), BoardKind::PICO), now);
        let plan = |d: &Directory, u: Uid, to: u8, pinned: &[PinnedAddress]| {
            d.assign_plan(u, a(to), mb, pinned, none)
        };
        // Reserved: the motherboard's own, 0x64, the unaddressed address, the internal one.
        for r in [MB, Address::STM32_BOOTLOADER, 0x77, 0x00] {
            assert_eq!(
                plan(&d, uid(1), r, &[]),
                Err(AssignError::Reserved),
                "{r:#04x}"
            );
        }
        assert_eq!(plan(&d, uid(9), 0x40, &[]), Err(AssignError::UnknownUid));
        // Another board there; pinned to another board; known there without an ID.
        assert_eq!(plan(&d, uid(1), 0x21, &[]), Err(AssignError::Taken));
        let pin = [PinnedAddress {
            by: PinBy::Uid(uid(2)),
            address: a(0x40),
        }];
        assert_eq!(plan(&d, uid(1), 0x40, &pin), Err(AssignError::Taken));
        assert_eq!(
            plan(&d, uid(2), 0x40, &pin),
            Ok(AssignPlan::SetAddress(a(0x21)))
        );
        assert_eq!(
            d.assign_plan(uid(1), a(0x41), mb, &[], |x| x == a(0x41)),
            Err(AssignError::Taken)
        );
        assert_eq!(plan(&d, uid(1), 0x20, &[]), Ok(AssignPlan::Already));
        assert_eq!(
            plan(&d, uid(1), 0x40, &[]),
            Ok(AssignPlan::SetAddress(a(0x20)))
        );
        // A lost board's address is free; a board that does not answer gets an assign.
        d.lost(a(0x21));
        assert_eq!(
            plan(&d, uid(1), 0x21, &[]),
            Ok(AssignPlan::SetAddress(a(0x20)))
        );
        assert_eq!(plan(&d, uid(2), 0x42, &[]), Ok(AssignPlan::Assign));
        d.reassign(uid(2), a(0x42));
        let b = d.find(BoardQuery::Uid(uid(2))).unwrap();
        assert_eq!((b.address, b.present), (a(0x42), false));
        assert_eq!(d.take_assign(), Some((uid(2), a(0x42))));
        // Being assigned there: taken for the others.
        d.reassign(uid(2), a(0x42));
        assert_eq!(plan(&d, uid(1), 0x42, &[]), Err(AssignError::Taken));
        // Two boards at one address: neither can be moved alone.
        d.seen(a(0x30), &info(uid(3), BoardKind::PICO), now);
        d.seen(a(0x30), &info(uid(4), BoardKind::PICO), now);
        assert_eq!(plan(&d, uid(3), 0x50, &[]), Err(AssignError::Collided));
        assert_eq!(plan(&d, uid(4), 0x50, &[]), Err(AssignError::Collided));
    }
}
