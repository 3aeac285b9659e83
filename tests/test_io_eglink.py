"""The demo crane's IO list (examples/crane/crane.csv) decoded from EG-Link:
every field of every area in captures/crane_eglink.pcap with its exact value,
scaling and units as shown, bit fields, fault experts, device keys, and no
change at all without a description."""
import pytest

from conftest import CAPTURES
from io_testlib import crane, described, expect_all, io_tshark, problems, write  # noqa: F401 (crane is a fixture)

CAP = CAPTURES / "crane_eglink.pcap"

FROM_RU = ["horn", "start", "stop", "gear", "hoist_speed", "trolley_speed", "operator_id"]
TO_RU = ["message_code", "message_text"]
PERIODIC = ["load", "hook_height", "slew_angle", "overload", "wind_alarm", "hoist_mode", "cycle",
            "wind_speed", "status_text"]
ALL = ["vrshark.io." + n for n in FROM_RU + TO_RU + PERIODIC]


def from_ru(horn, start, stop, gear, hoist, trolley, operator_id=7):
    return dict(zip(FROM_RU, (horn, start, stop, gear, hoist, trolley, operator_id)))


def periodic(load, height, slew, overload, wind_alarm, mode, cycle, wind, text):
    return dict(zip(PERIODIC, (load, height, slew, overload, wind_alarm, mode, cycle, wind, text.ljust(16))))


# frame -> {field name: value}; fields of the other areas must be absent.
EXPECTED = {
    1: periodic(0.0, 25.0, 90.0, False, False, 0, 1, 3.5, "READY"),
    2: from_ru(False, True, False, 0, 0.0, 0.0),
    3: {},
    4: periodic(12.5, 25.0, 90.0, False, False, 3, 2, 4.25, "RUNNING"),
    5: from_ru(False, False, False, 1, 75.5, -25.0),
    6: {},
    7: periodic(12.5, 31.2, 90.1, False, False, 1, 3, 4.5, "LIFTING"),
    8: from_ru(True, False, False, 2, 100.0, -100.0),
    9: {},
    10: periodic(52.3, 44.0, 359.9, True, False, 3, 4, 12.75, "OVERLOAD"),
    11: {"message_code": 1, "message_text": "LOAD 52.3 T "},
    12: {},
    13: from_ru(False, False, True, 3, -50.0, 0.0),
    14: {},
    15: periodic(52.3, 0.0, 0.0, False, True, 2, 5, 21.0, "WIND ALARM"),
    16: {"message_code": 2, "message_text": "WIND 21 M/S "},
    17: {},
}


@pytest.mark.parametrize("two_pass", [False, True])
def test_every_crane_field_exact(crane, two_pass):
    """The demo list's rows are limited to the crane's BU origin (0x2C01):
    frame 1, the controller's first VRPO, comes before any packet of the
    BU, so one pass does not know its BU yet; with -2 the EG-Link analysis
    has learned it (docs/io.md, Device keys)."""
    frames = crane.frames(CAP, ALL, two_pass=two_pass)
    assert sorted(frames) == sorted(EXPECTED)
    want = dict(EXPECTED)
    if not two_pass:
        want[1] = {}
    expect_all(crane, CAP, want, ALL, two_pass=two_pass)


def test_scaling_units_and_bits_as_shown(crane):
    text = crane.verbose(CAP, display_filter="frame.number == 5 or frame.number == 7 or frame.number == 10")
    for line in [
        "Machine data (crane.csv)",
        "Hoist joystick (%): 75.5 (raw 755)",
        "Trolley joystick (%): -25 (raw -250)",
        "..01 .... = Speed range: Low (1)",
        ".... ...0 = Horn button: Released",
        "Hook height (m): 31.2 (raw 512)",
        "Slew angle (°): 90.1 (raw 901)",
        "Load on the hook (t): 52.3 (raw 5230)",
        ".... ...1 = Overload: Yes",
        "0011 .... = Hoist mode: Holding (3)",
        "Wind speed (m/s): 12.75",
        "Cycle counter: 4",
        "Status text: OVERLOAD        ",
    ]:
        assert "        " + line + "\n" in text or "    " + line + "\n" in text, line


def test_filters_and_types(crane):
    assert crane.field(CAP, "frame.number", display_filter="vrshark.io.load > 50") == ["10", "15"]
    assert crane.field(CAP, "frame.number", display_filter="vrshark.io.horn") == ["2", "5", "8", "13"]
    assert crane.field(CAP, "frame.number", display_filter="vrshark.io.horn == 1") == ["8"]
    assert crane.field(CAP, "frame.number", display_filter='vrshark.io.message_text contains "WIND"') == ["16"]
    fields = {line.split("\t")[2]: line.split("\t")[3] for line in
              crane.run(["-G", "fields"], allow_errors=True).stdout.splitlines() if line.startswith("F\t")}
    assert fields["vrshark.io.hoist_speed"] == "FT_DOUBLE"
    assert fields["vrshark.io.operator_id"] == "FT_UINT8"
    assert fields["vrshark.io.cycle"] == "FT_UINT32"
    assert fields["vrshark.io.horn"] == "FT_BOOLEAN"
    assert fields["vrshark.io.wind_speed"] == "FT_FLOAT"
    assert fields["vrshark.io.message_text"] == "FT_STRING"


def test_fault_values_are_experts(crane):
    experts = crane.experts(CAP)
    assert "Overload: Yes (1)" in experts[10]
    assert "Speed range: 3" in experts[13]
    assert "Wind alarm: Yes (1)" in experts[15]
    assert "Message to the operator: Wind alarm (2)" in experts[16]
    assert all("Message to the operator" not in m for m in experts.get(11, []))
    severities = crane.frames(CAP, ["_ws.expert.severity"], display_filter="vrshark_io.fault.error")
    assert sorted(severities) == [10, 13]
    assert crane.field(CAP, "frame.number", display_filter="vrshark_io.fault.warn") == ["15", "16"]
    info = dict(crane.fields(CAP, ["frame.number", "_ws.col.Info"]))
    assert info["10"].endswith("[overload]")
    assert info["15"].endswith("[wind_alarm]")


def test_device_keys_select_the_origin(conf_dir, work_dir):
    """Rows limited to origin=0x2C01 (the BU of the capture) apply on the BU's
    VRCI and, through the learned BU origin, on the controller's VRCO and VRPO;
    rows for another origin never apply."""
    t = described(conf_dir, work_dir, "two.csv", [
        "area,byte,type,name,device",
        "cmd.from_ru,6,u8,op_here,origin=0x2C01",
        "cmd.from_ru,6,u8,op_elsewhere,origin=0x2002",
        "cmd.to_ru,0,u8,code_here,origin=11265",
        "periodic.to_ru,8,u32le,cycle_here,origin=0x2c01",
        "periodic.to_ru,8,u32le,cycle_elsewhere,origin=0x2002",
        "cmd.to_ru,0,u8,code_any,",
        ])
    names = ["vrshark.io." + n for n in ("op_here", "op_elsewhere", "code_here", "cycle_here",
                                         "cycle_elsewhere", "code_any")]
    for two_pass in (False, True):
        frames = t.frames(CAP, names, two_pass=two_pass)
        t.expect(CAP, 2, {"vrshark.io.op_here": 7, "vrshark.io.op_elsewhere": None}, two_pass=two_pass)
        t.expect(CAP, 16, {"vrshark.io.code_here": 2, "vrshark.io.code_any": 2}, two_pass=two_pass)
        t.expect(CAP, 15, {"vrshark.io.cycle_here": 5, "vrshark.io.cycle_elsewhere": None}, two_pass=two_pass)
        assert all(f["vrshark.io.op_elsewhere"] == "" and f["vrshark.io.cycle_elsewhere"] == ""
                   for f in frames.values())


def test_several_device_keys(conf_dir, work_dir):
    """A device cell with several keys (separated by ';') applies wherever
    any of them matches; rows overlap when they share a bit and any device;
    a bad key among several is named."""
    t = described(conf_dir, work_dir, "multi.csv", [
        "area,byte,type,name,device",
        "cmd.from_ru,6,u8,op_here,origin=0x2002; origin=0x2C01",            # 2
        "cmd.from_ru,6,u8,op_elsewhere,origin=0x3003;server=10.0.0.1",       # 3
        "cmd.from_ru,6,u8,op_clash,origin=0x4004;origin=0x2002",             # 4
        "cmd.from_ru,7,u8,op_bad,origin=0x2C01;unit=3",                      # 5
        ])
    names = ["vrshark.io.op_here", "vrshark.io.op_elsewhere"]   # the rows left out have no field
    for two_pass in (False, True):
        t.expect(CAP, 2, {"vrshark.io.op_here": 7, "vrshark.io.op_elsewhere": None}, two_pass=two_pass)
        frames = t.frames(CAP, names, two_pass=two_pass)
        assert sorted(n for n, f in frames.items() if f["vrshark.io.op_here"]) == [2, 5, 8, 13]
        assert not any(f["vrshark.io.op_elsewhere"] for f in frames.values())
    proc = t.run(["-n", "-r", str(CAP), "-c", "1"])
    assert problems(proc) == [
        "multi.csv line 4: 'op_clash' overlaps 'op_here' (line 2) in cmd.from_ru; fix: check byte, bit and type "
        "of both rows; two fields may not share a bit of the same area and device",
        "multi.csv line 5: bad device key 'unit=3'; fix: write terminal=N, slot=N, frame_id=0xNNNN, origin=0xNNNN "
        "or server=<IP address>, or leave it empty for any device"]


def test_reassembled_periodic_data(conf_dir, work_dir):
    """A split VRPO burst is decoded once, from the reassembled data, in the frame that completes it."""
    write(work_dir, "split.csv", "area,byte,type,name\nperiodic.to_ru,1190,u8,far_byte\n"
          "periodic.to_ru,0,u16le,first_word\n")
    t = io_tshark(conf_dir, work_dir)
    frames = t.frames(CAPTURES / "eglink_vrpo_split.pcap", ["vrshark.io.far_byte", "vrshark.io.first_word"])
    decoded = {n: f for n, f in frames.items() if f["vrshark.io.first_word"]}
    assert sorted(decoded) == [3, 6, 9]
    # machine_data(cycle): first word 2350 + 5 * cycle, byte k of the filler (cycle + k - 28) & 0xff
    for cycle, n in enumerate((3, 6, 9)):
        assert int(decoded[n]["vrshark.io.first_word"]) == 2350 + 5 * cycle
        assert int(decoded[n]["vrshark.io.far_byte"]) == (cycle + 1190 - 28) & 0xFF


def test_area_shorter_than_described(conf_dir, work_dir):
    write(work_dir, "long.csv", "area,byte,type,name\nperiodic.to_ru,0,u16le,word0\n"
          "periodic.to_ru,40,u32le,beyond_a\nperiodic.to_ru,60,u8,beyond_b\n")
    t = io_tshark(conf_dir, work_dir)
    t.expect(CAP, 1, {"vrshark.io.word0": 0, "vrshark.io.beyond_a": None})
    assert t.experts(CAP)[1] == ["2 described fields are beyond the 32 bytes of periodic.to_ru: beyond_a, beyond_b"]


def test_no_description_changes_nothing(conf_dir, work_dir, tshark):
    """With an empty description folder the full -V decode of the EG-Link
    captures is the same as with the EG-Link hooks disabled."""
    t = io_tshark(conf_dir, work_dir)
    off = ["--disable-protocol", "vrshark_io_eglink_vrci", "--disable-protocol", "vrshark_io_eglink_vrco",
           "--disable-protocol", "vrshark_io_eglink_vrpo"]
    for name in ("crane_eglink.pcap", "eglink_commands.pcap", "eglink_vrpo_split.pcap", "eglink_armed.pcap"):
        for two_pass in (False, True):
            assert t.verbose(CAPTURES / name, two_pass=two_pass) == \
                t.verbose(CAPTURES / name, two_pass=two_pass, extra=off), name
    assert t.run(["-G", "fields"], allow_errors=True).stdout.count("\tvrshark.io.") == 0
