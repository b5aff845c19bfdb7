//! Plug and play (issue 24): the unique ID, the reserved address, `BootInfo` with and without
//! the ID, and the operations that move a board.

use x10_microcode::{
    Address, BatchWriter, BoardKind, BootInfo, Capabilities, Error, Identity, Op, Request,
    ResetReason, Uid,
};

const UID: Uid = Uid([0xe6, 0x61, 0x38, 0x52, 0x83, 0x3f, 0x5c, 0x2a]);

fn identity() -> Identity {
    Identity {
        protocol_version: 1,
        firmware: [0, 1, 0],
        board: BoardKind::PICO,
        sensor_ports: 4,
        actuator_ports: 4,
        capabilities: Capabilities(0x01ff),
        adc_bits: 12,
    }
}

#[test]
fn assignable_addresses_are_the_external_range_without_0x77() {
    for raw in 0u8..=0xff {
        let ok = (0x08..=0x76).contains(&raw);
        assert_eq!(Address::assignable(raw).is_ok(), ok, "{raw:#04x}");
        if !ok {
            assert_eq!(Address::assignable(raw), Err(Error::BadArgument));
        }
    }
    assert_eq!(Address::UNADDRESSED.get(), 0x77);
    assert!(Address::UNADDRESSED.is_unaddressed());
    assert!(!Address::new(0x76).unwrap().is_unaddressed());
}

#[test]
fn boot_info_with_without_and_with_a_cut_id() {
    let b = BootInfo {
        identity: identity(),
        reset_reason: ResetReason::Software,
        uid: Some(UID),
    };
    let (bytes, n) = b.to_bytes();
    assert_eq!(n, 19);
    assert_eq!(
        bytes,
        [1, 0, 1, 0, 3, 4, 4, 0xff, 1, 12, 5, 0xe6, 0x61, 0x38, 0x52, 0x83, 0x3f, 0x5c, 0x2a]
    );
    assert_eq!(BootInfo::parse(&bytes), Ok(b));
    // A board of an earlier version: no ID.
    let old = BootInfo::parse(&bytes[..11]).unwrap();
    assert_eq!(old.uid, None);
    assert_eq!(old.identity, identity());
    let (bytes_old, n_old) = old.to_bytes();
    assert_eq!(n_old, 11);
    assert_eq!(&bytes_old[..11], &bytes[..11]);
    // A cut ID is refused, never read as a shorter one.
    for len in 12..19 {
        assert_eq!(
            BootInfo::parse(&bytes[..len]),
            Err(Error::BadLength),
            "{len}"
        );
    }
    for len in 0..11 {
        assert_eq!(
            BootInfo::parse(&bytes[..len]),
            Err(Error::BadLength),
            "{len}"
        );
    }
}

#[test]
fn uid_hash_differs_between_ids_and_is_fixed_per_id() {
    assert_eq!(UID.hash32(), 0xaa8f_eaf7);
    assert_eq!(UID.hash32(), UID.hash32());
    // Each single flipped bit gives another hash.
    for bit in 0..64 {
        let mut u = UID;
        u.0[bit / 8] ^= 1 << (bit % 8);
        assert_ne!(u.hash32(), UID.hash32(), "bit {bit}");
    }
    assert_eq!(UID.to_string(), "e6613852833f5c2a");
    assert_eq!(Uid::parse(&UID.0[..7]), Err(Error::BadLength));
}

#[test]
fn moving_operations_are_refused_in_a_batch() {
    let a = Address::new(0x20).unwrap();
    for op in [
        Op::Assign {
            uid: UID,
            address: a,
        },
        Op::SetAddress(a),
        Op::WhoIsThere,
    ] {
        let mut buf = [0u8; 28];
        let mut w = BatchWriter::new(&mut buf);
        assert_eq!(w.push(&op), Err(Error::BadArgument), "{op:?}");
        // The same item written by hand is refused when parsed.
        let mut data = [0u8; 9];
        let n = op.emit_data(&mut data).unwrap();
        let mut item = vec![op.fn_op_byte(), 0, n as u8];
        item.extend_from_slice(&data[..n]);
        let mut frame = vec![0x50, 0x09, 0x00, 0x01];
        frame.extend_from_slice(&item);
        assert_eq!(Request::parse(&frame), Err(Error::BadArgument), "{op:?}");
    }
    // Blink is an ordinary output and may be batched.
    let mut buf = [0u8; 28];
    let mut w = BatchWriter::new(&mut buf);
    assert_eq!(w.push(&Op::Blink(3)), Ok(()));
}

#[test]
fn set_address_expects_its_reply_and_the_others_are_outputs() {
    let a = Address::new(0x20).unwrap();
    assert!(Op::SetAddress(a).expects_reply());
    assert!(!Op::Assign {
        uid: UID,
        address: a
    }
    .expects_reply());
    assert!(!Op::Blink(1).expects_reply());
    assert!(!Op::WhoIsThere.expects_reply());
    // Assign's address is checked like set_address's.
    let mut frame = vec![0x08, 0x77, 0x00, 0x01];
    frame.extend_from_slice(&UID.0);
    for (raw, ok) in [
        (0x07u8, false),
        (0x08, true),
        (0x76, true),
        (0x77, false),
        (0x78, false),
    ] {
        let mut f = frame.clone();
        f.push(raw);
        assert_eq!(Request::parse(&f).is_ok(), ok, "{raw:#04x}");
    }
}
