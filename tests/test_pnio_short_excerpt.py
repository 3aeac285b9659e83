"""Issue 54 item 5: a PROFINET excerpt too short to decide is said, not silent.

An MC-MB2-PN duplex base and EC-Link BUs (20- and 224-byte output images),
made with scapy's PROFINET layers (tests/pnio_testlib.py) with their Connect,
cut as a user would: `editcap -r` keeps 15 or 40 cyclic frames, no Connect.
The frames have the shape of ours, but the evidence the inference waits for
(watchdogs, PCI, PCO moving) takes longer than they span. On the second pass
every frame of both directions carries mcmb2.candidate with the frames seen,
about how many the evidence takes, and the setting that decodes them, which
decodes them as the Connect does. One pass cannot know the capture ends
there and says nothing. tools/test runs this file with and without the C
plugin (whose front end hands the Lua carrier only the FrameIDs it watches).
"""
import shutil
import subprocess

import pytest

from conftest import _world_dir
from pnio_testlib import CaptureFile, Device, eclink_submodules, mac, mcmb2_submodules
from test_pnio_midsession import ECLINK_FIELDS, MCMB2_FIELDS, eclink_traffic, mcmb2_traffic

# the values decoded (not the ages, nor Info: an excerpt's first frames do not know the changes before them)
VALUES = {"mcmb2": [f for f in MCMB2_FIELDS if not f.endswith("_age") and f != "_ws.col.Info"],
          "eclink": [f for f in ECLINK_FIELDS if not f.endswith("_age") and f != "_ws.col.Info"]}

NOTE = ("Shaped like %s, too few frames to decide: %d of %s in %.3f s, about %d needed (%s); to decode them: "
        "mcmb2.layouts:%s")
DEVICES = {
    # name: (device, traffic, what the note names, the evidence it waits for, the entry, decoded fields)
    "base": (lambda: Device(mcmb2_submodules("duplex", 2, 4, 10, 0, 1), mac(0x71), 0x8701, 0x8702),
             lambda d, cap: mcmb2_traffic(d, cap, 300, 4, 10),
             "an MC-MB2-PN duplex/simplex base", 1.0, "watchdogs moving twice: 1 s, SP-14-023 2.4",
             "0x8701/0x8702=duplex:4/10@2", VALUES["mcmb2"]),
    "bu20": (lambda: Device(eclink_submodules(2, 20), mac(0x72), 0x8703, 0x8704),
             lambda d, cap: eclink_traffic(d, cap, 300, 20),
             "an EC-Link BU", 0.25, "3 input images, PCI at 125 ms: 0.25 s, TS-0007 8.3",
             "0x8703/0x8704=eclink:/20@2", VALUES["eclink"]),
    "bu224": (lambda: Device(eclink_submodules(3, 224), mac(0x73), 0x8705, 0x8706),
              lambda d, cap: eclink_traffic(d, cap, 300, 224),
              "an EC-Link BU", 4.0, "PCI at 125 ms, PCO moving twice: 4 s, TS-0007 8.3, 8.4",
              "0x8705/0x8706=eclink:/224@3", VALUES["eclink"]),
}
START = 103             # the first cyclic frame kept (frames 1, 2: the Connect)
FIELDS = ["_ws.expert.message", "mcmb2.candidate_setting", "mcmb2.system", "eclink.image"]


@pytest.fixture(scope="module")
def excerpts():
    """{(device, frames): (path of the excerpt, path of the capture with the Connect)}."""
    work = _world_dir("vrshark-short-excerpt-")
    out = {}
    for name, (make, traffic, *_rest) in DEVICES.items():
        d, cap = make(), CaptureFile()
        for p in d.connect():
            cap.add(p)
        traffic(d, cap)
        full = cap.write(work / ("%s.pcap" % name))
        for n in (15, 40):
            path = work / ("%s-%d.pcap" % (name, n))
            subprocess.run(["editcap", "-r", str(full), str(path), "%d-%d" % (START, START + n - 1)], check=True)
            path.chmod(0o644)
            out[name, n] = (path, full)
    yield out
    shutil.rmtree(work, ignore_errors=True)


@pytest.mark.parametrize("frames", [15, 40])
@pytest.mark.parametrize("name", sorted(DEVICES))
def test_too_few_frames_to_decide_is_said(tshark, excerpts, name, frames):
    path, _ = excerpts[name, frames]
    _, _, what, need, evidence, entry, _ = DEVICES[name]
    d = DEVICES[name][0]()
    # the traffic's frames are 1 ms apart: the count needed at that pace
    note = NOTE % (what, frames, "0x%04x/0x%04x" % (d.in_fid, d.out_fid), (frames - 1) * 0.001,
                   round(need / 0.001) + 1, evidence, entry)
    got = tshark.frames(path, FIELDS, two_pass=True)
    assert got == {n: {"_ws.expert.message": note, "mcmb2.candidate_setting": "mcmb2.layouts:" + entry,
                       "mcmb2.system": "", "eclink.image": ""} for n in range(1, frames + 1)}
    # one pass: the capture might go on; nothing is said, nothing decoded
    one = tshark.frames(path, FIELDS)
    assert set(one) == set(got) and not any(v for row in one.values() for v in row.values())


@pytest.mark.parametrize("name", sorted(DEVICES))
def test_the_setting_offered_decodes_as_the_connect(tshark, excerpts, name):
    path, full = excerpts[name, 40]
    entry, fields = DEVICES[name][5], DEVICES[name][6]
    want = tshark.frames(full, fields, two_pass=True)
    for two_pass in (False, True):
        got = tshark.frames(path, fields, prefs={"mcmb2.layouts": entry}, two_pass=two_pass)
        assert got == {n - START + 1: want[n] for n in range(START, START + 40)}, two_pass


def test_a_whole_capture_of_a_device_that_never_moves_stays_silent(tshark, work_dir):
    """The same base whose watchdogs stand for 1.5 s: not said to be ours
    (a foreign device whose bytes never move), only too short ones are."""
    make, *_ = DEVICES["base"]
    d, cap = make(), CaptureFile()
    for _ in range(750):
        cap.add(d.cyclic("in", {1: b"\x11\x05", 2: b"\x01\x02\x03\x04"}), 0.001)
        cap.add(d.cyclic("out", {3: b"\x00\x07", 4: bytes(range(1, 11))}), 0.001)
    path = cap.write(work_dir / "still.pcap")
    assert tshark.frames(path, ["frame.number"], display_filter="mcmb2 || mcmb2.candidate", two_pass=True) == {}
    short = work_dir / "still-15.pcap"
    subprocess.run(["editcap", "-r", str(path), str(short), "1-15"], check=True)
    got = tshark.frames(short, ["mcmb2.candidate_setting"], two_pass=True)
    assert {r["mcmb2.candidate_setting"] for r in got.values()} == {"mcmb2.layouts:0x8701/0x8702=duplex:4/10@2"}
