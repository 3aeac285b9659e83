"""EC-Link over Modbus/TCP in Input + Commands and Input Only mode, against
a real Modbus/TCP stack: the pymodbus BU of test_eclink_modbus_realstack
(alone, mode "commands": its RU sends CCI 6 at 0.5 s), a pymodbus client as
the PLC, captured on lo.

TS-0007 section 5.1, the Modbus/TCP getting-started guide: Input + Commands
skips step 6 ("update PCO") and 9 (periodic data to the RU); Input Only
skips 4 (writing the output data), 5, 6, 8 and 9. Section 8.4 puts the PCO
monitoring with the periodic output data. So:
- Input + Commands: the PLC writes the 20-byte output image (holding
  registers 0..9), echoes CCI in CAO, and never touches PCO (0 for 2.6 s):
  the connection is recognised, no PCO stall, one note naming the mode;
- Input Only: the PLC only reads: recognised from the input images alone,
  nothing said of PCO.
Expected values come from what the PLC logged.
"""
import time

import pytest

import test_eclink_modbus_realstack as rs

RUN_S = 2.6


def _registers(img):
    return [img[2 * k] | img[2 * k + 1] << 8 for k in range(len(img) // 2)]


def _commands_plc(log):
    bu = rs._client(rs.BU)
    end = time.monotonic() + RUN_S
    while time.monotonic() < end:
        rr = bu.read_input_registers(0, count=32, device_id=1)
        assert not rr.isError(), rr
        cci = rr.registers[0] >> 8
        log["read"].append(cci)
        # PCO 0, CCO 0, PAO 0, CAO = CCI, command to RU: 10 registers
        wr = bu.write_registers(0, _registers(bytes([0, 0, 0, cci]) + b"TO-RU-COMMAND-16"), device_id=1)
        assert not wr.isError(), wr
        log["written"].append(cci)
        time.sleep(0.05)
    bu.close()


def _input_only_plc(log):
    bu = rs._client(rs.BU)
    end = time.monotonic() + 1.5
    while time.monotonic() < end:
        rr = bu.read_input_registers(0, count=32, device_id=1)
        assert not rr.isError(), rr
        log["read"].append(rr.registers[0] >> 8)
        time.sleep(0.05)
    bu.close()


@pytest.fixture(scope="module")
def commands_capture():
    yield from rs.captured("commands", _commands_plc)


@pytest.fixture(scope="module")
def input_only_capture():
    yield from rs.captured("commands", _input_only_plc)


NAMES = ["modbus.func_code", "eclink.image", "eclink.pco", "eclink.cao", "eclink.cci", "eclink.periodic_size",
         "eclink_modbus.accepted_in", "eclink_modbus.pco_age", "eclink_modbus.pco_stalled",
         "eclink_modbus.commands_mode", "eclink_modbus.cmd_from_ru.ack", "_ws.expert.message",
         "frame.time_relative"]


@pytest.mark.parametrize("two_pass", [False, True])
def test_input_and_commands_mode(tshark, commands_capture, two_pass):
    cap, log = commands_capture
    assert 6 in log["read"] and set(log["written"]) >= {5, 6}
    got = tshark.frames(cap, NAMES, prefs=rs.PREFS, two_pass=two_pass)
    outputs = [n for n, v in sorted(got.items()) if v["eclink.image"] == "output"]
    assert outputs, "the connection is recognised"
    # as the PLC wrote them: PCO 0 on every write, CAO echoing CCI; no periodic data
    decoded = [int(got[n]["eclink.cao"]) for n in outputs]
    assert decoded == log["written"][-len(decoded):]
    assert {got[n]["eclink.pco"] for n in outputs} == {"0"}
    assert {got[n]["eclink.periodic_size"] for n in outputs} == {""}
    t = [float(got[n]["frame.time_relative"]) for n in outputs]
    assert t[-1] - t[0] > 2.0, "PCO stood for over 2000 ms"
    # no PCO stall, no PCO age: not supervised in this mode
    assert not any(v["eclink_modbus.pco_stalled"] or v["eclink_modbus.pco_age"] for v in got.values())
    # one note naming the mode, on the first output write of the recognised
    # connection, in one pass as with -2
    noted = [n for n, v in got.items() if v["eclink_modbus.commands_mode"]]
    accepted = int(next(v["eclink_modbus.accepted_in"] for v in got.values() if v["eclink_modbus.accepted_in"]))
    writes = [n for n, v in sorted(got.items()) if v["modbus.func_code"] == "16" and n > accepted
              and v["eclink.image"] == "output"]
    assert noted == [writes[0]]
    # the mode's own counters are still supervised: CCI 6 echoed by CAO
    assert [n for n, v in got.items() if v["eclink_modbus.cmd_from_ru.ack"]]


@pytest.mark.parametrize("two_pass", [False, True])
def test_input_only_mode(tshark, input_only_capture, two_pass):
    cap, log = input_only_capture
    got = tshark.frames(cap, NAMES, prefs=rs.PREFS, two_pass=two_pass)
    inputs = [n for n, v in sorted(got.items()) if v["eclink.image"] == "input"]
    assert inputs and len(inputs) >= len(log["read"]) - 8, "recognised from the input images alone"
    assert not any(v["eclink.image"] == "output" for v in got.values())
    assert not any(v["eclink_modbus.pco_stalled"] or v["eclink_modbus.commands_mode"] or v["eclink_modbus.pco_age"]
                   for v in got.values())
