"""EG-Link: every field of every packet type, exact values, asserted by field name."""
import pytest

from eglink_testlib import expect_frames, gen

ARMED = "eglink_armed.pcap"


def crc_of(frame_bytes_payload):
    return "0x%08x" % gen.crc32_mpeg2(frame_bytes_payload)


def test_vrpi_every_field(tshark, capture_file):
    # Frame 19 of the demo: full hoist down, switch 3 toggled down, potentiometer at 650.
    body = gen.packet("VRPI", gen.armed(joysticks=(-1000, 0, 0, 0),
                                        switches=(0, 0, -1, 650, 0, 0, 0, 0), encoder=8),
                      origin=0x1001, serial=8)[:-4]
    tshark.expect(capture_file(ARMED), 19, {
        "eglink.type": "VRPI", "eglink.revision": "0", "eglink.origin": "0x1001",
        "eglink.serial": "8", "eglink.size": "46", "eglink.spare": "0x00000000",
        "eglink.bu_state": "0x11", "eglink.relays_open": False, "eglink.vlaps": "1",
        "eglink.unarmed_rus": "0", "eglink.eg_link_status": "1", "eglink.ec_link_status": "0",
        "eglink.c_link_status": "1", "eglink.armed_ru": "0xbeef", "eglink.ru_state": "3",
        "eglink.ru_battery": "87", "eglink.ru_rssi": "72", "eglink.ru_cable": "0",
        "eglink.ru_docked": "0", "eglink.ru_disabled": "0", "eglink.joystick1": "-1000",
        "eglink.joystick2": "0", "eglink.joystick3": "0", "eglink.joystick4": "0",
        "eglink.switch1": "0", "eglink.switch2": "0", "eglink.switch3": "-1",
        "eglink.switch4": "650", "eglink.switch5": "0", "eglink.switch6": "0",
        "eglink.switch7": "0", "eglink.switch8": "0", "eglink.encoder": "8",
        "eglink.encoder_switch": "0", "eglink.payload_spare": "000000000000",
        "eglink.crc": crc_of(body), "eglink.crc.status": "1",
    })


def test_vrpi_extremes(tshark, capture_file):
    tshark.expect(capture_file("eglink_states.pcap"), 13, {
        "eglink.joystick1": 1000, "eglink.joystick2": -1000, "eglink.joystick3": 1,
        "eglink.joystick4": -1,
        "eglink.switch1": 1, "eglink.switch2": -1, "eglink.switch3": 1000, "eglink.switch4": 3,
        "eglink.switch5": 2, "eglink.switch6": 0, "eglink.switch7": -1, "eglink.switch8": 1,
        "eglink.encoder": 255, "eglink.vlaps": 0, "eglink.eg_link_status": 6,
    })


def test_vrpo_fields(tshark, capture_file):
    tshark.expect(capture_file(ARMED), 2, {
        "eglink.type": "VRPO", "eglink.origin": "0x0000", "eglink.serial": "0",
        "eglink.size": "66", "eglink.packet_number": "0",
        "eglink.periodic_data": gen.machine_data(0).hex(), "eglink.crc.status": "1"})


@pytest.mark.parametrize("frame, ptype, origin, serial, cmd, data", [
    (25, "VRCI", "0x1001", "11", "5", b"\x01\x00LIGHTS ON"),
    (43, "VRCO", "0x0000", "23", "1", b"\x10\x00OVERLOAD 95%"),
])
def test_command_fields(tshark, capture_file, frame, ptype, origin, serial, cmd, data):
    tshark.expect(capture_file(ARMED), frame, {
        "eglink.type": ptype, "eglink.origin": origin, "eglink.serial": serial,
        "eglink.size": "22", "eglink.command_id": cmd, "eglink.payload_spare": "00000000",
        "eglink.command_data": (data + bytes(16 - len(data))).hex(), "eglink.crc.status": "1"})


@pytest.mark.parametrize("frame, ptype, origin, cmd", [(26, "VRAO", "0x0000", "5"),
                                                       (45, "VRAI", "0x1001", "1")])
def test_ack_fields(tshark, capture_file, frame, ptype, origin, cmd):
    tshark.expect(capture_file(ARMED), frame, {
        "eglink.type": ptype, "eglink.origin": origin, "eglink.size": "2",
        "eglink.command_id": cmd, "eglink.command_data": None, "eglink.crc.status": "1"})


def test_armed_info_column(tshark, capture_file):
    got = expect_frames(tshark, capture_file(ARMED), {
        1: {"_ws.col.Info": "VRPI BU=Armed RU 0xbeef=Enabled"},
        2: {"_ws.col.Info": "VRPO Pkt=0 64 bytes"},
        19: {"_ws.col.Info": "VRPI BU=Armed RU 0xbeef=Enabled J1=-1000"},
        25: {"_ws.col.Info": "VRCI Cmd=5"},
        26: {"_ws.col.Info": "VRAO Cmd=5"},
        43: {"_ws.col.Info": "VRCO Cmd=1"},
        45: {"_ws.col.Info": "VRAI Cmd=1"},
    })
    assert len(got) == 58


def test_demo_rates(tshark, capture_file):
    got = tshark.frames(capture_file(ARMED), ["eglink.type", "frame.time_relative"])
    times = {t: [float(f["frame.time_relative"]) for _, f in sorted(got.items())
                 if f["eglink.type"] == t] for t in ("VRPI", "VRPO")}
    assert all(abs(b - a - 0.125) < 1e-6 for a, b in zip(times["VRPI"], times["VRPI"][1:]))
    assert all(abs(b - a - 0.100) < 1e-6 for a, b in zip(times["VRPO"], times["VRPO"][1:]))


# eglink_states.pcap: every BU state, then every RU state under an armed BU.
STATES = {
    1: {"eglink.bu_state": "0x00", "eglink.ru_state": 0, "eglink.relays_open": True},
    2: {"eglink.bu_state": "0x01", "eglink.ru_state": 4, "eglink.relays_open": True},
    3: {"eglink.bu_state": "0x02", "eglink.ru_state": 0, "eglink.relays_open": True},
    4: {"eglink.bu_state": "0x03", "eglink.ru_state": 0, "eglink.relays_open": True},
    5: {"eglink.bu_state": "0x04", "eglink.ru_state": 0, "eglink.relays_open": True},
    6: {"eglink.bu_state": "0x10", "eglink.ru_state": 0, "eglink.relays_open": False},
    7: {"eglink.bu_state": "0x11", "eglink.ru_state": 0, "eglink.relays_open": False},
    8: {"eglink.bu_state": "0x11", "eglink.ru_state": 1, "eglink.relays_open": False},
    9: {"eglink.bu_state": "0x11", "eglink.ru_state": 2, "eglink.relays_open": False,
        "eglink.ru_disabled": 1},
    10: {"eglink.bu_state": "0x11", "eglink.ru_state": 2, "eglink.relays_open": False,
         "eglink.ru_disabled": 2},
    11: {"eglink.bu_state": "0x11", "eglink.ru_state": 2, "eglink.relays_open": False,
         "eglink.ru_disabled": 3},
    12: {"eglink.bu_state": "0x11", "eglink.ru_state": 3, "eglink.relays_open": False,
         "eglink.ru_cable": 1, "eglink.ru_docked": 1, "eglink.encoder_switch": 1},
    13: {"eglink.bu_state": "0x11", "eglink.ru_state": 3, "eglink.relays_open": False},
}
LINKS = ["eglink.eg_link_status", "eglink.ec_link_status", "eglink.c_link_status"]


def test_every_state(tshark, capture_file):
    got = expect_frames(tshark, capture_file("eglink_states.pcap"), STATES)
    assert sorted(got) == list(range(1, 14))
    # every link status value 0..6 appears in one of the three link fields
    links = tshark.frames(capture_file("eglink_states.pcap"), LINKS)
    assert {int(f[n]) for f in links.values() for n in LINKS} == set(range(7))


def test_value_strings(tshark, capture_file):
    text = tshark.verbose(capture_file("eglink_states.pcap"))
    for line in ["BU state: Initial (0x00)", "BU state: Stopped (0x01)",
                 "BU state: External link error (0x02)", "BU state: Blocked (0x03)",
                 "BU state: Failed (0x04)", "BU state: Disarmed (0x10)", "BU state: Armed (0x11)",
                 "[ES-Link relays: Open]", "[ES-Link relays: Closed]",
                 "RU state: Initial (0)", "RU state: Disarmed (1)", "RU state: Armed (2)",
                 "RU state: Enabled (3)", "RU state: Stopped (4)",
                 "EG-Link status: No link (2)", "EG-Link status: Link error (3)",
                 "EC-Link status: Interface error (4)", "C-Link status: Data error (5)",
                 "EG-Link status: Passive (6)", "EC-Link status: Unused (0)",
                 "C-Link status: Operational (1)",
                 "RU disabled: Enabled (0)", "RU disabled: Disabled (tilted) (1)",
                 "RU disabled: Disabled (inactivity) (2)", "RU disabled: Disabled (other cause) (3)",
                 "RU cable: Cable (1)", "RU cable: Wireless (0)", "RU docked: Docked (1)",
                 "RU docked: Not docked (0)", "Encoder switch: Pushed (1)",
                 "Encoder switch: Released (0)", "RU battery: 87 %", "RU C-Link RSSI: 72 %",
                 "Packet ID: VRPI (Periodic Input, BU to controller)"]:
        assert "        " + line + "\n" in text or "    " + line + "\n" in text, line


def test_undefined_values_read_unknown_hex(tshark, capture_file):
    """An undefined value reads "Unknown (0x42)" in the tree, whatever the field's base."""
    text = tshark.verbose(capture_file("eglink_range.pcap"))
    for line in ["BU state: Unknown (0x05)", "BU state: Unknown (0x20)",
                 "RU state: Unknown (0x05)", "RU disabled: Unknown (0x04)",
                 "RU cable: Unknown (0x02)", "RU docked: Unknown (0x03)",
                 "Encoder switch: Unknown (0xff)", "EG-Link status: Unknown (0x07)",
                 "EC-Link status: Unknown (0xc8)", "C-Link status: Unknown (0x09)",
                 "RU battery: 101 %", "RU C-Link RSSI: 255 %"]:
        assert "        " + line + "\n" in text, line
    assert "Unknown (5)" not in text and "Unknown (200)" not in text
    # the field values stay numbers for filters and -T fields
    tshark.expect(capture_file("eglink_range.pcap"), 11, {"eglink.ru_state": "5"})
    tshark.expect(capture_file("eglink_range.pcap"), 10, {"eglink.ec_link_status": "200"})


def test_disarmed(tshark, capture_file):
    cap = capture_file("eglink_disarmed.pcap")
    want = {"eglink.bu_state": "0x10", "eglink.c_link_status": 6, "eglink.armed_ru": "0x0000"}
    got = tshark.frames(cap, list(want) + ["eglink.unarmed_rus", "_ws.col.Info"],
                        display_filter="eglink.type == \"VRPI\"")
    vrpi = [got[n] for n in sorted(got)]
    assert len(vrpi) == 12
    expect_frames(tshark, cap, {n: want for n in got}, display_filter="eglink.type == \"VRPI\"")
    assert [int(f["eglink.unarmed_rus"]) for f in vrpi] == [0] * 4 + [1] * 4 + [2] * 4
    assert vrpi[-1]["_ws.col.Info"] == "VRPI BU=Disarmed Unarmed RUs=2"


def test_vrpo_split(tshark, capture_file):
    cap = capture_file("eglink_vrpo_split.pcap")
    got = tshark.frames(cap, ["eglink.packet_number", "eglink.size", "_ws.col.Info"])
    assert sorted(got) == list(range(1, 10))
    expect_frames(tshark, cap, {
        n: {"eglink.packet_number": (n - 1) % 3, "eglink.size": [490, 490, 226][(n - 1) % 3]}
        for n in got})
    tshark.expect(cap, 1, {"_ws.col.Info": "VRPO Pkt=0 488 bytes"})
    tshark.expect(cap, 2, {"_ws.col.Info": "VRPO Pkt=1 488 bytes"})
    assert got[3]["_ws.col.Info"].startswith("VRPO Pkt=2 224 bytes")


def test_commands_capture(tshark, capture_file):
    got = tshark.frames(capture_file("eglink_commands.pcap"),
                        ["eglink.type", "eglink.serial", "eglink.command_id"],
                        display_filter="eglink.command_id")
    commands = [got[n] for n in sorted(got)]
    assert [(f["eglink.type"], f["eglink.command_id"]) for f in commands] == \
        [("VRCI", "7")] * 3 + [("VRAO", "7")] + [("VRCO", "3")] * 2 + [("VRAI", "3")]
    serials = [int(f["eglink.serial"]) for f in commands if f["eglink.type"] == "VRCI"]
    assert len(set(serials)) == 3 and serials == sorted(serials)


def test_unknown_type_decodes_header(tshark, capture_file):
    expect_frames(tshark, capture_file("eglink_unknown_type.pcap"), {
        2: {"eglink.type": "VRXI", "eglink.size": 6, "eglink.unknown_payload": "010203040506",
            "eglink.crc.status": 1},
        3: {"eglink.type": "VRPX", "eglink.size": 5, "eglink.unknown_payload": "0000616263",
            "eglink.crc.status": 1},
        4: {"eglink.type": "VRSI", "eglink.size": 0, "eglink.unknown_payload": None,
            "eglink.crc.status": 1},
    })
