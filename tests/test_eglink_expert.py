"""EG-Link: every single-packet expert message, exact text, on exactly the right frames."""
import pytest

from eglink_testlib import dissector_experts, messages

CLEAN = ["eglink_armed.pcap", "eglink_disarmed.pcap", "eglink_commands.pcap",
         "eglink_vrpo_split.pcap", "eglink_heuristic.pcap"]


@pytest.mark.parametrize("name", CLEAN)
def test_clean_captures_have_no_findings(tshark, capture_file, name):
    assert messages(tshark, capture_file(name)) == {}


def test_range_violations(tshark, capture_file):
    assert messages(tshark, capture_file("eglink_range.pcap")) == {
        1: ["Joystick 1 position 1001 is outside -1000..+1000",
            "Joystick 2 position -1001 is outside -1000..+1000",
            "Joystick 3 position 32767 is outside -1000..+1000",
            "Joystick 4 position -32768 is outside -1000..+1000"],
        2: ["RU battery 101 % is above 100 %", "RU C-Link RSSI 255 % is above 100 %"],
        3: ["4 VLAPs reported: a BU has at most 3"],
        4: ["RU disabled reason 4 is not defined (0 enabled, 1 tilted, 2 inactivity, 3 other)"],
        5: ["RU cable is 2: only 0 and 1 are defined", "RU docked is 3: only 0 and 1 are defined",
            "Encoder switch is 255: only 0 and 1 are defined"],
        6: ["No RU is armed (Armed RU 0) but these RU fields are not 0: "
            "RU battery, joystick 2, switch 8, encoder"],
        7: ["Payload spare bytes are not 0: reserved for future use, the sender may use a "
            "newer layout than TS-0006"],
        8: ["BU state 0x05 is not defined in TS-0006",
            "ES-Link relays open: BU state undefined (0x05), an undefined state below Disarmed"],
        9: ["BU state 0x20 is not defined in TS-0006"],
        10: ["EG-Link status 7 is not a defined link status (0..6)",
             "EC-Link status 200 is not a defined link status (0..6)",
             "C-Link status 9 is not a defined link status (0..6)"],
        11: ["RU state 5 is not defined in TS-0006 (0..4)"],
        12: ["No RU is armed (Armed RU 0) but these RU fields are not 0: RU state",
             "RU stopped (stop switch, free-fall/shock sensor or RU fault): ES-Link relays open"],
    }


def test_range_expert_names(tshark, capture_file):
    names = {n: sorted({e for e, _ in v})
             for n, v in dissector_experts(tshark, capture_file("eglink_range.pcap")).items()}
    assert names[1] == ["eglink.joystick.range"]
    assert names[2] == ["eglink.ru_battery.range", "eglink.ru_rssi.range"]
    assert names[3] == ["eglink.vlaps.range"]
    assert names[4] == ["eglink.ru_disabled.unknown"]
    assert names[5] == ["eglink.flag.invalid"]
    assert names[6] == ["eglink.armed_ru.unarmed_data"]
    assert names[7] == ["eglink.payload_spare.nonzero"]
    assert names[8] == ["eglink.bu_state.relays_open", "eglink.bu_state.unknown"]
    assert names[10] == ["eglink.link_status.unknown"]
    assert names[11] == ["eglink.ru_state.unknown"]
    assert names[12] == ["eglink.armed_ru.unarmed_data", "eglink.ru_state.stopped"]


def test_relays_open_and_stopped(tshark, capture_file):
    assert messages(tshark, capture_file("eglink_states.pcap")) == {
        1: ["ES-Link relays open: BU state Initial (0x00), the BU is not fully operative yet"],
        2: ["ES-Link relays open: BU state Stopped (0x01), the armed RU asked the BU to stop",
            "RU stopped (stop switch, free-fall/shock sensor or RU fault): ES-Link relays open"],
        3: ["ES-Link relays open: BU state External link error (0x02), monitoring found an "
            "error on the EC-Link or EG-Link"],
        4: ["ES-Link relays open: BU state Blocked (0x03), contact with the armed RU is lost: "
            "switch the RU on and arm it again"],
        5: ["ES-Link relays open: BU state Failed (0x04), the BU self-test found a fatal "
            "internal error"],
    }


def test_relays_open_is_a_warning(tshark, capture_file):
    rows = tshark.fields(capture_file("eglink_states.pcap"), ["frame.number"],
                         display_filter="eglink.bu_state.relays_open && _ws.expert.severity == warning")
    assert [r[0] for r in rows] == ["1", "2", "3", "4", "5"]
    rows = tshark.fields(capture_file("eglink_states.pcap"), ["frame.number"],
                         display_filter="eglink.relays_open == 1")
    assert [r[0] for r in rows] == ["1", "2", "3", "4", "5"]


def test_header_rules(tshark, capture_file):
    spare = ("reserved for future use, the sender may use a newer layout than TS-0006")
    assert messages(tshark, capture_file("eglink_header.pcap")) == {
        1: ["Revision 1: only revision 0 (the TS-0006 layout) is known, the payload may differ"],
        2: ["Origin is 0x1001 in a VRPO from the machine controller: it must be 0"],
        3: ["Origin is 0x0002 in a VRCO from the machine controller: it must be 0"],
        4: ["Origin is 0xffff in a VRAO from the machine controller: it must be 0"],
        5: ["Origin is 0 in a VRPI from the BU: the BU should send its unique ID"],
        6: ["Origin is 0 in a VRAI from the BU: the BU should send its unique ID"],
        7: ["Header spare is 0x00000100, not 0: " + spare],
        8: ["Payload spare bytes are not 0: " + spare],
        9: ["Payload spare bytes are not 0: " + spare],
    }


def test_sizes(tshark, capture_file):
    def fixed(ptype, size, got):
        return "A %s payload is %d bytes, this one has %d: decoded as far as it goes" % (
            ptype, size, got)
    vrpo = ("A VRPO payload is 2 to 490 bytes (packet number + up to 488 bytes of data), "
            "this one has %d: decoded as far as it goes")
    assert messages(tshark, capture_file("eglink_wrong_size.pcap")) == {
        1: ["Size says 40 payload bytes but the UDP payload carries 46 (UDP payload length - 20)"],
        2: [fixed("VRPI", 46, 30)],
        3: [fixed("VRPI", 46, 50)],
        4: [vrpo % 1],
        5: [vrpo % 500],
        6: [fixed("VRCI", 22, 20)],
        7: [fixed("VRCO", 22, 24)],
        8: [fixed("VRAI", 2, 4)],
        9: [fixed("VRAO", 2, 0)],
        10: ["Packet is 18 bytes, too short for packet ID, header and CRC (20 bytes)"],
        11: ["Packet is 8 bytes, too short for packet ID, header and CRC (20 bytes)"],
        12: ["Unknown packet type VRP: TS-0006 defines VRPI, VRPO, VRCI, VRCO, VRAI and VRAO; "
             "only the header and CRC are decoded",
             "Packet is 3 bytes, too short for packet ID, header and CRC (20 bytes)"],
        13: ["Size says 0 payload bytes but the UDP payload carries 2 (UDP payload length - 20)"],
    }


def test_sizes_decode_what_fits(tshark, capture_file):
    rows = tshark.fields(capture_file("eglink_wrong_size.pcap"),
                         ["eglink.joystick4", "eglink.switch1", "eglink.switch4", "eglink.encoder",
                          "eglink.extra_payload", "eglink.crc.status", "eglink.origin",
                          "eglink.size"])
    assert rows[0][:4] == ["400", "0", "0", "0"]          # Size wrong, all 46 bytes decoded
    assert rows[1][:4] == ["400", "0", "0", ""]           # 30 bytes: up to switch 4
    assert rows[2][4] == "00000000"                       # 4 bytes beyond the VRPI layout
    assert [r[5] for r in rows[:9]] == ["1"] * 9          # the CRC is at the end of the datagram
    assert [r[5] for r in rows[9:12]] == ["", "", ""]     # no room for a CRC
    assert rows[9][6:8] == ["0x1001", "46"]               # header decoded as far as present
    assert rows[10][6:8] == ["0x1001", ""]


def test_size_experts_are_malformed_errors(tshark, capture_file):
    rows = tshark.fields(capture_file("eglink_wrong_size.pcap"), ["frame.number"],
                         display_filter="_ws.expert.group == malformed && _ws.expert.severity == error")
    assert len(rows) == 13


def test_unknown_types(tshark, capture_file):
    msg = ("Unknown packet type %s: TS-0006 defines VRPI, VRPO, VRCI, VRCO, VRAI and VRAO; "
           "only the header and CRC are decoded")
    got = messages(tshark, capture_file("eglink_unknown_type.pcap"))
    assert got == {2: [msg % "VRXI"], 3: [msg % "VRPX"], 4: [msg % "VRSI"]}
    info = tshark.field(capture_file("eglink_unknown_type.pcap"), "_ws.col.Info")
    assert info[1:4] == ["VRXI (unknown type) 6 bytes", "VRPX (unknown type) 5 bytes",
                         "VRSI (unknown type) 0 bytes"]
