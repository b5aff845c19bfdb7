//! Robot programs await events instead of polling: an analog window crossing reported by the
//! board itself (`AnalogSensor::watch_window`, `wait_crossing`), on the internal board and on
//! a daughterboard, with `select` against a timer.

use embassy_futures::select::{select, Either};
use embassy_time::{Duration, Instant, Timer};
use std::cell::RefCell;
use std::rc::Rc;
use x10_devices::{AnalogSensor, Crossing, Error, SELF};
use x10_microcode::Address;
use x10_sim::sim::{SimConfig, X10};
use x10_sim::world::{Board, Device, Signal, World};

type Seen = Rc<RefCell<Vec<(u64, Crossing)>>>;

/// Watches 0..=500 counts of the light sensor on `board`; records every crossing and when it
/// was seen (ms of virtual time), until no crossing comes for 2 s.
async fn watch(x10: X10, board: Address, seen: Seen) -> Result<(), Error> {
    let light = AnalogSensor::new(x10, board, 1)?;
    light.watch_window(0, 500).await?;
    loop {
        match select(light.wait_crossing(), Timer::after(Duration::from_secs(2))).await {
            Either::First(c) => seen.borrow_mut().push((Instant::now().as_millis(), c?)),
            Either::Second(()) => return Ok(()),
        }
    }
}

fn world() -> World {
    // Light: 100 counts, ramping to 900 between 1 s and 2 s (above 500 from 1.5 s), back to
    // 100 at 3 s.
    let light = Signal::linear([
        (0, 100.0),
        (1_000, 100.0),
        (2_000, 900.0),
        (3_000, 900.0),
        (3_000, 100.0),
    ]);
    World::new()
        .board(Board::internal(2, 2))
        .board(Board::new(9, 2, 2))
        .device(Device::light_sensor("light", SELF, 1).counts(light.clone()))
        .device(Device::light_sensor("light9", 9, 1).counts(light))
}

#[test]
fn a_window_crossing_wakes_the_task_that_awaits_it() {
    for board in [Address::INTERNAL, Address::new(9).unwrap()] {
        let seen: Seen = Rc::default();
        let s = seen.clone();
        let config = SimConfig {
            duration_ms: 6_000,
            ..SimConfig::default()
        };
        let outcome = world()
            .sim(config)
            .unwrap()
            .with_robot("watch", move |x10| watch(x10, board, s))
            .run()
            .unwrap();
        let seen = seen.borrow().clone();
        // Inside at first (reported once when the watch starts), out at ~1.5 s, in at 3 s;
        // the board samples every 10 ms, so each is seen within one sampling period.
        let what: Vec<bool> = seen.iter().map(|(_, c)| c.inside).collect();
        assert_eq!(what, [true, false, true], "board {}: {seen:?}", board.get());
        let (t_out, out) = seen[1];
        assert!((1_500..=1_512).contains(&t_out), "{t_out}");
        assert!(out.value > 500, "{out:?}");
        let (t_in, back) = seen[2];
        assert!((3_000..=3_012).contains(&t_in), "{t_in}");
        assert_eq!(back.value, 100);
        // The task ended by itself 2 s after the last crossing: no polling loop ran meanwhile.
        assert!(outcome.trace.render().contains("watch: ended"));
    }
}

/// Two tasks wait for the same pin's events; one of them works for 15 ms after each event
/// before it waits again, and the pin changes again meanwhile. Both get every event: the
/// slow task's next event is held for it while it works (issue 10, "two waiters on one pin":
/// it was missed, silently).
#[test]
fn two_tasks_waiting_on_one_pin_each_get_every_event() {
    use x10_microcode::{EventConfig, Op, Pin, Port};
    let world = World::new().board(Board::new(9, 2, 2)).device(
        Device::button("button", 9, 1, Pin::A)
            .pressed_at_ms(100, 10)
            .pressed_at_ms(300, 10),
    );
    let seen: [Rc<RefCell<Vec<u8>>>; 2] = Default::default();
    let pin = Port::sensor(1).unwrap().pin(Pin::A);
    let db = Address::new(9).unwrap();
    let waiter = |slow: bool, log: Rc<RefCell<Vec<u8>>>| {
        move |x10: X10| async move {
            if !slow {
                let both = EventConfig {
                    rising: true,
                    falling: true,
                    ..EventConfig::OFF
                };
                x10.call(db, Op::EventEnable(pin, both)).await?;
            }
            loop {
                let ev = x10.wait_event(db, pin).await?;
                log.borrow_mut()
                    .push(ev.value.first().copied().unwrap_or(0xff));
                if slow {
                    Timer::after(Duration::from_millis(15)).await;
                }
            }
            #[allow(unreachable_code)]
            Ok::<(), x10_devices::LinkError>(())
        }
    };
    let config = SimConfig {
        duration_ms: 500,
        ..SimConfig::default()
    };
    world
        .sim(config)
        .unwrap()
        .with_robot("quick", waiter(false, seen[0].clone()))
        .with_robot("slow", waiter(true, seen[1].clone()))
        .run()
        .unwrap();
    // Pressed (1), released (0), twice, for each task.
    assert_eq!(*seen[0].borrow(), [1, 0, 1, 0]);
    assert_eq!(*seen[1].borrow(), [1, 0, 1, 0]);
}

/// Issue 22 item 9: a task waits once for a pin's event, takes it and moves on; the pin's
/// next event is held for that task. A second task that waits on the pin later must get it
/// (before: it was kept for the first task, which never came back, and counted nowhere).
#[test]
fn a_task_that_waits_later_gets_the_event_held_for_one_that_moved_on() {
    use x10_microcode::{EventConfig, Op, Pin, Port};
    let world = World::new()
        .board(Board::new(9, 2, 2))
        .device(Device::button("button", 9, 1, Pin::A).pressed_at_ms(100, 10));
    let pin = Port::sensor(1).unwrap().pin(Pin::A);
    let db = Address::new(9).unwrap();
    type Log = Rc<RefCell<Vec<(&'static str, u8, u64)>>>;
    let seen: Log = Rc::default();
    let (s1, s2) = (seen.clone(), seen.clone());
    let config = SimConfig {
        duration_ms: 500,
        ..SimConfig::default()
    };
    world
        .sim(config)
        .unwrap()
        .with_robot("once", move |x10: X10| async move {
            let both = EventConfig {
                rising: true,
                falling: true,
                ..EventConfig::OFF
            };
            x10.call(db, Op::EventEnable(pin, both)).await?;
            let ev = x10.wait_event(db, pin).await?;
            s1.borrow_mut()
                .push(("once", ev.value[0], Instant::now().as_millis()));
            // moves on: never waits for this pin again
            Timer::after(Duration::from_secs(10)).await;
            Ok::<(), x10_devices::LinkError>(())
        })
        .with_robot("later", move |x10: X10| async move {
            Timer::after(Duration::from_millis(200)).await;
            let ev = x10.wait_event(db, pin).await?;
            s2.borrow_mut()
                .push(("later", ev.value[0], Instant::now().as_millis()));
            Ok::<(), x10_devices::LinkError>(())
        })
        .run()
        .unwrap();
    // Pressed at 100 ms (the first task), released at 110 ms: held, then the second task's
    // at once when it waits at 200 ms.
    let seen = seen.borrow().clone();
    assert_eq!(seen.len(), 2, "{seen:?}");
    assert_eq!((seen[0].0, seen[0].1), ("once", 1));
    assert_eq!(seen[1], ("later", 0, 200));
}

/// A board that restarts forgets its event enables; with the safe defaults the motherboard
/// sets them again when it prepares the board after its boot, so a task waiting for a button
/// keeps getting its presses (before: none after the reset, for good).
#[test]
fn event_enables_are_set_again_after_a_board_restarts() {
    use x10_microcode::{EventConfig, Op, Pin, Port};
    let world = World::new().board(Board::new(9, 2, 2)).device(
        Device::button("button", 9, 1, Pin::A)
            .pressed_at_ms(100, 20)
            .pressed_at_ms(600, 20),
    );
    let pin = Port::sensor(1).unwrap().pin(Pin::A);
    let db = Address::new(9).unwrap();
    let seen: Rc<RefCell<Vec<u8>>> = Rc::default();
    let log = seen.clone();
    let config = SimConfig {
        duration_ms: 900,
        ..SimConfig::default()
    };
    world
        .sim(config)
        .unwrap()
        .reset_at("db09", 300, 5)
        .with_robot("buttons", move |x10: X10| async move {
            let both = EventConfig {
                rising: true,
                falling: true,
                ..EventConfig::OFF
            };
            x10.call(db, Op::EventEnable(pin, both)).await?;
            loop {
                let ev = x10.wait_event(db, pin).await?;
                log.borrow_mut().push(ev.value[0]);
            }
            #[allow(unreachable_code)]
            Ok::<(), x10_devices::LinkError>(())
        })
        .run()
        .unwrap();
    // Pressed and released before the reset at 300 ms, and again at 600 ms after it.
    assert_eq!(*seen.borrow(), [1, 0, 1, 0]);
}
