"""A polled MC-MB2-PN base without its Connect, whatever frame layout the
IO controller assigned: the controller, not the device, places every IO
data object (data, then its IOPS) and every IOCS in the C-SDU (the IOCR
block's frame offsets). PC WORX RT Basic puts the IOCS first; others put
the data objects first and the IOCS last, or interleave them in slot order.

The oracle is the decode of the same traffic with its Connect, whose IOCR
blocks carry the offsets (test_pnio_frame_layouts.py checks the Connect
path against the frames the test library lays out): without the Connect,
with -2, every cyclic frame reads exactly as with it. Modules of one size
keep their slot order among themselves (nothing in the frames tells two of
them apart), and the test data never hold 0x80.
"""
import random

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from pnio_testlib import Device, mac, mcmb2_submodules
from test_pnio_frame_layouts import LAYOUTS, captures
from test_pnio_midsession import _slots, _spread

FIELDS = ["mcmb2.system", "mcmb2.direction", "mcmb2.status", "mcmb2.uplink_watchdog", "mcmb2.uplink_size",
          "mcmb2.downlink_size", "mcmb2.downlink_watchdog", "mcmb2.slot", "mcmb2.slot.status", "mcmb2.slot.terminal",
          "mcmb2.slot.uplink_data", "mcmb2.slot.downlink_data", "_ws.col.Info", "_ws.expert.message"]


def polled_traffic(d, cap, pairs, up, data, ascii_, terminals, seed=0):
    """pairs cycles of a polled uplink (status 0x0F, slots 1..terminals
    present) and its downlink (data, then ASCII text), both watchdogs
    moving; no byte is 0x80."""
    rnd = random.Random(seed)
    ins, outs = _slots(d, "in"), _slots(d, "out")
    byte = lambda: rnd.choice([b for b in range(1, 256) if b != 0x80])  # noqa: E731
    slots = [0x10 * (k + 1) + 1 for k in range(terminals)] + [0x0F] * (4 - terminals)
    for i in range(pairs):
        header = bytes([0x0F, (i + 1) & 0xFF, up, data + ascii_] + slots)
        payload = b"".join(bytes(byte() for _ in range(up)) for _ in range(terminals))
        cap.add(d.cyclic("in", _spread(ins, "inlen", header + payload)), 0.002)
        down = b"".join(bytes(byte() for _ in range(data)) + (b"HOIST%02d " % k * 64)[:ascii_]
                        for k in range(terminals))
        cap.add(d.cyclic("out", _spread(outs, "outlen", bytes([0, (i + 1) & 0xFF]) + down)), 0.002)


def assert_reads_as_with_connect(tshark, with_connect, without):
    a = tshark.frames(with_connect, FIELDS, two_pass=True)
    b = tshark.frames(without, FIELDS, two_pass=True)
    # every cyclic frame decodes with the Connect
    assert all(row["mcmb2.system"] == "polled" for n, row in a.items() if n > 2)
    assert sorted(b) == [n - 2 for n in sorted(a) if n > 2]
    for n in b:
        assert b[n] == a[n + 2], "frame %d" % n


# (dap, Y, downlink data bytes, downlink ASCII bytes, terminals)
CASES = {"ascii": (4, 6, 2, 8, 2), "three": (1, 26, 4, 0, 3), "dap8": (8, 8, 10, 20, 1)}


@pytest.mark.parametrize("layout", sorted(LAYOUTS))
@pytest.mark.parametrize("case", sorted(CASES))
def test_polled_layout_without_its_connect(tshark, work_dir, case, layout):
    dap, up, data, ascii_, n = CASES[case]
    subs = mcmb2_submodules("polled", dap, up, data, ascii_, n)
    with_connect, without = captures(
        work_dir, "polled_%s_%s" % (case, layout),
        lambda: Device(subs, mac(40), 0x8001, 0x8002, order=LAYOUTS[layout]),
        lambda d, cap: polled_traffic(d, cap, 12, up, data, ascii_, n))
    assert_reads_as_with_connect(tshark, with_connect, without)
    # laid out by the header, in both directions, in one pass as well
    got = tshark.frames(without, ["mcmb2.layout", "mcmb2.direction"])
    assert got[1] == {"mcmb2.layout": "polled header in frame 1", "mcmb2.direction": "uplink"}
    assert got[2] == {"mcmb2.layout": "polled header in frame 1", "mcmb2.direction": "downlink"}


polled_config = st.tuples(st.integers(1, 8), st.integers(1, 4), st.integers(1, 15).map(lambda n: 2 * n),
                          st.integers(0, 10).map(lambda n: 2 * n), st.integers(0, 10).map(lambda n: 2 * n))


def singles_anywhere(perms):
    """order(direction, elements) for Device: the DAP's IOPS/IOCS and the
    IOCS anywhere (each direction's permutation), the IO data objects in
    slot order among themselves. Modules in another order can cut a frame
    as another split of Z would (2 + 8 ASCII read as 8 + 2 ASCII): nothing
    in the frame tells them apart, and slot order is taken."""
    def order(direction, elements):
        out = [elements[i] for i in perms[direction] if i < len(elements)]
        positions = [p for p, e in enumerate(out) if e[0] == "data" and e[1].slot > 0]
        members = sorted((out[p] for p in positions), key=lambda e: (e[1].slot, e[1].subslot))
        for p, e in zip(positions, members):
            out[p] = e
        return out
    return order


@settings(max_examples=10, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(cfg=polled_config, perms=st.fixed_dictionaries({"in": st.permutations(range(60)),
                                                        "out": st.permutations(range(60))}),
       seed=st.integers(0, 2 ** 16))
def test_any_polled_frame_layout(tshark, work_dir, cfg, perms, seed):
    """Any place for the DAP IOPS/IOCS and the IOCS in each direction, any
    DAP count, terminals, Y and split of Z."""
    dap, n, up, data, ascii_ = cfg
    subs = mcmb2_submodules("polled", dap, up, data, ascii_, n)
    assert len(subs) <= 60
    name = "polled-any-%d" % len(list(work_dir.glob("with_polled-any-*")))
    with_connect, without = captures(work_dir, name,
                                     lambda: Device(subs, mac(41), 0x8001, 0x8002, order=singles_anywhere(perms)),
                                     lambda d, cap: polled_traffic(d, cap, 6, up, data, ascii_, n, seed))
    assert_reads_as_with_connect(tshark, with_connect, without)


def test_layout_table_polled_entry_with_frame_order(tshark, work_dir):
    """A polled entry with its sizes takes a frame order (here PC WORX: the
    IOCS first in both directions) and then reads as with the Connect, the
    polled header recognition off; without the order the frames do not fit."""
    dap, up, data, ascii_, n = CASES["ascii"]
    subs = mcmb2_submodules("polled", dap, up, data, ascii_, n)
    with_connect, without = captures(work_dir, "polled_table_pcworx",
                                     lambda: Device(subs, mac(42), 0x8001, 0x8002, order=LAYOUTS["pcworx"]),
                                     lambda d, cap: polled_traffic(d, cap, 6, up, data, ascii_, n))
    a = tshark.frames(with_connect, FIELDS, two_pass=True)
    entry = "0x8001/0x8002=polled:2x6/2x2,a8@4"
    prefs = {"mcmb2.layouts": entry + "[5c,4d,h,4,2,4,2/4d,5c,h,2,a8,2,a8]", "mcmb2.heuristic": "FALSE"}
    b = tshark.frames(without, FIELDS, prefs=prefs)
    for num in b:
        assert b[num] == a[num + 2], "frame %d" % num
    got = tshark.frames(without, ["mcmb2.layout", "mcmb2.slot.uplink_data"],
                        prefs={"mcmb2.layouts": entry, "mcmb2.heuristic": "FALSE"})
    assert got[1]["mcmb2.slot.uplink_data"] != a[3]["mcmb2.slot.uplink_data"]


def test_a_downlink_of_its_header_only_with_the_iocs_first(tshark, work_dir):
    """DAP 1, one terminal, Y=2, Z=0: the uplink carries one IOCS (of the
    downlink header), put right after the DAP IOPS. In the usual order it
    would read as a second DAP IOPS with a zero IOCS from the padding; the
    reading whose IOCS all fit wins (found by test_any_polled_frame_layout)."""
    perms = {"in": [0, 3, 2, 1] + list(range(4, 60)), "out": list(range(60))}
    subs = mcmb2_submodules("polled", 1, 2, 0, 0, 1)
    with_connect, without = captures(work_dir, "polled_header_only",
                                     lambda: Device(subs, mac(43), 0x8001, 0x8002, order=singles_anywhere(perms)),
                                     lambda d, cap: polled_traffic(d, cap, 6, 2, 0, 0, 1))
    assert_reads_as_with_connect(tshark, with_connect, without)


def test_iocs_among_the_dap_iops_with_ascii_only(tshark, work_dir):
    """DAP 2, one terminal, Y=2, no downlink data, 4 ASCII bytes; the
    uplink's first IOCS placed between the DAP's IOPS (found by
    test_any_polled_frame_layout on Wireshark 4.6, Lua only)."""
    perms = {"in": [0, 2, 3, 1] + list(range(4, 60)), "out": list(range(60))}
    subs = mcmb2_submodules("polled", 2, 2, 0, 4, 1)
    with_connect, without = captures(work_dir, "polled_iocs_among_dap",
                                     lambda: Device(subs, mac(44), 0x8001, 0x8002, order=singles_anywhere(perms)),
                                     lambda d, cap: polled_traffic(d, cap, 6, 2, 0, 4, 1, 0))
    assert_reads_as_with_connect(tshark, with_connect, without)


class _Garbled:
    """Adds the frames of `cap`, each downlink's last C-SDU byte set to 0x01
    (no IOxS, no padding): no downlink layout fits."""
    def __init__(self, cap, ctl_mac):
        self.cap, self.ctl_mac = cap, ctl_mac

    def add(self, pkt, *args):
        if pkt.src == self.ctl_mac:
            raw = bytearray(bytes(pkt))
            raw[-5] = 0x01
            pkt = type(pkt)(bytes(raw))
        self.cap.add(pkt, *args)


def test_a_downlink_no_layout_fits_is_said(tshark, work_dir):
    """The uplink's polled header is decoded; the downlink frames from its
    controller fit none of the layouts the header allows: each says so and
    names the setting, in one pass and with -2, also after the recognition
    has given up (70 pairs, more than it tries)."""
    dap, up, data, ascii_, n = CASES["ascii"]
    subs = mcmb2_submodules("polled", dap, up, data, ascii_, n)
    _, without = captures(work_dir, "polled_garbled",
                          lambda: Device(subs, mac(45), 0x8001, 0x8002),
                          lambda d, cap: polled_traffic(d, _Garbled(cap, d.ctl_mac), 70, up, data, ascii_, n))
    text = ("From the IO controller to the MC-MB2-PN polled base laid out by the polled header in frame 1, but no "
            "downlink layout its header allows (Y=6, Z=10, 2 slot(s) used) fits this frame; to decode it: its "
            "layout in mcmb2.layouts")
    fields = ["mcmb2.direction", "mcmb2.layout", "mcmb2.candidate_setting", "_ws.expert.message"]
    for two_pass in (False, True):
        got = tshark.frames(without, fields, two_pass=two_pass)
        assert len(got) == 140
        for num in (2, 64, 128, 140):
            assert got[num] == {"mcmb2.direction": "", "mcmb2.layout": "", "mcmb2.candidate_setting": "mcmb2.layouts",
                                "_ws.expert.message": text}, (two_pass, num)
        assert got[139]["mcmb2.direction"] == "uplink"
        assert got[139]["mcmb2.layout"] == "polled header in frame 1"


def test_downlink_data_holding_bad_iocs_values(tshark, work_dir):
    """DAP 1, two terminals, Y=24, 14 data + 18 ASCII bytes, the downlink's
    IOCS and DAP IOCS scattered among the modules, and a terminal's data
    starting 0x40 0x40 (a valid IOCS value, Bad by IO device): a cut that
    reads those two bytes as IOCS and two GOOD IOCS as data is found first;
    the cut whose IOxS are all GOOD wins (found by
    test_any_polled_frame_layout on Wireshark 4.4, Lua only)."""
    out = [16, 15, 2, 3, 4, 5, 6, 7, 21, 9, 10, 17, 11, 20, 18, 19, 0, 1, 14, 12, 13, 8] + list(range(22, 60))
    perms = {"in": list(range(60)), "out": out}
    subs = mcmb2_submodules("polled", 1, 24, 14, 18, 2)
    with_connect, without = captures(work_dir, "polled_bad_iocs_values",
                                     lambda: Device(subs, mac(46), 0x8001, 0x8002, order=singles_anywhere(perms)),
                                     lambda d, cap: polled_traffic(d, cap, 6, 24, 14, 18, 2, 62316))
    assert_reads_as_with_connect(tshark, with_connect, without)
