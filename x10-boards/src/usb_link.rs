//! The USB link of the motherboard images (issue 26, docs/usb-link.md): a CDC-ACM serial
//! device (embassy-usb) carrying `x10-link` frames. `start_motherboard` installs [`RECORDER`]
//! as the motherboard's call observer and spawns the board's USB task, which runs
//! [`run`]: the USB device, a reader that decodes the laptop's requests and serves them
//! through `X10::call` (`x10_link::recorder::serve`), and a writer that drains the recorder's
//! ring in 64-byte packets.
//!
//! Nobody listening costs the robot a counter per call: records are kept only between the
//! laptop's hello and its bye, or the end of the connection. Unplugged, the host's bus reset
//! at the next plug-in disables the endpoints: both loops see `EndpointError::Disabled`, stop
//! listening, empty the ring and wait for the device to be configured again; the laptop's new
//! hello starts the records again. Nothing here waits on a robot task or makes one wait.

use embassy_futures::join::join3;
use embassy_usb::class::cdc_acm::{CdcAcmClass, Receiver, Sender, State};
use embassy_usb::driver::Driver;
use embassy_usb::{Builder, Config};
use firmware_mb::X10;
use x10_link::recorder::{serve, Identity, Recorder};
use x10_link::{Feed, FrameReader, ToDevice};

/// Bytes of frames the motherboard keeps for the laptop (about 60 call records).
pub const RING_BYTES: usize = 2048;

/// USB full speed's bulk packet size.
const PACKET: usize = 64;

/// The motherboard's recorder, its call observer in the images.
pub static RECORDER: Recorder<RING_BYTES> = Recorder::new();

/// What embassy-usb keeps for the device's life: its descriptors, control buffer and the
/// CDC-ACM class's state.
struct Buffers {
    config_descriptor: [u8; 128],
    bos_descriptor: [u8; 16],
    control: [u8; 64],
    state: State<'static>,
}

static BUFFERS: static_cell::StaticCell<Buffers> = static_cell::StaticCell::new();

/// USB vendor and product ID: pid.codes' test IDs (0x1209:0x0001), for a device that is not
/// sold; a product gets its own.
pub const USB_VID_PID: (u16, u16) = (0x1209, 0x0001);

/// Runs the USB device and the link on `driver`; never returns. `board` names the board in
/// the hello.
pub async fn run<D: Driver<'static>>(driver: D, x10: X10, board: &'static str) -> ! {
    let mut config = Config::new(USB_VID_PID.0, USB_VID_PID.1);
    config.manufacturer = Some("X10");
    config.product = Some("X10 motherboard");
    config.max_power = 100;
    config.max_packet_size_0 = 64;

    let Some(b) = BUFFERS.try_init(Buffers {
        config_descriptor: [0; 128],
        bos_descriptor: [0; 16],
        control: [0; 64],
        state: State::new(),
    }) else {
        // A second run: the USB block has one device, already running.
        loop {
            core::future::pending::<()>().await;
        }
    };
    let mut builder = Builder::new(
        driver,
        config,
        &mut b.config_descriptor,
        &mut b.bos_descriptor,
        &mut [],
        &mut b.control,
    );
    let class = CdcAcmClass::new(&mut builder, &mut b.state, PACKET as u16);
    let mut usb = builder.build();
    let (tx, rx) = class.split();
    let who = Identity {
        address: x10.config().address.get(),
        board,
        robot: crate::start::robot_name(),
    };
    let (never, _, _) = join3(usb.run(), write_loop(tx), read_loop(rx, x10, who)).await;
    never
}

/// Drains the ring to the laptop, one packet at a time; a full packet that empties the ring
/// is followed by a zero-length one so the host's read ends. One `write_packet` for both (each
/// await of it is a copy of its poll in the task's state machine: issue 26's flash budget).
async fn write_loop<D: Driver<'static>>(mut tx: Sender<'static, D>) -> ! {
    let mut packet = [0u8; PACKET];
    loop {
        tx.wait_connection().await;
        // The last packet written was full and emptied the ring: a zero-length one is due.
        let mut end_read = false;
        loop {
            let n = if end_read {
                0
            } else {
                RECORDER.take(&mut packet)
            };
            if n == 0 && !end_read {
                RECORDER.wait_data().await;
                continue;
            }
            if tx
                .write_packet(packet.get(..n).unwrap_or(&[]))
                .await
                .is_err()
            {
                break;
            }
            end_read = n == PACKET && RECORDER.pending() == 0;
        }
        RECORDER.set_listening(false);
    }
}

/// Reads the laptop's frames and serves each request in turn.
async fn read_loop<D: Driver<'static>>(mut rx: Receiver<'static, D>, x10: X10, who: Identity) -> ! {
    let mut reader: FrameReader<128> = FrameReader::new();
    let mut packet = [0u8; PACKET];
    loop {
        rx.wait_connection().await;
        reader.clear();
        loop {
            let Ok(n) = rx.read_packet(&mut packet).await else {
                break;
            };
            for &b in packet.get(..n).unwrap_or(&[]) {
                match reader.feed(b) {
                    Feed::Pending => {}
                    Feed::TooLong => RECORDER.bad_frame(),
                    Feed::Frame => match reader.decode_device() {
                        Ok(req) => {
                            let hello = matches!(req, ToDevice::Hello(_));
                            serve(&RECORDER, x10, who, req).await;
                            if hello {
                                // The first line a laptop gets over the link (docs/usb-link.md).
                                defmt::info!(
                                    "USB link: a laptop listens (link version {=u16})",
                                    x10_link::LINK_VERSION
                                );
                            }
                        }
                        Err(_) => {
                            RECORDER.bad_frame();
                            RECORDER.send(&x10_link::ToHost::Refused { id: 0 });
                        }
                    },
                }
            }
        }
        RECORDER.set_listening(false);
    }
}
