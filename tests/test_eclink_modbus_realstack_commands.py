"""Commands from the RU over a real Modbus/TCP stack: where a late echo and
a missing echo are reported.

The pymodbus BU of test_eclink_modbus_realstack (alone, mode "commands")
sends CCI 6 at 0.5 s and CCI 7 at 4 s; the PLC, a pymodbus client, reads the
input image every 50 ms and writes the output image, echoing CCI 6 in CAO
only 2.6 s after it first read it, and CCI 7 never. Expected, by what the PLC
logged (not by anything the project generated):
- the response that first carries CCI 6 and the one that first carries
  CCI 7: "not acknowledged" with [unacked] (second pass), linked to the
  first frame of the connection after the deadline;
- the write whose CAO first echoes 6: [late ack] with its latency;
- no other frame tagged, above all no read request (second pass);
- in one pass, as CI runs tshark, the "not acknowledged" warning and
  [unacked] on that first frame after the deadline instead, naming and
  linking the command.
"""
import re
import subprocess
import time

import pytest

import test_eclink_modbus_realstack as rs

ECHO_DELAY_S = 2.6
RUN_S = 6.6


def _plc(log):
    bu = rs._client(rs.BU)
    pco, cao = 1, 5
    first_seen = {}
    end = time.monotonic() + RUN_S
    while time.monotonic() < end:
        rr = bu.read_input_registers(0, count=32, device_id=1)
        assert not rr.isError(), rr
        cci = rr.registers[0] >> 8
        now = time.monotonic()
        first_seen.setdefault(cci, now)
        log["read"].append((now, cci))
        if cci == 6 and now - first_seen[6] >= ECHO_DELAY_S:
            cao = 6
        wr = bu.write_registers(0, rs._output_registers(pco, cao), device_id=1)
        assert not wr.isError(), wr
        log["written"].append((time.monotonic(), pco, cao))
        pco = (pco + 1) & 0xFF
        time.sleep(0.05)
    bu.close()


@pytest.fixture(scope="module")
def commands_capture():
    yield from rs.captured("commands", _plc)


NAMES = ["_ws.col.Info", "modbus.func_code", "eclink.image", "eclink.cci", "eclink.cao",
         "eclink_modbus.deadline_in", "eclink_modbus.cmd_from_ru_in", "eclink_modbus.cmd_from_ru_latency",
         "eclink_modbus.cmd_from_ru.late", "eclink_modbus.cmd_from_ru.late_ack",
         "eclink_modbus.cmd_from_ru.deadline", "frame.time_relative"]


def test_findings_on_the_frames_that_carry_them(tshark, commands_capture):
    cap, log = commands_capture
    # what the PLC saw: CCI 6 then 7, echoed 6 only
    assert [c for c in sorted({c for _, c in log["read"]})] == [5, 6, 7]
    assert {c for _, _, c in log["written"]} == {5, 6}
    got = tshark.frames(cap, NAMES, prefs=rs.PREFS, two_pass=True)
    inputs = [(f, v) for f, v in sorted(got.items()) if v["eclink.image"] == "input"]
    first_6 = next(f for f, v in inputs if v["eclink.cci"] == "6")
    first_7 = next(f for f, v in inputs if v["eclink.cci"] == "7")
    echo = next(f for f, v in sorted(got.items()) if v["eclink.image"] == "output" and v["eclink.cao"] == "6")
    tagged = {f: v["_ws.col.Info"] for f, v in got.items() if "[unacked]" in v["_ws.col.Info"]
              or "[late ack]" in v["_ws.col.Info"]}
    deadlines = {int(got[cmd]["eclink_modbus.deadline_in"]): cmd for cmd in (first_6, first_7)}
    # (the frames past the deadlines too: [unacked] where a live capture shows it)
    assert sorted(tagged) == sorted([first_6, first_7, echo] + list(deadlines))
    assert "Read Input Registers [unacked] [EC-Link input" in tagged[first_6]
    assert "Read Input Registers [unacked] [EC-Link input" in tagged[first_7]
    assert "Write Multiple Registers [late ack] [EC-Link output" in tagged[echo]
    for cmd in (first_6, first_7):
        assert got[cmd]["eclink_modbus.cmd_from_ru.late"]
        deadline = int(got[cmd]["eclink_modbus.deadline_in"])
        # the first frame of the connection past 2 s after the command; it notes it, tagged
        assert 2.0 < float(got[deadline]["frame.time_relative"]) - float(got[cmd]["frame.time_relative"]) < 2.3
        assert got[deadline]["eclink_modbus.cmd_from_ru.deadline"]
        assert int(got[deadline]["eclink_modbus.cmd_from_ru_in"]) == cmd
        assert got[deadline]["_ws.col.Info"].endswith(" [unacked]")
    # the late echo: after about 2.6 s, its own expert, not the unacked one
    assert got[echo]["eclink_modbus.cmd_from_ru.late_ack"] and not got[echo]["eclink_modbus.cmd_from_ru.late"]
    assert int(got[echo]["eclink_modbus.cmd_from_ru_in"]) == first_6
    assert 2.6 <= float(got[echo]["eclink_modbus.cmd_from_ru_latency"]) < 3.0
    # no read request carries a command finding (but the note where a deadline passed)
    assert not [f for f, v in got.items() if v["modbus.func_code"] == "4" and not v["eclink.image"]
                and (v["eclink_modbus.cmd_from_ru.late"] or "[unacked]" in v["_ws.col.Info"] and f not in deadlines)]
    # one pass: each failed command's warning on the frame past its deadline, nowhere else
    one = tshark.frames(cap, NAMES + ["_ws.expert.message"], prefs=rs.PREFS)
    assert sorted(f for f, v in one.items() if v["eclink_modbus.cmd_from_ru.late"]) == sorted(deadlines)
    assert sorted(f for f, v in one.items() if "[unacked]" in v["_ws.col.Info"]) == sorted(deadlines)
    assert not [f for f, v in one.items() if v["eclink_modbus.cmd_from_ru.deadline"]]
    for deadline, cmd in deadlines.items():
        assert int(one[deadline]["eclink_modbus.cmd_from_ru_in"]) == cmd
        cci = got[cmd]["eclink.cci"]
        assert "Command from RU (CCI %s in frame %d) not acknowledged by CAO within 2.000 s: the BU shows \"EC: Bad data\"" % (cci, cmd) \
            in one[deadline]["_ws.expert.message"].split(",")
        assert not one[cmd]["eclink_modbus.deadline_in"] and "[unacked]" not in one[cmd]["_ws.col.Info"]
    assert "[late ack]" in one[echo]["_ws.col.Info"] and not one[echo]["eclink_modbus.cmd_from_ru.late"]


def _stepped_back(capture, frame, folder, seconds=2.0):
    """The capture with frames `frame`.. moved `seconds` earlier, with
    Wireshark's own tools (editcap -r / -t, mergecap -a): a clock set back
    while capturing."""
    head, tail, moved, out = (folder / n for n in ("head.pcapng", "tail.pcapng", "moved.pcapng",
                                                    "stepped.pcapng"))
    subprocess.run(["editcap", "-r", str(capture), str(head), "1-%d" % (frame - 1)], check=True)
    subprocess.run(["editcap", "-r", str(capture), str(tail), "%d-999999999" % frame], check=True)
    subprocess.run(["editcap", "-t", "-%g" % seconds, str(tail), str(moved)], check=True)
    subprocess.run(["mergecap", "-a", "-w", str(out), str(head), str(moved)], check=True)
    out.chmod(0o644)
    return out


def test_clock_step_hides_no_command(tshark, commands_capture, work_dir):
    """Time stepped back 2 s one second after the command CCI 6: the first
    ADU after the step has the clock step warning, the commands not
    acknowledged and the late echo are found on the same frames as without
    the step, and no time is negative (one pass and two)."""
    cap, _ = commands_capture
    names = NAMES + ["eclink_modbus.time_backwards", "eclink_modbus.pci_age", "eclink_modbus.pco_age",
                     "eclink_modbus.time", "_ws.expert.message"]
    want = tshark.frames(cap, names, prefs=rs.PREFS, two_pass=True)
    first_6 = next(f for f, v in sorted(want.items()) if v["eclink.image"] == "input" and v["eclink.cci"] == "6")
    t6 = float(want[first_6]["frame.time_relative"])
    step = next(f for f, v in sorted(want.items())
                if float(v["frame.time_relative"]) > t6 + 1.0 and v["modbus.func_code"])
    stepped = _stepped_back(cap, step, work_dir)
    for two_pass in (True, False):
        got = tshark.frames(stepped, names, prefs=rs.PREFS, two_pass=two_pass)
        ref = want if two_pass else tshark.frames(cap, names, prefs=rs.PREFS)
        assert [f for f, v in got.items() if v["eclink_modbus.time_backwards"]] == [step]
        assert re.search(r"Time went backwards by 1\.\d{3} s after frame \d+ \(clock step\): the PCI, PCO, "
                         r"command deadline and poll gap rules restart here", got[step]["_ws.expert.message"])
        def on(frames, field):
            return sorted(f for f, v in frames.items() if v[field])

        # the commands (two passes) and the late echo: the same frames
        assert on(got, "eclink_modbus.cmd_from_ru.late_ack") == on(ref, "eclink_modbus.cmd_from_ru.late_ack")
        if two_pass:
            assert on(got, "eclink_modbus.cmd_from_ru.late") == on(ref, "eclink_modbus.cmd_from_ru.late")
        # where a deadline is seen passing: the step counts as no time, so
        # the first frame past it comes at most the step's own gap later (the
        # analysis's clock runs on ADUs: the gap from the ADU before, not from
        # a bare TCP segment between them, which a busy machine puts there)
        before = max(f for f in want if f < step and want[f]["modbus.func_code"])
        gap = float(want[step]["frame.time_relative"]) - float(want[before]["frame.time_relative"])
        field = "eclink_modbus.cmd_from_ru.deadline" if two_pass else "eclink_modbus.cmd_from_ru.late"
        moved, orig = on(got, field), on(ref, field)
        assert len(moved) == len(orig) == 2, (two_pass, moved, orig)
        for m, o in zip(moved, orig):
            t_o = float(want[o]["frame.time_relative"])
            skipped = [f for f in want if o <= f < m and want[f]["modbus.func_code"] and float(want[f]["frame.time_relative"]) - t_o > gap + 0.001]
            assert m >= o and not skipped, (two_pass, m, o, gap, skipped)
        for f, v in got.items():
            for field in ("eclink_modbus.pci_age", "eclink_modbus.pco_age", "eclink_modbus.time",
                          "eclink_modbus.cmd_from_ru_latency"):
                assert all(float(x) >= 0 for x in v[field].split(",") if x), (f, field, v[field])
        echo = next(f for f, v in got.items() if v["eclink_modbus.cmd_from_ru.late_ack"])
        assert float(got[echo]["eclink_modbus.cmd_from_ru_latency"]) > 2.0
