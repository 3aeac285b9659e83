"""A live capture in Wireshark's GUI, as a field engineer watches one (issue
55 §6): Wireshark 4.x under Xvfb with the `vrshark` profile of the README's
installs (the full one and the Lua plugins alone), run as an unprivileged
user, capturing on lo while captures/eglink_analysis_vrci_unacked.pcap is
sent again as real UDP (239.255.42.20, TTL 1) with its timing. VRCI 8 (its
frame 5) is never acknowledged; its deadline passes at its frame 61.

Wireshark colours a live row once, when it first draws it, from a
dissection after the frame's first pass: the command's row is drawn long
before its deadline. So the failed command is marked where it becomes
known: the row of frame 61 shows `[unacked]` and turns the colour of a
command not acknowledged as it arrives, and no other row has that colour,
before the deadline or after (docs/eglink.md "Live"). Re-filtered while
the capture runs (xdotool types the Commands button's filter), the list
shows that one row of that colour among the command's; the command's row
now reads `[unacked]` too (its forward link, as `-2` shows it), in the
colour it was drawn in.

A Lua postdissector beside the plugins logs what the GUI dissected (frame,
first pass or not, the Info column); screenshots give the rows' colours.
The pictures stay in build/gui-artefacts/.

dumpcap must capture as that user (tools/setup gives it cap_net_raw and
cap_net_admin): the test skips, saying so, where it cannot."""
import subprocess
import threading
import time

import pytest

from conftest import BUILD, CAPTURES, PROFILE_DIR, profile_buttons
from gui_testlib import (PROBE_X, WIDTH, Gui, Session, add_probe, column, have_gui, have_keys, near, read_ppm, rule_colours,
                         runs)
from installed_testlib import IS_ROOT, RUN_UID, Installed

pytestmark = pytest.mark.skipif(not have_gui(), reason="wireshark, Xvfb or imagemagick missing (tools/setup)")

ARTEFACTS = BUILD / "gui-artefacts"
CAPTURE = CAPTURES / "eglink_analysis_vrci_unacked.pcap"
GROUP = "239.255.42.20"
DEADLINE_FRAME, COMMAND_FRAME = 61, 5
UNACKED = "vrshark: command not acknowledged"
FIRST_ROW_Y = 123   # the first row of the packet list, below its header (pixels)
BEFORE_S = 1.8      # the deadline passes at 2.2 s (VRCI 8 at 0.2 s, 2000 ms), frame 61 at 2.24 s

PROBE = """-- vrshark live test probe: what the GUI dissects
local out = assert(io.open(%r, "a"))
local probe = Proto("vrshark_live_probe", "vrshark live test probe")
function probe.dissector(tvb, pinfo, tree)
    out:write(pinfo.number, "\\t", pinfo.visited and "visited" or "first", "\\t", tostring(pinfo.cols.info), "\\n")
    out:flush()
end
register_postdissector(probe)
"""


def dumpcap_captures_as_user():
    """None, or why dumpcap cannot capture on lo as the test's user."""
    if not IS_ROOT:
        cmd = ["dumpcap", "-i", "lo", "-a", "duration:1", "-w", "/dev/null", "-q"]
    else:
        cmd = ["setpriv", "--reuid=%d" % RUN_UID, "--regid=%d" % RUN_UID, "--clear-groups",
               "dumpcap", "-i", "lo", "-a", "duration:1", "-w", "/dev/null", "-q"]
    try:
        proc = subprocess.run(cmd, capture_output=True, text=True, timeout=20)
    except (OSError, subprocess.TimeoutExpired) as e:
        return str(e)
    return None if proc.returncode == 0 else (proc.stderr.strip() or "dumpcap failed")


def udp_packets(path):
    """[(seconds from the first, source address, destination port, payload)] of a capture."""
    from scapy.all import IP, UDP, rdpcap
    pkts = rdpcap(str(path))
    t0 = float(pkts[0].time)
    return [(float(p.time) - t0, p[IP].src, p[UDP].dport, bytes(p[UDP].payload)) for p in pkts]


def probe_lines(path):
    """[(frame, "first" or "visited", Info)] the probe logged, of the
    dissections with columns (a filter's have none: Info "(info)")."""
    out = []
    for line in path.read_text(errors="replace").splitlines():
        parts = line.split("\t")
        if len(parts) == 3 and parts[0].isdigit() and parts[2] != "(info)":
            out.append((int(parts[0]), parts[1], parts[2]))
    return out


@pytest.fixture(scope="module", params=["personal", "lua-only"])
def live(request):
    why = dumpcap_captures_as_user()
    if why:
        pytest.skip("dumpcap cannot capture on lo as an unprivileged user (tools/setup gives it "
                    "cap_net_raw,cap_net_admin): %s" % why)
    inst = Installed(request.param)
    probe_out = add_probe(inst, "vrshark_live_probe.lua", PROBE)
    gui = Gui(inst, ARTEFACTS)
    yield request.param, gui, probe_out
    gui.close()
    inst.remove()


def test_live_capture_marks_the_failed_command(live):
    kind, gui, probe_out = live
    packets = udp_packets(CAPTURE)
    from test_report_model import mcast_socket     # (TTL 1, from 127.0.0.1)
    socks = {src: mcast_socket() for src in sorted({p[1] for p in packets})}
    ports = " or ".join("src port %d" % s.getsockname()[1] for s in socks.values())
    warm = next(iter(socks.values()))
    # (the packet list alone in the window: the rows from the one of the command on;
    # no completion list under the filter bar while xdotool types)
    session = Session(gui, ["-C", "vrshark", "-o", "gui.layout_content_2:NONE", "-o", "gui.layout_content_3:NONE",
                            "-o", "gui.autocomplete_filter:FALSE",
                            "-i", "lo", "-k", "-f", "udp and dst host %s and (%s)" % (GROUP, ports)])
    colours = rule_colours(PROFILE_DIR / "colorfilters")
    try:
        # the capture runs once a warm-up datagram (not EG-Link) shows in the probe
        deadline = time.time() + 40
        while not probe_lines(probe_out):
            assert session.proc.poll() is None, session.output()
            assert time.time() < deadline, "Wireshark captured nothing on lo:\n" + session.output()
            warm.sendto(b"vrshark live test", (GROUP, 5899))
            time.sleep(0.5)
        time.sleep(1.0)
        base = max(n for n, _, _ in probe_lines(probe_out))
        session.focus()     # (the pointer off the rows)
        # the capture again, with its timing; a screenshot (in the background,
        # so as not to hold the timing up) 0.4 s before the deadline
        shots = {}
        before = threading.Timer(BEFORE_S, lambda: shots.__setitem__("before", gui.screenshot()))
        start = time.monotonic()
        before.start()
        for t, src, port, payload in packets:
            wait = start + t - time.monotonic()
            if wait > 0:
                time.sleep(wait)
            socks[src].sendto(payload, (GROUP, port))
        before.join()
        time.sleep(1.5)
        shots["after"] = gui.screenshot()
        # a re-filter (the capture still running): the Commands button's filter; the
        # first row selected (a click), then the last (End), to see each one's colour
        if have_keys():
            session.press("ctrl+slash")
            session.xdotool("key", "ctrl+a", "BackSpace")
            session.xdotool("type", "--delay", "10", dict(profile_buttons())["Commands"])
            session.xdotool("key", "Return")
            time.sleep(2.0)
            session.xdotool("mousemove", str(WIDTH // 3), str(FIRST_ROW_Y), "click", "1")
            session.focus()
            time.sleep(0.5)
            shots["commands-first"] = gui.screenshot()
            session.xdotool("mousemove", str(WIDTH // 3), str(FIRST_ROW_Y), "click", "1", "key", "End")
            session.focus()
            time.sleep(0.5)
            shots["commands-last"] = gui.screenshot()
    finally:
        out = session.close()
        for s in socks.values():
            s.close()
    for name, pic in shots.items():
        subprocess.run(["convert", "ppm:-", str(ARTEFACTS / ("live-%s-%s.png" % (kind, name)))], input=pic,
                       check=True)
    for bad in ("Lua Error", "Dissector bug", "dissector bug"):
        assert bad not in out, out
    seen = probe_lines(probe_out)
    frames = {n - base for n, _, _ in seen if n > base}
    assert frames == set(range(1, len(packets) + 1)), "the GUI did not dissect every frame sent"
    # the row of the deadline frame, drawn as it arrived: [unacked] whenever the
    # list dissects it
    drawn = [info for n, how, info in seen if n - base == DEADLINE_FRAME and how == "visited"]
    assert drawn and set(drawn) == {"VRPO Pkt=0 64 bytes [unacked]"}, drawn
    # the command as the live list drew it (before its deadline): not marked
    drawn = [info for n, how, info in seen if n - base == COMMAND_FRAME and how == "visited"]
    assert drawn and drawn[0] == "VRCI Cmd=8", drawn
    # the colours: no row of a failed command before the deadline, one (61) after; the
    # Commands button shows it among the command's rows (20), in that colour but when
    # it is the selected row
    for name, want, rows in (("before", 0, 5), ("after", 1, 5), ("commands-first", 1, 19), ("commands-last", 0, 20)):
        if name not in shots:
            continue
        col = runs(column(read_ppm(shots[name]), PROBE_X))
        unacked = [n for c, n in col if near(c, colours[UNACKED])]
        healthy = sum(n for c, n in col if near(c, colours["vrshark: EG-Link"]))
        assert len(unacked) == want and all(n >= 12 for n in unacked), (name, unacked, ARTEFACTS)
        assert healthy >= rows * 12, (name, "EG-Link rows", healthy, ARTEFACTS)
    if "commands-last" in shots:
        # re-dissected after the deadline, the command's row reads [unacked] too (its
        # forward link, as -2 shows it), in the colour it was drawn in
        drawn = [info for n, how, info in seen if n - base == COMMAND_FRAME and how == "visited"]
        assert drawn[-1] == "VRCI Cmd=8 [unacked]", drawn
