//! SDA/SCL as a Value Change Dump (IEEE 1364 §18) that GTKWave and Surfer open.
//!
//! The waveform is made from the wire symbols of the recorded transactions
//! ([`crate::bus::BusRecord::wire`]) with the bus timing: START, 8 data bits and an ACK bit per
//! byte (SDA changes a quarter into SCL low, SCL low 53 % and high 47 % of a period), repeated
//! START, STOP, and SCL held low while a target stretches. Timescale 1 ns.

use std::fmt::Write as _;

use crate::bus::{BusRecord, WireSym};
use crate::exec::Nanos;
use crate::timing::Timing;

const SCL: char = '!';
const SDA: char = '"';

struct Dump {
    out: String,
    t: Option<Nanos>,
    scl: bool,
    sda: bool,
}

impl Dump {
    fn set(&mut self, at: Nanos, id: char, value: bool) {
        let cur = if id == SCL { self.scl } else { self.sda };
        if cur == value {
            return;
        }
        // Keep time monotonic even if two symbols were recorded back to back.
        let at = self.t.map_or(at, |t| at.max(t));
        if self.t != Some(at) {
            let _ = writeln!(self.out, "#{at}");
            self.t = Some(at);
        }
        let _ = writeln!(self.out, "{}{}", u8::from(value), id);
        if id == SCL {
            self.scl = value;
        } else {
            self.sda = value;
        }
    }
}

/// Renders `records` (in time order) as a VCD file.
pub fn render(records: &[BusRecord], timing: Timing, clock_label: &str) -> String {
    let mut d = Dump {
        out: String::new(),
        t: None,
        scl: true,
        sda: true,
    };
    let _ = write!(
        d.out,
        "$comment X10 simulated I2C bus at {clock_label} $end\n\
         $version x10-sim {} $end\n\
         $timescale 1ns $end\n\
         $scope module i2c $end\n\
         $var wire 1 {SCL} SCL $end\n\
         $var wire 1 {SDA} SDA $end\n\
         $upscope $end\n\
         $enddefinitions $end\n\
         #0\n\
         $dumpvars\n\
         1{SCL}\n\
         1{SDA}\n\
         $end\n",
        env!("CARGO_PKG_VERSION"),
    );
    d.t = Some(0);
    let low = timing.low_ns();
    let q = low / 4;
    let mut last_end = 0;
    for rec in records {
        for &(t, sym) in &rec.wire {
            match sym {
                WireSym::Start => {
                    d.set(t, SCL, true);
                    d.set(t, SDA, false);
                    d.set(t + timing.hd_sta_ns, SCL, false);
                }
                WireSym::Bit { value } => {
                    d.set(t, SCL, false);
                    d.set(t + q, SDA, value);
                    d.set(t + low, SCL, true);
                    d.set(t + timing.bit_ns, SCL, false);
                }
                WireSym::RepeatedStart => {
                    d.set(t + q, SDA, true);
                    d.set(t + low, SCL, true);
                    d.set(t + low + timing.su_sta_ns, SDA, false);
                    d.set(t + low + timing.su_sta_ns + timing.hd_sta_ns, SCL, false);
                }
                WireSym::Stop => {
                    d.set(t + q, SDA, false);
                    d.set(t + low, SCL, true);
                    d.set(t + low + timing.su_sto_ns, SDA, true);
                }
                WireSym::Stuck { until } => {
                    d.set(t, SDA, false);
                    d.set(until, SDA, true);
                }
                WireSym::SclStuck { until } => {
                    d.set(t, SCL, false);
                    d.set(until, SCL, true);
                }
            }
        }
        last_end = last_end.max(rec.end_ns);
    }
    // A final timestamp so viewers show the last STOP in full.
    let end = last_end + timing.buf_ns;
    if d.t.is_some_and(|t| t < end) {
        let _ = writeln!(d.out, "#{end}");
    }
    d.out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bus::Outcome;
    use crate::timing::Speed;

    fn record(wire: Vec<(Nanos, WireSym)>, end_ns: Nanos) -> BusRecord {
        BusRecord {
            txn: 0,
            start_ns: 0,
            end_ns,
            master: 0,
            addr: 0x09,
            target: None,
            written: vec![],
            received: vec![],
            is_read: false,
            read: vec![],
            outcome: Outcome::Ok,
            losers: vec![],
            stretch_ns: 0,
            faults: vec![],
            wire,
        }
    }

    #[test]
    fn start_bit_stop_edges() {
        let t = Speed::Standard.timing();
        let wire = vec![
            (0, WireSym::Start),
            (4_000, WireSym::Bit { value: true }),
            (14_000, WireSym::Bit { value: false }),
            (24_000, WireSym::Stop),
        ];
        let vcd = render(&[record(wire, 24_000 + t.stop_ns())], t, "100k");
        let body = vcd.split("$end\n").last().unwrap();
        // low = 5300, quarter = 1325
        let expected = "0\"\n#4000\n0!\n#5325\n1\"\n#9300\n1!\n#14000\n0!\n\
                        #15325\n0\"\n#19300\n1!\n#24000\n0!\n#29300\n1!\n#33300\n1\"\n#38000\n";
        assert_eq!(body, expected);
        assert!(vcd.contains("$timescale 1ns $end"));
        assert!(vcd.contains("$var wire 1 ! SCL $end"));
        assert!(vcd.contains("$var wire 1 \" SDA $end"));
        assert!(vcd.contains("$enddefinitions $end"));
    }
}
