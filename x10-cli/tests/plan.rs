//! `x10 plan` prints what the motherboard would update in a world, in words, before any run
//! (issue 25): the exact output for `x10-sim/tests/plan.toml`, and a world without images.

use std::process::Command;

fn x10(args: &[&str]) -> (Option<i32>, String, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_x10"))
        .args(args)
        .current_dir(concat!(env!("CARGO_MANIFEST_DIR"), "/.."))
        .output()
        .unwrap();
    (
        out.status.code(),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

#[test]
fn the_plan_of_a_world_in_words() {
    let (code, out, err) = x10(&["plan", "--world", "x10-sim/tests/plan.toml"]);
    assert_eq!(code, Some(0), "{err}");
    assert_eq!(
        out,
        "# x10 plan x10-sim/tests/plan.toml\n\
         the motherboard carries pico 2.0.0 (fakes of the right length and CRC in the simulator)\n\
         board 0x21 (pico) runs 0.1.0, the motherboard carries 2.0.0: it will be updated\n\
         board 0x22 (pico) runs 0.1.0: pinned (update = false), not updated\n\
         board 0x23 \"arm\" (pico) runs 2.0.0: up to date, not updated\n\
         board 0x24 (g431) runs 0.1.0: the motherboard carries no g431 image, not updated\n\
         board \"gripper\" (no address yet) (pico) runs 1.9.9, the motherboard carries 2.0.0: it will be updated\n"
    );
}

#[test]
fn a_world_without_images_updates_nothing() {
    let (code, out, _) = x10(&["plan", "fig4_4"]);
    assert_eq!(code, Some(0));
    let mut lines = out.lines();
    assert_eq!(lines.next(), Some("# x10 plan robots/worlds/fig4_4.toml"));
    assert_eq!(
        lines.next(),
        Some("the motherboard carries no daughterboard images: no board is updated")
    );
    // Daughterboard 9 (the internal board is part of the motherboard: no line), at the
    // simulator's own version.
    let line = lines.next().unwrap();
    assert!(line.starts_with("board 0x09 (simulated) runs "), "{line}");
    assert!(
        line.ends_with(": the motherboard carries no simulated image, not updated"),
        "{line}"
    );
    assert_eq!(lines.next(), None);
}

#[test]
fn a_bad_version_is_named_with_its_line() {
    let path = std::env::temp_dir().join(format!("x10-plan-{}.toml", std::process::id()));
    std::fs::write(
        &path,
        "[[board]]\naddress = 0x21\nkind = \"pico\"\nfirmware = \"0.1\"\n",
    )
    .unwrap();
    let file = path.display().to_string();
    let (code, out, err) = x10(&["plan", "--world", &file]);
    std::fs::remove_file(&path).unwrap();
    assert_eq!(code, Some(1));
    assert_eq!(out, "");
    assert!(
        err.starts_with(&format!("x10 plan: {file}: line 4")),
        "{err}"
    );
    assert!(err.contains("major.minor.patch"), "{err}");
}
