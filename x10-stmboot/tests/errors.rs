//! The bootloader's refusals, a wrong chip, a wrong image and a bad read-back become typed
//! errors, and none of them leaves the board unreachable.

use embassy_futures::block_on;
use embedded_hal_async::i2c::I2c;
use x10_stmboot::model::{rig, Boot, ModelError, RomModel};
use x10_stmboot::{cmd, update, Client, Error, Phase, C011, ROM_ADDRESS};

fn image(len: usize) -> Vec<u8> {
    let mut v: Vec<u8> = (0..len).map(|i| (i * 7 + 3) as u8).collect();
    v[..4].copy_from_slice(&0x2000_1800u32.to_le_bytes());
    v
}

#[test]
fn a_glitched_frame_is_refused_with_its_command_and_phase() {
    // Frames of a write: command, address, data (0, 1, 2 from the first write on).
    for (n, phase) in [(0, Phase::Command), (1, Phase::Address), (2, Phase::Data)] {
        let (m, bus, delay) = rig(RomModel::c011(&image(2048)));
        m.borrow_mut().enter_rom();
        let mut c = Client::new(bus, delay);
        assert_eq!(block_on(c.get_version()), Ok(0x12));
        block_on(c.erase_pages(1, 1)).unwrap();
        m.borrow_mut().corrupt_write(n);
        let r = block_on(c.write_memory(0x0800_0800, &[0x12; 16]));
        assert_eq!(
            r,
            Err(Error::Nack {
                command: cmd::NO_STRETCH_WRITE_MEMORY,
                phase
            })
        );
        // Nothing was programmed, and the bootloader takes the next command.
        assert!(m.borrow().flash()[0x800..0x1000].iter().all(|&b| b == 0xFF));
        block_on(c.write_memory(0x0800_0800, &[0x12; 16])).unwrap();
        assert_eq!(&m.borrow().flash()[0x800..0x810], &[0x12; 16]);
    }
}

#[test]
fn a_glitched_erase_count_or_page_list_is_refused() {
    for (n, phase) in [(1, Phase::Count), (2, Phase::Pages)] {
        let (m, bus, delay) = rig(RomModel::c011(&image(4096)));
        m.borrow_mut().enter_rom();
        let mut c = Client::new(bus, delay);
        block_on(c.get_version()).unwrap();
        m.borrow_mut().corrupt_write(n);
        assert_eq!(
            block_on(c.erase_pages(1, 1)),
            Err(Error::Nack {
                command: cmd::NO_STRETCH_ERASE,
                phase
            })
        );
        assert!(m.borrow().holds(&image(4096)), "nothing erased");
    }
}

#[test]
fn another_chip_is_refused_before_anything_is_erased() {
    let old = image(3000);
    let mut model = RomModel::c011(&old);
    model.pid = 0x453; // an STM32C031
    let (m, bus, delay) = rig(model);
    m.borrow_mut().enter_rom();
    let mut c = Client::new(bus, delay);
    assert_eq!(
        block_on(update(&mut c, &C011, &image(2000))),
        Err(Error::WrongChip { pid: 0x453 })
    );
    assert!(m.borrow().holds(&old));
    assert_eq!(m.borrow_mut().power_on(), Boot::Flash);
}

#[test]
fn an_empty_or_oversized_image_is_refused_before_any_bus_traffic() {
    let (m, bus, delay) = rig(RomModel::c011(&image(100)));
    m.borrow_mut().enter_rom();
    let mut c = Client::new(bus, delay);
    assert_eq!(
        block_on(update(&mut c, &C011, &[])),
        Err(Error::BadImage { len: 0 })
    );
    assert_eq!(
        block_on(update(&mut c, &C011, &vec![0; 32 * 1024 + 1])),
        Err(Error::BadImage { len: 32 * 1024 + 1 })
    );
    assert_eq!(m.borrow().stats().transactions, 0);
    assert_eq!(
        block_on(c.read_memory(0x0800_0000, &mut [0; 257])),
        Err(Error::BadLength { len: 257 })
    );
    assert_eq!(
        block_on(c.write_memory(0x0800_0000, &[])),
        Err(Error::BadLength { len: 0 })
    );
    assert_eq!(
        block_on(c.erase_pages(0, 0)),
        Err(Error::BadLength { len: 0 })
    );
}

#[test]
fn programming_flash_that_is_not_erased_is_refused() {
    let (m, bus, delay) = rig(RomModel::c011(&image(2048)));
    m.borrow_mut().enter_rom();
    let mut c = Client::new(bus, delay);
    block_on(c.get_version()).unwrap();
    assert_eq!(
        block_on(c.write_memory(0x0800_0100, &[0; 8])),
        Err(Error::Nack {
            command: cmd::NO_STRETCH_WRITE_MEMORY,
            phase: Phase::Data
        })
    );
    assert!(m.borrow().holds(&image(2048)));
}

#[test]
fn addresses_outside_main_flash_and_misaligned_writes_are_refused() {
    let (m, bus, delay) = rig(RomModel::c011(&image(100)));
    m.borrow_mut().enter_rom();
    let mut c = Client::new(bus, delay);
    assert_eq!(
        block_on(c.read_memory(0x2000_0000, &mut [0; 4])),
        Err(Error::Nack {
            command: cmd::READ_MEMORY,
            phase: Phase::Address
        })
    );
    assert_eq!(
        block_on(c.write_memory(0x0800_0804, &[0; 8])),
        Err(Error::Nack {
            command: cmd::WRITE_MEMORY,
            phase: Phase::Address
        })
    );
    assert_eq!(
        block_on(c.go(0x0800_8000)),
        Err(Error::Nack {
            command: cmd::GO,
            phase: Phase::Address
        })
    );
    let mut four = [0u8; 4];
    block_on(c.read_memory(0x0800_7FFC, &mut four)).unwrap();
    assert_eq!(four, [0xFF; 4]);
}

#[test]
fn a_cell_that_does_not_program_fails_the_read_back_and_leaves_the_board_empty() {
    let new = image(3000);
    // Byte 1000 of the image is 0x5B (1000 * 7 + 3 = 7003, low byte 0x5B): bit 2 is 0.
    assert_eq!(new[1000], 0x5B);
    let (m, bus, delay) = rig(RomModel::c011(&image(500)));
    m.borrow_mut().enter_rom();
    m.borrow_mut().stick_bit(1000, 0x04);
    let mut c = Client::new(bus, delay);
    assert_eq!(
        block_on(update(&mut c, &C011, &new)),
        Err(Error::Verify {
            address: 0x0800_0000 + 1000
        })
    );
    // The first double word was never written: the board boots its ROM bootloader.
    assert_eq!(m.borrow_mut().power_on(), Boot::Rom);
}

#[test]
fn protocol_1_0_gets_the_stretching_commands_and_no_busy() {
    let new = image(6000);
    let mut model = RomModel::c011(&image(100));
    model.version = 0x10;
    let (m, bus, delay) = rig(model);
    m.borrow_mut().enter_rom();
    let mut c = Client::new(bus, delay);
    let report = block_on(update(&mut c, &C011, &new)).unwrap();
    assert!(!report.no_stretch);
    assert_eq!(report.busy_polls, 0);
    assert!(m.borrow().holds(&new));
    // Such a bootloader refuses a no-stretch command.
    m.borrow_mut().enter_rom();
    let mut raw = x10_stmboot::model::ModelBus(m.clone());
    block_on(raw.write(ROM_ADDRESS, &[0x32, 0xCD])).unwrap();
    let mut b = [0u8];
    block_on(raw.read(ROM_ADDRESS, &mut b)).unwrap();
    assert_eq!(b, [x10_stmboot::NACK]);
}

#[test]
fn a_board_not_in_its_bootloader_does_not_answer() {
    let (m, bus, delay) = rig(RomModel::c011(&image(100)));
    let mut c = Client::new(bus, delay);
    assert_eq!(
        block_on(update(&mut c, &C011, &image(200))),
        Err(Error::Bus(ModelError::NoAck))
    );
    assert_eq!(m.borrow().boot(), Boot::Flash);
}

#[test]
fn a_flash_that_stays_busy_past_the_budget_is_still_busy() {
    let (m, bus, delay) = rig(RomModel::c011(&image(100)));
    m.borrow_mut().enter_rom();
    let mut c = Client::new(bus, delay);
    c.busy_timeout_us = 1_000;
    block_on(c.get_version()).unwrap();
    assert_eq!(
        block_on(c.erase_pages(0, 1)),
        Err(Error::StillBusy {
            command: cmd::NO_STRETCH_ERASE
        })
    );
}
