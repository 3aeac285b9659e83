"""Statistics > EG-Link without the C plugin (lua/vrshark/eglink_stats.luam):
with VRSHARK_EGLINK_STATS set, a Lua-only tshark run prints the same tree as
the C plugin's -z eglink,stat (eglink-stats.c), rows, counts, averages,
minimums, maximums and percentages, in one pass and two (docs/eglink.md,
"EG-Link in Lua")."""
import os
import re
import subprocess

import pytest

from conftest import ROOT

TSHARK = str(ROOT / "tools" / "tshark")
ROW = re.compile(r"^(\s*\S.*?)\s{2,}(\d+)\s*(.*)$")


def _rows(text):
    rows = []
    for line in text.splitlines():
        if not line.strip() or line.startswith(("=", "-", "EG-Link:", "Topic")):
            continue
        m = ROW.match(line)
        assert m, line
        rows.append((m.group(1), int(m.group(2)), m.group(3).split()))
    return rows


def _c_stats(capture, two_pass):
    env = {k: v for k, v in os.environ.items() if k != "VRSHARK_NO_C_PLUGIN"}
    args = [TSHARK, "-r", str(capture), "-q", "-z", "eglink,stat"] + (["-2"] if two_pass else [])
    out = subprocess.run(args, env=env, capture_output=True, text=True, check=True).stdout
    rows = []
    for name, count, vals in _rows(out):
        pct = [v for v in vals if v.endswith("%")]
        before = vals[:vals.index(pct[0])]
        # Average, Min Val, Max Val (value rows), then Rate (ms)
        rows.append((name, count, before[:-1], pct[0]))
    return rows


def _lua_stats(capture, two_pass):
    env = dict(os.environ, VRSHARK_NO_C_PLUGIN="1", VRSHARK_EGLINK_STATS="1")
    args = [TSHARK, "-r", str(capture), "-q"] + (["-2"] if two_pass else [])
    proc = subprocess.run(args, env=env, capture_output=True, text=True, check=True)
    assert "Lua" not in proc.stderr
    return [(name, count, vals[:-1], vals[-1]) for name, count, vals in _rows(proc.stdout)]


@pytest.mark.parametrize("two_pass", [False, True])
@pytest.mark.parametrize("name", ["eglink_analysis_session.pcap", "eglink_analysis_vrci_unacked.pcap",
                                  "eglink_analysis_vrpo_incomplete.pcap", "eglink_analysis_two_bus.pcap"])
def test_lua_stats_match_c(name, two_pass):
    capture = ROOT / "captures" / name
    lua = _lua_stats(capture, two_pass)
    assert lua, "no statistics printed"
    assert lua == _c_stats(capture, two_pass)


def test_lua_stats_session_values():
    """The session capture's tree, by row: intervals, acknowledgement times and
    the BU state periods (TS-0006 4.1.1)."""
    rows = {(name.strip(), count): vals for name, count, vals, _ in
            _lua_stats(ROOT / "captures" / "eglink_analysis_session.pcap", False)}
    assert ("EG-Link base units", 60) in rows
    assert rows[("Interval (ms)", 22)] == ["130.68", "125", "250"]
    assert rows[("Acknowledgement time (ms)", 2)] == ["80.00", "50", "110"]
    assert rows[("0x11 Armed", 1)] == ["1000.00", "1000", "1000"]


def test_walkthrough_names_the_lua_menu_item():
    """README's walkthrough names the Statistics item of both installs: the Lua
    EG-Link registers its own (a Lua plugin cannot take the C plugin's name)."""
    lua = (ROOT / "lua" / "vrshark" / "eglink_stats.luam").read_text()
    item = re.search(r'register_menu\("([^"]+)"', lua).group(1)
    walkthrough = (ROOT / "README.md").read_text().split("## A five-minute walkthrough", 1)[1].split("\n## ")[0]
    text = " ".join(walkthrough.split())
    assert item == "EG-Link (Lua)"
    assert "*Statistics > EG-Link* (*%s* in the Lua-only install)" % item in text
