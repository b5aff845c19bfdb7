//! A recording test double for [`Link`] (feature `testing`; `no_std`, no allocation).
//!
//! [`RecordingLink`] encodes every operation it is given as the exact request frame a
//! motherboard would send (`Request::emit`, no PEC), with sequence numbers it assigns itself:
//! 0, 1, 2, … (wrapping after 255), and answers each call with the next scripted outcome.
//! Tests then compare the recorded bytes and call [`RecordingLink::finish`], which fails if a
//! scripted outcome or event was left unconsumed, a call found no script, or a recorded frame
//! was never looked at.
//!
//! ```
//! # use x10_devices::{testing::RecordingLink, Sensor, SELF};
//! let link = RecordingLink::<8>::new();
//! link.reply(&[0x34, 0x02]); // the board answers 0x0234 = 564
//! let force = Sensor::new(&link, SELF, 1).unwrap();
//! let raw = embassy_futures::block_on(force.read_analog()).unwrap();
//! assert_eq!(raw, 564);
//! link.assert_sent(&[&[0x30, 0x00, 0x80, 0x00]]); // ANALOG READ, SELF, sensor port 1, seq 0
//! link.finish();
//! ```
//!
//! Like an assertion, the checking methods panic on a mismatch: that is their purpose, and
//! they only run in tests.
#![allow(clippy::panic)]

use core::cell::RefCell;
use core::fmt;

use heapless::{Deque, Vec};
use x10_microcode::{Address, Op, Payload, PinRef, Request, MAX_REQUEST_LEN};

use crate::{Link, LinkError, PinEvent};

/// One recorded request frame.
pub type Frame = Vec<u8, MAX_REQUEST_LEN>;

/// Events a [`RecordingLink`] can hold.
pub const MAX_EVENTS: usize = 16;

/// Shows a frame as spaced hex bytes: `12 09 01 02`.
pub struct Hex<'a>(pub &'a [u8]);

impl fmt::Display for Hex<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for (i, b) in self.0.iter().enumerate() {
            if i > 0 {
                f.write_str(" ")?;
            }
            write!(f, "{b:02x}")?;
        }
        Ok(())
    }
}

impl fmt::Debug for Hex<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        fmt::Display::fmt(self, f)
    }
}

struct Frames<'a>(&'a [Frame]);

impl fmt::Display for Frames<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for frame in self.0 {
            writeln!(f, "    {}", Hex(frame))?;
        }
        Ok(())
    }
}

type EventEntry = (Address, PinRef, Result<PinEvent, LinkError>);

struct State<const N: usize> {
    next_seq: u8,
    sent: Vec<Frame, N>,
    /// Frames already checked by `assert_sent` / `take_sent`.
    checked: usize,
    script: Deque<Result<Payload, LinkError>, N>,
    events: Deque<EventEntry, MAX_EVENTS>,
    unscripted: usize,
    overflowed: bool,
    calls: usize,
}

/// A [`Link`] that records request frames and replays scripted outcomes. `N` bounds both the
/// recorded frames and the scripted outcomes.
///
/// Drivers take the link by value; pass `&RecordingLink` (it implements [`Link`] and `Clone`
/// through the blanket `impl Link for &L`), keep the double, inspect it afterwards.
pub struct RecordingLink<const N: usize = 128> {
    state: RefCell<State<N>>,
}

impl<const N: usize> Default for RecordingLink<N> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const N: usize> RecordingLink<N> {
    /// An empty double; the first frame gets sequence number 0.
    pub const fn new() -> Self {
        RecordingLink {
            state: RefCell::new(State {
                next_seq: 0,
                sent: Vec::new(),
                checked: 0,
                script: Deque::new(),
                events: Deque::new(),
                unscripted: 0,
                overflowed: false,
                calls: 0,
            }),
        }
    }

    /// Sets the sequence number of the next frame (to test wrap-around).
    pub fn set_next_seq(&self, seq: u8) -> &Self {
        self.state.borrow_mut().next_seq = seq;
        self
    }

    fn push(&self, outcome: Result<Payload, LinkError>) -> &Self {
        if self.state.borrow_mut().script.push_back(outcome).is_err() {
            panic!("RecordingLink: more than {N} scripted outcomes");
        }
        self
    }

    /// The next call succeeds with `payload` (a read's reply payload).
    ///
    /// # Panics
    /// When `payload` is longer than a reply payload can be, or the script is full.
    pub fn reply(&self, payload: &[u8]) -> &Self {
        match Payload::from_slice(payload) {
            Ok(p) => self.push(Ok(p)),
            Err(_) => panic!(
                "RecordingLink: payload of {} bytes is too long",
                payload.len()
            ),
        }
    }

    /// The next call succeeds with an empty payload (an output acknowledged).
    ///
    /// # Panics
    /// When the script is full.
    pub fn ack(&self) -> &Self {
        self.push(Ok(Payload::new()))
    }

    /// The next `n` calls succeed with an empty payload.
    ///
    /// # Panics
    /// When the script is full.
    pub fn acks(&self, n: usize) -> &Self {
        for _ in 0..n {
            self.ack();
        }
        self
    }

    /// The next call fails with `error` (its frame is still recorded: it was sent).
    ///
    /// # Panics
    /// When the script is full.
    pub fn fail(&self, error: LinkError) -> &Self {
        self.push(Err(error))
    }

    /// Queues `event` for a `wait_event` on its own source and pin.
    ///
    /// # Panics
    /// When more than [`MAX_EVENTS`] are queued.
    pub fn event(&self, event: PinEvent) -> &Self {
        let entry = (event.source, event.pin, Ok(event));
        if self.state.borrow_mut().events.push_back(entry).is_err() {
            panic!("RecordingLink: more than {MAX_EVENTS} scripted events");
        }
        self
    }

    /// Queues a failure for a `wait_event` on `db`, `pin`.
    ///
    /// # Panics
    /// When more than [`MAX_EVENTS`] are queued.
    pub fn event_error(&self, db: Address, pin: PinRef, error: LinkError) -> &Self {
        if self
            .state
            .borrow_mut()
            .events
            .push_back((db, pin, Err(error)))
            .is_err()
        {
            panic!("RecordingLink: more than {MAX_EVENTS} scripted events");
        }
        self
    }

    /// Every frame recorded so far, checked or not.
    pub fn sent(&self) -> Vec<Frame, N> {
        self.state.borrow().sent.clone()
    }

    /// The frames recorded since the last check, marking them checked.
    pub fn take_sent(&self) -> Vec<Frame, N> {
        let mut s = self.state.borrow_mut();
        let new = s.sent.get(s.checked..).unwrap_or(&[]);
        let out = Vec::from_slice(new).unwrap_or_default();
        s.checked = s.sent.len();
        out
    }

    /// Number of `call`s made (including unscripted and invalid ones).
    pub fn calls(&self) -> usize {
        self.state.borrow().calls
    }

    /// Checks that the frames recorded since the last check are exactly `expected`, in order.
    ///
    /// # Panics
    /// On any difference, listing both sides in hex.
    pub fn assert_sent(&self, expected: &[&[u8]]) {
        let got = self.take_sent();
        let same = got.len() == expected.len()
            && got.iter().zip(expected).all(|(g, e)| g.as_slice() == *e);
        if !same {
            struct Exp<'a>(&'a [&'a [u8]]);
            impl fmt::Display for Exp<'_> {
                fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
                    for e in self.0 {
                        writeln!(f, "    {}", Hex(e))?;
                    }
                    Ok(())
                }
            }
            panic!(
                "RecordingLink: frames differ\n  sent:\n{}  expected:\n{}",
                Frames(&got),
                Exp(expected)
            );
        }
    }

    /// Checks that the test is complete: every scripted outcome and event consumed, every call
    /// had a script, nothing overflowed, and every recorded frame was checked.
    ///
    /// # Panics
    /// Otherwise, saying what is left.
    pub fn finish(&self) {
        let s = self.state.borrow();
        if s.overflowed {
            panic!("RecordingLink: more than {N} frames were sent");
        }
        if s.unscripted > 0 {
            panic!(
                "RecordingLink: {} call(s) found no scripted outcome",
                s.unscripted
            );
        }
        if !s.script.is_empty() {
            panic!(
                "RecordingLink: {} scripted outcome(s) never consumed",
                s.script.len()
            );
        }
        if !s.events.is_empty() {
            panic!(
                "RecordingLink: {} scripted event(s) never consumed",
                s.events.len()
            );
        }
        if s.checked != s.sent.len() {
            panic!(
                "RecordingLink: frames never checked:\n{}",
                Frames(s.sent.get(s.checked..).unwrap_or(&[]))
            );
        }
    }
}

impl<const N: usize> Link for RecordingLink<N> {
    /// Validates `op` as the motherboard runtime does (`Err(Invalid)`, nothing recorded, no
    /// script consumed), records its frame, then pops the next scripted outcome; with none
    /// left it counts an unscripted call and answers `Err(Unsupported)`.
    async fn call(&self, db: Address, op: Op<'_>) -> Result<Payload, LinkError> {
        let mut s = self.state.borrow_mut();
        s.calls += 1;
        op.validate()?;
        let request = Request {
            db,
            seq: s.next_seq,
            op,
        };
        let mut buf = [0u8; MAX_REQUEST_LEN];
        let len = request.emit(&mut buf)?;
        let frame = Frame::from_slice(buf.get(..len).unwrap_or(&[])).unwrap_or_default();
        if s.sent.push(frame).is_err() {
            s.overflowed = true;
        }
        s.next_seq = s.next_seq.wrapping_add(1);
        match s.script.pop_front() {
            Some(outcome) => outcome,
            None => {
                s.unscripted += 1;
                Err(LinkError::Unsupported)
            }
        }
    }

    /// Pops the first queued event for `db`, `pin`; with none it counts an unscripted call
    /// and answers `Err(Unsupported)`.
    async fn wait_event(&self, db: Address, pin: PinRef) -> Result<PinEvent, LinkError> {
        let mut s = self.state.borrow_mut();
        // One full rotation: take the first match, put every other event back in order.
        let mut found = None;
        for _ in 0..s.events.len() {
            if let Some(entry) = s.events.pop_front() {
                if found.is_none() && entry.0 == db && entry.1 == pin {
                    found = Some(entry.2);
                } else {
                    // Cannot fail: an entry was just popped.
                    let _ = s.events.push_back(entry);
                }
            }
        }
        if let Some(outcome) = found {
            return outcome;
        }
        s.unscripted += 1;
        Err(LinkError::Unsupported)
    }
}
