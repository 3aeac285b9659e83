"""MC-MB2-PN polled systems: from the Connect, and from the self-describing header."""
import pytest

CONNECT = "mcmb2_polled_connect.pcap"
NOCONNECT = "mcmb2_polled_noconnect.pcap"
VLAN = "mcmb2_polled_vlan.pcap"
SAFE = ": bring the system to a safe state"
# _ws.expert.severity / .group as tshark -T fields prints them (epan/proto.h PI_*)
ERROR, SEQUENCE, PROTOCOL = 0x00800000, 0x02000000, 0x09000000


def test_uplink_header_and_slots(tshark, capture_file):
    tshark.expect(capture_file(CONNECT), 3, {
        "mcmb2.system": "polled", "mcmb2.status": 0xF, "mcmb2.uplink_watchdog": 1, "mcmb2.uplink_size": 24,
        "mcmb2.downlink_size": 10, "mcmb2.slot": [1, 2, 3, 4], "mcmb2.slot.status": [1, 1, 1, 0xF],
        "mcmb2.slot.terminal": [1, 2, 3, 0],
        "mcmb2.slot.uplink_data": [bytes([0x10 + k] * 24).hex() for k in range(3)],
        "_ws.col.Info": "Uplink polled: Polled system normal mode, watchdog 1, Y=24 Z=10, "
                        "slots 1:T1 present, 2:T2 present, 3:T3 present"})


def test_downlink_slots(tshark, capture_file):
    tshark.expect(capture_file(CONNECT), 4, {
        "mcmb2.direction": "downlink", "mcmb2.reserved": 0, "mcmb2.downlink_watchdog": 1, "mcmb2.slot": [1, 2, 3],
        "mcmb2.slot.downlink_data": [bytes([0xA0 + k] * 10).hex() for k in range(3)],
        "_ws.col.Info": "Downlink polled: watchdog 1, 3 slot(s)"})


def test_polled_experts(tshark, capture_file):
    ex = tshark.experts(capture_file(CONNECT))
    assert 3 not in ex and 4 not in ex
    assert ex[7] == ["Slot 2 now serves terminal 5 (was terminal 2): dynamic polling"]
    assert ex[9] == ["Slot 3: terminal status Unknown (0x3) is undefined" + SAFE]
    assert ex[11] == ["MC-MB2-PN status Unknown (0x1) is undefined on a polled system" + SAFE]
    assert ex[13] == ["Fieldbus update failure (E010): no valid terminal data, the IO controller must keep the "
                      "system in a safe state"]
    assert ex[15] == ["Y=20, Z=10, 3 used slot(s) differ from the configured layout (Y=24, Z=10, 3 slot(s))" + SAFE]
    assert ex[17] == ["Terminal number bits are 2, not 0, on a polled system",
                      "Slot 2: terminal status Active stop is not 'Terminal present' but its uplink data is not all 0"]
    assert ex[18] == ["Reserved byte is 0x05, not 0"]


def test_info_names_statuses_and_tags_findings(tshark, capture_file):
    """Names as on the duplex side, never "status 0xA"; [E010] and [undefined] tags right after
    the watchdog, in view where the packet list cuts the long slot list."""
    cap = capture_file(CONNECT)
    tshark.expect(cap, 7, {"_ws.col.Info": "Uplink polled: Polled system normal mode, watchdog 3, Y=24 Z=10, "
                                           "slots 1:T1 present, 2:T5 present, 3:T3 present"})
    tshark.expect(cap, 9, {"mcmb2.slot.status.undefined": True, "_ws.expert.severity": ERROR,
                           "_ws.expert.group": PROTOCOL,
                           "_ws.col.Info": "Uplink polled: Polled system normal mode, watchdog 4 [undefined], Y=24 Z=10, "
                                           "slots 1:T1 present, 2:T5 present, 3:T3 Unknown (0x3)"})
    tshark.expect(cap, 11, {"mcmb2.status.undefined": True, "_ws.expert.severity": ERROR,
                            "_ws.expert.group": PROTOCOL,
                            "_ws.col.Info": "Uplink polled: Unknown (0x1), watchdog 5 [undefined], Y=24 Z=10, "
                                            "slots 1:T1 present, 2:T5 present, 3:T3 present"})
    tshark.expect(cap, 13, {"mcmb2.status": 0xA, "mcmb2.status.e010": True, "mcmb2.no_valid_data": None,
                            "_ws.expert.severity": ERROR, "_ws.expert.group": SEQUENCE,
                            "_ws.col.Info": "Uplink polled: Fieldbus update failure (E010), watchdog 6 [E010], Y=24 Z=10, "
                                            "slots 1:T1 absent, 2:T5 absent, 3:T3 absent"})
    tshark.expect(cap, 17, {"_ws.col.Info": "Uplink polled: Polled system normal mode, watchdog 8, Y=24 Z=10, "
                                            "slots 1:T1 present, 2:T5 active stop, 3:T3 present"})
    infos = tshark.field(cap, "_ws.col.Info", display_filter="mcmb2")
    assert infos and not any("status 0x" in i for i in infos)


def test_slot_absent_with_zero_data_is_quiet(tshark, capture_file):
    assert 5 not in tshark.experts(capture_file(CONNECT))
    tshark.expect(capture_file(CONNECT), 5, {"mcmb2.slot.status": [1, 0, 1, 0xF], "_ws.expert.message": None})


@pytest.mark.parametrize("name", [NOCONNECT, VLAN])
def test_header_lays_out_both_directions(tshark, capture_file, name):
    fields = ["mcmb2.direction", "mcmb2.layout", "mcmb2.slot.uplink_data", "mcmb2.slot.downlink_data"]
    # The downlink sent before the first uplink header is not ours yet.
    tshark.expect(capture_file(name), 1, dict.fromkeys(fields))
    tshark.expect(capture_file(name), 2, {"mcmb2.direction": "uplink", "mcmb2.layout": "polled header in frame 2",
                                          "mcmb2.slot.uplink_data": [bytes([0x30] * 10).hex(),
                                                                     bytes([0x31] * 10).hex()],
                                          "mcmb2.slot.downlink_data": None})
    tshark.expect(capture_file(name), 3, {"mcmb2.direction": "downlink",
                                          "mcmb2.layout": "polled header in frame 2",
                                          "mcmb2.slot.uplink_data": None,
                                          "mcmb2.slot.downlink_data": ["40404040", "41414141"]})
    assert tshark.experts(capture_file(name))[8] == \
        ["Slot 2 now serves terminal 4 (was terminal 2): dynamic polling"]


def test_vlan_frames_are_tagged(tshark, capture_file):
    assert tshark.field(capture_file(VLAN), "vlan.id", display_filter="mcmb2")[:2] == ["100", "100"]


def test_header_heuristic_can_be_switched_off(tshark, capture_file):
    got = tshark.frames(capture_file(NOCONNECT), ["mcmb2.system"], prefs={"mcmb2.heuristic": "FALSE"})
    assert got and all(r == {"mcmb2.system": ""} for r in got.values())


@pytest.mark.parametrize("name", [CONNECT, NOCONNECT])
def test_two_pass_agrees(tshark, capture_file, name):
    fields = ["mcmb2.slot.terminal", "mcmb2.slot.uplink_data", "mcmb2.slot.downlink_data", "_ws.col.Info",
              "_ws.expert.message"]
    one = tshark.frames(capture_file(name), fields)
    assert one == tshark.frames(capture_file(name), fields, two_pass=True)
    assert any(r["_ws.expert.message"] for r in one.values())
