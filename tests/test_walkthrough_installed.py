"""README's "A five-minute walkthrough", step by step, in the layout it
tells a user to make: the personal install (installed_testlib), the system
tshark as that user, the `vrshark` profile from ~/.config/wireshark. Each
test names the step whose sentences it checks; the colours are checked on
the frames the profile's colour rules and filter buttons pick, and in the
picture by tests/test_gui_installed.py."""
import re
import subprocess

import pytest

from conftest import CAPTURES, ROOT, profile_buttons
from installed_testlib import Installed

README = (ROOT / "README.md").read_text()
PROFILE = ROOT / "profile" / "vrshark"


def walkthrough():
    return README.split("## A five-minute walkthrough", 1)[1].split("\n## ", 1)[0]


def profile_rule(name):
    for line in (PROFILE / "colorfilters").read_text().splitlines():
        if line.startswith("@" + name + "@"):
            return line.split("@")[2]
    raise KeyError(name)


def button(label):
    return dict(profile_buttons())[label]


@pytest.fixture(scope="module")
def user():
    inst = Installed("personal")
    yield inst
    inst.remove()


def frames(user, capture, filt, fields=("frame.number",)):
    args = ["-n", "-2", "-r", str(CAPTURES / capture), "-Y", filt, "-T", "fields"]
    for f in fields:
        args += ["-e", f]
    proc = user.tshark(args)
    assert proc.returncode == 0, proc.stderr
    return [line.split("\t") for line in proc.stdout.splitlines()]


def profile_lines(user, capture, filt):
    """The packet list with the profile's columns, one line per frame."""
    proc = user.tshark(["-C", "vrshark", "-n", "-2", "-r", str(CAPTURES / capture), "-Y", filt])
    assert proc.returncode == 0, proc.stderr
    return {int(line.split()[0]): line for line in proc.stdout.splitlines()}


def test_step2_relays_open_rows(user):
    text = walkthrough()
    assert "(frames 41, 43, 48 and 50) are dark red" in text and "(frames 1–8, BU state `Initial`)" in text
    red = [int(r[0]) for r in frames(user, "eglink_analysis_session.pcap", profile_rule("vrshark: ES-Link relays open"))]
    assert red == [1, 3, 6, 8, 41, 43, 48, 50]
    lines = profile_lines(user, "eglink_analysis_session.pcap", "frame.number in {41,43,48,50}")
    for n in (41, 43, 48, 50):
        assert "[relays open]" in lines[n] and " Stopped " in lines[n], lines[n]
    for n, line in profile_lines(user, "eglink_analysis_session.pcap", "frame.number in {1,3,6,8}").items():
        assert " Initial " in line, line
    # "Click Safety to see only these rows"
    safety = [int(r[0]) for r in frames(user, "eglink_analysis_session.pcap", button("Safety"))]
    assert safety == red


def test_step3_tree_and_analysis(user):
    proc = user.tshark(["-n", "-2", "-r", str(CAPTURES / "eglink_analysis_session.pcap"), "-V",
                        "-Y", "frame.number in {41,45,47}"])
    text = proc.stdout
    # the BU state sits next to its relays-open warning
    assert re.search(r"BU state: Stopped \(0x01\)\n\s+\[Expert Info \(Warning/Response\): ES-Link relays open", text)
    # each command linked to its acknowledgement, both ways
    assert "[Acknowledged in frame: 47 (VRAI)]" in text and "[Acknowledges frame: 45 (VRCO command 9)]" in text
    # lost packets and gaps are named
    lost = frames(user, "eglink_analysis_session.pcap", "_ws.expert", ("_ws.expert.message",))
    assert any("1 packet lost from this sender" in r[0] for r in lost)
    gap = frames(user, "eglink_analysis_vrpi_gap.pcap", "eglink.analysis.vrpi_gap", ("_ws.col.Info",))
    assert gap and all("[gap " in r[0] for r in gap), gap


def test_step4_experts_and_statistics(user):
    assert "`BU 0x1001 (192.168.32.10)`" in walkthrough()
    proc = user.tshark(["-n", "-r", str(CAPTURES / "eglink_analysis_session.pcap"), "-q", "-z", "eglink,stat"])
    assert re.search(r"^ BU 0x1001 \(192\.168\.32\.10\)\s+60\s", proc.stdout, re.M), proc.stdout
    proc = user.tshark(["-n", "-2", "-r", str(CAPTURES / "eglink_analysis_session.pcap"), "-q", "-z", "expert"])
    for group in ("Warns", "Notes", "Chats"):
        assert group in proc.stdout
    # two BUs on one group: analysed apart, the shared group said once per
    # BU and controller (2 BUs, 2 controllers)
    proc = user.tshark(["-n", "-r", str(CAPTURES / "eglink_analysis_shared_group.pcap"), "-q", "-z", "eglink,stat"])
    assert set(re.findall(r"^ (BU 0x\w+ \([\d.]+\))", proc.stdout, re.M)) == {
        "BU 0x1001 (10.0.0.1)", "BU 0x2002 (10.0.0.2)"}, proc.stdout
    shared = [r for r in frames(user, "eglink_analysis_shared_group.pcap", "_ws.expert", ("_ws.expert.message",))
              if "is shared by several BUs or controllers" in r[0]]
    assert len(shared) == 4


def test_step5_e010_and_watchdog(user):
    lines = profile_lines(user, "mcmb2_polled_connect.pcap", "frame.number == 13")
    assert "[E010]" in lines[13]
    e010 = [int(r[0]) for r in frames(user, "mcmb2_polled_connect.pcap", profile_rule("vrshark: E010 / fieldbus failure"))]
    assert e010 == [13]
    tree = user.tshark(["-n", "-2", "-r", str(CAPTURES / "mcmb2_polled_connect.pcap"), "-V",
                        "-Y", "frame.number == 13"]).stdout
    assert "Slot 1: Terminal absent, terminal 1" in tree and "Terminal status: Terminal absent" in tree
    stalled = frames(user, "mcmb2_duplex_watchdog.pcap", profile_rule("vrshark: watchdog stalled"),
                     ("_ws.col.Info", "mcmb2.watchdog_since"))
    first = stalled[0]
    assert "[watchdog stalled 1.200 s]" in first[0] and first[1] == "11"
    n = frames(user, "mcmb2_duplex_watchdog.pcap", "frame.number == 23", ("_ws.col.Info",))
    assert "[watchdog stalled 1.200 s]" in n[0][0]


def step(n):
    """The text of step n of the walkthrough."""
    return re.search(r"^%d\. (.*?)(?=^\d+\. |\Z)" % n, walkthrough(), re.M | re.S).group(1)


def shell(user, command):
    """A command of the README as the user runs it in a terminal, from the top of the checkout."""
    proc = subprocess.run(user.command("sh", ["-c", command]), env=user.env(), capture_output=True, text=True,
                          cwd=str(ROOT))
    assert proc.returncode == 0, "%s\n%s" % (command, proc.stdout + proc.stderr)


def test_step6_machine_data(user):
    """The step's commands, as written, on the fresh account (no vrshark-io
    folder yet); the demo crane's data named; `vrshark.io` shows the frames
    with machine data; the removal it gives takes the names away."""
    text = " ".join(step(6).split())
    commands = re.findall(r"`((?:mkdir|cp|rm) [^`]+)`", text)
    install = [c for c in commands if c.startswith("mkdir")]
    remove = [c for c in commands if c.startswith("rm ")]
    assert len(install) == 1 and len(remove) == 1, commands
    assert not (user.config / "vrshark-io").exists()
    shell(user, install[0])
    assert (user.config / "vrshark-io" / "crane.csv").read_text() == \
        (ROOT / "examples" / "crane" / "crane.csv").read_text()
    assert "`captures/crane_eglink.pcap`" in text and "*Machine data (crane.csv)*" in text
    rows = frames(user, "crane_eglink.pcap", "vrshark.io", ("frame.number", "vrshark.io.horn",
                                                            "vrshark.io.hoist_speed", "vrshark.io"))
    assert [int(r[0]) for r in rows] == [1, 2, 4, 5, 7, 8, 10, 11, 13, 15, 16]
    assert all(r[3] == "crane.csv" for r in rows)
    assert [r[2] for r in rows if r[2]] == ["0", "75.5", "100", "-50"]
    assert "`vrshark.io.hoist_speed > 50`" in text
    assert [r[0] for r in frames(user, "crane_eglink.pcap", "vrshark.io.hoist_speed > 50")] == ["5", "8"]
    tree = user.tshark(["-n", "-2", "-r", str(CAPTURES / "crane_eglink.pcap"), "-V", "-Y", "frame.number == 10"])
    assert "Machine data (crane.csv)" in tree.stdout and "Load on the hook (t): 52.3 (raw 5230)" in tree.stdout
    # "The demo list names only the demo crane's devices"
    assert frames(user, "eglink_analysis_session.pcap", "vrshark_io || vrshark.io") == []
    shell(user, remove[0])
    assert frames(user, "crane_eglink.pcap", "vrshark_io || vrshark.io") == []


def test_step7_report_installed(user):
    report = user.home / ".local" / "bin" / "vrshark-report"
    assert report.exists()
    captures = sorted(str(p) for p in CAPTURES.glob("*faults*.pcap"))
    assert captures
    proc = subprocess.run(user.command(str(report), captures + ["--fail-on", "warn"]), env=user.env(),
                          capture_output=True, text=True, cwd=str(user.home))
    assert proc.returncode == 1, proc.stdout + proc.stderr
    for path in captures:
        assert path.rsplit("/", 1)[1] in proc.stdout
    assert "stalled" in proc.stdout


def test_profinet_worked_example(user):
    """docs/profinet.md, "Worked example": what frames 2, 7, 13 and 15 read."""
    doc = " ".join((ROOT / "docs" / "profinet.md").read_text().split("## Worked example", 1)[1].split())
    rows = {int(r[0]): r[1:] for r in frames(user, "mcmb2_polled_connect.pcap", "frame.number in {2,7,13,15}",
                                               ("frame.number", "_ws.col.Info", "_ws.expert.message"))}
    assert rows[2][1] == "Cyclic data layout learned: polled device: uplink FrameID 0x8005, downlink FrameID 0x8006"
    assert '"%s"' % rows[2][1] in doc
    assert "`%s`" % rows[7][0] in doc
    assert '"Slot 2 now serves terminal 5 (was terminal 2): dynamic polling"' in doc
    assert rows[7][1] == "Slot 2 now serves terminal 5 (was terminal 2): dynamic polling"
    assert rows[13][0].startswith("Uplink polled: Fieldbus update failure (E010), watchdog 6 [E010], ")
    assert "Y=20" in rows[15][0] and "differ from the configured layout (Y=24" in rows[15][1]
    tree = user.tshark(["-n", "-2", "-r", str(CAPTURES / "mcmb2_polled_connect.pcap"), "-T", "fields",
                        "-e", "mcmb2.slot.status", "-e", "mcmb2.slot.terminal", "-Y", "frame.number == 7"]).stdout
    assert tree.split("\t")[1].strip() == "1,5,3,0"
