"""Issue 54 item 1: an inferred MC-MB2-PN layout keeps the wire's byte order.

A duplex base (scapy's PROFINET layers, tests/pnio_testlib.py) whose
downlink carries a 10-byte data module holding text-like bytes ("MOTOR
0042"), then a 20-byte ASCII module. The frames fit two readings of
SP-14-023 section 5.3: 10 data + 20 ASCII bytes (the Connect's, the
modules in frame order) or 30 ASCII bytes (20 + 10, the text module taken
for ASCII and moved behind the 20-byte one in the slot order). The frames
cannot tell which module is ASCII; the reading that keeps the frame order
is taken, the tree says so and offers the other, and whichever is pinned
the field holds the frame's bytes in frame order.

The capture is cut as a field capture is, with editcap: the Connect cut by
the snaplen (-s 64, the cyclic frames whole) and a 100-frame excerpt (-r)
without it. Every downlink frame, one pass and two, with and without the C
plugin (tools/test runs this file in both phases).
"""
import re
import shutil
import subprocess

import pytest

from conftest import _world_dir
from pnio_testlib import CaptureFile, Device, mac, mcmb2_submodules
from test_pnio_midsession import _slots, _spread

FIDS = (0x8541, 0x8542)
CONNECT = "0x8541/0x8542=duplex:4/10,a20@2"                # what the Connect says, the modules in frame order
TEXT_AS_ASCII = "0x8541/0x8542=duplex:4/a30@2[/2d,2c,h,a10,a20]"
PAIRS = 500
FIELDS = ["mcmb2.direction", "mcmb2.downlink_data", "mcmb2.uplink_data", "mcmb2.downlink_watchdog",
          "mcmb2.base_unit"]
PASSES = pytest.mark.parametrize("two_pass", [False, True], ids=["one-pass", "two-pass"])


def text(i):
    return b"MOTOR %04d" % (i // 50), b"CRANE HOIST NUMBER 1"


@pytest.fixture(scope="module")
def captures():
    """{name: path}: with the Connect, its Connect cut (-s 64), an excerpt of 100 frames (-r)."""
    work = _world_dir("vrshark-frame-order-")
    d = Device(mcmb2_submodules("duplex", 2, 4, 10, 20, 1), mac(0x54), *FIDS)
    ins, outs = _slots(d, "in"), _slots(d, "out")
    cap = CaptureFile()
    for p in d.connect():
        cap.add(p)
    for i in range(PAIRS):
        cap.add(d.cyclic("in", _spread(ins, "inlen", bytes([0x31, (i // 5) & 0xFF, 1, 2, 3, 4]))), 0.002)
        data, ascii_ = text(i)
        cap.add(d.cyclic("out", _spread(outs, "outlen", bytes([0, (i // 5) & 0xFF]) + data + ascii_)), 0.002)
    paths = {"connect": cap.write(work / "connect.pcap")}
    assert max(len(p) for p in cap.packets[2:]) <= 64 < min(len(p) for p in cap.packets[:2])
    paths["cut"] = work / "cut64.pcap"
    subprocess.run(["editcap", "-s", "64", str(paths["connect"]), str(paths["cut"])], check=True)
    paths["excerpt"] = work / "excerpt.pcap"
    subprocess.run(["editcap", "-r", str(paths["connect"]), str(paths["excerpt"]), "103-202"], check=True)
    for p in paths.values():
        p.chmod(0o644)
    yield paths
    shutil.rmtree(work, ignore_errors=True)


def wire_order(frame_number, shift):
    """The downlink data of a frame as the wire holds it (frame order), by
    the frame number in the capture with the Connect (shift: frames before it)."""
    i = (frame_number + shift - 3) // 2
    return b"".join(text(i)).hex()


def downlinks(tshark, path, two_pass, prefs=None):
    got = tshark.frames(path, FIELDS, two_pass=two_pass, prefs=prefs)
    return {n: r for n, r in got.items() if r["mcmb2.direction"] == "downlink"}


@PASSES
@pytest.mark.parametrize("name,shift", [("cut", 0), ("excerpt", 102)])
def test_every_downlink_field_in_frame_order(tshark, captures, name, shift, two_pass):
    """Every decoded downlink frame's data are its bytes in frame order, as
    with the Connect: with -2 all of them, in one pass those from the frame
    the layout is inferred in."""
    want = downlinks(tshark, captures["connect"], two_pass=True)
    assert len(want) == PAIRS
    got = downlinks(tshark, captures[name], two_pass)
    expected = PAIRS if name == "cut" else 50
    assert len(got) == expected if two_pass else 0 < len(got) < expected
    for n, row in got.items():
        assert row["mcmb2.downlink_data"] == wire_order(n, shift), n
        assert row == want[n + shift], n


@pytest.mark.parametrize("name", ["cut", "excerpt"])
def test_the_layout_taken_keeps_the_order_and_says_what_it_chose(tshark, captures, name):
    """The entry is the Connect's; the tree says which modules it took for
    ASCII, and offers the reading with the text taken for ASCII (in
    mcmb2.candidate_setting, and in the settling note)."""
    got = tshark.frames(captures[name], ["mcmb2.layout_entry", "mcmb2.layout_order", "mcmb2.candidate_setting"],
                        display_filter="mcmb2.system", two_pass=True)
    assert {tuple(r.values()) for r in got.values()} == {(
        CONNECT,
        "which downlink modules are ASCII taken from the frame order (SP-14-023 5.3: data modules first), though "
        "a data module holds text; with the text taken for ASCII (against the frame order) the layout is "
        + TEXT_AS_ASCII,
        "mcmb2.layouts:" + TEXT_AS_ASCII)}
    note = tshark.frames(captures[name], ["_ws.expert.message"], display_filter="mcmb2.layout.inferred")
    [text_] = [r["_ws.expert.message"] for r in note.values()]
    # (an expert text is cut at 240 bytes: the cut Connect's longer note loses the other entry's end)
    pinned, other = re.search(r"; to pin it, add to mcmb2\.layouts: (\S+); or, text as ASCII \(against the frame "
                              r"order\): (\S+)$", text_).groups()
    assert pinned == CONNECT and TEXT_AS_ASCII.startswith(other) and (name == "cut" or other == TEXT_AS_ASCII)


@PASSES
@pytest.mark.parametrize("entry", [CONNECT, TEXT_AS_ASCII])
def test_either_entry_pinned_decodes_as_the_connect(tshark, captures, entry, two_pass):
    """The entry the note offers to pin the layout decodes every frame as
    the Connect does; the other reading, pinned, shows the same bytes (a
    field's bytes are the frame's, in frame order, whichever module is
    taken for ASCII)."""
    want = downlinks(tshark, captures["connect"], two_pass=True)
    got = downlinks(tshark, captures["excerpt"], two_pass, prefs={"mcmb2.layouts": entry})
    assert len(got) == 50
    assert got == {n: want[n + 102] for n in got}
