"""EG-Link registration: ports 5825/5827, the input port preference, the UDP
heuristic (on by default; off by preference or by Wireshark's heuristic switch),
Decode As, and no false positives on other traffic."""
import pytest

from conftest import Tshark
from eglink_testlib import expect_frames, gen

HEUR = "eglink_heuristic.pcap"
EGLINK_FRAMES = [1, 2, 3, 4, 5, 6, 9]


def eglink_frames(tshark, cap, **kw):
    """Numbers of the frames decoded as EG-Link."""
    return sorted(tshark.frames(cap, [], display_filter="eglink", **kw))


def test_default_ports(tshark, capture_file):
    got = tshark.frames(capture_file("eglink_armed.pcap"), ["udp.dstport", "eglink.type"])
    assert len(got) == 58
    # inputs (VR.I) to 5825, outputs (VR.O) to 5827, every frame EG-Link
    expect_frames(tshark, capture_file("eglink_armed.pcap"), {
        n: {"udp.dstport": 5825 if f["eglink.type"].endswith("I") else 5827}
        for n, f in got.items()})
    assert {f["eglink.type"][-1:] for f in got.values()} == {"I", "O"}


def test_heuristic_on_by_default(tshark, capture_file):
    assert eglink_frames(tshark, capture_file(HEUR)) == EGLINK_FRAMES
    expect_frames(tshark, capture_file(HEUR), {7: {"_ws.col.Protocol": "UDP"},
                                               8: {"_ws.col.Protocol": "UDP"}})


def test_heuristic_disabled(tshark, capture_file):
    assert eglink_frames(tshark, capture_file(HEUR), extra=["--disable-heuristic", "eglink_udp"]) == []
    # the configured ports still work without the heuristic
    assert len(eglink_frames(tshark, capture_file("eglink_armed.pcap"),
                             extra=["--disable-heuristic", "eglink_udp"])) == 58


def test_heuristic_enable_switch(capture_file, work_dir):
    """Off in a profile (Analyze > Enabled Protocols), on again with --enable-heuristic."""
    (work_dir / "heuristic_protos").write_text("eglink_udp,0\n")
    tshark = Tshark(work_dir)
    assert eglink_frames(tshark, capture_file(HEUR)) == []
    assert eglink_frames(tshark, capture_file(HEUR),
                         extra=["--enable-heuristic", "eglink_udp"]) == EGLINK_FRAMES


def test_heuristic_preference_off(tshark, capture_file):
    assert eglink_frames(tshark, capture_file(HEUR), prefs={"eglink.heuristic": "FALSE"}) == []


def test_input_port_preference_registers_output_port(tshark, capture_file):
    kw = dict(prefs={"eglink.heuristic": "FALSE", "eglink.input_port": "6100"})
    assert eglink_frames(tshark, capture_file(HEUR), **kw) == EGLINK_FRAMES
    # and 5825/5827 are then no longer EG-Link
    assert eglink_frames(tshark, capture_file("eglink_armed.pcap"),
                         extra=["--disable-heuristic", "eglink_udp"], **kw) == []


def test_input_port_range(tshark, capture_file):
    kw = dict(prefs={"eglink.heuristic": "FALSE", "eglink.input_port": "5825,6000-6100"})
    assert eglink_frames(tshark, capture_file(HEUR), **kw) == EGLINK_FRAMES
    assert len(eglink_frames(tshark, capture_file("eglink_armed.pcap"), **kw)) == 58


def test_decode_as(tshark, capture_file):
    kw = dict(prefs={"eglink.heuristic": "FALSE"})
    got = eglink_frames(tshark, capture_file(HEUR), decode_as=["udp.port==6100,eglink"], **kw)
    assert got == [1, 3, 6, 9]
    # Decode As shows what is on the port, even what the heuristic refuses
    kw = dict(decode_as=["udp.port==6200,eglink"], display_filter="udp.port == 6200")
    got = tshark.frames(capture_file(HEUR), ["eglink.type", "_ws.col.Info"], **kw)
    assert len(got) == 2
    first, second = sorted(got)
    expect_frames(tshark, capture_file(HEUR), {
        first: {"eglink.type": "VRPI"},
        second: {"eglink.type": "VRQI", "_ws.col.Info": "VRQI (unknown type) 2 bytes"}}, **kw)


def test_unknown_type_on_port_is_shown(tshark, capture_file):
    cap = capture_file("eglink_unknown_type.pcap")
    got = expect_frames(tshark, cap, {n: {"_ws.col.Protocol": "EG-Link"} for n in range(1, 6)})
    assert len(got) == 5


def test_not_vr_on_port_is_not_eglink(tshark, work_dir):
    cap = gen.Capture()
    link = gen.Link(cap)
    link.raw_bu(0.0, b"HELLO WORLD, THIS IS NOT EG-LINK")
    link.raw_bu(0.1, b"V")
    path = work_dir / "not_eglink.pcap"
    path.write_bytes(cap.to_bytes())
    assert eglink_frames(tshark, path) == []


@pytest.mark.parametrize("name", ["modbus_example.pcap", "pnio_connect_and_cyclic.pcap",
                                  "pnio_connect_many.pcapng"])
def test_public_captures_not_eglink(tshark, public_capture, name):
    assert eglink_frames(tshark, public_capture(name)) == []


def test_preferences_listed(tshark):
    out = tshark.run(["-G", "defaultprefs"]).stdout
    for line in ["#eglink.input_port: 5825", "#eglink.crc_variant: CRC-32/MPEG-2 (TS-0006)",
                 "#eglink.crc_byte_order: Little-endian (TS-0006)", "#eglink.heuristic: TRUE"]:
        assert line + "\n" in out


def test_heuristic_listed(tshark):
    rows = [line.split("\t") for line in tshark.run(["-G", "heuristic-decodes"]).stdout.splitlines()]
    assert ["udp", "eglink", "T"] in [r[:3] for r in rows]
