"""How frames reach the plugin: EtherType 0x8892 wrapped around PN-RT, the
Connect through UDP 34964 and the controller's port; nothing else."""
import pytest

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
    rows = tshark.fields(capture_file(CM_PORT), ["frame.number", "udp.srcport", "mcmb2.direction",
                                                 "mcmb2.uplink_data", "mcmb2.layout", "frame.protocols"],
                         two_pass=two_pass)
    assert rows[1][:2] == ["2", "49157"]
    assert [r[2] for r in rows[2:8]] == ["uplink", "downlink"] * 3
    assert rows[2][3] == bytes((i & 0xFF) or 1 for i in range(8)).hex()
    assert rows[2][4] == "Connect in frame 1"
    # a datagram that is not DCE/RPC on the controller's port is left alone
    assert rows[8][5] == "eth:ethertype:ip:udp:data"
    ex = tshark.experts(capture_file(CM_PORT), two_pass=two_pass)
    assert ex[1][-1] == "Cyclic data layout learned: duplex device: uplink FrameID assigned in the response, " \
        "downlink FrameID 0x8102"
    assert ex[2][-1] == "Cyclic data layout learned: duplex device: uplink FrameID 0x8101, downlink FrameID 0x8102"
    assert tshark.field(capture_file(CM_PORT), "mcmb2.frame_id", display_filter="frame.number==1") == ["0x8102"]


def test_disabling_the_carrier(tshark, capture_file):
    """--disable-protocol vrshark_pnio: the documented trade-off, PN-RT frames fall back to data."""
    rows = tshark.fields(capture_file("mcmb2_duplex_connect.pcap"), ["frame.protocols", "mcmb2.system"],
                         extra=["--disable-protocol", "vrshark_pnio"])
    assert rows[0] == ["eth:ethertype:ip:udp:dcerpc", ""]
    assert rows[2] == ["eth:ethertype:data", ""]
