"""Time that steps back in the middle of a capture (a clock set back while
capturing, captures joined): the step is a finding on the frame where it
happens, the rules restart there counting the step as no time, no age or
duration is negative, and every fault of the capture is still found on its
frame. The stepped captures are the project's own with every frame from
one on 2 s earlier (tools/capgen/clock_step.py), so their faults are those
of the original capture, found on the same frames."""
import json
import os
import subprocess

import pytest

from conftest import CAPTURES, ROOT, expert_infos

# stepped capture: (original, the first frame moved back, the frame before
# it, protocol, the rules its text names)
STEPPED = {
    "clockstep_modbus.pcap": ("eclink_modbus_faults.pcap", 24, 23, "eclink_modbus",
                              "the PCI, PCO, command deadline and poll gap rules"),
    "clockstep_eclink_pnio.pcap": ("eclink_pnio_connect.pcap", 50, 49, "eclink_pnio",
                                   "the PCI, PCO and command deadline rules"),
    "clockstep_mcmb2.pcap": ("mcmb2_duplex_watchdog.pcap", 20, 19, "mcmb2", "the watchdog rules"),
}
# The step counts as no time: the gap between the two frames of the step
# (1 ms in clockstep_eclink_pnio) is not counted, so the deadline of the
# command of frame 43 is seen passing one frame later (the downlink frame
# right after: 77, not 76). {capture: {frame in the original: frame here}}
MOVED = {"clockstep_eclink_pnio.pcap": {76: 77}}
# every time the Lua protocols show: none may be negative
TIMES = ["eclink_modbus.pci_age", "eclink_modbus.pco_age", "eclink_modbus.time", "eclink_modbus.poll_gap_time",
         "eclink_modbus.cmd_from_ru_latency", "eclink_modbus.cmd_to_ru_latency", "eclink_pnio.pci_age",
         "eclink_pnio.pco_age", "mcmb2.watchdog_age"]


def _experts(tshark, capture, two_pass):
    return {(f, name, msg) for f, name, _, _, msg, _ in expert_infos(tshark.json(CAPTURES / capture,
                                                                                  two_pass=two_pass))}


@pytest.mark.parametrize("two_pass", [False, True], ids=["one-pass", "two-pass"])
@pytest.mark.parametrize("stepped", sorted(STEPPED))
def test_step_is_a_finding_and_every_fault_is_still_found(tshark, stepped, two_pass):
    original, frame, before, proto, rules = STEPPED[stepped]
    got = _experts(tshark, stepped, two_pass)
    step = [e for e in got if e[1] == proto + ".time_backwards"]
    assert len(step) == 1 and step[0][0] == frame, step
    # the capture's times: 2 s back, less the gap between the two frames
    rel = tshark.frames(CAPTURES / stepped, ["frame.time_epoch"])
    back = float(rel[before]["frame.time_epoch"]) - float(rel[frame]["frame.time_epoch"])
    assert 1.8 < back < 2.0
    assert step[0][2] == ("Time went backwards by %.3f s after frame %d (clock step): %s restart here, "
                          "counting the step as no time" % (back, before, rules))
    # the faults of the original on the same frames (the time-only wording aside)
    moved = MOVED.get(stepped, {})
    want = {(moved.get(f, f), name) for f, name, _ in _experts(tshark, original, two_pass)}
    assert {(f, name) for f, name, _ in got if name != proto + ".time_backwards"} == want


@pytest.mark.parametrize("stepped", sorted(STEPPED))
def test_no_time_is_negative(tshark, stepped):
    for two_pass in (False, True):
        for f, row in tshark.frames(CAPTURES / stepped, TIMES, two_pass=two_pass).items():
            for name, value in row.items():
                for v in filter(None, value.split(",")):
                    assert float(v) >= 0, (stepped, f, name, v)


@pytest.mark.parametrize("stepped", sorted(STEPPED))
def test_ages_as_without_the_step(tshark, stepped):
    """Every age and duration as in the original capture, but for the gap
    of the step itself (at most 125 ms here) on those measured across it."""
    original = STEPPED[stepped][0]
    names = [n for n in TIMES if n.startswith(STEPPED[stepped][3])]
    got = tshark.frames(CAPTURES / stepped, names, two_pass=True)
    want = tshark.frames(CAPTURES / original, names, two_pass=True)
    assert sorted(got) == sorted(want)
    for f in want:
        for name in names:
            a, b = got[f][name].split(","), want[f][name].split(",")
            assert len(a) == len(b), (f, name)
            for x, y in zip(a, b):
                if x or y:
                    assert 0 <= float(y) - float(x) <= 0.125 + 1e-6, (stepped, f, name, x, y)
                    if f < STEPPED[stepped][1]:
                        assert x == y


def test_stall_across_the_step_counts_the_time_before_it(tshark):
    """mcmb2_duplex_watchdog: the uplink watchdog stands from 1.0 s and is
    flagged 1.199 s later, the step 1.999 s back between: the same age as
    without the step (the 1 ms gap of the step aside)."""
    got = tshark.frames(CAPTURES / "clockstep_mcmb2.pcap", ["mcmb2.watchdog_age", "_ws.expert.message"],
                        two_pass=True)
    assert "Uplink watchdog unchanged for 1.199 s (value 5): bring the system to a safe state" \
        in got[23]["_ws.expert.message"]
    assert [float(got[f]["mcmb2.watchdog_age"]) for f in (19, 20, 21)] == [0.8, 0.799, 0.999]


def _report(conf_dir, capture):
    env = dict(os.environ, TZ="UTC", LC_ALL="C.UTF-8", WIRESHARK_CONFIG_DIR=str(conf_dir))
    proc = subprocess.run([str(ROOT / "tools" / "vrshark-report"), "--json", "captures/" + capture], env=env,
                          cwd=str(ROOT), capture_output=True, text=True, timeout=600)
    return json.loads(proc.stdout)["captures"][0]["timeline"]


@pytest.mark.parametrize("stepped", sorted(STEPPED))
def test_report_lists_the_step_and_every_fault(conf_dir, stepped):
    """vrshark-report: the step is a warning at its frame; every other entry
    of the original on the same frame with the same severity (a deadline one
    frame later where the dissector sees it so, MOVED); no time or duration
    runs backwards."""
    original, frame = STEPPED[stepped][:2]
    got = _report(conf_dir, stepped)
    step = [e for e in got if e["field"] and e["field"].endswith(".time_backwards")]
    assert [(e["frame"], e["severity"], e["text"]) for e in step] == [
        (frame, "warning", "time went backwards (clock step): the rules restart there")]
    moved = MOVED.get(stepped, {})
    want = sorted((moved.get(e["frame"], e["frame"]), e["severity"], e["field"] or e["kind"])
                  for e in _report(conf_dir, original))
    assert sorted((e["frame"], e["severity"], e["field"] or e["kind"]) for e in got if e not in step) == want
    times = [e["time"] for e in got]
    assert times == sorted(times)
    assert all(e["duration"] is None or e["duration"] >= 0 for e in got)
