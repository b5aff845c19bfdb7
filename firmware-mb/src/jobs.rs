//! The job queue: the requests waiting for the dispatcher (external boards) or for the
//! internal daughterboard's worker (address 0), oldest first, with their frames. Owns
//! [`Jobs`] and what a job is ([`Job`], [`JobMeta`]); the slot each job holds is
//! [`crate::requests`]'s.
//!
//! The queue has room for one job per pending slot ([`REQUEST_QUEUE_LEN`] =
//! [`MAX_PENDING`]), so a caller that got a slot never waits for room; releasing the slot
//! takes its job out, so a request whose caller gave up never reaches the bus.

use heapless::{Deque, Vec};
use x10_microcode::{Address, PinRef, MAX_FRAME_LEN};

use crate::requests::{Ticket, MAX_PENDING};

/// Requests that can wait for the dispatcher: one per pending slot, so a caller that holds a
/// slot never waits for room in the queue ([`MAX_PENDING`]).
pub const REQUEST_QUEUE_LEN: usize = MAX_PENDING;

/// What kind of transfer a job is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum JobKind {
    /// A request to its board, prepared first, read back as its operation says.
    Request,
    /// The frame written to the general call address (0x00) with its check over `0x00`
    /// (`sample`, `apply`); no board is prepared for it.
    GeneralCall,
    /// A plain read (no write first) of `read` bytes from the board, handed back raw (a sweep
    /// frame, an `apply`'s status).
    PlainRead,
}

/// What the dispatcher needs to know about a request besides its bytes.
#[derive(Clone, Copy, Debug)]
pub(crate) struct JobMeta {
    pub(crate) ticket: Ticket,
    pub(crate) kind: JobKind,
    pub(crate) db: Address,
    pub(crate) seq: u8,
    /// Payload bytes to read after a repeated START, besides the reply header and the PEC
    /// byte (`None`: the request is a single write). The PEC byte is added, or not, when the
    /// request goes on the bus, as the board's PEC state is then.
    pub(crate) read: Option<usize>,
    /// A deferred operation (pulse-in): the pin its deferred reply names and how long after
    /// the `pending` answer the board may still send it, in µs. Only such a request may be
    /// answered `pending`.
    pub(crate) deferred: Option<(PinRef, u64)>,
    /// Failsafe timeout the request sets (a `set_failsafe`), kept alive once the board has it.
    pub(crate) failsafe_change: Option<u16>,
}

/// A request for the dispatcher: its frame, ready to go on the bus.
#[derive(Clone, Debug)]
pub(crate) struct Job {
    pub(crate) meta: JobMeta,
    pub(crate) frame: Vec<u8, MAX_FRAME_LEN>,
}

impl Job {
    /// A request of the runtime's own (board set-up, keepalive) to `db` with sequence number
    /// `seq`: no pending slot, read back when `read` says how many payload bytes to read.
    pub(crate) fn own(
        db: Address,
        seq: u8,
        read: Option<usize>,
        frame: Vec<u8, MAX_FRAME_LEN>,
    ) -> Job {
        Job {
            meta: JobMeta {
                ticket: Ticket {
                    index: usize::MAX,
                    generation: 0,
                },
                kind: JobKind::Request,
                db,
                seq,
                read,
                deferred: None,
                failsafe_change: None,
            },
            frame,
        }
    }
}

/// The queued jobs, oldest first (a ring: taking the oldest moves nothing). Each holds a
/// slot, so the queue never overflows.
pub(crate) struct Jobs {
    queue: Deque<Job, REQUEST_QUEUE_LEN>,
}

impl Jobs {
    pub(crate) const fn new() -> Jobs {
        Jobs {
            queue: Deque::new(),
        }
    }

    /// Queues a job (behind every job queued before) for the dispatcher, or for the internal
    /// daughterboard's worker when it is for address 0.
    ///
    /// # Errors
    /// The job back if the queue is full (it cannot be while each job holds a slot).
    pub(crate) fn push(&mut self, job: Job) -> Result<(), Job> {
        self.queue.push_back(job)
    }

    /// Takes the job of request `t` out, if it is still queued.
    pub(crate) fn remove(&mut self, t: Ticket) {
        if !self.queue.is_empty() {
            self.queue.retain(|j| j.meta.ticket != t);
        }
    }

    /// Takes the oldest queued job that `wanted` accepts, keeping the others in their order.
    /// One queue serves the dispatcher and the internal daughterboard's worker (a second
    /// queue of 16 jobs would cost about 1.1 KiB of RAM): the oldest job is usually the one
    /// wanted; otherwise the queue is turned once around.
    fn take_first(&mut self, wanted: impl Fn(&Job) -> bool) -> Option<Job> {
        if self.queue.front().is_some_and(&wanted) {
            return self.queue.pop_front();
        }
        if !self.queue.iter().any(&wanted) {
            return None;
        }
        let mut found = None;
        for _ in 0..self.queue.len() {
            let Some(job) = self.queue.pop_front() else {
                break;
            };
            if found.is_none() && wanted(&job) {
                found = Some(job);
            } else {
                // Never full: one was just taken out.
                let _ = self.queue.push_back(job);
            }
        }
        found
    }

    /// The oldest job queued for the dispatcher, or for the internal daughterboard when
    /// `internal`.
    pub(crate) fn pop(&mut self, internal: bool) -> Option<Job> {
        self.take_first(|j| j.meta.db.is_internal() == internal)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn job(index: usize, board: u8) -> Job {
        Job {
            meta: JobMeta {
                ticket: Ticket {
                    index,
                    generation: 1,
                },
                kind: JobKind::Request,
                db: Address::new(board).unwrap(),
                seq: 0,
                read: None,
                deferred: None,
                failsafe_change: None,
            },
            frame: Vec::new(),
        }
    }

    #[test]
    fn the_dispatcher_and_the_internal_worker_each_take_their_oldest_job() {
        let mut q = Jobs::new();
        for (index, board) in [(0, 9), (1, 0), (2, 10), (3, 0)] {
            q.push(job(index, board)).unwrap();
        }
        let index = |j: Option<Job>| j.map(|j| j.meta.ticket.index);
        assert_eq!(index(q.pop(true)), Some(1));
        assert_eq!(index(q.pop(false)), Some(0));
        assert_eq!(index(q.pop(true)), Some(3));
        assert_eq!(index(q.pop(true)), None);
        assert_eq!(index(q.pop(false)), Some(2));
        assert_eq!(index(q.pop(false)), None);
    }

    #[test]
    fn a_released_request_leaves_the_queue() {
        let mut q = Jobs::new();
        for index in 0..REQUEST_QUEUE_LEN {
            q.push(job(index, 9)).unwrap();
        }
        assert!(q.push(job(99, 9)).is_err());
        q.remove(job(5, 9).meta.ticket);
        q.push(job(99, 9)).unwrap();
        let order: Vec<usize, REQUEST_QUEUE_LEN> =
            core::iter::from_fn(|| q.pop(false).map(|j| j.meta.ticket.index)).collect();
        let want: Vec<usize, REQUEST_QUEUE_LEN> = (0..REQUEST_QUEUE_LEN)
            .filter(|&i| i != 5)
            .chain([99])
            .collect();
        assert_eq!(order, want);
    }
}
