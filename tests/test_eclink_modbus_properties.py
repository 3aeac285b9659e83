"""Property tests of the EC-Link over Modbus/TCP detection (hypothesis).

Every valid input image and link-status combination is recognized within
the first second of a BU's traffic; thousands of ordinary devices (zeros,
counters, random registers, 0/1 flags, values inside the image's ranges,
read at registers 0..31 or wherever a BU's image would be) never are.

Each example is a list of many connections in one capture, checked with one
tshark run, so that thousands of devices cost a few runs.
"""
import random
import struct

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from modbus_testlib import Traffic, bu_connection, read_input
from tools.capgen import eclink_modbus as mbgen

SETTINGS = dict(deadline=None, derandomize=True, database=None,
                suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large,
                                       HealthCheck.function_scoped_fixture])
_runs = iter(range(10 ** 6))  # a new file name per example (tshark's results are cached by arguments)

S16 = st.integers(-32768, 32767)
JOY = st.integers(-1000, 1000)


@st.composite
def image_fields(draw, ec=st.integers(1, 6)):
    """Arguments of mbgen.input_image (but PCI) for any valid input image."""
    f = dict(cci=draw(st.integers(0, 255)), pai=draw(st.integers(0, 255)), cai=draw(st.integers(0, 255)),
             cmd=draw(st.binary(min_size=16, max_size=16)),
             bu_state=draw(st.sampled_from([0x00, 0x01, 0x02, 0x03, 0x04, 0x10, 0x11])),
             vlaps=draw(st.integers(0, 3)), unarmed=draw(st.integers(0, 255)),
             eg=draw(st.integers(0, 6)), ec=draw(ec), cl=draw(st.integers(0, 6)))
    if draw(st.booleans()):
        f.update(armed_ru=draw(st.integers(1, 0xFFFF)), ru_state=draw(st.integers(0, 4)),
                 battery=draw(st.integers(0, 100)), rssi=draw(st.integers(0, 100)),
                 cable=draw(st.integers(0, 1)), docked=draw(st.integers(0, 1)), disabled=draw(st.integers(0, 3)),
                 joy=tuple(draw(st.lists(JOY, min_size=4, max_size=4))),
                 sw=tuple(draw(st.lists(S16, min_size=8, max_size=8))),
                 enc=draw(st.integers(0, 255)), encsw=draw(st.integers(0, 1)))
    else:
        f.update(armed_ru=0, ru_state=0, battery=0, rssi=0, cable=0, docked=0, disabled=0)
    return f


@st.composite
def bu_behaviour(draw):
    """A BU and its controller: any valid image, poll 10..300 ms, any of the
    three ways to read the input image, with or without output writes, the
    BU's clock within 2 % of 125 ms, PCI starting anywhere (wraps)."""
    poll = draw(st.floats(0.01, 0.3))
    return dict(fields=draw(image_fields()), poll=poll, polls=int(1.2 / poll) + 2,
                fc=draw(st.sampled_from([4, 3, 2])), write=draw(st.booleans()),
                phase=draw(st.floats(0, 0.124)), pci0=draw(st.integers(0, 255)),
                period=draw(st.floats(0.1225, 0.1275)))


def _accepted(tshark, cap):
    """{tcp.stream: first frame with eclink_modbus.accepted_in}."""
    rows = tshark.fields(cap, ["tcp.stream", "eclink_modbus.accepted_in"], display_filter="eclink_modbus.accepted_in")
    out = {}
    for stream, acc in rows:
        out.setdefault(int(stream), int(acc.split(",")[0]))
    return out


@settings(max_examples=6, **SETTINGS)
@given(bus=st.lists(bu_behaviour(), min_size=40, max_size=40))
def test_every_valid_bu_is_recognized_within_a_second(tshark, work_dir, bus):
    traffic = Traffic()
    deadline = {}
    for b in bus:
        stream, reads = bu_connection(traffic, **b)
        t0 = reads[0][1]
        # the last frame of the first second: the read response (and its write) at t0 + 1.0 s at the latest
        deadline[stream] = max(frame for frame, t, _ in reads if t <= t0 + 1.0) + (2 if b["write"] else 0)
    cap = traffic.write(work_dir, "bus-%d.pcap" % next(_runs))
    got = _accepted(tshark, cap)
    late = {s: (got.get(s), deadline[s], bus[s]) for s in deadline if not got.get(s) or got[s] > deadline[s]}
    assert not late


def test_every_link_status_combination(tshark, work_dir):
    """EG-Link 0..6 x EC-Link 1..6 x C-Link 0..6 (294 BUs), read only every
    125 ms: each recognized by its third image."""
    traffic = Traffic()
    third = {}
    for eg in range(7):
        for ec in range(1, 7):
            for cl in range(7):
                stream, reads = bu_connection(traffic, dict(eg=eg, ec=ec, cl=cl), polls=4, poll=0.125, phase=0.01)
                third[stream] = reads[2][0]
    cap = traffic.write(work_dir, "links.pcap")
    assert _accepted(tshark, cap) == third


# --- ordinary devices ------------------------------------------------------------

KINDS = ["zeros", "counters", "clock", "random", "random_static", "flags", "flags_static",
         "in_range_static", "in_range_changing"]


def _flags(rnd):
    return b"".join(struct.pack(">H", rnd.randrange(2)) for _ in range(32))


@st.composite
def ordinary_device(draw):
    """An ordinary Modbus server polled where a BU's input image would be:
    its 32 registers (or 512 bits) per poll, and what its client writes."""
    kind = draw(st.sampled_from(KINDS))
    seed = draw(st.integers(0, 2 ** 32 - 1))
    poll = draw(st.floats(0.03, 0.3))
    d = dict(kind=kind, seed=seed, poll=poll, polls=int(1.2 / poll) + 2, fc=draw(st.sampled_from([4, 3, 2])),
             tick=draw(st.sampled_from([0.1, 0.125, 0.25, 1.0])), fields=None, writes=None)
    if kind.startswith("in_range"):
        d["fields"] = draw(image_fields(ec=st.integers(0, 6)))
    if draw(st.booleans()):
        start = draw(st.integers(0, 200))
        count = draw(st.integers(1, 123))
        if start == 0 and count in (10, 112):
            count += 1  # writing the whole output image is a controller's evidence
        d["writes"] = (start, count)
    return d


def _registers(d, i, rnd, static):
    """The 64 bytes of the device's registers 0..31 (as on the wire) at poll i."""
    kind = d["kind"]
    if kind == "zeros":
        return bytes(64)
    if kind == "counters":      # every register counts up by its own step with every poll
        return b"".join(struct.pack(">H", (static[k] + i * (k + 1)) & 0xFFFF) for k in range(32))
    if kind == "clock":         # registers 0..7 count time ticks, the rest 0
        n = int(i * d["poll"] / d["tick"])
        return b"".join(struct.pack(">H", (static[k] + n) & 0xFFFF) for k in range(8)) + bytes(48)
    if kind == "random":
        return bytes(rnd.randrange(256) for _ in range(64))
    if kind == "flags":
        return _flags(rnd)
    if kind in ("random_static", "flags_static"):
        return static
    fields = dict(d["fields"])
    if kind == "in_range_changing":
        fields.update(bu_state=rnd.choice([0, 1, 2, 3, 4, 0x10, 0x11]), vlaps=rnd.randrange(4),
                      eg=rnd.randrange(7), ec=rnd.randrange(7), cl=rnd.randrange(7))
    return mbgen.regs(mbgen.input_image(pci=rnd.randrange(256), **fields))


def ordinary_connection(traffic, d):
    rnd = random.Random(d["seed"])
    mb, stream = traffic.client()
    static = None
    if d["kind"] in ("counters", "clock"):
        static = [rnd.randrange(65536) for _ in range(32)]
    elif d["kind"] == "random_static":
        static = bytes(rnd.randrange(256) for _ in range(64))
    elif d["kind"] == "flags_static":
        static = _flags(rnd)
    t = traffic.t + 0.01
    for i in range(d["polls"]):
        t = traffic.t + 0.01 + i * d["poll"]
        regs = _registers(d, i, rnd, static)
        # read_input swaps byte pairs back into image order: hand it the image that gives these registers
        read_input(mb, t, d["fc"], mbgen.regs(regs))
        if d["writes"]:
            start, count = d["writes"]
            mb.write_regs(t + 0.004, start, bytes(rnd.randrange(256) for _ in range(2 * count)))
    traffic.done(t + 0.01)
    return stream


@settings(max_examples=12, **SETTINGS)
@given(devices=st.lists(ordinary_device(), min_size=170, max_size=170))
def test_ordinary_devices_are_never_recognized(tshark, work_dir, devices):
    traffic = Traffic()
    for d in devices:
        ordinary_connection(traffic, d)
    cap = traffic.write(work_dir, "ordinary-%d.pcap" % next(_runs))
    got = _accepted(tshark, cap)
    assert not {s: devices[s] for s in got}


# --- the hint: a BU's shape, not recognised ---------------------------------------

def _candidates(tshark, cap):
    """{tcp.stream: {frame: candidate setting}} of every frame with the note (one pass)."""
    rows = tshark.fields(cap, ["tcp.stream", "frame.number", "eclink_modbus.candidate_setting"],
                         display_filter="eclink_modbus.candidate")
    out = {}
    for stream, frame, setting in rows:
        out.setdefault(int(stream), {})[int(frame)] = setting
    return out


@settings(max_examples=4, **SETTINGS)
@given(excerpts=st.lists(st.tuples(image_fields(), st.integers(2, 254), st.sampled_from([4, 3, 2])),
                         min_size=60, max_size=60))
def test_every_valid_image_and_write_of_an_excerpt_gets_the_hint(tshark, work_dir, excerpts):
    """An excerpt of any valid BU: two input images (PCI n, n + 1) read 125 ms
    apart, one valid output write between them: too short to be recognized,
    each of the three carries the note with its server's setting."""
    traffic = Traffic()
    expected = {}
    for fields, pci, fc in excerpts:
        mb, stream = traffic.client()
        t = traffic.t + 0.01
        _, first = read_input(mb, t, fc, mbgen.input_image(pci=pci, **fields))
        write, _ = mb.write_regs(t + 0.01, 0, mbgen.regs(mbgen.output_image(pco=pci, cao=fields["cci"])))
        _, second = read_input(mb, t + 0.125, fc, mbgen.input_image(pci=pci + 1, **fields))
        traffic.done(t + 0.13)
        server = mb.conn.s[0]
        expected[stream] = {f: "eclink_modbus.servers:" + server for f in (first, write, second)}
    cap = traffic.write(work_dir, "excerpts-%d.pcap" % next(_runs))
    assert _candidates(tshark, cap) == expected


PLAIN_KINDS = ["zeros", "counters", "clock", "random", "random_static", "flags", "flags_static"]


@st.composite
def plain_device(draw):
    """An ordinary device (0/1 flags, counters, ...) polled exactly like a BU:
    the whole input image read, then 112 counting registers written from 0."""
    poll = draw(st.floats(0.03, 0.3))
    return dict(kind=draw(st.sampled_from(PLAIN_KINDS)), seed=draw(st.integers(0, 2 ** 32 - 1)), poll=poll,
                polls=draw(st.integers(1, 12)), fc=draw(st.sampled_from([4, 3, 2])),
                tick=draw(st.sampled_from([0.1, 0.125, 0.25, 1.0])), fields=None, writes=None,
                count0=draw(st.integers(0, 180)))


@settings(max_examples=6, **SETTINGS)
@given(devices=st.lists(plain_device(), min_size=120, max_size=120))
def test_ordinary_devices_never_get_the_hint(tshark, work_dir, devices):
    traffic = Traffic()
    for d in devices:
        rnd = random.Random(d["seed"])
        mb, _ = traffic.client()
        static = [rnd.randrange(65536) for _ in range(32)] if d["kind"] in ("counters", "clock") else \
            bytes(rnd.randrange(256) for _ in range(64)) if d["kind"] == "random_static" else \
            _flags(rnd) if d["kind"] == "flags_static" else None
        t = traffic.t + 0.01
        for i in range(d["polls"]):
            t = traffic.t + 0.01 + i * d["poll"]
            read_input(mb, t, d["fc"], mbgen.regs(_registers(d, i, rnd, static)))
            mb.write_regs(t + 0.004, 0, b"".join(struct.pack(">H", (d["count0"] + i + k) & 0xFFFF)
                                                 for k in range(112)))
        traffic.done(t + 0.01)
    cap = traffic.write(work_dir, "plain-%d.pcap" % next(_runs))
    got = _candidates(tshark, cap)
    assert not {s: devices[s] for s in got}
