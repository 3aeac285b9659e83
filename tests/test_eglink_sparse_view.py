"""EG-Link in Lua (lua/eglink.lua, the Lua plugins without the C plugin) on
an invisible tree (the packet list, tshark -Y, -z taps): only the referenced
EG-Link fields are added, the analysis adds no items, the columns and the
expert info are as ever (docs/quality.md, "What the decoders add, and when").

What a user sees must not change: every field the sparse display adds as a
custom column (all occurrences), Protocol and Info, display filters, -T
fields, -z expert and -z io,phs are compared with the full tree
(VRSHARK_FULL_TREE=1), in one pass and two.
"""
import subprocess

import pytest

from conftest import CAPTURES
from test_sparse_view import _script_lines

LUA_ONLY = {"VRSHARK_NO_C_PLUGIN": "1"}
EGLINK_CAPTURES = sorted(p.name for p in CAPTURES.glob("*.pcap") if "eglink" in p.name)
# A few captures that carry every packet type, bad CRCs, undefined values,
# cut packets, reassembly and the analysis findings.
SOME = ["eglink_analysis_spec_rules.pcap", "eglink_analysis_vrpo_split.pcap", "eglink_armed.pcap",
        "eglink_bad_crc.pcap", "eglink_commands.pcap", "eglink_range.pcap", "eglink_truncated.pcap",
        "eglink_wrong_size.pcap", "crane_eglink.pcap"]
# Prefs some captures are decoded with elsewhere (a CRC variant, another port).
PREFS = {"eglink_crc_variants.pcap": ["-o", "eglink.crc_variant:bzip2"]}


_FIELDS = []


def _eglink_fields(tshark):
    """The EG-Link fields the sparse display adds itself (not the analysis's,
    not the reassembled periodic data: those mean the full tree)."""
    if _FIELDS:
        return _FIELDS
    env = dict(tshark.env)
    env.update(LUA_ONLY)
    out = subprocess.run([tshark.cmd, "-G", "fields"], env=env, capture_output=True, text=True, timeout=600).stdout
    names = []
    for line in out.splitlines():
        cols = line.split("\t")
        if len(cols) > 4 and cols[0] == "F" and cols[4] == "eglink" and cols[3] != "FT_NONE":
            if not cols[2].startswith("eglink.analysis") and cols[2] != "eglink.periodic_data":
                names.append(cols[2])
    assert "eglink.bu_state" in names and "eglink.crc.status" in names
    _FIELDS.extend(sorted(names))
    return _FIELDS


def _columns(names):
    cols = ['"No."', '"%m"', '"Protocol"', '"%p"', '"Info"', '"%i"']
    for n in names:
        cols += ['"%s"' % n, '"%%Cus:%s:0:R"' % n]
    return ",".join(cols)


def _run(tshark, args, full=False):
    env = dict(tshark.env)
    env.pop("VRSHARK_FULL_TREE", None)
    env.update(LUA_ONLY)
    if full:
        env["VRSHARK_FULL_TREE"] = "1"
    proc = subprocess.run([tshark.cmd] + args, env=env, capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert "Lua Error" not in proc.stdout + proc.stderr
    return proc.stdout


@pytest.mark.parametrize("name", [None, "eglink_crc_variants.pcap"])
@pytest.mark.parametrize("two_pass", [False, True])
def test_columns_are_those_of_the_full_tree(tshark, merged_captures, name, two_pass):
    """Every field the sparse display adds, as a column, with Protocol and
    Info: those of the full tree, frame by frame (name None: the captures of
    SOME and a cut VRPO burst, one after the other in one file)."""
    merged = merged_captures(SOME + ["eglink_analysis_vrpo_incomplete.pcap"]) if name is None else None
    path = merged.path if merged else CAPTURES / name
    args = ["-n", "-r", str(path), "-o", "gui.column.format:" + _columns(_eglink_fields(tshark))]
    args += PREFS.get(name, []) + (["-2"] if two_pass else [])
    sparse = _run(tshark, args)
    full = _run(tshark, args, full=True)
    assert sparse.splitlines() == full.splitlines(), merged.first_difference(sparse, full) if merged else name
    assert "EG-Link" in sparse


@pytest.mark.parametrize("name", [None] + sorted(PREFS))
@pytest.mark.parametrize("two_pass", [False, True])
def test_expert_statistics_are_those_of_the_full_tree(tshark, merged_captures, name, two_pass):
    """-z expert of every EG-Link capture (name None: those decoded without a
    preference, one after the other in one file) as with the full tree."""
    path = merged_captures([n for n in EGLINK_CAPTURES if n not in PREFS]).path if name is None \
        else CAPTURES / name
    args = ["-n", "-q", "-r", str(path), "-z", "expert"] + PREFS.get(name, [])
    args += ["-2"] if two_pass else []
    assert _run(tshark, args) == _run(tshark, args, full=True)


FILTERS = ["eglink.bu_state == 4", "udp.length == 1", "eglink.crc.status == 0 || eglink.joystick1 < 0",
           "eglink.relays_open", "eglink.type == \"VRPO\" && eglink.serial > 2 || eglink.packet_number == 1",
           "eglink.command_id || eglink.payload_spare", "eglink.ru_state == 4 || eglink.switch3 != 0",
           "eglink.analysis.lost || eglink.periodic_data", "eglink", "eglink.bu_state && eglink"]


@pytest.mark.parametrize("flt, two_pass", [(f, False) for f in FILTERS] + [(f, True) for f in FILTERS[:3]])
def test_filters_select_the_frames_of_the_full_tree(tshark, merged_captures, flt, two_pass):
    """-Y selects the same frames, with the same Info, and the same expert
    statistics, as with the full tree (the captures of SOME one after the
    other in one file)."""
    merged = merged_captures(SOME)
    args = ["-n", "-r", str(merged.path), "-Y", flt, "-z", "expert"] + (["-2"] if two_pass else [])
    sparse = _run(tshark, args)
    full = _run(tshark, args, full=True)
    assert sparse == full, (flt, merged.first_difference(sparse, full))
    if flt != "udp.length == 1":
        assert sparse.count("EG-Link") > 0, flt


def test_fields_output_and_protocol_hierarchy_are_those_of_the_full_tree(tshark):
    """-T fields (the bench's fields) and -z io,phs with a filter on EG-Link fields."""
    for name in SOME:
        args = ["-n", "-r", str(CAPTURES / name), "-T", "fields", "-e", "frame.number", "-e", "eglink.type",
                "-e", "eglink.serial", "-e", "eglink.bu_state", "-e", "eglink.joystick1", "-e", "_ws.col.Info"]
        assert _run(tshark, args) == _run(tshark, args, full=True), name
        args = ["-n", "-q", "-r", str(CAPTURES / name), "-Y", "eglink.serial >= 0", "-z", "io,phs"]
        assert _run(tshark, args) == _run(tshark, args, full=True), name


# Writes "sparse FRAME" or "full FRAME" for every EG-Link packet the
# analysis sees: what the decoder hands it (`want ~= nil`, lua/eglink.lua),
# so which packets the sparse display served.
PROBE = r"""
local out = assert(io.open(os.getenv("VRSHARK_PROBE_OUT"), "w"))
local analysis = package.loaded["vrshark.eglink_analysis"]
local dissect = analysis.dissect
analysis.dissect = function(tvb, pinfo, tree, item, info, sparse)
    out:write(sparse and "sparse " or "full ", pinfo.number, "\n") out:flush()
    return dissect(tvb, pinfo, tree, item, info, sparse)
end
"""


def _served(tshark, work_dir, capture, args, full=False):
    lines = _script_lines(tshark, work_dir, PROBE, capture, args, full=full, extra_env=LUA_ONLY)
    return [line.split() for line in lines]


@pytest.mark.parametrize("args, sparse", [
    (["-Y", "eglink.bu_state == 4"], True),
    # every field the sparse display adds, the first and the last of them
    (["-Y", "eglink.type == \"VRPO\" || eglink.command_data || eglink.switch8 > 0 || eglink.crc.status == 0"], True),
    (["-Y", "udp.length == 1"], True),                    # nothing of EG-Link referenced
    (["-V"], False),                                      # a visible tree
    (["-Y", "eglink"], False),                            # the protocol itself
    (["-Y", "eglink.crc.bad"], False),                    # an expert of it
    (["-Y", "eglink.periodic_data"], False),              # the reassembled periodic data
    (["-Y", "eglink.analysis.bu_origin"], False),         # an analysis field
    # an analysis field past the first 48 fields of eglink (frontends.lua_view()'s key groups)
    (["-Y", "eglink.bu_state == 4 || eglink.reassembled_in"], False),
])
def test_which_ways_of_running_serve_the_sparse_display(tshark, work_dir, args, sparse):
    """Lua plugins alone: every EG-Link packet is served sparsely where it
    should be, none where a field the sparse display cannot add (or the
    protocol itself) is referenced, and none with VRSHARK_FULL_TREE."""
    capture = CAPTURES / "eglink_analysis_spec_rules.pcap"
    frames = tshark.field(capture, "frame.number", display_filter="eglink")
    assert len(frames) > 10
    got = _served(tshark, work_dir, capture, args)
    assert [n for _, n in got] == frames
    assert {kind for kind, _ in got} == {"sparse" if sparse else "full"}
    assert {kind for kind, _ in _served(tshark, work_dir, capture, args, full=True)} == {"full"}
