"""EG-Link: the analysis of each packet, kept from the first pass, reads back
the same in the second pass (tshark -2) and in the GUI.

Most packets keep a 12-byte record in a table by frame number
(eglink_frame_store() in plugins/vrshark/eglink-records.c): the expected
serial is not stored but derived from the packet's serial when it was in
sequence, and the layer of the EG-Link header sits in three bits. Packets
after a gap, deeper than eight layers, or with findings keep the full
record. Every analysis value that is no link to a later frame is compared,
one pass against two, on every EG-Link capture and on a copy of the lost
packets capture with the EG-Link header 14 layers deep.

The Lua EG-Link keeps records of its own (a number a frame, a table for a
frame with findings: lua/vrshark/eglink_records.luam); tools/test runs these
tests with it too (VRSHARK_NO_C_PLUGIN=1), and they read back alike.
"""
import pytest
from scapy.all import Dot1Q, Ether, rdpcap, wrpcap

from conftest import CAPTURES

NAMES = sorted(p.name for p in CAPTURES.glob("eglink_*.pcap"))
# (not eglink.analysis.ack_in, last_vrpi ...: they can point at later frames)
VALUES = ["eglink.analysis.bu_stream", "eglink.analysis.bu_origin", "eglink.analysis.device",
          "eglink.analysis.expected_serial", "eglink.analysis.lost", "eglink.analysis.repeat_of",
          "eglink.analysis.time_since_prev_vrpi", "eglink.analysis.time_since_prev_vrpo",
          "eglink.analysis.retransmission_of", "eglink.analysis.ack_to", "eglink.analysis.ack_time",
          "eglink.analysis.failed_command"]


def _rows(tshark, capture, **kw):
    return tshark.frames(capture, VALUES, **kw)


@pytest.mark.parametrize("name", NAMES)
def test_analysis_values_read_back_in_the_second_pass(tshark, name):
    one = _rows(tshark, CAPTURES / name)
    two = _rows(tshark, CAPTURES / name, two_pass=True)
    if name == "eglink_analysis_shared_group.pcap":
        # (a controller's packets get their BU from an acknowledgement that
        # may come later: in the second pass only; test_eglink_analysis.py)
        for rows in (one, two):
            for row in rows.values():
                for k in ("eglink.analysis.bu_stream", "eglink.analysis.bu_origin", "eglink.analysis.device"):
                    row.pop(k)
    assert one == two
    if name.startswith("eglink_analysis_"):
        assert any(row["eglink.analysis.expected_serial"] for row in one.values())


def test_expected_serial_in_sequence_and_after_a_gap(tshark):
    """In sequence: the packet's own serial, from the compact record; after
    the gap (frame 13 of the lost capture): the serial expected, from the
    full record; the first packet of a sender has none."""
    lost = CAPTURES / "eglink_analysis_lost.pcap"
    for kw in ({}, {"two_pass": True}):
        rows = tshark.frames(lost, ["eglink.serial", "eglink.analysis.expected_serial", "eglink.analysis.lost"], **kw)
        assert rows[13] == {"eglink.serial": "6", "eglink.analysis.expected_serial": "4",
                            "eglink.analysis.lost": "2"}
        assert rows[15] == {"eglink.serial": "9", "eglink.analysis.expected_serial": "8",
                            "eglink.analysis.lost": "1"}
        assert rows[1]["eglink.analysis.expected_serial"] == ""
        in_seq = [r for r in rows.values() if r["eglink.analysis.expected_serial"] and not r["eglink.analysis.lost"]]
        assert len(in_seq) > 10
        assert all(r["eglink.analysis.expected_serial"] == r["eglink.serial"] for r in in_seq)


def test_nine_layers_deep(tshark, work_dir):
    """Four VLAN tags put the EG-Link header at layer 14 (frame, eth and
    ethertype, 4 x vlan and ethertype, ip, udp, eglink): beyond the compact
    record's layer bits (8 layers), so every
    packet keeps its full record; the values are those of the plain capture."""
    plain = CAPTURES / "eglink_analysis_lost.pcap"
    tagged = work_dir / "eglink_lost_vlan4.pcap"
    packets = []
    for p in rdpcap(str(plain)):
        q = Ether(src=p[Ether].src, dst=p[Ether].dst) / Dot1Q(vlan=1) / Dot1Q(vlan=2) / Dot1Q(vlan=3) / \
            Dot1Q(vlan=4, type=p[Ether].type) / p[Ether].payload
        q.time = p.time
        packets.append(q)
    wrpcap(str(tagged), packets)
    tagged.chmod(0o644)
    # (frame.protocols leaves out frame, layer 1; each tag adds vlan and ethertype)
    layers = tshark.field(tagged, "frame.protocols", display_filter="frame.number == 13")
    assert layers[0].split(":").index("eglink") + 2 == 14
    want = _rows(tshark, plain)
    assert _rows(tshark, tagged) == want
    assert _rows(tshark, tagged, two_pass=True) == want
