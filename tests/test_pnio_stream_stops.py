"""Issue 55 section 1: a PROFINET stream of ours that stops is said on the
first frame after its deadline, whichever frame that is.

scapy-built traffic (tests/pnio_testlib.py), cut the way a real fault cuts
it: an MC-MB2-PN duplex base whose uplink ends at 0.8 s while the
controller's downlink runs on (SP-14-023 3.1.2: the uplink watchdog not
updated for 1 s), the downlink ending while the uplink runs on (2.4: the
downlink watchdog within 2000 ms, E010), an EC-Link BU whose input frames
end while its outputs run on (TS-0007 8.3: PCI stops for 500 ms), and a
base whose two streams end while another PROFINET device runs on: there
the finding is on that device's frame, which reaches Lua only through the
C front end's clock hook (or the Lua carrier without the C plugin). With
the Connect and without it (an excerpt that starts mid-session: the
layout table, or the layout inferred from the frames). Each stream steps
its own PN-RT cycle counter by the Connect's cycle (SendClockFactor 32 x
ReductionRatio 8 = 256 units of 31.25 us, 8 ms), a frame each 8 ms.

Exact fields by name, one pass and -2, with the C plugin and without it
(tools/test runs this file in both phases).
"""
import struct
import subprocess

import pytest
from scapy.contrib.pnio import PNIORealTimeCyclicPDU
from scapy.layers.l2 import Ether
from scapy.packet import Raw

from conftest import _world_dir
from pnio_testlib import CaptureFile, Device, eclink_submodules, mac, mcmb2_submodules
from test_pnio_midsession import _slots, _spread, eclink_image_in, eclink_image_out

PASSES = pytest.mark.parametrize("two_pass", [False, True], ids=["one-pass", "two-pass"])
CYCLE = 0.008           # each stream's frame interval, the Connect's cycle
STEP = 256              # its cycle counter step (32 x 8)
FOREIGN_FID = 0x0400    # another device's cyclic frames: no FrameID of ours, no candidate
MISSING = "mcmb2.uplink_missing || mcmb2.downlink_missing || eclink_pnio.input_missing || eclink_pnio.output_missing"
FIELDS = ["mcmb2.uplink_missing", "mcmb2.downlink_missing", "mcmb2.missing_since", "mcmb2.missing_time",
          "eclink_pnio.input_missing", "eclink_pnio.output_missing", "eclink_pnio.missing_since",
          "eclink_pnio.missing_time", "_ws.expert.message", "_ws.col.Info", "pn_rt.frame_id"]


class Plant:
    """Frames at absolute times (seconds after the Connect), each stream
    with its own cycle counter; written in time order. .frames: [(t, kind)]
    of the written file, kind "up", "down", "foreign", "connect"."""

    def __init__(self, device):
        self.d = device
        self.events = []
        self.counters = {}

    def add(self, t, kind, pkt, counter=None):
        if counter is not None:
            pkt[PNIORealTimeCyclicPDU].cycleCounter = counter & 0xFFFF
        self.events.append((t, kind, pkt))

    def stream(self, kind, start, end, make, interval=CYCLE, step=STEP):
        """Frames of one stream from start (inclusive) to end (exclusive)."""
        i = 0
        while start + i * interval < end - 1e-9:
            t = start + i * interval
            self.add(t, kind, make(i, t), (int(round(t / interval)) * step))
            i += 1

    def foreign(self, start, end, interval=0.004):
        i = 0
        while start + i * interval < end - 1e-9:
            raw = struct.pack(">H", FOREIGN_FID) + bytes(40) + struct.pack(">HBB", (i * 128) & 0xFFFF, 0x35, 0)
            self.events.append((start + i * interval, "foreign",
                                Ether(src=mac(0x99), dst=mac(0x98), type=0x8892) / Raw(raw)))
            i += 1

    def write(self, path, connect=True):
        cap = CaptureFile()
        self.frames = []
        if connect:
            for p in self.d.connect():
                cap.add(p)
                self.frames.append((None, "connect"))
        base = cap.packets[-1].time if cap.packets else 1700000000
        for t, kind, pkt in sorted(self.events, key=lambda e: e[0]):
            pkt.time = base + 0.1 + t
            cap.packets.append(pkt)
            self.frames.append((t, kind))
        return cap.write(path)

    def last(self, kind):
        """(frame number, time) of the last frame of a kind."""
        n = max(i for i, (_, k) in enumerate(self.frames) if k == kind)
        return n + 1, self.frames[n][0]

    def first_after(self, t):
        """The frame number of the first frame later than t."""
        return next(i + 1 for i, (ft, _) in enumerate(self.frames) if ft is not None and ft > t + 1e-7)


def duplex_device():
    return Device(mcmb2_submodules("duplex", 1, 4, 10, 0, 1), mac(0x55), 0x8001, 0x8002)


def duplex_plant(up_end, down_end, foreign_end=None):
    """An MC-MB2-PN duplex base: uplink frames at 0, 8, 16 ms ... until
    up_end, downlink frames 3 ms after each uplink slot until down_end
    (watchdogs moving every 20 ms and 100 ms)."""
    d = duplex_device()
    ins, outs = _slots(d, "in"), _slots(d, "out")
    plant = Plant(d)
    plant.stream("up", 0.0, up_end, lambda i, t: d.cyclic("in", _spread(
        ins, "inlen", bytes([0x31, int(t / 0.020) & 0xFF, 1, 2, 3, 4]))))
    plant.stream("down", 0.003, down_end, lambda i, t: d.cyclic("out", _spread(
        outs, "outlen", bytes([0, int(t / 0.100) & 0xFF]) + bytes(10))))
    if foreign_end:
        plant.foreign(0.001, foreign_end)
    return plant


def eclink_plant(in_end, out_end):
    """An EC-Link BU: input frames until in_end (PCI every 125 ms), output
    frames 3 ms after each input slot until out_end (PCO every 100 ms)."""
    d = Device(eclink_submodules(4, 224), mac(0x56), 0x8011, 0x8012)
    plant = Plant(d)
    plant.stream("up", 0.0, in_end, lambda i, t: d.cyclic("in", {1: eclink_image_in(int(t / 0.125))}))
    plant.stream("down", 0.003, out_end, lambda i, t: d.cyclic("out", {2: eclink_image_out(int(t / 0.100))}))
    return plant


@pytest.fixture(scope="module")
def work():
    return _world_dir("vrshark-stream-stops-")


def excerpt(path, first, out):
    """Frames first.. of a capture (editcap -r): a capture that starts mid-session."""
    subprocess.run(["editcap", "-r", str(path), str(out), "%d-%d" % (first, 10 ** 6)], check=True)
    out.chmod(0o644)
    return out


def missing_rows(tshark, path, two_pass, **kw):
    return tshark.frames(path, FIELDS, display_filter=MISSING, two_pass=two_pass, **kw)


CASES = {
    # the uplink ends at 0.8 s, the downlink runs on: on a downlink frame
    "uplink": dict(ends=(0.8, 2.0), kind="up", limit=1.0, other="down", age="1.003", fid=0x8002,
                   text="No uplink frame (FrameID 0x8001) for 1.003 s since frame %d, over the 1.000 s the spec "
                        "allows: the uplink watchdog is not updated, bring the system to a safe state "
                        "(SP-14-023 3.1.2)"),
    # the downlink ends at 0.8 s, the uplink runs on: on an uplink frame
    "downlink": dict(ends=(3.0, 0.8), kind="down", limit=2.0, other="up", age="2.005", fid=0x8001,
                     text="No downlink frame (FrameID 0x8002) for 2.005 s since frame %d, over the 2.000 s the "
                          "spec allows: the downlink watchdog is not updated, the base shows E010 (SP-14-023 2.4)"),
}


@PASSES
@pytest.mark.parametrize("stream", sorted(CASES))
def test_one_direction_ends_the_other_runs_on(tshark, work, two_pass, stream):
    c = CASES[stream]
    plant = duplex_plant(up_end=c["ends"][0], down_end=c["ends"][1])
    path = plant.write(work / ("%s_ends.pcap" % stream))
    last, t_last = plant.last(c["kind"])
    at = plant.first_after(t_last + c["limit"])
    assert plant.frames[at - 1][1] == c["other"]
    got = missing_rows(tshark, path, two_pass)
    assert sorted(got) == [at]
    other = "downlink" if stream == "uplink" else "uplink"
    tshark.expect(path, at, {
        "mcmb2.%s_missing" % stream: True, "mcmb2.%s_missing" % other: None, "mcmb2.missing_since": last,
        "mcmb2.missing_time": float(c["age"]), "pn_rt.frame_id": c["fid"]}, two_pass=two_pass)
    assert c["text"] % last in got[at]["_ws.expert.message"]
    assert got[at]["_ws.col.Info"].endswith(" [no %s %s s]" % (stream, c["age"]))


@PASSES
def test_eclink_inputs_end_outputs_run_on(tshark, work, two_pass):
    plant = eclink_plant(in_end=0.8, out_end=2.0)
    path = plant.write(work / "eclink_inputs_end.pcap")
    last, t_last = plant.last("up")
    at = plant.first_after(t_last + 0.5)
    got = missing_rows(tshark, path, two_pass)
    assert sorted(got) == [at]
    tshark.expect(path, at, {
        "eclink_pnio.input_missing": True, "eclink_pnio.output_missing": None, "eclink_pnio.missing_since": last,
        "eclink_pnio.missing_time": 0.507, "pn_rt.frame_id": 0x8012}, two_pass=two_pass)
    assert ("No input frame (FrameID 0x8011) for 0.507 s since frame %d, over the 0.500 s the spec allows: PCI "
            "cannot move, bring the system to a safe state (TS-0007 8.3)" % last) in got[at]["_ws.expert.message"]
    assert got[at]["_ws.col.Info"].endswith(" [no input 0.507 s]")


@PASSES
def test_both_streams_end_another_device_runs_on(tshark, work, two_pass):
    """The findings are on the other device's frames: with the C plugin they
    reach Lua only through the front end's clock hook."""
    plant = duplex_plant(up_end=0.8, down_end=0.8, foreign_end=3.0)
    path = plant.write(work / "both_end.pcap")
    up_last, t_up = plant.last("up")
    down_last, t_down = plant.last("down")
    at_up, at_down = plant.first_after(t_up + 1.0), plant.first_after(t_down + 2.0)
    assert plant.frames[at_up - 1][1] == plant.frames[at_down - 1][1] == "foreign"
    got = missing_rows(tshark, path, two_pass)
    assert sorted(got) == [at_up, at_down]
    tshark.expect(path, at_up, {"mcmb2.uplink_missing": True, "mcmb2.missing_since": up_last,
                                "mcmb2.missing_time": 1.001, "pn_rt.frame_id": FOREIGN_FID}, two_pass=two_pass)
    tshark.expect(path, at_down, {"mcmb2.downlink_missing": True, "mcmb2.missing_since": down_last,
                                  "mcmb2.missing_time": 2.002, "pn_rt.frame_id": FOREIGN_FID}, two_pass=two_pass)
    assert got[at_up]["_ws.col.Info"].endswith(" [no uplink 1.001 s]")
    assert got[at_down]["_ws.col.Info"].endswith(" [no downlink 2.002 s]")


@PASSES
def test_filed_under_the_decoders_protocol(tshark, work, two_pass):
    """On another device's frame too, the finding is MC-MB2-PN's (-z expert
    lists it under MCMB2)."""
    plant = duplex_plant(up_end=0.8, down_end=0.8, foreign_end=3.0)
    path = plant.write(work / "both_end_expert.pcap")
    out = tshark.run(["-n", "-q", "-r", str(path), "-z", "expert,error"] + (["-2"] if two_pass else [])).stdout
    rows = [line for line in out.splitlines() if "No uplink frame" in line or "No downlink frame" in line]
    # (each stream: past the Connect's data hold time, then past the spec's limit)
    assert len(rows) == 4 and all(" MCMB2 " in r and "Sequence" in r for r in rows), out
    assert sum("data hold time" in r for r in rows) == 2


@PASSES
def test_without_the_connect_layout_table(tshark, work, two_pass):
    """An excerpt from frame 50 on, decoded by the layout table: the same
    finding, its frame numbers those of the excerpt."""
    plant = duplex_plant(up_end=0.8, down_end=2.0)
    full = plant.write(work / "uplink_ends_full.pcap")
    path = excerpt(full, 50, work / "uplink_ends_excerpt.pcap")
    last, t_last = plant.last("up")
    at = plant.first_after(t_last + 1.0)
    prefs = {"mcmb2.layouts": "0x8001/0x8002=duplex:4/10", "mcmb2.connect": "TRUE"}
    got = missing_rows(tshark, path, two_pass, prefs=prefs)
    assert sorted(got) == [at - 49]
    tshark.expect(path, at - 49, {"mcmb2.uplink_missing": True, "mcmb2.missing_since": last - 49,
                                  "mcmb2.missing_time": 1.003}, two_pass=two_pass, prefs=prefs)


@PASSES
def test_without_the_connect_inferred(tshark, work, two_pass):
    """An excerpt from frame 50 on, its layout inferred from the frames."""
    plant = duplex_plant(up_end=0.8, down_end=2.0)
    full = plant.write(work / "uplink_ends_full2.pcap")
    path = excerpt(full, 50, work / "uplink_ends_inferred.pcap")
    last, t_last = plant.last("up")
    at = plant.first_after(t_last + 1.0)
    got = missing_rows(tshark, path, two_pass)
    assert sorted(got) == [at - 49]
    tshark.expect(path, at - 49, {"mcmb2.uplink_missing": True, "mcmb2.missing_since": last - 49,
                                  "mcmb2.missing_time": 1.003}, two_pass=two_pass)


@PASSES
def test_healthy_streams_say_nothing(tshark, work, two_pass):
    plant = duplex_plant(up_end=2.0, down_end=2.0, foreign_end=2.0)
    path = plant.write(work / "healthy.pcap")
    assert missing_rows(tshark, path, two_pass) == {}
    assert tshark.frames(path, ["frame.number"], two_pass=two_pass,
                         display_filter="mcmb2.data_hold_exceeded || mcmb2.frames_lost") == {}
