"""Issue 55 section 1, the PROFINET cycle: the data hold time of the
Connect's IOCR (DataHoldFactor x SendClockFactor x ReductionRatio x 31.25
us) and gaps in the PN-RT cycle counter (lost frames, with their count).

scapy-built MC-MB2-PN duplex traffic (tests/test_pnio_stream_stops.py's
Plant): each stream a frame each 8 ms, its cycle counter stepping by the
Connect's 256 units; the Connect's DataHoldFactor is scapy's 10 (80 ms).
Uplink frames are taken out the way a bad link loses them (the sender's
counter runs on); the time stamps are shaken the way a capture's are (the
counters not): jitter and a capture that held its frames back are no gap.
Without the Connect (an excerpt decoded by the layout table) the step is
learned from the frames and the data hold time is not judged. One pass
and -2, with the C plugin and without it (tools/test runs both phases).
"""
import random

import pytest

from test_pnio_stream_stops import CYCLE, PASSES, STEP, Plant, duplex_device, excerpt
from pnio_testlib import mac
from test_pnio_midsession import _slots, _spread

CYCLE_FIELDS = ["mcmb2.data_hold_exceeded", "mcmb2.frames_lost", "mcmb2.lost_frames", "mcmb2.missing_since",
                "mcmb2.missing_time", "mcmb2.uplink_missing", "_ws.expert.message", "_ws.col.Info",
                "pn_rt.frame_id"]
CYCLE_FINDINGS = "mcmb2.data_hold_exceeded || mcmb2.frames_lost || mcmb2.uplink_missing || mcmb2.downlink_missing"
TABLE = {"mcmb2.layouts": "0x8001/0x8002=duplex:4/10"}


@pytest.fixture(scope="module")
def work():
    from conftest import _world_dir
    return _world_dir("vrshark-pnio-cycle-")


def plant_with(lost_up=(), shake=None, end=1.0):
    """A duplex base, both streams to `end`; uplink frames whose time falls
    in one of the (start, stop) ranges of lost_up are lost; shake(t) moves a
    frame's time stamp (its counter stays)."""
    d = duplex_device()
    ins, outs = _slots(d, "in"), _slots(d, "out")
    plant = Plant(d)
    for kind, start, make in (
            ("up", 0.0, lambda t: d.cyclic("in", _spread(ins, "inlen", bytes([0x31, int(t / 0.020) & 0xFF, 1, 2,
                                                                                3, 4])))),
            ("down", 0.003, lambda t: d.cyclic("out", _spread(outs, "outlen", bytes([0, int(t / 0.100) & 0xFF])
                                                              + bytes(10))))):
        i = 0
        while start + i * CYCLE < end - 1e-9:
            t = start + i * CYCLE
            i += 1
            if kind == "up" and any(a < t < b for a, b in lost_up):
                continue
            plant.add(shake(t) if shake else t, kind, make(t), int(round(t / CYCLE)) * STEP)
    return plant


def rows(tshark, path, two_pass, **kw):
    return tshark.frames(path, CYCLE_FIELDS, display_filter=CYCLE_FINDINGS, two_pass=two_pass, **kw)


@PASSES
def test_gap_past_the_data_hold_time(tshark, work, two_pass):
    """Uplink frames lost from 0.400 s to 0.504 s: the first frame past
    0.400 + 80 ms says the data hold time passed (a downlink frame), the
    uplink's next frame that 12 frames were lost."""
    plant = plant_with(lost_up=[(0.400, 0.504)])
    path = plant.write(work / "hold.pcap")
    last = next(i + 1 for i, (t, k) in enumerate(plant.frames) if k == "up" and t is not None and abs(t - 0.4) < 1e-9)
    at = plant.first_after(0.480)
    back = next(i + 1 for i, (t, k) in enumerate(plant.frames) if k == "up" and t is not None and t > 0.5)
    got = rows(tshark, path, two_pass)
    assert sorted(got) == [at, back]
    tshark.expect(path, at, {"mcmb2.data_hold_exceeded": True, "mcmb2.missing_since": last,
                             "mcmb2.missing_time": 0.083, "mcmb2.frames_lost": None, "pn_rt.frame_id": 0x8002},
                  two_pass=two_pass)
    assert ("No uplink frame (FrameID 0x8001) for 0.083 s since frame %d, past the data hold time of 0.080 s "
            "(DataHoldFactor 10 x cycle 8.000 ms, from the Connect): the IO controller aborts the AR" % last) \
        in got[at]["_ws.expert.message"]
    assert got[at]["_ws.col.Info"].endswith(" [data hold 0.083 s]")
    tshark.expect(path, back, {"mcmb2.frames_lost": True, "mcmb2.lost_frames": 12, "mcmb2.data_hold_exceeded": None,
                               "pn_rt.frame_id": 0x8001}, two_pass=two_pass)
    assert ("12 uplink frames (FrameID 0x8001) lost before this one: cycle counter 12800 -> 16128, 13 steps of 256 "
            "(the Connect's SendClockFactor x ReductionRatio)") in got[back]["_ws.expert.message"]
    assert got[back]["_ws.col.Info"].endswith(" [12 lost]")


@PASSES
def test_lost_frames_counted(tshark, work, two_pass):
    """Three uplink frames lost (32 ms: within the data hold time)."""
    plant = plant_with(lost_up=[(0.200, 0.232)])
    path = plant.write(work / "lost3.pcap")
    back = next(i + 1 for i, (t, k) in enumerate(plant.frames) if k == "up" and t is not None and t > 0.231)
    got = rows(tshark, path, two_pass)
    assert sorted(got) == [back]
    tshark.expect(path, back, {"mcmb2.frames_lost": True, "mcmb2.lost_frames": 3, "mcmb2.data_hold_exceeded": None},
                  two_pass=two_pass)


@PASSES
def test_without_the_connect_the_step_is_learned(tshark, work, two_pass):
    """An excerpt without the Connect, decoded by the layout table: the step
    is the stream's own; the data hold time is not known, not judged."""
    plant = plant_with(lost_up=[(0.200, 0.232), (0.400, 0.504)])
    full = plant.write(work / "learned_full.pcap")
    path = excerpt(full, 10, work / "learned.pcap")
    backs = [next(i + 1 for i, (t, k) in enumerate(plant.frames) if k == "up" and t is not None and t > after) - 9
             for after in (0.231, 0.503)]
    got = rows(tshark, path, two_pass, prefs=TABLE)
    assert sorted(got) == backs
    for n, count in zip(backs, (3, 12)):
        tshark.expect(path, n, {"mcmb2.frames_lost": True, "mcmb2.lost_frames": count,
                                "mcmb2.data_hold_exceeded": None}, two_pass=two_pass, prefs=TABLE)
    assert "(the stream's own step)" in got[backs[0]]["_ws.expert.message"]


@PASSES
def test_jitter_is_not_loss(tshark, work, two_pass):
    """Time stamps shaken by up to 3 ms, and a capture that held every frame
    from 0.400 s to 0.490 s back until 0.490 s (its counters regular): no
    finding."""
    rnd = random.Random(55)

    def shake(t):
        if 0.400 < t < 0.490:
            return 0.490 + (t - 0.400) / 1000
        if 0.390 < t < 0.510:
            return t
        return t + rnd.uniform(-0.003, 0.003)
    plant = plant_with(shake=shake)
    path = plant.write(work / "jitter.pcap")
    assert rows(tshark, path, two_pass) == {}


@PASSES
def test_an_uneven_counter_is_not_judged(tshark, work, two_pass):
    """A sender whose counter does not step evenly (256, 288, 224 ...) and
    sometimes by twice its step: never a loss."""
    d = duplex_device()
    ins, outs = _slots(d, "in"), _slots(d, "out")
    plant = Plant(d)
    counter = 0
    for i in range(100):
        t = i * CYCLE
        counter += (256, 288, 224, 512)[i % 4]
        plant.add(t, "up", d.cyclic("in", _spread(ins, "inlen", bytes([0x31, i // 3 & 0xFF, 1, 2, 3, 4]))), counter)
        plant.add(t + 0.003, "down", d.cyclic("out", _spread(outs, "outlen", bytes([0, i // 12 & 0xFF]) + bytes(10))),
                  i * STEP)
    path = plant.write(work / "uneven.pcap")
    assert rows(tshark, path, two_pass) == {}
    assert rows(tshark, path, two_pass, prefs=TABLE) == {}


@PASSES
def test_a_real_device_gains_only_its_stop(tshark, public_capture, two_pass):
    """Real traffic: the cyclic frames of a public capture's device
    (FrameIDs 0xc002 and 0xc000, 8 ms cycle) decoded as an MC-MB2-PN base by
    the layout table. Its counters step evenly: no frame lost; its Connect
    is not one of ours (no data hold time). Its frames end at 59.7 s while
    the capture goes on: both streams stop, said on frame 636."""
    path = public_capture("pnio_connect_and_cyclic.pcap")
    prefs = {"mcmb2.layouts": "0xc002/0xc000=duplex:2/2"}
    got = tshark.frames(path, ["mcmb2.uplink_missing", "mcmb2.downlink_missing", "mcmb2.frames_lost",
                               "mcmb2.data_hold_exceeded"], display_filter=CYCLE_FINDINGS, prefs=prefs,
                        two_pass=two_pass)
    assert got == {636: {"mcmb2.uplink_missing": "1", "mcmb2.downlink_missing": "1", "mcmb2.frames_lost": "",
                         "mcmb2.data_hold_exceeded": ""}}
