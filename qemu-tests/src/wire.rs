//! Two nodes on one loopback "bus": what one writes, the other listens to; a write-then-read
//! waits for the other's answer. A node addressed while its inbox is full NACKs, as an I2C
//! target that is busy would.

use embassy_sync::blocking_mutex::raw::NoopRawMutex;
use embassy_sync::channel::Channel;
use embassy_sync::signal::Signal;
use x10_hal::bus::{BusError, Incoming, MultiMaster};
use x10_microcode::MAX_FRAME_LEN;

/// Bytes of one transfer.
pub type Bytes = heapless::Vec<u8, { MAX_FRAME_LEN + 1 }>;

/// One write, and how many bytes the writer reads back after a repeated START.
struct Transfer {
    bytes: Bytes,
    read_len: Option<usize>,
}

/// The bus: node 0 and node 1 with their addresses.
pub struct Wire {
    addr: [u8; 2],
    inbox: [Channel<NoopRawMutex, Transfer, 2>; 2],
    readback: [Signal<NoopRawMutex, Bytes>; 2],
}

impl Wire {
    /// A bus with node 0 at `addr0` and node 1 at `addr1`.
    pub const fn new(addr0: u8, addr1: u8) -> Wire {
        Wire {
            addr: [addr0, addr1],
            inbox: [Channel::new(), Channel::new()],
            readback: [Signal::new(), Signal::new()],
        }
    }

    /// Node `n`'s port (0 or 1).
    pub fn end(&self, n: usize) -> End<'_> {
        End {
            wire: self,
            me: n & 1,
            read_len: None,
        }
    }
}

/// One node's [`MultiMaster`] port on a [`Wire`].
pub struct End<'a> {
    wire: &'a Wire,
    me: usize,
    read_len: Option<usize>,
}

impl End<'_> {
    fn send(&self, addr: u8, bytes: &[u8], read_len: Option<usize>) -> Result<(), BusError> {
        let peer = 1 - self.me;
        if addr != self.wire.addr[peer] {
            return Err(BusError::Nack);
        }
        let bytes = Bytes::from_slice(bytes).map_err(|_| BusError::Overrun)?;
        self.wire.inbox[peer]
            .try_send(Transfer { bytes, read_len })
            .map_err(|_| BusError::Nack)
    }
}

impl MultiMaster for End<'_> {
    async fn write(&mut self, addr: u8, bytes: &[u8]) -> Result<(), BusError> {
        self.send(addr, bytes, None)
    }

    async fn write_read(
        &mut self,
        addr: u8,
        bytes: &[u8],
        read: &mut [u8],
    ) -> Result<(), BusError> {
        // An answer to an abandoned earlier read must not be taken for this one.
        self.wire.readback[self.me].reset();
        self.send(addr, bytes, Some(read.len()))?;
        let answer = self.wire.readback[self.me].wait().await;
        for (i, b) in read.iter_mut().enumerate() {
            *b = answer.get(i).copied().unwrap_or(0xFF);
        }
        Ok(())
    }

    async fn addressed(&mut self) -> Result<(), BusError> {
        // Waits for a transfer in the inbox without taking it out.
        self.wire.inbox[self.me].ready_to_receive().await;
        Ok(())
    }

    async fn listen(&mut self, buf: &mut [u8]) -> Result<Incoming, BusError> {
        let t = self.wire.inbox[self.me].receive().await;
        let n = t.bytes.len();
        buf.get_mut(..n)
            .ok_or(BusError::Overrun)?
            .copy_from_slice(&t.bytes);
        self.read_len = t.read_len;
        Ok(match t.read_len {
            None => Incoming::Write(n),
            Some(_) => Incoming::WriteRead(n),
        })
    }

    async fn respond(&mut self, bytes: &[u8]) -> Result<(), BusError> {
        let len = self.read_len.take().ok_or(BusError::Bus)?;
        let mut answer = Bytes::new();
        for i in 0..len.min(answer.capacity()) {
            // The controller reads `len` bytes; past the reply it gets 0xFF.
            let _ = answer.push(bytes.get(i).copied().unwrap_or(0xFF));
        }
        self.wire.readback[1 - self.me].signal(answer);
        Ok(())
    }
}
