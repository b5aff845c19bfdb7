//! Function 7, `update`: the frames a daughterboard's bootloader answers while it takes a new
//! image over the bus (`docs/protocol.md`, "Firmware over the bus").
//!
//! A board enters its bootloader when the application is asked to (System 12,
//! [`crate::Op::EnterUpdate`]); the bootloader then answers these five operations at the
//! board's own address, every frame with its check (PEC byte or CRC-16):
//!
//! | byte 0 | operation | data | reply payload |
//! |---|---|---|---|
//! | `0x70` | begin | [`ImageInfo`], 12 bytes | empty |
//! | `0x71` | chunk | offset u32 LE, then 1..=[`CHUNK_MAX`] image bytes | empty |
//! | `0x72` | commit | none | empty |
//! | `0x73` | status | none | [`UpdateReport`], 6 bytes |
//! | `0x74` | leave | none | empty |
//!
//! Every refusal is a status of its own ([`crate::Status::WrongKind`] …
//! [`crate::Status::Incomplete`]).

use crate::{BoardKind, Error, Result, Status, MAX_REQUEST_DATA};

/// Image bytes one `chunk` carries at most: the request's data less the 4-byte offset.
pub const CHUNK_MAX: usize = MAX_REQUEST_DATA - 4;

/// The CRC-32 the update frames name: CRC-32/ISO-HDLC (the zlib / Ethernet CRC-32).
pub const IMAGE_CRC: crc::Crc<u32> = crc::Crc::<u32>::new(&crc::CRC_32_ISO_HDLC);

/// CRC-32/ISO-HDLC of a whole image.
pub fn image_crc32(bytes: &[u8]) -> u32 {
    IMAGE_CRC.checksum(bytes)
}

/// A firmware version: major, minor, patch (as `identify` reports it). Compared in that order.
pub type Version = [u8; 3];

/// What `begin` announces: the data of operand 0, 12 bytes.
///
/// | bytes | field |
/// |---|---|
/// | 0..=3 | image length, u32 LE |
/// | 4..=7 | CRC-32/ISO-HDLC of the image, u32 LE |
/// | 8 | board kind the image is built for |
/// | 9..=11 | the image's firmware version: major, minor, patch |
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ImageInfo {
    /// Image length in bytes.
    pub len: u32,
    /// CRC-32/ISO-HDLC of the image.
    pub crc32: u32,
    /// The board kind the image is for.
    pub board: BoardKind,
    /// The image's firmware version.
    pub version: Version,
}

impl ImageInfo {
    /// Encoded length.
    pub const LEN: usize = 12;

    /// Parses the data of `begin`.
    ///
    /// # Errors
    /// [`Error::BadLength`] unless exactly [`ImageInfo::LEN`] bytes.
    pub fn parse(data: &[u8]) -> Result<ImageInfo> {
        let [l0, l1, l2, l3, c0, c1, c2, c3, board, ma, mi, pa] = *data else {
            return Err(Error::BadLength);
        };
        Ok(ImageInfo {
            len: u32::from_le_bytes([l0, l1, l2, l3]),
            crc32: u32::from_le_bytes([c0, c1, c2, c3]),
            board: BoardKind(board),
            version: [ma, mi, pa],
        })
    }

    /// Encodes the data of `begin`.
    pub fn to_bytes(&self) -> [u8; Self::LEN] {
        let [l0, l1, l2, l3] = self.len.to_le_bytes();
        let [c0, c1, c2, c3] = self.crc32.to_le_bytes();
        let [ma, mi, pa] = self.version;
        [l0, l1, l2, l3, c0, c1, c2, c3, self.board.0, ma, mi, pa]
    }
}

/// One operation of function 7.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum UpdateOp<'a> {
    /// Operand 0: a new transfer into the inactive slot (any transfer under way is dropped).
    Begin(ImageInfo),
    /// Operand 1: `data` belongs at `offset` of the image. Only the next expected offset is
    /// taken, or a repeat of the last chunk (answered `ok` again, nothing written twice).
    Chunk {
        /// Where the bytes go in the image.
        offset: u32,
        /// 1..=[`CHUNK_MAX`] bytes.
        data: &'a [u8],
    },
    /// Operand 2: verify length, CRC-32, kind and version, mark the slot for the swap and
    /// reset once the reply has been read.
    Commit,
    /// Operand 3: report the transfer ([`UpdateReport`]).
    Status,
    /// Operand 4: leave the bootloader and start the current image unchanged.
    Leave,
}

/// Operand codes of function 7.
#[allow(missing_docs)]
impl UpdateOp<'_> {
    pub const BEGIN: u8 = 0;
    pub const CHUNK: u8 = 1;
    pub const COMMIT: u8 = 2;
    pub const STATUS: u8 = 3;
    pub const LEAVE: u8 = 4;
}

impl<'a> UpdateOp<'a> {
    /// Parses operand and data (byte 2 must be 0).
    ///
    /// # Errors
    /// [`Error::UnknownOperand`], [`Error::BadLength`], [`Error::BadArgument`] (a port byte).
    pub fn parse(operand: u8, port: u8, data: &'a [u8]) -> Result<UpdateOp<'a>> {
        let op = match (operand, data) {
            (Self::BEGIN, _) => UpdateOp::Begin(ImageInfo::parse(data)?),
            (Self::CHUNK, [o0, o1, o2, o3, rest @ ..]) if !rest.is_empty() => UpdateOp::Chunk {
                offset: u32::from_le_bytes([*o0, *o1, *o2, *o3]),
                data: rest,
            },
            (Self::CHUNK, _) => return Err(Error::BadLength),
            (Self::COMMIT, []) => UpdateOp::Commit,
            (Self::STATUS, []) => UpdateOp::Status,
            (Self::LEAVE, []) => UpdateOp::Leave,
            (Self::COMMIT | Self::STATUS | Self::LEAVE, _) => return Err(Error::BadLength),
            _ => {
                return Err(Error::UnknownOperand {
                    function: 7,
                    operand,
                })
            }
        };
        if port != 0 {
            return Err(Error::BadArgument);
        }
        Ok(op)
    }

    /// The operand code.
    pub const fn operand(&self) -> u8 {
        match self {
            UpdateOp::Begin(_) => Self::BEGIN,
            UpdateOp::Chunk { .. } => Self::CHUNK,
            UpdateOp::Commit => Self::COMMIT,
            UpdateOp::Status => Self::STATUS,
            UpdateOp::Leave => Self::LEAVE,
        }
    }

    /// Name, as the `x10` tool prints it.
    pub const fn name(&self) -> &'static str {
        match self {
            UpdateOp::Begin(_) => "begin",
            UpdateOp::Chunk { .. } => "chunk",
            UpdateOp::Commit => "commit",
            UpdateOp::Status => "status",
            UpdateOp::Leave => "leave",
        }
    }

    /// Data bytes on the wire.
    pub fn data_len(&self) -> usize {
        match self {
            UpdateOp::Begin(_) => ImageInfo::LEN,
            UpdateOp::Chunk { data, .. } => 4 + data.len(),
            _ => 0,
        }
    }

    /// Writes the data bytes into `buf`; returns how many.
    ///
    /// # Errors
    /// [`Error::BufferTooShort`].
    pub fn emit_data(&self, buf: &mut [u8]) -> Result<usize> {
        let n = self.data_len();
        let out = buf.get_mut(..n).ok_or(Error::BufferTooShort)?;
        match self {
            UpdateOp::Begin(info) => out.copy_from_slice(&info.to_bytes()),
            UpdateOp::Chunk { offset, data } => {
                let (o, d) = out.split_at_mut(4);
                o.copy_from_slice(&offset.to_le_bytes());
                d.copy_from_slice(data);
            }
            _ => {}
        }
        Ok(n)
    }

    /// Payload length of an `ok` reply: [`UpdateReport::LEN`] for `status`, else 0.
    pub const fn reply_len(&self) -> usize {
        match self {
            UpdateOp::Status => UpdateReport::LEN,
            _ => 0,
        }
    }
}

/// Function 7 as [`crate::Op::Update`] carries it: the operand and the data bytes, checked
/// for their lengths only. An application refuses function 7 whatever it says, so it never
/// pays for decoding it; a bootloader decodes it with [`UpdateFrame::op`]. Build one with
/// [`UpdateOp::to_op`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct UpdateFrame<'a> {
    operand: u8,
    data: &'a [u8],
}

impl<'a> UpdateFrame<'a> {
    /// Checks operand, port byte and data length.
    ///
    /// # Errors
    /// [`Error::UnknownOperand`], [`Error::BadLength`], [`Error::BadArgument`] (a port byte).
    pub fn parse(operand: u8, port: u8, data: &'a [u8]) -> Result<UpdateFrame<'a>> {
        let ok = match operand {
            UpdateOp::BEGIN => data.len() == ImageInfo::LEN,
            UpdateOp::CHUNK => data.len() > 4,
            UpdateOp::COMMIT | UpdateOp::STATUS | UpdateOp::LEAVE => data.is_empty(),
            _ => {
                return Err(Error::UnknownOperand {
                    function: 7,
                    operand,
                })
            }
        };
        if !ok {
            return Err(Error::BadLength);
        }
        if port != 0 {
            return Err(Error::BadArgument);
        }
        Ok(UpdateFrame { operand, data })
    }

    /// The operand.
    pub const fn operand(&self) -> u8 {
        self.operand
    }

    /// The data bytes.
    pub const fn data(&self) -> &'a [u8] {
        self.data
    }

    /// The operation, decoded.
    pub fn op(&self) -> UpdateOp<'a> {
        UpdateOp::parse(self.operand, 0, self.data).unwrap_or(UpdateOp::Status)
    }

    /// Name, as the `x10` tool prints it.
    pub const fn name(&self) -> &'static str {
        match self.operand {
            UpdateOp::BEGIN => "begin",
            UpdateOp::CHUNK => "chunk",
            UpdateOp::COMMIT => "commit",
            UpdateOp::STATUS => "status",
            _ => "leave",
        }
    }

    /// Payload length of an `ok` reply: [`UpdateReport::LEN`] for `status`, else 0.
    pub const fn reply_len(&self) -> usize {
        if self.operand == UpdateOp::STATUS {
            UpdateReport::LEN
        } else {
            0
        }
    }
}

impl UpdateOp<'_> {
    /// The operation as a request's [`crate::Op`], its data written into `buf`.
    pub fn to_op<'b>(&self, buf: &'b mut [u8; MAX_REQUEST_DATA]) -> crate::Op<'b> {
        let n = self.emit_data(buf).unwrap_or(0);
        crate::Op::Update(UpdateFrame {
            operand: self.operand(),
            data: buf.get(..n).unwrap_or(&[]),
        })
    }
}

/// Where a bootloader's transfer is (byte 0 of the `status` reply).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum UpdateState {
    /// 0: no transfer (after start, a refused `begin`, or a refused `commit`).
    Idle,
    /// 1: `begin` taken, chunks being received.
    Receiving,
    /// 2: `commit` verified the image and marked the slot; the board resets into it.
    Committed,
    /// A code this version does not know.
    Unknown(u8),
}

impl UpdateState {
    /// Decodes the state byte.
    pub const fn from_byte(b: u8) -> UpdateState {
        match b {
            0 => UpdateState::Idle,
            1 => UpdateState::Receiving,
            2 => UpdateState::Committed,
            x => UpdateState::Unknown(x),
        }
    }

    /// Encodes the state byte.
    pub const fn to_byte(self) -> u8 {
        match self {
            UpdateState::Idle => 0,
            UpdateState::Receiving => 1,
            UpdateState::Committed => 2,
            UpdateState::Unknown(x) => x,
        }
    }

    /// Name, as the `x10` tool prints it.
    pub const fn name(self) -> &'static str {
        match self {
            UpdateState::Idle => "idle",
            UpdateState::Receiving => "receiving",
            UpdateState::Committed => "committed",
            UpdateState::Unknown(_) => "unknown",
        }
    }
}

/// Reply payload of `status`, 6 bytes: state (1 byte), image bytes received (u32 LE), the
/// status of the last refused operation (1 byte; `ok` when none since `begin`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct UpdateReport {
    /// Where the transfer is.
    pub state: UpdateState,
    /// Image bytes received and taken so far (the next offset expected).
    pub received: u32,
    /// The last refusal, or `ok`.
    pub last_error: Status,
}

impl UpdateReport {
    /// Encoded length.
    pub const LEN: usize = 6;

    /// Parses a `status` payload.
    ///
    /// # Errors
    /// [`Error::BadLength`] unless exactly [`UpdateReport::LEN`] bytes.
    pub fn parse(payload: &[u8]) -> Result<UpdateReport> {
        let [state, r0, r1, r2, r3, err] = *payload else {
            return Err(Error::BadLength);
        };
        Ok(UpdateReport {
            state: UpdateState::from_byte(state),
            received: u32::from_le_bytes([r0, r1, r2, r3]),
            last_error: Status::from_byte(err),
        })
    }

    /// Encodes the payload.
    pub fn to_bytes(&self) -> [u8; Self::LEN] {
        let [r0, r1, r2, r3] = self.received.to_le_bytes();
        [
            self.state.to_byte(),
            r0,
            r1,
            r2,
            r3,
            self.last_error.to_byte(),
        ]
    }
}
