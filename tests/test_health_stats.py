"""Statistics > MC-MB2-PN and Statistics > EC-Link (lua/vrshark/health.luam):
tshark -z mcmb2,stat and -z eclink,stat print one row per device and
direction with its frames, the cycle (min / median / max of the intervals
between the stream's frames), the longest silence and the frame that ended
it, the stalls, the commands failed and the findings of the analysis by
severity (docs/profinet.md and docs/eclink-modbus.md, "Statistics"). The
rows come from the first-pass analysis: one pass and -2 print the same, with
the C plugin and with the Lua plugins alone (both phases of tools/test run
this file). Also -z eglink,stat, which the Lua-only install registers itself
(docs/eglink.md)."""
import re
from decimal import Decimal

import pytest

from conftest import ROOT
from pnio_testlib import CaptureFile, Device, mac, mcmb2_submodules
import test_eclink_modbus_realstack as rs
import test_eclink_modbus_realstack_commands as rsc

COLUMNS = ["Frames", "Cycle min (ms)", "median", "max", "Longest silence (ms)", "ended in", "Stalls", "Failed",
           "Errors", "Warnings", "Notes"]


def health(tshark, capture, kind, two_pass=False, prefs=None):
    """{(device, stream): {column: text}} of tshark -z <kind>,stat."""
    args = ["-r", str(capture), "-q", "-z", "%s,stat" % kind]
    for name, value in sorted((prefs or {}).items()):
        args += ["-o", "%s:%s" % (name, value)]
    out = tshark.run(args + (["-2"] if two_pass else [])).stdout
    lines = out.splitlines()
    title = {"mcmb2": "MC-MB2-PN health", "eclink": "EC-Link health"}[kind]
    at = next(i for i, line in enumerate(lines) if line.startswith(title))
    head = re.split(r"\s{2,}", lines[at + 1].strip())
    assert head == ["Device", "Stream"] + COLUMNS
    rows = {}
    for line in lines[at + 3:]:
        if line.startswith("="):
            break
        if line.startswith("(no "):
            continue
        cells = re.split(r"\s{2,}", line.strip())
        assert len(cells) == len(head), line
        rows[(cells[0], cells[1])] = dict(zip(COLUMNS, cells[2:]))
    return rows


def both_passes(tshark, capture, kind, prefs=None):
    one = health(tshark, capture, kind, prefs=prefs)
    assert health(tshark, capture, kind, two_pass=True, prefs=prefs) == one
    return one


def row(frames, cycle, silence, ended, stalls=0, failed=0, errors=0, warnings=0, notes=0):
    return {"Frames": str(frames), "Cycle min (ms)": cycle[0], "median": cycle[1], "max": cycle[2],
            "Longest silence (ms)": silence, "ended in": str(ended), "Stalls": str(stalls), "Failed": str(failed),
            "Errors": str(errors), "Warnings": str(warnings), "Notes": str(notes)}


def test_watchdog_stalls(tshark, capture_file):
    """Both watchdogs stall (SP-14-023 2.4): each direction one stall, an
    error, and the pace warning before it."""
    rows = both_passes(tshark, capture_file("mcmb2_duplex_watchdog.pcap"), "mcmb2")
    dev = "HMSIndus_00:00:02 FrameIDs 0x8003/0x8004"
    assert rows == {
        (dev, "uplink"): row(25, ("200.000", "200.000", "200.000"), "200.000", 5, stalls=1, errors=1, warnings=1),
        (dev, "downlink"): row(25, ("200.000", "200.000", "200.000"), "200.000", 6, stalls=1, errors=1,
                               warnings=1),
    }
    assert health(tshark, capture_file("mcmb2_duplex_watchdog.pcap"), "eclink") == {}


def test_modbus_poll_gaps_stalls_and_failed_commands(tshark, capture_file):
    """eclink_modbus_faults.pcap: two poll gaps and a PCI stall on the input
    image (TS-0007 8.3), the PCO stall on the output image (8.4); the command
    from the RU and the one to it both unacknowledged (8.1, 8.2), the first
    echoed late; the BU state change a note. The reads stop for 2.050 s
    (ended by frame 28), the writes too (frame 30)."""
    rows = both_passes(tshark, capture_file("eclink_modbus_faults.pcap"), "eclink")
    dev = "Modbus/TCP 192.168.2.41:502 unit 1"
    assert rows == {
        (dev, "input image read"): row(9, ("50.000", "125.000", "2050.000"), "2050.000", 28, stalls=3, failed=1,
                                       errors=1, warnings=4, notes=2),
        (dev, "output image written"): row(9, ("125.000", "125.000", "2050.000"), "2050.000", 30, stalls=1,
                                           failed=1, errors=1, warnings=1, notes=1),
    }


def test_healthy_eclink_pnio(tshark, capture_file):
    """A healthy EC-Link over PROFINET: the cycle, nothing else."""
    rows = both_passes(tshark, capture_file("crane_eclink_pnio.pcap"), "eclink")
    dev = "PROFINET HMSIndus_00:00:02 FrameIDs 0x8023/0x8024"
    assert rows == {
        (dev, "input"): row(4, ("125.000", "125.000", "125.000"), "125.000", 5),
        (dev, "output"): row(4, ("125.000", "125.000", "125.000"), "125.000", 6),
    }


def test_eclink_pnio_unacked_command(tshark, capture_file):
    """eclink_pnio_connect.pcap: PCI stalls (TS-0007 8.3) and PCO stalls
    (8.4), the command from the RU in frame 43 never echoed (8.1): one failed
    command on the input, counted as the two-pass tree shows it (the warning
    on the command, the note where its deadline passed) in one pass too; the
    BU state change a note."""
    rows = both_passes(tshark, capture_file("eclink_pnio_connect.pcap"), "eclink")
    dev = "PROFINET HMSIndus_00:00:02 FrameIDs 0x8010/0x8011"
    assert rows == {
        (dev, "input"): row(40, ("125.000", "125.000", "125.000"), "125.000", 5, stalls=1, failed=1, errors=1,
                            warnings=1, notes=2),
        (dev, "output"): row(40, ("125.000", "125.000", "125.000"), "125.000", 6, stalls=1, errors=1),
    }


# -- scapy PROFINET: an MC-MB2-PN whose uplink stops after a point ----------

def _uplink_removed(path, cycles=20, stop_after=8, period=0.1):
    """A duplex MC-MB2-PN (Connect, then one uplink and one downlink every
    100 ms, watchdogs counting) whose uplink frames are left out after the
    first `stop_after`: (path, frame numbers of the uplinks, of the downlinks)."""
    subs = mcmb2_submodules("duplex", 1, 2, 2, 0, 1)
    d = Device(subs, mac(0x42), 0x8042, 0xC042)
    cap = CaptureFile()
    req, res = d.connect(seq=1)
    cap.add(req)
    cap.add(res)
    ups, downs = [], []
    for i in range(cycles):
        wd = (i + 1) & 0xFF
        if i < stop_after:
            ups.append(cap.add(d.cyclic("in", {1: bytes([0x11, wd]), 2: b"\x01\x02"})))
        downs.append(cap.add(d.cyclic("out", {3: bytes([1, wd]), 4: b"\x00\x00"})))
    # (exact times: pcap keeps microseconds, a float sum drifts from them;
    # the Connect 1 ms apart, then a frame every half period while both
    # directions run, every period after)
    t = Decimal(1700000000)
    for k, p in enumerate(cap.packets):
        t += Decimal("0.001") if k < 2 else Decimal(str(period / 2 if k < 2 + 2 * stop_after else period))
        p.time = t
    cap.write(path)
    return path, ups, downs


def test_scapy_uplink_removed_after_a_point(tshark, work_dir):
    path, ups, downs = _uplink_removed(work_dir / "health_uplink_removed.pcap")
    rows = both_passes(tshark, path, "mcmb2")
    dev = "02:00:00:00:00:42 FrameIDs 0x8042/0xc042"
    # the stream that stopped: counted as a stall once mcmb2.uplink_missing exists
    missing = int("mcmb2.uplink_missing" in (ROOT / "lua" / "mcmb2.lua").read_text())
    assert rows == {
        (dev, "uplink"): row(8, ("100.000", "100.000", "100.000"), "100.000", ups[1], stalls=missing,
                             errors=missing),
        (dev, "downlink"): row(20, ("100.000", "100.000", "100.000"), "100.000", downs[1]),
    }
    assert len(ups) == 8 and len(downs) == 20


# -- pymodbus: a real BU server and PLC on 127.0.0.1 ------------------------

@pytest.fixture(scope="module")
def commands_capture():
    yield from rs.captured("commands", rsc._plc)


def test_pymodbus_commands(tshark, commands_capture):
    """The pymodbus BU sends CCI 6 and CCI 7; the PLC echoes 6 only, 2.6 s late
    (tests/test_eclink_modbus_realstack_commands.py): both commands failed,
    the late echo a warning; as many reads and writes as the PLC logged."""
    cap, log = commands_capture
    rows = both_passes(tshark, cap, "eclink", prefs=rs.PREFS)
    dev = "Modbus/TCP 127.0.0.1:%d unit 1" % rs.PORT
    inp, out = rows[(dev, "input image read")], rows[(dev, "output image written")]
    assert set(rows) == {(dev, "input image read"), (dev, "output image written")}
    # (the heuristic takes the connection for a candidate from the first
    # input image on, which the first read's response carries: docs/eclink-modbus.md)
    assert int(inp["Frames"]) == len(log["read"]) - 1
    assert int(out["Frames"]) == len(log["written"])
    assert inp["Failed"] == "2" and out["Failed"] == "0"
    # the two "not acknowledged" warnings and the late echo
    assert inp["Warnings"] == "3"
    assert inp["Errors"] == "0" and out["Errors"] == "0"
    # the PLC polls every 50 ms plus its own round trips
    assert 45 <= float(inp["median"]) <= 200


# -- -z eglink,stat without the C plugin ------------------------------------

def test_eglink_stat(tshark, capture_file):
    """-z eglink,stat in both installs (the C plugin's in the full install,
    vrshark/eglink_analysis.luam's without it): the unacknowledged VRCI of
    eglink_analysis_vrci_unacked.pcap is one failed command."""
    cap = capture_file("eglink_analysis_vrci_unacked.pcap")
    for two_pass in (False, True):
        out = tshark.run(["-r", str(cap), "-q", "-z", "eglink,stat"] + (["-2"] if two_pass else [])).stdout
        lines = [line for line in out.splitlines() if line.strip()]
        assert lines[1] == "EG-Link:"
        counts = {}
        for line in lines:
            m = re.match(r"^\s*(\S.*?)\s{2,}(\d+)", line)
            if m:
                counts.setdefault(m.group(1), int(m.group(2)))
        assert counts["EG-Link base units"] == 67
        assert counts["VRCI commands (BU to controller)"] == 1
        assert counts["Failed (not acknowledged in time)"] == 1
        assert out.count("EG-Link:") == 1
