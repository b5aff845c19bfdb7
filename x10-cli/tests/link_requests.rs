//! The laptop's side of the plug-and-play and update requests (link version 2): `Robot`'s
//! requests go out as the exact frames of docs/usb-link.md, a board list of several pages is
//! put together, the answers and update records come out in words, and a motherboard of link
//! version 1 (which refuses the new requests) is reported as such. The motherboard's side is
//! tested in x10-link (tests/requests.rs, on the simulated motherboard).

use std::collections::VecDeque;
use std::io::{Read, Write};
use std::time::Duration;

use x10_cli::link_requests::{
    assign_text, board_line, boards_text, parse_address, parse_uid, update_status_text, update_text,
};
use x10_cli::monitor::{Robot, RobotError};
use x10_link::{
    encode, encode_host, AssignStatus, BoardEntry, BoardState, CallError, Feed, FrameReader,
    ToDevice, ToHost, UpdateFailure, UpdatePhase, UpdateRec, UpdateStatus, MAX_FRAME,
};

const UID: [u8; 8] = [0xe6, 0x61, 0x38, 0x52, 0x83, 0x3f, 0x5c, 0x2a];

/// The fake motherboard's answers to a request.
type Answerer = dyn FnMut(&ToDevice<'_>) -> Vec<ToHost<'static>>;

/// A motherboard standing on the other side of the port: every request written is decoded
/// (kept in `requests`, Rust's `Debug` form) and answered by `answer`.
struct FakeMb {
    reader: FrameReader<{ MAX_FRAME }>,
    requests: std::rc::Rc<std::cell::RefCell<Vec<String>>>,
    out: VecDeque<u8>,
    answer: Box<Answerer>,
}

impl FakeMb {
    fn new(answer: impl FnMut(&ToDevice<'_>) -> Vec<ToHost<'static>> + 'static) -> FakeMb {
        FakeMb {
            reader: FrameReader::new(),
            requests: Default::default(),
            out: VecDeque::new(),
            answer: Box::new(answer),
        }
    }
}

impl Write for FakeMb {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        for &b in buf {
            if self.reader.feed(b) == Feed::Frame {
                let req = self.reader.decode_device().unwrap();
                self.requests.borrow_mut().push(format!("{req:?}"));
                for m in (self.answer)(&req) {
                    let mut f = [0u8; MAX_FRAME];
                    let n = encode_host(&m, &mut f).unwrap();
                    self.out.extend(&f[..n]);
                }
            }
        }
        Ok(buf.len())
    }

    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

impl Read for FakeMb {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        if self.out.is_empty() {
            return Err(std::io::ErrorKind::TimedOut.into());
        }
        let n = buf.len().min(self.out.len());
        for (slot, b) in buf.iter_mut().zip(self.out.drain(..n)) {
            *slot = b;
        }
        Ok(n)
    }
}

fn board(n: u8) -> BoardEntry {
    BoardEntry {
        address: 0x20 + n,
        uid: [n; 8],
        kind: 3,
        firmware: [0, 1, n],
        state: if n.is_multiple_of(2) {
            BoardState::Present
        } else {
            BoardState::Lost
        },
    }
}

#[test]
fn the_board_list_is_asked_page_by_page_and_printed() {
    // Eleven boards: a page of 8, then 3.
    let all: Vec<BoardEntry> = (0..11).map(board).collect();
    let pages = all.clone();
    let mb = FakeMb::new(move |req| match *req {
        ToDevice::Boards { id, first } => vec![ToHost::BoardList {
            id,
            total: 11,
            first,
            boards: pages
                .iter()
                .skip(usize::from(first))
                .take(8)
                .copied()
                .collect(),
        }],
        _ => vec![],
    });
    let mut robot = Robot::new(mb).unwrap();
    assert_eq!(robot.board_list().unwrap(), all);
    assert_eq!(
        boards_text(&all[..2]),
        "0x20  0000000000000000  Pico       0.1.0    present\n\
         0x21  0101010101010101  Pico       0.1.1    lost\n"
    );
    assert_eq!(boards_text(&[]), "no board known yet\n");
    let mut updating = board(2);
    updating.state = BoardState::Updating;
    updating.kind = 5;
    assert_eq!(
        board_line(&updating),
        "0x22  0202020202020202  STM32C011  0.1.2    updating"
    );
}

#[test]
fn requests_go_out_as_the_documented_frames() {
    let mb = FakeMb::new(|req| match *req {
        ToDevice::Assign { id, .. } => vec![ToHost::Assigned {
            id,
            status: AssignStatus::Done,
        }],
        // The board, at its new address.
        ToDevice::Boards { id, .. } => vec![ToHost::BoardList {
            id,
            total: 1,
            first: 0,
            boards: std::iter::once(BoardEntry {
                address: 0x40,
                uid: UID,
                kind: 3,
                firmware: [0, 1, 0],
                state: BoardState::Present,
            })
            .collect(),
        }],
        ToDevice::Update { id, .. } => vec![ToHost::UpdateAnswer {
            id,
            status: UpdateStatus::Started(1),
        }],
        _ => vec![],
    });
    let requests = mb.requests.clone();
    let mut robot = Robot::new(mb).unwrap();
    assert_eq!(robot.assign(UID, 0x40).unwrap(), AssignStatus::Done);
    assert_eq!(
        robot.start_update(Some(UID)).unwrap(),
        UpdateStatus::Started(1)
    );
    assert_eq!(robot.start_update(None).unwrap(), UpdateStatus::Started(1));
    assert_eq!(
        requests.borrow()[1..],
        [
            "Assign { id: 1, uid: [230, 97, 56, 82, 131, 63, 92, 42], address: 64 }",
            "Boards { id: 2, first: 0 }",
            "Update { id: 3, uid: Some([230, 97, 56, 82, 131, 63, 92, 42]) }",
            "Update { id: 4, uid: None }",
        ]
    );
    assert!(requests.borrow()[0].starts_with("Hello(Hello { version: 2,"));
    // The frames of docs/usb-link.md (ids 12, 14 and 16 there; the robot numbers from 1).
    let mut f = [0u8; MAX_FRAME];
    let n = encode(
        &ToDevice::Assign {
            id: 12,
            uid: UID,
            address: 0x40,
        },
        &mut f,
    )
    .unwrap();
    assert_eq!(
        f[..n],
        [
            0x0e, 0x06, 0x0c, 0xe6, 0x61, 0x38, 0x52, 0x83, 0x3f, 0x5c, 0x2a, 0x40, 0x46, 0x9a,
            0x00
        ]
    );
}

#[test]
fn an_update_is_followed_to_its_end_in_words() {
    let rec = |phase, at_us| {
        ToHost::Update(UpdateRec {
            db: 0x20,
            from: [0, 1, 0],
            to: [2, 0, 0],
            phase,
            at_us,
        })
    };
    let mb = FakeMb::new(move |req| match *req {
        ToDevice::Update { id, .. } => vec![
            ToHost::UpdateAnswer {
                id,
                status: UpdateStatus::Started(1),
            },
            rec(UpdatePhase::Started, 1_000),
            rec(UpdatePhase::Done, 15_000_000),
        ],
        _ => vec![],
    });
    let mut robot = Robot::new(mb).unwrap();
    let from = robot.run.updates.len();
    assert_eq!(
        robot.start_update(Some(UID)).unwrap(),
        UpdateStatus::Started(1)
    );
    let records = robot
        .wait_updates(from, 1, Duration::from_millis(200))
        .unwrap();
    let lines: Vec<String> = records.iter().map(update_text).collect();
    assert_eq!(
        lines,
        [
            "board 0x20: updating 0.1.0 \u{2192} 2.0.0 ...",
            "board 0x20: updating 0.1.0 \u{2192} 2.0.0 ... done",
        ]
    );
    // No second update ends: a typed timeout, not a hang.
    assert!(matches!(
        robot.wait_updates(records.len(), 1, Duration::from_millis(20)),
        Err(RobotError::NoAnswer)
    ));
    let failed = UpdateRec {
        db: 0x20,
        from: [0, 1, 0],
        to: [2, 0, 0],
        phase: UpdatePhase::Failed(UpdateFailure::RolledBack),
        at_us: 0,
    };
    assert_eq!(
        update_text(&failed),
        "board 0x20: updating 0.1.0 \u{2192} 2.0.0 ... failed: it came back with its old version (rolled back)"
    );
}

#[test]
fn a_motherboard_of_link_version_1_refuses_and_is_told_apart() {
    // A version-1 motherboard cannot decode the new requests: it answers `Refused { id: 0 }`.
    let mb = FakeMb::new(|req| match req {
        ToDevice::Hello(_) => vec![],
        _ => vec![ToHost::Refused { id: 0 }],
    });
    let mut robot = Robot::new(mb).unwrap();
    robot.timeout = Duration::from_millis(200);
    let e = robot.board_list().unwrap_err();
    assert!(matches!(e, RobotError::Refused), "{e}");
    assert!(e.to_string().contains("older link version"), "{e}");
    assert!(matches!(robot.assign(UID, 0x40), Err(RobotError::Refused)));
}

#[test]
fn answers_and_arguments_in_words() {
    assert_eq!(parse_uid("e6613852833f5c2a"), Ok(UID));
    assert_eq!(parse_uid("e6:61:38:52:83:3f:5c:2a"), Ok(UID));
    assert!(parse_uid("e6613852833f5c").is_err());
    assert!(parse_uid("zz613852833f5c2a").is_err());
    assert!(parse_uid("é6613852833f5c2").is_err());
    assert_eq!(parse_address("0x40"), Ok(0x40));
    assert_eq!(parse_address("64"), Ok(64));
    assert!(parse_address("0x140").is_err());
    assert_eq!(
        assign_text(UID, 0x40, &AssignStatus::Done),
        "board e6613852833f5c2a answers at 0x40"
    );
    assert_eq!(
        assign_text(UID, 0x40, &AssignStatus::NotConfirmed(CallError::Timeout)),
        "board e6613852833f5c2a did not confirm 0x40: no reply in time"
    );
    assert_eq!(
        assign_text(UID, 0x64, &AssignStatus::Reserved),
        "0x64 is reserved (a board takes 0x08..=0x76, not the motherboard's own, not 0x64)"
    );
    assert_eq!(
        update_status_text(&UpdateStatus::Busy(0x20)),
        "busy: board 0x20 is being updated"
    );
    assert_eq!(
        update_status_text(&UpdateStatus::NoImages),
        "refused: this motherboard image carries no daughterboard images"
    );
}
