"""The base unit's display text beside the findings that cause it, so what the
display shows can be matched with the capture: the EC-Link BU's LCD
(TS-0007 section 9, `eclink.lcd`) and the MC-MB2-PN base's E010
(SP-14-023 section 2.4, `mcmb2.display`)."""
import pytest

from test_eclink_image import USER_DLT, input_image, raw_capture  # noqa: F401 (a fixture)

BAD_DATA = ': the BU shows "EC: Bad data"'


@pytest.mark.parametrize("two_pass", [False, True])
def test_bad_data_beside_the_modbus_findings(tshark, capture_file, two_pass):
    """TS-0007 9: "EC: Bad data" when the controller does not increment PCO
    (8.4: 2000 ms) or does not acknowledge a command from the RU with CAO
    (8.1: 2000 ms). eclink_modbus_faults.pcap: CCI 2 in frame 17 never echoed
    (its deadline seen in frame 28), PCO stands from frame 26 (found in 30),
    CCI 2 echoed after 3.007 s in frame 34. One pass puts the command's
    warning on frame 28; two passes put it on the command, and the deadline
    note on frame 28."""
    cap = capture_file("eclink_modbus_faults.pcap")
    got = tshark.frames(cap, ["eclink.lcd", "_ws.expert.message"], display_filter="eclink.lcd",
                        two_pass=two_pass)
    assert {n: r["eclink.lcd"] for n, r in got.items()} == dict.fromkeys(
        [17, 28, 30, 34] if two_pass else [28, 30, 34], "EC: Bad data")
    bad = {n: [m for m in r["_ws.expert.message"].split(",") if m.endswith(BAD_DATA)] for n, r in got.items()}
    if two_pass:
        assert bad[17] == ["Command from RU (CCI 2) not acknowledged by CAO within 2.000 s (deadline at frame 28)"
                           + BAD_DATA]
        assert bad[28] == ["Deadline of the command from RU (CCI 2) passed with no CAO echo" + BAD_DATA]
    else:
        assert bad[28] == ["Command from RU (CCI 2 in frame 17) not acknowledged by CAO within 2.000 s" + BAD_DATA]
    assert bad[30] == ["PCO 4 has not changed for 2.050 s (limit 2.000 s)" + BAD_DATA]
    assert bad[34] == ["CAO echoed CCI 2 after 3.007 s (limit 2.000 s)" + BAD_DATA]
    # the command to the RU that CAI never echoes (CCO 2, frame 18) is the
    # BU's own failure: section 9 names no display text for it
    experts = tshark.experts(cap, two_pass=two_pass)
    to_ru = [m for ms in experts.values() for m in ms if "by CAI" in m or "no CAI echo" in m]
    assert to_ru and not [m for m in to_ru if "EC: " in m]


@pytest.mark.parametrize("two_pass", [False, True])
def test_bad_data_beside_the_pnio_findings(tshark, capture_file, two_pass):
    """TS-0007 9 over PROFINET IO, the same text: eclink_pnio_connect.pcap,
    PCO 18 stands (found in frame 72), CCI 2 in frame 43 never echoed
    (deadline seen in frame 76). The PCI stall of frame 31 is for the
    controller to act on (8.3): no display text."""
    cap = capture_file("eclink_pnio_connect.pcap")
    got = tshark.frames(cap, ["eclink.lcd", "_ws.expert.message"], display_filter="eclink.lcd",
                        two_pass=two_pass)
    assert {n: r["eclink.lcd"] for n, r in got.items()} == dict.fromkeys(
        [43, 72, 76] if two_pass else [72, 76], "EC: Bad data")
    assert "PCO 18 has not changed for 2.125 s (limit 2.000 s)" + BAD_DATA in got[72]["_ws.expert.message"]
    if two_pass:
        assert got[76]["_ws.expert.message"] == ("Deadline of the command from RU (CCI 2) passed with no CAO echo"
                                                 + BAD_DATA)
    else:
        assert got[76]["_ws.expert.message"] == ("Command from RU (CCI 2 in frame 43) not acknowledged by CAO "
                                                 "within 2.000 s" + BAD_DATA)
    assert tshark.frame(cap, 31, ["eclink.lcd", "_ws.expert.message"]) == {
        "eclink.lcd": "", "_ws.expert.message": "PCI 10 has not changed for 0.625 s (limit 0.500 s)"}


def test_ec_link_status_names_the_display(tshark, raw_capture):  # noqa: F811 (the fixture)
    """TS-0007 9 and 6.1.2: the BU's own EC-Link status (input byte 24) names
    the four conditions of its display, 2 No link "EC: No Data", 3 Link error
    "EC: Cfg. Error", 4 Interface error "EC: Module Error", 5 Data error
    "EC: Bad data"; 0 Unused, 1 Operational and 6 Passive none. The field
    sits under the EC-Link status (a generated child), not under the EG-Link
    or C-Link status of the same value."""
    cap = raw_capture(*[input_image(b24=v) for v in range(7)], input_image(b23=5, b25=2))
    got = tshark.frames(cap, ["eclink.ec_link_status", "eclink.lcd"], extra=["-o", USER_DLT])
    assert {n: (r["eclink.ec_link_status"], r["eclink.lcd"]) for n, r in got.items()} == {
        1: ("0", ""), 2: ("1", ""), 3: ("2", "EC: No Data"), 4: ("3", "EC: Cfg. Error"),
        5: ("4", "EC: Module Error"), 6: ("5", "EC: Bad data"), 7: ("6", ""), 8: ("1", "")}
    tree = [line.strip() for line in tshark.verbose(cap, display_filter="frame.number == 6",
                                                    extra=["-o", USER_DLT]).splitlines()]
    at = tree.index("EC-Link status: Data error (5)")
    assert tree[at + 1] == "[BU display (TS-0007 9): EC: Bad data]"
    # a column or a filter finds them
    assert list(tshark.frames(cap, [], display_filter='eclink.lcd == "EC: Cfg. Error"',
                              extra=["-o", USER_DLT])) == [4]


@pytest.mark.parametrize("two_pass", [False, True])
def test_e010_beside_the_mcmb2_findings(tshark, capture_file, two_pass):
    """SP-14-023 2.4 and 1.5: the base indicates E010 when the downlink
    watchdog stands past its timeout, and reports it as status 0xA (3.1.1,
    4.1.1). mcmb2_duplex_watchdog.pcap: the downlink watchdog stands (found in
    frame 34); mcmb2_polled_connect.pcap: the polled base reports 0xA in
    frame 13. mcmb2.display == "E010" finds both."""
    stall = tshark.frames(capture_file("mcmb2_duplex_watchdog.pcap"), ["mcmb2.display", "_ws.expert.message"],
                          display_filter='mcmb2.display == "E010"', two_pass=two_pass)
    assert stall == {34: {"mcmb2.display": "E010", "_ws.expert.message":
                          "Downlink watchdog unchanged for 2.200 s (value 5): the base shows E010"}}
    status = tshark.frames(capture_file("mcmb2_polled_connect.pcap"), ["mcmb2.display", "mcmb2.status"],
                           display_filter="mcmb2.display", two_pass=two_pass)
    assert status == {13: {"mcmb2.display": "E010", "mcmb2.status": "0x0a"}}
