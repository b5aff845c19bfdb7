//! `docs/boards.md` shows each board's pin map; this test renders the tables from the code's
//! tables (`x10_boards::pins`) and checks that the document holds exactly those, between its
//! `<!-- begin pins:NAME -->` / `<!-- end pins:NAME -->` markers. On a mismatch it prints
//! the block to paste.

use std::fmt::Write as _;

use x10_boards::pins::{BoardMap, C011, G431, PICO};

/// Physical header pin of a Pico GPIO (Raspberry Pi Pico datasheet, pinout).
fn pico_header_pin(gpio: u8) -> Option<u8> {
    const PINS: [(u8, u8); 26] = [
        (0, 1),
        (1, 2),
        (2, 4),
        (3, 5),
        (4, 6),
        (5, 7),
        (6, 9),
        (7, 10),
        (8, 11),
        (9, 12),
        (10, 14),
        (11, 15),
        (12, 16),
        (13, 17),
        (14, 19),
        (15, 20),
        (16, 21),
        (17, 22),
        (18, 24),
        (19, 25),
        (20, 26),
        (21, 27),
        (22, 29),
        (26, 31),
        (27, 32),
        (28, 34),
    ];
    PINS.iter().find(|(g, _)| *g == gpio).map(|(_, p)| *p)
}

/// `PIN_14` → `GP14 (pin 19)`.
fn pico_pin(name: &str) -> String {
    let gpio: u8 = name
        .strip_prefix("PIN_")
        .and_then(|n| n.parse().ok())
        .unwrap_or_else(|| panic!("{name} is not a Pico GPIO"));
    let header = pico_header_pin(gpio).unwrap_or_else(|| panic!("GP{gpio} is not on the header"));
    format!("GP{gpio} (pin {header})")
}

/// `PWM_SLICE1` → `slice 1`.
fn pico_unit(name: &str) -> String {
    format!("slice {}", name.trim_start_matches("PWM_SLICE"))
}

fn g431_pin(name: &str) -> String {
    name.to_owned()
}

/// `TIM1` → `TIM1 CH1/CH2`.
fn g431_unit(name: &str) -> String {
    format!("{name} CH1/CH2")
}

/// Package pin of a C011F6 pad in TSSOP-20 (ST datasheet DS13866, pinout).
fn c011_package_pin(name: &str) -> Option<u8> {
    const PINS: [(&str, u8); 15] = [
        ("PB7", 1),
        ("PC14", 2),
        ("PC15", 3),
        ("PA0", 7),
        ("PA1", 8),
        ("PA2", 9),
        ("PA3", 10),
        ("PA4", 11),
        ("PA5", 12),
        ("PA6", 13),
        ("PA7", 14),
        ("PA8", 15),
        ("PA11", 16),
        ("PA12", 17),
        ("PB6", 20),
    ];
    PINS.iter().find(|(n, _)| *n == name).map(|(_, p)| *p)
}

/// `PA0` → `PA0 (pin 7)`.
fn c011_pin(name: &str) -> String {
    let p = c011_package_pin(name).unwrap_or_else(|| panic!("{name} is no C011F6 pad"));
    format!("{name} (pin {p})")
}

fn render(map: &BoardMap, pin: fn(&str) -> String, unit: fn(&str) -> String) -> String {
    let mut s = String::new();
    let _ = writeln!(s, "| bus | SDA | SCL |\n|---|---|---|");
    let _ = writeln!(
        s,
        "| {} | {} | {} |",
        map.i2c.block,
        pin(map.i2c.sda),
        pin(map.i2c.scl)
    );
    let _ = writeln!(s);
    let _ = writeln!(
        s,
        "| sensor port | digital A | digital B | analog |\n|---|---|---|---|"
    );
    for (i, p) in map.sensors.iter().enumerate() {
        let _ = writeln!(
            s,
            "| S{} | {} | {} | {} |",
            i + 1,
            pin(p.a),
            pin(p.b),
            pin(p.analog)
        );
    }
    let _ = writeln!(s);
    let _ = writeln!(
        s,
        "| actuator port | PWM A | PWM B | PWM unit | digital A | digital B |\n|---|---|---|---|---|---|"
    );
    for (i, p) in map.actuators.iter().enumerate() {
        let _ = writeln!(
            s,
            "| A{} | {} | {} | {} | {} | {} |",
            i + 1,
            pin(p.pwm_a),
            pin(p.pwm_b),
            unit(p.pwm_unit),
            pin(p.a),
            pin(p.b)
        );
    }
    if !map.jumpers.is_empty() {
        let _ = writeln!(s);
        let _ = writeln!(
            s,
            "| address jumper | pin | adds when fitted |\n|---|---|---|"
        );
        for (k, j) in map.jumpers.iter().enumerate() {
            let _ = writeln!(s, "| J{k} | {} | {} |", pin(j), 1u8 << k);
        }
    }
    s
}

fn block<'a>(doc: &'a str, name: &str) -> &'a str {
    let begin = format!("<!-- begin pins:{name} -->\n");
    let end = format!("<!-- end pins:{name} -->");
    let start = doc
        .find(&begin)
        .unwrap_or_else(|| panic!("docs/boards.md has no {begin:?}"))
        + begin.len();
    let len = doc[start..]
        .find(&end)
        .unwrap_or_else(|| panic!("docs/boards.md has no {end:?}"));
    &doc[start..start + len]
}

fn check(doc: &str, name: &str, expected: &str) {
    let found = block(doc, name);
    assert!(
        found == expected,
        "docs/boards.md, pins:{name} differs from the code's table; it should read:\n{expected}"
    );
}

fn doc() -> String {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../docs/boards.md");
    std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{path}: {e}"))
}

#[test]
fn pico_table_matches_the_code() {
    check(&doc(), "pico", &render(&PICO, pico_pin, pico_unit));
}

#[test]
fn g431_table_matches_the_code() {
    check(&doc(), "g431", &render(&G431, g431_pin, g431_unit));
}

#[test]
fn c011_table_matches_the_code() {
    check(&doc(), "c011", &render(&C011, c011_pin, g431_unit));
}

#[test]
fn rendering_names_header_pins() {
    assert_eq!(pico_pin("PIN_0"), "GP0 (pin 1)");
    assert_eq!(pico_pin("PIN_28"), "GP28 (pin 34)");
    assert_eq!(pico_unit("PWM_SLICE5"), "slice 5");
    let r = render(&PICO, pico_pin, pico_unit);
    assert!(r.contains("| S1 | GP14 (pin 19) | GP15 (pin 20) | GP26 (pin 31) |"));
    assert!(r.contains("| J2 | GP22 (pin 29) | 4 |"));
}
