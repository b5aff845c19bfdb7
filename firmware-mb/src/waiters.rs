//! Pin events and the tasks that wait for them: the waiter slots (who waits for which pin,
//! and the event held for a task between two waits) and the queue of pin events nobody
//! waited for. Owns [`Waiters`]: pure bookkeeping, no waiting (the signals that wake the
//! waiting tasks are the motherboard's, one per waiter slot).

use core::task::Waker;

use heapless::Vec;
use x10_devices::{LinkError, PinEvent};
use x10_microcode::{Address, PinRef};

use crate::diag::{bump, MbDiagnostics};

/// Tasks waiting for a pin event at the same time.
pub const MAX_EVENT_WAITERS: usize = 8;
/// Pin events kept for a later `wait_event` when no task was waiting.
pub const UNCLAIMED_EVENTS: usize = 8;

#[derive(Clone, Copy, Debug)]
enum Waiter {
    Free,
    Waiting(Address, PinRef),
    /// An event was put in the waiter's signal; the waiter has not taken it yet.
    Delivered(Address, PinRef),
    /// The slot's task took an event for this pin and has not called `wait_event` again yet:
    /// events for the pin meanwhile are held for it (one; a second is counted as dropped),
    /// so a task waiting on a pin in a loop misses none, whoever else waits on it.
    Lingering(Address, PinRef),
}

#[derive(Clone, Debug)]
struct WaiterSlot {
    generation: u32,
    state: Waiter,
    /// The task the slot belongs to (its waker): the task's next `wait_event` for the same
    /// pin takes this slot again.
    owner: Option<Waker>,
    /// An event that came while the slot was lingering.
    held: Option<PinEvent>,
    /// `held` has been given to another task too (a first wait for the pin), once.
    shared: bool,
}

/// A registered event waiter.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct WaiterTicket {
    pub(crate) index: usize,
    pub(crate) generation: u32,
}

/// The waiter slots and the unclaimed pin events.
pub(crate) struct Waiters {
    waiters: [WaiterSlot; MAX_EVENT_WAITERS],
    generation: u32,
    unclaimed: Vec<PinEvent, UNCLAIMED_EVENTS>,
}

impl Waiters {
    pub(crate) const fn new() -> Waiters {
        Waiters {
            waiters: [const {
                WaiterSlot {
                    generation: 0,
                    state: Waiter::Free,
                    owner: None,
                    held: None,
                    shared: false,
                }
            }; MAX_EVENT_WAITERS],
            generation: 0,
            unclaimed: Vec::new(),
        }
    }

    /// Registers the calling task (`task`, its waker) as waiting for the next event of
    /// `(board, pin)`, or returns an event at once: one held for this task since its last
    /// `wait_event` for the pin, or one nobody waited for (the unclaimed queue).
    ///
    /// # Errors
    /// [`LinkError::Busy`] when every waiter slot is taken by a task that waits.
    pub(crate) fn wait_for(
        &mut self,
        board: Address,
        pin: PinRef,
        task: &Waker,
        diag: &mut MbDiagnostics,
    ) -> Result<Result<PinEvent, WaiterTicket>, LinkError> {
        let own = self.waiters.iter().position(|w| {
            matches!(w.state, Waiter::Lingering(b, p) if b == board && p == pin)
                && w.owner.as_ref().is_some_and(|o| o.will_wake(task))
        });
        // The queue first: an event for the pin is queued only while no slot waits or
        // lingers on it (one delivered and not yet taken included), so a queued event is
        // always older than the one held by a lingering slot.
        if let Some(i) = self
            .unclaimed
            .iter()
            .position(|e| e.source == board && e.pin == pin)
        {
            return Ok(Ok(self.unclaimed.remove(i)));
        }
        if let Some(ev) = own
            .and_then(|i| self.waiters.get_mut(i))
            .and_then(|w| w.held.take())
        {
            return Ok(Ok(ev));
        }
        // A task's first wait for the pin: an event held for another task that took the
        // pin's previous event and has not come back is this task's too (every task waiting
        // for a pin gets its events); it stays held for the other task as well.
        if own.is_none() {
            let other = self.waiters.iter_mut().find(|w| {
                matches!(w.state, Waiter::Lingering(b, p) if b == board && p == pin)
                    && w.held.is_some()
                    && !w.shared
            });
            if let Some(w) = other {
                w.shared = true;
                if let Some(ev) = w.held.clone() {
                    return Ok(Ok(ev));
                }
            }
        }
        // Its own slot, else a free one, else one lingering for a task that stopped waiting
        // (an empty one first; a held event it drops is counted).
        let index = own
            .or_else(|| {
                self.waiters
                    .iter()
                    .position(|w| matches!(w.state, Waiter::Free))
            })
            .or_else(|| {
                self.waiters
                    .iter()
                    .position(|w| matches!(w.state, Waiter::Lingering(..)) && w.held.is_none())
            })
            .or_else(|| {
                self.waiters
                    .iter()
                    .position(|w| matches!(w.state, Waiter::Lingering(..)))
            });
        let Some(index) = index else {
            return Err(LinkError::Busy);
        };
        self.generation = self.generation.wrapping_add(1);
        let generation = self.generation;
        let mut dropped = false;
        if let Some(w) = self.waiters.get_mut(index) {
            dropped = w.held.is_some();
            *w = WaiterSlot {
                generation,
                state: Waiter::Waiting(board, pin),
                owner: Some(task.clone()),
                held: None,
                shared: false,
            };
        }
        if dropped {
            bump(&mut diag.events_dropped);
        }
        Ok(Err(WaiterTicket { index, generation }))
    }

    /// The waiters an event for `(board, pin)` goes to: each is marked delivered. With none,
    /// the event is kept for a later `wait_event` (pushing out the oldest when full).
    pub(crate) fn deliver(
        &mut self,
        ev: &PinEvent,
        diag: &mut MbDiagnostics,
        mut to: impl FnMut(usize),
    ) {
        let mut any = false;
        let mut dropped = 0u32;
        for (i, w) in self.waiters.iter_mut().enumerate() {
            match w.state {
                Waiter::Waiting(b, p) if b == ev.source && p == ev.pin => {
                    w.state = Waiter::Delivered(b, p);
                    to(i);
                    any = true;
                }
                Waiter::Lingering(b, p) if b == ev.source && p == ev.pin => {
                    if w.held.is_some() {
                        // Its task has not come back for the last one: counted, not silent.
                        dropped += 1;
                    } else {
                        w.held = Some(ev.clone());
                        w.shared = false;
                    }
                    any = true;
                }
                _ => {}
            }
        }
        for _ in 0..dropped {
            bump(&mut diag.events_dropped);
        }
        if !any {
            self.keep_unclaimed(ev.clone(), false, diag);
        }
    }

    /// Keeps an event for a later `wait_event`: at the back (newest), or at the front when a
    /// waiter went away before taking it.
    pub(crate) fn keep_unclaimed(&mut self, ev: PinEvent, front: bool, diag: &mut MbDiagnostics) {
        if self.unclaimed.is_full() {
            self.unclaimed.remove(0);
            bump(&mut diag.events_dropped);
        }
        let at = if front { 0 } else { self.unclaimed.len() };
        let _ = self.unclaimed.insert(at, ev);
    }

    /// A wait ended without taking its event (its future was dropped: a timeout, a
    /// `select`): the slot lingers for its task, empty, so that the task's next wait for the
    /// pin is known as its own (not a first wait, which could be handed an event this task
    /// already had). Returns true if an event had been delivered to it (the caller takes it
    /// from the signal and queues it at the front, older than anything the slot holds later).
    pub(crate) fn unwait(&mut self, t: WaiterTicket) -> bool {
        match self.waiters.get_mut(t.index) {
            Some(w) if w.generation == t.generation => match w.state {
                Waiter::Waiting(b, p) | Waiter::Delivered(b, p) => {
                    let delivered = matches!(w.state, Waiter::Delivered(..));
                    w.state = Waiter::Lingering(b, p);
                    w.held = None;
                    w.shared = false;
                    delivered
                }
                _ => false,
            },
            _ => false,
        }
    }

    /// The waiter took its event: the slot lingers for its task, holding the pin's next
    /// event until the task waits again.
    pub(crate) fn took(&mut self, t: WaiterTicket) {
        if let Some(w) = self.waiters.get_mut(t.index) {
            if w.generation == t.generation {
                if let Waiter::Delivered(b, p) = w.state {
                    w.state = Waiter::Lingering(b, p);
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use x10_microcode::EventKind;

    extern crate std;
    use std::sync::Arc;
    use std::task::Wake;

    struct Task;

    impl Wake for Task {
        fn wake(self: Arc<Self>) {}
    }

    /// A waker of a task of its own (`will_wake` tells them apart).
    fn task() -> Waker {
        Waker::from(Arc::new(Task))
    }

    fn board() -> Address {
        Address::new(9).unwrap()
    }

    const PIN: PinRef = PinRef::from_byte(0x80);

    /// A pin-change event carrying `n` as its level byte (to tell events apart).
    fn event(n: u8) -> PinEvent {
        PinEvent {
            source: board(),
            kind: EventKind::PinChange,
            pin: PIN,
            value: heapless::Vec::from_slice(&[n]).unwrap(),
        }
    }

    fn ticket(r: Result<Result<PinEvent, WaiterTicket>, LinkError>) -> WaiterTicket {
        match r {
            Ok(Err(t)) => t,
            other => panic!("expected to wait, got {other:?}"),
        }
    }

    fn got(r: Result<Result<PinEvent, WaiterTicket>, LinkError>) -> u8 {
        match r {
            Ok(Ok(ev)) => ev.value[0],
            other => panic!("expected an event, got {other:?}"),
        }
    }

    /// The fuzz finding `event-out-of-order--lingering-held-before-queued`: an event that
    /// came while the task's slot was delivered (queued) is older than the one its slot held
    /// afterwards, and comes first.
    #[test]
    fn a_queued_event_comes_before_the_one_held_after_it() {
        let (mut w, mut d) = (Waiters::new(), MbDiagnostics::default());
        let a = task();
        let t = ticket(w.wait_for(board(), PIN, &a, &mut d));
        let mut to = Vec::<usize, 8>::new();
        w.deliver(&event(1), &mut d, |i| to.push(i).unwrap());
        assert_eq!(to, [t.index]);
        w.deliver(&event(2), &mut d, |_| panic!("delivered twice"));
        w.took(t);
        w.deliver(&event(3), &mut d, |_| panic!("a lingering slot holds"));
        assert_eq!(got(w.wait_for(board(), PIN, &a, &mut d)), 2);
        assert_eq!(got(w.wait_for(board(), PIN, &a, &mut d)), 3);
        ticket(w.wait_for(board(), PIN, &a, &mut d));
        assert_eq!(d.events_dropped, 0);
    }

    /// The fuzz finding `event-out-of-order--rewait-after-timeout-takes-anothers-held`: two
    /// tasks got event 1; event 2 is held for both; task A takes it, waits again and gives up
    /// (a timeout drops its wait). Waiting once more, it must not get event 2 a second time
    /// from B's slot, as a task's first wait would.
    #[test]
    fn a_wait_given_up_leaves_the_task_its_slot_and_no_second_copy() {
        let (mut w, mut d) = (Waiters::new(), MbDiagnostics::default());
        let (a, b) = (task(), task());
        let ta = ticket(w.wait_for(board(), PIN, &a, &mut d));
        let tb = ticket(w.wait_for(board(), PIN, &b, &mut d));
        w.deliver(&event(1), &mut d, |_| {});
        w.took(ta);
        w.took(tb);
        w.deliver(&event(2), &mut d, |_| panic!("both slots linger"));
        assert_eq!(got(w.wait_for(board(), PIN, &a, &mut d)), 2);
        let again = ticket(w.wait_for(board(), PIN, &a, &mut d));
        assert!(!w.unwait(again));
        ticket(w.wait_for(board(), PIN, &a, &mut d));
        // B still gets its own copy.
        assert_eq!(got(w.wait_for(board(), PIN, &b, &mut d)), 2);
    }
}
