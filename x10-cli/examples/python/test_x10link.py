"""x10link.py against docs/usb-link.md's example frames (every row of its table), and its
Robot against a fake port answering with those frames. Run: python3 -m unittest discover -s
x10-cli/examples/python (./test-all does)."""
import os
import unittest

import x10link

UID = bytes.fromhex("e6613852833f5c2a")
DOC = os.path.join(os.path.dirname(__file__), "..", "..", "..", "docs", "usb-link.md")


def doc_rows():
    rows = []
    for line in open(DOC, encoding="utf-8"):
        cells = [c.strip() for c in line.split("|")]
        if len(cells) >= 5 and cells[1] in ("ToHost", "ToDevice"):
            rows.append((cells[1], cells[2].strip("`"), bytes.fromhex(cells[3].strip("`"))))
    return rows


def row(way, prefix):
    found = [b for w, m, b in doc_rows() if w == way and m.startswith(prefix)]
    assert len(found) == 1, (way, prefix, found)
    return found[0]


class Frames(unittest.TestCase):
    def test_every_to_device_row_is_encoded_exactly(self):
        self.assertEqual(x10link.hello("x10"), row("ToDevice", "Hello"))
        self.assertEqual(x10link.bye(), row("ToDevice", "Bye"))
        self.assertEqual(x10link.call(7, 0, 0x12, 0x01), row("ToDevice", "Call"))
        self.assertEqual(x10link.diagnostics(8), row("ToDevice", "Diagnostics"))
        self.assertEqual(x10link.list_boards(9), row("ToDevice", "ListBoards"))
        self.assertEqual(x10link.boards(11, 0), row("ToDevice", "Boards"))
        self.assertEqual(x10link.assign(12, UID, 0x40), row("ToDevice", "Assign"))
        self.assertEqual(x10link.update(14, UID), row("ToDevice", "Update { id: 14"))
        self.assertEqual(x10link.update(16), row("ToDevice", "Update { id: 16"))
        self.assertEqual(len([w for w, _, _ in doc_rows() if w == "ToDevice"]), 9)

    def test_every_to_host_row_is_decoded_exactly(self):
        want = {
            "Hello": {"kind": "Hello", "version": 2, "address": 8, "board": "Pico", "robot": "fig4_4"},
            "Log": {"kind": "Log", "bytes": bytes([1, 2, 0, 3])},
            "Call(CallRec { db: 0": {"kind": "Call", "db": 0, "fn_op": 0x20, "port": 0, "data": bytes([127]),
                                     "outcome": {"ok": b""}, "start_us": 1000000, "end_us": 1000450},
            "Call(CallRec { db: 9": {"kind": "Call", "db": 9, "fn_op": 0x30, "port": 0x80, "data": b"",
                                     "outcome": {"err": "Status", "status": 5}, "start_us": 2000, "end_us": 2900},
            "Event": {"kind": "Event", "db": 9, "event_kind": 1, "port": 128, "seq": 4, "status": 0,
                      "payload": bytes([1]), "at_us": 1500000},
            "Output(OutputRec { db: 0, port: 0": {"kind": "Output", "db": 0, "port": 0, "value": ("Duty", 127), "at_us": 1000450},
            "Output(OutputRec { db: 0, port: 1": {"kind": "Output", "db": 0, "port": 1, "value": ("Level", True), "at_us": 1000900},
            "Dropped": {"kind": "Dropped", "calls": 3, "events": 0, "outputs": 2, "log_bytes": 0, "bad_frames": 1},
            "Reply": {"kind": "Reply", "id": 7, "outcome": {"ok": bytes([2, 0])}},
            "Diagnostics": {"kind": "Diagnostics", "id": 8, "counters": [12, 12, 0, 0]},
            "Boards": {"kind": "Boards", "id": 9, "addresses": [0, 9]},
            "Refused": {"kind": "Refused", "id": 10},
            "BoardList": {"kind": "BoardList", "id": 11, "total": 2, "first": 0, "boards": [
                {"address": 0x20, "uid": UID, "kind": 3, "firmware": (0, 1, 0), "state": "Present"},
                {"address": 0x31, "uid": bytes([9, 8, 7, 6, 5, 4, 3, 2]), "kind": 5,
                 "firmware": (2, 0, 0), "state": "Lost"}]},
            "Assigned { id: 12": {"kind": "Assigned", "id": 12, "status": "Done"},
            "Assigned { id: 13": {"kind": "Assigned", "id": 13, "status": "NotConfirmed",
                                  "error": {"err": "Timeout"}},
            "UpdateAnswer { id: 14": {"kind": "UpdateAnswer", "id": 14, "status": "Started", "boards": 1},
            "UpdateAnswer { id: 15": {"kind": "UpdateAnswer", "id": 15, "status": "Busy", "board": 0x20},
            "Update(UpdateRec { db: 32, from: [0, 1, 0], to: [2, 0, 0], phase: Started": {
                "kind": "Update", "db": 0x20, "version_from": (0, 1, 0), "version_to": (2, 0, 0),
                "phase": "Started", "at_us": 2000000},
            "Update(UpdateRec { db: 32, from: [0, 1, 0], to: [2, 0, 0], phase: Failed": {
                "kind": "Update", "db": 0x20, "version_from": (0, 1, 0), "version_to": (2, 0, 0),
                "phase": "Failed", "failure": "RolledBack",
                "at_us": 17000000},
        }
        self.assertEqual(len([w for w, _, _ in doc_rows() if w == "ToHost"]), len(want))
        for prefix, message in want.items():
            data = row("ToHost", prefix)
            self.assertEqual(data[-1], 0)
            self.assertEqual(x10link.decode(x10link.unframe(data[:-1])), message, prefix)

    def test_a_damaged_frame_is_refused(self):
        data = bytearray(row("ToHost", "Refused")[:-1])
        data[2] ^= 0x01
        with self.assertRaises(ValueError):
            x10link.unframe(bytes(data))


class FakePort:
    """Keeps what is written; reads the answers given, one packet at a time."""

    def __init__(self, answers):
        self.written, self.answers = bytearray(), list(answers)

    def write(self, data):
        self.written += data

    def read(self, n):
        return self.answers.pop(0) if self.answers else b""


class RobotOverAPort(unittest.TestCase):
    def test_lists_the_boards_and_calls_an_operation(self):
        boards = row("ToHost", "Boards")
        reply = row("ToHost", "Reply")
        call = row("ToHost", "Call(CallRec { db: 0")
        # A record first, the boards' answer cut in two packets, then the reply.
        port = FakePort([call + boards[:3], boards[3:], reply])
        robot = x10link.Robot(port)
        robot._next = 9
        self.assertEqual(robot.boards(), [0, 9])
        self.assertEqual(robot.records[0]["kind"], "Call")
        robot._next = 7
        self.assertEqual(robot.call(0, 0x12, 0x01), bytes([2, 0]))
        self.assertEqual(bytes(port.written), x10link.hello() + x10link.list_boards(9)
                         + row("ToDevice", "Call"))

    def test_lists_plug_and_plays_boards_assigns_and_starts_an_update(self):
        port = FakePort([row("ToHost", "BoardList"), row("ToHost", "Assigned { id: 12"),
                         row("ToHost", "Update(UpdateRec { db: 32, from: [0, 1, 0], to: [2, 0, 0], phase: Started")
                         + row("ToHost", "UpdateAnswer { id: 14")])
        robot = x10link.Robot(port)
        robot._next = 11
        found = robot.board_list()
        self.assertEqual([(b["address"], b["state"]) for b in found], [(0x20, "Present"), (0x31, "Lost")])
        self.assertEqual(robot.assign(UID, 0x40)["status"], "Done")
        robot._next = 14
        self.assertEqual(robot.start_update(UID)["boards"], 1)
        self.assertEqual(robot.records[-1]["phase"], "Started")
        self.assertEqual(bytes(port.written), x10link.hello() + row("ToDevice", "Boards")
                         + row("ToDevice", "Assign") + row("ToDevice", "Update { id: 14"))

    def test_an_older_motherboard_refuses(self):
        # A version-1 motherboard does not decode the request: `Refused { id: 0 }`.
        refused = x10link.frame(b"\x09\x00")
        robot = x10link.Robot(FakePort([refused]))
        with self.assertRaises(RuntimeError):
            robot.board_list()

    def test_no_answer_is_a_timeout(self):
        robot = x10link.Robot(FakePort([]), timeout_reads=3)
        with self.assertRaises(TimeoutError):
            robot.counters()


if __name__ == "__main__":
    unittest.main()
