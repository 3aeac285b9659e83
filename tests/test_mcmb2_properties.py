"""Every MC-MB2-PN module configuration that SP-14-023 section 5.3 allows is
recognised and laid out right: with its Connect, from the layout table, and
(polled) from the self-describing uplink header alone.

Hypothesis draws batches of devices (polled: 1-4 used slots in any of the
four, uplink Y bytes and downlink data + ASCII bytes per terminal within the
256-byte areas of sections 4.1 and 4.2; duplex/simplex: 2-254 uplink bytes,
0-254 downlink bytes; 1-8 DAP submodules). A batch is one capture, so one
tshark run checks dozens of devices; the frames come from tests/pnio_testlib.py
(scapy's PROFINET layers, not tools/capgen). The uplink FrameIDs repeat across
devices (devices choose them), the downlink FrameIDs are the controller's
and unique.

Each device sends: uplink (normal), downlink, uplink with E010 and zero data,
downlink. All IOPS and IOCS are GOOD (shown as one "all GOOD" item, so no
mcmb2.iops/iocs fields), every frame of ours has no expert info but the E010
one, and the analysis runs on every frame.
"""
import itertools

import pytest
from hypothesis import HealthCheck, Phase, given, settings
from hypothesis import strategies as st

from conftest import assert_fields
from pnio_testlib import ASCII_MODULES, DATA_MODULES, E010, CaptureFile, Device, largest_first, mac, \
    mcmb2_submodules

SETTINGS = settings(max_examples=6, deadline=None, database=None, derandomize=True, phases=[Phase.generate],
                    suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture,
                                           HealthCheck.data_too_large])
SLOT_SETS = {n: list(itertools.combinations((1, 2, 3, 4), n)) for n in range(1, 5)}
UPLINK_FIDS = (0x8000, 0x8001, 0xC000)  # shared by the devices of a batch
BATCHES = itertools.count()


def even(lo, hi):
    return st.integers(lo // 2, hi // 2).map(lambda v: v * 2)


def no_iops_lookalike(b):
    # A downlink byte 0x80 where another data/ASCII split would put its IOPS
    # makes that one frame fit both splits equally (the plan then stays open
    # for the next frames, see test_mcmb2_recognition.py); keep the batches
    # to frames that tell the splits apart.
    return b.replace(b"\x80", b"\x7f")


@st.composite
def polled(draw):
    n = draw(st.integers(1, 4))
    y = draw(even(2, 248 // n))                 # 8 + n * Y <= 256 (section 4.1)
    z = draw(even(0, 254 // n))                 # 2 + n * Z <= 256 (section 4.2)
    data = draw(even(0, z))
    return {"system": "polled", "slots": draw(st.sampled_from(SLOT_SETS[n])), "up": y, "data": data,
            "ascii": z - data, "dap": draw(st.integers(1, 8)),
            "terminals": draw(st.lists(st.integers(1, 15), min_size=n, max_size=n)),
            "up_pay": [draw(st.binary(min_size=y, max_size=y)) for _ in range(n)],
            "down_pay": [no_iops_lookalike(draw(st.binary(min_size=data, max_size=data)))
                         + draw(st.text(st.characters(min_codepoint=0x20, max_codepoint=0x7E), min_size=z - data,
                                        max_size=z - data)).encode() for _ in range(n)],
            "wd": draw(st.integers(0, 254)), "fid": draw(st.sampled_from(UPLINK_FIDS))}


@st.composite
def duplex(draw):
    y = draw(even(2, 254))
    z = draw(even(0, 254))
    data = draw(even(0, z))
    return {"system": "duplex", "slots": (1,), "up": y, "data": data, "ascii": z - data,
            "dap": draw(st.integers(1, 8)), "terminals": [draw(st.integers(0, 15))],
            "up_pay": [draw(st.binary(min_size=y, max_size=y))],
            "down_pay": [draw(st.binary(min_size=z, max_size=z))],
            "base_unit": draw(st.integers(0, 255)),
            "wd": draw(st.integers(0, 254)), "fid": draw(st.sampled_from(UPLINK_FIDS))}


def modules(size, sizes):
    return len(largest_first(size, sizes))


class Batch:
    """The devices of one capture and what each of their frames must show."""

    def __init__(self, configs, mode):
        self.mode = mode            # "connect", "table" or "header"
        self.cap = CaptureFile()
        self.expected = {}          # frame -> {field: value}
        self.table = []
        self.devices = []
        for i, c in enumerate(configs):
            subs = mcmb2_submodules(c["system"], c["dap"], c["up"], c["data"], c["ascii"], len(c["slots"]))
            # The layout table names FrameIDs only: unique uplink FrameIDs there.
            in_fid = 0x8100 + i if mode == "table" else c["fid"]
            d = Device(subs, mac(0x100 + i), in_fid, 0xC100 + i, ip="10.0.%d.%d" % (i // 200, 2 + i % 200))
            self.devices.append((d, c))
        # The Connects first, then the cyclic frames round by round, the devices interleaved.
        self.layout = {}
        for i, (d, c) in enumerate(self.devices):
            if mode == "connect":
                req, res = d.connect(seq=i + 1, request_fids=(0xFFFF, d.out_fid) if i % 2 else None,
                                     endian=i % 2)
                self.layout[i] = "Connect in frame %d" % self.cap.add(req)
                self.cap.add(res)
            elif mode == "table":
                self.layout[i] = "preference"
                self.table.append(self.table_entry(d, c))
        for step in range(4):
            for i, (d, c) in enumerate(self.devices):
                self.frame(i, d, c, step)

    @staticmethod
    def table_entry(d, c):
        n = len(c["slots"])
        per = "%dx" % n if c["system"] == "polled" else ""
        down = ",".join(x for x in ("%d" % c["data"] if c["data"] else "",
                                    "a%d" % c["ascii"] if c["ascii"] else "") if x)
        return "0x%04x/0x%04x=%s:%s%d/%s%s@%d" % (d.in_fid, d.out_fid, c["system"], per, c["up"],
                                                  per if down else "", down, c["dap"])

    def frame(self, i, d, c, step):
        n = len(c["slots"])
        polled = c["system"] == "polled"
        wd = (c["wd"] + step // 2) & 0xFF
        up_mods = modules(c["up"], DATA_MODULES)
        down_mods = modules(c["data"], DATA_MODULES) + modules(c["ascii"], ASCII_MODULES)
        e010 = step == 2
        if step in (0, 2):
            pay = [bytes(c["up"]) for _ in range(n)] if e010 else c["up_pay"]
            status = [(t << 4) | (0 if e010 else 1) for t in c["terminals"]]
            if polled:
                slots = [0x0F] * 4
                for k, s in zip(c["slots"], status):
                    slots[k - 1] = s
                header = bytes([0x0A if e010 else 0x0F, wd, c["up"], c["data"] + c["ascii"]] + slots)
            else:
                header = bytes([0x0A | (c["terminals"][0] << 4) if e010 else status[0], wd])
            num = self.cap.add(d.cyclic("in", self.spread(d, "in", header, pay)))
            if self.mode == "header" and step == 0:
                self.layout[i] = "polled header in frame %d" % num
            want = {"mcmb2.system": c["system"], "mcmb2.direction": "uplink", "mcmb2.layout": self.layout[i],
                    "mcmb2.status": header[0] & 0x0F, "mcmb2.uplink_watchdog": wd, "mcmb2.iops": None,
                    "mcmb2.iocs": None, "_ws.expert.message": E010 if e010 else None}
            if polled:
                want.update({"mcmb2.terminal": 0, "mcmb2.uplink_size": c["up"],
                             "mcmb2.downlink_size": c["data"] + c["ascii"], "mcmb2.slot": [1, 2, 3, 4],
                             "mcmb2.slot.status": [s & 0x0F for s in slots],
                             "mcmb2.slot.terminal": [s >> 4 for s in slots],
                             "mcmb2.slot.uplink_data": [p.hex() for p in pay], "mcmb2.uplink_data": None})
            else:
                want.update({"mcmb2.terminal": c["terminals"][0], "mcmb2.uplink_data": pay[0].hex(),
                             "mcmb2.slot": None})
        else:
            header = bytes([0 if polled else c["base_unit"], wd])
            num = self.cap.add(d.cyclic("out", self.spread(d, "out", header, c["down_pay"])))
            want = {"mcmb2.system": c["system"], "mcmb2.direction": "downlink", "mcmb2.layout": self.layout[i],
                    "mcmb2.downlink_watchdog": wd, "mcmb2.iops": None, "mcmb2.iocs": None,
                    "mcmb2.uplink_data": None, "_ws.expert.message": None}
            z = c["data"] + c["ascii"]
            if polled:
                want.update({"mcmb2.reserved": 0, "mcmb2.slot": list(c["slots"]) if z else None,
                             "mcmb2.slot.downlink_data": [p.hex() for p in c["down_pay"]] if z else None})
            else:
                want.update({"mcmb2.base_unit": c["base_unit"],
                             "mcmb2.downlink_data": c["down_pay"][0].hex() if z else None})
        self.expected[num] = want

    @staticmethod
    def spread(d, direction, header, payloads):
        """{slot: bytes}: the header module, then the terminals' bytes over their modules in slot order."""
        mods = [s for s in sorted(d.subs, key=lambda s: s.slot)
                if s.slot and (s.outlen if direction == "out" else s.inlen)]
        out, rest = {mods[0].slot: header}, b"".join(payloads)
        for s in mods[1:]:
            n = s.outlen if direction == "out" else s.inlen
            out[s.slot], rest = rest[:n], rest[n:]
        assert rest == b""
        return out

    def check(self, tshark, work_dir, name, two_pass=False):
        # A new file name for every batch: the fixture caches tshark runs by their arguments.
        path = self.cap.write(work_dir / ("%d-%s" % (next(BATCHES), name)))
        names = sorted({k for want in self.expected.values() for k in want})
        prefs = {"mcmb2.layouts": ";".join(self.table)} if self.table else None
        got = tshark.frames(path, names, prefs=prefs, two_pass=two_pass)
        for num, want in sorted(self.expected.items()):
            assert_fields(got[num], want, "frame %d of %s" % (num, name))
        return got


@SETTINGS
@given(st.lists(polled(), min_size=20, max_size=40))
def test_polled_from_the_header_alone(tshark, work_dir, configs):
    Batch(configs, "header").check(tshark, work_dir, "header.pcap")


@SETTINGS
@given(st.lists(st.one_of(polled(), duplex()), min_size=20, max_size=40))
def test_with_the_connect(tshark, work_dir, configs):
    Batch(configs, "connect").check(tshark, work_dir, "connect.pcap")


@SETTINGS
@given(st.lists(st.one_of(polled(), duplex()), min_size=20, max_size=40))
def test_from_the_layout_table(tshark, work_dir, configs):
    Batch(configs, "table").check(tshark, work_dir, "table.pcap")


@pytest.mark.parametrize("mode,slot_sets,z_max", [("header", ((2,), (1, 2, 3, 4)), 40),
                                                  ("connect", ((1, 2, 3, 4),), 20)])
def test_every_downlink_split(tshark, work_dir, mode, slot_sets, z_max):
    """Every split of Z = data + ASCII, 4 DAP submodules: from the header up
    to 40 bytes with 1 and with 4 terminals, with the Connect up to 20 bytes
    with 4 (a Connect costs scapy 40 ms; the hypothesis tests draw the rest)."""
    configs = []
    for z in range(0, z_max + 2, 2):
        for data in range(0, z + 1, 2):
            for slots in slot_sets:
                n = len(slots)
                configs.append({"system": "polled", "slots": slots, "up": 6, "data": data, "ascii": z - data,
                                "dap": 4, "terminals": list(range(1, n + 1)),
                                "up_pay": [bytes([0x10 * k + 1] * 6) for k in range(n)],
                                "down_pay": [bytes(range(1, data + 1)) + b"ascii text for slot %d.............."[
                                    :z - data].ljust(z - data, b".") for k in range(n)],
                                "wd": 7, "fid": 0x8001})
    batch = Batch(configs, mode)
    batch.check(tshark, work_dir, mode + "-splits.pcap")
    batch.check(tshark, work_dir, mode + "-splits.pcap", two_pass=True)
