//! parse → emit → parse on arbitrary bytes, for every frame kind, with and without PEC.
//!
//! The first input byte chooses the frame kind (and PEC); the rest is the frame. Whatever
//! parses must re-emit to exactly the input bytes (the encoding is canonical) and parse again to
//! the same value. Parsing must never panic; a panic or a failed assertion here is a bug.
#![no_main]

use libfuzzer_sys::fuzz_target;
use x10_microcode::{Address, Event, Reply, Request, MAX_FRAME_LEN};

fuzz_target!(|input: &[u8]| {
    let Some((&selector, bytes)) = input.split_first() else {
        return;
    };
    // A board and an MB address for the PEC variants.
    let Ok(db) = Address::new(0x09) else { return };
    let Ok(mb) = Address::new(0x10) else { return };
    let mut out = [0u8; MAX_FRAME_LEN + 1];
    match selector % 6 {
        0 => {
            if let Ok(r) = Request::parse(bytes) {
                let n = r.emit(&mut out).expect("a parsed request re-emits");
                assert_eq!(&out[..n], bytes);
                assert_eq!(Request::parse(&out[..n]), Ok(r));
            }
        }
        1 => {
            // The PEC covers the address the frame was sent to (`db`), whatever byte 1 says;
            // `emit_with_pec` covers `r.db`, so re-emit the frame and add the PEC for `db`.
            if let Ok(r) = Request::parse_with_pec(db, bytes) {
                let n = r.emit(&mut out).expect("a parsed request re-emits");
                let n = x10_microcode::pec::append(db.addr_byte(false), &mut out, n)
                    .expect("room for the PEC byte");
                assert_eq!(&out[..n], bytes);
                assert_eq!(Request::parse_with_pec(db, &out[..n]), Ok(r));
            }
        }
        2 => {
            if let Ok(r) = Reply::parse(bytes) {
                let n = r.emit(&mut out).expect("a parsed reply re-emits");
                assert_eq!(&out[..n], bytes);
                assert_eq!(Reply::parse(&out[..n]), Ok(r));
            }
        }
        3 => {
            let pec_on = selector & 0x80 != 0;
            if let Ok(r) = Reply::parse_read(db, pec_on, bytes) {
                let n = if pec_on {
                    r.emit_with_pec(db, &mut out)
                } else {
                    r.emit(&mut out)
                }
                .expect("a parsed reply re-emits");
                assert_eq!(&out[..n], &bytes[..n]);
                assert_eq!(Reply::parse_read(db, pec_on, &out[..n]), Ok(r));
            }
        }
        4 => {
            if let Ok(e) = Event::parse(bytes) {
                let n = e.emit(&mut out).expect("a parsed event re-emits");
                assert_eq!(&out[..n], bytes);
                assert_eq!(Event::parse(&out[..n]), Ok(e));
            }
        }
        _ => {
            if let Ok(e) = Event::parse_with_pec(mb, bytes) {
                let n = e
                    .emit_with_pec(mb, &mut out)
                    .expect("a parsed event re-emits");
                assert_eq!(&out[..n], bytes);
                assert_eq!(Event::parse_with_pec(mb, &out[..n]), Ok(e));
            }
        }
    }
});
