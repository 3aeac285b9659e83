"""A BU's Modbus/TCP connection whose TCP segments come out of order: a
request sent in two segments, the second captured first. With Wireshark's
default (tcp.reassemble_out_of_order off) TCP hands the request to no
dissector: its response is "without a request", and the note names the TCP
setting that reassembles them; with that setting the request and its
response decode as in the capture sent in order (one pass and two)."""
import shutil

import pytest
from scapy.all import TCP, rdpcap, wrpcap

from conftest import CAPTURES, _world_dir

ORIGINAL = "eclink_modbus_segments.pcap"
REQUEST = 19          # the read of the input image (Trans 6) after the connection is recognised
TEXT = ("Response without a request in the capture: the request was not captured, or its TCP segments came out "
        "of order (TCP Previous segment not captured, Retransmission), which tcp.reassemble_out_of_order:TRUE "
        "reassembles")
NAMES = ["eclink_modbus.no_request", "eclink_modbus.request_in", "eclink.image", "eclink.pci", "eclink.bu_state",
         "modbus.func_code", "_ws.expert.message"]


@pytest.fixture(scope="module")
def out_of_order():
    """ORIGINAL with the request of frame REQUEST sent as two segments, the
    second (bytes 6..) captured first: frames REQUEST and REQUEST + 1."""
    pk = rdpcap(str(CAPTURES / ORIGINAL))
    q = pk[REQUEST - 1]
    payload = bytes(q[TCP].payload)
    parts = []
    for seq, data, dt in ((q[TCP].seq + 6, payload[6:], 0.0), (q[TCP].seq, payload[:6], 0.0005)):
        p = q.copy()
        p[TCP].remove_payload()
        p[TCP].add_payload(data)
        p[TCP].seq = seq
        del p["IP"].len, p["IP"].chksum, p[TCP].chksum
        p = p.__class__(bytes(p))
        p.time = q.time + dt
        parts.append(p)
    folder = _world_dir("vrshark-ooo-")
    path = folder / "out-of-order.pcap"
    wrpcap(str(path), list(pk[:REQUEST - 1]) + parts + list(pk[REQUEST:]))
    path.chmod(0o644)
    yield path
    shutil.rmtree(folder, ignore_errors=True)


@pytest.mark.parametrize("two_pass", [False, True], ids=["one-pass", "two-pass"])
def test_default_names_the_tcp_setting(tshark, out_of_order, two_pass):
    got = tshark.frames(out_of_order, NAMES, two_pass=two_pass)
    response = REQUEST + 2
    assert [f for f, v in got.items() if v["eclink_modbus.no_request"]] == [response]
    assert TEXT in got[response]["_ws.expert.message"]
    # no image from a response whose request (its start address) is unknown
    assert not got[response]["eclink.image"]


@pytest.mark.parametrize("two_pass", [False, True], ids=["one-pass", "two-pass"])
def test_with_the_setting_decoded_as_in_order(tshark, out_of_order, two_pass):
    prefs = {"tcp.reassemble_out_of_order": "TRUE"}
    got = tshark.frames(out_of_order, NAMES, prefs=prefs, two_pass=two_pass)
    want = tshark.frames(CAPTURES / ORIGINAL, NAMES, two_pass=two_pass)
    assert not [f for f, v in got.items() if v["eclink_modbus.no_request"]]
    # the reassembled request in the second segment's frame, its response one later
    assert got[REQUEST + 1]["modbus.func_code"] == "4"
    response = got[REQUEST + 2]
    assert response["eclink_modbus.request_in"] == str(REQUEST + 1)
    for name in ("eclink.image", "eclink.pci", "eclink.bu_state"):
        assert response[name] == want[REQUEST + 1][name], name
    # every other frame as in the capture sent in order (one frame later)
    for f in range(REQUEST + 2, len(want) + 1):
        for name in ("eclink.image", "eclink.pci", "eclink.bu_state"):
            assert got[f + 1][name] == want[f][name], (f, name)


@pytest.mark.parametrize("snaplen", [80, 200])
def test_cut_adus_never_decoded_into_values(tshark, work_dir, snaplen):
    """Modbus/TCP cut by the capture (editcap -s): Wireshark names each cut
    frame ("Packet size limited during capture") and TCP reassembles no cut
    segment; every EC-Link value shown is the one sent (at 200 bytes the
    reads are whole, the output writes cut), none from bytes not captured."""
    import subprocess
    cut = work_dir / ("s%d.pcap" % snaplen)
    subprocess.run(["editcap", "-s", str(snaplen), str(CAPTURES / "eclink_modbus_basic.pcap"), str(cut)], check=True)
    cut.chmod(0o644)
    names = ["eclink.image", "eclink.pci", "eclink.pco", "eclink.cao", "eclink.bu_state", "eclink.periodic_data"]
    want = tshark.frames(CAPTURES / "eclink_modbus_basic.pcap", names, two_pass=True)
    for two_pass in (False, True):
        got = tshark.frames(cut, names + ["frame.cap_len", "frame.len"], two_pass=two_pass)
        shown = 0
        for f, v in got.items():
            for name in names:
                if v[name]:
                    assert v[name] == want[f][name], (f, name)
                    shown += 1
            if v["frame.cap_len"] != v["frame.len"]:
                assert not v["eclink.image"], f
        assert shown > 0 if snaplen == 200 else shown == 0
