"""The Lua side's state that the C front ends read on every frame
(plugins/vrshark/vrshark-flags.c, taken by lua/vrshark/frontends.luam with
package.loadlib): the flags FLAG_PN_PENDING and FLAG_PN_RESPONSE, the listed
servers, the word that the Modbus hooks changed. Set by Lua the moment they
change; where the functions cannot be bound (VRSHARK_LUA_FLAGS set, as
without package.loadlib) the C side asks Lua about every frame it might
want, looks the servers up in the hook table and reads the Modbus hooks on
every frame: the same decode, slower."""
import copy
import os

import pytest

from conftest import CAPTURES

needs_c = pytest.mark.skipif(bool(os.environ.get("VRSHARK_NO_C_PLUGIN")), reason="runs without the C plugin")

# What frontends.luam bound, what the C functions answer to a wrong name,
# and what a mistyped key handed to fe.hook does.
PROBE = r"""
package.path = %(lua)r .. "/?.luam;" .. package.path
local fe = require("vrshark.frontends")
local seam = require("vrshark.seam")
local out = assert(io.open(%(out)r, "w"))
out:write("bound ", tostring(fe.flags), "\n")
local lib = os.getenv(seam.ENV_FRONTENDS_LIB)
if fe.flags then
    local flag = package.loadlib(lib, seam.FN_FLAG)
    local servers = package.loadlib(lib, seam.FN_SERVERS)
    out:write("flag_mistyped ", tostring(flag("pn.pendng", true)), "\n")
    out:write("flag_missing_on ", tostring(flag(seam.FLAG_PN_PENDING)), "\n")
    out:write("servers_no_prefix ", tostring(servers(seam.server_key("10.0.0.1"), "10.0.0.2")), "\n")
    out:write("servers_listed ", tostring(servers(seam.server_key("10.0.0.1", 502))), "\n")
    out:write("servers_none ", tostring(servers()), "\n")
end
for _, key in ipairs({ "pn.pendng", seam.MB_HOOK_ALWAYS }) do
    local ok, err = pcall(fe.hook, fe.pn_hook, key, nil, true)
    out:write("hook_", key, " ", tostring(ok), " ", tostring(err), "\n")
end
out:close()
"""


def unbound(tshark):
    """The same tshark with the state functions left unbound."""
    t = copy.copy(tshark)
    t.env = dict(tshark.env, VRSHARK_LUA_FLAGS="1")
    t._cache = {}
    return t


def probe(lua_probe):
    return dict(line.split(" ", 1) for line in lua_probe(PROBE))


@needs_c
def test_the_state_is_bound_and_refuses_a_wrong_name(lua_probe):
    got = probe(lua_probe)
    assert "no hook pn.pendng in vrshark.pn.hook" in got.pop("hook_pn.pendng")
    assert "no hook always in vrshark.pn.hook" in got.pop("hook_always")
    assert got == {"bound": "true", "flag_mistyped": "false", "flag_missing_on": "false",
                   "servers_no_prefix": "false", "servers_listed": "true", "servers_none": "true"}


@needs_c
def test_left_unbound_with_vrshark_lua_flags(tshark, lua_probe, monkeypatch):
    monkeypatch.setitem(tshark.env, "VRSHARK_LUA_FLAGS", "1")
    got = probe(lua_probe)
    assert got["bound"] == "false"
    assert "no hook pn.pendng in vrshark.pn.hook" in got["hook_pn.pendng"]


@pytest.mark.skipif(not os.environ.get("VRSHARK_NO_C_PLUGIN"), reason="runs with the C plugin")
def test_nothing_to_bind_without_the_c_plugin(lua_probe):
    got = probe(lua_probe)
    assert got["bound"] == "false"
    # (no hook tables without the C plugin: fe.hook has nothing to put a key in)
    assert got["hook_pn.pendng"].startswith("false ")


# Every capture of the Lua-decoded PROFINET and Modbus/TCP protocols, one
# after the other in one file, with settings that use each piece of state:
# the candidates and the inference (mcmb2.heuristic), Connect responses,
# listed servers (one with its port, one for every port) beside the
# detection, each detection.
OURS = sorted(p.name for p in CAPTURES.glob("*.pcap")
              if p.name.startswith(("crane_eclink", "crane_mcmb2", "eclink_", "mcmb2_", "modbus_", "snaplen_",
                                    "clockstep_")))
SETTINGS = {
    "defaults": [],
    "servers": ["-o", "eclink_modbus.servers:192.168.2.41:5020,10.0.0.1,192.168.2.41"],
    "servers, detection off": ["-o", "eclink_modbus.detection:off", "-o", "eclink_modbus.servers:192.168.2.41"],
    "always, no heuristic": ["-o", "eclink_modbus.detection:always", "-o", "mcmb2.heuristic:FALSE"],
}
RUNS = {"details": ["-n", "-V"], "two passes": ["-n", "-2", "-V"]}


@needs_c
@pytest.mark.parametrize("settings", sorted(SETTINGS))
@pytest.mark.parametrize("run", sorted(RUNS))
def test_unbound_decodes_the_same(tshark, merged_captures, settings, run):
    merged = merged_captures(OURS)
    args = RUNS[run] + SETTINGS[settings] + ["-r", str(merged.path)]
    bound = tshark.run(args, cache=False).stdout
    left_out = unbound(tshark).run(args, cache=False).stdout
    assert bound.strip()
    assert bound == left_out, merged.first_difference(bound, left_out)
