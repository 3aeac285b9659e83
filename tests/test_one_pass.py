"""A one-pass tshark run keeps no per-frame records (lua/vrshark/passes.luam):
the EC-Link over Modbus/TCP decoder and the PROFINET carrier keep what a
frame's first pass worked out only for a later pass, and a tshark run without
-2 has none. Nothing shown may change: the same run under a program name
other than tshark keeps them (passes.once() is false there) and must print
the very same packet details."""
import pytest

PASSES = r"""
package.path = %(lua)r .. "/?.luam;" .. package.path
local passes = require("vrshark.passes")
local out = assert(io.open(%(out)r, "w"))
local cases = {
    { "tshark", "-r", "x.pcap" },
    { "/usr/bin/tshark", "-n", "-r", "x.pcap", "-Y", "eclink" },
    { "tshark", "-2", "-r", "x.pcap" },
    { "tshark", "-r", "x.pcap", "-2" },
    { "tshark", "-n2r", "x.pcap" },
    { "tshark", "-Y", "-2", "-r", "x.pcap" },
    { "tshark", "-Y-2", "-r", "x.pcap" },
    { "tshark", "-o", "x:-2", "-r", "x.pcap" },
    { "tshark", "-nr", "x.pcap", "--", "-2" },
    { "wireshark", "-r", "x.pcap" },
    { "sharkd", "-" },
    {},
}
for i, words in ipairs(cases) do
    out:write(string.format("%%d %%s\n", i, tostring(passes.once_args(words))))
end
out:write("this " .. tostring(passes.once()) .. "\n")
out:close()
"""


def test_which_runs_are_one_pass(lua_probe):
    got = dict(line.split(" ", 1) for line in lua_probe(PASSES))
    assert got == {
        "1": "true", "2": "true",
        "3": "false", "4": "false", "5": "false",   # -2, alone or among other options
        "6": "true", "7": "true", "8": "true",      # "-2" as the value of an option
        "9": "true",                                # after --: no option
        "10": "false", "11": "false", "12": "false",  # not tshark: every frame may be shown again
        "this": "true",                             # the probe's own run: tshark -n -q -r ... -c 1
    }


# (capture, text the details must hold: the decoder ran)
CAPTURES = [
    ("crane_eclink_modbus.pcap", "EC-Link input image"),
    ("eclink_modbus_faults.pcap", "EC-Link"),
    ("eclink_modbus_periodic.pcap", "Reassembled periodic data"),
    ("crane_eclink_pnio.pcap", "EC-Link input image"),
    ("eclink_pnio_noconnect.pcap", "EC-Link"),
    ("crane_mcmb2.pcap", "MC-MB2-PN"),
    ("mcmb2_duplex_noconnect.pcap", "MC-MB2-PN"),
    ("mcmb2_polled_connect.pcap", "MC-MB2-PN"),
]


@pytest.mark.parametrize("name,marker", CAPTURES)
def test_one_pass_shows_what_keeping_records_shows(tshark, keeping_tshark, capture_file, name, marker):
    args = ["-n", "-r", str(capture_file(name)), "-V"]
    once = tshark.run(args, cache=False).stdout
    kept = keeping_tshark.run(args, cache=False).stdout
    assert marker in once
    assert once == kept


@pytest.mark.parametrize("name,marker", [("crane_eclink_modbus.pcap", "[EC-Link "),
                                         ("crane_eclink_pnio.pcap", "acknowledges the command"),
                                         ("crane_mcmb2.pcap", "MCMB2")])
def test_one_pass_columns_and_experts_as_when_kept(tshark, keeping_tshark, capture_file, name, marker):
    # the packet list's case: an invisible tree (the sparse view), Info and -z expert
    args = ["-n", "-r", str(capture_file(name)), "-z", "expert"]
    once = tshark.run(args, cache=False).stdout
    kept = keeping_tshark.run(args, cache=False).stdout
    assert marker in once
    assert once == kept


# Traffic the project did not make: real PROFINET IO devices (their frames
# reach the carrier as candidates and Connects) and a real Modbus/TCP device.
# (The EC-Link BU of a real pymodbus stack: test_eclink_modbus_realstack.py.)
@pytest.mark.parametrize("name", ["pnio_connect_and_cyclic.pcap", "pnio_connect_many.pcapng",
                                  "modbus_example.pcap"])
def test_public_captures_one_pass_as_when_kept(tshark, keeping_tshark, public_capture, name):
    for args in (["-V"], ["-z", "expert"]):
        args = ["-n", "-r", str(public_capture(name))] + args
        assert tshark.run(args, cache=False).stdout == keeping_tshark.run(args, cache=False).stdout
