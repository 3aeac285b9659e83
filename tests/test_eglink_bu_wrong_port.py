"""The other port direction (TS-0006 2.2: the BU sends to the input packet
port, the controller to the output packet port, input + 2): a BU whose VRPI
and VRCI go to the output packet port is on the wrong port, as a controller
packet on the input port is, and stays the BU it is (its stream, its
serials). Sent from real UDP sockets on lo, as dumpcap captures them; one
pass and -2, both decoders alike."""
import os
import shutil
import time

import pytest

from test_eglink_field_captures import analysis
from test_eglink_pairing import GROUP, _socket
from test_eglink_parity import assert_same, c_tshark, lua_tshark  # noqa: F401 (fixtures)

LUA_ONLY = bool(os.environ.get("VRSHARK_NO_C_PLUGIN"))
BU, CTRL = "127.0.0.1", "127.0.0.11"


def wrong(ptype):
    return ("eglink.analysis.wrong_port",
            "%s sent to UDP port 5827, the output packet port: the BU sends VRPI, VRCI and VRAI to its input "
            "packet port (5825 here, TS-0006 §2.2); analysed with this BU's packets" % ptype)


@pytest.fixture(scope="module")
def bu_on_the_output_port():
    """Frames 1-4 on the right ports (VRPI 5825, VRPO 5827 twice); 5: the BU's
    VRPI to 5827; 6: VRPO; 7: the BU's VRCI to 5827; 8: the controller's VRAO;
    9: VRPI to 5825 again. The BU's serials 0..4 in order."""
    from test_report_model import capture_on_lo
    from eglink_testlib import gen
    from conftest import _world_dir
    folder = _world_dir("vrshark-buport-", 0o755)     # (tshark may run as nobody)
    path = folder / "bu_wrong_port.pcap"
    bu, ctrl = _socket(BU), _socket(CTRL)
    steps = []
    for k in range(2):
        steps += [(bu, "VRPI", gen.armed(), 5825), (ctrl, "VRPO", gen.vrpo(0, gen.machine_data(k)), 5827)]
    steps += [(bu, "VRPI", gen.armed(), 5827), (ctrl, "VRPO", gen.vrpo(0, gen.machine_data(2)), 5827),
              (bu, "VRCI", gen.command(1, b"\x01\x00HORN"), 5827), (ctrl, "VRAO", gen.ack(1), 5827),
              (bu, "VRPI", gen.armed(), 5825)]

    def send():
        serials = {}
        for sock, ptype, payload, port in steps:
            n = serials.get(id(sock), 0)
            serials[id(sock)] = n + 1
            sock.sendto(gen.packet(ptype, payload, origin=0x1001 if sock is bu else 0, serial=n), (GROUP, port))
            time.sleep(0.04)

    capture_on_lo(path, (bu, ctrl), send)
    yield path
    shutil.rmtree(folder, ignore_errors=True)


FIELDS = ["ip.src", "udp.dstport", "eglink.analysis.expected_port", "eglink.analysis.bu_stream",
          "eglink.analysis.device"]


@pytest.mark.parametrize("two_pass", [False, True])
def test_bu_packet_on_the_output_port(tshark, bu_on_the_output_port, two_pass):
    cap = bu_on_the_output_port
    found = analysis(tshark, cap, two_pass=two_pass)
    assert {f: v for f, v in found.items()} == {5: [wrong("VRPI")], 7: [wrong("VRCI")]}
    rows = tshark.frames(cap, FIELDS, two_pass=two_pass)
    assert len(rows) == 9
    bu_rows = {f: r for f, r in rows.items() if r["ip.src"] == BU}
    assert {f: r["eglink.analysis.expected_port"] for f, r in bu_rows.items()} == \
        {1: "", 3: "", 5: "5825", 7: "5825", 9: ""}
    # the same BU throughout: one stream, its VRCI acknowledged by the controller (no failure)
    assert {r["eglink.analysis.bu_stream"] for r in bu_rows.values()} == {"0"}
    info = tshark.frames(cap, ["_ws.col.Info"], two_pass=two_pass)
    assert [f for f, r in info.items() if "[wrong port]" in r["_ws.col.Info"]] == [5, 7]


@pytest.mark.skipif(LUA_ONLY, reason="the first phase compares both decoders")
def test_c_and_lua_alike(c_tshark, lua_tshark, bu_on_the_output_port):   # noqa: F811
    for two_pass in (False, True):
        assert_same(c_tshark, lua_tshark, bu_on_the_output_port, two_pass)
