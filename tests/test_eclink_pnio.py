"""EC-Link images over PROFINET IO and the handshake analysis."""
CAP = "eclink_pnio_connect.pcap"


def test_images_from_the_connect(tshark, capture_file):
    cap = capture_file(CAP)
    tshark.expect(cap, 1, {"eclink.image": None, "eclink_pnio.layout": None})
    tshark.expect(cap, 3, {"eclink.image": "input", "eclink.pci": 1, "eclink.cci": 0, "eclink.bu_state": 0x10,
                           "eclink.joystick1": 500, "eclink.joystick2": -250, "eclink.pco": None,
                           "eclink.periodic_size": None, "eclink_pnio.layout": "Connect in frame 1"})
    tshark.expect(cap, 4, {"eclink.image": "output", "eclink.pci": None, "eclink.bu_state": None, "eclink.pco": 1,
                           "eclink.periodic_size": 10, "eclink_pnio.layout": "Connect in frame 1"})


def test_connect_learned(tshark, capture_file):
    ex = tshark.experts(capture_file(CAP))
    assert ex[1] == ["Cyclic data layout learned: eclink device: uplink FrameID 0x8010, downlink FrameID 0x8011"]


def test_handshake_experts(tshark, capture_file):
    ex = tshark.experts(capture_file(CAP))
    assert "BU state Disarmed -> Armed" in ex[7]
    assert "New command from RU: CCI 0 -> 1" in ex[9]
    assert "CAO 1 acknowledges the command from RU of frame 9 after 251 ms" in ex[14]
    assert "New command to RU: CCO 0 -> 1" in ex[20]
    assert "CAI 1 acknowledges the command to RU of frame 20 after 124 ms" in ex[21]
    assert "PCI 10 has not changed for 625 ms (since frame 21, limit 500 ms)" in ex[31]
    assert "New command from RU: CCI 1 -> 2" in ex[43]
    assert "PCO 18 has not changed for 2125 ms (since frame 38, limit 2000 ms)" in ex[72]
    assert "Command from RU (CCI 2, frame 43) not acknowledged by CAO within 2000 ms" in ex[76]
    stalls = [n for n, m in ex.items() if any("has not changed" in x for x in m)]
    assert stalls == [31, 72]


def test_filters_by_expert_field(tshark, capture_file):
    assert list(tshark.frames(capture_file(CAP), [], display_filter="eclink_pnio.cmd_from_ru.late")) == [76]


def test_two_pass_agrees(tshark, capture_file):
    fields = ["eclink.pci", "eclink_pnio.pci_age", "_ws.expert.message"]
    one = tshark.frames(capture_file(CAP), fields)
    assert one == tshark.frames(capture_file(CAP), fields, two_pass=True)
    assert any(r["_ws.expert.message"] for r in one.values())
