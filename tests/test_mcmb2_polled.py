"""MC-MB2-PN polled systems: from the Connect, and from the self-describing header."""
import pytest

CONNECT = "mcmb2_polled_connect.pcap"
NOCONNECT = "mcmb2_polled_noconnect.pcap"
VLAN = "mcmb2_polled_vlan.pcap"


def test_uplink_header_and_slots(tshark, capture_file):
    rows = tshark.fields(capture_file(CONNECT),
                         ["mcmb2.system", "mcmb2.status", "mcmb2.uplink_watchdog", "mcmb2.uplink_size",
                          "mcmb2.downlink_size", "mcmb2.slot", "mcmb2.slot.status", "mcmb2.slot.terminal",
                          "mcmb2.slot.uplink_data"], display_filter="frame.number==3")
    assert rows == [["polled", "0x0f", "1", "24", "10", "1,2,3,4", "0x01,0x01,0x01,0x0f", "1,2,3,0",
                     ",".join(bytes([0x10 + k] * 24).hex() for k in range(3))]]


def test_downlink_slots(tshark, capture_file):
    rows = tshark.fields(capture_file(CONNECT), ["mcmb2.direction", "mcmb2.reserved", "mcmb2.downlink_watchdog",
                                                 "mcmb2.slot", "mcmb2.slot.downlink_data"],
                         display_filter="frame.number==4")
    assert rows == [["downlink", "0x00", "1", "1,2,3", ",".join(bytes([0xA0 + k] * 10).hex() for k in range(3))]]


def test_polled_experts(tshark, capture_file):
    ex = tshark.experts(capture_file(CONNECT))
    assert 3 not in ex and 4 not in ex
    assert ex[7] == ["Slot 2 now serves terminal 5 (was terminal 2): dynamic polling"]
    assert ex[9] == ["Slot 3: undefined terminal status 0x3: bring the system to a safe state"]
    assert ex[11] == ["Undefined MC-MB2-PN status 0x1 on a polled system: bring the system to a safe state"]
    assert ex[13][0].startswith("Fieldbus update failure (E010)")
    assert ex[15] == ["Y=20, Z=10, 3 used slot(s) differ from the configured layout (Y=24, Z=10, 3 slot(s)): "
                      "bring the system to a safe state"]
    assert ex[17] == ["Terminal number bits are 2, not 0, on a polled system",
                      "Slot 2: terminal status 0x7 is not 'Terminal present' but its uplink data is not all 0"]
    assert ex[18] == ["Reserved byte is 0x05, not 0"]


def test_slot_absent_with_zero_data_is_quiet(tshark, capture_file):
    assert 5 not in tshark.experts(capture_file(CONNECT))
    assert tshark.field(capture_file(CONNECT), "mcmb2.slot.status", display_filter="frame.number==5") == \
        ["0x01,0x00,0x01,0x0f"]


@pytest.mark.parametrize("name", [NOCONNECT, VLAN])
def test_header_lays_out_both_directions(tshark, capture_file, name):
    rows = tshark.fields(capture_file(name), ["frame.number", "mcmb2.direction", "mcmb2.layout",
                                              "mcmb2.slot.uplink_data", "mcmb2.slot.downlink_data"])
    by = {int(r[0]): r[1:] for r in rows}
    # The downlink sent before the first uplink header is not ours yet.
    assert by[1] == ["", "", "", ""]
    assert by[2] == ["uplink", "polled header in frame 2", "3030303030303030303030,3131313131313131313131"[:0]
                     + bytes([0x30] * 10).hex() + "," + bytes([0x31] * 10).hex(), ""]
    assert by[3] == ["downlink", "polled header in frame 2", "", "40404040,41414141"]
    assert tshark.experts(capture_file(name))[8] == \
        ["Slot 2 now serves terminal 4 (was terminal 2): dynamic polling"]


def test_vlan_frames_are_tagged(tshark, capture_file):
    assert tshark.field(capture_file(VLAN), "vlan.id", display_filter="mcmb2")[:2] == ["100", "100"]


def test_header_heuristic_can_be_switched_off(tshark, capture_file):
    rows = tshark.fields(capture_file(NOCONNECT), ["mcmb2.system"], prefs={"mcmb2.heuristic": "FALSE"})
    assert all(r == [""] for r in rows)


@pytest.mark.parametrize("name", [CONNECT, NOCONNECT])
def test_two_pass_agrees(tshark, capture_file, name):
    fields = ["frame.number", "mcmb2.slot.terminal", "mcmb2.slot.uplink_data", "mcmb2.slot.downlink_data",
              "_ws.expert.message"]
    one = tshark.fields(capture_file(name), fields)
    assert one == tshark.fields(capture_file(name), fields, two_pass=True)
    assert any(r[4] for r in one)
