"""The "eglink.data" dissector table: the EG-Link plugin hands the machine's own
data areas to whoever registered for them, without knowing their format.

A probe Lua script registers for "vrci", "vrco" and "vrpo" and shows the area
name and the bytes it was given; the bytes must be exactly the command data of
each VRCI/VRCO, the periodic data of a one-packet VRPO burst, and the
reassembled periodic data of a split burst (once, in the frame that completes it).
"""
import pytest

from conftest import CAPTURES

PROBE = r"""
local probe = Proto("eglink_data_probe", "eglink.data probe")
local f_area = ProtoField.string("eglink_data_probe.area", "Area")
local f_data = ProtoField.bytes("eglink_data_probe.data", "Data")
probe.fields = { f_area, f_data }
for _, area in ipairs({ "vrci", "vrco", "vrpo" }) do
    local d = Proto("eglink_data_probe_" .. area, "probe " .. area)
    function d.dissector(tvb, _, tree)
        local t = tree:add(probe, tvb())
        t:add(f_area, area)
        t:add(f_data, tvb())
        return tvb:len()
    end
    DissectorTable.get("eglink.data"):add(area, d)
end
"""

NAMES = ["eglink.type", "eglink.packet_number", "eglink.command_data", "eglink.periodic_data",
         "eglink_data_probe.area", "eglink_data_probe.data"]


@pytest.fixture
def probe(work_dir):
    script = work_dir / "eglink_data_probe.lua"
    script.write_text(PROBE)
    script.chmod(0o644)
    return ["-X", "lua_script:%s" % script]


@pytest.mark.parametrize("two_pass", [False, True])
def test_command_data_handed_on(tshark, probe, two_pass):
    frames = tshark.frames(CAPTURES / "eglink_commands.pcap", NAMES, extra=probe, two_pass=two_pass)
    commands = [n for n, f in frames.items() if f["eglink.type"] in ("VRCI", "VRCO")]
    assert len(commands) == 5
    for n, f in frames.items():
        if f["eglink.type"] in ("VRCI", "VRCO"):
            assert f["eglink_data_probe.area"] == f["eglink.type"].lower(), n
            assert f["eglink_data_probe.data"] == f["eglink.command_data"], n
            assert len(f["eglink_data_probe.data"]) == 32, n
        elif f["eglink.type"] == "VRPO":
            # A one-packet burst: its periodic data as it is.
            assert f["eglink.packet_number"] == "0", n
            assert f["eglink_data_probe.area"] == "vrpo", n
            assert f["eglink_data_probe.data"] == f["eglink.periodic_data"], n
        else:
            assert f["eglink_data_probe.area"] == "", n


@pytest.mark.parametrize("two_pass", [False, True])
def test_reassembled_periodic_data_handed_on_once(tshark, probe, two_pass):
    frames = tshark.frames(CAPTURES / "eglink_vrpo_split.pcap", NAMES, extra=probe, two_pass=two_pass)
    handed = {n: f for n, f in frames.items() if f["eglink_data_probe.area"]}
    assert sorted(handed) == [3, 6, 9]
    for last in (3, 6, 9):
        fragments = "".join(frames[n]["eglink.periodic_data"].split(",")[0] for n in (last - 2, last - 1, last))
        assert handed[last]["eglink_data_probe.area"] == "vrpo"
        assert handed[last]["eglink_data_probe.data"] == fragments


def test_nothing_registered_nothing_changes(tshark):
    """Without a registration the decode is the same as before (no probe fields, no errors)."""
    frames = tshark.frames(CAPTURES / "eglink_commands.pcap", ["eglink.type", "eglink.command_data"])
    assert [f["eglink.type"] for f in frames.values()].count("VRCI") == 3
