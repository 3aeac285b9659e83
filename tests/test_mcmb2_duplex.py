"""MC-MB2-PN duplex/simplex cyclic data laid out from the Connect in the capture."""
import pytest

from conftest import assert_fields

DUPLEX = "mcmb2_duplex_connect.pcap"
WATCHDOG = "mcmb2_duplex_watchdog.pcap"
UNDEFINED = {17: 3, 19: 4, 21: 5, 23: 6, 25: 8, 27: 9, 29: 0xB, 31: 0xC, 33: 0xD, 35: 0xE, 37: 0xF}
NO_VALID = ": no valid terminal data, the IO controller must keep the system in a safe state"
# _ws.expert.severity / .group as tshark -T fields prints them (epan/proto.h PI_*)
ERROR, WARNING = 0x00800000, 0x00600000
SEQUENCE, RESPONSE_CODE, PROTOCOL = 0x02000000, 0x03000000, 0x09000000


def test_connect_frames_learn_the_layout(tshark, capture_file):
    ex = tshark.experts(capture_file(DUPLEX))
    want = "Cyclic data layout learned: duplex device: uplink FrameID 0x8001, downlink FrameID 0x8002"
    assert ex[1] == [want]
    assert ex[2] == [want]
    tshark.expect(capture_file(DUPLEX), 1, {"mcmb2.frame_id": [0x8001, 0x8002], "mcmb2.system": "duplex"})


def test_uplink_fields(tshark, capture_file):
    tshark.expect(capture_file(DUPLEX), 7, {
        "mcmb2.system": "duplex", "mcmb2.direction": "uplink", "mcmb2.status": 1, "mcmb2.terminal": 1,
        "mcmb2.uplink_watchdog": 3, "mcmb2.layout": "Connect in frame 1",
        # 20 + 4 + 2 byte modules, IOPS stripped
        "mcmb2.uplink_data": bytes(((1 * 7 + i) & 0xFF) or 1 for i in range(26)).hex(),
        "mcmb2.downlink_data": None, "_ws.col.Info": "Uplink duplex: Terminal present, terminal 1, watchdog 3"})
    tshark.expect(capture_file(DUPLEX), 3, {"mcmb2.status": 0, "mcmb2.terminal": 0})


def test_downlink_fields(tshark, capture_file):
    tshark.expect(capture_file(DUPLEX), 8, {
        "mcmb2.direction": "downlink", "mcmb2.base_unit": 1, "mcmb2.downlink_watchdog": 3,
        # 10 data + 20 ASCII bytes: three modules, IOPS stripped
        "mcmb2.downlink_data": bytes(((102 * 7 + i) & 0xFF) or 1 for i in range(30)).hex(),
        "mcmb2.uplink_data": None, "mcmb2.status": None,
        "_ws.col.Info": "Downlink duplex: base unit 1, watchdog 3"})


def test_every_undefined_status_is_an_error(tshark, capture_file):
    """Undefined statuses read "Unknown (0x3)" as the field does: error, Protocol, Info tag [undefined]."""
    got = tshark.frames(capture_file(DUPLEX), ["_ws.expert.message", "_ws.expert.severity", "_ws.expert.group",
                                               "_ws.col.Info"])
    for frame, st in UNDEFINED.items():
        assert_fields(got[frame], {
            "_ws.expert.message": "MC-MB2-PN status Unknown (0x%x) is undefined: bring the system to a safe state"
                                  % st,
            "_ws.expert.severity": ERROR, "_ws.expert.group": PROTOCOL,
            "_ws.col.Info": "Uplink duplex: Unknown (0x%x), terminal 1, watchdog %d [undefined]"
                            % (st, 8 + (frame - 17) // 2)}, "frame %d" % frame)
    defined = tshark.frames(capture_file(DUPLEX), [], display_filter="mcmb2.status.undefined")
    assert sorted(defined) == sorted(UNDEFINED)


def test_not_present_status_and_data(tshark, capture_file):
    """Absent, blocked, active stop: the safety state the base reports (warning, Response code)."""
    ex = tshark.experts(capture_file(DUPLEX))
    assert ex[3] == ["Terminal absent" + NO_VALID]
    assert ex[5] == ["Terminal blocked (waiting for start key)" + NO_VALID]
    assert ex[11] == ["Active stop" + NO_VALID,
                      "Status Active stop is not 'Terminal present' but the uplink data is not all 0"]
    tshark.expect(capture_file(DUPLEX), 3, {"mcmb2.no_valid_data": True, "_ws.expert.severity": WARNING,
                                            "_ws.expert.group": RESPONSE_CODE,
                                            "_ws.col.Info": "Uplink duplex: Terminal absent, terminal 0, watchdog 1 [no valid data]"})
    assert 7 not in ex and 8 not in ex


def test_e010_is_a_sequence_error_with_an_info_tag(tshark, capture_file):
    """E010 reported by the base: an error in the Sequence group, like the stall that causes it."""
    tshark.expect(capture_file(DUPLEX), 13, {
        "mcmb2.status": 0xA, "mcmb2.status.e010": True, "mcmb2.no_valid_data": None,
        "_ws.expert.message": "Fieldbus update failure (E010)" + NO_VALID,
        "_ws.expert.severity": ERROR, "_ws.expert.group": SEQUENCE,
        "_ws.col.Info": "Uplink duplex: Fieldbus update failure (E010), terminal 1, watchdog 6 [E010]"})


def test_bad_iops_and_iocs(tshark, capture_file):
    ex = tshark.experts(capture_file(DUPLEX))
    assert ex[9] == ["IOPS of slot 3/0x1 is Bad (by subslot) (0x00)"]
    assert ex[16] == ["IOCS of slot 1/0x1 is Bad (by IO controller) (0x60)"]
    tshark.expect(capture_file(DUPLEX), 9, {"mcmb2.iops": [0x80] * 6 + [0x00, 0x80]})
    # all GOOD: one summary item, no per-byte fields
    tshark.expect(capture_file(DUPLEX), 7, {"mcmb2.iops": None, "mcmb2.iocs": None})


def test_watchdog_stalls(tshark, capture_file):
    """Ages to the millisecond, the frame the value dates from as a link, a tag on every stalled frame."""
    ex = tshark.experts(capture_file(WATCHDOG))
    assert ex[23] == ["Uplink watchdog unchanged for 1.200 s (value 5): bring the system to a safe state"]
    assert ex[34] == ["Downlink watchdog unchanged for 2.200 s (value 5): the base shows E010"]
    stalls = [n for n, msgs in ex.items() if any("watchdog unchanged" in m for m in msgs)]
    assert stalls == [23, 34]
    cap = capture_file(WATCHDOG)
    tshark.expect(cap, 21, {"mcmb2.watchdog_age": "1.000000000", "mcmb2.watchdog_since": None,
                            "_ws.col.Info": "Uplink duplex: Terminal present, terminal 1, watchdog 5"})
    tshark.expect(cap, 23, {"mcmb2.watchdog_age": "1.200000000", "mcmb2.watchdog_since": 11,
                            "mcmb2.uplink_watchdog.stalled": True, "_ws.expert.severity": ERROR,
                            "_ws.expert.group": SEQUENCE,
                            "_ws.col.Info": "Uplink duplex: Terminal present, terminal 1, watchdog 5 "
                                            "[watchdog stalled 1.200 s]"})
    tshark.expect(cap, 25, {"mcmb2.watchdog_age": "1.400000000", "mcmb2.watchdog_since": 11,
                            "_ws.expert.message": None,
                            "_ws.col.Info": "Uplink duplex: Terminal present, terminal 1, watchdog 5 "
                                            "[watchdog stalled 1.400 s]"})
    tshark.expect(cap, 27, {"mcmb2.watchdog_age": "0.000000000", "mcmb2.watchdog_since": None})
    tshark.expect(cap, 34, {"mcmb2.watchdog_since": 12, "mcmb2.downlink_watchdog.stalled": True,
                            "_ws.col.Info": "Downlink duplex: base unit 0, watchdog 5 [watchdog stalled 2.200 s]"})
    ages = tshark.field(cap, "mcmb2.watchdog_age")
    assert ages and all(a == "" or a.endswith("000000") for a in ages)  # whole milliseconds


def test_simplex_downlink_has_no_data(tshark, capture_file):
    tshark.expect(capture_file(WATCHDOG), 4, {"mcmb2.base_unit": 0, "mcmb2.downlink_watchdog": 1,
                                              "mcmb2.downlink_data": None})


@pytest.mark.parametrize("name", [DUPLEX, WATCHDOG])
def test_two_pass_agrees(tshark, capture_file, name):
    fields = ["mcmb2.status", "mcmb2.uplink_data", "mcmb2.downlink_data", "mcmb2.watchdog_age",
              "mcmb2.watchdog_since", "_ws.col.Info", "_ws.expert.message"]
    one = tshark.frames(capture_file(name), fields)
    assert one == tshark.frames(capture_file(name), fields, two_pass=True)
    assert any(r["_ws.expert.message"] for r in one.values())
