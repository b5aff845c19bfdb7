//! Test image of the emulated RP2040's flash path (emu/lib/flash.js): embassy-rp 0.10's
//! blocking `Flash` on the rig's ROM, SSI and NOR flash models, and a software reset.
//!
//! At each boot it logs the flash's unique ID and JEDEC ID (read through the SSI), reads a
//! counter from the last 4 KiB sector (erased: 0), and while it is below `LAST` erases the
//! sector, writes the counter + 1, reads it back and resets itself with `SCB::sys_reset`
//! (AIRCR.SYSRESETREQ). So an erased chip logs the counters 0, 1, 2 across two resets, and any
//! later boot (a power cycle) logs 2 again: the scenario `flash` (emu/scenarios/40-flash.mjs)
//! checks these lines.
#![no_std]
#![no_main]

use defmt_rtt as _;
use embassy_rp::flash::{Blocking, Flash, ERASE_SIZE};
use panic_probe as _;

/// The Pico's flash: 2 MiB.
const FLASH_SIZE: usize = 2 * 1024 * 1024;
/// The counter's sector: the last one.
const SECTOR: u32 = (FLASH_SIZE - ERASE_SIZE) as u32;
/// The counter value at which the image stops resetting itself.
const LAST: u32 = 2;

#[cortex_m_rt::entry]
fn main() -> ! {
    let p = embassy_rp::init(Default::default());
    let mut flash = Flash::<_, Blocking, FLASH_SIZE>::new_blocking(p.FLASH);
    let mut uid = [0u8; 8];
    if let Err(e) = flash.blocking_unique_id(&mut uid) {
        defmt::error!("unique id: {}", e);
    }
    match flash.blocking_jedec_id() {
        Ok(jedec) => defmt::info!("unique id {=[u8]:02x} jedec {=u32:06x}", uid, jedec),
        Err(e) => defmt::error!("jedec id: {}", e),
    }
    let count = match read(&mut flash) {
        // An erased sector: the counter starts at 0.
        Ok(u32::MAX) => 0,
        Ok(n) => n,
        Err(e) => {
            defmt::error!("read: {}", e);
            halt()
        }
    };
    defmt::info!("counter {=u32}", count);
    if count < LAST {
        let next = count + 1;
        let written = flash
            .blocking_erase(SECTOR, SECTOR + ERASE_SIZE as u32)
            .and_then(|()| flash.blocking_write(SECTOR, &next.to_le_bytes()))
            .and_then(|()| read(&mut flash));
        match written {
            Ok(back) => defmt::info!("wrote {=u32}, read back {=u32}; reset", next, back),
            Err(e) => {
                defmt::error!("write: {}", e);
                halt()
            }
        }
        cortex_m::peripheral::SCB::sys_reset();
    }
    defmt::info!("done");
    halt()
}

/// The counter word at the start of the sector (through XIP).
fn read(
    flash: &mut Flash<'_, embassy_rp::peripherals::FLASH, Blocking, FLASH_SIZE>,
) -> Result<u32, embassy_rp::flash::Error> {
    let mut word = [0u8; 4];
    flash.blocking_read(SECTOR, &mut word)?;
    Ok(u32::from_le_bytes(word))
}

fn halt() -> ! {
    loop {
        cortex_m::asm::wfe();
    }
}
