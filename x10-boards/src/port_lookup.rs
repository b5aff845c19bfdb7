//! Where the port or pin of a request leads among a board's sensor ports and actuator ports,
//! and which error answers a port or pin the board lacks or a port of the wrong kind. The
//! same on every chip: the chip modules (`pico`, `stm32`) hold the ports and ask here. Owns
//! no state; tested on the host.

use x10_hal::ports::PortError;
use x10_microcode::{PinRef, Port, PortKind};

/// A pin, a PWM unit or an ADC of a board's ports (both chips): shared between the requests
/// and a pulse-in measurement, which holds its pin while it waits for edges. Only ever taken
/// without waiting ([`take`]), so it is a flag and the value, not an async mutex: no waker to
/// wake when it is let go (embassy-sync's `Mutex` cost 600 B more flash on db-pico).
#[cfg(feature = "_chip")]
pub struct Lock<T> {
    taken: core::cell::Cell<bool>,
    value: core::cell::UnsafeCell<T>,
}

// SAFETY: the flag is tested and set in a critical section, so at most one `Guard` exists at
// a time, on whichever context took it; the value is only reached through that guard.
#[cfg(feature = "_chip")]
#[allow(unsafe_code)]
unsafe impl<T: Send> Sync for Lock<T> {}

#[cfg(feature = "_chip")]
impl<T> Lock<T> {
    /// `value`, not taken.
    pub const fn new(value: T) -> Self {
        Lock {
            taken: core::cell::Cell::new(false),
            value: core::cell::UnsafeCell::new(value),
        }
    }
}

/// A [`Lock`] taken: the value, until dropped.
#[cfg(feature = "_chip")]
pub struct Guard<'a, T> {
    lock: &'a Lock<T>,
}

#[cfg(feature = "_chip")]
#[allow(unsafe_code)]
impl<T> core::ops::Deref for Guard<'_, T> {
    type Target = T;
    fn deref(&self) -> &T {
        // SAFETY: this guard is the only one (see `Lock`'s `Sync`).
        unsafe { &*self.lock.value.get() }
    }
}

#[cfg(feature = "_chip")]
#[allow(unsafe_code)]
impl<T> core::ops::DerefMut for Guard<'_, T> {
    fn deref_mut(&mut self) -> &mut T {
        // SAFETY: this guard is the only one (see `Lock`'s `Sync`).
        unsafe { &mut *self.lock.value.get() }
    }
}

#[cfg(feature = "_chip")]
impl<T> Drop for Guard<'_, T> {
    fn drop(&mut self) {
        // Only the holder clears the flag: one byte store, no critical section needed.
        self.lock.taken.set(false);
    }
}

/// Takes `lock` without waiting. Only a pulse-in holds a lock across an await (its pin), so a
/// PWM unit or the ADC is never found taken on the single-threaded executor; whatever is
/// taken is answered [`PortError::Busy`].
///
/// # Errors
/// [`PortError::Busy`] when `lock` is held.
#[cfg(feature = "_chip")]
#[inline(always)]
pub fn take<T>(lock: &Lock<T>) -> Result<Guard<'_, T>, PortError> {
    cortex_m::interrupt::free(|_| {
        if lock.taken.replace(true) {
            Err(PortError::Busy)
        } else {
            Ok(Guard { lock })
        }
    })
}

/// The sensor port `port` names.
///
/// # Errors
/// [`PortError::Unsupported`] for an actuator port, [`PortError::NoSuchPin`] past the last
/// sensor port.
pub fn sensor<S>(sensors: &[S], port: Port) -> Result<&S, PortError> {
    match port.kind() {
        PortKind::Sensor => sensors
            .get(usize::from(port.index()))
            .ok_or(PortError::NoSuchPin),
        PortKind::Actuator => Err(PortError::Unsupported),
    }
}

/// The actuator port `port` names.
///
/// # Errors
/// [`PortError::Unsupported`] for a sensor port, [`PortError::NoSuchPin`] past the last
/// actuator port.
pub fn actuator<A>(actuators: &[A], port: Port) -> Result<&A, PortError> {
    match port.kind() {
        PortKind::Actuator => actuators
            .get(usize::from(port.index()))
            .ok_or(PortError::NoSuchPin),
        PortKind::Sensor => Err(PortError::Unsupported),
    }
}

/// The digital pin `pin` names, on a sensor port (its pins: `sensor_pins`) or an actuator
/// port (`actuator_pins`).
///
/// # Errors
/// [`PortError::NoSuchPin`] past the last port of its kind.
pub fn digital<'a, S, A, P>(
    sensors: &'a [S],
    actuators: &'a [A],
    pin: PinRef,
    sensor_pins: impl FnOnce(&'a S) -> &'a [P; 2],
    actuator_pins: impl FnOnce(&'a A) -> &'a [P; 2],
) -> Result<&'a P, PortError> {
    let i = usize::from(pin.port.index());
    let pins = match pin.port.kind() {
        PortKind::Sensor => sensor_pins(sensors.get(i).ok_or(PortError::NoSuchPin)?),
        PortKind::Actuator => actuator_pins(actuators.get(i).ok_or(PortError::NoSuchPin)?),
    };
    pins.get(pin.pin.index()).ok_or(PortError::NoSuchPin)
}

#[cfg(test)]
mod tests {
    use super::*;
    use x10_microcode::test_support::{a, s};
    use x10_microcode::Pin;

    const SENSORS: [[u8; 2]; 2] = [[10, 11], [20, 21]];
    const ACTUATORS: [[u8; 2]; 1] = [[30, 31]];

    #[test]
    fn ports_of_the_wrong_kind_are_unsupported_and_missing_ones_no_such_pin() {
        assert_eq!(sensor(&SENSORS, s(2)), Ok(&[20, 21]));
        assert_eq!(sensor(&SENSORS, s(3)), Err(PortError::NoSuchPin));
        assert_eq!(sensor(&SENSORS, a(1)), Err(PortError::Unsupported));
        assert_eq!(sensor(&SENSORS, a(9)), Err(PortError::Unsupported));
        assert_eq!(actuator(&ACTUATORS, a(1)), Ok(&[30, 31]));
        assert_eq!(actuator(&ACTUATORS, a(2)), Err(PortError::NoSuchPin));
        assert_eq!(actuator(&ACTUATORS, s(1)), Err(PortError::Unsupported));
        assert_eq!(actuator(&ACTUATORS, s(9)), Err(PortError::Unsupported));
    }

    #[test]
    fn digital_pins_on_both_kinds_of_port() {
        let pin = |p: Port, b: Pin| digital(&SENSORS, &ACTUATORS, p.pin(b), |s| s, |a| a);
        assert_eq!(pin(s(1), Pin::A), Ok(&10));
        assert_eq!(pin(s(2), Pin::B), Ok(&21));
        assert_eq!(pin(a(1), Pin::B), Ok(&31));
        assert_eq!(pin(s(3), Pin::A), Err(PortError::NoSuchPin));
        assert_eq!(pin(a(2), Pin::A), Err(PortError::NoSuchPin));
    }
}
