"""vrshark-report: exact safety timelines of the fault captures, the devices
found, the text output, the gate and its exit codes, JSON, JUnit, bad input.

Each run goes through tools/vrshark-report (and so tools/tshark) with the
hermetic configuration of the other tests; runs are cached by arguments.
"""
import json
import os
import shutil
import subprocess
import sys
import xml.etree.ElementTree as ET

import pytest

from conftest import CAPTURES, ROOT

REPORT = ROOT / "tools" / "vrshark-report"
sys.path.insert(0, str(ROOT / "tools"))
from report import catalog, rows as report_rows  # noqa: E402

# Fields of plugins newer than some installs: a report asks for them only
# when the tshark knows them.
OPTIONAL = set(catalog.CANDIDATE_SETTINGS) | set(catalog.CANDIDATE_SETTINGS.values())


@pytest.fixture(scope="session")
def report(conf_dir):
    """report(*args) -> CompletedProcess of tools/vrshark-report ARGS (cwd: the checkout)."""
    cache = {}
    env = dict(os.environ, TZ="UTC", LC_ALL="C.UTF-8", WIRESHARK_CONFIG_DIR=str(conf_dir))

    def run(*args):
        key = tuple(str(a) for a in args)
        if key not in cache:
            cache[key] = subprocess.run([str(REPORT)] + list(key), env=env, cwd=str(ROOT),
                                        capture_output=True, text=True, timeout=600)
        return cache[key]
    return run


def as_json(proc):
    return json.loads(proc.stdout)


def timeline(report, name, *args):
    """(frame, severity, device, text) of each entry; name: a capture under captures/ or a path."""
    doc = as_json(report("--json", *args, name if "/" in str(name) else "captures/" + name))
    return [(e["frame"], e["severity"], e["device"], e["text"]) for e in doc["captures"][0]["timeline"]]


def failed(frame, field, warning, note):
    """A failed command's entry: the report lists the plugin's warning (field)
    where one pass gives it (at the first frame past the deadline), else the
    note that the deadline passed (a plugin that gives the warning on the
    second pass only)."""
    return (frame, "failed", 1, (field, warning, note))


@pytest.fixture(scope="session")
def one_pass_failure(tshark):
    """one_pass_failure(capture, field, frame): whether one pass puts the failed
    command's warning on that frame."""
    def check(name, field, frame):
        return str(frame) in tshark.field(CAPTURES / name, "frame.number", display_filter=field)
    return check


def expected(name, one_pass_failure):
    out = []
    for f, sev, d, texts in TIMELINES[name]:
        if sev == "failed":
            field, warning, note = texts
            out.append((f, "warning", d, warning) if one_pass_failure(name, field, f) else (f, "note", d, note))
        else:
            out.append((f, sev, d, texts))
    return out


# (frame, severity, device, text) of every timeline entry, in order.
TIMELINES = {
    "eglink_analysis_session.pcap": [
        (1, 'warning', 1, 'ES-Link relays open (BU state Initial) for 0.500 s, closed in frame 10'),
        (10, 'note', 1, 'BU state Initial -> Disarmed (after 0.500 s or more)'),
        (19, 'note', 1, 'BU state Disarmed -> Armed (after 0.500 s)'),
        (19, 'note', 1, 'RU state Initial (no RU armed) -> Enabled (RU 0xbeef) (after 1.000 s or more)'),
        (26, 'note', 1, 'command retransmitted: first sent in frame 23'),
        (32, 'warning', 1, '1 packet lost'),
        (41, 'note', 1, 'BU state Armed -> Stopped (after 1.000 s)'),
        (41, 'note', 1, 'RU 0xbeef state Enabled -> Stopped (after 1.000 s)'),
        (41, 'warning', 1, 'ES-Link relays open (BU state Stopped) for 0.500 s, closed in frame 52'),
        (52, 'note', 1, 'BU state Stopped -> Armed (after 0.500 s)'),
        (52, 'note', 1, 'RU 0xbeef state Stopped -> Enabled (after 0.500 s)'),
    ],
    "eglink_states.pcap": [
        (1, 'warning', 1, 'ES-Link relays open (BU state Initial) for 0.625 s, closed in frame 6'),
        # links No link (1), Link error, Interface error, Data error (3)
        (1, 'warning', 1, 'a link reports a fault (2x, frames 1-3 over 0.250 s)'),
        (2, 'note', 1, 'BU state Initial -> Stopped (after 0.125 s or more)'),
        (2, 'note', 1, 'RU state Initial (no RU armed) -> Stopped (RU 0xbeef) (after 0.125 s or more)'),
        (3, 'note', 1, 'BU state Stopped -> External link error (after 0.125 s)'),
        (3, 'note', 1, 'RU state Stopped (RU 0xbeef) -> Initial (no RU armed) (after 0.125 s)'),
        (4, 'note', 1, 'BU state External link error -> Blocked (after 0.125 s)'),
        (5, 'note', 1, 'BU state Blocked -> Failed (after 0.125 s)'),
        (6, 'note', 1, 'BU state Failed -> Disarmed (after 0.125 s)'),
        (7, 'note', 1, 'BU state Disarmed -> Armed (after 0.125 s)'),
        (7, 'note', 1, 'RU state Initial (no RU armed) -> Initial (RU 0xbeef) (after 0.500 s)'),
        # RU 0xbeef armed, RU state Initial (TS-0006 4.1.3)
        (7, 'warning', 1, 'status fields contradict each other'),
        (8, 'note', 1, 'RU 0xbeef state Initial -> Disarmed (after 0.125 s)'),
        (8, 'note', 1, 'RU state Disarmed (used inside the BU only) on the wire'),
        (9, 'note', 1, 'RU 0xbeef state Disarmed -> Armed (after 0.125 s)'),
        (12, 'note', 1, 'RU 0xbeef state Armed -> Enabled (after 0.375 s)'),
        (13, 'warning', 1, 'link status Passive where it is not allowed'),
    ],
    "eglink_analysis_vrpo_gap.pcap": [
        (35, 'note', 1, 'BU state Armed -> External link error (after 3.000 s or more)'),
        (35, 'warning', 1, 'ES-Link relays open (BU state External link error) for 0.750 s, closed in frame 44'),
        (35, 'error', 1, 'no VRPO for 2.600 s (after frame 18, limit 2000 ms), received again in frame 40'),
        (44, 'note', 1, 'BU state External link error -> Armed (after 0.750 s)'),
    ],
    "eglink_analysis_lost.pcap": [
        (13, 'warning', 1, '3 packets lost (2x, frames 13-15 over 0.190 s)'),
    ],
    "eglink_analysis_repeated.pcap": [
        (9, 'warning', 1, 'repeated packet (2x, frames 9-15 over 0.325 s)'),
    ],
    "eglink_analysis_vrci_unacked.pcap": [
        (8, 'note', 1, 'command retransmitted: first sent in frame 5 (19x, frames 8-58 over 1.800 s)'),
        failed(61, 'eglink.analysis.vrci_unacked',
               'VRCI of frame 5 not acknowledged in time: the command failed',
               'deadline of the VRCI of frame 5 passed'),
    ],
    "eglink_analysis_vrco_unacked.pcap": [
        (8, 'note', 1, 'command retransmitted: first sent in frame 5 and 1 other value '
         '(38x, frames 8-120 over 4.100 s)'),
        failed(61, 'eglink.analysis.vrco_unacked',
               'VRCO of frame 5 not acknowledged in time: the command failed',
               'deadline of the VRCO of frame 5 passed'),
        failed(123, 'eglink.analysis.vrco_unacked',
               'VRCO of frame 67 not acknowledged in time: the command failed',
               'deadline of the VRCO of frame 67 passed'),
        (128, 'warning', 1, 'command 5 acknowledged after 2.300 s (late)'),
    ],
    "eglink_analysis_vrpi_gap.pcap": [
        (16, 'error', 1, 'no VRPI for 0.875 s (after frame 10, limit 500 ms), received again in frame 20'),
    ],
    "eglink_bad_crc.pcap": [
        (1, 'error', 1, 'bad CRC (6x, frames 1-6 over 0.050 s)'),
    ],
    "eglink_analysis_two_bus.pcap": [
        (27, 'warning', 2, '1 packet lost'),
    ],
    "eclink_modbus_faults.pcap": [
        (21, 'warning', 1, 'no input image for 0.700 s (after frame 17, limit 500 ms)'),
        (21, 'error', 1, 'PCI stalled at 2 for 0.825 s (unchanged since frame 17, limit 500 ms), moving again in frame 25'),
        failed(28, 'eclink_modbus.cmd_from_ru.late',
               'command from RU of frame 17 not echoed by CAO in time: the command failed, the BU shows "EC: Bad data"',
               'deadline of the command from RU of frame 17 passed'),
        failed(28, 'eclink_modbus.cmd_to_ru.late',
               'command to RU of frame 18 not echoed by CAI in time: the command failed',
               'deadline of the command to RU of frame 18 passed'),
        (29, 'warning', 1, 'no input image for 2.050 s (after frame 25, limit 500 ms)'),
        (30, 'error', 1, 'PCO stalled at 4 for 2.175 s (unchanged since frame 26, limit 2000 ms: the BU shows "EC: Bad data"), moving again in frame 34'),
        (34, 'warning', 1, 'command from RU of frame 17 echoed by CAO late (after 3.007 s): the BU shows "EC: Bad data"'),
        (37, 'note', 1, 'RU 0x1234 state Enabled -> undefined 0x05 (after 3.250 s or more)'),
        (37, 'error', 1, 'VLAPs out of range: 4'),
        (37, 'error', 1, 'undefined link status: EG-Link status 0x07'),
        (37, 'error', 1, 'undefined RU state 0x05'),
        (37, 'error', 1, 'percentage over 100: RU battery 101 %'),
        (37, 'error', 1, 'flag not 0 or 1: RU cable 0x02'),
        (37, 'error', 1, 'undefined RU disabled reason 0x04'),
        (37, 'error', 1, 'joystick out of range: joystick 1 at 1001'),
        (37, 'warning', 1, 'spare not 0: bytes 00010000 and 1 other value (2x, frames 37-40 over 0.097 s)'),
        (39, 'note', 1, 'BU state Armed -> undefined 0x42 (after 3.300 s or more)'),
        (39, 'note', 1, 'RU state undefined 0x05 (RU 0x1234) -> Initial (no RU armed) (after 0.050 s)'),
        (39, 'error', 1, 'undefined BU state 0x42'),
        (39, 'error', 1, 'RU fields not 0 while no RU is armed'),
        (40, 'error', 1, 'periodic data size over 51200: 60000 bytes'),
    ],
    "eclink_pnio_connect.pcap": [
        # the Disarmed BU's images name RU 0x1234 (TS-0007 6.1.1)
        (3, 'warning', 1, 'status fields contradict each other (2x, frames 3-5 over 0.125 s)'),
        (7, 'note', 1, 'BU state Disarmed -> Armed (after 0.250 s or more)'),
        (31, 'error', 1, 'PCI stalled at 10 for 0.875 s (unchanged since frame 21, limit 500 ms), moving again in frame 35'),
        (72, 'error', 1, 'PCO stalled at 18 for 2.625 s (unchanged since frame 38, limit 2000 ms: the BU shows "EC: Bad data"), moving again in frame 80'),
        failed(76, 'eclink_pnio.cmd_from_ru.late',
               'command from RU of frame 43 not echoed by CAO in time: the command failed, the BU shows "EC: Bad data"',
               'deadline of the command from RU of frame 43 passed'),
    ],
    "mcmb2_polled_connect.pcap": [
        (5, 'note', 1, 'slot 2 terminal 2 present -> terminal 2 absent (after 0.100 s or more)'),
        (7, 'note', 1, 'slot 2 terminal 2 absent -> terminal 5 present (after 0.100 s)'),
        (9, 'note', 1, 'slot 3 terminal 3 present -> terminal 3 undefined 0x03 (after 0.300 s or more)'),
        (9, 'error', 1, 'undefined slot status 0x03 in slot 3'),
        (11, 'note', 1, 'status normal mode -> undefined 0x01 (after 0.400 s or more)'),
        (11, 'note', 1, 'slot 3 terminal 3 undefined 0x03 -> terminal 3 present (after 0.100 s)'),
        (11, 'error', 1, 'undefined status 0x01'),
        (13, 'note', 1, 'status undefined 0x01 -> fieldbus update failure (E010) (after 0.100 s)'),
        (13, 'note', 1, 'slot 1 terminal 1 present -> terminal 1 absent (after 0.500 s or more)'),
        (13, 'note', 1, 'slot 2 terminal 5 present -> terminal 5 absent (after 0.300 s)'),
        (13, 'note', 1, 'slot 3 terminal 3 present -> terminal 3 absent (after 0.100 s)'),
        (13, 'error', 1, 'E010 reported by the base'),
        (15, 'note', 1, 'status fieldbus update failure (E010) -> normal mode (after 0.100 s)'),
        (15, 'note', 1, 'slot 1 terminal 1 absent -> terminal 1 present (after 0.100 s)'),
        (15, 'note', 1, 'slot 2 terminal 5 absent -> terminal 5 present (after 0.100 s)'),
        (15, 'note', 1, 'slot 3 terminal 3 absent -> terminal 3 present (after 0.100 s)'),
        (15, 'error', 1, 'Y, Z or slots differ from the configured layout: the frame has Y=20, Z=10'),
        (17, 'note', 1, 'slot 2 terminal 5 present -> terminal 5 active stop (after 0.100 s)'),
        (17, 'warning', 1, 'terminal bits set in a polled status: terminal 2'),
        (17, 'warning', 1, 'data not 0 while the terminal is not present'),
        (18, 'warning', 1, 'reserved byte not 0: 0x05'),
    ],
    "mcmb2_duplex_watchdog.pcap": [
        (17, 'warning', 1, 'uplink watchdog not incremented within 500 ms'),
        (18, 'warning', 1, 'downlink watchdog not incremented within 500 ms'),
        (23, 'error', 1, 'uplink watchdog stalled at 5 for 1.600 s (unchanged since frame 11, limit 1000 ms), moving again in frame 27'),
        (34, 'error', 1, 'downlink watchdog stalled at 5 for 2.600 s (unchanged since frame 12, limit 2000 ms: the base shows E010), moving again in frame 38'),
    ],
    "mcmb2_duplex_connect.pcap": [
        (3, 'warning', 1, 'no valid terminal data (3x, frames 3-11 over 0.400 s)'),
        (5, 'note', 1, 'status absent -> blocked (after 0.100 s or more)'),
        (7, 'note', 1, 'status blocked -> present (after 0.100 s)'),
        (9, 'warning', 1, 'IOPS not GOOD: 0x00'),
        (11, 'note', 1, 'status present -> active stop (after 0.200 s)'),
        (11, 'warning', 1, 'data not 0 while the terminal is not present'),
        (13, 'note', 1, 'status active stop -> fieldbus update failure (E010) (after 0.100 s)'),
        (13, 'error', 1, 'E010 reported by the base'),
        (15, 'note', 1, 'status fieldbus update failure (E010) -> present (after 0.100 s)'),
        (16, 'warning', 1, 'IOCS not GOOD: 0x60'),
        (17, 'note', 1, 'status present -> undefined 0x03 (after 0.100 s)'),
        (17, 'error', 1, 'undefined status 0x03 and 10 other values (11x, frames 17-37 over 1.000 s)'),
        (19, 'note', 1, 'status undefined 0x03 -> undefined 0x04 (after 0.100 s)'),
        (21, 'note', 1, 'status undefined 0x04 -> undefined 0x05 (after 0.100 s)'),
        (23, 'note', 1, 'status undefined 0x05 -> undefined 0x06 (after 0.100 s)'),
        (25, 'note', 1, 'status undefined 0x06 -> undefined 0x08 (after 0.100 s)'),
        (27, 'note', 1, 'status undefined 0x08 -> undefined 0x09 (after 0.100 s)'),
        (29, 'note', 1, 'status undefined 0x09 -> undefined 0x0B (after 0.100 s)'),
        (31, 'note', 1, 'status undefined 0x0B -> undefined 0x0C (after 0.100 s)'),
        (33, 'note', 1, 'status undefined 0x0C -> undefined 0x0D (after 0.100 s)'),
        (35, 'note', 1, 'status undefined 0x0D -> undefined 0x0E (after 0.100 s)'),
        (37, 'note', 1, 'status undefined 0x0E -> undefined 0x0F (after 0.100 s)'),
    ],
    "eglink_header.pcap": [
        (1, 'warning', 1, 'unknown layout revision 1'),
        # TS-0006 5.1.5: the packet of revision 1 is kept out of the analysis, so the
        # BU's origin is first known from frame 5 (0), and changes at frame 7
        (1, 'note', 1, 'packet of another header revision not analysed'),
        (2, 'warning', 1, 'origin not 0 in a controller packet: 0x1001 and 2 other values '
         '(3x, frames 2-4 over 0.020 s)'),
        (5, 'warning', 1, 'origin 0 in a BU packet (2x, frames 5-6 over 0.010 s)'),
        (7, 'warning', 1, 'header spare not 0: 0x00000100'),
        (7, 'warning', 1, 'another origin at the same BU address: 0x1001'),
        (8, 'warning', 1, 'payload spare not 0: bytes 00ff0000 and 1 other value (2x, frames 8-9 over 0.010 s)'),
    ],
}


@pytest.mark.parametrize("name", sorted(TIMELINES))
def test_timeline(report, one_pass_failure, name):
    assert timeline(report, name) == expected(name, one_pass_failure)


def test_devices_two_bus(report):
    devs = as_json(report("--json", "captures/eglink_analysis_two_bus.pcap"))["captures"][0]["devices"]
    got = [(d["id"], d["kind"], d["name"], d["frames"], d["first_frame"], d["last_frame"],
            d["layout"], d["initial"]) for d in devs]
    assert got == [
        (1, "eglink", "EG-Link BU 0x1001 (192.168.32.10 to 239.255.42.20:5825)", 20, 1, 38,
         "TS-0006 on UDP ports 5825, 5827: by port",
         {"BU state": "Armed", "RU state": "Enabled (RU 0xbeef)"}),
        (2, "eglink", "EG-Link BU 0x1002 (192.168.32.11 to 239.255.42.21:5825)", 19, 2, 39,
         "TS-0006 on UDP ports 5825, 5827: by port",
         {"BU state": "Disarmed", "RU state": "Initial (no RU armed)"}),
    ]
    assert devs[0]["address"] == {"group": "239.255.42.20", "port": 5825, "origin": "0x1001",
                                  "bu": "192.168.32.10", "controller": "192.168.32.20",
                                  "ports": [5825, 5827]}


def test_devices_mcmb2_terminals(report):
    dev = as_json(report("--json", "captures/mcmb2_polled_connect.pcap"))["captures"][0]["devices"][0]
    assert (dev["name"], dev["layout"], dev["frames"]) == (
        "MC-MB2-PN polled base 00:30:11:00:00:02", "Connect in frame 1", 16)
    assert [(t["terminal"], t["slots"], t["first_frame"], t["last_frame"], t["frames"])
            for t in dev["terminals"]] == [(1, [1], 3, 17, 8), (2, [2], 3, 5, 2),
                                           (3, [3], 3, 17, 8), (5, [2], 7, 17, 6)]
    assert dev["final"]["slot 2"] == "terminal 5 active stop"


@pytest.mark.parametrize("name, kind, device, layout", [
    ("eclink_modbus_faults.pcap", "eclink_modbus", "EC-Link BU, Modbus/TCP server 192.168.2.41:502",
     "heuristic, recognised in frame 13"),
    ("eclink_pnio_connect.pcap", "eclink_pnio", "EC-Link BU, PROFINET device 00:30:11:00:00:02",
     "Connect in frame 1"),
    ("mcmb2_duplex_watchdog.pcap", "mcmb2", "MC-MB2-PN duplex base 00:30:11:00:00:02",
     "Connect in frame 1"),
    ("eglink_heuristic.pcap", "eglink", "EG-Link BU 0x1001 (192.168.32.10 to 239.255.42.20:6100)",
     "TS-0006 on UDP ports 6100, 6102: heuristic"),
])
def test_device_names_and_layouts(report, name, kind, device, layout):
    devs = as_json(report("--json", "captures/" + name))["captures"][0]["devices"]
    assert [(d["kind"], d["name"], d["layout"]) for d in devs] == [(kind, device, layout)]


def test_preference_changes_limit(report):
    """-o goes to tshark and to the report's own limits."""
    got = timeline(report, "eglink_analysis_vrpi_gap.pcap", "-o", "eglink.vrpi_gap_ms:300")
    assert (16, "warning", 1, "no VRPI for 0.875 s (after frame 10, limit 300 ms), "
            "received again in frame 20") not in got
    assert any("limit 300 ms" in text for _, _, _, text in got)


def test_decode_as(report):
    # without it: a candidate, with the setting under which its traffic is judged
    without = as_json(report("--json", "captures/eclink_modbus_port5020.pcap"))["captures"][0]
    assert [(d["kind"], d["address"]) for d in without["devices"]] == [
        ("candidate", {"server": "192.168.2.41", "port": 5020, "setting": "eclink_modbus.port:502,5020"})]
    with_rule = as_json(report("--json", "-d", "tcp.port==5020,eclink_modbus",
                               "captures/eclink_modbus_port5020.pcap"))["captures"][0]
    assert [d["name"] for d in with_rule["devices"]] == ["EC-Link BU, Modbus/TCP server 192.168.2.41:5020"]


# --- text output and the gate ---------------------------------------------------

VRPO_GAP_TEXT = """\
== captures/eglink_analysis_vrpo_gap.pcap
56 frames, 4.440 s from 2026-01-01 00:00:00.000 UTC
1 device:
  [1] EG-Link BU 0x1001 (192.168.32.10 to 239.255.42.20:5825)
      frames 1-56 (56), 0.000 s to 4.440 s; layout: TS-0006 on UDP ports 5825, 5827: by port
      first: BU state Armed, RU state Enabled (RU 0xbeef)
health (per stream; cycle: the intervals between its frames):
  device  stream           frames  cycle ms min / median / max  longest silence      stalls  failed  findings E/W/N
  [1]     BU VRPI              36        125.0 / 125.0 / 125.0  0.125 s to frame 3        0       0           0/1/0
  [1]     controller VRPO      20       100.0 / 100.0 / 2600.0  2.600 s to frame 40       1       0           1/0/0
timeline (4 entries: 1 error, 1 warning, 2 note; seconds from the first frame):
      time   frame  severity  device
     3.000      35  note      [1]  BU state Armed -> External link error (after 3.000 s or more)
     3.000      35  warning   [1]  ES-Link relays open (BU state External link error) for 0.750 s, closed in frame 44
     3.000      35  error     [1]  no VRPO for 2.600 s (after frame 18, limit 2000 ms), received again in frame 40
     3.750      44  note      [1]  BU state External link error -> Armed (after 0.750 s)
"""


def test_text_output(report):
    proc = report("captures/eglink_analysis_vrpo_gap.pcap")
    assert (proc.returncode, proc.stdout, proc.stderr) == (0, VRPO_GAP_TEXT, "")


def test_faults_gate_warn(report, one_pass_failure):
    """The acceptance run: one timeline per capture, exit 1, one line saying why."""
    captures = sorted(str(p.relative_to(ROOT)) for p in CAPTURES.glob("*faults*.pcap"))
    proc = report(*captures, "--fail-on", "warn")
    assert proc.returncode == 1
    assert [ln for ln in proc.stdout.splitlines() if ln.startswith("== ")] == \
        ["== " + c for c in captures]
    assert "     1.178      21  error     [1]  PCI stalled at 2 for 0.825 s (unchanged since " \
        "frame 17, limit 500 ms), moving again in frame 25" in proc.stdout.splitlines()
    assert proc.stderr.splitlines() == [
        "vrshark-report: FAIL (--fail-on warn): %d finding(s) at warning or above; first: "
        "captures/eclink_modbus_faults.pcap frame 21: no input image for 0.700 s (after frame 17, "
        "limit 500 ms)" % (16 + sum(one_pass_failure("eclink_modbus_faults.pcap", field, 28) for field in
                                    ("eclink_modbus.cmd_from_ru.late", "eclink_modbus.cmd_to_ru.late")))]


@pytest.mark.parametrize("gate, status", [(None, 0), ("note", 1), ("warn", 1), ("error", 1)])
def test_gate_levels(report, gate, status):
    """eglink_analysis_vrpo_gap has notes, warnings and an error (the VRPO gap)."""
    args = ["--fail-on", gate] if gate else []
    proc = report(*args, "captures/eglink_analysis_vrpo_gap.pcap")
    assert proc.returncode == status
    assert len(proc.stderr.splitlines()) == status


def test_clean_capture_passes_every_gate(report):
    proc = report("--fail-on", "note", "captures/eglink_armed.pcap")
    assert proc.returncode == 0, proc.stderr
    assert "timeline: no state change and no finding" in proc.stdout


def test_no_vrshark_traffic(report):
    proc = report("--fail-on", "note", "captures/modbus_plain_devices.pcap")
    assert proc.returncode == 0
    assert proc.stdout.splitlines()[-1] == "  no EG-Link, EC-Link or MC-MB2-PN traffic found"
    doc = as_json(report("--json", "captures/modbus_plain_devices.pcap"))
    assert doc["captures"][0]["frames"] == 113
    assert doc["captures"][0]["devices"] == [] and doc["captures"][0]["timeline"] == []


@pytest.mark.parametrize("args", [[], ["--fail-on", "warning2", "captures/eglink_armed.pcap"],
                                  ["--no-such-option", "captures/eglink_armed.pcap"]])
def test_usage_errors(report, args):
    proc = report(*args)
    assert proc.returncode == 2
    assert proc.stdout == "" and "usage: vrshark-report" in proc.stderr


def test_several_captures_in_order(report):
    names = ["captures/mcmb2_duplex_watchdog.pcap", "captures/eglink_bad_crc.pcap",
             "captures/eclink_pnio_connect.pcap"]
    doc = as_json(report("--json", "-j", "2", *names))
    assert [c["capture"] for c in doc["captures"]] == names
    assert doc["exit_status"] == 0 and doc["schema"] == 1


# --- bad input ------------------------------------------------------------------------

@pytest.fixture(scope="module")
def bad_files(tmp_path_factory):
    d = tmp_path_factory.mktemp("report-bad")
    good = (CAPTURES / "eglink_armed.pcap").read_bytes()
    (d / "truncated.pcap").write_bytes(good[:3000])
    (d / "text.pcap").write_text("this is not a capture\n")
    (d / "empty.pcap").write_bytes(b"")
    (d / "header.pcap").write_bytes(good[:10])
    shutil.copy(CAPTURES / "eglink_bad_crc.pcap", d / "ok.pcap")
    return d


def test_bad_input(report, bad_files):
    names = ["missing.pcap", "text.pcap", "ok.pcap", "empty.pcap", "header.pcap", "truncated.pcap"]
    proc = report(*[bad_files / n for n in names])
    assert proc.returncode == 2
    assert proc.stderr.splitlines() == ["vrshark-report: %s: %s" % (bad_files / n, msg) for n, msg in [
        ("missing.pcap", "no such file"),
        ("text.pcap", "not a capture file (pcap or pcapng expected)"),
        ("empty.pcap", "empty file, not a capture"),
        ("header.pcap", "truncated: the file ends before its first packet"),
        ("truncated.pcap", "truncated: the capture ends in the middle of a packet (after frame 22)"),
    ]]
    # The readable captures still report, the truncated one up to its cut.
    assert "  [1] EG-Link BU 0x1001 (192.168.32.10 to 239.255.42.20:5825)" in proc.stdout
    assert "     0.000       1  error     [1]  bad CRC (6x, frames 1-6 over 0.050 s)" in proc.stdout
    assert "22 frames, 1.140 s from 2026-01-01 00:00:00.000 UTC" in proc.stdout


def test_bad_input_wins_over_findings(report, bad_files):
    proc = report("--fail-on", "note", bad_files / "ok.pcap", bad_files / "missing.pcap")
    assert proc.returncode == 2
    assert len(proc.stderr.splitlines()) == 2  # the unreadable capture and the gate


def test_directory(report, tmp_path):
    proc = report(tmp_path)
    assert proc.returncode == 2
    assert proc.stderr == "vrshark-report: %s: is a directory, not a capture file\n" % tmp_path


def test_tshark_without_plugins(report, tmp_path):
    """A tshark that lacks the plugins is named in one line, exit 2."""
    proc = subprocess.run([str(REPORT), "--tshark", "/usr/bin/tshark", "captures/eglink_armed.pcap"],
                          cwd=str(ROOT), capture_output=True, text=True,
                          env=dict(os.environ, HOME=str(tmp_path), WIRESHARK_CONFIG_DIR=str(tmp_path)))
    assert proc.returncode == 2
    assert proc.stderr == ("vrshark-report: captures/eglink_armed.pcap: /usr/bin/tshark does not "
                           "know the eglink, eclink and mcmb2 fields: install the vrshark plugins "
                           "(cmake --install) or choose a tshark with --tshark\n")


def test_unknown_field_is_left_out(monkeypatch):
    """A field an older plugin does not register: its column stays empty, the rest is read."""
    fields = list(report_rows.ALL_FIELDS)
    col = fields.index("eglink.command_id")
    fields[col] = "eglink.no_such_field"
    monkeypatch.setattr(report_rows, "ALL_FIELDS", fields)
    cmd, env = report_rows.tshark_command()
    rows = report_rows.Rows(CAPTURES / "eglink_armed.pcap", cmd, env=env)
    got = list(rows)
    assert "eglink.no_such_field" in rows.unknown and rows.error is None
    assert set(rows.unknown) <= {"eglink.no_such_field"} | OPTIONAL
    assert len(got) == 58
    assert all(r[col] == "" for r in got)
    assert got[24][report_rows.COL["eglink.type"]] == "VRCI"


def test_piped_output_has_no_progress_bar(report):
    proc = report("captures/eglink_analysis_vrci_unacked.pcap")
    assert "\r" not in proc.stderr and "[" not in proc.stderr


# --- JSON and JUnit ---------------------------------------------------------------------

def test_json_schema(report):
    doc = as_json(report("--json", "--fail-on", "error", "captures/mcmb2_duplex_watchdog.pcap"))
    assert set(doc) == {"schema", "fail_on", "expect", "exit_status", "captures"}
    assert (doc["fail_on"], doc["expect"], doc["exit_status"]) == ("error", [], 1)
    cap = doc["captures"][0]
    assert set(cap) == {"capture", "error", "frames", "tcp_frames", "held", "start", "start_epoch",
                        "duration", "devices", "timeline", "counts", "missing"}
    assert (cap["frames"], cap["tcp_frames"]) == (52, 0)
    # (its two UDP frames are the Connect: PNIO-CM, no UDP that EG-Link could be on)
    assert cap["held"] == {"udp": {"frames": 0, "cut": 0}, "pnio_cm": {"frames": 2, "cut": 0}, "tcp": {"frames": 0, "cut": 0, "cut_ports": []},
                           "profinet": {"frames": 50, "cut": 0, "undecoded": 0, "frame_ids": [],
                                        "connect_cut": None},
                           "snaplen": None}
    # the two watchdog pace warnings (frames 17, 18), the two stalls
    assert cap["counts"] == {"note": 0, "warning": 2, "error": 2}
    assert set(cap["devices"][0]) == {"id", "kind", "name", "address", "layout", "frames",
                                      "first_frame", "last_frame", "start", "end", "initial",
                                      "final", "not_captured", "streams", "terminals"}
    assert cap["devices"][0]["streams"][0] == {
        "stream": "uplink 0x8003", "frames": 25, "first_frame": 3, "last_frame": 51, "limit_ms": 1000,
        "cycle_ms": {"min": 200.0, "median": 200.0, "max": 200.0},
        "longest_silence": {"s": 0.2, "frame": 5}, "stalls": 1, "commands_failed": 0,
        "findings": {"error": 1, "warning": 1, "note": 0}}
    stall = cap["timeline"][3]
    assert stall == {"time": 3.201, "frame": 34, "device": 1, "severity": "error", "kind": "stall",
                     "field": "mcmb2.downlink_watchdog.stalled", "text": stall["text"], "count": 1,
                     "last_frame": 34, "duration": 2.6, "end_frame": 38, "end_time": 3.601}


def test_junit(report, tmp_path, bad_files):
    out = tmp_path / "report.xml"
    proc = report("--junit", out, "--fail-on", "warn", "captures/eglink_analysis_two_bus.pcap",
                  "captures/eglink_armed.pcap", bad_files / "text.pcap",
                  "captures/modbus_plain_devices.pcap")
    assert proc.returncode == 2
    root = ET.parse(out).getroot()
    assert root.tag == "testsuites"
    assert (root.get("tests"), root.get("failures"), root.get("errors")) == ("5", "1", "1")
    suites = root.findall("testsuite")
    assert [s.get("name") for s in suites] == ["captures/eglink_analysis_two_bus.pcap",
                                               "captures/eglink_armed.pcap", str(bad_files / "text.pcap"),
                                               "captures/modbus_plain_devices.pcap"]
    cases = suites[0].findall("testcase")
    assert [c.get("name") for c in cases] == [
        "EG-Link BU 0x1001 (192.168.32.10 to 239.255.42.20:5825)",
        "EG-Link BU 0x1002 (192.168.32.11 to 239.255.42.21:5825)"]
    assert cases[0].find("failure") is None
    failure = cases[1].find("failure")
    assert failure.get("message") == "1 finding(s) at or above warning; first in frame 27: 1 packet lost"
    assert failure.text == "frame 27  0.635 s  warning  1 packet lost"
    error = suites[2].find("testcase/error")
    assert error.get("message") == "not a capture file (pcap or pcapng expected)"
    assert suites[3].find("testcase").get("name") == "no vrshark traffic"


@pytest.mark.parametrize("name, frames, want", [
    ("mcmb2_duplex_watchdog.pcap", "1-25", [
        (17, "warning", 1, "uplink watchdog not incremented within 500 ms"),
        (18, "warning", 1, "downlink watchdog not incremented within 500 ms"),
        (23, "error", 1, "uplink watchdog stalled at 5 for 1.400 s or more (unchanged since frame 11, "
         "limit 1000 ms), until the end of the capture")]),
    ("eglink_analysis_vrpo_gap.pcap", "1-38", [
        # (the VRPO stopped at frame 18, 2.435 s before the cut capture ends: past its 2000 ms)
        (18, "error", 1, "controller VRPO: last frame 18 at 0.940 s; the capture goes on 2.435 s without it "
         "(limit 2000 ms)"),
        (35, "note", 1, "BU state Armed -> External link error (after 3.000 s or more)"),
        (35, "warning", 1, "ES-Link relays open (BU state External link error) for 0.375 s or more, "
         "until the end of the capture"),
        (35, "error", 1, "no VRPO for 2.435 s or more (after frame 18, limit 2000 ms), "
         "until the end of the capture")]),
])
def test_open_at_the_end(report, tmp_path, name, frames, want):
    """A relay, stall or gap still open when the capture ends: its length so far."""
    cut = tmp_path / name
    subprocess.run(["editcap", "-r", str(CAPTURES / name), str(cut), frames], check=True)
    doc = as_json(report("--json", cut))
    assert [(e["frame"], e["severity"], e["device"], e["text"])
            for e in doc["captures"][0]["timeline"]] == want
    assert all(e["end_frame"] is None for e in doc["captures"][0]["timeline"] if e["kind"] != "state")


def test_pcapng_and_gzip(report, tmp_path):
    ng, gz = tmp_path / "crc.pcapng", tmp_path / "crc.pcap.gz"
    subprocess.run(["editcap", "-F", "pcapng", str(CAPTURES / "eglink_bad_crc.pcap"), str(ng)], check=True)
    subprocess.run("gzip -c %s > %s" % (CAPTURES / "eglink_bad_crc.pcap", gz), shell=True, check=True)
    for path in (ng, gz):
        assert timeline(report, path) == [
            (1, "error", 1, "bad CRC (6x, frames 1-6 over 0.050 s)")]


@pytest.fixture
def odd_files(tmp_path):
    """Files tshark opens, or refuses, that are not captures of ours."""
    tmp_path.chmod(0o755)
    files = {
        "text3": b"vm\n",                                        # read by tshark as one frame, no time
        "random": bytes((i * 73 + 11) % 256 for i in range(4096)),
        "pcap_header_only": bytes.fromhex("d4c3b2a1020004000000000000000000ffff000001000000"),
    }
    cut = (CAPTURES / "eglink_armed.pcap").read_bytes()
    files["pcap_cut"] = cut[:len(cut) // 2 + 7]
    paths = {}
    for name, data in files.items():
        path = tmp_path / name
        path.write_bytes(data)
        path.chmod(0o644)
        paths[name] = path
    paths["directory"] = tmp_path
    return paths


@pytest.mark.parametrize("name", ["text3", "random", "pcap_header_only", "pcap_cut", "directory"])
def test_any_input_reports_or_says_why(report, odd_files, name):
    """Whatever tshark makes of a file: a report (exit 0/1), or exit 2 with
    one line naming the file; never a traceback."""
    proc = report("--json", odd_files[name])
    assert "Traceback" not in proc.stderr and "Error" not in proc.stderr.split(":", 1)[0]
    if proc.returncode == 2:
        assert len(proc.stderr.splitlines()) == 1 and str(odd_files[name]) in proc.stderr, proc.stderr
    else:
        assert proc.returncode == 0, proc.stderr
        doc = as_json(proc)["captures"][0]
        assert doc["devices"] == [] or name == "pcap_cut"
    if name == "text3":  # tshark reads it as MP4 media: not a network capture
        assert proc.returncode == 2 and "not a network capture" in proc.stderr
