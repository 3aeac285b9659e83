"""EG-Link: one packet of each type cut at every length, as a short UDP datagram
and as a frame snapped by the capture. Never a dissector bug; a short datagram is
decoded as far as it goes with expert info, a snapped frame says it was cut
(eglink.cut) and ends in the usual
'packet size limited' exception.

The Lua EG-Link (a Wireshark without the C plugin, VRSHARK_NO_C_PLUGIN=1)
cannot raise that exception: it writes the same Info, without the
"[Packet size limited during capture: EG-Link truncated]" item (_ws.short)."""
import os

import pytest

from eglink_testlib import expect_frames, gen, messages

PACKETS = {
    "VRPI": gen.packet("VRPI", gen.armed(joysticks=(-200, 300, 0, 0)), origin=gen.BU_ORIGIN, serial=1),
    "VRPO": gen.packet("VRPO", gen.vrpo(0, gen.machine_data(0, 24)), serial=2),
    "VRCI": gen.packet("VRCI", gen.command(5, b"\x01\x00ABC"), origin=gen.BU_ORIGIN, serial=3),
    "VRCO": gen.packet("VRCO", gen.command(6, b"\x02\x00XYZ"), serial=4),
    "VRAI": gen.packet("VRAI", gen.ack(6), origin=gen.BU_ORIGIN, serial=5),
    "VRAO": gen.packet("VRAO", gen.ack(5), serial=6),
}
HEADERS = 14 + 20 + 8  # Ethernet, IPv4, UDP
LUA_ONLY = bool(os.environ.get("VRSHARK_NO_C_PLUGIN"))
LIMITED = "[Packet size limited during capture]"
# _ws.short of a cut frame: the exception's item (C), none (Lua)
SHORT = None if LUA_ONLY else "[Packet size limited during capture: EG-Link truncated]"


def send(link, ptype, t, pkt, snap=None):
    if ptype.endswith("I"):
        return link.raw_bu(t, pkt, snap)
    return link.raw_ctrl(t, pkt, snap)


def check_output(tshark, path):
    """({frame: {"_ws.malformed", "_ws.short", "_ws.col.Protocol", "experts"}}, -V text)"""
    text = tshark.run(["-n", "-r", str(path), "-V"]).stdout
    assert "Dissector bug" not in text and "dissector bug" not in text
    frames = tshark.frames(path, ["_ws.malformed", "_ws.short", "_ws.col.Protocol", "_ws.col.Info"])
    found = messages(tshark, path)
    for n, fields in frames.items():
        fields["experts"] = found.get(n, [])
    return frames, text


@pytest.mark.parametrize("ptype", sorted(PACKETS))
def test_short_datagram_every_length(tshark, work_dir, ptype):
    pkt = PACKETS[ptype]
    link = gen.Link()
    for n in range(len(pkt) + 1):
        send(link, ptype, 0.001 * n, pkt[:n])
    path = work_dir / ("short_%s.pcap" % ptype)
    path.write_bytes(link.cap.to_bytes())
    frames, text = check_output(tshark, path)
    assert sorted(frames) == list(range(1, len(pkt) + 2))
    for frame, got in sorted(frames.items()):
        n = frame - 1                       # bytes of the packet in this datagram
        assert got["_ws.short"] == "", "frame %d: exception" % frame
        if n < 2:
            assert got["_ws.col.Protocol"] != "EG-Link", "frame %d" % frame
            continue
        assert got["_ws.col.Protocol"] == "EG-Link", "frame %d" % frame
        if n < len(pkt):
            # a cut packet is always reported, as too short, wrong size or bad CRC
            assert got["experts"], "no expert info for %d bytes" % n
        else:
            assert got["_ws.malformed"] == "" and got["experts"] == [], "frame %d" % frame
    assert "Exception occurred" not in text


@pytest.mark.parametrize("ptype", sorted(PACKETS))
def test_snapped_every_length(tshark, work_dir, ptype):
    pkt = PACKETS[ptype]
    link = gen.Link()
    for cut in range(1, len(pkt) + 1):
        send(link, ptype, 0.001 * cut, pkt, snap=cut)
    path = work_dir / ("snapped_%s.pcap" % ptype)
    path.write_bytes(link.cap.to_bytes())
    frames, _ = check_output(tshark, path)
    assert sorted(frames) == list(range(1, len(pkt) + 1))
    for frame, got in sorted(frames.items()):
        # only the ordinary truncation exception, never a malformed packet
        # (a Size finding of a packet cut before its Size is in the expert
        # list only: C adds it to no item, Lua to the frame's top tree,
        # whose hidden _ws.malformed then shows)
        if not (LUA_ONLY and len(pkt) - frame < 12):
            assert got["_ws.malformed"] == "", "frame %d: malformed" % frame
        assert got["_ws.col.Info"].endswith(LIMITED), "frame %d: no truncation shown" % frame
        if not LUA_ONLY:
            assert got["_ws.short"].startswith(LIMITED[:-1]), "frame %d" % frame
        elif len(pkt) - frame >= 2:         # (EG-Link's: "VR" captured)
            assert got["_ws.short"] == "", "frame %d" % frame


def test_shipped_truncated_capture(tshark, capture_file):
    info = ["VRPI BU=Armed RU 0xbeef=Enabled J1=-500[Packet size limited during capture]",
            "VRPO Pkt=0 64 bytes[Packet size limited during capture]",
            "VRCI Cmd=8[Packet size limited during capture]",
            "VRCO (truncated)[Packet size limited during capture]",
            "VRAI Cmd=8[Packet size limited during capture]",
            "VRA[Packet size limited during capture]"]
    got = expect_frames(tshark, capture_file("eglink_truncated.pcap"), {
        n: {"_ws.short": SHORT, "_ws.malformed": None, "_ws.col.Info": text}
        for n, text in enumerate(info, 1)})
    assert len(got) == 6


def test_snapped_vrpi_still_says_relays_open(tshark, work_dir):
    """Info is written from the bytes the capture holds before the tree is
    built, so a VRPI cut by the snap length still names its states and tags
    open relays; the relays item is left out only when the capture cannot tell."""
    vrpi_len = 16 + 46 + 4
    link = gen.Link()
    # BU Stopped: only the BU state byte captured
    link.bu(0.0, "VRPI", gen.vrpi(bu_state=0x01, armed_ru=gen.ARMED_RU, ru_state=4),
            origin=gen.BU_ORIGIN, snap=vrpi_len - 17)
    # BU Armed, RU stopped: captured up to the RU state
    link.bu(0.1, "VRPI", gen.armed(ru_state=4), origin=gen.BU_ORIGIN,
            snap=vrpi_len - 25)
    # BU Armed, the RU state cut off: the relays cannot be told
    link.bu(0.2, "VRPI", gen.armed(), origin=gen.BU_ORIGIN, snap=vrpi_len - 21)
    path = work_dir / "snapped_relays.pcap"
    path.write_bytes(link.cap.to_bytes())
    limited = "[Packet size limited during capture]"
    expect_frames(tshark, path, {
        1: {"_ws.col.Info": "VRPI BU=Stopped [relays open]" + limited,
            "eglink.relays_open": True, "_ws.malformed": None},
        2: {"_ws.col.Info": "VRPI BU=Armed RU 0xbeef=Stopped [relays open]" + limited,
            "eglink.relays_open": True, "_ws.malformed": None},
        3: {"_ws.col.Info": "VRPI BU=Armed" + limited, "eglink.relays_open": None,
            "_ws.malformed": None},
    })
