"""EC-Link raw images (the "eclink" dissector on a user link-layer type), as a
Profibus DP user decodes a hex dump: text2pcap -l 147, then tshark with a
user_dlts entry."""
import struct
import subprocess

import pytest

USER_DLT = 'uat:user_dlts:"User 0 (DLT=147)","eclink","0","","0",""'


def input_image(**over):
    img = bytearray(64)
    img[0:4] = bytes([5, 2, 1, 9])
    img[20:26] = bytes([0x11, 1, 2, 1, 1, 1])
    img[26:28] = struct.pack(">H", 0x1234)
    img[28:34] = bytes([3, 80, 90, 1, 0, 0])
    img[34:42] = struct.pack(">4h", 500, -250, 0, 1000)
    img[42:58] = struct.pack(">8h", 1, -1, 0, 3, 0, 0, 0, 1000)
    img[58:60] = bytes([200, 1])
    for off, val in over.items():
        img[int(off[1:])] = val
    return bytes(img)


def output_image(size=300, block=1, spare=0, std=True):
    img = bytearray(224 if std else 20)
    img[0:4] = bytes([7, 8, 0, 3])
    img[4:20] = b"HELLO-RU".ljust(16, b"\0")
    if std:
        img[20:24] = struct.pack(">HBB", size, block, spare)
        img[24:224] = bytes(i & 0xFF for i in range(200))
    return bytes(img)


@pytest.fixture
def raw_capture(work_dir):
    def make(*images):
        txt = work_dir / "images.txt"
        txt.write_text("".join("0000 " + " ".join("%02x" % b for b in img) + "\n" for img in images))
        pcap = work_dir / "images.pcap"
        subprocess.run(["text2pcap", "-q", "-l", "147", str(txt), str(pcap)], check=True)
        pcap.chmod(0o644)
        return pcap
    return make


def test_input_image_fields(tshark, raw_capture):
    cap = raw_capture(input_image())
    names = ["eclink.image", "eclink.pci", "eclink.cci", "eclink.pai", "eclink.cai", "eclink.bu_state",
             "eclink.vlaps", "eclink.unarmed_rus", "eclink.eg_link_status", "eclink.ec_link_status",
             "eclink.c_link_status", "eclink.armed_ru", "eclink.ru_state", "eclink.ru_battery",
             "eclink.ru_rssi", "eclink.ru_cable", "eclink.ru_docked", "eclink.ru_disabled",
             "eclink.joystick1", "eclink.joystick2", "eclink.joystick3", "eclink.joystick4",
             "eclink.switch1", "eclink.switch2", "eclink.switch4", "eclink.switch8",
             "eclink.encoder", "eclink.encoder_switch", "eclink.spare", "eclink.cmd_from_ru"]
    row = tshark.fields(cap, names, prefs={}, extra=["-o", USER_DLT])[0]
    assert row == ["input", "5", "2", "1", "9", "0x11", "1", "2", "1", "1", "1", "4660", "3", "80",
                   "90", "1", "0", "0", "500", "-250", "0", "1000", "1", "-1", "3", "1000",
                   "200", "1", "00000000", "00000000000000000000000000000000"]
    assert tshark.experts(cap, extra=["-o", USER_DLT]) == {}


def test_output_images(tshark, raw_capture):
    cap = raw_capture(output_image(), output_image(std=False))
    rows = tshark.fields(cap, ["eclink.image", "eclink.pco", "eclink.cco", "eclink.pao", "eclink.cao",
                               "eclink.cmd_to_ru", "eclink.periodic_size", "eclink.periodic_block",
                               "eclink.spare"], extra=["-o", USER_DLT])
    assert rows[0] == ["output", "7", "8", "0", "3", "48454c4c4f2d52550000000000000000", "300", "1", "00"]
    assert rows[1] == ["output", "7", "8", "0", "3", "48454c4c4f2d52550000000000000000", "", "", ""]
    data = tshark.field(cap, "eclink.periodic_data", extra=["-o", USER_DLT])
    assert data[0] == bytes(range(200)).hex()
    assert data[1] == ""


def test_input_checks(tshark, raw_capture):
    bad = input_image(b20=0x03, b21=4, b23=7, b28=5, b29=101, b30=150, b31=2, b33=4, b34=0x03,
                      b35=0xE9, b59=2, b61=1)
    stopped = input_image(b28=4)
    unarmed = input_image(b26=0, b27=0)
    cap = raw_capture(bad, stopped, unarmed)
    exp = tshark.experts(cap, extra=["-o", USER_DLT])
    assert exp[1] == [
        "ES-Link relays open: BU state Blocked (0x03)",
        "VLAPs 4 is out of range 0..3",
        "EG-Link status 7 is undefined (0..6)",
        "RU state 5 is undefined (0..4)",
        "RU battery 101 % is over 100 %",
        "RU C-Link RSSI 150 % is over 100 %",
        "RU cable 2 is not 0 or 1",
        "RU disabled 4 is undefined (0..3)",
        "Joystick 1 position 1001 is out of range -1000..1000",
        "Encoder switch 2 is not 0 or 1",
        "Spare bytes 60..63 are not 0",
    ]
    assert exp[2] == ["RU stopped: ES-Link relays open"]
    assert exp[3][0] == "Armed RU is 0 but RU state is not 0"
    assert "Armed RU is 0 but Joystick 1 is not 0" in exp[3]
    relays = tshark.field(cap, "eclink.es_relays_open", extra=["-o", USER_DLT])
    assert relays == ["1", "", ""]


def test_output_checks(tshark, raw_capture):
    cap = raw_capture(output_image(size=60000, block=0, spare=5), output_image(size=150, block=1),
                      output_image(size=51200, block=255))
    exp = tshark.experts(cap, extra=["-o", USER_DLT])
    assert exp[1] == ["Periodic data size 60000 is over 51200", "Spare byte 23 is 0x05, not 0"]
    assert exp[2] == ["Periodic data block 1 is beyond the periodic data size 150 (blocks 0..0)"]
    assert 3 not in exp


def test_bad_length(tshark, raw_capture):
    cap = raw_capture(bytes(10))
    assert tshark.experts(cap, extra=["-o", USER_DLT]) == {
        1: ["10 bytes is not an EC-Link image (input 64, output 20 or 224)"]}
    assert tshark.field(cap, "_ws.col.Info", extra=["-o", USER_DLT]) == ["Not an EC-Link image (10 bytes)"]
