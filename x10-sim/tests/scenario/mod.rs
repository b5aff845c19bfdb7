//! The reference the world files of the thesis programs (`robots/worlds/fig4_*.toml`) are
//! checked against: the boards and scripted signals as the simulator hard-coded them before
//! worlds were files. Test code only.
#![allow(dead_code)]
//!
//! | program | board | port | script |
//! |---|---|---|---|
//! | fig4_2, fig4_4 | SELF (mb) | S2.B button | pressed at 2.0 s, released at 3.0 s |
//! | fig4_2, fig4_4 | SELF (mb) | S1 force | 40 counts; 350 from 3.6 s to 4.2 s |
//! | fig4_2, fig4_4 | SELF (mb) | A1 motor | (output) |
//! | fig4_4 | db09 | S1 light | 200 counts, rising from 0.5 s to 900 at 2.5 s, 300 from 4.0 s |
//! | fig4_4 | db09 | A1 motor | (output) |
//! | fig4_6 | db11 (17) | S1 freezer thermistor | −18 °C at 0 s warming to +6 °C at 4 s |
//! | fig4_6 | db6c (108) | S6 oven thermistor | 250 °F (121 °C) |
//! | fig4_6 | db0a (10) | A3.A alarm | (output) |
//!
//! So in a 5 s run: fig4_2's motor runs from about 2.0 s to 3.0 s (button) and from 3.6 s to
//! 4.2 s (force); fig4_4's second motor runs from about 1.93 s to 4.0 s; fig4_6's alarm goes
//! on when the freezer passes 1 °C, at about 3.17 s, and stays on.

use std::rc::Rc;

use x10_devices::ThermistorConfig;
use x10_microcode::Address;

use x10_sim::ports::{Analog, Digital, SensorScript};
use x10_sim::sim::{Sim, SimConfig};

/// When the fig4_2 button is pressed (ms).
pub const BUTTON_PRESS_MS: u64 = 2_000;
/// When it is released (ms).
pub const BUTTON_RELEASE_MS: u64 = 3_000;
/// When the force sensor reads 350 (ms)…
pub const FORCE_FROM_MS: u64 = 3_600;
/// …until (ms).
pub const FORCE_UNTIL_MS: u64 = 4_200;

/// The light level on db09 S1 at `t_us`.
pub fn light_level(t_us: u64) -> u16 {
    let ms = t_us / 1_000;
    match ms {
        0..=499 => 200,
        500..=2_499 => (200 + (t_us - 500_000) * 700 / 2_000_000) as u16,
        2_500..=3_999 => 900,
        _ => 300,
    }
}

/// The freezer temperature in °C at `t_us`: −18 °C warming linearly to +6 °C at 4 s.
pub fn freezer_celsius(t_us: u64) -> f32 {
    let t = (t_us.min(4_000_000)) as f32 / 4_000_000.0;
    -18.0 + 24.0 * t
}

/// The oven temperature in °C (250 °F).
pub const OVEN_CELSIUS: f32 = 121.1;

/// The raw 10-bit reading of the thesis's thermistor divider
/// ([`ThermistorConfig::THESIS`]) at `celsius`: the raw value whose converted temperature is
/// closest (the conversion is the driver's own).
pub fn thermistor_raw(celsius: f32) -> u16 {
    let cfg = ThermistorConfig::THESIS;
    let temp = |raw: u16| cfg.kelvin(raw).map(|k| k.0 - 273.15).ok();
    // Higher raw = hotter with the thermistor on the high side: binary search.
    let (mut lo, mut hi) = (1u16, 1022u16);
    while lo < hi {
        let mid = lo + (hi - lo) / 2;
        match temp(mid) {
            Some(t) if t < celsius => lo = mid + 1,
            _ => hi = mid,
        }
    }
    // lo is the first raw at or above the temperature; take the closer neighbour.
    let above = temp(lo).unwrap_or(f32::MAX);
    let below = lo.checked_sub(1).and_then(temp).unwrap_or(f32::MIN);
    if (above - celsius).abs() <= (celsius - below).abs() {
        lo
    } else {
        lo - 1
    }
}

fn addr(n: u8) -> Address {
    // Only the constant addresses below: all valid.
    Address::external(n).unwrap_or(Address::INTERNAL)
}

/// The boards of example `name` (`fig4_2`, `fig4_4`, `fig4_6`) with the scripts above, without
/// its robot tasks; `None` for another name.
pub fn build(name: &str, config: SimConfig) -> Option<Sim> {
    let sim = Sim::new(config);
    let sim = match name {
        "fig4_2" | "fig4_4" => {
            let internal = sim
                .ports("mb", 2, 2)
                .with_sensor(
                    1,
                    SensorScript {
                        analog: Analog::Steps {
                            initial: 40,
                            steps: vec![(FORCE_FROM_MS, 350), (FORCE_UNTIL_MS, 40)],
                        },
                        ..SensorScript::default()
                    },
                )
                .with_sensor(
                    2,
                    SensorScript {
                        b: Digital::Toggles {
                            initial: false,
                            toggles_ms: vec![BUTTON_PRESS_MS, BUTTON_RELEASE_MS],
                        },
                        ..SensorScript::default()
                    },
                );
            let sim = sim.with_internal_ports(internal);
            if name == "fig4_4" {
                let ports = sim.ports("db09", 2, 2).with_sensor(
                    1,
                    SensorScript {
                        analog: Analog::Func(Rc::new(light_level)),
                        ..SensorScript::default()
                    },
                );
                sim.with_board(addr(9), ports)
            } else {
                sim
            }
        }
        "fig4_6" => {
            let freezer = sim.ports("db11", 2, 2).with_sensor(
                1,
                SensorScript {
                    analog: Analog::Func(Rc::new(|t| thermistor_raw(freezer_celsius(t)))),
                    ..SensorScript::default()
                },
            );
            let oven = sim.ports("db6c", 6, 2).with_sensor(
                6,
                SensorScript {
                    analog: Analog::Const(thermistor_raw(OVEN_CELSIUS)),
                    ..SensorScript::default()
                },
            );
            let control = sim.ports("db0a", 2, 3);
            sim.with_board(addr(17), freezer)
                .with_board(addr(108), oven)
                .with_board(addr(10), control)
        }
        _ => return None,
    };
    Some(sim)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn thermistor_raw_inverts_the_driver() {
        let cfg = ThermistorConfig::THESIS;
        for c in [-18.0f32, 0.0, 1.0, 25.0, 121.1] {
            let raw = thermistor_raw(c);
            let back = cfg.kelvin(raw).unwrap().0 - 273.15;
            assert!((back - c).abs() < 1.5, "{c} -> {raw} -> {back}");
        }
        assert!(thermistor_raw(-18.0) < thermistor_raw(25.0));
    }

    #[test]
    fn light_crosses_700_at_about_1_93_s() {
        assert_eq!(light_level(0), 200);
        assert_eq!(light_level(1_930_000), 700);
        assert!(light_level(1_932_000) > 700);
        assert_eq!(light_level(3_000_000), 900);
        assert_eq!(light_level(4_000_000), 300);
    }
}
