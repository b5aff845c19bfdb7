//! The pin map of each board: ONE table per board.
//!
//! Each table is a macro holding nothing but peripheral names, so that the same tokens feed
//! two consumers:
//!
//! * [`describe`] turns it into a plain [`BoardMap`] of names ([`PICO`], [`G431`]); it compiles
//!   everywhere, `docs/boards.md` is checked against it by a host test, and the port counts the
//!   firmware reports come from it;
//! * the chip modules (`pico`, `g431`, behind the `rp2040` / `stm32g431` features) expand the
//!   same table into the code that takes those peripherals out of the HAL's `Peripherals` and
//!   builds the bus and the ports. The HAL's pin traits then check at compile time that every
//!   pin can do what the table asks of it (I2C function, PWM slice/timer channel, ADC input),
//!   and the borrow checker that no pin is used twice.

/// Names of the two I2C lines and the I2C block they belong to.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BusPins {
    /// I2C block (`I2C0`, `I2C1`).
    pub block: &'static str,
    /// SDA pin.
    pub sda: &'static str,
    /// SCL pin.
    pub scl: &'static str,
}

/// One sensor port: two digital I/O pins and one analog input.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SensorPins {
    /// Digital pin A.
    pub a: &'static str,
    /// Digital pin B.
    pub b: &'static str,
    /// Analog input.
    pub analog: &'static str,
}

/// One actuator port: two PWM pins on one PWM unit (so the port has one frequency) and two
/// digital I/O pins.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ActuatorPins {
    /// The PWM unit both PWM pins belong to (an RP2040 PWM slice, an STM32 timer).
    pub pwm_unit: &'static str,
    /// PWM pin A (slice channel A / timer channel 1).
    pub pwm_a: &'static str,
    /// PWM pin B (slice channel B / timer channel 2).
    pub pwm_b: &'static str,
    /// Digital pin A.
    pub a: &'static str,
    /// Digital pin B.
    pub b: &'static str,
}

/// A board's whole pin map, by peripheral names as the HAL spells them.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BoardMap {
    /// Board name.
    pub board: &'static str,
    /// The bus.
    pub i2c: BusPins,
    /// Sensor ports, port 1 first.
    pub sensors: &'static [SensorPins],
    /// Actuator ports, port 1 first.
    pub actuators: &'static [ActuatorPins],
    /// Address-select jumper inputs, bit 0 first (may be empty).
    pub jumpers: &'static [&'static str],
}

impl BoardMap {
    /// Number of sensor ports.
    pub const fn sensor_ports(&self) -> u8 {
        self.sensors.len() as u8
    }

    /// Number of actuator ports.
    pub const fn actuator_ports(&self) -> u8 {
        self.actuators.len() as u8
    }

    /// Every pin the map uses, in table order (bus, sensors, actuators, jumpers).
    pub fn pins(&self) -> impl Iterator<Item = &'static str> + '_ {
        let bus = [self.i2c.sda, self.i2c.scl];
        let sensors = self.sensors.iter().flat_map(|s| [s.a, s.b, s.analog]);
        let actuators = self
            .actuators
            .iter()
            .flat_map(|a| [a.pwm_a, a.pwm_b, a.a, a.b]);
        bus.into_iter()
            .chain(sensors)
            .chain(actuators)
            .chain(self.jumpers.iter().copied())
    }
}

/// The Raspberry Pi Pico (RP2040) table.
///
/// 26 GPIOs reach the header (GP0–GP22, GP26–GP28). The three ADC inputs (GP26–GP28; GP29
/// measures VSYS on the Pico) limit it to three sensor ports; three actuator ports take 12 more
/// pins, each port's PWM pins being channels A and B of one slice (GP2n/GP2n+1 is slice n mod
/// 8). Three pins are left: the address-select jumpers.
macro_rules! pico_table {
    ($then:ident) => {
        $then! {
            board: "Raspberry Pi Pico (RP2040)",
            i2c: I2C0 { sda: PIN_0, scl: PIN_1 },
            // (digital A, digital B, analog)
            sensors: [
                (PIN_14, PIN_15, PIN_26),
                (PIN_16, PIN_17, PIN_27),
                (PIN_18, PIN_19, PIN_28),
            ],
            // (PWM slice, PWM A, PWM B, digital A, digital B)
            actuators: [
                (PWM_SLICE1, PIN_2, PIN_3, PIN_4, PIN_5),
                (PWM_SLICE3, PIN_6, PIN_7, PIN_8, PIN_9),
                (PWM_SLICE5, PIN_10, PIN_11, PIN_12, PIN_13),
            ],
            jumpers: [PIN_20, PIN_21, PIN_22],
        }
    };
}

/// The STM32G431CB table (WeAct STM32G431CB core board; the NUCLEO-G431RB has every pin too).
///
/// Left free: PA13/PA14 (SWD), PA11/PA12 (USB connector), PB8 (BOOT0), PC6 (LED), PC13 (key),
/// PC14/PC15 and PF0/PF1 (crystals). That leaves 30 pins: the bus takes 2, four actuator ports
/// take 16 (each on channels 1 and 2 of its own timer: TIM1, TIM2, TIM3, TIM15 are the timers
/// with both channels on free pins) and four sensor ports take the last 12, with all analog
/// inputs on ADC1. No pin is left for jumpers: the address is set at build time.
macro_rules! g431_table {
    ($then:ident) => {
        $then! {
            board: "STM32G431CB (WeAct core board)",
            i2c: I2C1 { sda: PB7, scl: PA15 },
            // (digital A, digital B, analog on ADC1)
            sensors: [
                (PB0, PB1, PA0),
                (PB2, PB10, PA1),
                (PB11, PB12, PA2),
                (PB13, PA4, PA3),
            ],
            // (timer, PWM A = CH1, PWM B = CH2, digital A, digital B)
            actuators: [
                (TIM1, PA8, PA9, PA10, PB9),
                (TIM2, PA5, PB3, PA6, PA7),
                (TIM3, PB4, PB5, PB6, PC4),
                (TIM15, PB14, PB15, PC10, PC11),
            ],
            jumpers: [],
        }
    };
}

/// The STM32C011F6 table (TSSOP-20, Cortex-M0+).
///
/// 20 pins: VDD, VSS, NRST (PF2) and SWD (PA13 SWDIO, PA14 SWCLK/BOOT0) stay free; 15 GPIO pads
/// remain (PA0-PA8, PA11, PA12, PB6, PB7, PC14, PC15; PA9/PA10 share pads with PA11/PA12 and
/// are not remapped). The bus takes PB6/PB7 (I2C1, AF6). TIM1 is the only timer with two
/// channels on free pins besides TIM3 (the time driver): one actuator port (CH1 on PA0, CH2 on
/// PA1, AF5). The other nine pins make three sensor ports, the analog inputs on ADC1 (IN2, IN5,
/// IN8). Four ports is the most 13 pins give (an actuator port takes 4, a sensor port 3), so
/// no pin is left for jumpers: the address is set at build time.
macro_rules! c011_table {
    ($then:ident) => {
        $then! {
            board: "STM32C011F6 (TSSOP-20)",
            i2c: I2C1 { sda: PB7, scl: PB6 },
            // (digital A, digital B, analog on ADC1)
            sensors: [
                (PC14, PC15, PA2),
                (PA3, PA4, PA5),
                (PA11, PA12, PA8),
            ],
            // (timer, PWM A = CH1, PWM B = CH2, digital A, digital B)
            actuators: [
                (TIM1, PA0, PA1, PA6, PA7),
            ],
            jumpers: [],
        }
    };
}

/// Expands a table into a [`BoardMap`] of names.
macro_rules! describe {
    (
        board: $board:literal,
        i2c: $i2c:ident { sda: $sda:ident, scl: $scl:ident },
        sensors: [ $( ($sa:ident, $sb:ident, $san:ident) ),* $(,)? ],
        actuators: [ $( ($unit:ident, $pa:ident, $pb:ident, $da:ident, $db:ident) ),* $(,)? ],
        jumpers: [ $( $j:ident ),* $(,)? ] $(,)?
    ) => {
        BoardMap {
            board: $board,
            i2c: BusPins {
                block: stringify!($i2c),
                sda: stringify!($sda),
                scl: stringify!($scl),
            },
            sensors: &[ $( SensorPins {
                a: stringify!($sa),
                b: stringify!($sb),
                analog: stringify!($san),
            } ),* ],
            actuators: &[ $( ActuatorPins {
                pwm_unit: stringify!($unit),
                pwm_a: stringify!($pa),
                pwm_b: stringify!($pb),
                a: stringify!($da),
                b: stringify!($db),
            } ),* ],
            jumpers: &[ $( stringify!($j) ),* ],
        }
    };
}

/// The Raspberry Pi Pico's pin map.
pub const PICO: BoardMap = pico_table!(describe);

/// The STM32G431CB's pin map.
pub const G431: BoardMap = g431_table!(describe);

/// The STM32C011F6's pin map.
pub const C011: BoardMap = c011_table!(describe);

#[cfg(test)]
mod tests {
    extern crate std;
    use std::collections::HashSet;
    use std::vec::Vec;

    use super::*;

    fn gpio(name: &str) -> u8 {
        name.strip_prefix("PIN_").unwrap().parse().unwrap()
    }

    #[test]
    fn no_pin_is_used_twice() {
        for map in [PICO, G431, C011] {
            let pins: Vec<_> = map.pins().collect();
            let unique: HashSet<_> = pins.iter().collect();
            assert_eq!(pins.len(), unique.len(), "{}", map.board);
        }
    }

    #[test]
    fn port_counts() {
        assert_eq!((PICO.sensor_ports(), PICO.actuator_ports()), (3, 3));
        assert_eq!((G431.sensor_ports(), G431.actuator_ports()), (4, 4));
        assert_eq!(PICO.jumpers.len(), 3);
        assert_eq!(G431.jumpers.len(), 0);
        // 26 header GPIOs on the Pico, 30 free pins on the WeAct board: all used.
        assert_eq!(PICO.pins().count(), 26);
        assert_eq!(G431.pins().count(), 30);
        // 15 GPIO pads of the TSSOP-20 outside SWD and NRST: all used.
        assert_eq!((C011.sensor_ports(), C011.actuator_ports()), (3, 1));
        assert_eq!(C011.jumpers.len(), 0);
        assert_eq!(C011.pins().count(), 15);
    }

    #[test]
    fn pico_pwm_pins_are_channels_a_and_b_of_their_slice() {
        let mut slices = HashSet::new();
        for a in PICO.actuators {
            let slice: u8 = a
                .pwm_unit
                .strip_prefix("PWM_SLICE")
                .unwrap()
                .parse()
                .unwrap();
            assert!(slices.insert(slice), "slice {slice} shared by two ports");
            let (pa, pb) = (gpio(a.pwm_a), gpio(a.pwm_b));
            assert_eq!(((pa / 2) % 8, pa % 2), (slice, 0), "{}", a.pwm_a);
            assert_eq!(((pb / 2) % 8, pb % 2), (slice, 1), "{}", a.pwm_b);
        }
    }

    #[test]
    fn pico_analog_pins_are_adc_inputs_and_header_pins_exist() {
        for s in PICO.sensors {
            assert!((26..=28).contains(&gpio(s.analog)), "{}", s.analog);
        }
        for p in PICO.pins() {
            let n = gpio(p);
            assert!(
                n <= 22 || (26..=28).contains(&n),
                "{p} is not on the Pico header"
            );
        }
    }

    /// The C011F6's pads (stm32-metapac 21's pin list of the chip) and what the table asks of
    /// them (its peripheral pin lists, with the alternate function): SWD and NRST stay free.
    #[test]
    fn c011_pins_exist_and_can_do_their_job() {
        let pads = [
            "PA0", "PA1", "PA2", "PA3", "PA4", "PA5", "PA6", "PA7", "PA8", "PA11", "PA12", "PB6",
            "PB7", "PC14", "PC15",
        ];
        for p in C011.pins() {
            assert!(pads.contains(&p), "{p} is not a free pad of the C011F6");
        }
        for p in ["PA13", "PA14", "PF2"] {
            assert!(!C011.pins().any(|q| q == p), "{p} must stay free");
        }
        assert_eq!((C011.i2c.scl, C011.i2c.sda), ("PB6", "PB7"));
        let adc = [
            "PA0", "PA1", "PA2", "PA3", "PA4", "PA5", "PA6", "PA7", "PA8", "PA11", "PA12",
        ];
        for s in C011.sensors {
            assert!(adc.contains(&s.analog), "{} has no ADC input", s.analog);
        }
        for a in C011.actuators {
            assert_eq!((a.pwm_unit, a.pwm_a, a.pwm_b), ("TIM1", "PA0", "PA1"));
        }
    }

    #[test]
    fn g431_timers_are_distinct() {
        let timers: HashSet<_> = G431.actuators.iter().map(|a| a.pwm_unit).collect();
        assert_eq!(timers.len(), G431.actuators.len());
    }
}
