"""EG-Link captures as they come from the field (issue 45): a packet that
arrives corrupted, a controller packet on the wrong port, two BUs whose
controllers the capture does not pair, packets cut by the snap length
(editcap -s) and a clock stepping back (editcap -t). Each in the dissector,
in one pass and with -2, and through tools/vrshark-report: the devices and
frame counts it gives.

Captures: tools/capgen/eglink_analysis.py (corrupted, wrong_port,
clock_step, unpaired), and committed captures cut or shifted by editcap
here, as a field engineer's capture would be.
"""
import json
import os
import shutil
import subprocess

import pytest

from conftest import CAPTURES, ROOT, expert_infos
from eglink_testlib import eglink_stats

REPORT = ROOT / "tools" / "vrshark-report"
LUA_ONLY = bool(os.environ.get("VRSHARK_NO_C_PLUGIN"))
CHAT = "2097152"


def analysis(tshark, capture, two_pass=False, skip=("eglink.cut",)):
    """{frame: [(expert name, message)]} of the EG-Link expert infos above chat
    level (eglink.analysis.* and the dissector's), but those in skip."""
    out = {}
    for frame, name, severity, _, message, _ in expert_infos(tshark.json(capture, two_pass=two_pass)):
        if name.startswith("eglink.") and severity != CHAT and name not in skip:
            out.setdefault(frame, []).append((name, message))
    return out


def present(tshark, capture, fields, **kw):
    """{frame: {field: value}} of the frames that have any of the fields."""
    got = tshark.frames(capture, fields, **kw)
    return {f: {n: v for n, v in row.items() if v} for f, row in got.items() if any(row.values())}


def both_passes(tshark, capture, fields):
    """present() of the fields, asserted the same in one pass and with -2."""
    one = present(tshark, capture, fields)
    assert present(tshark, capture, fields, two_pass=True) == one
    return one


def report(*args):
    """tools/vrshark-report --json: (exit status, the first capture's report)."""
    proc = subprocess.run([str(REPORT), "--json"] + [str(a) for a in args], capture_output=True,
                          text=True, cwd=str(ROOT), stdin=subprocess.DEVNULL, timeout=600,
                          env=dict(os.environ, TZ="UTC", LC_ALL="C.UTF-8"))
    assert proc.returncode in (0, 1), proc.stderr
    return proc.returncode, json.loads(proc.stdout)["captures"][0]


def devices(rep):
    return [(d["name"], d["frames"]) for d in rep["devices"]]


def timeline(rep):
    return [(e["frame"], e["severity"], e["text"]) for e in rep["timeline"]]


def editcap(work_dir, capture, name, *args, frames=None):
    """editcap ARGS capture work_dir/name [frames]"""
    if not shutil.which("editcap"):
        pytest.skip("editcap is not installed")
    out = work_dir / name
    subprocess.run(["editcap"] + list(args) + [str(capture), str(out)] + ([frames] if frames else []),
                   check=True)
    out.chmod(0o644)
    return out


# --- a packet that arrives corrupted is no loss --------------------------------------------

def test_corrupted_serial_is_not_lost(tshark):
    cap = CAPTURES / "eglink_analysis_corrupted.pcap"
    exp = analysis(tshark, cap)
    assert exp[10] == [("eglink.analysis.serial_corrupted",
                        "Serial 103 arrived with a bad CRC, frame 8: not counted as lost")]
    assert exp[14] == [("eglink.analysis.serial_corrupted",
                        "Serial 6 arrived with a wrong size, frame 13: not counted as lost")]
    assert not [f for f, v in exp.items() if ("eglink.analysis.serial_gap" in dict(v))]
    assert both_passes(tshark, cap, ["eglink.analysis.corrupted_in", "eglink.analysis.lost"]) == {
        10: {"eglink.analysis.corrupted_in": "8"}, 14: {"eglink.analysis.corrupted_in": "13"}}
    tshark.expect(cap, 10, {"eglink.analysis.expected_serial": 103, "eglink.serial": 104,
                            "_ws.col.Info": "VRPI BU=Armed RU 0xbeef=Enabled"})


def test_corrupted_serial_in_a_real_gap_counts_the_others(tshark, work_dir):
    """Serials 2 and 3 missing, 3 arrived with a bad CRC: 1 lost, not 2."""
    from eglink_testlib import gen
    link = gen.Link()
    for serial, t in ((0, 0.0), (1, 0.125), (3, 0.375), (4, 0.5)):
        link.bu_serial = serial
        link.bu(t, "VRPI", gen.armed(), crc_value=0 if serial == 3 else None)
    path = work_dir / "gap_and_crc.pcap"
    path.write_bytes(link.cap.to_bytes())
    assert analysis(tshark, path, skip=("eglink.crc.bad",))[4] == [
        ("eglink.analysis.serial_gap", "1 packet lost from this sender: serial 2 expected, 4 received"),
        ("eglink.analysis.serial_corrupted", "Serial 3 arrived with a bad CRC, frame 3: not counted as lost")]
    assert both_passes(tshark, path, ["eglink.analysis.lost"]) == {4: {"eglink.analysis.lost": "1"}}


def test_corrupted_serial_in_the_report():
    status, rep = report("captures/eglink_analysis_corrupted.pcap")
    assert devices(rep) == [("EG-Link BU 0x1001 (192.168.32.10 to 239.255.42.20:5825)", 18)]
    lines = timeline(rep)
    assert not [ln for ln in lines if "lost" in ln[2] and "not lost" not in ln[2]]
    assert lines == [
        (8, "error", "bad CRC"),
        (10, "note", "a serial of the gap arrived with a bad CRC or size: not lost: arrived in frame 8 "
                     "and 1 other value (2x, frames 10-14 over 0.240 s)"),
        (13, "error", "header Size disagrees with the UDP length: Size 1, UDP payload 86 bytes")]


# --- a controller packet on the wrong port -------------------------------------------------

def test_wrong_port_belongs_to_its_controller(tshark):
    cap = CAPTURES / "eglink_analysis_wrong_port.pcap"
    exp = analysis(tshark, cap)
    assert exp == {
        8: [("eglink.analysis.wrong_port",
             "VRAO sent to UDP port 6001: the machine controller sends VRPO, VRCO and VRAO to the "
             "BU's input port + 2 (5827 here, TS-0006 §2.2); analysed with this controller's packets")],
        14: [("eglink.analysis.wrong_port",
              "VRCO sent to UDP port 5825, the BU's input port: the machine controller sends VRPO, "
              "VRCO and VRAO to the BU's input port + 2 (5827 here, TS-0006 §2.2); analysed with "
              "this controller's packets")]}
    fields = ["eglink.analysis.expected_port", "eglink.analysis.ack_to", "eglink.analysis.lost"]
    assert both_passes(tshark, cap, fields) == {
        8: {"eglink.analysis.expected_port": "5827", "eglink.analysis.ack_to": "7"},
        14: {"eglink.analysis.expected_port": "5827"},
        15: {"eglink.analysis.ack_to": "14"}}
    # every packet is the one BU's, in both passes
    for two_pass in (False, True):
        assert set(tshark.field(cap, "eglink.analysis.bu_stream", two_pass=two_pass)) == {"0"}
    assert tshark.frame(cap, 8, ["_ws.col.Info"])["_ws.col.Info"] == "VRAO Cmd=5 [wrong port]"


def test_controller_on_its_own_port_is_not_flagged(tshark, work_dir):
    """A controller with no BU in the capture, on a port of its own (the
    heuristic finds it): nothing says which port it should use. One pass
    says it is not joined to a BU yet; two passes know it never is."""
    from eglink_testlib import gen
    link = gen.Link(input_port=5999)
    link.ctrl(0.0, "VRAO", gen.ack(5))
    path = work_dir / "vrao_6001.pcap"
    path.write_bytes(link.cap.to_bytes())
    assert analysis(tshark, path) == {1: [(
        "eglink.analysis.not_joined", "VRAO sent to UDP port 6001, where no BU has been seen: not joined to "
        "a BU yet (two passes join it to the BU its controller turns up with later)")]}
    assert analysis(tshark, path, two_pass=True) == {}


# --- an excerpt that starts with a packet sent to a wrong port ------------------------------

@pytest.fixture(scope="module")
def wrong_port_excerpt():
    """Real UDP sockets on lo: a BU (VRPI, VRCI 5) and its controller (VRPO to 5827,
    VRAO 5 to port 6001, VRPO to 5827 again); the excerpt a user cuts with editcap -r
    from the VRCI on: the controller's first packet in it is the VRAO on the wrong port."""
    import time
    from test_report_model import capture_on_lo, mcast_socket
    from eglink_testlib import gen
    from conftest import _world_dir
    folder = _world_dir("vrshark-excerpt-", 0o755)    # (tshark may run as nobody)
    whole = folder / "whole.pcap"
    bu, ctrl = mcast_socket(), mcast_socket()
    group = "239.255.42.20"
    steps = [(ctrl, "VRPO", gen.vrpo(0, gen.machine_data(0)), 5827),
             (bu, "VRPI", gen.armed(), 5825),
             (bu, "VRCI", gen.command(5, b"\x01\x00HORN"), 5825),
             (ctrl, "VRAO", gen.ack(5), 6001),
             (ctrl, "VRPO", gen.vrpo(0, gen.machine_data(1)), 5827),
             (bu, "VRPI", gen.armed(), 5825),
             (ctrl, "VRPO", gen.vrpo(0, gen.machine_data(2)), 5827),
             (bu, "VRPI", gen.armed(), 5825)]

    def send():
        serials = {id(bu): 0, id(ctrl): 0}
        for sock, ptype, payload, port in steps:
            origin = 0x1001 if sock is bu else 0
            sock.sendto(gen.packet(ptype, payload, origin=origin, serial=serials[id(sock)]), (group, port))
            serials[id(sock)] += 1
            time.sleep(0.03)    # (VRPO 60 to 120 ms apart, as TS-0006 recommends)

    capture_on_lo(whole, (bu, ctrl), send)
    yield editcap(folder, whole, "excerpt.pcap", "-r", frames="3-8")
    shutil.rmtree(folder, ignore_errors=True)


def test_excerpt_starting_at_a_wrong_port_packet(tshark, wrong_port_excerpt):
    """The excerpt's frame 2 is the controller's VRAO to port 6001, acknowledging the
    BU's VRCI (frame 1); from frame 3 on the controller is on the BU's port. One pass
    cannot know it yet and says so; two passes join the VRAO to the BU, on the wrong
    port, acknowledging the VRCI. Either way the VRCI is acknowledged from then on: no
    'not resent', no failed command."""
    cap = wrong_port_excerpt
    one = analysis(tshark, cap)
    assert one == {2: [("eglink.analysis.not_joined",
                        "VRAO sent to UDP port 6001, where no BU has been seen: not joined to a BU yet "
                        "(two passes join it to the BU its controller turns up with later)")]}
    assert analysis(tshark, cap, two_pass=True) == {
        2: [("eglink.analysis.wrong_port",
             "VRAO sent to UDP port 6001: the machine controller sends VRPO, VRCO and VRAO to the "
             "BU's input port + 2 (5827 here, TS-0006 §2.2); analysed with this controller's packets")]}
    fields = ["eglink.analysis.bu_origin", "eglink.analysis.device", "eglink.analysis.ack_to",
              "eglink.analysis.ack_in", "eglink.analysis.expected_port", "_ws.col.Info"]
    two = tshark.frames(cap, fields, two_pass=True)
    assert two[2] == {"eglink.analysis.bu_origin": "0x1001", "eglink.analysis.device": "0x1001",
                      "eglink.analysis.ack_to": "1", "eglink.analysis.ack_in": "",
                      "eglink.analysis.expected_port": "5827", "_ws.col.Info": "VRAO Cmd=5 [wrong port]"}
    assert two[1]["eglink.analysis.ack_in"] == "2"
    first = tshark.frames(cap, fields)
    assert first[2] == {"eglink.analysis.bu_origin": "", "eglink.analysis.device": "BU not known",
                        "eglink.analysis.ack_to": "", "eglink.analysis.ack_in": "",
                        "eglink.analysis.expected_port": "", "_ws.col.Info": "VRAO Cmd=5"}
    # from frame 3 on, both passes alike: every packet the one BU's
    for got in (first, two):
        assert {f: r["eglink.analysis.device"] for f, r in got.items() if f >= 3} == \
            {f: "0x1001" for f in range(3, 7)}


def test_excerpt_starting_at_a_wrong_port_packet_in_the_report(wrong_port_excerpt):
    """One pass, as the report reads: the VRAO is the BU's, not a device of its own,
    and no command of the BU failed or went unanswered."""
    status, rep = report(wrong_port_excerpt)
    assert devices(rep) == [("EG-Link BU 0x1001 (127.0.0.1 to 239.255.42.20:5825)", 6)]
    assert rep["devices"][0]["address"]["ports"] == [5825, 5827, 6001]
    assert timeline(rep) == []
    assert status == 0


def test_wrong_port_in_the_report():
    status, rep = report("captures/eglink_analysis_wrong_port.pcap")
    assert devices(rep) == [("EG-Link BU 0x1001 (192.168.32.10 to 239.255.42.20:5825)", 22)]
    assert rep["devices"][0]["address"]["ports"] == [5825, 5827, 6001]
    assert timeline(rep) == [
        (8, "warning", "controller packet sent to the wrong UDP port: port 6001 and 1 other value "
                       "(2x, frames 8-14 over 0.280 s)")]
    assert status == 0  # no --fail-on


# --- two BUs, two controllers, no commands: pairing unknown --------------------------------

def test_unpaired_controllers_are_listed_apart():
    _, rep = report("captures/eglink_analysis_unpaired.pcap")
    unknown = ", BU not known (no command acknowledged between it and a BU of the group: pairing unknown)"
    assert devices(rep) == [
        ("EG-Link BU 0x1001 (10.0.0.1 to 239.255.42.20:5825)", 40),
        ("EG-Link BU 0x2002 (10.0.0.2 to 239.255.42.20:5825)", 40),
        ("EG-Link controller 10.0.0.11 to 239.255.42.20:5827" + unknown, 40),
        ("EG-Link controller 10.0.0.12 to 239.255.42.20:5827" + unknown, 40)]


def test_paired_controllers_join_their_bus():
    """The controllers of eglink_analysis_shared_group.pcap acknowledge their
    BU's commands: their packets are their BU's, also those from before the
    acknowledgement that tells it."""
    _, rep = report("captures/eglink_analysis_shared_group.pcap")
    assert devices(rep) == [("EG-Link BU 0x1001 (10.0.0.1 to 239.255.42.20:5825)", 33),
                            ("EG-Link BU 0x2002 (10.0.0.2 to 239.255.42.20:5825)", 33)]
    assert [d["first_frame"] for d in rep["devices"]] == [1, 2]


def test_unpaired_controllers_in_the_statistics(tshark):
    """(-z eglink,stat, or the Lua EG-Link's VRSHARK_EGLINK_STATS=1 table)"""
    text = eglink_stats(tshark, CAPTURES / "eglink_analysis_unpaired.pcap")
    for name in ("BU 0x1001 (10.0.0.1)", "BU 0x2002 (10.0.0.2)", "Controller 10.0.0.11 (BU not known)",
                 "Controller 10.0.0.12 (BU not known)"):
        assert name in text


# --- cut by the snap length ------------------------------------------------------------------

@pytest.mark.parametrize("snap", [64, 96])
@pytest.mark.parametrize("name", ["eglink_analysis_vrco_unacked.pcap", "eglink_analysis_lost.pcap",
                                  "eglink_analysis_vrci_retransmission.pcap"])
def test_cut_packets_are_analysed_as_received(tshark, work_dir, name, snap):
    """editcap -s: every finding of the whole capture, and no other (no loss,
    no command 'not in the capture', no deadline moved), one pass and -2."""
    whole = CAPTURES / name
    cut = editcap(work_dir, whole, "cut.pcap", "-s", str(snap))
    for two_pass in (False, True):
        assert analysis(tshark, cut, two_pass) == analysis(tshark, whole, two_pass), two_pass
    fields = ["eglink.analysis.lost", "eglink.analysis.ack_to", "eglink.analysis.failed_command",
              "eglink.analysis.retransmission_of", "eglink.analysis.bu_stream"]
    assert both_passes(tshark, cut, fields) == present(tshark, whole, fields)


def test_cut_packet_is_named_and_holds_only_what_it_has(tshark, work_dir):
    cut = editcap(work_dir, CAPTURES / "eglink_analysis_vrco_unacked.pcap", "cut64.pcap", "-s", "64")
    exp = {f: [m for n, m in v if n == "eglink.cut"]
           for f, v in analysis(tshark, cut, skip=()).items()}
    assert exp[1] == ["Packet cut by the capture (snaplen): 22 of 66 bytes captured; decoded as far "
                      "as captured, CRC not checked, counted as received"]
    assert exp[5] == ["Packet cut by the capture (snaplen): 22 of 42 bytes captured; decoded as far "
                      "as captured, CRC not checked, counted as received"]
    # the VRPI: BU state and the RU fields up to byte 6, nothing after; no CRC
    tshark.expect(cut, 1, {"eglink.bu_state": 0x11, "eglink.c_link_status": 1, "eglink.armed_ru": None,
                           "eglink.joystick1": None, "eglink.crc": None, "eglink.crc.status": None,
                           "_ws.malformed": None})
    # the VRCO: its Command ID, no command data
    tshark.expect(cut, 5, {"eglink.command_id": 4, "eglink.command_data": None, "eglink.crc": None})
    # (the C plugin ends it with Wireshark's exception; the Lua EG-Link writes its Info)
    got = tshark.frame(cut, 1, ["_ws.short", "_ws.col.Info"])
    assert got["_ws.col.Info"].endswith("[Packet size limited during capture]")
    assert LUA_ONLY or got["_ws.short"].startswith("[Packet size limited during capture")


def test_cut_burst_is_not_reassembled(tshark, work_dir):
    cut = editcap(work_dir, CAPTURES / "eglink_analysis_vrpo_split.pcap", "cut_split.pcap", "-s", "96")
    exp = analysis(tshark, cut)
    bursts = [m for v in exp.values() for n, m in v if n == "eglink.analysis.burst_incomplete"]
    assert bursts and all("(packet 0 cut by the capture)" in m for m in bursts)
    assert tshark.field(cut, "eglink.reassembled.length") == [""] * len(tshark.field(cut, "frame.number"))


def test_cut_capture_in_the_report(work_dir):
    cut = editcap(work_dir, CAPTURES / "eglink_analysis_vrco_unacked.pcap", "cut96.pcap", "-s", "96")
    _, whole = report("captures/eglink_analysis_vrco_unacked.pcap")
    _, rep = report(cut)
    assert devices(rep) == devices(whole) == [("EG-Link BU 0x1001 (192.168.32.10 to 239.255.42.20:5825)", 131)]
    lines = timeline(rep)
    assert lines[0][1:] == ("note", "packet cut by the capture (snaplen): decoded as far as captured "
                            "(90x, frames 1-131 over 4.940 s)")
    assert lines[1:] == timeline(whole)


# --- the clock steps back ------------------------------------------------------------------

TIMES = ["eglink.analysis.time_since_prev_vrpi", "eglink.analysis.time_since_prev_vrpo",
         "eglink.analysis.ack_time"]


def no_negative_times(tshark, capture):
    for two_pass in (False, True):
        for frame, row in present(tshark, capture, TIMES, two_pass=two_pass).items():
            assert all(float(v) >= 0 for v in row.values()), (frame, row)


def test_clock_step_capture(tshark):
    cap = CAPTURES / "eglink_analysis_clock_step.pcap"
    exp = analysis(tshark, cap)
    assert exp[27] == [("eglink.analysis.time_backwards",
                        "Time went backwards by 1.940 s (clock step): this packet is older than the "
                        "EG-Link packet before it; gap, age and deadline rules restart here")]
    # the command of 0.2 s fails 2 s after the step (-1.0 s), at the first packet past 1.0 s
    assert exp[64] == [("eglink.analysis.vrco_unacked",
                        "VRCO command 4 (frame 5) not acknowledged by a VRAI within 2000 ms")]
    # (and VRCO 4 resent every 100 ms until 0.9 s, TS-0006 5.1.4)
    assert sorted(f for f, v in exp.items() if [n for n, _ in v] != ["eglink.analysis.retransmission"]) == \
        [27, 64]
    assert both_passes(tshark, cap, ["eglink.analysis.time_backwards_after"]) == \
        {27: {"eglink.analysis.time_backwards_after": "26"}}
    # no interval across the step; the next ones measured from it
    tshark.expect(cap, 27, {"eglink.analysis.time_since_prev_vrpi": None})
    tshark.expect(cap, 28, {"eglink.analysis.time_since_prev_vrpo": None})
    tshark.expect(cap, 29, {"eglink.analysis.time_since_prev_vrpi": 0.125})
    tshark.expect(cap, 30, {"eglink.analysis.time_since_prev_vrpo": 0.1})
    no_negative_times(tshark, cap)
    assert tshark.frame(cap, 27, ["_ws.col.Info"])["_ws.col.Info"].endswith("[time backwards 1.940 s]")


def test_clock_set_back_by_editcap(tshark, work_dir):
    """The second half of a capture 2 s earlier (editcap -t -2, mergecap -a):
    the step is on its first frame, the deadlines restart there, and no time
    is below 0 (time_since_prev_vrpo was -1.9 s)."""
    if not shutil.which("mergecap"):
        pytest.skip("mergecap is not installed")
    whole = CAPTURES / "eglink_analysis_vrco_unacked.pcap"
    first = editcap(work_dir, whole, "a.pcap", "-r", frames="1-40")
    second = editcap(work_dir, editcap(work_dir, whole, "b0.pcap", "-r", frames="41-132"),
                     "b.pcap", "-t", "-2")
    stepped = work_dir / "stepped.pcap"
    subprocess.run(["mergecap", "-a", "-w", str(stepped), str(first), str(second)], check=True)
    stepped.chmod(0o644)
    for two_pass in (False, True):
        exp = analysis(tshark, stepped, two_pass)
        assert exp[41] == [("eglink.analysis.time_backwards",
                            "Time went backwards by 1.940 s (clock step): this packet is older than "
                            "the EG-Link packet before it; gap, age and deadline rules restart here")]
    no_negative_times(tshark, stepped)
    # command 4 (frame 5) fails 2 s after the step, no longer 2 s after it was sent (61)
    one = analysis(tshark, stepped)
    failed = [f for f, v in one.items() if ("eglink.analysis.vrco_unacked" in dict(v))]
    assert failed == [96, 123]
    _, rep = report(stepped)
    assert devices(rep) == [("EG-Link BU 0x1001 (192.168.32.10 to 239.255.42.20:5825)", 131)]
    assert (41, "warning", "time went backwards (clock step): gap and deadline rules restart") in timeline(rep)
    for entry in rep["timeline"]:
        assert entry["duration"] is None or entry["duration"] >= 0, entry


# --- what the capture cut is not captured, in the report ------------------------------------

@pytest.fixture(scope="module")
def half_cut_sockets():
    """Real UDP sockets on lo: an armed BU (RU 0xbeef Enabled) and its controller,
    twelve VRPIs; the capture a user gets when the second half came through a
    64-byte snaplen (editcap -s 64 on frames 13 on, mergecap -a)."""
    import time
    from test_report_model import capture_on_lo, mcast_socket
    from eglink_testlib import gen
    from conftest import _world_dir
    folder = _world_dir("vrshark-half-cut-", 0o755)    # (tshark may run as nobody)
    whole = folder / "whole.pcap"
    bu, ctrl = mcast_socket(), mcast_socket()

    def send():
        for i in range(12):
            bu.sendto(gen.packet("VRPI", gen.armed(), origin=0x1001, serial=i), ("239.255.42.20", 5825))
            ctrl.sendto(gen.packet("VRPO", gen.vrpo(0, gen.machine_data(i)), serial=i), ("239.255.42.20", 5827))
            time.sleep(0.06)    # (VRPO inside the recommended 50 to 200 ms)

    capture_on_lo(whole, (bu, ctrl), send)
    first = editcap(folder, whole, "first.pcap", "-r", frames="1-12")
    second = editcap(folder, whole, "second.pcap", "-s", "64", "-r", frames="13-24")
    path = folder / "half_cut.pcap"
    subprocess.run(["mergecap", "-a", "-w", str(path), str(first), str(second)], check=True)
    path.chmod(0o644)
    yield path
    shutil.rmtree(folder, ignore_errors=True)


def test_cut_state_is_not_captured_from_real_sockets(tshark, half_cut_sockets):
    """tshark leaves the cut VRPIs' RU state and armed RU empty (one pass and -2);
    the report says the RU state was not captured from the first cut VRPI on and
    reports no state change that the wire did not carry."""
    path = half_cut_sockets
    rows = both_passes(tshark, path, ["eglink.type", "eglink.ru_state", "eglink.armed_ru", "eglink.cut"])
    vrpis = {f: r for f, r in rows.items() if r.get("eglink.type") == "VRPI"}
    cut = sorted(f for f, r in vrpis.items() if r.get("eglink.cut"))
    assert cut and min(cut) > 12
    assert all("eglink.ru_state" not in vrpis[f] and "eglink.armed_ru" not in vrpis[f] for f in cut)
    status, rep = report("--fail-on", "warn", path)
    assert status == 0
    (dev,) = rep["devices"]
    assert dev["initial"] == {"BU state": "Armed", "RU state": "Enabled (RU 0xbeef)"}
    assert dev["final"]["RU state"] == "not captured from frame %d on (before: Enabled (RU 0xbeef))" % min(cut)
    assert dev["not_captured"]["RU state"]["first_frame"] == min(cut)
    # the cut note, and no state change
    assert [e["text"].split(" (12x")[0] for e in rep["timeline"]] == [
        "packet cut by the capture (snaplen): decoded as far as captured"]
