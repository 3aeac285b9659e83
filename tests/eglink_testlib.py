"""Helpers for the EG-Link dissector tests: its own expert names, expert info
read from -T json so that findings of other EG-Link modules do not get in the
way, by-name assertions over several frames, and what tells the C plugin from
the Lua EG-Link (tools/test's Lua-only phase, VRSHARK_NO_C_PLUGIN=1)."""
import copy
import os
import sys
from pathlib import Path

from conftest import ROOT, same_value

if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from tools.capgen import eglink as gen  # noqa: E402  (the capture generator)

# Every expert field packet-eglink.c registers.
DISSECTOR_EXPERTS = {
    "eglink.too_short", "eglink.size.mismatch", "eglink.size.invalid", "eglink.type.unknown",
    "eglink.revision.unknown", "eglink.origin.nonzero", "eglink.origin.zero",
    "eglink.spare.nonzero", "eglink.payload_spare.nonzero", "eglink.crc.bad",
    "eglink.crc.variant", "eglink.bu_state.relays_open", "eglink.bu_state.unknown",
    "eglink.link_status.unknown", "eglink.vlaps.range", "eglink.ru_state.stopped",
    "eglink.ru_state.unknown", "eglink.ru_battery.range", "eglink.ru_rssi.range",
    "eglink.flag.invalid", "eglink.ru_disabled.unknown", "eglink.joystick.range",
    "eglink.armed_ru.unarmed_data", "eglink.link_status.passive", "eglink.ru_state.disarmed",
    "eglink.fields_disagree", "eglink.link_status.fault",
}


# Wireshark's expert severities and groups (epan/proto.h PI_*) by the names
# the table of docs/findings.md "How findings read" uses.
SEVERITIES = {0x00200000: "chat", 0x00400000: "note", 0x00600000: "warning",
              0x00800000: "error"}
GROUPS = {0x01000000: "checksum", 0x02000000: "sequence", 0x03000000: "response code",
          0x04000000: "request code", 0x05000000: "undecoded", 0x06000000: "reassemble",
          0x07000000: "malformed", 0x08000000: "debug", 0x09000000: "protocol"}


def _walk(node, found):
    if isinstance(node, list):
        for item in node:
            _walk(item, found)
    elif isinstance(node, dict):
        if "_ws.expert.message" in node:
            names = [k for k in node if k in DISSECTOR_EXPERTS]
            if names:
                found.append((names[0], node["_ws.expert.message"],
                              SEVERITIES[int(node["_ws.expert.severity"])],
                              GROUPS[int(node["_ws.expert.group"])]))
        for value in node.values():
            _walk(value, found)


def _dissector_findings(tshark, capture, **kw):
    out = {}
    for pkt in tshark.json(capture, **kw):
        layers = pkt["_source"]["layers"]
        found = []
        _walk(layers.get("eglink", {}), found)
        if found:
            out[int(layers["frame"]["frame.number"])] = found
    return out


def dissector_experts(tshark, capture, **kw):
    """{frame number: [(expert name, message), ...]} of the dissector's own expert info."""
    return {n: [(e, m) for e, m, _, _ in v]
            for n, v in _dissector_findings(tshark, capture, **kw).items()}


def expert_kinds(tshark, capture, **kw):
    """{expert name: {(severity, group), ...}} of the dissector's own expert info."""
    out = {}
    for found in _dissector_findings(tshark, capture, **kw).values():
        for name, _, severity, group in found:
            out.setdefault(name, set()).add((severity, group))
    return out


def expect_frames(tshark, capture, expected, **kw):
    """Assert the fields of several frames by name: expected is
    {frame number: {field name: value}} (values as tshark.expect() takes them).
    The message lists every frame and field that differs."""
    names = sorted({name for fields in expected.values() for name in fields})
    got = tshark.frames(capture, names, **kw)
    wrong = []
    for frame, fields in sorted(expected.items()):
        if frame not in got:
            wrong.append("  frame %d: not displayed" % frame)
            continue
        wrong += ["  frame %d %s: got %r, want %r" % (frame, name, got[frame].get(name), want)
                  for name, want in fields.items() if not same_value(got[frame].get(name, ""), want)]
    assert not wrong, "fields differ in %s:\n%s" % (Path(capture).name, "\n".join(wrong))
    return got


def messages(tshark, capture, **kw):
    """{frame number: [message, ...]} of the dissector's own expert info."""
    return {n: [m for _, m in v] for n, v in dissector_experts(tshark, capture, **kw).items()}


# --- the C plugin or the Lua EG-Link ------------------------------------------
# tools/test runs the EG-Link tests a second time with the Lua plugins alone
# (VRSHARK_NO_C_PLUGIN=1). Where Wireshark's Lua API allows no other way the
# two differ (docs/eglink.md, "What differs"); these name the difference.

LUA_ONLY = bool(os.environ.get("VRSHARK_NO_C_PLUGIN"))

# The protocol's short name in -z expert and the Expert dialog: a Lua
# protocol's is its name in capitals.
EGLINK_SHORT_NAME = "EGLINK" if LUA_ONLY else "EG-Link"

_LUA_STATS = {}


def eglink_stats(tshark, capture, two_pass=False, prefs=None):
    """The text of the EG-Link statistics tree of a capture: the C plugin's
    -z eglink,stat, or without it the Lua EG-Link's table
    (VRSHARK_EGLINK_STATS=1, printed at the end of the run; tshark -z cannot
    name a Lua statistic). The Lua table has the same rows, order, counts,
    averages, minimums, maximums and percentages, without the Rate and Burst
    columns (lua_stats_text() turns a C table into it)."""
    opts = tshark._opts(prefs=prefs, two_pass=two_pass)
    if not LUA_ONLY:
        return tshark.run(["-q", "-n", "-r", str(capture), "-z", "eglink,stat"] + opts).stdout
    if id(tshark) not in _LUA_STATS:
        t = copy.copy(tshark)
        t.env = dict(tshark.env, VRSHARK_EGLINK_STATS="1")
        t._cache = {}
        _LUA_STATS[id(tshark)] = t
    return _LUA_STATS[id(tshark)].run(["-q", "-n", "-r", str(capture)] + opts).stdout


# Columns of the C table the Lua one has not.
C_ONLY_STATS_COLUMNS = ("Rate (ms)", "Burst Rate", "Burst Start")


def lua_stats_text(c_text):
    """A C plugin's -z eglink,stat text as the Lua EG-Link prints the same
    tree: no Rate (ms), Burst Rate and Burst Start columns, no blank lines,
    the rules as wide as the remaining columns."""
    lines = [line for line in c_text.splitlines() if line.strip()]
    header = next(line for line in lines if line.startswith("Topic / Item"))
    rate, percent, burst = (header.index(t) for t in ("Rate (ms)", "Percent", "Burst Rate"))
    width = rate + burst - percent
    out = []
    for line in lines:
        if set(line) <= set("=-"):
            out.append(line[0] * width)
        else:
            out.append((line[:rate] + line[percent:burst]).rstrip())
    return "\n".join(out) + "\n"
