"""MC-MB2-PN duplex/simplex cyclic data laid out from the Connect in the capture."""
import pytest

DUPLEX = "mcmb2_duplex_connect.pcap"
WATCHDOG = "mcmb2_duplex_watchdog.pcap"
UNDEFINED = {17: 3, 19: 4, 21: 5, 23: 6, 25: 8, 27: 9, 29: 0xB, 31: 0xC, 33: 0xD, 35: 0xE, 37: 0xF}


@pytest.fixture(scope="module")
def rows(tshark, capture_file):
    fields = ["frame.number", "mcmb2.system", "mcmb2.direction", "mcmb2.status", "mcmb2.terminal",
              "mcmb2.uplink_watchdog", "mcmb2.uplink_data", "mcmb2.base_unit", "mcmb2.downlink_watchdog",
              "mcmb2.downlink_data", "mcmb2.layout"]
    return {int(r[0]): dict(zip(fields, r)) for r in tshark.fields(capture_file(DUPLEX), fields)}


def test_connect_frames_learn_the_layout(tshark, capture_file):
    ex = tshark.experts(capture_file(DUPLEX))
    want = "Cyclic data layout learned: duplex device: uplink FrameID 0x8001, downlink FrameID 0x8002"
    assert ex[1] == [want]
    assert ex[2] == [want]
    assert tshark.field(capture_file(DUPLEX), "mcmb2.frame_id", display_filter="frame.number==1") == \
        ["0x8001,0x8002"]


def test_uplink_fields(rows):
    r = rows[7]
    assert r["mcmb2.system"] == "duplex"
    assert r["mcmb2.direction"] == "uplink"
    assert r["mcmb2.status"] == "0x01"
    assert r["mcmb2.terminal"] == "1"
    assert r["mcmb2.uplink_watchdog"] == "3"
    # 20 + 4 + 2 byte modules, IOPS stripped
    assert r["mcmb2.uplink_data"] == bytes(((1 * 7 + i) & 0xFF) or 1 for i in range(26)).hex()
    assert r["mcmb2.layout"] == "Connect in frame 1"
    assert rows[3]["mcmb2.status"] == "0x00" and rows[3]["mcmb2.terminal"] == "0"


def test_downlink_fields(rows):
    r = rows[8]
    assert r["mcmb2.direction"] == "downlink"
    assert r["mcmb2.base_unit"] == "1"
    assert r["mcmb2.downlink_watchdog"] == "3"
    # 10 data + 20 ASCII bytes: three modules, IOPS stripped
    assert r["mcmb2.downlink_data"] == bytes(((102 * 7 + i) & 0xFF) or 1 for i in range(30)).hex()
    assert r["mcmb2.uplink_data"] == ""


def test_every_undefined_status_is_an_error(tshark, capture_file):
    ex = tshark.experts(capture_file(DUPLEX))
    for frame, st in UNDEFINED.items():
        assert ex[frame] == ["Undefined MC-MB2-PN status 0x%X: bring the system to a safe state" % st]
    defined = tshark.fields(capture_file(DUPLEX), ["frame.number"], display_filter="mcmb2.status.undefined")
    assert sorted(int(r[0]) for r in defined) == sorted(UNDEFINED)


def test_not_present_status_and_data(tshark, capture_file):
    ex = tshark.experts(capture_file(DUPLEX))
    assert ex[3] == ["Terminal absent: no valid terminal data, the IO controller must keep the system in a "
                     "safe state"]
    assert ex[11] == [
        "Active stop: no valid terminal data, the IO controller must keep the system in a safe state",
        "Status 0x7 is not 'Terminal present' but the uplink data is not all 0"]
    assert ex[13][0].startswith("Fieldbus update failure (E010)")
    assert 7 not in ex and 8 not in ex


def test_bad_iops_and_iocs(tshark, capture_file):
    ex = tshark.experts(capture_file(DUPLEX))
    assert ex[9] == ["IOPS of slot 3/0x1 is Bad (by subslot) (0x00)"]
    assert ex[16] == ["IOCS of slot 1/0x1 is Bad (by IO controller) (0x60)"]
    iops = tshark.field(capture_file(DUPLEX), "mcmb2.iops", display_filter="frame.number==9")
    assert iops == ["0x80,0x80,0x80,0x80,0x80,0x80,0x00,0x80"]


def test_watchdog_stalls(tshark, capture_file):
    ex = tshark.experts(capture_file(WATCHDOG))
    assert ex[23] == ["Uplink watchdog unchanged for 1200 ms (value 5 since frame 11): bring the system to a "
                      "safe state"]
    assert ex[34] == ["Downlink watchdog unchanged for 2200 ms (value 5 since frame 12): the base shows E010"]
    stalls = [n for n, msgs in ex.items() if any("watchdog unchanged" in m for m in msgs)]
    assert stalls == [23, 34]
    assert tshark.field(capture_file(WATCHDOG), "mcmb2.watchdog_age", display_filter="frame.number==21") == \
        ["1.000000000"]


def test_simplex_downlink_has_no_data(tshark, capture_file):
    rows = tshark.fields(capture_file(WATCHDOG), ["mcmb2.base_unit", "mcmb2.downlink_watchdog",
                                                   "mcmb2.downlink_data"], display_filter="frame.number==4")
    assert rows == [["0", "1", ""]]


@pytest.mark.parametrize("name", [DUPLEX, WATCHDOG])
def test_two_pass_agrees(tshark, capture_file, name):
    fields = ["frame.number", "mcmb2.status", "mcmb2.uplink_data", "mcmb2.downlink_data", "mcmb2.watchdog_age",
              "_ws.expert.message"]
    one = tshark.fields(capture_file(name), fields)
    two = tshark.fields(capture_file(name), fields, two_pass=True)
    assert one == two
    assert any(r[5] for r in one)
