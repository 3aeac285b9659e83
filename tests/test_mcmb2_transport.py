"""How frames reach the plugin: EtherType 0x8892 wrapped around PN-RT, the
Connect through UDP 34964 and the controller's port; nothing else."""
import os
import re

import pytest
from scapy.utils import rdpcap

from conftest import assert_fields
from tools.capgen.pcap import Capture

CM_PORT = "mcmb2_duplex_cm_port.pcap"


def test_cyclic_frames_go_through_the_carrier(tshark, capture_file):
    rows = tshark.field(capture_file("mcmb2_duplex_connect.pcap"), "frame.protocols",
                        display_filter="frame.number == 1 || frame.number == 3")
    # Lua-only, the carrier is not mcmb2's Proto: it shows mcmb2's frames
    # through mcmb2's dissector (lua/vrshark/pnio_systems.luam through())
    own = ":mcmb2" if os.environ.get("VRSHARK_NO_C_PLUGIN") else ""
    assert rows == ["eth:ethertype:ip:udp:vrshark_pnio:dcerpc" + own, "eth:ethertype:vrshark_pnio:pn_rt:pn_io" + own]
    # EC-Link's, in both installs, through eclink_pnio's (when a field of
    # ours is looked at: with nothing of ours to show, a cyclic frame is not
    # shown, docs/profinet.md "Expert info")
    got = tshark.frames(capture_file("eclink_pnio_connect.pcap"), ["frame.protocols", "eclink.pci"],
                        display_filter="frame.number == 1 || frame.number == 3")
    assert [got[n]["frame.protocols"] for n in (1, 3)] == ["eth:ethertype:ip:udp:vrshark_pnio:dcerpc:eclink_pnio",
                                                           "eth:ethertype:vrshark_pnio:pn_rt:pn_io:eclink_pnio"]


@pytest.mark.skipif(bool(os.environ.get("VRSHARK_NO_C_PLUGIN")), reason="the C front end's FrameID table")
@pytest.mark.parametrize("two_pass", [False, True])
def test_eclink_frameids_handed_to_eclink_pnio(tshark, capture_file, two_pass):
    """With the C plugin a FrameID whose layouts are all EC-Link's is registered under eclink_pnio's
    own Proto (vrshark_pnio.lua entry_proto()): its frames are dissected under it, so the protocol
    list ends with it even when nothing of ours is looked at (`-q`: a call through() would be
    skipped), and Lua is entered once a frame, not twice."""
    cap = str(capture_file("eclink_pnio_connect.pcap"))
    pass_args = ["-2"] if two_pass else []
    rows = tshark.run(["-q", "-n", "-r", cap, "-T", "fields", "-e", "frame.protocols"] + pass_args).stdout.split()
    assert len(rows) == 82
    assert rows[:2] == ["eth:ethertype:ip:udp:vrshark_pnio:dcerpc:eclink_pnio"] * 2  # the Connect
    assert set(rows[2:]) == {"eth:ethertype:vrshark_pnio:pn_rt:pn_io:eclink_pnio"}
    # Protocol Hierarchy walks the tree: Wireshark 4.0's Lua wraps each Lua
    # dissector's tree in an item "_ws.lua.fake", one per entry into Lua
    # (two with the carrier's call through eclink_pnio's dissector; 4.6
    # shows none)
    phs = tshark.run(["-q", "-r", cap, "-z", "io,phs"] + pass_args).stdout
    rows = [(len(m.group(1)), m.group(2), int(m.group(3)))
            for m in re.finditer(r"^( *)(\S+) +frames:(\d+) ", phs, re.M)]
    names = [name for _, name, _ in rows]
    pn_io = names.index("pn_io")
    below = names[pn_io + 1:names.index("eclink_pnio", pn_io)]
    assert rows[pn_io][2] == 80 and set(below) <= {"_ws.lua.fake"} and len(below) <= 1, phs
    assert rows[names.index("eclink_pnio", pn_io)][2] == 80, phs


def test_vlan_tagged_frames_too(tshark, capture_file):
    protos = tshark.field(capture_file("mcmb2_polled_vlan.pcap"), "frame.protocols", display_filter="mcmb2")
    assert protos and all(p.startswith("eth:ethertype:vlan:ethertype:vrshark_pnio:pn_rt") for p in protos)


def test_foreign_traffic_never_reaches_the_plugin(tshark, capture_file):
    protos = tshark.field(capture_file("eglink_armed.pcap"), "frame.protocols")
    assert protos and not any("vrshark_pnio" in p for p in protos)


@pytest.mark.parametrize("two_pass", [False, True])
def test_response_from_the_device_port(tshark, capture_file, two_pass):
    """The Connect response comes from the device's own port and assigns the input FrameID."""
    got = tshark.frames(capture_file(CM_PORT), ["udp.srcport", "mcmb2.direction", "mcmb2.uplink_data",
                                                "mcmb2.layout", "frame.protocols"], two_pass=two_pass)
    assert_fields(got[2], {"udp.srcport": 49157}, "frame 2")
    assert [got[n]["mcmb2.direction"] for n in range(3, 9)] == ["uplink", "downlink"] * 3
    assert_fields(got[3], {"mcmb2.uplink_data": bytes((i & 0xFF) or 1 for i in range(8)).hex(),
                           "mcmb2.layout": "Connect in frame 1"}, "frame 3")
    # a datagram that is not DCE/RPC on the controller's port is left alone
    assert_fields(got[9], {"frame.protocols": "eth:ethertype:ip:udp:data", "mcmb2.direction": None}, "frame 9")
    ex = tshark.experts(capture_file(CM_PORT), two_pass=two_pass)
    assert ex[1][-1] == "Cyclic data layout learned: duplex device: uplink FrameID assigned in the response, " \
        "downlink FrameID 0x8102"
    assert ex[2][-1] == "Cyclic data layout learned: duplex device: uplink FrameID 0x8101, downlink FrameID 0x8102"
    tshark.expect(capture_file(CM_PORT), 1, {"mcmb2.frame_id": 0x8102})


@pytest.mark.parametrize("two_pass", [False, True])
def test_foreign_connects_before_ours(tshark, capture_file, work_dir, two_pass):
    """A controller connects a foreign device again and again (its Connect
    request is only looked up after the first: the C front end hands no
    repeat over while no AR is held), then the base: the base's Connect is
    learned and its cyclic frames decoded, the foreign requests get nothing."""
    frames = [bytes(p) for p in rdpcap(str(capture_file(CM_PORT)))]
    # the same request with the submodule of slot 1 in subslot 2: no system of ours
    # (UDP payload at 42; its first 0x0104 block of slot 1 at 444, the subslot 22 bytes in)
    req = bytearray(frames[0])
    assert req[42 + 444:42 + 446] == b"\x01\x04" and req[42 + 444 + 12:42 + 444 + 14] == b"\x00\x01"
    req[42 + 444 + 22:42 + 444 + 24] = b"\x00\x02"
    cap = Capture()
    for i, frame in enumerate([bytes(req)] * 3 + frames):
        cap.add(0.001 * (i + 1), frame)
    path = work_dir / "foreign_then_ours.pcap"
    path.write_bytes(cap.to_bytes())
    path.chmod(0o644)
    got = tshark.frames(path, ["dcerpc.opnum", "mcmb2.direction", "mcmb2.system"], two_pass=two_pass)
    for n in (1, 2, 3):
        assert_fields(got[n], {"dcerpc.opnum": 0, "mcmb2.direction": None, "mcmb2.system": None}, "frame %d" % n)
    assert [got[n]["mcmb2.direction"] for n in range(6, 12)] == ["uplink", "downlink"] * 3
    ex = tshark.experts(path, two_pass=two_pass)
    # (Wireshark's PNIO has its own word on the FrameIDs; ours has none here)
    assert not any("layout" in m or "not decoded" in m for n in (1, 2, 3) for m in ex.get(n, [])), ex
    assert ex[4][-1] == "Cyclic data layout learned: duplex device: uplink FrameID assigned in the response, " \
        "downlink FrameID 0x8102"
    assert ex[5][-1] == "Cyclic data layout learned: duplex device: uplink FrameID 0x8101, downlink FrameID 0x8102"


def test_disabling_the_carrier(tshark, capture_file):
    """--disable-protocol vrshark_pnio: the documented trade-off, PN-RT frames fall back to data."""
    off = {"extra": ["--disable-protocol", "vrshark_pnio"]}
    cap = capture_file("mcmb2_duplex_connect.pcap")
    tshark.expect(cap, 1, {"frame.protocols": "eth:ethertype:ip:udp:dcerpc", "mcmb2.system": None}, **off)
    tshark.expect(cap, 3, {"frame.protocols": "eth:ethertype:data", "mcmb2.system": None}, **off)
