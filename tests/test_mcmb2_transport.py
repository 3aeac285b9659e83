"""How frames reach the plugin: EtherType 0x8892 wrapped around PN-RT, the
Connect through UDP 34964 and the controller's port; nothing else."""
import pytest

from conftest import assert_fields

CM_PORT = "mcmb2_duplex_cm_port.pcap"


def test_cyclic_frames_go_through_the_carrier(tshark, capture_file):
    rows = tshark.field(capture_file("mcmb2_duplex_connect.pcap"), "frame.protocols",
                        display_filter="frame.number == 1 || frame.number == 3")
    assert rows == ["eth:ethertype:ip:udp:vrshark_pnio:dcerpc", "eth:ethertype:vrshark_pnio:pn_rt:pn_io"]


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


def test_disabling_the_carrier(tshark, capture_file):
    """--disable-protocol vrshark_pnio: the documented trade-off, PN-RT frames fall back to data."""
    off = {"extra": ["--disable-protocol", "vrshark_pnio"]}
    cap = capture_file("mcmb2_duplex_connect.pcap")
    tshark.expect(cap, 1, {"frame.protocols": "eth:ethertype:ip:udp:dcerpc", "mcmb2.system": None}, **off)
    tshark.expect(cap, 3, {"frame.protocols": "eth:ethertype:data", "mcmb2.system": None}, **off)
