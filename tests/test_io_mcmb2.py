"""The demo crane's IO list decoded from MC-MB2-PN terminal data
(captures/crane_mcmb2.pcap): the same fields as on EG-Link, exact values;
polled slots with their device keys (terminal, slot, FrameID)."""
import pytest

from conftest import CAPTURES
from io_testlib import assert_nothing_added, crane, described, expect_all  # noqa: F401 (crane is a fixture)

CAP = CAPTURES / "crane_mcmb2.pcap"
UP = ["horn", "start", "stop", "gear", "hoist_speed", "trolley_speed", "operator_id"]
DOWN = ["message_code", "message_text"]
ALL = ["vrshark.io." + n for n in UP + DOWN]


def up(horn, start, stop, gear, hoist, trolley):
    return dict(zip(UP, (horn, start, stop, gear, hoist, trolley, 7)))


EXPECTED = {
    1: {}, 2: {},
    3: up(False, True, False, 0, 0.0, 0.0),
    4: {"message_code": 0, "message_text": " " * 12},
    5: up(False, False, False, 1, 75.5, -25.0),
    6: {"message_code": 0, "message_text": " " * 12},
    7: up(True, False, False, 2, 100.0, -100.0),
    8: {"message_code": 1, "message_text": "LOAD 52.3 T "},
    9: up(False, False, True, 3, -50.0, 0.0),
    10: {"message_code": 2, "message_text": "WIND 21 M/S "},
}




@pytest.mark.parametrize("two_pass", [False, True])
def test_every_crane_field_exact(crane, two_pass):
    expect_all(crane, CAP, EXPECTED, ALL, two_pass=two_pass)


def test_shown_under_the_mcmb2_tree(crane):
    text = crane.verbose(CAP, display_filter="frame.number == 5")
    tree = text.split("MC-MB2-PN", 1)[1]
    assert "    Machine data (crane.csv)\n" in tree
    assert "        Hoist joystick (%): 75.5 (raw 755)\n" in tree
    assert "        ..01 .... = Speed range: Low (1)\n" in tree


def test_faults(crane):
    experts = crane.experts(CAP)
    assert "Speed range: 3" in experts[9]
    assert "Message to the operator: Wind alarm (2)" in experts[10]


def test_polled_slots_and_device_keys(conf_dir, work_dir):
    """mcmb2_polled_connect.pcap: slots 1-3 carry terminals 1, 2 (later 5) and 3;
    uplink bytes are 0x10 + slot - 1, downlink bytes 0xa0 + slot - 1."""
    t = described(conf_dir, work_dir, "polled.csv", [
        "area,byte,type,name,device",
        "mcmb2.up,0,u8,any_up,",
        "mcmb2.up,1,u8,t5_up,terminal=5",
        "mcmb2.up,2,u8,slot3_up,slot=3",
        "mcmb2.up,3,u8,other_fid,frame_id=0x8001",
        "mcmb2.down,0,u8,slot2_down,slot=2",
        "mcmb2.down,1,u8,fid_down,frame_id=0x8006",
        ])
    cap = CAPTURES / "mcmb2_polled_connect.pcap"
    names = ["vrshark.io." + n for n in ("any_up", "t5_up", "slot3_up", "other_fid", "slot2_down", "fid_down")]
    for two_pass in (False, True):
        t.expect(cap, 3, {"vrshark.io.any_up": [0x10, 0x11, 0x12], "vrshark.io.t5_up": None,
                          "vrshark.io.slot3_up": 0x12, "vrshark.io.other_fid": None}, two_pass=two_pass)
        t.expect(cap, 7, {"vrshark.io.t5_up": 0x11}, two_pass=two_pass)
        t.expect(cap, 4, {"vrshark.io.slot2_down": 0xA1, "vrshark.io.fid_down": [0xA0, 0xA1, 0xA2]},
                 two_pass=two_pass)
        assert all(f["vrshark.io.other_fid"] == "" for f in t.frames(cap, names, two_pass=two_pass).values())


def test_no_description_adds_nothing(conf_dir, work_dir):
    assert_nothing_added(conf_dir, work_dir,
                         ("crane_mcmb2.pcap", "mcmb2_polled_connect.pcap", "mcmb2_duplex_connect.pcap"))
