"""The clock of streams that stop (lua/vrshark/deadlines.luam) reaches
frames no Lua decoder sees: with the C plugin through hook "clock" of the
front ends (vrshark-frontends.c:clock_tick, told the earliest deadline and
the marked frames by vrshark_lua_clock_due and _mark), without it through
the Lua carrier, which sees every PROFINET frame.

A probe script arms one deadline on the first frame, DT seconds later; its
finding (an item and an Info tag) must be on the first frame after the
deadline, whatever that frame is: a PNIO-CM datagram, a PN-PTCP frame
(EtherType 0x8892, no FrameID of ours), a Modbus/TCP poll of a server that
is no BU. One pass and -2 agree, and the finding is on that frame alone.
tools/test runs this file in both phases; the Modbus/TCP frame is the C
front end's (without the C plugin eclink_modbus.lua ticks the clock).
"""
import os

import pytest

from conftest import ROOT

PROBE = """
package.path = %(lua)r .. "/?.luam;" .. package.path
local d = require("vrshark.deadlines")
local p = Proto("clockprobe", "clock probe")
local armed = false
register_postdissector(p)
function p.init() armed = false end
function p.dissector(tvb, pinfo, tree)
    if pinfo.visited or armed then return end
    armed = true
    local from = pinfo.number
    d.arm("probe", pinfo.abs_ts + %(dt)s, function(pi, now)
        local n = pi.number
        return function(tvb2, pinfo2, tree2)
            tree2:add(p, tvb2(0, 0), string.format("probe fired on %%d, armed on %%d", n, from))
            pinfo2.cols.info:append(" [probe]")
        end
    end)
end
"""

PASSES = pytest.mark.parametrize("two_pass", [False, True], ids=["one-pass", "two-pass"])
C_PLUGIN = not os.environ.get("VRSHARK_NO_C_PLUGIN")


def probed(tshark, work_dir, capture, dt, two_pass):
    """{frame number: Info} of the frames whose Info carries the probe's tag."""
    script = work_dir / ("probe-%s.lua" % str(dt).replace(".", "_"))
    script.write_text(PROBE % {"lua": str(ROOT / "lua"), "dt": dt})
    script.chmod(0o644)
    args = ["-n", "-r", str(capture), "-X", "lua_script:%s" % script, "-T", "fields", "-e", "frame.number",
            "-e", "_ws.col.Protocol", "-e", "_ws.col.Info"] + (["-2"] if two_pass else [])
    out = tshark.run(args, cache=False).stdout
    got = {}
    for line in out.splitlines():
        number, proto, info = line.split("\t", 2)
        if "[probe]" in info:
            got[int(number)] = proto
    return got


@PASSES
@pytest.mark.parametrize("dt, frame, proto", [(0.05, 9, "PNIO-CM"), (1.0, 34, "PN-PTCP")], ids=["pnio-cm", "pn-rt"])
def test_the_clock_reaches_a_frame_no_decoder_sees(tshark, work_dir, public_capture, dt, frame, proto, two_pass):
    cap = public_capture("pnio_connect_and_cyclic.pcap")
    assert probed(tshark, work_dir, cap, dt, two_pass) == {frame: proto}


@PASSES
@pytest.mark.skipif(not C_PLUGIN, reason="without the C plugin eclink_modbus.lua ticks the clock")
def test_the_modbus_front_end_ticks_the_clock(tshark, work_dir, public_capture, two_pass):
    cap = public_capture("modbus_example.pcap")
    assert probed(tshark, work_dir, cap, 0.5, two_pass) == {99: "Modbus/TCP"}
