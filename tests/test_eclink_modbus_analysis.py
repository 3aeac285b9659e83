"""EC-Link over Modbus/TCP: handshake analysis, periodic output reassembly,
one pass and two passes agree."""
import re

import pytest

from conftest import assert_fields


def test_command_handshake(tshark, capture_file):
    cap = capture_file("eclink_modbus_basic.pcap")
    exp = tshark.experts(cap)
    assert exp[17] == ["New command from RU: CCI 3 -> 4"]
    # the command's frame is a link beside the acknowledgement, never a number in its text
    assert exp[26] == ["CAO 4 acknowledges the command from RU after 0.257 s"]
    assert exp[30] == ["New command to RU: CCO 7 -> 8"]
    assert exp[37] == ["CAI 8 acknowledges the command to RU after 0.243 s"]
    names = ["eclink_modbus.cmd_from_ru_in", "eclink_modbus.cmd_from_ru_latency",
             "eclink_modbus.cmd_to_ru_in", "eclink_modbus.cmd_to_ru_latency"]
    got = tshark.frames(cap, names, display_filter="eclink_modbus.cmd_from_ru_in || eclink_modbus.cmd_to_ru_in")
    assert list(got) == [26, 37]
    assert_fields(got[26], {"eclink_modbus.cmd_from_ru_in": 17, "eclink_modbus.cmd_from_ru_latency": "0.257000000",
                            "eclink_modbus.cmd_to_ru_in": None}, "frame 26")
    assert_fields(got[37], {"eclink_modbus.cmd_to_ru_in": 30, "eclink_modbus.cmd_to_ru_latency": "0.243000000",
                            "eclink_modbus.cmd_from_ru_in": None}, "frame 37")
    back = tshark.frames(cap, ["eclink_modbus.cao_in", "eclink_modbus.cai_in"],
                         display_filter="eclink_modbus.cao_in || eclink_modbus.cai_in", two_pass=True)
    assert list(back) == [17, 30]
    assert_fields(back[17], {"eclink_modbus.cao_in": 26, "eclink_modbus.cai_in": None}, "frame 17")
    assert_fields(back[30], {"eclink_modbus.cai_in": 37, "eclink_modbus.cao_in": None}, "frame 30")


def test_bu_state_change(tshark, capture_file):
    cap = capture_file("eclink_modbus_basic.pcap")
    exp = tshark.experts(cap)
    # (the capture's Blocked BU still names RU 0x1234 but reports RU state Initial: TS-0007 6.1.3)
    initial = "Armed RU 0x1234 but RU state Initial (0): Initial means no RU is armed yet"
    assert exp[45] == ["ES-Link relays open: BU state Blocked (0x03)", initial, "BU state Armed -> Blocked"]
    assert exp[49] == ["ES-Link relays open: BU state Blocked (0x03)", initial]
    changed = tshark.frames(cap, ["eclink_modbus.bu_state_prev", "eclink.es_relays_open", "_ws.col.Info"],
                            display_filter="eclink_modbus.bu_state_prev")
    assert list(changed) == [45]
    assert_fields(changed[45], {"eclink_modbus.bu_state_prev": "0x11", "eclink.es_relays_open": 1}, "frame 45")
    assert changed[45]["_ws.col.Info"].endswith("BU=Blocked RU 0x1234=Initial]")
    assert "Registers [relays open] [EC-Link input PCI=" in changed[45]["_ws.col.Info"]


def test_stalls_and_late_echoes(tshark, capture_file):
    cap = capture_file("eclink_modbus_faults.pcap")
    exp = tshark.experts(cap)
    assert exp[17] == ["New command from RU: CCI 1 -> 2"]
    assert exp[18] == ["New command to RU: CCO 1 -> 2"]
    # times to the millisecond; the frame the counter last moved in is a link field
    assert exp[21] == ["PCI 2 has not changed for 0.700 s (limit 0.500 s)"]
    tshark.expect(cap, 21, {"eclink_modbus.pci_since": 17, "eclink_modbus.pci_age": "0.700000000",
                            "eclink_modbus.pco_since": None})
    # one pass: the first frame after the deadline (a read request here) carries the
    # failed commands' warnings, naming and linking them ...
    # (the output image, last written in 26 at 1.31 s, not written for 2.04 s:
    # the first frame after its deadline, lua/vrshark/deadlines.luam)
    missing = "BU 192.168.2.41:502 unit 1: output image not written for 2.040 s (PCO timeout 2.000 s, TS-0007 8.4): " \
        "last written in frame 26"
    assert exp[28] == ["Input image not read for 2.050 s (PCI timeout 0.500 s)",
                       "Command from RU (CCI 2 in frame 17) not acknowledged by CAO within 2.000 s: the BU shows \"EC: Bad data\"",
                       "Command to RU (CCO 2 in frame 18) not acknowledged by CAI within 2.000 s",
                       missing]
    tshark.expect(cap, 28, {"eclink_modbus.missing_since": 26, "eclink_modbus.missing_time": "2.040000000"})
    tshark.expect(cap, 28, {"eclink_modbus.cmd_from_ru_in": 17, "eclink_modbus.cmd_to_ru_in": 18,
                            "eclink_modbus.cmd_from_ru.late": True, "eclink_modbus.cmd_to_ru.late": True,
                            "eclink_modbus.cmd_from_ru.deadline": None, "eclink_modbus.cmd_to_ru.deadline": None})
    assert exp[17] == ["New command from RU: CCI 1 -> 2"]
    # ... the second pass: there only a note naming each command ...
    two = tshark.experts(cap, two_pass=True)
    assert two[28] == ["Input image not read for 2.050 s (PCI timeout 0.500 s)",
                       "Deadline of the command from RU (CCI 2) passed with no CAO echo: the BU shows \"EC: Bad data\"",
                       "Deadline of the command to RU (CCO 2) passed with no CAI echo",
                       missing]
    tshark.expect(cap, 28, {"eclink_modbus.cmd_from_ru_in": 17, "eclink_modbus.cmd_to_ru_in": 18,
                            "eclink_modbus.cmd_from_ru.deadline": True, "eclink_modbus.cmd_to_ru.deadline": True,
                            "eclink_modbus.cmd_from_ru.late": None, "eclink_modbus.cmd_to_ru.late": None},
                  two_pass=True)
    # ... and the commands themselves are not acknowledged, linked forward to it
    assert two[17] == ["New command from RU: CCI 1 -> 2",
                       "Command from RU (CCI 2) not acknowledged by CAO within 2.000 s (deadline at frame 28): the BU shows \"EC: Bad data\""]
    assert two[18] == ["New command to RU: CCO 1 -> 2",
                       "Command to RU (CCO 2) not acknowledged by CAI within 2.000 s (deadline at frame 28)"]
    for n in (17, 18):
        tshark.expect(cap, n, {"eclink_modbus.deadline_in": 28}, two_pass=True)
    tshark.expect(cap, 17, {"eclink_modbus.cmd_from_ru.late": True}, two_pass=True)
    tshark.expect(cap, 18, {"eclink_modbus.cmd_to_ru.late": True}, two_pass=True)
    # ... a stall on the first frame after the limit that carries the unchanged counter
    assert exp[30] == ["PCO 4 has not changed for 2.050 s (limit 2.000 s): the BU shows \"EC: Bad data\""]
    tshark.expect(cap, 30, {"eclink_modbus.pco_since": 26, "eclink_modbus.pci_since": None})
    assert exp[34] == ["CAO echoed CCI 2 after 3.007 s (limit 2.000 s): the BU shows \"EC: Bad data\""]


def test_severities_one_voice(tshark, capture_file):
    """docs/findings.md "How findings read": a PCI/PCO stall is an error in Sequence, a late or
    unacknowledged command a warning in Sequence, a new command or ack chat."""
    cap = capture_file("eclink_modbus_faults.pcap")
    names = ["_ws.expert.severity", "_ws.expert.group"]
    got = tshark.frames(cap, names, display_filter="eclink_modbus.pci_stalled || eclink_modbus.pco_stalled")
    assert list(got) == [21, 30]
    for n in (21, 30):
        assert_fields(got[n], {"_ws.expert.severity": "8388608", "_ws.expert.group": "33554432"}, "frame %d" % n)
    late = tshark.frames(cap, names, display_filter="eclink_modbus.cmd_from_ru.late || "
                                                    "eclink_modbus.cmd_from_ru.late_ack", two_pass=True)
    assert list(late) == [17, 34]
    # the command not acknowledged in time (17, second pass); the echo came late (34)
    assert list(tshark.frames(cap, [], display_filter="eclink_modbus.cmd_from_ru.late", two_pass=True)) == [17]
    assert list(tshark.frames(cap, [], display_filter="eclink_modbus.cmd_from_ru.late_ack")) == [34]
    for n in (17, 34):     # 17 also notes the new command (chat)
        assert set(late[n]["_ws.expert.severity"].split(",")) - {"2097152"} == {"6291456"}, n
        assert set(late[n]["_ws.expert.group"].split(",")) == {"33554432"}, n
    chat = tshark.frames(cap, names, display_filter="eclink_modbus.cmd_from_ru")
    assert_fields(chat[17], {"_ws.expert.severity": "2097152", "_ws.expert.group": "33554432"}, "frame 17")


def test_failed_commands_are_warnings_in_one_pass(tshark, capture_file):
    """How CI runs tshark (issue 27): a severity filter and -z expert find both
    failed commands in one pass (on frame 28, past their deadline) and with -2
    (on the commands, 17 and 18), each once."""
    cap = capture_file("eclink_modbus_faults.pcap")
    late = "eclink_modbus.cmd_from_ru.late || eclink_modbus.cmd_to_ru.late"
    warning = "_ws.expert.severity >= warning && (%s)" % late
    assert list(tshark.frames(cap, [], display_filter=warning)) == [28]
    assert list(tshark.frames(cap, [], display_filter=warning, two_pass=True)) == [17, 18]
    for two_pass, where in (([], "in frame 1[78]"), (["-2"], r"deadline at frame 28")):
        text = tshark.run(["-q", "-n", "-r", str(cap), "-z", "expert,warn"] + two_pass).stdout
        counted = [line.split()[0] for line in text.splitlines()
                   if "not acknowledged by CA" in line and re.search(where, line)]
        assert counted == ["1", "1"], text
        assert re.search(r"Warns \((\d+)\)", text).group(1) == "7"


def test_info_tags_for_stalls_and_unacked_commands(tshark, capture_file):
    info = {n: r["_ws.col.Info"] for n, r in tshark.frames(capture_file("eclink_modbus_faults.pcap"),
                                                              ["_ws.col.Info"]).items()}
    # the tags before the image summary: in view where the column cuts the long Modbus text
    assert "Read Input Registers [PCI stalled 0.700 s] [EC-Link input PCI=2 " in info[21]
    assert info[21].endswith("BU=Armed RU 0x1234=Enabled]")
    assert "Write Multiple Registers [PCO stalled 2.050 s] [EC-Link output PCO=4 " in info[30]
    # [unacked] on the commands (second pass), on the read request that saw the deadline
    # pass in one pass
    assert info[28].endswith("Read Input Registers [unacked] [poll gap 2.050 s] [no output 2.040 s]")
    assert [n for n, i in info.items() if "[unacked]" in i] == [28]
    two = {n: r["_ws.col.Info"] for n, r in tshark.frames(capture_file("eclink_modbus_faults.pcap"),
                                                           ["_ws.col.Info"], two_pass=True).items()}
    assert "Read Input Registers [unacked] [EC-Link input PCI=2 CCI=2 " in two[17]
    assert "Write Multiple Registers [unacked] [EC-Link output PCO=2 CCO=2 " in two[18]
    # ... and on the request past the deadline on every pass (where a live capture shows it), beside
    # the output image that stopped (eclink_modbus.output_missing)
    assert two[28].endswith("Read Input Registers [unacked] [poll gap 2.050 s] [no output 2.040 s]")
    assert [n for n, i in two.items() if "[unacked]" in i] == [17, 18, 28]
    # a late echo reads [late ack], as docs/findings.md "How findings read" says (not [unacked])
    assert "Write Multiple Registers [late ack] [EC-Link output " in info[34]
    assert "stalled" not in info[25] and "stalled" not in info[17]
    assert not any("?" in i for i in info.values())


def test_value_checks_over_modbus(tshark, capture_file):
    cap = capture_file("eclink_modbus_faults.pcap")
    exp = tshark.experts(cap)
    assert "Joystick 2 position -1001 is outside -1000..+1000" in exp[37]
    assert exp[39] == ["BU state Unknown (0x42): not defined in TS-0007", "Armed RU is 0 but Joystick 1 is not 0",
                       "BU state Armed -> Unknown (0x42)"]
    assert exp[40] == ["Periodic data size 60000 is over 51200", "Spare byte 23 is 0x09, not 0"]


def test_periodic_reassembly(tshark, capture_file):
    cap = capture_file("eclink_modbus_periodic.pcap")
    payload = bytes((i * 7 + 3) & 0xFF for i in range(450))
    r = tshark.fields(cap, ["frame.number", "eclink_modbus.periodic.length", "eclink_modbus.periodic.block_in",
                            "eclink_modbus.periodic.data"], display_filter="eclink_modbus.periodic.data")
    assert r == [["14", "450", "6,10,14", payload.hex()], ["26", "450", "18,22,26", payload.hex()]]
    exp = tshark.experts(cap)
    assert exp[14] == ["Periodic data reassembled: 450 bytes from 3 blocks"]
    assert exp[30] == ["Periodic data block 3 is beyond the periodic data size 450 (blocks 0..2)"]
    links = tshark.fields(cap, ["frame.number", "eclink_modbus.periodic.reassembled_in"],
                          display_filter="eclink_modbus.periodic.reassembled_in", two_pass=True)
    assert links == [["6", "14"], ["10", "14"], ["18", "26"], ["22", "26"]]
    assert "Reassembled periodic data" in tshark.verbose(cap, display_filter="frame.number == 14", extra=["-x"])


def test_assembled_images(tshark, capture_file):
    cap = capture_file("eclink_modbus_functions.pcap")
    prefs = {"eclink_modbus.assembled": "TRUE"}
    # the capture is recognized in its closing run (frame 41): its frames are decoded on the second pass
    r = tshark.fields(cap, ["frame.number", "eclink_modbus.assembled"], display_filter="frame.number in {5, 9, 27}",
                      prefs=prefs, aggregator="|", two_pass=True)
    assert r == [["5", "input image as of this frame (64 of 64 bytes seen)|output image as of this frame "
                  "(0 of 20 bytes seen)"],
                 ["9", "input image as of this frame (64 of 64 bytes seen)|output image as of this frame "
                  "(0 of 20 bytes seen)"],
                 ["27", "input image as of this frame (64 of 64 bytes seen)|output image as of this frame "
                  "(224 of 224 bytes seen)"]]
    # frame 27 reads CAO (2) back; its assembled output image has the same value
    cao = tshark.field(cap, "eclink.cao", display_filter="frame.number == 27", prefs=prefs, two_pass=True)
    assert cao == ["2,2"]
    assert tshark.field(cap, "eclink.cao", display_filter="frame.number == 27", two_pass=True) == ["2"]
    # no expert info from the assembled copies
    assert tshark.experts(cap, prefs=prefs, two_pass=True) == tshark.experts(cap, two_pass=True)


# One pass: the failed command's warning on the first frame past its deadline;
# the second pass notes the deadline there.
ONE_PASS_FAILED = re.compile(r"^Command (from|to) RU \((CC[IO]) (\d+) in frame \d+\) not acknowledged by "
                             r"(CA[OI]) within 2\.000 s(.*)$")


def as_second_pass(message):
    return ONE_PASS_FAILED.sub(r"Deadline of the command \1 RU (\2 \3) passed with no \4 echo\5", message)


ANALYSIS_FIELDS = ["frame.number", "eclink.image", "eclink.pci", "eclink.pco", "eclink.cci", "eclink.cao",
                   "eclink.bu_state", "eclink.cut", "eclink_modbus.request_in", "eclink_modbus.pci_age",
                   "eclink_modbus.pco_age", "eclink_modbus.cmd_from_ru_in", "eclink_modbus.cmd_to_ru_in",
                   "eclink_modbus.periodic.block_in", "eclink_modbus.accepted_in", "_ws.expert.message"]


@pytest.mark.parametrize("name", ["eclink_modbus_basic.pcap", "eclink_modbus_faults.pcap",
                                  "eclink_modbus_periodic.pcap", "eclink_modbus_functions.pcap",
                                  "eclink_modbus_segments.pcap", "eclink_modbus_late_accept.pcap"])
def test_two_pass_agrees(tshark, capture_file, name):
    """Everything but the forward links (response_in, cao_in, cai_in,
    periodic.reassembled_in, deadline_in and the command's "not acknowledged"
    finding, only known once the later frame is seen) and the frames before
    the connection is recognized (decoded on the second pass only) is the
    same in one pass and in two; the warning of a failed command that one
    pass puts on the frame past its deadline reads as the note there."""
    cap = capture_file(name)

    def without_forward(row):
        return row[:-1] + [",".join(as_second_pass(m) for m in row[-1].split(",") if "(deadline at frame" not in m)]
    one = [without_forward(r) for r in tshark.fields(cap, ANALYSIS_FIELDS)]
    two = [without_forward(r) for r in tshark.fields(cap, ANALYSIS_FIELDS, two_pass=True)]
    accepted = ANALYSIS_FIELDS.index("eclink_modbus.accepted_in")
    first = min(int(row[accepted].split(",")[0]) for row in one if row[accepted])
    assert [row for row in one if int(row[0]) >= first] == [row for row in two if int(row[0]) >= first]
    assert not any(row[1] for row in one if int(row[0]) < first)
    assert any(row[1] for row in one)


def test_times_in_the_tree_read_to_the_millisecond(tshark, capture_file):
    """docs/findings.md "How findings read": times rounded to the millisecond, in the
    tree too (the field keeps its exact value for filters)."""
    text = tshark.verbose(capture_file("eclink_modbus_faults.pcap"), display_filter="frame.number == 21")
    assert "[Time since PCI changed: 0.700 s]" in text
    assert "0.700000000 seconds" not in text
    text = tshark.verbose(capture_file("mcmb2_duplex_watchdog.pcap"), display_filter="frame.number == 25")
    assert "[Watchdog unchanged for: 1.400 s]" in text
    text = tshark.verbose(capture_file("eclink_pnio_connect.pcap"), display_filter="frame.number == 40")
    assert "[Time since PCO changed: 0.125 s]" in text
    assert tshark.field(capture_file("eclink_modbus_faults.pcap"), "frame.number",
                        display_filter="eclink_modbus.pci_age == 0.7") == ["21"]


def test_cai_timeout_preference(tshark, capture_file):
    """TS-0007 8.2 gives no time for the CAI echo: the limit is the project's own
    preference eclink_modbus.cai_timeout (2000 ms by default, test_stalls_and_late_echoes).
    At 700 ms the command to RU of frame 18 (0.485 s) fails at frame 22 (1.185 s) instead
    of 28; the command from RU keeps the 2000 ms TS-0007 8.1 gives CAO."""
    cap = capture_file("eclink_modbus_faults.pcap")
    prefs = {"eclink_modbus.cai_timeout": "700"}
    one = tshark.experts(cap, prefs=prefs)
    assert "Command to RU (CCO 2 in frame 18) not acknowledged by CAI within 0.700 s" in one[22]
    assert not [m for m in one[28] if "CAI" in m]
    assert "Command from RU (CCI 2 in frame 17) not acknowledged by CAO within 2.000 s: " \
           "the BU shows \"EC: Bad data\"" in one[28]
    tshark.expect(cap, 22, {"eclink_modbus.cmd_to_ru.late": True, "eclink_modbus.cmd_to_ru_in": 18}, prefs=prefs)
    two = tshark.experts(cap, prefs=prefs, two_pass=True)
    assert two[18] == ["New command to RU: CCO 1 -> 2",
                       "Command to RU (CCO 2) not acknowledged by CAI within 0.700 s (deadline at frame 22)"]
    assert "Deadline of the command to RU (CCO 2) passed with no CAI echo" in two[22]
    tshark.expect(cap, 18, {"eclink_modbus.deadline_in": 22}, prefs=prefs, two_pass=True)
