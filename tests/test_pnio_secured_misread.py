"""Wireshark 4.6 reads a PROFINET RT_CLASS_1 frame (FrameID 0x8000-0xBFFF)
as secured when C-SDU bytes 6-7 hold a length it expects there: the C-SDU
length less 20 (PN-RT) or less 4 (PNIO). Any data byte pair of a device can
hold it (a watchdog counter reaching that value did, in
test_pnio_frame_layouts.py on 4.6). With the Connect in the capture, PNIO
knows the IOCR and runs out of bytes: the frame is malformed to Wireshark.
The Connect's layout fits the frame all the same: it is decoded, with a
note saying why both are there (mcmb2.pn_malformed, eclink_pnio.pn_malformed).
Earlier versions read these frames as usual: no exception, no note.

The oracle is not the Connect path: the same frames without the Connect,
laid out by the layout table (PNIO then knows no IOCR and raises nothing),
must decode to the same fields. One pass and two agree; never a Lua error.
"""
import re

import pytest

from pnio_testlib import CaptureFile, Device, eclink_submodules, mac, mcmb2_submodules
from test_pnio_midsession import ECLINK_FIELDS, MCMB2_FIELDS, _slots, _spread, eclink_image_in, \
    eclink_image_out

PAIRS = 8
# (pair, direction, what C-SDU bytes 6-7 hold: the C-SDU length less this)
MISREAD = [(2, "in", 20), (4, "out", 4), (6, "out", 20), (7, "in", 4)]
WHO = {20: "PN-RT", 4: "PNIO"}


def data_bytes(d, direction):
    """{C-SDU offset: (slot, index in its data)} of the data bytes of one
    direction, and the C-SDU length (the frames are padded to 40)."""
    where, off = {}, 0
    for kind, s in d._elements(direction):
        n = d._length(s, direction)
        if kind == "data":
            for i in range(n):
                where[off + i] = (s.slot, i)
            off += n
        off += 1
    return where, max(off, 40)


def misread(d, direction, data, less):
    """data ({slot: bytes}) with C-SDU bytes 6-7 set to the C-SDU length less `less`."""
    where, size = data_bytes(d, direction)
    assert 6 in where and 7 in where, "C-SDU bytes 6-7 are no data bytes in this layout"
    out = {k: bytearray(v) for k, v in data.items()}
    for k, b in enumerate((size - less).to_bytes(2, "big")):
        slot, i = where[6 + k]
        out[slot][i] = b
    return {k: bytes(v) for k, v in out.items()}, (size - less, less, size)


def mcmb2_data(d, i, direction):
    if direction == "in":
        return _spread(_slots(d, "in"), "inlen", bytes([0x31, i]) + bytes(k + 1 for k in range(32)))
    return _spread(_slots(d, "out"), "outlen", bytes([0, i]) + bytes(range(9, 29)) + b"HOIST SLOW 2")


def eclink_data(d, i, direction):
    return {1: eclink_image_in(i // 2)} if direction == "in" else {2: eclink_image_out(i // 2, length=20)}


SYSTEMS = {
    # system: (submodules, FrameIDs, frame data, fields, layout-table entry, expert namespace)
    # (44-byte C-SDUs in both directions: no padding, so PNIO runs out of bytes on either misreading)
    "mcmb2": (lambda: mcmb2_submodules("duplex", 2, 32, 20, 12, 1), (0x8300, 0x8301), mcmb2_data,
              MCMB2_FIELDS, "0x8300/0x8301=duplex:32/20,a12@2", "mcmb2"),
    "eclink": (lambda: eclink_submodules(1, 20), (0x8310, 0x8311), eclink_data, ECLINK_FIELDS,
               "0x8310/0x8311=eclink:64/20@1", "eclink_pnio"),
}


def capture(work_dir, system, connect):
    """The Connect (if asked) and PAIRS pairs of uplink + downlink frames;
    returns the path and {frame number: (the value in C-SDU bytes 6-7, the
    length less it, the C-SDU length)} of the frames Wireshark 4.6 misreads."""
    subs, (fin, fout), data, _, _, _ = SYSTEMS[system]
    d = Device(subs(), mac(310), fin, fout)
    cap, values, n = CaptureFile(), {}, 0
    if connect:
        for p in d.connect():
            cap.add(p)
            n += 1
    for i in range(PAIRS):
        for direction in ("in", "out"):
            frame = data(d, i, direction)
            for pair, where, less in MISREAD:
                if (pair, where) == (i, direction):
                    frame, values[n + 1] = misread(d, direction, frame, less)
            cap.add(d.cyclic(direction, frame), 0.002)
            n += 1
    return cap.write(work_dir / ("misread-%s-%s.pcap" % (system, "connect" if connect else "table"))), values


def version(tshark):
    return tuple(int(x) for x in re.search(r"(\d+)\.(\d+)", tshark.run(["-v"]).stdout).groups())


@pytest.mark.parametrize("system", sorted(SYSTEMS))
def test_a_frame_wireshark_reads_as_secured_is_decoded_by_the_connect_layout_and_said(tshark, work_dir, system):
    _, _, _, fields, entry, ns = SYSTEMS[system]
    with_connect, values = capture(work_dir, system, True)
    table, _ = capture(work_dir, system, False)
    secured = version(tshark) >= (4, 6)
    for two_pass in (False, True):
        oracle = tshark.frames(table, fields, prefs={"mcmb2.layouts": entry}, two_pass=two_pass)
        got = tshark.frames(with_connect, fields + ["_ws.malformed"], two_pass=two_pass)
        experts = tshark.experts(with_connect, two_pass=two_pass)
        assert len(got) == 2 + 2 * PAIRS
        malformed = sorted(n for n, row in got.items() if row["_ws.malformed"] != "")
        # 4.6 throws on the misread frames whose IOCR reaches past the bytes
        # it leaves to PNIO (here at least one a system); earlier versions never
        assert set(malformed) <= set(values) and (bool(malformed) if secured else malformed == []), malformed
        for n in range(3, 3 + 2 * PAIRS):
            row = got[n]
            assert {f: row[f] for f in fields} == oracle[n - 2], n
            assert row[fields[0]] != "", n   # decoded
            notes = [m for m in experts.get(n, []) if m.startswith("Malformed to Wireshark")]
            if n in malformed:
                value, less, size = values[n]
                assert notes == [
                    "Malformed to Wireshark's %s (C-SDU bytes 6-7, %d, read as a SecurityLength), but the layout "
                    "(Connect in frame 1) fits its %d-byte C-SDU: decoded" % (WHO[less], value, size)], n
            else:
                assert notes == [], n
        # the note is one of ours: filterable by its name
        named = tshark.field(with_connect, "frame.number", display_filter=ns + ".pn_malformed", two_pass=two_pass)
        assert named == [str(n) for n in malformed]
    assert "Lua Error" not in tshark.verbose(with_connect, two_pass=True)
