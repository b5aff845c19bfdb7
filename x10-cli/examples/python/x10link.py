"""The X10 motherboard's USB link from Python (docs/usb-link.md): its frames (postcard, a
CRC-16, COBS, a zero byte) and a small `Robot` over pyserial that lists the boards, reads the
counters, calls an operation, gives a board an address and starts updates, as
`x10_cli::monitor::Robot` does in Rust.

    from x10link import Robot
    robot = Robot.open("/dev/ttyACM0")       # says hello
    print(robot.boards())                     # [0, 9]
    robot.call(0, 0x12, 0x01)                 # io high A1.B on the motherboard's own ports
    for b in robot.board_list():              # link version 2: plug and play's boards
        print(hex(b["address"]), b["uid"].hex(), b["firmware"], b["state"])
    robot.assign(bytes.fromhex("e6613852833f5c2a"), 0x40)   # -> {"status": "Done"}
    robot.start_update(None)                  # every board out of date -> {"status": "Started", "boards": 1}

Only the standard library for the frames; pyserial (`pip install pyserial`) for a port.
The frames are checked against the doc's example table by test_x10link.py.
"""

LINK_VERSION = 2

# ToHost variants, in order (docs/usb-link.md, "Messages, motherboard to laptop").
TO_HOST = ["Hello", "Log", "Call", "Event", "Output", "Dropped", "Reply", "Diagnostics",
           "Boards", "Refused", "BoardList", "Assigned", "UpdateAnswer", "Update"]
BOARD_STATES = ["Present", "Lost", "Updating", "Collided"]
ASSIGN_STATUS = ["Done", "UnknownUid", "Reserved", "Taken", "Collided", "NotConfirmed"]
UPDATE_STATUS = ["Started", "NoImages", "UnknownUid", "NotPresent", "NoImage", "UpToDate", "Busy"]
UPDATE_PHASES = ["Started", "Done", "Failed"]
UPDATE_FAILURES = ["NoMethod", "Enter", "NoBootloader", "Refused", "Link", "NotBack",
                   "RolledBack", "Rom"]
ANSWERS = ("Reply", "Diagnostics", "Boards", "Refused", "BoardList", "Assigned", "UpdateAnswer")
CALL_ERRORS = ["Nack", "Timeout", "ArbitrationLost", "Bus", "BadReply", "Status", "Invalid",
               "Busy", "Unsupported", "BadAddress", "Updating"]
OUTPUT_VALUES = ["Level", "Duty", "FrequencyHz", "PulseWidthUs"]


def crc16(data):
    """CRC-16/IBM-3740: polynomial 0x1021, initial 0xFFFF, no reflection."""
    c = 0xFFFF
    for b in data:
        c ^= b << 8
        for _ in range(8):
            c = ((c << 1) ^ 0x1021) & 0xFFFF if c & 0x8000 else (c << 1) & 0xFFFF
    return c


def cobs_encode(data):
    out = bytearray([0])
    code_at, code = 0, 1
    for b in data:
        if b == 0:
            out[code_at] = code
            code_at, code = len(out), 1
            out.append(0)
            continue
        out.append(b)
        code += 1
        if code == 0xFF:
            out[code_at] = code
            code_at, code = len(out), 1
            out.append(0)
    out[code_at] = code
    return bytes(out)


def cobs_decode(data):
    out = bytearray()
    i = 0
    while i < len(data):
        code = data[i]
        if code == 0 or i + code > len(data):
            raise ValueError("bad COBS")
        out += data[i + 1:i + code]
        i += code
        if code != 0xFF and i < len(data):
            out.append(0)
    return bytes(out)


def frame(message):
    """A frame around a message's postcard bytes: CRC (little-endian), COBS, a zero."""
    c = crc16(message)
    return cobs_encode(bytes(message) + bytes([c & 0xFF, c >> 8])) + b"\0"


def unframe(data):
    """The postcard bytes of one frame (without its zero); ValueError when damaged."""
    raw = cobs_decode(data)
    if len(raw) < 2 or crc16(raw[:-2]) != raw[-2] | raw[-1] << 8:
        raise ValueError("CRC mismatch")
    return raw[:-2]


def varint(n):
    out = bytearray()
    while n >= 0x80:
        out.append(n & 0x7F | 0x80)
        n >>= 7
    out.append(n)
    return bytes(out)


def lenbytes(b):
    return varint(len(b)) + bytes(b)


# Laptop to motherboard (ToDevice).
def hello(board="python"):
    return frame(b"\0" + varint(LINK_VERSION) + b"\0" + lenbytes(board.encode()) + lenbytes(b""))


def bye():
    return frame(b"\x01")


def call(id, db, fn_op, port, data=b""):
    """`ToDevice::Call`: operation byte 0 (`fn_op`), byte 2 (`port`) and data, on board `db`."""
    return frame(b"\x02" + varint(id) + bytes([db, fn_op, port]) + lenbytes(data))


def diagnostics(id):
    return frame(b"\x03" + varint(id))


def list_boards(id):
    return frame(b"\x04" + varint(id))


def boards(id, first=0):
    """`ToDevice::Boards` (version 2): plug and play's boards from index `first`."""
    return frame(b"\x05" + varint(id) + bytes([first]))


def assign(id, uid, address):
    """`ToDevice::Assign` (version 2): the board with unique ID `uid` (8 bytes) to `address`."""
    return frame(b"\x06" + varint(id) + bytes(uid) + bytes([address]))


def update(id, uid=None):
    """`ToDevice::Update` (version 2): the board `uid` (8 bytes), or every board (None)."""
    return frame(b"\x07" + varint(id) + (b"\x00" if uid is None else b"\x01" + bytes(uid)))


class _Reader:
    def __init__(self, data):
        self.data, self.i = data, 0

    def byte(self):
        if self.i >= len(self.data):
            raise ValueError("truncated")
        self.i += 1
        return self.data[self.i - 1]

    def varint(self):
        n, shift = 0, 0
        while True:
            b = self.byte()
            n |= (b & 0x7F) << shift
            shift += 7
            if b < 0x80:
                return n

    def bytes(self):
        n = self.varint()
        if self.i + n > len(self.data):
            raise ValueError("truncated")
        self.i += n
        return bytes(self.data[self.i - n:self.i])

    def fixed(self, n):
        return bytes(self.byte() for _ in range(n))

    def error(self):
        e = CALL_ERRORS[self.varint()]
        return {"err": e, "status": self.byte()} if e == "Status" else {"err": e}

    def outcome(self):
        if self.varint() == 0:
            return {"ok": self.bytes()}
        return self.error()


def decode(message):
    """A `ToHost` message (its postcard bytes) as a dict with its `kind`."""
    r = _Reader(message)
    kind = TO_HOST[r.varint()]
    m = {"kind": kind}
    if kind == "Hello":
        m.update(version=r.varint(), address=r.byte(), board=r.bytes().decode(),
                 robot=r.bytes().decode())
    elif kind == "Log":
        m["bytes"] = r.bytes()
    elif kind == "Call":
        m.update(db=r.byte(), fn_op=r.byte(), port=r.byte(), data=r.bytes(),
                 outcome=r.outcome(), start_us=r.varint(), end_us=r.varint())
    elif kind == "Event":
        m.update(db=r.byte(), event_kind=r.byte(), port=r.byte(), seq=r.byte(),
                 status=r.byte(), payload=r.bytes(), at_us=r.varint())
    elif kind == "Output":
        m.update(db=r.byte(), port=r.byte())
        v = OUTPUT_VALUES[r.varint()]
        m["value"] = (v, bool(r.byte()) if v == "Level" else r.byte() if v == "Duty"
                      else r.varint())
        m["at_us"] = r.varint()
    elif kind == "Dropped":
        for f in ["calls", "events", "outputs", "log_bytes", "bad_frames"]:
            m[f] = r.varint()
    elif kind == "Reply":
        m.update(id=r.varint(), outcome=r.outcome())
    elif kind == "Diagnostics":
        m["id"] = r.varint()
        m["counters"] = [r.varint() for _ in range(r.varint())]
    elif kind == "Boards":
        m["id"] = r.varint()
        m["addresses"] = list(r.bytes())
    elif kind == "Refused":
        m["id"] = r.varint()
    elif kind == "BoardList":
        m.update(id=r.varint(), total=r.byte(), first=r.byte())
        m["boards"] = [{"address": r.byte(), "uid": r.fixed(8), "kind": r.byte(),
                        "firmware": tuple(r.fixed(3)), "state": BOARD_STATES[r.varint()]}
                       for _ in range(r.varint())]
    elif kind == "Assigned":
        m["id"] = r.varint()
        m["status"] = ASSIGN_STATUS[r.varint()]
        if m["status"] == "NotConfirmed":
            m["error"] = r.error()
    elif kind == "UpdateAnswer":
        m["id"] = r.varint()
        m["status"] = UPDATE_STATUS[r.varint()]
        if m["status"] == "Started":
            m["boards"] = r.byte()
        elif m["status"] == "Busy":
            m["board"] = r.byte()
    elif kind == "Update":
        m.update(db=r.byte(), version_from=tuple(r.fixed(3)), version_to=tuple(r.fixed(3)))
        m["phase"] = UPDATE_PHASES[r.varint()]
        if m["phase"] == "Failed":
            m["failure"] = UPDATE_FAILURES[r.varint()]
        m["at_us"] = r.varint()
    if r.i != len(message):
        raise ValueError("bytes left over")
    return m


class Robot:
    """The robot behind a port: `port` has `write(bytes)` and `read(n)` (pyserial's
    `Serial`, or any object like it), and says hello at once."""

    def __init__(self, port, timeout_reads=100):
        self.port, self.timeout_reads = port, timeout_reads
        self.records, self._pending, self._next = [], bytearray(), 1
        self.port.write(hello())

    @classmethod
    def open(cls, path):
        import serial  # pyserial
        return cls(serial.Serial(path, 115200, timeout=0.05))

    def _ask(self, make):
        id, self._next = self._next, self._next % 0xFFFF + 1
        self.port.write(make(id))
        for _ in range(self.timeout_reads):
            for b in self.port.read(256):
                if b != 0:
                    self._pending.append(b)
                    continue
                data, self._pending = bytes(self._pending), bytearray()
                try:
                    m = decode(unframe(data))
                except (ValueError, IndexError):
                    continue
                if m["kind"] in ANSWERS and m.get("id") in (id, 0):
                    return m
                self.records.append(m)
        raise TimeoutError("no answer from the robot")

    def boards(self):
        return self._ask(list_boards)["addresses"]

    def counters(self):
        return self._ask(diagnostics)["counters"]

    def call(self, db, fn_op, port, data=b""):
        """Calls an operation; returns its reply payload, raises RuntimeError with the error."""
        m = self._ask(lambda id: call(id, db, fn_op, port, data))
        if m["kind"] == "Refused":
            raise RuntimeError("refused")
        if "err" in m["outcome"]:
            raise RuntimeError(m["outcome"])
        return m["outcome"]["ok"]

    def board_list(self):
        """Every board plug and play knows (link version 2), page by page; raises RuntimeError
        when the motherboard refuses (an older link version)."""
        found = []
        while True:
            m = self._ask(lambda id: boards(id, len(found)))
            if m["kind"] != "BoardList":
                raise RuntimeError("refused: the motherboard's link version is older than 2")
            found += m["boards"]
            if not m["boards"] or len(found) >= m["total"]:
                return found

    def assign(self, uid, address):
        """Gives the board `uid` (8 bytes) the address; returns the `Assigned` message's dict."""
        m = self._ask(lambda id: assign(id, uid, address))
        if m["kind"] != "Assigned":
            raise RuntimeError("refused: the motherboard's link version is older than 2")
        return m

    def start_update(self, uid=None):
        """Starts the update of the board `uid` (8 bytes), or of every board (None); returns
        the `UpdateAnswer` message's dict. `Update` records follow in `records`."""
        m = self._ask(lambda id: update(id, uid))
        if m["kind"] != "UpdateAnswer":
            raise RuntimeError("refused: the motherboard's link version is older than 2")
        return m
