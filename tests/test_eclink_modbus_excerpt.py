"""A short excerpt of EC-Link over Modbus/TCP (captures/eclink_modbus_excerpt.pcap):
17 frames exported from a longer capture, two input images and one write of
a BU (192.168.2.41), too short for the evidence the heuristic accepts a
connection on, and an IO device (192.168.2.60) polled like a BU beside it
(0/1 inputs that pass every value check of an input image, 112 counting
registers written from 0).

Unpinned: the BU's image frames carry the note eclink_modbus.candidate with
the exact setting that decodes it, the IO device nothing. Pinned
(eclink_modbus.servers): the BU decoded from its first frame, in one pass
and in two, the IO device still plain. The preference's other forms (a
port, several entries, invalid ones) and the hint on a capture accepted
later (one pass only) too.
"""
import pytest

CAP = "eclink_modbus_excerpt.pcap"
BU, IO = "192.168.2.41", "192.168.2.60"
SETTING = "eclink_modbus.servers:192.168.2.41"
NEEDS = "3 input images with PCI at the BU's 125 ms cadence"
HINTS = {
    2: "Looks like a BU (input image), not recognised: needs %s (1 so far); to decode it now: %s"
       % (NEEDS, SETTING),
    5: "Looks like a BU (output write), not recognised: needs %s (1 so far) and 2 consistent output writes "
       "(1 so far); to decode it now: %s" % (NEEDS, SETTING),
    10: "Looks like a BU (input image), not recognised: needs %s (2 so far) and 2 consistent output writes "
        "(1 so far); to decode it now: %s" % (NEEDS, SETTING),
}
NAMES = ["ip.src", "ip.dst", "eclink.image", "eclink_modbus.candidate", "eclink_modbus.candidate_setting",
         "eclink_modbus", "eclink_modbus.accepted_in"]
# what the BU's three image frames hold (tools/capgen/eclink_modbus.py, excerpt())
INPUT = {"eclink.image": "input", "eclink.cci": 6, "eclink.cai": 2, "eclink.bu_state": 0x11,
         "eclink.armed_ru": 0x4242, "eclink.ru_battery": 77, "eclink.ru_rssi": 88, "eclink.joystick1": 370,
         "eclink.joystick4": -12, "eclink.encoder": 42, "eclink_modbus.server": "192.168.2.41:502",
         "eclink_modbus.candidate": None, "eclink_modbus.accepted_in": None}
DECODED = {2: dict(INPUT, **{"eclink.pci": 40}),
           5: {"eclink.image": "output", "eclink.pco": 7, "eclink.cco": 3, "eclink.cao": 6,
               "eclink.cmd_to_ru": "544f2d52552d434f4d4d414e442d3136", "eclink_modbus.candidate": None},
           10: dict(INPUT, **{"eclink.pci": 41})}


@pytest.mark.parametrize("two_pass", [False, True])
def test_unpinned_the_bu_gets_the_setting_the_io_device_nothing(tshark, capture_file, two_pass):
    cap = capture_file(CAP)
    got = tshark.frames(cap, NAMES, two_pass=two_pass)
    assert len(got) == 17
    noted = {f: v for f, v in got.items() if v["eclink_modbus.candidate"]}
    assert sorted(noted) == sorted(HINTS)
    assert {v["eclink_modbus.candidate_setting"] for v in noted.values()} == {SETTING}
    # nothing decoded: the setting's field alone, the protocol never
    assert [f for f, v in got.items() if v["eclink.image"] or v["eclink_modbus"] or v["eclink_modbus.accepted_in"]] \
        == []
    assert [f for f, v in got.items() if IO in (v["ip.src"], v["ip.dst"]) and v["eclink_modbus.candidate_setting"]] \
        == []
    exp = tshark.experts(cap, two_pass=two_pass)
    assert exp == {f: [text] for f, text in HINTS.items()}
    for f in HINTS:
        tshark.expect(cap, f, {"_ws.expert.severity": 0x00400000, "_ws.expert.group": 0x05000000},  # note, undecoded
                      two_pass=two_pass)


@pytest.mark.parametrize("two_pass", [False, True])
@pytest.mark.parametrize("entry", ["192.168.2.41", " 192.168.2.41:502 ", "10.0.0.9,192.168.2.41"])
def test_pinned_the_bu_is_decoded_from_its_first_frame(tshark, capture_file, two_pass, entry):
    cap = capture_file(CAP)
    prefs = {"eclink_modbus.servers": entry}
    got = tshark.frames(cap, NAMES, prefs=prefs, two_pass=two_pass)
    assert sorted(f for f, v in got.items() if v["eclink.image"]) == sorted(DECODED)
    assert [f for f, v in got.items() if v["eclink_modbus.candidate"] or v["eclink_modbus.accepted_in"]] == []
    # every BU frame with Modbus data is EC-Link's, no IO device frame is
    assert [f for f, v in got.items() if v["eclink_modbus"] and BU not in (v["ip.src"], v["ip.dst"])] == []
    for f, expected in DECODED.items():
        tshark.expect(cap, f, expected, prefs=prefs, two_pass=two_pass)


def test_pinned_with_detection_off(tshark, capture_file):
    """detection = off: nothing is judged by evidence, the listed servers are decoded."""
    cap = capture_file(CAP)
    off = {"eclink_modbus.detection": "off"}
    assert tshark.fields(cap, ["frame.number"], prefs=off, display_filter="eclink_modbus.candidate || eclink") == []
    got = tshark.frames(cap, ["eclink.pci"], prefs=dict(off, **{"eclink_modbus.servers": BU}),
                        display_filter="eclink.image")
    assert {f: v["eclink.pci"] for f, v in got.items()} == {2: "40", 5: "", 10: "41"}


def test_invalid_entries_are_named_once_and_the_rest_works(tshark, capture_file):
    cap = capture_file(CAP)
    value = "nonsense, 192.168.2.41, 10.0.0.300:5020, 10.0.0.1:70000,"
    proc = tshark.run(["-n", "-2", "-r", str(cap), "-o", "eclink_modbus.servers:%s" % value, "-Y", "eclink.image",
                       "-T", "fields", "-e", "frame.number"])
    assert proc.stdout.split() == ["2", "5", "10"]
    lines = [line for line in proc.stderr.splitlines() if "eclink_modbus.servers" in line]
    assert lines == ["vrshark: eclink_modbus.servers: \"nonsense\" is not an IPv4 address with an optional TCP "
                     "port, e.g. 192.168.2.41 or 192.168.2.41:5020: ignored; \"10.0.0.300:5020\" is not an IPv4 "
                     "address with an optional TCP port, e.g. 192.168.2.41 or 192.168.2.41:5020: ignored; "
                     "\"10.0.0.1:70000\": port 70000 is not 1..65535: ignored"]
    assert "Lua Error" not in proc.stdout + proc.stderr


def test_a_port_entry_decodes_that_port(tshark, capture_file):
    """192.168.2.41:5020: the BU on port 5020 is decoded from its first frame
    with no other setting (its port is taken like eclink_modbus.port's); the
    address alone names the Modbus/TCP port (502), not 5020."""
    cap = capture_file("eclink_modbus_port5020.pcap")
    with_port = tshark.frames(cap, ["eclink.image", "eclink_modbus.accepted_in", "modbus.func_code"],
                              prefs={"eclink_modbus.servers": "192.168.2.41:5020"})
    modbus = [f for f, v in with_port.items() if v["modbus.func_code"]]
    assert modbus[0] == 4 and len(modbus) == 16
    # every input image response and every write request: from the first on
    assert [f for f in modbus if with_port[f]["eclink.image"]] == [5, 6, 9, 10, 13, 14, 17, 18]
    assert [f for f, v in with_port.items() if v["eclink_modbus.accepted_in"]] == []
    assert tshark.fields(cap, ["frame.number"], prefs={"eclink_modbus.servers": "192.168.2.41"},
                         display_filter="modbus || eclink") == []


def test_hint_in_one_pass_until_accepted_none_on_the_second(tshark, capture_file):
    """A BU on port 5020 (eclink_modbus.port), accepted in frame 13: in one
    pass its image frames before it carry the note, with the port in the
    setting; on the second pass they are decoded and carry none."""
    cap = capture_file("eclink_modbus_port5020.pcap")
    prefs = {"eclink_modbus.port": "5020"}
    one = tshark.frames(cap, ["eclink_modbus.candidate_setting", "eclink.image"], prefs=prefs)
    noted = {f: v["eclink_modbus.candidate_setting"] for f, v in one.items() if v["eclink_modbus.candidate_setting"]}
    assert noted == {f: "eclink_modbus.servers:192.168.2.41:5020" for f in (5, 6, 9, 10)}
    assert [f for f in noted if one[f]["eclink.image"]] == []
    two = tshark.frames(cap, ["eclink_modbus.candidate", "eclink.image"], prefs=prefs, two_pass=True)
    assert [f for f, v in two.items() if v["eclink_modbus.candidate"]] == []
    assert all(two[f]["eclink.image"] for f in noted)


@pytest.mark.parametrize("name", ["eclink_modbus_basic.pcap", "modbus_plain_devices.pcap"])
def test_no_hint_on_a_second_pass_of_an_accepted_bu_nor_on_plain_devices(tshark, capture_file, name):
    got = tshark.fields(capture_file(name), ["frame.number"], two_pass=True, display_filter="eclink_modbus.candidate")
    assert got == []
