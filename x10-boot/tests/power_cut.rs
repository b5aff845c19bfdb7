//! A power cut at every flash operation of a whole update (the application's `enter_update`,
//! the transfer, the commit, embassy-boot's swap in `prepare_boot`, the new image's confirm):
//! after each, the board starts the old image or the new one (never neither), an unconfirmed
//! new image is rolled back at the next reset, and the board can still be updated.

mod common;

use std::rc::Rc;

use common::*;
use embassy_boot::State;
use x10_boot::{Exit, StartMode};
use x10_microcode::Status;

const V1: [u8; 3] = [0, 2, 0];
const V2: [u8; 3] = [0, 3, 0];
const V3: [u8; 3] = [0, 4, 0];

/// The steps of one update, as the motherboard drives them; stops at the first failed flash
/// operation (the power is gone). True when every step ran.
fn full_cycle(board: &Board, power: &Rc<Power>, img: &[u8], version: [u8; 3]) -> bool {
    if board.enter_update(power).is_err() {
        return false;
    }
    let Ok((state, mode)) = board.start(power) else {
        return false;
    };
    assert_eq!((state, mode), (State::DfuDetach, StartMode::Update));
    let (status, exit) = update_mode(board, power, img, version);
    if power.dead() {
        return false;
    }
    assert_eq!((status, exit), (Status::Ok, Exit::Reset));
    let Ok((state, mode)) = board.start(power) else {
        return false;
    };
    assert_eq!((state, mode), (State::Swap, StartMode::Application));
    assert!(board.active_is(img));
    if board.confirm(power).is_err() {
        return false;
    }
    let Ok((state, _)) = board.start(power) else {
        return false;
    };
    assert_eq!(state, State::Boot);
    !power.dead()
}

fn every_cut(cut: Cut) -> u64 {
    let v1 = image(20_000, V1, 1);
    let v2 = image(ACTIVE, V2, 2);
    let v3 = image(31_001, V3, 3);
    // The operations of a whole update with the power on.
    let board = Board::new(&v1);
    let on = Power::new(None, cut);
    assert!(full_cycle(&board, &on, &v2, V2));
    assert!(board.active_is(&v2));
    let total = on.ops.get();
    let (mut old, mut new, mut rolled_back) = (0, 0, 0);
    for n in 0..=total {
        let board = Board::new(&v1);
        let power = Power::new(Some(n), cut);
        let done = full_cycle(&board, &power, &v2, V2);
        assert_eq!(done, n == total, "cut after {n} of {total}");
        // Power back: the board starts.
        let on = Power::new(None, cut);
        let (state, mode) = board.start(&on).expect("start");
        let is_old = board.active_is(&v1);
        let is_new = board.active_is(&v2);
        assert!(is_old ^ is_new, "cut after {n}: neither image ({state:?})");
        if is_old {
            old += 1;
        } else {
            new += 1;
        }
        if state == State::Swap && board.state_magic() == State::Swap {
            // The new image runs unconfirmed; it never answers the MB: the next reset rolls it
            // back. (`prepare_boot` returns the state it found, `Swap`, and leaves the revert
            // mark.)
            assert!(is_new, "cut after {n}");
            assert_eq!(mode, StartMode::Application);
            let (state, mode) = board.start(&on).expect("start");
            assert_eq!(
                (state, mode),
                (State::Swap, StartMode::Application),
                "cut after {n}"
            );
            assert_eq!(board.state_magic(), State::Revert, "cut after {n}");
            assert!(board.active_is(&v1), "cut after {n}: not rolled back");
            rolled_back += 1;
        } else if state == State::Swap {
            // A cut in the confirm: before it invalidated the swap's progress, the image is
            // taken as unconfirmed and rolled back at this start; after, embassy-boot's revert
            // finds no progress to undo and the confirmed new image stays (marked `Revert`,
            // which counts as booted).
            assert_eq!(board.state_magic(), State::Revert, "cut after {n}");
            if is_old {
                rolled_back += 1;
            }
        }
        // And it can still be updated.
        assert!(
            full_cycle(&board, &on, &v3, V3),
            "cut after {n}: no update after"
        );
        assert!(board.active_is(&v3), "cut after {n}");
        assert_eq!(board.state_magic(), State::Boot);
    }
    assert!(
        old > 0 && new > 0 && rolled_back > 0,
        "{old} {new} {rolled_back}"
    );
    println!("{cut:?}: {total} flash operations, {old} cuts left the old image, {new} the new one, {rolled_back} rolled back");
    total
}

#[test]
fn power_cut_at_every_operation_clean() {
    let total = every_cut(Cut::Clean);
    // 8 erases and 128 writes of the transfer, the state's magic 3 times, the swap's
    // 8 pages × 2 copies, each an erase, 16 writes and a progress write (and a few more).
    assert!(total > 8 + 128 + 8 * 2 * 18, "{total}");
}

#[test]
fn power_cut_at_every_operation_torn() {
    every_cut(Cut::Torn);
}
