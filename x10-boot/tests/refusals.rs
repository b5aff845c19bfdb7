//! Every refusal of the update session is a status of its own, and none changes the active
//! slot or marks anything for a swap.

mod common;

use common::*;
use embassy_boot::{BlockingFirmwareState, State};
use x10_boot::{Exit, Session};
use x10_microcode::{
    pec, Address, BoardKind, ImageInfo, Reply, Status, UpdateOp, UpdateReport, UpdateState,
    CHUNK_MAX,
};

const OLD: [u8; 3] = [0, 2, 0];
const NEW: [u8; 3] = [0, 3, 0];

/// Runs `f` on a session over a board holding the old image, then checks that the active slot
/// and the state are untouched (unless `f` committed).
fn with_session(f: impl FnOnce(&mut Session<'_, Part, Part, BUF>)) -> Board {
    let old = image(20_000, OLD, 1);
    let board = Board::new(&old);
    let power = Power::new(None, Cut::Clean);
    board.enter_update(&power).unwrap();
    {
        let mut aligned = [0u8; WRITE];
        let st = BlockingFirmwareState::new(board.part(0, &power), &mut aligned);
        let mut s = Session::new(config(), board.part(2, &power), st);
        f(&mut s);
    }
    assert!(board.active_is(&old));
    board
}

fn refused(board: Board) {
    assert_eq!(board.state_magic(), State::DfuDetach);
}

#[test]
fn wrong_kind_too_large_too_old_are_refused_at_begin() {
    let img = image(4_000, NEW, 2);
    refused(with_session(|s| {
        let mut i = info(&img, NEW);
        i.board = BoardKind::G431;
        assert_eq!(call(s, 1, UpdateOp::Begin(i)).0, Status::WrongKind);
        let mut i = info(&img, NEW);
        i.len = (DFU - ERASE + 1) as u32;
        assert_eq!(call(s, 2, UpdateOp::Begin(i)).0, Status::TooLarge);
        i.len = 0;
        assert_eq!(call(s, 3, UpdateOp::Begin(i)).0, Status::TooLarge);
        assert_eq!(
            call(s, 4, UpdateOp::Begin(info(&img, [0, 1, 9]))).0,
            Status::TooOld
        );
        // Nothing begun: a chunk or a commit has no session.
        let chunk = UpdateOp::Chunk {
            offset: 0,
            data: &img[..CHUNK_MAX],
        };
        assert_eq!(call(s, 5, chunk).0, Status::NoSession);
        assert_eq!(call(s, 6, UpdateOp::Commit).0, Status::NoSession);
        assert_eq!(
            status(s),
            UpdateReport {
                state: UpdateState::Idle,
                received: 0,
                last_error: Status::NoSession
            }
        );
    }));
}

#[test]
fn corrupt_image_is_refused_at_commit() {
    let img = image(5_000, NEW, 3);
    let board = with_session(|s| {
        let mut sent = img.clone();
        sent[4_321] ^= 0x10;
        let (st, _) = call(s, 1, UpdateOp::Begin(info(&img, NEW)));
        assert_eq!(st, Status::Ok);
        for (i, c) in sent.chunks(CHUNK_MAX).enumerate() {
            let op = UpdateOp::Chunk {
                offset: (i * CHUNK_MAX) as u32,
                data: c,
            };
            assert_eq!(call(s, i as u8, op).0, Status::Ok);
        }
        assert_eq!(call(s, 7, UpdateOp::Commit).0, Status::BadCrc);
        assert_eq!(s.exit(), Exit::Stay);
        assert_eq!(status(s).state, UpdateState::Idle);
        // The right image then goes through.
        assert_eq!(transfer(s, &img, NEW), Status::Ok);
        assert_eq!(s.exit(), Exit::Reset);
    });
    assert_eq!(board.state_magic(), State::Swap);
}

#[test]
fn truncated_image_is_refused_at_commit() {
    let img = image(5_000, NEW, 4);
    refused(with_session(|s| {
        assert_eq!(call(s, 1, UpdateOp::Begin(info(&img, NEW))).0, Status::Ok);
        for (i, c) in img[..4_800].chunks(CHUNK_MAX).enumerate() {
            let op = UpdateOp::Chunk {
                offset: (i * CHUNK_MAX) as u32,
                data: c,
            };
            assert_eq!(call(s, 2, op).0, Status::Ok);
        }
        assert_eq!(call(s, 3, UpdateOp::Commit).0, Status::Incomplete);
        assert_eq!(
            status(s),
            UpdateReport {
                state: UpdateState::Receiving,
                received: 4_800,
                last_error: Status::Incomplete
            }
        );
    }));
}

#[test]
fn chunks_out_of_order_are_refused_and_a_repeat_is_idempotent() {
    let img = image(3_000, NEW, 5);
    let board = with_session(|s| {
        assert_eq!(call(s, 1, UpdateOp::Begin(info(&img, NEW))).0, Status::Ok);
        let c = |i: usize| UpdateOp::Chunk {
            offset: (i * CHUNK_MAX) as u32,
            data: &img[i * CHUNK_MAX..((i + 1) * CHUNK_MAX).min(img.len())],
        };
        assert_eq!(call(s, 2, c(0)).0, Status::Ok);
        // Skipping one: refused; the one before the last: refused.
        assert_eq!(call(s, 3, c(2)).0, Status::OutOfOrder);
        assert_eq!(call(s, 4, c(1)).0, Status::Ok);
        assert_eq!(call(s, 5, c(0)).0, Status::OutOfOrder);
        // The last one again (its reply was lost): ok, nothing taken twice.
        assert_eq!(call(s, 6, c(1)).0, Status::Ok);
        assert_eq!(status(s).received, 2 * CHUNK_MAX as u32);
        // The same offset with other bytes' length is no repeat.
        let short = UpdateOp::Chunk {
            offset: CHUNK_MAX as u32,
            data: &img[CHUNK_MAX..CHUNK_MAX + 3],
        };
        assert_eq!(call(s, 7, short).0, Status::OutOfOrder);
        // A chunk that runs past the end.
        let n = img.len().div_ceil(CHUNK_MAX);
        for i in 2..n {
            assert_eq!(call(s, 8, c(i)).0, Status::Ok);
        }
        let past = UpdateOp::Chunk {
            offset: img.len() as u32,
            data: &[1],
        };
        assert_eq!(call(s, 9, past).0, Status::TooLarge);
        assert_eq!(call(s, 10, UpdateOp::Commit).0, Status::Ok);
        assert_eq!(s.exit(), Exit::Reset);
    });
    assert_eq!(board.state_magic(), State::Swap);
    let power = Power::new(None, Cut::Clean);
    board.start(&power).unwrap();
    assert!(board.active_is(&img));
}

#[test]
fn a_chunk_past_the_length_is_too_large() {
    let img = image(100, NEW, 6);
    refused(with_session(|s| {
        assert_eq!(call(s, 1, UpdateOp::Begin(info(&img, NEW))).0, Status::Ok);
        let op = UpdateOp::Chunk {
            offset: 0,
            data: &img[..24],
        };
        assert_eq!(call(s, 2, op).0, Status::Ok);
        for i in 1..4 {
            let op = UpdateOp::Chunk {
                offset: 24 * i,
                data: &img[24 * i as usize..24 * (i as usize + 1)],
            };
            assert_eq!(call(s, 3, op).0, Status::Ok);
        }
        // 96 of 100 taken; 24 more would run past the end.
        let op = UpdateOp::Chunk {
            offset: 96,
            data: &[0; 24],
        };
        assert_eq!(call(s, 4, op).0, Status::TooLarge);
    }));
}

#[test]
fn frames_without_their_check_or_for_another_board_are_refused() {
    refused(with_session(|s| {
        let info = ImageInfo {
            len: 10,
            crc32: 0,
            board: KIND,
            version: NEW,
        };
        let mut data = [0u8; 28];
        let req = x10_microcode::Request {
            db: Address::new(DB).unwrap(),
            seq: 9,
            op: UpdateOp::Begin(info).to_op(&mut data),
        };
        let mut buf = [0u8; 40];
        let n = req.emit(&mut buf).unwrap();
        // No check at all: the last two bytes are taken as a CRC-16 and do not match.
        s.handle_write(&buf[..n]);
        assert_eq!(read_reply(s, 9).0, Status::PecMismatch);
        assert_eq!(s.pec_errors(), 1);
        // Another board's address, with its right check.
        let other = x10_microcode::Request {
            db: Address::new(0x2b).unwrap(),
            ..req
        };
        let n = other.emit(&mut buf).unwrap();
        let n = pec::append(Address::new(DB).unwrap().addr_byte(false), &mut buf, n).unwrap();
        s.handle_write(&buf[..n]);
        assert_eq!(read_reply(s, 9).0, Status::WrongAddress);
        // An application operation: unsupported in update mode; a ping is answered.
        let ping = x10_microcode::Request {
            db: Address::new(DB).unwrap(),
            seq: 3,
            op: x10_microcode::Op::Ping,
        };
        let n = ping.emit_with_pec(&mut buf).unwrap();
        s.handle_write(&buf[..n]);
        assert_eq!(read_reply(s, 3).0, Status::Ok);
        let id = x10_microcode::Request {
            op: x10_microcode::Op::Identify,
            ..ping
        };
        let n = id.emit_with_pec(&mut buf).unwrap();
        s.handle_write(&buf[..n]);
        assert_eq!(read_reply(s, 3).0, Status::Unsupported);
        // A read with nothing held.
        let mut rx = [0u8; 8];
        let n = s.take_reply(&mut rx);
        let body = pec::strip(Address::new(DB).unwrap().addr_byte(true), &rx[..n]).unwrap();
        assert_eq!(Reply::parse(body).unwrap().status, Status::NoRequest);
    }));
}

#[test]
fn leave_boots_the_current_image() {
    let board = with_session(|s| {
        assert_eq!(call(s, 1, UpdateOp::Leave).0, Status::Ok);
        assert_eq!(s.exit(), Exit::Leave);
    });
    assert_eq!(board.state_magic(), State::Boot);
    let power = Power::new(None, Cut::Clean);
    let (state, mode) = board.start(&power).unwrap();
    assert_eq!(
        (state, mode),
        (State::Boot, x10_boot::StartMode::Application)
    );
}

#[test]
fn the_exit_waits_for_the_reply_to_be_read() {
    with_session(|s| {
        let mut data = [0u8; 28];
        let req = x10_microcode::Request {
            db: Address::new(DB).unwrap(),
            seq: 1,
            op: UpdateOp::Leave.to_op(&mut data),
        };
        let mut buf = [0u8; 16];
        let n = req.emit_with_pec(&mut buf).unwrap();
        s.handle_write(&buf[..n]);
        assert_eq!(s.exit(), Exit::Stay);
        assert_eq!(read_reply(s, 1).0, Status::Ok);
        assert_eq!(s.exit(), Exit::Leave);
    });
}

#[test]
fn flash_work_waits_until_the_reply_has_been_read() {
    let old = image(20_000, OLD, 1);
    let board = Board::new(&old);
    let power = Power::new(None, Cut::Clean);
    let mut aligned = [0u8; WRITE];
    let st = BlockingFirmwareState::new(board.part(0, &power), &mut aligned);
    let mut s: Session<'_, Part, Part, BUF> = Session::new(config(), board.part(2, &power), st);
    let img = image(300, NEW, 7);
    let send = |s: &mut Session<'_, Part, Part, BUF>, op: UpdateOp<'_>| {
        let mut data = [0u8; 28];
        let req = x10_microcode::Request {
            db: Address::new(DB).unwrap(),
            seq: 1,
            op: op.to_op(&mut data),
        };
        let mut buf = [0u8; 40];
        let n = req.emit_with_pec(&mut buf).unwrap();
        s.handle_write(&buf[..n]);
        let mut rx = [0u8; 40];
        s.take_reply(&mut rx);
    };
    // begin: answered without touching the flash; the first sector's erase follows.
    send(&mut s, UpdateOp::Begin(info(&img, NEW)));
    assert_eq!(power.ops.get(), 0);
    s.work();
    assert_eq!(power.ops.get(), 1);
    // Chunks up to the buffer's 256 bytes: no flash; the one that fills it leaves a write.
    for i in 0..11 {
        let op = UpdateOp::Chunk {
            offset: (i * CHUNK_MAX) as u32,
            data: &img[i * CHUNK_MAX..(i + 1) * CHUNK_MAX],
        };
        send(&mut s, op);
        assert_eq!(power.ops.get(), 1, "chunk {i}");
        s.work();
    }
    // 264 bytes taken: the 11th chunk filled the buffer; its write came after its reply.
    assert_eq!(power.ops.get(), 2);
    let rest = UpdateOp::Chunk {
        offset: 264,
        data: &img[264..288],
    };
    send(&mut s, rest);
    s.work();
    let last = UpdateOp::Chunk {
        offset: 288,
        data: &img[288..],
    };
    send(&mut s, last);
    s.work();
    assert_eq!(power.ops.get(), 2);
    // commit: the tail is written and read back before the reply; the mark after it.
    send(&mut s, UpdateOp::Commit);
    assert_eq!(power.ops.get(), 3);
    assert_eq!(s.exit(), Exit::Stay);
    s.work();
    assert_eq!(s.exit(), Exit::Reset);
    assert_eq!(board.state_magic(), State::Swap);
}

#[test]
fn after_a_commit_a_repeated_commit_is_ok_and_a_new_begin_is_busy() {
    let old = image(20_000, OLD, 1);
    let new = image(6_000, NEW, 5);
    let board = Board::new(&old);
    let power = Power::new(None, Cut::Clean);
    board.enter_update(&power).unwrap();
    {
        let mut aligned = [0u8; WRITE];
        let st = BlockingFirmwareState::new(board.part(0, &power), &mut aligned);
        let mut s: Session<'_, Part, Part, BUF> = Session::new(config(), board.part(2, &power), st);
        assert_eq!(transfer(&mut s, &new, NEW), Status::Ok);
        // The commit's reply was lost: the motherboard sends it again.
        assert_eq!(call(&mut s, 7, UpdateOp::Commit).0, Status::Ok);
        // A begin now would write into the slot the swap reads.
        assert_eq!(
            call(&mut s, 8, UpdateOp::Begin(info(&old, [0, 4, 0]))).0,
            Status::Busy
        );
        assert_eq!(status(&mut s).state, UpdateState::Committed);
        assert_eq!(s.exit(), Exit::Reset);
    }
    assert_eq!(board.state_magic(), State::Swap);
    board.start(&power).unwrap();
    assert!(board.active_is(&new));
}
