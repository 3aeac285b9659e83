"""Which BU a controller belongs to when the capture does not show it: two
BUs and their controllers on the default group, no command acknowledged
between them, BU 1 and controller 1 alone on the group first, BU 2 and
controller 2 later. Sent from real UDP sockets on lo (four addresses), as
dumpcap captures them. A controller joined to its BU only for being alone
with it loses that join when the second BU appears: one pass from there on,
with a note; -2 from its first packet. Both controllers end up alike, "BU
not known", in both decoders and in the report.
"""
import os
import shutil
import socket
import time

import pytest

from test_eglink_field_captures import analysis, devices, report
from test_eglink_parity import assert_same, c_tshark, lua_tshark  # noqa: F401 (fixtures)

LUA_ONLY = bool(os.environ.get("VRSHARK_NO_C_PLUGIN"))

GROUP = "239.255.42.20"
BU1, CTRL1, BU2, CTRL2 = "127.0.0.1", "127.0.0.11", "127.0.0.2", "127.0.0.12"
WITHDRAWN = (
    "eglink.analysis.join_withdrawn",
    "Controller 127.0.0.11 no longer joined to BU 0x1001 (127.0.0.1): only being alone with it on "
    "239.255.42.20 port 5825 joined them, and this packet is a second BU's there: BU not known until a "
    "command acknowledged between them")


def _socket(ip):
    s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    s.setsockopt(socket.IPPROTO_IP, socket.IP_MULTICAST_TTL, 1)
    s.setsockopt(socket.IPPROTO_IP, socket.IP_MULTICAST_IF, socket.inet_aton("127.0.0.1"))
    s.bind((ip, 0))
    return s


@pytest.fixture(scope="module")
def late_second_bu():
    """Frames 1-8: BU 1 and controller 1 alone (VRPI, VRPO); frame 9 on: BU 2 and
    controller 2 too (VRPI 0x2002, VRPO), 3 rounds; no commands."""
    from test_report_model import capture_on_lo
    from eglink_testlib import gen
    from conftest import _world_dir
    folder = _world_dir("vrshark-pairing-", 0o755)    # (tshark may run as nobody)
    path = folder / "late_second_bu.pcap"
    bu1, c1, bu2, c2 = (_socket(ip) for ip in (BU1, CTRL1, BU2, CTRL2))
    origin = {id(bu1): 0x1001, id(bu2): 0x2002}
    steps = []
    for k in range(4):      # (VRPO 70 ms apart, then 80 ms: as TS-0006 recommends)
        steps += [(bu1, "VRPI", gen.armed(), 5825, 0.035),
                  (c1, "VRPO", gen.vrpo(0, gen.machine_data(k)), 5827, 0.035)]
    for k in range(3):
        steps += [(bu2, "VRPI", gen.armed(armed_ru=0xCAFE), 5825, 0.02),
                  (c2, "VRPO", gen.vrpo(0, gen.machine_data(50 + k)), 5827, 0.02),
                  (bu1, "VRPI", gen.armed(), 5825, 0.02),
                  (c1, "VRPO", gen.vrpo(0, gen.machine_data(4 + k)), 5827, 0.02)]

    def send():
        serials = {}
        for sock, ptype, payload, port, pause in steps:
            n = serials.get(id(sock), 0)
            serials[id(sock)] = n + 1
            sock.sendto(gen.packet(ptype, payload, origin=origin.get(id(sock), 0), serial=n), (GROUP, port))
            time.sleep(pause)

    capture_on_lo(path, (bu1, c1, bu2, c2), send)
    yield path
    shutil.rmtree(folder, ignore_errors=True)


FIELDS = ["ip.src", "eglink.analysis.bu_stream", "eglink.analysis.bu_origin", "eglink.analysis.device",
          "eglink.analysis.joined_alone"]


def _by_sender(rows, src):
    return {f: {k: v for k, v in r.items() if k != "ip.src"} for f, r in rows.items() if r["ip.src"] == src}


def test_one_pass_withdraws_the_join_at_the_second_bu(tshark, late_second_bu):
    rows = tshark.frames(late_second_bu, FIELDS)
    assert len(rows) == 20
    alone = {"eglink.analysis.bu_stream": "0", "eglink.analysis.bu_origin": "0x1001",
             "eglink.analysis.device": "0x1001", "eglink.analysis.joined_alone": "1"}
    apart = {"eglink.analysis.bu_stream": "", "eglink.analysis.bu_origin": "",
             "eglink.analysis.device": "BU not known", "eglink.analysis.joined_alone": ""}
    assert _by_sender(rows, CTRL1) == {2: alone, 4: alone, 6: alone, 8: alone, 12: apart, 16: apart, 20: apart}
    assert _by_sender(rows, CTRL2) == {10: apart, 14: apart, 18: apart}
    assert {f: r["eglink.analysis.bu_stream"] for f, r in rows.items() if r["ip.src"] == BU2} == \
        {9: "1", 13: "1", 17: "1"}
    notes = {f: [e for e in v if e[0] == WITHDRAWN[0]] for f, v in analysis(tshark, late_second_bu).items()}
    assert {f: v for f, v in notes.items() if v} == {9: [WITHDRAWN]}


def test_two_passes_never_join_either_controller(tshark, late_second_bu):
    """-2: the first pass saw the whole channel: controller 1 is not joined from its
    first packet on, as controller 2; the note is the same."""
    rows = tshark.frames(late_second_bu, FIELDS, two_pass=True)
    apart = {"eglink.analysis.bu_stream": "", "eglink.analysis.bu_origin": "",
             "eglink.analysis.device": "BU not known", "eglink.analysis.joined_alone": ""}
    assert _by_sender(rows, CTRL1) == {f: apart for f in (2, 4, 6, 8, 12, 16, 20)}
    assert _by_sender(rows, CTRL2) == {f: apart for f in (10, 14, 18)}
    assert {f: r["eglink.analysis.bu_stream"] for f, r in rows.items() if r["ip.src"] == BU1} == \
        {f: "0" for f in (1, 3, 5, 7, 11, 15, 19)}
    notes = {f: [e for e in v if e[0] == WITHDRAWN[0]]
             for f, v in analysis(tshark, late_second_bu, two_pass=True).items()}
    assert {f: v for f, v in notes.items() if v} == {9: [WITHDRAWN]}


@pytest.mark.skipif(LUA_ONLY, reason="the first phase compares both decoders")
def test_c_and_lua_alike(c_tshark, lua_tshark, late_second_bu):   # noqa: F811
    for two_pass in (False, True):
        assert_same(c_tshark, lua_tshark, late_second_bu, two_pass)


def test_a_second_controller_withdraws_the_join(tshark, work_dir):
    """The same with one BU and a second controller: the note on the second
    controller's first packet; neither controller joined after it (nor, with -2,
    the first before it)."""
    from eglink_testlib import gen
    first = gen.Link()
    first.bu(0.0, "VRPI", gen.armed())
    first.ctrl(0.01, "VRPO", gen.vrpo(0, gen.machine_data(0)))
    second = gen.Link(cap=first.cap, ctrl_ip="192.168.32.21")
    second.ctrl(0.05, "VRPO", gen.vrpo(0, gen.machine_data(50)))
    first.ctrl(0.08, "VRPO", gen.vrpo(0, gen.machine_data(1)))
    path = work_dir / "second_controller.pcap"
    path.write_bytes(first.cap.to_bytes())
    note = ("eglink.analysis.join_withdrawn",
            "Controller 192.168.32.20 no longer joined to BU 0x1001 (192.168.32.10): only being alone with "
            "it on 239.255.42.20 port 5825 joined them, and this packet is a second controller's there: BU "
            "not known until a command acknowledged between them")
    for two_pass, devices_seen in ((False, ["0x1001", "0x1001", "BU not known", "BU not known"]),
                                   (True, ["0x1001", "BU not known", "BU not known", "BU not known"])):
        rows = tshark.frames(path, ["eglink.analysis.device"], two_pass=two_pass)
        assert [r["eglink.analysis.device"] for r in rows.values()] == devices_seen
        notes = {f: [e for e in v if e[0] == note[0]] for f, v in analysis(tshark, path, two_pass).items()}
        assert {f: v for f, v in notes.items() if v} == {3: [note]}


def test_an_acknowledgement_keeps_the_join(tshark, work_dir):
    """A command acknowledged while the two are alone is evidence: a second BU later
    withdraws nothing (captures/eglink_analysis_shared_group.pcap's controllers are
    joined by their acknowledgements; here the one of a single BU)."""
    from eglink_testlib import gen
    link = gen.Link()
    link.bu(0.0, "VRPI", gen.armed())
    link.ctrl(0.01, "VRPO", gen.vrpo(0, gen.machine_data(0)))
    link.bu(0.02, "VRCI", gen.command(5, b"\x01\x00HORN"))
    link.ctrl(0.03, "VRAO", gen.ack(5))
    other = gen.Link(bu_ip="10.0.0.2", cap=link.cap, origin=0x2002)
    other.bu(0.1, "VRPI", gen.armed())
    link.ctrl(0.11, "VRPO", gen.vrpo(0, gen.machine_data(1)))
    path = work_dir / "acked_then_second_bu.pcap"
    path.write_bytes(link.cap.to_bytes())
    for two_pass in (False, True):
        rows = tshark.frames(path, ["eglink.analysis.device", "eglink.analysis.joined_alone"], two_pass=two_pass)
        assert [r["eglink.analysis.device"] for r in rows.values()] == ["0x1001"] * 4 + ["0x2002", "0x1001"]
        # (joined by its acknowledgement from frame 4 on; before it, alone: -2 keeps that, nothing withdrew it)
        assert [r["eglink.analysis.joined_alone"] for r in rows.values()] == ["", "1", "", "", "", ""]
        assert not any(WITHDRAWN[0] in [e[0] for e in v] for v in analysis(tshark, path, two_pass).values())


def test_the_report_lists_both_controllers_alike(late_second_bu):
    """One pass, as the report reads: controller 1's packets from before the second BU
    are its own too (as -2 shows), not BU 1's: both controllers alike, each a device
    of its own with all its packets; the note in the timeline at frame 9."""
    _, rep = report(late_second_bu)
    unknown = ", BU not known (no command acknowledged between it and a BU of the group: pairing unknown)"
    assert sorted(devices(rep)) == [
        ("EG-Link BU 0x1001 (127.0.0.1 to 239.255.42.20:5825)", 7),
        ("EG-Link BU 0x2002 (127.0.0.2 to 239.255.42.20:5825)", 3),
        ("EG-Link controller 127.0.0.11 to 239.255.42.20:5827" + unknown, 7),
        ("EG-Link controller 127.0.0.12 to 239.255.42.20:5827" + unknown, 3)]
    by_name = {d["name"].split(" to ")[0]: d for d in rep["devices"]}
    assert by_name["EG-Link controller 127.0.0.11"]["first_frame"] == 2
    assert by_name["EG-Link controller 127.0.0.11"]["address"]["ports"] == [5827]
    assert by_name["EG-Link BU 0x1001 (127.0.0.1"]["address"]["ports"] == [5825]
    assert "controller" not in by_name["EG-Link BU 0x1001 (127.0.0.1"]["address"]
    assert [(e["frame"], e["text"]) for e in rep["timeline"] if "alone" in e["text"]] == [
        (9, "controller no longer joined to the BU it was alone with")]
