"""EG-Link: one packet of each type cut at every length, as a short UDP datagram
and as a frame snapped by the capture. Never a dissector bug; a short datagram is
decoded as far as it goes with expert info, a snapped frame ends in the usual
'packet size limited' exception."""
import pytest

from eglink_testlib import gen, messages

PACKETS = {
    "VRPI": gen.packet("VRPI", gen.armed(joysticks=(-200, 300, 0, 0)), origin=gen.BU_ORIGIN, serial=1),
    "VRPO": gen.packet("VRPO", gen.vrpo(0, gen.machine_data(0, 24)), serial=2),
    "VRCI": gen.packet("VRCI", gen.command(5, b"\x01\x00ABC"), origin=gen.BU_ORIGIN, serial=3),
    "VRCO": gen.packet("VRCO", gen.command(6, b"\x02\x00XYZ"), serial=4),
    "VRAI": gen.packet("VRAI", gen.ack(6), origin=gen.BU_ORIGIN, serial=5),
    "VRAO": gen.packet("VRAO", gen.ack(5), serial=6),
}
HEADERS = 14 + 20 + 8  # Ethernet, IPv4, UDP


def send(link, ptype, t, pkt, snap=None):
    if ptype.endswith("I"):
        return link.raw_bu(t, pkt, snap)
    return link.raw_ctrl(t, pkt, snap)


def check_output(tshark, path):
    text = tshark.run(["-n", "-r", str(path), "-V"]).stdout
    assert "Dissector bug" not in text and "dissector bug" not in text
    rows = tshark.fields(path, ["frame.number", "_ws.malformed", "_ws.short", "_ws.col.Protocol"])
    found = messages(tshark, path)
    return [r + [found.get(int(r[0]), [])] for r in rows], text


@pytest.mark.parametrize("ptype", sorted(PACKETS))
def test_short_datagram_every_length(tshark, work_dir, ptype):
    pkt = PACKETS[ptype]
    link = gen.Link()
    for n in range(len(pkt) + 1):
        send(link, ptype, 0.001 * n, pkt[:n])
    path = work_dir / ("short_%s.pcap" % ptype)
    path.write_bytes(link.cap.to_bytes())
    rows, text = check_output(tshark, path)
    assert len(rows) == len(pkt) + 1
    for n, row in enumerate(rows):
        assert row[2] == "", "frame %d: exception" % (n + 1)
        if n < 2:
            assert row[3] != "EG-Link"
            continue
        assert row[3] == "EG-Link"
        if n < len(pkt):
            # a cut packet is always reported, as too short, wrong size or bad CRC
            assert row[4], "no expert info for %d bytes" % n
        else:
            assert row[1] == "" and row[4] == []
    assert "Exception occurred" not in text


@pytest.mark.parametrize("ptype", sorted(PACKETS))
def test_snapped_every_length(tshark, work_dir, ptype):
    pkt = PACKETS[ptype]
    link = gen.Link()
    for cut in range(1, len(pkt) + 1):
        send(link, ptype, 0.001 * cut, pkt, snap=cut)
    path = work_dir / ("snapped_%s.pcap" % ptype)
    path.write_bytes(link.cap.to_bytes())
    rows, _ = check_output(tshark, path)
    assert len(rows) == len(pkt)
    for row in rows:
        # only the ordinary truncation exception, never a malformed packet
        assert row[1] == "", "frame %s: malformed" % row[0]
        assert row[2].startswith("[Packet size limited during capture"), \
            "frame %s: no truncation shown" % row[0]


def test_shipped_truncated_capture(tshark, capture_file):
    rows = tshark.fields(capture_file("eglink_truncated.pcap"),
                         ["eglink.type", "_ws.short", "_ws.malformed", "_ws.col.Info"])
    assert [r[1] for r in rows] == ["[Packet size limited during capture: EG-Link truncated]"] * 6
    assert [r[2] for r in rows] == [""] * 6
    assert [r[3] for r in rows] == [
        "VRPI Armed RU=0xbeef Enabled[Packet size limited during capture]",
        "VRPO Pkt=0 64 bytes[Packet size limited during capture]",
        "VRCI Cmd=8[Packet size limited during capture]",
        "VRCO[Packet size limited during capture]",
        "VRAI Cmd=8[Packet size limited during capture]",
        "VRA[Packet size limited during capture]",
    ]
