"""A BU and its controller that restart early (issue 55 §6): power-cycled
while commissioning, they number their packets from 0 again after a
silence, long before the serial could fall back by more than the repeat
window (1024). From real UDP sockets on lo, as dumpcap captures them; each
case in one pass and with -2 (the C plugin and, in tools/test's Lua-only
phase, the Lua EG-Link: test_eglink_parity compares the two on every
project capture).

- After a silence longer than the VRPI/VRPO gap limit, a serial that falls
  back is a restart (`eglink.analysis.serial_restart`): the silence is the
  VRPI gap it is, and the packets after it are analysed, so a command that
  is never acknowledged counts as failed (Expert Information and the
  statistics).
- A VRPI with BU state Initial and a serial fallen back is a restart too.
- The same serial again is a repeat, silence or not; a serial that falls
  back a little with no silence and no BU state Initial stays a repeat
  (`eglink.analysis.serial_repeat`, "[Repeated]", not analysed further).
"""
import re
import shutil
import time

import pytest

from conftest import _world_dir, expert_infos
from eglink_testlib import eglink_stats, gen

GROUP, BU_PORT, CTRL_PORT = "239.255.42.20", 5825, 5827
CHAT = "2097152"


def analysis(tshark, capture, two_pass=False):
    """{frame: [(expert name, message)]} of the EG-Link findings above chat level."""
    out = {}
    for frame, name, severity, _, message, _ in expert_infos(tshark.json(capture, two_pass=two_pass)):
        if name.startswith("eglink.") and severity != CHAT and name != "eglink.analysis.vrpo_interval":
            out.setdefault(frame, []).append((name, message))
    return out


def named(exp, name):
    """{frame: [message]} of one expert field."""
    out = {}
    for frame, found in exp.items():
        for n, m in found:
            if n == name:
                out.setdefault(frame, []).append(m)
    return out


def failed_commands(tshark, capture, two_pass=False):
    text = eglink_stats(tshark, capture, two_pass=two_pass)
    m = re.search(r"^\s*Failed \(not acknowledged in time\)\s+(\d+)", text, re.M)
    assert m, text
    return int(m.group(1))


def send_schedule(events):
    """events: [(seconds from now, socket, bytes, port)], sent in time order with their timing."""
    start = time.monotonic()
    for t, sock, data, port in sorted(events, key=lambda e: e[0]):
        wait = start + t - time.monotonic()
        if wait > 0:
            time.sleep(wait)
        sock.sendto(data, (GROUP, port))


class Sender:
    """One sender's packets, numbered in time order: from 0, from 0 again at
    a restart, or with a serial of their own that leaves the count as it is."""

    def __init__(self, sock, port, origin):
        self.sock, self.port, self.origin = sock, port, origin
        self.plan = []

    def at(self, t, ptype, payload, serial=None, restart=False):
        self.plan.append((t, ptype, payload, serial, restart))

    def events(self):
        out, count = [], 0
        for t, ptype, payload, serial, restart in sorted(self.plan, key=lambda e: e[0]):
            if restart:
                count = 0
            if serial is None:
                serial, count = count, count + 1
            out.append((t, self.sock, gen.packet(ptype, payload, origin=self.origin, serial=serial), self.port))
        return out


def periodic(bu, ctrl, start, end, vrpi=None, restart=False):
    """VRPIs every 125 ms and VRPOs every 100 ms from start to end (seconds);
    restart: both number from 0 again at start."""
    t = start
    while t < end - 1e-9:
        bu.at(t, "VRPI", vrpi or gen.armed(), restart=restart and t == start)
        t += 0.125
    t, n = start + 0.05, 0
    while t < end - 1e-9:
        ctrl.at(t, "VRPO", gen.vrpo(0, gen.machine_data(n)), restart=restart and n == 0)
        t += 0.1
        n += 1


def capture(name, build):
    """Capture on lo what build(bu, ctrl) schedules (Sender objects of a BU
    0x1001 and its controller); the capture's path."""
    from test_report_model import capture_on_lo, mcast_socket
    folder = _world_dir("vrshark-restart-", 0o755)     # (tshark may run as nobody)
    path = folder / name
    bu_sock, ctrl_sock = mcast_socket(), mcast_socket()
    bu, ctrl = Sender(bu_sock, BU_PORT, 0x1001), Sender(ctrl_sock, CTRL_PORT, 0)
    build(bu, ctrl)
    capture_on_lo(path, (bu_sock, ctrl_sock), lambda: send_schedule(bu.events() + ctrl.events()))
    bu_sock.close()
    ctrl_sock.close()
    return folder, path


@pytest.fixture(scope="module")
def restarted():
    """1 s of traffic, 2.5 s of silence, then both restart with serial 0; the
    BU sends VRCI 1 at 0.3 s after its restart and resends it every 100 ms
    until its 2 s timeout, never acknowledged; 2.6 s of traffic after the
    restart in all."""
    def build(bu, ctrl):
        periodic(bu, ctrl, 0.0, 1.0)
        periodic(bu, ctrl, 3.5, 6.1, restart=True)
        for k in range(20):
            bu.at(3.8 + 0.1 * k + 0.01, "VRCI", gen.command(1, b"\x11"))
    folder, path = capture("restarted.pcap", build)
    yield path
    shutil.rmtree(folder, ignore_errors=True)


def frames_of(tshark, capture, **kw):
    return tshark.frames(capture, ["eglink.type", "eglink.serial", "eglink.origin", "_ws.col.Info",
                                   "eglink.analysis.failed_command", "eglink.analysis.deadline_in",
                                   "eglink.analysis.repeat_of"], **kw)


def restart_frames(tshark, capture):
    """The first VRPI and the first VRPO with serial 0 after the first of each."""
    rows = frames_of(tshark, capture)
    out = {}
    for f, r in sorted(rows.items()):
        if r["eglink.serial"] == "0":
            out.setdefault(r["eglink.type"], []).append(f)
    return out["VRPI"][1], out["VRPO"][1], rows


@pytest.mark.parametrize("two_pass", [False, True], ids=["one_pass", "two_pass"])
def test_restart_after_silence_is_analysed(tshark, restarted, two_pass):
    vrpi, vrpo, rows = restart_frames(tshark, restarted)
    exp = analysis(tshark, restarted, two_pass=two_pass)
    # the restart of each sender, and nothing repeated
    assert named(exp, "eglink.analysis.serial_restart") == {
        vrpi: ["Serial jumped back from 7 to 0: the sender restarted?"],
        vrpo: ["Serial jumped back from 9 to 0: the sender restarted?"]}
    assert named(exp, "eglink.analysis.serial_repeat") == {}
    assert not [f for f, r in rows.items() if "[Repeated]" in r["_ws.col.Info"]]
    # the 2.5 s without VRPI before the restart: the VRPI gap it is
    (gap,) = named(exp, "eglink.analysis.vrpi_gap")[vrpi]
    m = re.fullmatch(r"No VRPI for (\d\.\d{3}) s \(more than 500 ms\): the machine controller should have "
                     r"flagged an error", gap)
    assert m and 2.5 < float(m.group(1)) < 2.9, gap
    assert re.search(r" \[gap 2\.\d{3} s\]", rows[vrpi]["_ws.col.Info"])
    # and the controller's, before its own restart
    (gap,) = named(exp, "eglink.analysis.vrpo_gap")[vrpo]
    assert re.fullmatch(r"No VRPO for 2\.\d{3} s \(more than \d+ ms\): .*", gap), gap


@pytest.mark.parametrize("two_pass", [False, True], ids=["one_pass", "two_pass"])
def test_unacked_command_after_a_restart_counts(tshark, restarted, two_pass):
    """VRCI 1, sent after the restart and never acknowledged: one warning
    (one pass: at the first packet past its deadline, -2: on the command),
    and the statistics count it failed."""
    rows = frames_of(tshark, restarted, two_pass=two_pass)
    vrcis = [f for f, r in sorted(rows.items()) if r["eglink.type"] == "VRCI"]
    assert len(vrcis) == 20
    command = vrcis[0]
    exp = analysis(tshark, restarted, two_pass=two_pass)
    unacked = named(exp, "eglink.analysis.vrci_unacked")
    (deadline,) = [f for f, r in rows.items() if r["eglink.analysis.failed_command"] == str(command)]
    assert deadline > vrcis[-1]
    if two_pass:
        assert unacked == {command: [
            "VRCI command 1 not acknowledged by a VRAO within 2000 ms (deadline at frame %d): "
            "the BU reports to the RU application that the command failed" % deadline]}
        assert rows[command]["eglink.analysis.deadline_in"] == str(deadline)
        assert named(exp, "eglink.analysis.vrci_deadline") == {deadline: [
            "Deadline of VRCI command 1 (frame %d) passed with no VRAO (2000 ms)" % command]}
    else:
        assert unacked == {deadline: [
            "VRCI command 1 (frame %d) not acknowledged by a VRAO within 2000 ms: "
            "the BU reports to the RU application that the command failed" % command]}
    # [unacked] where the deadline passed on every pass (as a live packet list shows it)
    assert rows[deadline]["_ws.col.Info"].endswith(" [unacked]")
    assert failed_commands(tshark, restarted, two_pass=two_pass) == 1


@pytest.fixture(scope="module")
def initial_restart():
    """No silence: the BU's VRPIs go on every 125 ms, but at 1 s it sends BU
    state Initial with serial 0 (a restart, TS-0006 §4.1.1 "not fully
    operative yet"); at 1.52 s it repeats its latest VRPI (serial 3, the
    same serial again), and at 2.01 s a VRPI whose serial is 3 behind the
    latest, BU state Armed."""
    def build(bu, ctrl):
        periodic(bu, ctrl, 0.0, 1.0)
        bu.at(1.0, "VRPI", gen.vrpi(bu_state=0), restart=True)
        periodic(bu, ctrl, 1.125, 1.5, vrpi=gen.vrpi(bu_state=0))
        bu.at(1.52, "VRPI", gen.vrpi(bu_state=0), serial=3)     # the same serial again
        periodic(bu, ctrl, 1.625, 2.6)
        bu.at(2.01, "VRPI", gen.armed(), serial=4)              # 3 behind the latest (7)
    folder, path = capture("initial.pcap", build)
    yield path
    shutil.rmtree(folder, ignore_errors=True)


@pytest.mark.parametrize("two_pass", [False, True], ids=["one_pass", "two_pass"])
def test_bu_state_initial_restarts_a_duplicate_repeats(tshark, initial_restart, two_pass):
    rows = frames_of(tshark, initial_restart, two_pass=two_pass)
    vrpis = [(f, int(r["eglink.serial"])) for f, r in sorted(rows.items()) if r["eglink.type"] == "VRPI"]
    restart = [f for f, s in vrpis if s == 0][1]
    dup = [f for i, (f, s) in enumerate(vrpis) if i and s == vrpis[i - 1][1]]
    back = [f for i, (f, s) in enumerate(vrpis) if i and 0 < vrpis[i - 1][1] - s < 10 and f != restart]
    assert len(dup) == 1 and len(back) == 1
    exp = analysis(tshark, initial_restart, two_pass=two_pass)
    assert named(exp, "eglink.analysis.serial_restart") == {
        restart: ["Serial jumped back from 7 to 0: the sender restarted?"]}
    (last,) = [s for f, s in vrpis if f < dup[0]][-1:]
    assert named(exp, "eglink.analysis.serial_repeat") == {
        dup[0]: ["Repeated packet: serial %d was already received; not analysed further" % last],
        # no silence, BU state Armed: a step back of 3 stays a repeat (or packets reordered)
        back[0]: ["Repeated or reordered packet: serial %d is older than the last one received (%d); "
                  "not analysed further" % (dict(vrpis)[back[0]], dict(vrpis)[back[0]] + 3)]}
    assert rows[dup[0]]["eglink.analysis.repeat_of"] != ""
    assert rows[dup[0]]["_ws.col.Info"].endswith(" [Repeated]")
    assert rows[back[0]]["_ws.col.Info"].endswith(" [Repeated]")
    assert not named(exp, "eglink.analysis.vrpi_gap")
