"""VRPI fields that contradict each other, and links that report a fault
(TS-0006 4.1, 4.1.1-4.1.3; TS-0007 9 for the EC-Link status): each case a
VRPI of an armed BU alone between healthy ones, sent from a real UDP socket
on lo as dumpcap captures it. Each gets its own warning, naming both fields
and their values (eglink.fields_disagree) or the link and what its status
means (eglink.link_status.fault), in one pass and with -2, in the C and the
Lua decoder alike; the healthy VRPIs get none. A VRPI whose CRC fails gets
none either: its values are its corrupted bytes.
"""
import os
import shutil
import socket
import time

import pytest

from test_eglink_field_captures import analysis
from test_eglink_parity import assert_same, c_tshark, lua_tshark  # noqa: F401 (fixtures)

LUA_ONLY = bool(os.environ.get("VRSHARK_NO_C_PLUGIN"))
NEW = ("eglink.fields_disagree", "eglink.link_status.fault")
DISAGREE, FAULT = NEW

# (VRPI payload arguments, the findings of that VRPI)
CASES = [
    (dict(disabled=1), [(DISAGREE, "RU state Enabled (3) but RU disabled Disabled (tilted) (1): an enabled RU "
                                   "is not disabled")]),
    (dict(ru_state=2), [(DISAGREE, "RU state Armed (2) but RU disabled Enabled (0): Armed means movements are "
                                   "disabled, by tilting or inactivity")]),
    (dict(ru_state=0), [(DISAGREE, "Armed RU 0xbeef but RU state Initial (0): Initial means no RU is armed "
                                   "yet")]),
    (dict(bu_state=0x10), [(DISAGREE, "BU state Disarmed (0x10) but Armed RU 0xbeef: a disarmed BU is armed "
                                      "against no RU")]),
    (dict(armed_ru=0, ru_state=0, battery=0, rssi=0),
     [(DISAGREE, "BU state Armed (0x11) but Armed RU 0: in that state the BU is armed against an RU")]),
    (dict(bu_state=0x01), [(DISAGREE, "BU state Stopped (0x01) but RU state Enabled (3): the BU stops when its "
                                      "RU signals stop (RU state Stopped)")]),
    (dict(eg_link=2), [(FAULT, "EG-Link status No link (2): the link is not operating: no valid data has been "
                               "received")]),
    (dict(ec_link=5), [(FAULT, "EC-Link status Data error (5): the link is up, but the data exchanged is in "
                               "error"),
                       (DISAGREE, "EC-Link status Data error (5) but BU state Armed (0x11): an EC-Link error "
                                  "holds the BU in Initial")]),
    (dict(c_link=4), [(FAULT, "C-Link status Interface error (4): the link's interface module reports an "
                              "error")]),
]
# frame 1 healthy, then each case followed by a healthy VRPI
EXPECTED = {2 + 2 * i: found for i, (_, found) in enumerate(CASES)}


@pytest.fixture(scope="module")
def contradictions():
    from test_report_model import capture_on_lo
    from eglink_testlib import gen
    from conftest import _world_dir
    folder = _world_dir("vrshark-disagree-", 0o755)    # (tshark may run as nobody)
    path = folder / "contradictions.pcap"
    bu = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    bu.setsockopt(socket.IPPROTO_IP, socket.IP_MULTICAST_TTL, 1)
    bu.setsockopt(socket.IPPROTO_IP, socket.IP_MULTICAST_IF, socket.inet_aton("127.0.0.1"))
    bu.bind(("127.0.0.1", 0))
    payloads = [gen.armed()]
    for kw, _ in CASES:
        payloads += [gen.armed(**kw), gen.armed()]
    payloads.append(gen.armed(disabled=1))       # the last: a bad CRC

    def send():
        for serial, payload in enumerate(payloads):
            crc = 0 if serial == len(payloads) - 1 else None
            bu.sendto(gen.packet("VRPI", payload, origin=0x1001, serial=serial, crc_value=crc),
                      ("239.255.42.20", 5825))
            time.sleep(0.03)

    capture_on_lo(path, (bu,), send)
    bu.close()
    yield path
    shutil.rmtree(folder, ignore_errors=True)


def _new_findings(tshark, capture, two_pass):
    return {f: [e for e in v if e[0] in NEW] for f, v in analysis(tshark, capture, two_pass).items()
            if any(e[0] in NEW for e in v)}


@pytest.mark.parametrize("two_pass", [False, True])
def test_each_contradiction_its_own_warning(tshark, contradictions, two_pass):
    assert _new_findings(tshark, contradictions, two_pass) == EXPECTED


def test_warning_severity_and_filters(tshark, contradictions):
    """Each a warning, and a filter of its own."""
    rows = tshark.frames(contradictions, ["_ws.expert.severity"], display_filter="eglink.fields_disagree")
    assert sorted(rows) == [2, 4, 6, 8, 10, 12, 16]
    rows = tshark.frames(contradictions, ["_ws.expert.severity"], display_filter="eglink.link_status.fault")
    assert sorted(rows) == [14, 16, 18]
    warn = tshark.frames(contradictions, ["frame.number"],
                         display_filter='(eglink.fields_disagree || eglink.link_status.fault) '
                                        '&& _ws.expert.severity == "warning"')
    assert sorted(warn) == [2, 4, 6, 8, 10, 12, 14, 16, 18]


@pytest.mark.skipif(LUA_ONLY, reason="the first phase compares both decoders")
def test_c_and_lua_alike(c_tshark, lua_tshark, contradictions):   # noqa: F811
    for two_pass in (False, True):
        assert_same(c_tshark, lua_tshark, contradictions, two_pass)
