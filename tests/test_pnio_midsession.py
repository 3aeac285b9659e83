"""PROFINET captured mid-session: the Connect happened hours before the
capture started, so the layout comes from the cyclic frames alone
(lua/vrshark/pnio_infer.luam). The frames are built with scapy's PROFINET
layers (tests/pnio_testlib.py), not tools/capgen, from SP-14-023 section 5.3
and TS-0007; a capture "without the Connect" is the same traffic with the
Connect simply not written.

- An MC-MB2-PN duplex base and an EC-Link BU (20- and 224-byte outputs),
  1,000 cyclic frames each: with -2 every frame decodes as it does with the
  Connect; in one pass from the frame the layout is inferred in; the tree
  says where the layout came from and offers the layout-table entry, which
  pasted into mcmb2.layouts decodes the same.
- Every configuration section 5.3 allows (hypothesis): DAP submodules 1..8,
  uplink Y, downlink data and ASCII bytes, simplex (no downlink data).
- Ordinary PROFINET IO devices (counters, 0/1 inputs, analogue values,
  constant 0x80 bytes): nothing of ours, one pass and two (no candidate
  note either: OURS takes in mcmb2.candidate).

Frame layouts other than slot order: tests/test_pnio_frame_layouts.py.
"""
import math

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from pnio_testlib import CaptureFile, Device, Submodule, dap_submodules, eclink_submodules, mac, \
    mcmb2_submodules

MCMB2_FIELDS = ["mcmb2.system", "mcmb2.direction", "mcmb2.status", "mcmb2.terminal", "mcmb2.uplink_watchdog",
                "mcmb2.uplink_data", "mcmb2.base_unit", "mcmb2.downlink_watchdog", "mcmb2.downlink_data",
                "mcmb2.watchdog_age", "_ws.col.Info"]
ECLINK_FIELDS = ["eclink.image", "eclink.pci", "eclink.cci", "eclink.bu_state", "eclink.joystick1", "eclink.pco",
                 "eclink.cao", "eclink.periodic_size", "eclink_pnio.pci_age", "eclink_pnio.pco_age",
                 "_ws.col.Info"]
OURS = "mcmb2 || eclink || eclink_pnio"


def _slots(d, direction):
    """The data submodules of one direction in slot order (header/image first)."""
    attr = "inlen" if direction == "in" else "outlen"
    return [s for s in sorted(d.subs, key=lambda s: (s.slot, s.subslot)) if s.slot > 0 and getattr(s, attr)]


def _spread(subs, attr, data):
    """{slot: bytes} of data laid over the submodules."""
    out = {}
    for s in subs:
        n = getattr(s, attr)
        out[s.slot], data = data[:n], data[n:]
    return out


def mcmb2_traffic(d, cap, pairs, up, data, text=b"HOIST OK", dt=0.001, wd_up_ms=20, wd_down_ms=100):
    """pairs cycles of uplink + downlink frames, dt apart: the uplink
    watchdog moving every wd_up_ms, the downlink one every wd_down_ms."""
    ins, outs = _slots(d, "in"), _slots(d, "out")
    ascii_ = sum(s.outlen for s in outs[1:]) - data
    for i in range(pairs):
        ms = int(i * 2 * dt * 1000)
        wd_up, wd_down = (ms // wd_up_ms) & 0xFF, (ms // wd_down_ms) & 0xFF
        payload = bytes((((i // 10) * 7 + k) % 31) + 1 for k in range(up))
        cap.add(d.cyclic("in", _spread(ins, "inlen", bytes([0x31, wd_up]) + payload)), dt)
        down = bytes(((i // 50) + k) % 31 + 1 for k in range(data)) + (text * 64)[:ascii_]
        cap.add(d.cyclic("out", _spread(outs, "outlen", bytes([0, wd_down]) + down)), dt)


def eclink_image_in(pci, cci=3, bu=0x11, joy=0):
    img = bytearray(64)
    img[0:4] = bytes([pci & 0xFF, cci, 0, cci])
    img[4:20] = b"FROM-RU-COMMAND!"
    img[20:26] = bytes([bu, 1, 0, 1, 1, 1])
    img[26:28] = (0x4242).to_bytes(2, "big")
    img[28:34] = bytes([3, 80, 90, 0, 0, 0])
    img[34:36] = joy.to_bytes(2, "big", signed=True)
    img[58] = 42
    return bytes(img)


def eclink_image_out(pco, cao=3, length=224):
    img = bytearray(length)
    img[0:4] = bytes([pco & 0xFF, 1, 0, cao])
    img[4:20] = b"TO-RU-COMMAND-16"
    if length == 224:
        img[20:22] = (12).to_bytes(2, "big")
        img[24:36] = bytes(range(1, 13))
    return bytes(img)


def eclink_traffic(d, cap, pairs, outlen, dt=0.001):
    """The BU's PCI every 125 ms, the controller's PCO every 100 ms."""
    for i in range(pairs):
        ms = int(i * 2 * dt * 1000)
        pci = ms // 125
        cap.add(d.cyclic("in", {1: eclink_image_in(pci, joy=(i * 7) % 1000)}), dt)
        out = {2: eclink_image_out(ms // 100, length=outlen)} if outlen else {}
        cap.add(d.cyclic("out", out), dt)


def write(cap, work_dir, name):
    return cap.write(work_dir / name)


def both(work_dir, name, device, traffic):
    """(capture with the Connect, the same without it)."""
    paths = []
    for connect in (True, False):
        cap = CaptureFile()
        if connect:
            for p in device.connect():
                cap.add(p)
        device.cycle = 0
        traffic(cap)
        paths.append(write(cap, work_dir, ("with_" if connect else "without_") + name))
    return paths


def settled_in(tshark, path, layout_field):
    """The frame the layout was inferred in (one pass), and the layout text."""
    got = tshark.frames(path, [layout_field], display_filter=layout_field)
    first = min(got)
    return first, got[first][layout_field]


def same_as_with_connect(tshark, with_connect, without, fields, offset=2):
    """Under -2 every cyclic frame decodes as with the Connect (offset: its frames)."""
    a = tshark.frames(with_connect, fields, two_pass=True)
    b = tshark.frames(without, fields, two_pass=True)
    assert len(b) >= 1000
    for n, row in b.items():
        assert row == a[n + offset], "frame %d" % n
    assert all(row[fields[0]] for row in b.values())


def test_duplex_base_mid_session(tshark, work_dir):
    d = Device(mcmb2_submodules("duplex", 4, 26, 2, 8, 1), mac(5), 0x8001, 0x8002)
    with_connect, without = both(work_dir, "duplex.pcap", d, lambda cap: mcmb2_traffic(d, cap, 500, 26, 2))
    same_as_with_connect(tshark, with_connect, without, MCMB2_FIELDS)
    # one pass: from the frame the layout is inferred in (both watchdogs moved twice)
    first, text = settled_in(tshark, without, "mcmb2.layout")
    assert text == "inferred from cyclic frames 1..%d" % first
    entry = "0x8001/0x8002=duplex:26/2,a8@4"
    tshark.expect(without, first, {"mcmb2.layout_entry": entry, "_ws.expert.message": (
        "Cyclic data layout inferred from frames 1..%d (no Connect in the capture); to pin it, add to "
        "mcmb2.layouts: %s" % (first, entry))})
    assert 100 < first < 250
    one = tshark.frames(without, ["mcmb2.system"])
    assert [n for n, r in one.items() if r["mcmb2.system"]] == list(range(first, 1001))
    # the offered entry pins the same layout
    pinned = tshark.frames(without, MCMB2_FIELDS, prefs={"mcmb2.layouts": entry}, two_pass=True)
    assert pinned == tshark.frames(without, MCMB2_FIELDS, two_pass=True)
    tshark.expect(without, 1, {"mcmb2.layout": "preference", "mcmb2.layout_entry": None},
                  prefs={"mcmb2.layouts": entry})
    # with the Connect nothing is inferred
    assert tshark.frames(with_connect, ["mcmb2.layout_entry"], display_filter="mcmb2.layout_entry") == {}


@pytest.mark.parametrize("outlen", [20, 224])
def test_eclink_bu_mid_session(tshark, work_dir, outlen):
    d = Device(eclink_submodules(4, outlen), mac(9), 0x8010, 0x8011)
    with_connect, without = both(work_dir, "eclink%d.pcap" % outlen, d,
                                 lambda cap: eclink_traffic(d, cap, 500, outlen))
    same_as_with_connect(tshark, with_connect, without, ECLINK_FIELDS)
    first, text = settled_in(tshark, without, "eclink_pnio.layout")
    assert text == "inferred from cyclic frames 1..%d" % first
    entry = "0x8010/0x8011=eclink:/%d@4" % outlen
    tshark.expect(without, first, {"eclink_pnio.layout_entry": entry})
    # the PCI chain of the input image (three images, 250 ms: 125 frame pairs) decides it
    assert 240 <= first <= 300
    pinned = tshark.frames(without, ECLINK_FIELDS, prefs={"mcmb2.layouts": entry}, two_pass=True)
    assert pinned == tshark.frames(without, ECLINK_FIELDS, two_pass=True)


def test_a_data_byte_holding_0x80_where_another_layout_has_an_iops(tshark, work_dir):
    """A downlink of 18 data bytes (modules 10 + 8) whose byte 8 holds 0x80
    for the first 300 cycles: an 8-byte module there and a 10-byte module
    after it (over the real IOPS) explain as many bytes as IOxS, but only
    with the modules out of slot order (10 before 8: section 5.3 splits
    largest first, and nothing in those bytes is text to make the 10 an
    ASCII module). The reading with every data object in slot order, as the
    controllers we know place them, is taken at once."""
    d = Device(mcmb2_submodules("duplex", 4, 10, 18, 0, 1), mac(11), 0x8020, 0x8021)
    ins, outs = _slots(d, "in"), _slots(d, "out")
    cap = CaptureFile()
    for i in range(500):
        wd_up, wd_down = (i // 10) & 0xFF, (i // 50) & 0xFF
        cap.add(d.cyclic("in", _spread(ins, "inlen", bytes([0x31, wd_up]) + bytes(range(1, 11)))))
        down = bytes(range(1, 19))
        down = down[:8] + bytes([0x80 if i < 300 else 0x09]) + down[9:]
        cap.add(d.cyclic("out", _spread(outs, "outlen", bytes([0, wd_down]) + down)))
    path = write(cap, work_dir, "ambiguous.pcap")
    assert tshark.frames(path, ["frame.number"], display_filter="mcmb2.layout.ambiguous || mcmb2.candidate",
                         two_pass=True) == {}
    first, text = settled_in(tshark, path, "mcmb2.layout")
    assert first < 300
    tshark.expect(path, first, {"mcmb2.layout_entry": "0x8020/0x8021=duplex:10/18@4"})
    two = tshark.frames(path, ["mcmb2.system", "mcmb2.downlink_data"], display_filter="mcmb2.system",
                        two_pass=True)
    assert sorted(two) == list(range(1, 1001))
    assert two[2]["mcmb2.downlink_data"] == (bytes(range(1, 9)) + b"\x80" + bytes(range(10, 19))).hex()


# -- every configuration of section 5.3 ----------------------------------------
config = st.one_of(
    st.tuples(st.just("duplex"), st.integers(1, 8), st.integers(1, 60).map(lambda n: 2 * n),
              st.integers(0, 30).map(lambda n: 2 * n), st.integers(0, 30).map(lambda n: 2 * n)),
    st.tuples(st.just("eclink"), st.integers(1, 8), st.sampled_from([0, 20, 224]), st.just(0), st.just(0)))


def expected_entry(cfg, in_fid, out_fid):
    system, dap, a, b, c = cfg
    if system == "eclink":
        if a == 0:
            return "0x%04x/-=eclink@%d" % (in_fid, dap)
        return "0x%04x/0x%04x=eclink:/%d@%d" % (in_fid, out_fid, a, dap)
    if b == 0 and c == 0:
        return "0x%04x/0x%04x=simplex:%d@%d" % (in_fid, out_fid, a, dap)
    down = ",".join(p for p in (str(b) if b else "", "a%d" % c if c else "") if p)
    return "0x%04x/0x%04x=duplex:%d/%s@%d" % (in_fid, out_fid, a, down, dap)


@settings(max_examples=8, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(configs=st.lists(config, min_size=1, max_size=6))
def test_every_section_5_3_configuration(tshark, work_dir, configs):
    # (a file of its own per example: tshark runs are cached by their arguments)
    """Several devices in one capture, each of its own configuration, none
    with a Connect: each is decoded with the layout it has."""
    cap = CaptureFile()
    devices = []
    for k, cfg in enumerate(configs):
        system, dap, a, b, c = cfg
        in_fid, out_fid = 0x8100 + 2 * k, 0x8101 + 2 * k
        if system == "eclink":
            d = Device(eclink_submodules(dap, a), mac(100 + k), in_fid, out_fid)
        else:
            d = Device(mcmb2_submodules("duplex", dap, a, b, c, 1), mac(100 + k), in_fid, out_fid)
        devices.append((cfg, d))
    # the devices' frames interleaved, as on one wire
    per = [CaptureFile() for _ in devices]
    for (cfg, d), sub in zip(devices, per):
        if cfg[0] == "eclink":
            eclink_traffic(d, sub, 160, cfg[2], dt=0.002)
        else:
            mcmb2_traffic(d, sub, 160, cfg[2], cfg[3], text=b"CRANE", dt=0.002, wd_up_ms=8, wd_down_ms=40)
    order = sorted((p.time, i, j) for i, sub in enumerate(per) for j, p in enumerate(sub.packets))
    cap.packets = [per[i].packets[j] for _, i, j in order]
    path = write(cap, work_dir, "configs-%d.pcap" % len(list(work_dir.glob("configs-*"))))
    got = tshark.frames(path, ["eth.src", "mcmb2.layout_entry", "eclink_pnio.layout_entry", "mcmb2.system",
                               "eclink.image"], two_pass=True)
    for k, (cfg, d) in enumerate(devices):
        mine = [r for r in got.values() if r["eth.src"] == d.mac]
        entries = {r["mcmb2.layout_entry"] or r["eclink_pnio.layout_entry"] for r in mine}
        assert entries == {expected_entry(cfg, d.in_fid, d.out_fid)}, cfg
        assert all(r["mcmb2.system"] or r["eclink.image"] for r in mine), cfg


# -- ordinary IO devices: never ours --------------------------------------------
def io_device(index, ins, outs):
    subs = dap_submodules(4)
    slot = 0
    for n in ins:
        slot += 1
        subs.append(Submodule(slot, 1, inlen=n))
    for n in outs:
        slot += 1
        subs.append(Submodule(slot, 1, outlen=n))
    return Device(subs, mac(200 + index), 0x8200 + 2 * index, 0x8201 + 2 * index)


FOREIGN = {
    # 32-bit counters counting every cycle, a 32-bit output counter
    "counters": (io_device(0, [4, 4], [4]),
                 lambda i: [i.to_bytes(4, "big"), (3 * i).to_bytes(4, "big")], lambda i: [(i // 2).to_bytes(4, "big")]),
    # 0/1 digital inputs in 2-byte modules, changing every few cycles; 0/1 outputs
    "digital": (io_device(1, [2] * 6, [2, 2]),
                lambda i: [bytes([(i // (3 + k)) % 2, k % 2]) for k in range(6)], lambda i: [b"\x00\x01", b"\x01\x00"]),
    # analogue values (a sine wave), an analogue setpoint
    "analogue": (io_device(2, [2, 2, 4, 20], [2, 4]),
                 lambda i: [int(16000 + 8000 * math.sin(i / 20)).to_bytes(2, "big"), (1234).to_bytes(2, "big"),
                            bytes(4), bytes(range(20))],
                 lambda i: [(i % 500).to_bytes(2, "big"), bytes(4)]),
    # modules holding constant 0x80 bytes (every byte looks like a GOOD IOxS)
    "constant": (io_device(3, [2, 10, 20], [2, 10]),
                 lambda i: [b"\x80" * 2, b"\x80" * 10, b"\x80" * 20], lambda i: [b"\x80" * 2, b"\x80" * 10]),
}


def foreign_capture(work_dir, names, pairs=500):
    cap = CaptureFile()
    for i in range(pairs):
        for name in names:
            d, ins, outs = FOREIGN[name]
            in_subs, out_subs = _slots(d, "in"), _slots(d, "out")
            cap.add(d.cyclic("in", {s.slot: v for s, v in zip(in_subs, ins(i))}), 0.0005)
            cap.add(d.cyclic("out", {s.slot: v for s, v in zip(out_subs, outs(i))}), 0.0005)
    return write(cap, work_dir, "foreign.pcap")


@pytest.mark.parametrize("two_pass", [False, True])
def test_ordinary_io_devices_are_not_ours(tshark, work_dir, two_pass):
    path = foreign_capture(work_dir, sorted(FOREIGN))
    assert len(tshark.frames(path, ["pn_rt.frame_id"], display_filter="pn_rt")) == 4000
    assert tshark.frames(path, ["frame.number"], display_filter=OURS, two_pass=two_pass) == {}


def test_a_base_beside_ordinary_devices(tshark, work_dir):
    """The same plant with an MC-MB2-PN base among them: the base alone is ours."""
    cap = CaptureFile()
    base = Device(mcmb2_submodules("duplex", 2, 10, 4, 0, 1), mac(7), 0x8050, 0x8051)
    sub = CaptureFile()
    mcmb2_traffic(base, sub, 500, 10, 4)
    foreign = foreign_capture(work_dir, sorted(FOREIGN), pairs=250)
    del foreign
    for i, p in enumerate(sub.packets):
        cap.add(p, 0.0005)
        if i % 2:
            for name in sorted(FOREIGN):
                d, ins, outs = FOREIGN[name]
                frames = d.cyclic("in", {s.slot: v for s, v in zip(_slots(d, "in"), ins(i))})
                cap.add(frames, 0.0001)
    path = write(cap, work_dir, "plant.pcap")
    got = tshark.frames(path, ["eth.src", "eth.dst", "mcmb2.layout_entry"], display_filter=OURS, two_pass=True)
    assert {(r["eth.src"], r["mcmb2.layout_entry"]) for r in got.values()} == {
        (base.mac, "0x8050/0x8051=duplex:10/4@2"), (base.ctl_mac, "0x8050/0x8051=duplex:10/4@2")}
