"""EG-Link: every field of every packet type, exact values (-T fields)."""
import pytest

from eglink_testlib import gen

VRPI_FIELDS = ["eglink.type", "eglink.revision", "eglink.origin", "eglink.serial", "eglink.size",
               "eglink.spare", "eglink.bu_state", "eglink.relays_open", "eglink.vlaps",
               "eglink.unarmed_rus", "eglink.eg_link_status", "eglink.ec_link_status",
               "eglink.c_link_status", "eglink.armed_ru", "eglink.ru_state", "eglink.ru_battery",
               "eglink.ru_rssi", "eglink.ru_cable", "eglink.ru_docked", "eglink.ru_disabled",
               "eglink.joystick1", "eglink.joystick2", "eglink.joystick3", "eglink.joystick4",
               "eglink.switch1", "eglink.switch2", "eglink.switch3", "eglink.switch4",
               "eglink.switch5", "eglink.switch6", "eglink.switch7", "eglink.switch8",
               "eglink.encoder", "eglink.encoder_switch", "eglink.payload_spare",
               "eglink.crc", "eglink.crc.status"]


def row(tshark, capture, frame, fields):
    rows = tshark.fields(capture, fields, display_filter="frame.number == %d" % frame)
    assert len(rows) == 1
    return dict(zip(fields, rows[0]))


def crc_of(frame_bytes_payload):
    return "0x%08x" % gen.crc32_mpeg2(frame_bytes_payload)


def test_vrpi_every_field(tshark, capture_file):
    # Frame 19 of the demo: full hoist down, switch 3 toggled down, potentiometer at 650.
    got = row(tshark, capture_file("eglink_armed.pcap"), 19, VRPI_FIELDS)
    body = gen.packet("VRPI", gen.armed(joysticks=(-1000, 0, 0, 0),
                                        switches=(0, 0, -1, 650, 0, 0, 0, 0), encoder=8),
                      origin=0x1001, serial=8)[:-4]
    assert got == {
        "eglink.type": "VRPI", "eglink.revision": "0", "eglink.origin": "0x1001",
        "eglink.serial": "8", "eglink.size": "46", "eglink.spare": "0x00000000",
        "eglink.bu_state": "0x11", "eglink.relays_open": "0", "eglink.vlaps": "1",
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
    }


def test_vrpi_extremes(tshark, capture_file):
    got = row(tshark, capture_file("eglink_states.pcap"), 13, VRPI_FIELDS)
    assert [got["eglink.joystick%d" % i] for i in range(1, 5)] == ["1000", "-1000", "1", "-1"]
    assert [got["eglink.switch%d" % i] for i in range(1, 9)] == \
        ["1", "-1", "1000", "3", "2", "0", "-1", "1"]
    assert got["eglink.encoder"] == "255"
    assert got["eglink.vlaps"] == "0"
    assert got["eglink.eg_link_status"] == "6"


def test_vrpo_fields(tshark, capture_file):
    fields = ["eglink.type", "eglink.origin", "eglink.serial", "eglink.size",
              "eglink.packet_number", "eglink.periodic_data", "eglink.crc.status"]
    got = row(tshark, capture_file("eglink_armed.pcap"), 2, fields)
    assert got == {"eglink.type": "VRPO", "eglink.origin": "0x0000", "eglink.serial": "0",
                   "eglink.size": "66", "eglink.packet_number": "0",
                   "eglink.periodic_data": gen.machine_data(0).hex(), "eglink.crc.status": "1"}


@pytest.mark.parametrize("frame, ptype, origin, serial, cmd, data", [
    (25, "VRCI", "0x1001", "11", "5", b"\x01\x00LIGHTS ON"),
    (43, "VRCO", "0x0000", "23", "1", b"\x10\x00OVERLOAD 95%"),
])
def test_command_fields(tshark, capture_file, frame, ptype, origin, serial, cmd, data):
    fields = ["eglink.type", "eglink.origin", "eglink.serial", "eglink.size",
              "eglink.command_id", "eglink.payload_spare", "eglink.command_data",
              "eglink.crc.status"]
    got = row(tshark, capture_file("eglink_armed.pcap"), frame, fields)
    assert got == {"eglink.type": ptype, "eglink.origin": origin, "eglink.serial": serial,
                   "eglink.size": "22", "eglink.command_id": cmd,
                   "eglink.payload_spare": "00000000",
                   "eglink.command_data": (data + bytes(16 - len(data))).hex(),
                   "eglink.crc.status": "1"}


@pytest.mark.parametrize("frame, ptype, origin, cmd", [(26, "VRAO", "0x0000", "5"),
                                                       (45, "VRAI", "0x1001", "1")])
def test_ack_fields(tshark, capture_file, frame, ptype, origin, cmd):
    fields = ["eglink.type", "eglink.origin", "eglink.size", "eglink.command_id",
              "eglink.command_data", "eglink.crc.status"]
    got = row(tshark, capture_file("eglink_armed.pcap"), frame, fields)
    assert got == {"eglink.type": ptype, "eglink.origin": origin, "eglink.size": "2",
                   "eglink.command_id": cmd, "eglink.command_data": "",
                   "eglink.crc.status": "1"}


def test_armed_info_column(tshark, capture_file):
    info = tshark.field(capture_file("eglink_armed.pcap"), "_ws.col.Info")
    assert info[0] == "VRPI Armed RU=0xbeef Enabled"
    assert info[1] == "VRPO Pkt=0 64 bytes"
    assert info[18] == "VRPI Armed RU=0xbeef Enabled J1=-1000"
    assert info[24:26] == ["VRCI Cmd=5", "VRAO Cmd=5"]
    assert (info[42], info[44]) == ("VRCO Cmd=1", "VRAI Cmd=1")
    assert len(info) == 58


def test_demo_rates(tshark, capture_file):
    rows = tshark.fields(capture_file("eglink_armed.pcap"), ["eglink.type", "frame.time_relative"])
    times = {t: [float(r[1]) for r in rows if r[0] == t] for t in ("VRPI", "VRPO")}
    assert all(abs(b - a - 0.125) < 1e-6 for a, b in zip(times["VRPI"], times["VRPI"][1:]))
    assert all(abs(b - a - 0.100) < 1e-6 for a, b in zip(times["VRPO"], times["VRPO"][1:]))


def test_every_state(tshark, capture_file):
    rows = tshark.fields(capture_file("eglink_states.pcap"),
                         ["eglink.bu_state", "eglink.ru_state", "eglink.relays_open",
                          "eglink.ru_disabled", "eglink.ru_cable", "eglink.ru_docked",
                          "eglink.encoder_switch", "eglink.eg_link_status",
                          "eglink.ec_link_status", "eglink.c_link_status"])
    assert [r[0] for r in rows] == ["0x00", "0x01", "0x02", "0x03", "0x04", "0x10"] + ["0x11"] * 7
    assert [r[1] for r in rows] == ["0", "4", "0", "0", "0", "0", "0", "1", "2", "2", "2", "3", "3"]
    assert [r[2] for r in rows] == ["1"] * 5 + ["0"] * 8
    assert [r[3] for r in rows][8:11] == ["1", "2", "3"]
    assert rows[11][4:7] == ["1", "1", "1"]
    assert {r[7] for r in rows} | {r[8] for r in rows} | {r[9] for r in rows} == \
        {str(i) for i in range(7)}


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
                 "Encoder switch: Released (0)", "RU battery: 87%", "RU C-Link RSSI: 72%",
                 "Packet ID: VRPI (Periodic Input, BU to controller)"]:
        assert "        " + line + "\n" in text or "    " + line + "\n" in text, line


def test_disarmed(tshark, capture_file):
    rows = tshark.fields(capture_file("eglink_disarmed.pcap"),
                         ["eglink.bu_state", "eglink.unarmed_rus", "eglink.c_link_status",
                          "eglink.armed_ru", "_ws.col.Info"], display_filter="eglink.type == \"VRPI\"")
    assert {r[0] for r in rows} == {"0x10"}
    assert [r[1] for r in rows] == ["0"] * 4 + ["1"] * 4 + ["2"] * 4
    assert {r[2] for r in rows} == {"6"}
    assert {r[3] for r in rows} == {"0x0000"}
    assert rows[-1][4] == "VRPI Disarmed Unarmed RUs=2"


def test_vrpo_split(tshark, capture_file):
    rows = tshark.fields(capture_file("eglink_vrpo_split.pcap"),
                         ["eglink.packet_number", "eglink.size", "_ws.col.Info"])
    assert [r[0] for r in rows] == ["0", "1", "2"] * 3
    assert [r[1] for r in rows] == ["490", "490", "226"] * 3
    info = [r[2] for r in rows]
    assert info[:2] == ["VRPO Pkt=0 488 bytes", "VRPO Pkt=1 488 bytes"]
    assert info[2].startswith("VRPO Pkt=2 224 bytes")


def test_commands_capture(tshark, capture_file):
    rows = tshark.fields(capture_file("eglink_commands.pcap"),
                         ["eglink.type", "eglink.serial", "eglink.command_id"],
                         display_filter="eglink.command_id")
    assert [(r[0], r[2]) for r in rows] == [("VRCI", "7")] * 3 + [("VRAO", "7")] + \
        [("VRCO", "3")] * 2 + [("VRAI", "3")]
    serials = [int(r[1]) for r in rows if r[0] == "VRCI"]
    assert len(set(serials)) == 3 and serials == sorted(serials)


def test_unknown_type_decodes_header(tshark, capture_file):
    rows = tshark.fields(capture_file("eglink_unknown_type.pcap"),
                         ["eglink.type", "eglink.size", "eglink.unknown_payload", "eglink.crc.status"])
    assert rows[1:4] == [["VRXI", "6", "010203040506", "1"], ["VRPX", "5", "0000616263", "1"],
                         ["VRSI", "0", "", "1"]]
