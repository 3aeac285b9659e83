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


# --- the mode: guessed (auto) or set (eclink_modbus.mode, an entry of eclink_modbus.servers) ---

GUESSED = ("PCO 0 has not changed for %s (limit 2.000 s): if this BU runs in Standard mode, it shows "
           "\"EC: Bad data\" and opens the relays with an RU armed; Input + Commands mode is guessed "
           "(set it: eclink_modbus.mode)")
MODE_NAMES = ["eclink.image", "eclink_modbus.pco_stalled", "eclink_modbus.pco_stalled.guessed",
              "eclink_modbus.commands_mode", "eclink_modbus.pco_since", "_ws.expert.message", "_ws.expert.severity"]


def _mode_frames(tshark, cap, prefs, two_pass):
    got = tshark.frames(cap, MODE_NAMES, prefs=dict(rs.PREFS, **prefs), two_pass=two_pass)
    kinds = {k: [n for n, v in sorted(got.items()) if v[k]] for k in
             ("eclink_modbus.pco_stalled", "eclink_modbus.pco_stalled.guessed", "eclink_modbus.commands_mode")}
    return got, kinds


@pytest.mark.parametrize("two_pass", [False, True])
def test_guessed_mode_says_what_a_pco_stall_would_be(tshark, commands_capture, two_pass):
    """auto (the default): the PLC writes only holding registers 0..9, so the BU is
    taken for Input + Commands and PCO is not supervised as an error; but a PCO that
    stands over 2000 ms is exactly when a Standard-mode BU shows "EC: Bad data": a
    warning (not a note) that names the guess, once, on the first write past the limit."""
    cap, _ = commands_capture
    got, kinds = _mode_frames(tshark, cap, {}, two_pass)
    assert kinds["eclink_modbus.pco_stalled"] == []
    warned = kinds["eclink_modbus.pco_stalled.guessed"]
    assert len(warned) == 1 and kinds["eclink_modbus.commands_mode"], kinds
    v = got[warned[0]]
    assert v["eclink.image"] == "output" and v["eclink_modbus.pco_since"]
    msg = [m for m in v["_ws.expert.message"].split(",") if m.startswith("PCO 0 has not")]
    assert len(msg) == 1
    age = msg[0].split("for ", 1)[1].split(" (", 1)[0]
    assert float(age.split()[0]) > 2.0
    assert v["_ws.expert.message"].count(GUESSED % age) == 1
    assert "6291456" in v["_ws.expert.severity"].split(",")        # warning


@pytest.mark.parametrize("prefs", [
    {"eclink_modbus.mode": "standard"},
    {"eclink_modbus.servers": "%s:%d=standard" % (rs.BU, rs.PORT)},
    # the server's own mode wins over the preference
    {"eclink_modbus.mode": "input_commands", "eclink_modbus.servers": "%s:%d=standard" % (rs.BU, rs.PORT)},
], ids=["preference", "server-entry", "entry-over-preference"])
@pytest.mark.parametrize("two_pass", [False, True])
def test_standard_mode_set_makes_the_stall_an_error(tshark, commands_capture, prefs, two_pass):
    """Set to Standard (the preference, or the server's entry in eclink_modbus.servers):
    the PCO that stands is the error it is at the BU, with what the BU shows; no note of
    Input + Commands mode, no guess."""
    cap, _ = commands_capture
    got, kinds = _mode_frames(tshark, cap, prefs, two_pass)
    assert kinds["eclink_modbus.commands_mode"] == [] and kinds["eclink_modbus.pco_stalled.guessed"] == []
    assert len(kinds["eclink_modbus.pco_stalled"]) == 1, kinds
    v = got[kinds["eclink_modbus.pco_stalled"][0]]
    assert "8388608" in v["_ws.expert.severity"].split(",")        # error
    assert [m for m in v["_ws.expert.message"].split(",") if m.startswith("PCO 0 has not")][0].endswith(
        "(limit 2.000 s): the BU shows \"EC: Bad data\"")


@pytest.mark.parametrize("prefs,noted", [
    ({"eclink_modbus.mode": "input_commands"}, True),
    ({"eclink_modbus.servers": "%s:%d=input_commands" % (rs.BU, rs.PORT)}, True),
    ({"eclink_modbus.mode": "input_only"}, False),
], ids=["input_commands", "server-entry", "input_only"])
@pytest.mark.parametrize("two_pass", [False, True])
def test_mode_set_to_one_without_pco(tshark, commands_capture, prefs, noted, two_pass):
    """Set to Input + Commands: the user knows the mode, the note stays and PCO is
    not watched (no warning); Input Only: no output image is supervised at all."""
    cap, _ = commands_capture
    got, kinds = _mode_frames(tshark, cap, prefs, two_pass)
    assert kinds["eclink_modbus.pco_stalled"] == [] and kinds["eclink_modbus.pco_stalled.guessed"] == []
    assert bool(kinds["eclink_modbus.commands_mode"]) == noted
