"""The demo crane's IO list decoded from EC-Link images, in PROFINET
(captures/crane_eclink_pnio.pcap) and Modbus/TCP (captures/crane_eclink_modbus.pcap):
command data from and to the RU and the periodic data, the same fields and
values as on EG-Link; multiplexed periodic data once reassembled; the server key."""
import re
import pytest

from conftest import CAPTURES
from io_testlib import assert_nothing_added, crane, described, expect_all  # noqa: F401 (crane is a fixture)

FROM_RU = ["horn", "start", "stop", "gear", "hoist_speed", "trolley_speed", "operator_id"]
TO_RU = ["message_code", "message_text"]
PERIODIC = ["load", "hook_height", "slew_angle", "overload", "wind_alarm", "hoist_mode", "cycle",
            "wind_speed", "status_text"]
ALL = ["vrshark.io." + n for n in FROM_RU + TO_RU + PERIODIC]


def from_ru(horn, start, stop, gear, hoist, trolley):
    return dict(zip(FROM_RU, (horn, start, stop, gear, hoist, trolley, 7)))


def to_ru(code, text, *state):
    out = {"message_code": code, "message_text": text.ljust(12)}
    out.update(zip(PERIODIC, state[:-1] + (state[-1].ljust(16),)))
    return out


# the four cycles: (input image values, output image values)
CYCLES = [
    (from_ru(False, True, False, 0, 0.0, 0.0), to_ru(0, "", 0.0, 25.0, 90.0, False, False, 0, 1, 3.5, "READY")),
    (from_ru(False, False, False, 1, 75.5, -25.0),
     to_ru(0, "", 12.5, 31.2, 90.1, False, False, 1, 3, 4.5, "LIFTING")),
    (from_ru(True, False, False, 2, 100.0, -100.0),
     to_ru(1, "LOAD 52.3 T", 52.3, 44.0, 359.9, True, False, 3, 4, 12.75, "OVERLOAD")),
    (from_ru(False, False, True, 3, -50.0, 0.0),
     to_ru(2, "WIND 21 M/S", 52.3, 0.0, 0.0, False, True, 2, 5, 21.0, "WIND ALARM")),
]
# frame numbers of (input image, output image) per cycle
PNIO_FRAMES = [(3, 4), (5, 6), (7, 8), (9, 10)]
MODBUS_FRAMES = [(5, 6), (9, 10), (13, 14), (17, 18)]   # read response, write request


def expected(frames, total):
    out = {n: {} for n in range(1, total + 1)}
    for (fin, fout), (vin, vout) in zip(frames, CYCLES):
        out[fin], out[fout] = vin, vout
    return out


@pytest.mark.parametrize("two_pass", [False, True])
def test_pnio_every_field_exact(crane, two_pass):
    expect_all(crane, CAPTURES / "crane_eclink_pnio.pcap", expected(PNIO_FRAMES, 10), ALL, two_pass=two_pass)


@pytest.mark.parametrize("two_pass", [False, True])
def test_modbus_every_field_exact(crane, two_pass):
    """Registers carry each byte pair swapped: the fields read the image order.
    One pass shows the connection from the frame that recognises it (the
    third input image, frame 13); two passes also the cycles before."""
    want = expected(MODBUS_FRAMES, 19)
    if not two_pass:
        for frame in (5, 6, 9, 10):
            want[frame] = {}
    expect_all(crane, CAPTURES / "crane_eclink_modbus.pcap", want, ALL, two_pass=two_pass)


def test_shown_under_the_image_items(crane):
    text = crane.verbose(CAPTURES / "crane_eclink_pnio.pcap", display_filter="frame.number == 8")
    # (Wireshark 4.2 and later mark a long bytes label "Periodic data […]:")
    cmd = re.split(r"Command to RU(?: \[…\])?: ", text, maxsplit=1)[1]
    assert cmd.split("\n")[1].strip() == "Machine data (crane.csv)"
    periodic = re.split(r"Periodic data(?: \[…\])?: ", text, maxsplit=1)[1]
    assert periodic.split("\n")[1].strip() == "Machine data (crane.csv)"
    assert "Load on the hook (t): 52.3 (raw 5230)" in periodic


def test_faults(crane):
    experts = crane.experts(CAPTURES / "crane_eclink_modbus.pcap")
    assert "Overload: Yes (1)" in experts[14]
    assert "Speed range: 3" in experts[17]
    assert "Message to the operator: Wind alarm (2)" in experts[18]
    assert "Wind alarm: Yes (1)" in experts[18]


def test_reassembled_periodic_data_and_server_key(conf_dir, work_dir):
    """eclink_modbus_periodic.pcap: 450 bytes of periodic data in blocks 0..2
    (byte i = (7 i + 3) & 0xff), decoded once per complete round, for the server
    192.168.2.41 only."""
    t = described(conf_dir, work_dir, "periodic.csv", [
        "area,byte,type,name,device",
        "periodic.to_ru,0,u8,first,server=192.168.2.41",
        "periodic.to_ru,449,u8,last,",
        "periodic.to_ru,10,u8,other_server,server=192.168.2.42",
        ])
    cap = CAPTURES / "eclink_modbus_periodic.pcap"
    names = ["vrshark.io.first", "vrshark.io.last", "vrshark.io.other_server", "eclink_modbus.periodic.length"]
    for two_pass in (False, True):
        frames = t.frames(cap, names, two_pass=two_pass)
        decoded = sorted(n for n, f in frames.items() if f["vrshark.io.last"])
        assert decoded == sorted(n for n, f in frames.items() if f["eclink_modbus.periodic.length"])
        assert len(decoded) == 2
        for n in decoded:
            assert frames[n]["vrshark.io.first"] == "3"
            assert int(frames[n]["vrshark.io.last"]) == (449 * 7 + 3) & 0xFF
        assert all(f["vrshark.io.other_server"] == "" for f in frames.values())


def test_no_description_adds_nothing(conf_dir, work_dir):
    assert_nothing_added(conf_dir, work_dir, ("crane_eclink_modbus.pcap", "crane_eclink_pnio.pcap",
                                              "eclink_modbus_periodic.pcap", "eclink_modbus_basic.pcap",
                                              "eclink_pnio_connect.pcap"))
