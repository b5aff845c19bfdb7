//! What the bus can do to a bootloader in update mode: any bytes at all, and a whole update
//! whose frames are hit by bit flips on the way. Nothing panics, nothing reaches the active
//! slot or the state partition but a verified commit, and a flipped frame is never taken for
//! the one the motherboard sent: the slot the commit marks holds exactly the image.

mod common;

use common::*;
use embassy_boot::{BlockingFirmwareState, State};
use proptest::prelude::*;
use x10_boot::{Exit, Session};
use x10_microcode::{pec, Address, Reply, Request, Status, UpdateOp, CHUNK_MAX};

const OLD: [u8; 3] = [0, 2, 0];
const NEW: [u8; 3] = [0, 3, 0];

/// A board with the old image, in update mode (the application took `enter_update`).
fn board(len: usize) -> (Board, Vec<u8>, std::rc::Rc<Power>) {
    let old = image(len, OLD, 11);
    let board = Board::new(&old);
    let power = Power::new(None, Cut::Clean);
    board.enter_update(&power).unwrap();
    (board, old, power)
}

/// The frame the motherboard sends for `op`, check included.
fn frame(seq: u8, op: UpdateOp<'_>) -> Vec<u8> {
    let mut data = [0u8; 28];
    let req = Request {
        db: Address::new(DB).unwrap(),
        seq,
        op: op.to_op(&mut data),
    };
    let mut buf = [0u8; 40];
    let n = req.emit_with_pec(&mut buf).unwrap();
    buf[..n].to_vec()
}

/// The reply the board holds, checked as the motherboard checks it: `None` when the check or
/// the frame is bad (the motherboard would try again).
fn reply(s: &mut Session<'_, Part, Part, BUF>) -> Option<(u8, Status)> {
    let mut rx = [0u8; 40];
    let n = s.take_reply(&mut rx);
    assert!(n <= rx.len());
    let body = pec::strip(Address::new(DB).unwrap().addr_byte(true), &rx[..n]).ok()?;
    let r = Reply::parse(body).ok()?;
    Some((r.seq, r.status))
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(2000))]

    /// Writes of any bytes, read or not, with the flash work done or not: no panic, the
    /// active slot and the state partition untouched (still waiting in update mode), and the
    /// board still takes a whole update afterwards.
    #[test]
    fn any_bytes_leave_the_old_image_and_an_updatable_board(
        writes in proptest::collection::vec(
            (proptest::collection::vec(any::<u8>(), 0..48), any::<bool>(), any::<bool>()),
            0..24,
        )
    ) {
        let (board, old, power) = board(6_000);
        {
            let mut aligned = [0u8; WRITE];
            let st = BlockingFirmwareState::new(board.part(0, &power), &mut aligned);
            let mut s: Session<'_, Part, Part, BUF> = Session::new(config(), board.part(2, &power), st);
            for (bytes, read, work) in &writes {
                s.handle_write(bytes);
                if *read {
                    let mut rx = [0u8; 40];
                    let n = s.take_reply(&mut rx);
                    prop_assert!(n <= rx.len());
                }
                if *work {
                    s.work();
                }
            }
            prop_assert_eq!(s.exit(), Exit::Stay);
            prop_assert!(board.active_is(&old));
            prop_assert_eq!(board.state_magic(), State::DfuDetach);
            // Still updatable: a whole transfer from `begin` is taken and committed.
            let new = image(5_000, NEW, 12);
            prop_assert_eq!(transfer(&mut s, &new, NEW), Status::Ok);
            s.work();
            prop_assert_eq!(s.exit(), Exit::Reset);
        }
        prop_assert_eq!(board.state_magic(), State::Swap);
    }

    /// A whole update in which frames are hit by bit flips (one to three bits per hit frame,
    /// in the request or in its reply), the motherboard trying each request again until a
    /// reply with the right sequence number and a good check comes back: the commit marks a
    /// slot that holds exactly the image sent, byte for byte.
    #[test]
    fn flipped_frames_never_reach_the_committed_slot(
        hits in proptest::collection::vec((0usize..1_000, proptest::collection::vec(0usize..320, 1..4), any::<bool>()), 0..40),
    ) {
        let (board, _old, power) = board(6_000);
        let new = image(3_000, NEW, 13);
        let mut ops: Vec<UpdateOp<'_>> = vec![UpdateOp::Begin(info(&new, NEW))];
        for (i, c) in new.chunks(CHUNK_MAX).enumerate() {
            ops.push(UpdateOp::Chunk { offset: (i * CHUNK_MAX) as u32, data: c });
        }
        ops.push(UpdateOp::Commit);
        let mut aligned = [0u8; WRITE];
        let st = BlockingFirmwareState::new(board.part(0, &power), &mut aligned);
        let mut s: Session<'_, Part, Part, BUF> = Session::new(config(), board.part(2, &power), st);
        let mut attempt = 0usize;
        for (i, op) in ops.iter().enumerate() {
            let seq = (i % 250) as u8 + 1;
            let sent = frame(seq, *op);
            let mut tries = 0;
            let status = loop {
                tries += 1;
                prop_assert!(tries < 10, "request {} never got through", i);
                let hit = hits.iter().find(|h| h.0 == attempt);
                attempt += 1;
                let mut f = sent.clone();
                match hit {
                    Some((_, bits, false)) => {
                        for b in bits {
                            let n = f.len() * 8;
                            f[(b % n) / 8] ^= 1 << (b % 8);
                        }
                        s.handle_write(&f);
                        // The board answers a frame it cannot trust with a status, never ok.
                        if let Some((_, st)) = reply(&mut s) {
                            prop_assert!(!st.is_ok() || f == sent, "a flipped request was taken: {:?}", st);
                        }
                        s.work();
                        continue;
                    }
                    Some((_, bits, true)) => {
                        // The request arrives; its reply is hit on the way back.
                        s.handle_write(&f);
                        let mut rx = [0u8; 40];
                        let n = s.take_reply(&mut rx);
                        for b in bits {
                            let m = n.max(1) * 8;
                            rx[(b % m) / 8] ^= 1 << (b % 8);
                        }
                        s.work();
                        let ok = pec::strip(Address::new(DB).unwrap().addr_byte(true), &rx[..n])
                            .ok()
                            .and_then(|body| Reply::parse(body).ok())
                            .map(|r| (r.seq, r.status));
                        match ok {
                            Some((q, st)) if q == seq => break st,
                            _ => continue,
                        }
                    }
                    None => {
                        s.handle_write(&f);
                        let r = reply(&mut s);
                        s.work();
                        match r {
                            Some((q, st)) if q == seq => break st,
                            _ => continue,
                        }
                    }
                }
            };
            prop_assert_eq!(status, Status::Ok, "request {}", i);
        }
        prop_assert_eq!(s.exit(), Exit::Reset);
        drop(s);
        prop_assert_eq!(board.state_magic(), State::Swap);
        let mem = board.mem.borrow();
        let dfu = &mem[STATE + ACTIVE..STATE + ACTIVE + new.len()];
        prop_assert!(dfu == &new[..], "the committed slot differs from the image sent");
    }
}
