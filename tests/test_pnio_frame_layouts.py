"""PROFINET frame layouts: the IO controller, not the device, places every
IO data object (data, then its IOPS) and every IOCS in the C-SDU (the IOCR
block's frame offsets), and controllers differ. SP-14-023 section 5.3 fixes
the order of the modules (the slots), not the order of the objects in the
frame.

The oracle is not the inference: it is the decode of the same traffic
with its Connect, whose IOCR blocks carry the offsets (the Connect path is
checked first against the frames the test library lays out). Without the
Connect, with -2, every cyclic frame must read exactly as with it, and the
layout-table entry the inference offers must pin the same layout.

- the public captures' layouts: PC WORX RT Basic (pnio_connect_many.pcapng
  frame 1: the IOCS first, then the IO data objects) and slot order
  (pnio_connect_and_cyclic.pcap frame 1: objects and IOCS interleaved in
  slot order), and one with the IOCS first in the uplink and last in the
  downlink (data objects first): a duplex base, a simplex base and an
  EC-Link BU with 0, 20 and 224 output bytes;
- any order (hypothesis): any §5.3 configuration, EC-Link 0/20/224, DAP
  1..8, any order of the objects and IOCS in each direction, the downlink
  data modules holding binary data or text-like bytes. The test data never
  hold 0x80 (a data byte holding 0x80 where another layout has its IOPS:
  test_pnio_midsession.py). Nothing in the frames tells two modules of one
  size apart, nor always a data module holding text from an ASCII module:
  whichever the inference takes, every data field holds the frame's bytes
  at the offsets the Connect gives, in frame order (issue 54 item 1).
"""
import random

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from scapy.utils import rdpcap

from pnio_testlib import DATA_MODULES, CaptureFile, Device, data_first, eclink_submodules, iocs_first, \
    largest_first, mac, mcmb2_submodules
from test_pnio_midsession import ECLINK_FIELDS, MCMB2_FIELDS, _slots, _spread, eclink_traffic, mcmb2_traffic

ENTRY_FIELD = {"mcmb2": "mcmb2.layout_entry", "eclink": "eclink_pnio.layout_entry"}


def up_iocs_first_down_data_first(direction, elements):
    """The IOCS first in the uplink; the data objects first, the IOCS last, in the downlink."""
    return iocs_first(direction, elements) if direction == "in" else data_first(direction, elements)


LAYOUTS = {"slot_order": None, "pcworx": iocs_first, "iocs_first_up_data_first_down": up_iocs_first_down_data_first}


def captures(work_dir, name, make_device, traffic):
    """(with the Connect, without it) of the same traffic."""
    paths = []
    for connect in (True, False):
        d = make_device()
        cap = CaptureFile()
        if connect:
            for p in d.connect():
                cap.add(p)
        traffic(d, cap)
        path = work_dir / ("%s_%s.pcap" % ("with" if connect else "without", name))
        paths.append(cap.write(path))
    return paths


def assert_reads_as_with_connect(tshark, with_connect, without, fields, system):
    """-2 without the Connect reads as -2 with it, frame by frame; the offered
    entry pins the same. Returns the entry."""
    a = tshark.frames(with_connect, fields, two_pass=True)
    b = tshark.frames(without, fields, two_pass=True)
    # every cyclic frame with data of ours (an EC-Link BU without outputs:
    # its uplink) decodes with the Connect
    decoded = [n for n in a if n > 2 and a[n][fields[0]]]
    assert len(decoded) >= (len(a) - 2) // 2
    assert {n: row for n, row in b.items()} == {n - 2: row for n, row in a.items() if n > 2}
    entries = tshark.frames(without, [ENTRY_FIELD[system]], two_pass=True)
    entry = {r[ENTRY_FIELD[system]] for r in entries.values()} - {""}
    assert len(entry) == 1, entry
    entry = entry.pop()
    pinned = tshark.frames(without, fields, prefs={"mcmb2.layouts": entry}, two_pass=True)
    assert pinned == b
    return entry


def test_the_connect_honours_the_frame_offsets(tshark, work_dir):
    """The oracle: with its Connect, a base laid out IOCS first (and data
    first) reads as the same base in slot order."""
    def make(order):
        return lambda: Device(mcmb2_submodules("duplex", 4, 26, 2, 8, 1), mac(5), 0x8001, 0x8002, order=order)
    traffic = lambda d, cap: mcmb2_traffic(d, cap, 100, 26, 2)  # noqa: E731
    ref, _ = captures(work_dir, "oracle_slot", make(None), traffic)
    want = tshark.frames(ref, MCMB2_FIELDS, two_pass=True)
    for name, order in LAYOUTS.items():
        got, _ = captures(work_dir, "oracle_" + name, make(order), traffic)
        assert tshark.frames(got, MCMB2_FIELDS, two_pass=True) == want, name


def _with(make, order):
    def device():
        d = make()
        d.order = order
        return d
    return device


CASES = {
    "duplex": (lambda: Device(mcmb2_submodules("duplex", 4, 26, 2, 8, 1), mac(5), 0x8001, 0x8002),
               lambda d, cap: mcmb2_traffic(d, cap, 300, 26, 2), MCMB2_FIELDS, "mcmb2"),
    "simplex": (lambda: Device(mcmb2_submodules("duplex", 2, 10, 0, 0, 1), mac(6), 0x8003, 0x8004),
                lambda d, cap: mcmb2_traffic(d, cap, 300, 10, 0), MCMB2_FIELDS, "mcmb2"),
    "eclink0": (lambda: Device(eclink_submodules(1, 0), mac(7), 0x8010, 0x8011),
                lambda d, cap: eclink_traffic(d, cap, 300, 0), ECLINK_FIELDS, "eclink"),
    "eclink20": (lambda: Device(eclink_submodules(4, 20), mac(8), 0x8012, 0x8013),
                 lambda d, cap: eclink_traffic(d, cap, 300, 20), ECLINK_FIELDS, "eclink"),
    "eclink224": (lambda: Device(eclink_submodules(3, 224), mac(9), 0x8014, 0x8015),
                  lambda d, cap: eclink_traffic(d, cap, 300, 224), ECLINK_FIELDS, "eclink"),
}
ENTRIES = {
    ("duplex", "slot_order"): "0x8001/0x8002=duplex:26/2,a8@4",
    ("duplex", "pcworx"): "0x8001/0x8002=duplex:26/2,a8@4[4d,3c,h,20,4,2]",
    ("duplex", "iocs_first_up_data_first_down"): "0x8001/0x8002=duplex:26/2,a8@4[4d,3c,h,20,4,2/h,2,a8,4d,4c]",
    ("simplex", "slot_order"): "0x8003/0x8004=simplex:10@2",
    ("simplex", "pcworx"): "0x8003/0x8004=simplex:10@2[2d,c,h,10]",
    ("simplex", "iocs_first_up_data_first_down"): "0x8003/0x8004=simplex:10@2[2d,c,h,10/h,2d,2c]",
    ("eclink0", "slot_order"): "0x8010/-=eclink@1",
    ("eclink0", "pcworx"): "0x8010/-=eclink@1",
    ("eclink0", "iocs_first_up_data_first_down"): "0x8010/-=eclink@1",
    ("eclink20", "slot_order"): "0x8012/0x8013=eclink:/20@4",
    ("eclink20", "pcworx"): "0x8012/0x8013=eclink:/20@4[4d,c,h]",
    ("eclink20", "iocs_first_up_data_first_down"): "0x8012/0x8013=eclink:/20@4[4d,c,h/h,4d,c]",
    ("eclink224", "slot_order"): "0x8014/0x8015=eclink:/224@3",
    ("eclink224", "pcworx"): "0x8014/0x8015=eclink:/224@3[3d,c,h]",
    ("eclink224", "iocs_first_up_data_first_down"): "0x8014/0x8015=eclink:/224@3[3d,c,h/h,3d,c]",
}


@pytest.mark.parametrize("layout", sorted(LAYOUTS))
@pytest.mark.parametrize("case", sorted(CASES))
def test_each_layout_without_its_connect(tshark, work_dir, case, layout):
    make, traffic, fields, system = CASES[case]
    with_connect, without = captures(work_dir, "%s_%s" % (case, layout), _with(make, LAYOUTS[layout]), traffic)
    entry = assert_reads_as_with_connect(tshark, with_connect, without, fields, system)
    # which IOxS byte is a DAP's IOPS and which an IOCS the frames cannot
    # tell: the entry counts the first singles as the DAP's
    assert entry == ENTRIES[case, layout]


# -- any order (hypothesis) ----------------------------------------------------
config = st.one_of(
    st.tuples(st.just("duplex"), st.integers(1, 8), st.integers(1, 40).map(lambda n: 2 * n),
              st.integers(0, 20).map(lambda n: 2 * n), st.integers(0, 20).map(lambda n: 2 * n)),
    st.tuples(st.just("eclink"), st.integers(1, 8), st.sampled_from([0, 20, 224]), st.just(0), st.just(0)))


def module_kinds(cfg, d):
    """{submodule: (direction, size, ascii)} of the data modules (not the headers/images)."""
    system, _, up, data, _ = cfg
    kinds = {}
    if system == "eclink":
        return kinds
    ins, outs = _slots(d, "in")[1:], _slots(d, "out")[1:]
    ndata = len(largest_first(data, DATA_MODULES))
    for s in ins:
        kinds[s] = ("in", s.inlen, False)
    for i, s in enumerate(outs):
        kinds[s] = ("out", s.outlen, i >= ndata)
    return kinds


def order_from(perms, kinds=None):
    """order(direction, elements) for Device: each direction's permutation;
    with kinds (module_kinds()), modules of one size and kind back in slot
    order among themselves."""
    def order(direction, elements):
        out = [elements[i] for i in perms[direction] if i < len(elements)]
        groups = {}
        for pos, e in enumerate(out):
            k = kinds.get(e[1]) if kinds and e[0] == "data" else None
            if k:
                groups.setdefault(k, []).append(pos)
        for positions in groups.values():
            members = sorted((out[p] for p in positions), key=lambda e: (e[1].slot, e[1].subslot))
            for p, e in zip(positions, members):
                out[p] = e
        return out
    return order


TEXT = b"ABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789 "


def random_mcmb2_traffic(d, cap, pairs, up, data, seed, text_data):
    """Data that never look like a header: random bytes (not 0x80), the
    downlink data modules text-like bytes (letters, digits, blanks) when
    text_data; the ASCII modules hold letters; both watchdogs move; base
    unit number 0 (multiple select not configured: a downlink header that
    reads as an uplink status byte, see test_pnio_candidate.py)."""
    rnd = random.Random(seed)
    ins, outs = _slots(d, "in"), _slots(d, "out")
    ascii_ = sum(s.outlen for s in outs[1:]) - data
    byte = lambda: rnd.choice([b for b in range(1, 256) if b != 0x80])  # noqa: E731
    data_byte = (lambda: rnd.choice(TEXT)) if text_data else byte  # noqa: E731
    for i in range(pairs):
        payload = bytes(byte() for _ in range(up))
        cap.add(d.cyclic("in", _spread(ins, "inlen", bytes([0x31, i & 0xFF]) + payload)), 0.002)
        down = bytes(data_byte() for _ in range(data)) + (b"CRANEHOIST" * 64)[:ascii_]
        cap.add(d.cyclic("out", _spread(outs, "outlen", bytes([0, i & 0xFF]) + down)), 0.002)


def assert_data_in_frame_order(tshark, path, d, fields):
    """Every decoded frame's uplink_data / downlink_data: the frame's bytes
    at the offsets of the Connect's IOCR blocks (Device.offsets), the
    modules taken in frame order."""
    got = tshark.frames(path, fields, two_pass=True)
    for n, pkt in enumerate(rdpcap(str(path)), start=1):
        raw = bytes(pkt)
        if len(raw) < 16 or raw[12:14] != b"\x88\x92":
            continue
        fid, c_sdu = int.from_bytes(raw[14:16], "big"), raw[16:]
        direction, field = ("in", "mcmb2.uplink_data") if fid == d.in_fid else ("out", "mcmb2.downlink_data")
        attr = "inlen" if direction == "in" else "outlen"
        objs = [(s, off) for s, off in d.offsets(direction)[0] if s.slot > 0][1:]   # the header's first
        want = b"".join(c_sdu[off:off + getattr(s, attr)] for s, off in sorted(objs, key=lambda p: p[1]))
        assert got[n][field] == want.hex(), (n, field)


@settings(max_examples=12, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(cfg=config, perms=st.fixed_dictionaries({"in": st.permutations(range(80)),
                                                 "out": st.permutations(range(80))}),
       seed=st.integers(0, 2 ** 16), text_data=st.booleans())
def test_any_frame_layout(tshark, work_dir, cfg, perms, seed, text_data):
    system, dap, a, b, c = cfg
    name = "any-%d" % len(list(work_dir.glob("with_any-*")))
    if system == "eclink":
        subs = eclink_submodules(dap, a)
        traffic = lambda d, cap: eclink_traffic(d, cap, 150, a, dt=0.002)  # noqa: E731
        fields = ECLINK_FIELDS
    else:
        subs = mcmb2_submodules("duplex", dap, a, b, c, 1)
        traffic = lambda d, cap: random_mcmb2_traffic(d, cap, 60, a, b, seed, text_data)  # noqa: E731
        fields = MCMB2_FIELDS
    # a permutation of the elements of each direction (at most 80 in these configurations)
    device = lambda: Device(subs, mac(300), 0x8300, 0x8301, order=order_from(perms))  # noqa: E731
    assert len(device().subs) <= 80
    with_connect, without = captures(work_dir, name, device, traffic)
    assert_reads_as_with_connect(tshark, with_connect, without, fields, "eclink" if system == "eclink" else "mcmb2")
    if system != "eclink":
        assert_data_in_frame_order(tshark, with_connect, device(), fields)
