"""EG-Link: every single-packet expert message, exact text, on exactly the right
frames; the severity and group of each (docs/findings.md "How findings read"
table); the Info tags [relays open] and [undefined]."""
import pytest

from eglink_testlib import DISSECTOR_EXPERTS, dissector_experts, expect_frames, expert_kinds, messages

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
        4: ["RU disabled reason Unknown (0x04): defined are 0 enabled, 1 tilted, 2 inactivity, "
            "3 other"],
        5: ["RU cable Unknown (0x02): only 0 and 1 are defined",
            "RU docked Unknown (0x03): only 0 and 1 are defined",
            "Encoder switch Unknown (0xff): only 0 and 1 are defined"],
        6: ["No RU is armed (Armed RU 0) but these RU fields are not 0: "
            "RU battery, joystick 2, switch 8, encoder"],
        7: ["Payload spare bytes are not 0: reserved for future use, the sender may use a "
            "newer layout than TS-0006"],
        8: ["BU state Unknown (0x05): not defined in TS-0006",
            "ES-Link relays open: BU state Unknown (0x05), an undefined state below Disarmed"],
        9: ["BU state Unknown (0x20): not defined in TS-0006"],
        10: ["EG-Link status Unknown (0x07): defined are 0..6",
             "EC-Link status Unknown (0xc8): defined are 0..6",
             "C-Link status Unknown (0x09): defined are 0..6"],
        11: ["RU state Unknown (0x05): defined are 0..4"],
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
        # TS-0006 4.1.2: links in use reporting a fault
        1: ["ES-Link relays open: BU state Initial (0x00), the BU is not fully operative yet",
            "EG-Link status No link (2): the link is not operating: no valid data has been received",
            "C-Link status No link (2): the link is not operating: no valid data has been received"],
        2: ["ES-Link relays open: BU state Stopped (0x01), the armed RU asked the BU to stop",
            "RU stopped (stop switch, free-fall/shock sensor or RU fault): ES-Link relays open"],
        3: ["ES-Link relays open: BU state External link error (0x02), monitoring found an "
            "error on the EC-Link or EG-Link",
            "EG-Link status Link error (3): a configuration error keeps the link from operating",
            "EC-Link status Interface error (4): the link's interface module reports an error",
            "C-Link status Data error (5): the link is up, but the data exchanged is in error"],
        4: ["ES-Link relays open: BU state Blocked (0x03), contact with the armed RU is lost: "
            "switch the RU on and arm it again"],
        5: ["ES-Link relays open: BU state Failed (0x04), the BU self-test found a fatal "
            "internal error"],
        # TS-0006 4.1.3: an armed RU is not in state Initial (no RU armed yet)
        7: ["Armed RU 0xbeef but RU state Initial (0): Initial means no RU is armed yet"],
        # TS-0006 4.1.3: RU state 1 is used inside the BU only
        8: ["RU state 1 (Disarmed) on the wire: TS-0006 uses it only inside the BU"],
        # TS-0006 4.1.2: Passive is reported on the C-Link only
        13: ["EG-Link status Passive: only the C-Link reports Passive"],
    }


def test_relays_open_is_a_warning(tshark, capture_file):
    cap = capture_file("eglink_states.pcap")
    shown = tshark.frames(cap, ["eglink.relays_open"],
                          display_filter="eglink.bu_state.relays_open && _ws.expert.severity == warning"
                                         " && _ws.expert.group == response")
    assert sorted(shown) == [1, 2, 3, 4, 5]
    assert sorted(tshark.frames(cap, [], display_filter="eglink.relays_open == 1")) == [1, 2, 3, 4, 5]


# docs/findings.md "How findings read": (severity, group) of every expert the
# dissector raises.
VOICE = {
    # safety state the BU reports
    "eglink.bu_state.relays_open": ("warning", "response code"),
    "eglink.ru_state.stopped": ("warning", "response code"),
    # undefined or out-of-range values
    "eglink.bu_state.unknown": ("error", "protocol"),
    "eglink.link_status.unknown": ("error", "protocol"),
    "eglink.vlaps.range": ("error", "protocol"),
    "eglink.ru_state.unknown": ("error", "protocol"),
    "eglink.ru_battery.range": ("error", "protocol"),
    "eglink.ru_rssi.range": ("error", "protocol"),
    "eglink.flag.invalid": ("error", "protocol"),
    "eglink.ru_disabled.unknown": ("error", "protocol"),
    "eglink.joystick.range": ("error", "protocol"),
    "eglink.armed_ru.unarmed_data": ("error", "protocol"),
    # damaged packets
    "eglink.crc.bad": ("error", "checksum"),
    "eglink.size.mismatch": ("error", "malformed"),
    "eglink.size.invalid": ("error", "malformed"),
    "eglink.too_short": ("error", "malformed"),
    # contract deviations that do not force the safe state
    "eglink.revision.unknown": ("warning", "protocol"),
    "eglink.origin.nonzero": ("warning", "protocol"),
    "eglink.origin.zero": ("warning", "protocol"),
    "eglink.spare.nonzero": ("warning", "protocol"),
    "eglink.payload_spare.nonzero": ("warning", "protocol"),
    # TS-0006 4.1.2 / 4.1.3: Passive where it is not allowed, RU state 1 on the wire
    "eglink.link_status.passive": ("warning", "protocol"),
    "eglink.ru_state.disarmed": ("note", "protocol"),
    # TS-0006 4.1-4.1.3: fields that contradict each other; a link in use
    # reporting a fault, as the BU reports its safety state
    "eglink.fields_disagree": ("warning", "protocol"),
    "eglink.link_status.fault": ("warning", "response code"),
    # what Wireshark says of its own kind: a packet type it cannot decode, a
    # CRC that another variant explains
    "eglink.type.unknown": ("warning", "undecoded"),
    "eglink.crc.variant": ("warning", "checksum"),
}
FINDING_CAPTURES = ["eglink_states.pcap", "eglink_range.pcap", "eglink_header.pcap",
                    "eglink_wrong_size.pcap", "eglink_unknown_type.pcap", "eglink_bad_crc.pcap",
                    "eglink_crc_variants.pcap"]


def test_severity_and_group_of_every_expert(tshark, capture_file):
    assert set(VOICE) == DISSECTOR_EXPERTS
    seen = {}
    for name in FINDING_CAPTURES:
        for expert, kinds in expert_kinds(tshark, capture_file(name)).items():
            seen.setdefault(expert, set()).update(kinds)
    # every expert is raised by one of the captures, always with its one kind
    assert seen == {name: {kind} for name, kind in VOICE.items()}


def test_relays_item_right_after_bu_state(tshark, capture_file):
    """In the tree the generated relays item follows the BU state item directly
    (its expert info sits on the BU state)."""
    text = tshark.verbose(capture_file("eglink_states.pcap"))
    items = [line.strip() for line in text.splitlines()
             if line.startswith(" " * 8) and not line.startswith(" " * 9)]
    bu = [i for i, line in enumerate(items) if line.startswith("BU state: ")]
    assert len(bu) == 13
    assert [items[i + 1] for i in bu] == ["[ES-Link relays: Open]"] * 5 + \
        ["[ES-Link relays: Closed]"] * 8


def test_info_names_the_states(tshark, capture_file):
    """Info says which value is the BU state and which the armed RU's state,
    and tags every VRPI whose ES-Link relays are open."""
    expect_frames(tshark, capture_file("eglink_states.pcap"), {
        1: {"_ws.col.Info": "VRPI BU=Initial [relays open]"},
        2: {"_ws.col.Info": "VRPI BU=Stopped RU 0xbeef=Stopped [relays open]"},
        3: {"_ws.col.Info": "VRPI BU=External link error [relays open]"},
        4: {"_ws.col.Info": "VRPI BU=Blocked [relays open]"},
        5: {"_ws.col.Info": "VRPI BU=Failed [relays open]"},
        6: {"_ws.col.Info": "VRPI BU=Disarmed Unarmed RUs=3"},
        7: {"_ws.col.Info": "VRPI BU=Armed RU 0xbeef=Initial"},
        8: {"_ws.col.Info": "VRPI BU=Armed RU 0xbeef=Disarmed"},
        12: {"_ws.col.Info": "VRPI BU=Armed RU 0xbeef=Enabled"},
        13: {"_ws.col.Info": "VRPI BU=Armed RU 0xbeef=Enabled J1=1000 J2=-1000 J3=1 J4=-1"},
    })


def test_info_relays_open_in_a_session(tshark, capture_file):
    """The stop in eglink_analysis_session.pcap: every VRPI of it is tagged, the
    packets around it are not."""
    cap = capture_file("eglink_analysis_session.pcap")
    got = tshark.frames(cap, ["eglink.type", "eglink.relays_open", "_ws.col.Info"],
                        display_filter="frame.number >= 39 && frame.number <= 52")
    tagged = sorted(n for n, f in got.items() if "[relays open]" in f["_ws.col.Info"])
    assert tagged == [41, 43, 48, 50]
    assert tagged == sorted(n for n, f in got.items() if f["eglink.relays_open"] == "1")
    expect_frames(tshark, cap, {
        39: {"_ws.col.Info": "VRPI BU=Armed RU 0xbeef=Enabled"},
        41: {"_ws.col.Info": "VRPI BU=Stopped RU 0xbeef=Stopped [relays open]"},
        50: {"_ws.col.Info": "VRPI BU=Stopped RU 0xbeef=Stopped [relays open]"},
        52: {"_ws.col.Info": "VRPI BU=Armed RU 0xbeef=Enabled"},
    })


def test_info_undefined(tshark, capture_file):
    """[undefined] on every VRPI with an undefined or out-of-range value; an
    undefined state reads Unknown (0x..)."""
    expect_frames(tshark, capture_file("eglink_range.pcap"), {
        1: {"_ws.col.Info": "VRPI BU=Armed RU 0xbeef=Enabled J1=1001 J2=-1001 J3=32767 J4=-32768 "
                            "[undefined]"},
        2: {"_ws.col.Info": "VRPI BU=Armed RU 0xbeef=Enabled [undefined]"},
        3: {"_ws.col.Info": "VRPI BU=Armed RU 0xbeef=Enabled [undefined]"},
        4: {"_ws.col.Info": "VRPI BU=Armed RU 0xbeef=Armed [undefined]"},
        5: {"_ws.col.Info": "VRPI BU=Armed RU 0xbeef=Enabled [undefined]"},
        6: {"_ws.col.Info": "VRPI BU=Disarmed Unarmed RUs=0 J2=10 [undefined]"},
        7: {"_ws.col.Info": "VRPI BU=Armed RU 0xbeef=Enabled"},      # spare: a warning only
        8: {"_ws.col.Info": "VRPI BU=Unknown (0x05) [relays open] [undefined]"},
        9: {"_ws.col.Info": "VRPI BU=Unknown (0x20) [undefined]"},
        10: {"_ws.col.Info": "VRPI BU=Armed RU 0xbeef=Enabled [undefined]"},
        11: {"_ws.col.Info": "VRPI BU=Armed RU 0xbeef=Unknown (0x05) [undefined]"},
        # no RU armed, yet its state says stopped: shown, relays open
        12: {"_ws.col.Info": "VRPI BU=Disarmed Unarmed RUs=0 RU 0x0000=Stopped [relays open] "
                             "[undefined]"},
    })


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
    cap = capture_file("eglink_wrong_size.pcap")
    # Size wrong, all 46 bytes decoded
    tshark.expect(cap, 1, {"eglink.joystick4": 400, "eglink.switch1": 0, "eglink.switch4": 0,
                           "eglink.encoder": 0})
    # 30 bytes: up to switch 4
    tshark.expect(cap, 2, {"eglink.joystick4": 400, "eglink.switch1": 0, "eglink.switch4": 0,
                           "eglink.encoder": None})
    # 4 bytes beyond the VRPI layout
    tshark.expect(cap, 3, {"eglink.extra_payload": "00000000"})
    # the CRC is at the end of the datagram; frames 10-12 have no room for one
    expect_frames(tshark, cap, {n: {"eglink.crc.status": 1 if n <= 9 else None}
                                for n in range(1, 13)})
    # the header decoded as far as present
    tshark.expect(cap, 10, {"eglink.origin": "0x1001", "eglink.size": 46})
    tshark.expect(cap, 11, {"eglink.origin": "0x1001", "eglink.size": None})


def test_size_experts_are_malformed_errors(tshark, capture_file):
    shown = tshark.frames(capture_file("eglink_wrong_size.pcap"), [],
                          display_filter="_ws.expert.group == malformed && _ws.expert.severity == error")
    assert sorted(shown) == list(range(1, 14))


def test_unknown_types(tshark, capture_file):
    msg = ("Unknown packet type %s: TS-0006 defines VRPI, VRPO, VRCI, VRCO, VRAI and VRAO; "
           "only the header and CRC are decoded")
    got = messages(tshark, capture_file("eglink_unknown_type.pcap"))
    assert got == {2: [msg % "VRXI"], 3: [msg % "VRPX"], 4: [msg % "VRSI"]}
    expect_frames(tshark, capture_file("eglink_unknown_type.pcap"), {
        2: {"_ws.col.Info": "VRXI (unknown type) 6 bytes"},
        3: {"_ws.col.Info": "VRPX (unknown type) 5 bytes"},
        4: {"_ws.col.Info": "VRSI (unknown type) 0 bytes"},
    })
