"""The contract between the C plugin and the Lua plugins as the C side
defines it (plugins/vrshark/vrshark-frontends.h; tests/test_seam.py holds
lua/vrshark/seam.luam to it): {name without VRSHARK_: value}."""
import re

from conftest import ROOT

HEADER = ROOT / "plugins" / "vrshark" / "vrshark-frontends.h"
EGLINK_HEADER = ROOT / "plugins" / "vrshark" / "packet-eglink.h"


def header_defines(path, prefix):
    """{name without prefix: value} of the #defines of a string or a number."""
    found = {}
    for name, value in re.findall(r'^#define\s+%s(\w+)\s+("[^"]*"|\d+)\s*$' % prefix, path.read_text(), re.M):
        found[name] = value[1:-1] if value.startswith('"') else int(value)
    return found


CONTRACT = header_defines(HEADER, "VRSHARK_")
CONTRACT["EGLINK_DATA_TABLE"] = header_defines(EGLINK_HEADER, "")["EGLINK_DATA_TABLE"]
