"""The Protocol and Info columns written through the C plugin
(plugins/vrshark/vrshark-columns.c, taken by lua/vrshark/frontends.luam with
package.loadlib): a Lua decoder called by a front end hands its text over
as parts, and the C plugin joins and writes them. Without the plugin, or
with VRSHARK_LUA_COLUMNS set, the decoders write through pinfo.cols. What
a user sees must be the same either way."""
import os

import pytest

from conftest import CAPTURES

needs_c = pytest.mark.skipif(bool(os.environ.get("VRSHARK_NO_C_PLUGIN")), reason="runs without the C plugin")

WRITERS = r"""
package.path = %(lua)r .. "/?.luam;" .. package.path
local fe = require("vrshark.frontends")
local out = assert(io.open(%(out)r, "w"))
out:write("set_cols " .. type(fe.set_cols) .. "\n")
out:write("append_info " .. type(fe.append_info) .. "\n")
-- no front end is calling a decoder now: nothing is written
if fe.set_cols then
    out:write("outside " .. tostring(fe.set_cols("MC-MB2", "a", "b")) .. " "
              .. tostring(fe.append_info("a", "b")) .. "\n")
end
out:close()
"""


@needs_c
def test_the_writers_come_from_the_c_plugin(lua_probe):
    got = dict(line.split(" ", 1) for line in lua_probe(WRITERS))
    assert got == {"set_cols": "function", "append_info": "function", "outside": "false false"}


@pytest.mark.skipif(not os.environ.get("VRSHARK_NO_C_PLUGIN"), reason="runs with the C plugin")
def test_without_the_c_plugin_pinfo_cols(lua_probe):
    assert lua_probe(WRITERS) == ["set_cols nil", "append_info nil"]


# every capture of the Lua-decoded protocols (several ADUs in a segment,
# partial images, bit accesses, polled and duplex layouts, findings)
OURS = sorted(p.name for p in CAPTURES.glob("*.pcap")
              if p.name.startswith(("crane_eclink", "crane_mcmb2", "eclink_", "mcmb2_", "modbus_")))

RUNS = {
    "packet list": ["-n"],
    "two passes": ["-n", "-2"],
    "filtered": ["-n", "-Y", "!(eclink.pci == 255 and mcmb2.uplink_watchdog == 255)"],  # (an invisible tree)
    "details": ["-n", "-P", "-V"],
}


@needs_c
@pytest.mark.parametrize("run", sorted(RUNS))
def test_columns_as_through_pinfo_cols(tshark, merged_captures, run):
    """Every capture of OURS, one after the other in one file: the same
    output through C as through pinfo.cols, frame by frame."""
    merged = merged_captures(OURS)
    args = RUNS[run][:1] + ["-r", str(merged.path)] + RUNS[run][1:]
    through_c = tshark.run(args, cache=False).stdout
    lua_cols = tshark.__class__(tshark.env["WIRESHARK_CONFIG_DIR"])
    lua_cols.env["VRSHARK_LUA_COLUMNS"] = "1"
    through_lua = lua_cols.run(args, cache=False).stdout
    assert through_c.strip()
    assert through_c == through_lua, merged.first_difference(through_c, through_lua)


PROBE = r"""
package.path = %(lua)r .. "/?.luam;" .. package.path
local fe = require("vrshark.frontends")
local out = assert(io.open(%(out)r, "w"))
local probe = Proto("vrshark_colprobe", "column writer probe")
local install
function probe.dissector(tvb, pinfo, tree)
    if pinfo.match_string == nil then install() return 0 end  -- the postdissector call
    -- (as many parts as an EC-Link summary has, and more)
    local ok = fe.append_info(" [probe ", tostring(pinfo.number), " a", "b", "c", "d", "e", "f", "g", "h", "i",
                              "j", "k", "l", "m", "n", "]")
    out:write(string.format("%%d %%s\n", pinfo.number, tostring(ok)))
    out:flush()
    return 0
end
function install() DissectorTable.get("vrshark.mbtcp.hook"):add("always", probe) end
register_postdissector(probe)
"""


@needs_c
def test_a_front_end_call_writes_through_c(tshark, work_dir, capture_file):
    """A decoder the Modbus front end calls writes through append_info(): it
    says so, and the text is in the Info column of that frame."""
    out = work_dir / "probe.txt"
    out.touch()
    out.chmod(0o666)
    script = work_dir / "probe.lua"
    script.write_text(PROBE % {"lua": str(CAPTURES.parent / "lua"), "out": str(out)})
    script.chmod(0o644)
    lines = tshark.run(["-n", "-r", str(capture_file("crane_eclink_modbus.pcap")), "-X", "lua_script:%s" % script],
                       cache=False).stdout.splitlines()
    calls = [line.split() for line in out.read_text().splitlines()]
    assert len(calls) >= 16
    assert {ok for _, ok in calls} == {"true"}
    for frame, _ in calls:
        assert lines[int(frame) - 1].endswith(" [probe %s abcdefghijklmn]" % frame)
