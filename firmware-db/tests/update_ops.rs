//! The application's two firmware-update operations (issue 25): System 12 `enter_update`
//! through the record's hook, answered `ok`, then the board restarts (as after a move to its own
//! address) once the reply has been read; System 13 `confirm_firmware` through its hook;
//! `unsupported` and `busy` when the hooks say so; function 7 is the bootloader's.

mod common;

use std::cell::RefCell;
use std::rc::Rc;

use common::{FakePorts, TestClock};
use embassy_sync::blocking_mutex::raw::NoopRawMutex;
use firmware_db::{AddressRecord, Daughterboard, DbConfig, StoreError};
use x10_microcode::{Address, BoardKind};

#[derive(Clone, Default)]
struct Hooks {
    calls: Rc<RefCell<Vec<&'static str>>>,
    fail: bool,
}

impl AddressRecord for Hooks {
    fn load(&mut self) -> Option<Address> {
        None
    }

    fn store(&mut self, _: Address) -> Result<(), StoreError> {
        Err(StoreError::NoRecord)
    }

    fn enter_update(&mut self) -> Result<(), StoreError> {
        self.calls.borrow_mut().push("enter_update");
        if self.fail {
            Err(StoreError::Failed)
        } else {
            Ok(())
        }
    }

    fn confirm_firmware(&mut self) -> Result<(), StoreError> {
        self.calls.borrow_mut().push("confirm_firmware");
        if self.fail {
            Err(StoreError::Failed)
        } else {
            Ok(())
        }
    }
}

fn board<R: AddressRecord>(record: R) -> Daughterboard<NoopRawMutex, FakePorts, R> {
    let cfg = DbConfig::new(Address::new(0x2a).unwrap(), BoardKind::SIMULATED);
    Daughterboard::with_record(FakePorts::new(TestClock::new(), 2, 2), cfg, record)
}

fn exchange<R: AddressRecord>(
    db: &Daughterboard<NoopRawMutex, FakePorts, R>,
    req: &[u8],
) -> Vec<u8> {
    db.handle_write(req, true);
    let mut buf = [0u8; 40];
    let n = db.take_reply(&mut buf);
    buf[..n].to_vec()
}

fn restarting<R: AddressRecord>(db: &Daughterboard<NoopRawMutex, FakePorts, R>) -> Option<Address> {
    let mut f = core::pin::pin!(db.moved());
    let waker = std::task::Waker::noop();
    match f.as_mut().poll(&mut std::task::Context::from_waker(waker)) {
        std::task::Poll::Ready(a) => Some(a),
        std::task::Poll::Pending => None,
    }
}

use std::future::Future;

#[test]
fn enter_update_answers_ok_then_restarts_once_read() {
    let hooks = Hooks::default();
    let db = board(hooks.clone());
    db.handle_write(&[0x0c, 0x2a, 0x00, 0x05], true);
    assert_eq!(*hooks.calls.borrow(), ["enter_update"]);
    db.served();
    assert_eq!(restarting(&db), None, "not before the reply is read");
    let mut buf = [0u8; 8];
    let n = db.take_reply(&mut buf);
    assert_eq!(buf[..n], [0x05, 0x00, 0x00]);
    db.served();
    assert_eq!(restarting(&db), Some(Address::new(0x2a).unwrap()));
}

#[test]
fn confirm_firmware_goes_through_its_hook_and_does_not_restart() {
    let hooks = Hooks::default();
    let db = board(hooks.clone());
    assert_eq!(exchange(&db, &[0x0d, 0x2a, 0x00, 0x06]), [0x06, 0x00, 0x00]);
    assert_eq!(*hooks.calls.borrow(), ["confirm_firmware"]);
    db.served();
    assert_eq!(restarting(&db), None);
}

#[test]
fn failing_hooks_answer_busy_and_nothing_restarts() {
    let db = board(Hooks {
        fail: true,
        ..Hooks::default()
    });
    assert_eq!(exchange(&db, &[0x0c, 0x2a, 0x00, 0x07]), [0x07, 0x0b, 0x00]);
    assert_eq!(exchange(&db, &[0x0d, 0x2a, 0x00, 0x08]), [0x08, 0x0b, 0x00]);
    db.served();
    assert_eq!(restarting(&db), None);
}

#[test]
fn without_a_bootloader_enter_update_is_unsupported_and_confirm_is_ok() {
    let db = board(firmware_db::NoRecord);
    assert_eq!(exchange(&db, &[0x0c, 0x2a, 0x00, 0x09]), [0x09, 0x0a, 0x00]);
    assert_eq!(exchange(&db, &[0x0d, 0x2a, 0x00, 0x0a]), [0x0a, 0x00, 0x00]);
    db.served();
    assert_eq!(restarting(&db), None);
}

#[test]
fn function_7_is_the_bootloader_s_and_no_update_op_goes_in_a_batch() {
    let db = board(Hooks::default());
    // status, commit: unsupported by an application.
    assert_eq!(exchange(&db, &[0x73, 0x2a, 0x00, 0x0b]), [0x0b, 0x0a, 0x00]);
    assert_eq!(exchange(&db, &[0x72, 0x2a, 0x00, 0x0c]), [0x0c, 0x0a, 0x00]);
    // A batch holding an enter_update: bad_argument, nothing called.
    assert_eq!(
        exchange(&db, &[0x50, 0x2a, 0x00, 0x0d, 0x0c, 0x00, 0x00]),
        [0x0d, 0x09, 0x00]
    );
}
