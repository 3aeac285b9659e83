"""vrshark-report's health rows (tools/report/health.py) on the findings the
dissectors give today: Modbus/TCP poll gaps, PCI and PCO stalls and failed
commands (eclink_modbus_faults.pcap), an EG-Link command never acknowledged
(eglink_analysis_vrci_unacked.pcap), in text, JSON, JUnit and HTML; and no
row and no stop on the public captures of devices that are not ours.
Streams that stop, on traffic the project did not make:
test_report_stream_stops.py.
"""
import json
import os
import subprocess
import xml.etree.ElementTree as ET

import pytest

from conftest import CAPTURES, ROOT

REPORT = ROOT / "tools" / "vrshark-report"
PUBLIC = ROOT.parent / "shared" / "captures" / "public"


def run(*args):
    env = dict(os.environ, TZ="UTC", LC_ALL="C.UTF-8")
    return subprocess.run([str(REPORT), "--no-progress"] + [str(a) for a in args], env=env, cwd=str(ROOT),
                          capture_output=True, text=True, timeout=300)


def rows(capture):
    rep = json.loads(run("--json", capture).stdout)["captures"][0]
    return {(d["id"], r["stream"]): r for d in rep["devices"] for r in d["streams"]}


def test_modbus_poll_gaps_stalls_and_failed_commands():
    """eclink_modbus_faults.pcap: the PLC does not read the input image for
    0.7 s and 2.05 s (two poll gaps), PCI stands 0.825 s and PCO 2.175 s; the
    command from the RU (CCI, sent in the input image) and the command to the
    RU (sent in the output image) both fail."""
    got = rows(CAPTURES / "eclink_modbus_faults.pcap")
    assert list(got) == [(1, "input image read (unit 1)"), (1, "output image written (unit 1)")]
    inp, out = got[(1, "input image read (unit 1)")], got[(1, "output image written (unit 1)")]
    assert (inp["frames"], inp["first_frame"], inp["last_frame"], inp["limit_ms"]) == (8, 13, 39, 500)
    assert inp["cycle_ms"] == {"min": 50.0, "median": 125.0, "max": 2050.0}
    assert inp["longest_silence"] == {"s": 2.05, "frame": 29}
    # two poll gaps and the PCI stall; the failed command from the RU
    assert (inp["stalls"], inp["commands_failed"]) == (3, 1)
    assert (out["frames"], out["limit_ms"], out["stalls"], out["commands_failed"]) == (7, 2000, 1, 1)
    assert out["longest_silence"] == {"s": 2.05, "frame": 30}
    # every finding of the timeline but the state changes is in one row
    rep = json.loads(run("--json", CAPTURES / "eclink_modbus_faults.pcap").stdout)["captures"][0]
    findings = [e for e in rep["timeline"] if e["kind"] != "state"]
    for severity in ("error", "warning", "note"):
        assert inp["findings"][severity] + out["findings"][severity] == \
            sum(1 for e in findings if e["severity"] == severity)


def test_eglink_unacknowledged_command_counts_on_the_bu_row():
    got = rows(CAPTURES / "eglink_analysis_vrci_unacked.pcap")
    assert [(k[1], r["frames"], r["stalls"], r["commands_failed"], r["findings"]) for k, r in got.items()] == [
        ("BU VRPI", 21, 0, 1, {"error": 0, "warning": 1, "note": 0}),
        ("controller VRPO", 26, 0, 0, {"error": 0, "warning": 0, "note": 0})]
    lines = run(CAPTURES / "eglink_analysis_vrci_unacked.pcap").stdout.splitlines()
    i = lines.index("health (per stream; cycle: the intervals between its frames):")
    assert lines[i + 2:i + 4] == [
        "  [1]     BU VRPI              21        125.0 / 125.0 / 125.0  0.125 s to frame 3       0       1"
        "           0/1/0",
        "  [1]     controller VRPO      26        100.0 / 100.0 / 100.0  0.100 s to frame 4       0       0"
        "           0/0/0"]


def test_health_table_in_html(tmp_path):
    pytest.importorskip("plotly")
    page = tmp_path / "r.html"
    assert run("--html", page, CAPTURES / "eglink_analysis_vrpo_gap.pcap").returncode == 0
    html = page.read_text()
    table = html[html.index("<h3>Health</h3>"):]
    table = table[:table.index("</table>")]
    assert ("<tr><td>1</td><td>controller VRPO</td><td class=num>20</td><td class=num>100.0 / 100.0 / 2600.0"
            "</td><td>2.600 s to frame 40</td><td class=num>1</td><td class=num>0</td><td class=num>1/0/0</td>"
            "</tr>") in table


def test_health_in_junit_for_every_stream(tmp_path):
    out = tmp_path / "r.xml"
    run("--junit", out, CAPTURES / "eclink_modbus_faults.pcap")
    props = [p.get("name") for p in ET.parse(out).iter("property") if p.get("name").startswith("health ")]
    assert props == ["health input image read (unit 1)", "health output image written (unit 1)"]


@pytest.mark.parametrize("name", ["modbus_example.pcap", "pnio_connect_and_cyclic.pcap",
                                  "pnio_connect_many.pcapng"])
def test_public_captures_have_no_rows_and_no_stop(name):
    """Real traffic of devices that are not ours: no device, so no stream and
    no stop, and the gate passes."""
    path = PUBLIC / name
    if not path.exists():
        pytest.skip("public capture %s not present" % path)
    proc = run("--json", "--fail-on", "error", path)
    assert proc.returncode == 0, proc.stderr
    rep = json.loads(proc.stdout)["captures"][0]
    assert rep["devices"] == [] and [e for e in rep["timeline"] if e["kind"] == "stopped"] == []
    assert "health" not in run(path).stdout


def test_cycle_median_and_silence_from_the_intervals():
    """The median of an even count is the mean of the two middle intervals;
    the longest silence names the frame that ended it (the first of equals)."""
    import sys
    sys.path.insert(0, str(ROOT / "tools"))
    from report import health
    s = health.Stream("input", "input", 0.5)
    for frame, t in ((1, 0.0), (2, 0.010), (3, 0.050), (4, 0.070), (5, 0.100), (6, 0.140)):
        s.add(frame, t)
    # intervals 10, 40, 20, 30, 40 ms
    assert (s.frames, s.low, s.high, s.median()) == (6, 0.01, 0.04, 0.03)
    assert (s.silence, s.silence_frame) == (0.04, 3)
    s.add(7, 0.160)
    assert s.median() == 0.025
