"""tshark -T fields with the Lua plugins alone (docs/quality.md, "tshark -T
fields without the C plugin").

-T fields prints only the fields -e names. Wireshark 4.0 dissects it on a
visible tree (4.4 and 4.6 on an invisible one, as for -Y), where TreeItem:referenced() says yes to every field; the
Lua decoders read tshark's command line instead (passes.fields_names(), as
the C front end does in vrshark-output.c) and add what the -e values and
the filters name, the columns and the expert info. What tshark prints must
not change: every line is compared with the full tree (VRSHARK_FULL_TREE=1),
in one pass and two. Where the command line cannot tell what is read (a
column, -P, -z, -X, --color, a macro in a filter) the tree is built whole.

Which frames the sparse display serves is seen by a probe that sits where a
user's own Lua plugin sits (the personal plugin folder of the HOME
tools/tshark gives tshark), not by -X lua_script, which builds the tree whole.
"""
import os
import shutil
import subprocess

import pytest

from conftest import CAPTURES
from test_eglink_sparse_view import SOME as EGLINK_SOME, _eglink_fields
from test_sparse_view import (ECLINK_PNIO_CAPTURES, ECLINK_PNIO_SPARSE, MCMB2_CAPTURES, MODBUS_CAPTURES,
                              MODBUS_SPARSE, PUBLIC, _fields, _group_input, _groups, _run)

LUA_ONLY = {"VRSHARK_NO_C_PLUGIN": "1"}
EXPERTS = ["_ws.expert.message", "_ws.expert.severity"]


@pytest.mark.parametrize("words, want", [
    (["tshark", "-r", "x", "-T", "fields", "-e", "eglink.serial"], ["eglink.serial"]),
    (["tshark", "-nTfields", "-eeglink.serial", "-e", "frame.number"], ["eglink.serial", "frame.number"]),
    (["/usr/bin/tshark", "-T", "pdml", "-T", "fields", "-e", "a.b"], ["a.b"]),
    # the filters' name-like words (a value, a word of a string: more to add, never less)
    (["tshark", "-T", "fields", "-e", "a.b", "-Y", "eglink.bu_state == 4 && ip.src==1.2.3.4"],
     ["a.b", "eglink.bu_state", "4", "ip.src", "1.2.3.4"]),
    (["tshark", "-T", "fields", "-2", "-R", "mcmb2.status", "--display-filter", "x.y>1"],
     ["mcmb2.status", "x.y", "1"]),
    (["tshark", "-T", "fields", "--read-filter=eclink.pci"], ["eclink.pci"]),
    (["tshark", "-T", "fields", "-Y", "-e"], ["e"]),                    # "-e" is the filter here
    # the whole tree: another output, not tshark, or something reads what the words do not name
    (["tshark", "-T", "fields", "-T", "pdml", "-e", "a.b"], False),
    (["tshark", "-e", "a.b"], False),
    (["wireshark", "-T", "fields", "-e", "a.b"], False),
    (["tshark", "-T", "fields", "-e", "_ws.col.Info"], False),
    (["tshark", "-T", "fields", "-e", "a.b", "-P"], False),
    (["tshark", "-T", "fields", "-e", "a.b", "--print"], False),
    (["tshark", "-T", "fields", "-e", "a.b", "-z", "expert"], False),
    (["tshark", "-T", "fields", "-e", "a.b", "-X", "lua_script:s.lua"], False),
    (["tshark", "-T", "fields", "-e", "a.b", "--color"], False),
    (["tshark", "-T", "fields", "-e", "a.b", "-Y", "${m}"], False),
    (["tshark", "-T", "fields", "-e", "len(a.b)"], False),
])
def test_fields_args(lua_probe, words, want):
    """passes.fields_args reads the command line as tshark's getopt_long() does."""
    script = """package.path = %(lua)r .. "/?.luam;" .. package.path
local passes = require("vrshark.passes")
local f = io.open(%(out)r, "w")
local names = passes.fields_args({""" + ", ".join('"%s"' % w for w in words) + """})
f:write(names and ("names " .. table.concat(names, " ")) or tostring(names))
f:close()
"""
    got = lua_probe(script)
    assert got == (["false"] if want is False else ["names " + " ".join(want)])


# The probes: "sparse N V" or "full N V" for every frame a decoder served,
# V "visible" or "invisible": the tree tshark dissected it on.
EGLINK_PROBE = r"""
local out = assert(io.open(os.getenv("VRSHARK_PROBE_OUT"), "w"))
local analysis = package.loaded["vrshark.eglink_analysis"]
local dissect = analysis.dissect
analysis.dissect = function(tvb, pinfo, tree, item, info, sparse)
    out:write(sparse and "sparse " or "full ", pinfo.number, tree.visible and " visible" or " invisible", "\n")
    out:flush()
    return dissect(tvb, pinfo, tree, item, info, sparse)
end
"""
MCMB2_PROBE = r"""
local out = assert(io.open(os.getenv("VRSHARK_PROBE_OUT"), "w"))
local systems = package.loaded["vrshark.pnio_systems"]
local dec = systems.decoder("duplex")
local sparse = dec.sparse
dec.sparse = function(rec, tvb, pinfo, tree, view)
    local ok = sparse(rec, tvb, pinfo, tree, view)
    if ok then out:write("sparse ", pinfo.number, tree.visible and " visible" or " invisible", "\n") end
    return ok
end
local spy = Proto("vrshark_tree_probe", "tree probe")
function spy.dissector(_, pinfo, tree)
    out:write("tree ", pinfo.number, tree.visible and " visible" or " invisible", "\n")
    out:flush()
end
register_postdissector(spy)
"""


def _personal_probe(tshark, work_dir, script, capture, args):
    """Runs the Lua-only tshark with `script` in the personal Lua plugin folder
    of the HOME tools/tshark makes under TMPDIR; the probe's lines."""
    tmp = work_dir / "tmp"
    root = os.getuid() == 0
    uid = int(os.environ.get("VRSHARK_RUN_UID", "65534")) if root else os.getuid()
    home = tmp / ("vrshark-home-%d" % uid)
    plugins = home / ".local" / "lib" / "wireshark" / "plugins"
    if tmp.exists():
        shutil.rmtree(tmp)
    plugins.mkdir(parents=True)
    (plugins / "probe.lua").write_text(script)
    for path in [tmp, home, home / ".local", home / ".local" / "lib", plugins.parent, plugins]:
        path.chmod(0o755)
        if root:
            os.chown(path, uid, uid)
    out = work_dir / "probe.txt"
    out.write_text("")
    out.chmod(0o666)
    env = dict(tshark.env, TMPDIR=str(tmp), VRSHARK_PROBE_OUT=str(out), **LUA_ONLY)
    env.pop("VRSHARK_FULL_TREE", None)
    proc = subprocess.run([tshark.cmd, "-n", "-r", str(capture)] + args, env=env, capture_output=True, text=True,
                          timeout=600)
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert "Lua Error" not in proc.stdout + proc.stderr
    return [line.split() for line in out.read_text().splitlines()]


# sparse: True, False, or VISIBLE_ONLY: the whole tree where tshark makes
# the tree visible (Wireshark 4.0), sparse where it does not (4.4 and 4.6:
# the referenced fields decide there, as for -Y).
VISIBLE_ONLY = "visible only"


def _expected(sparse, printed):
    visible = {v for _, _, v in printed}
    assert len(visible) == 1, printed[:5]
    if sparse == VISIBLE_ONLY:
        sparse = visible != {"visible"}
    return {"sparse" if sparse else "full"}


@pytest.mark.parametrize("args, sparse", [
    (["-T", "fields", "-e", "eglink.serial"], True),
    (["-T", "fields", "-e", "frame.number", "-e", "eglink.bu_state", "-e", "_ws.expert.message"], True),
    (["-T", "fields", "-e", "frame.number", "-Y", "eglink.bu_state == 4"], True),
    (["-2", "-T", "fields", "-e", "eglink.serial"], True),
    (["-T", "fields", "-e", "eglink"], False),                    # the protocol itself
    (["-T", "fields", "-e", "eglink.analysis.lost"], False),      # an analysis field: the full tree
    (["-T", "fields", "-e", "eglink.serial", "-Y", "eglink"], VISIBLE_ONLY),   # (an invisible tree: the protocol item is added)
    (["-T", "fields", "-e", "eglink.serial", "-e", "_ws.col.Info"], VISIBLE_ONLY),
    (["-T", "fields", "-e", "eglink.serial", "-P"], VISIBLE_ONLY),
    (["-T", "pdml"], False),
])
def test_which_eglink_runs_are_served_sparsely(tshark, work_dir, args, sparse):
    """Every EG-Link packet is served sparsely with -T fields where the
    command line tells what is read, and none where it cannot."""
    capture = CAPTURES / "eglink_analysis_spec_rules.pcap"
    frames = tshark.field(capture, "frame.number", display_filter="eglink")
    assert len(frames) > 10
    got = _personal_probe(tshark, work_dir, EGLINK_PROBE, capture, args)
    printed = got[-len(frames):]        # (with -2: the second pass, the one printed)
    assert [n for _, n, _ in printed] == frames
    assert {kind for kind, _, _ in printed} == _expected(sparse, printed), printed[:5]


@pytest.mark.parametrize("args, sparse", [
    (["-T", "fields", "-e", "mcmb2.status"], True),
    (["-T", "fields", "-e", "frame.number", "-Y", "mcmb2.status == 1"], True),
    (["-T", "fields", "-e", "mcmb2"], False),
    (["-T", "fields", "-e", "mcmb2.status", "-e", "_ws.col.Info"], VISIBLE_ONLY),
    (["-T", "fields", "-e", "mcmb2.status", "-z", "expert"], VISIBLE_ONLY),
])
def test_which_mcmb2_runs_are_served_sparsely(tshark, work_dir, args, sparse):
    """The same for MC-MB2-PN behind the Lua PROFINET carrier."""
    capture = CAPTURES / "mcmb2_duplex_connect.pcap"
    cyclic = tshark.field(capture, "frame.number", display_filter="mcmb2 && pn_rt")
    assert len(cyclic) > 10
    got = _personal_probe(tshark, work_dir, MCMB2_PROBE, capture, args)
    trees = [line for line in got if line[0] == "tree"]
    assert len(trees) > len(cyclic)
    served = [n for kind, n, _ in got if kind == "sparse"]
    assert served == (cyclic if _expected(sparse, trees) == {"sparse"} else [])


def _lines(tshark, capture, names, extra=(), two_pass=False, prefs=()):
    args = ["-n", "-r", str(capture), "-T", "fields", "-E", "header=y", "-E", "occurrence=a", "-e", "frame.number"]
    for n in names:
        args += ["-e", n]
    args += list(extra) + list(prefs) + (["-2"] if two_pass else [])
    sparse = _run(tshark, args, extra_env=LUA_ONLY)
    assert sparse.splitlines() == _run(tshark, args, full=True, extra_env=LUA_ONLY).splitlines()
    return sparse


# The captures compared: None stands for those that need no preference, one
# after the other in one file (one run covers them: tshark's start-up is most
# of a run's time); the others one by one.
EGLINK_CRC = "eglink_crc_variants.pcap"
EGLINK_MERGED = EGLINK_SOME + ["eglink_analysis_vrpo_incomplete.pcap"]


@pytest.mark.parametrize("name", [None, EGLINK_CRC])
@pytest.mark.parametrize("two_pass", [False, True])
def test_eglink_fields_output_is_that_of_the_full_tree(tshark, merged_captures, name, two_pass):
    """EG-Link: every field the sparse display adds, with the expert
    messages, and with a filter on one of them (the captures of EGLINK_SOME
    and a cut VRPO burst in one file; the CRC variant with its preference)."""
    if name is None:
        capture, prefs = merged_captures(EGLINK_MERGED).path, []
    else:
        capture, prefs = CAPTURES / name, ["-o", "eglink.crc_variant:bzip2"]
    names = _eglink_fields(tshark) + EXPERTS
    out = _lines(tshark, capture, names, two_pass=two_pass, prefs=prefs)
    assert out.count("\n") > 2
    _lines(tshark, capture, ["eglink.serial", "eglink.joystick1"], ["-Y", "eglink.bu_state >= 0x10"],
           two_pass=two_pass, prefs=prefs)


@pytest.mark.parametrize("name", _groups(MCMB2_CAPTURES + PUBLIC))
@pytest.mark.parametrize("two_pass", [False, True])
def test_mcmb2_fields_output_is_that_of_the_full_tree(tshark, merged_captures, name, two_pass):
    """MC-MB2-PN: every field of mcmb2 (those the sparse display adds, and
    the full tree's for the others), with the expert messages (every
    MC-MB2-PN capture)."""
    capture, prefs, _ = _group_input(merged_captures, name, MCMB2_CAPTURES)
    names = sorted(set(_fields(tshark)))
    _lines(tshark, capture, names + EXPERTS, two_pass=two_pass, prefs=prefs)
    _lines(tshark, capture, ["mcmb2.status", "mcmb2.uplink_watchdog"], ["-Y", "mcmb2.status != 0"],
           two_pass=two_pass, prefs=prefs)


@pytest.mark.parametrize("proto, name", [(p, n) for p, names in (("eclink_pnio", ECLINK_PNIO_CAPTURES),
                                                                   ("eclink_modbus", MODBUS_CAPTURES))
                                          for n in _groups(names)])
@pytest.mark.parametrize("two_pass", [False, True])
def test_eclink_fields_output_is_that_of_the_full_tree(tshark, merged_captures, proto, name, two_pass):
    """EC-Link: the fields its sparse display adds (eclink.lcd, the BU
    display beside a finding, means the full tree), with the expert messages
    (every capture of each carrier)."""
    sparse = {"eclink_pnio": ECLINK_PNIO_SPARSE, "eclink_modbus": MODBUS_SPARSE}[proto]
    names = sorted(set(_fields(tshark, "eclink")) - {"eclink.lcd"}) + sparse
    capture, prefs, _ = _group_input(merged_captures, name,
                                     ECLINK_PNIO_CAPTURES if proto == "eclink_pnio" else MODBUS_CAPTURES)
    _lines(tshark, capture, names + EXPERTS, two_pass=two_pass, prefs=prefs)


@pytest.fixture(scope="module")
def realstack_capture():
    """pymodbus BU and PLC on 127.0.0.1, captured (test_eclink_modbus_realstack)."""
    import test_eclink_modbus_realstack as rs
    from test_eclink_modbus_realstack_commands import _plc
    for got in rs.captured("commands", _plc):
        yield got + (rs.PREFS,)


@pytest.mark.parametrize("two_pass", [False, True])
def test_real_stack_fields_output_is_that_of_the_full_tree(tshark, realstack_capture, two_pass):
    """Traffic the project did not make: a pymodbus BU and PLC. -T fields
    with the EC-Link fields its sparse display adds is that of the full tree,
    and carries what the PLC logged it wrote (CAO 5, then its echo 6)."""
    cap, log, prefs = realstack_capture
    args = []
    for k, v in sorted(prefs.items()):
        args += ["-o", "%s:%s" % (k, v)]
    names = ["eclink.image", "eclink.cci", "eclink.cao", "eclink.pco"] + MODBUS_SPARSE + EXPERTS
    out = _lines(tshark, cap, names, two_pass=two_pass, prefs=args)
    header = out.splitlines()[0].split("\t")
    rows = [dict(zip(header, line.split("\t"))) for line in out.splitlines()[1:]]
    written = {int(r["eclink.cao"]) for r in rows if r["eclink.image"] == "output"}
    assert written == {c for _, _, c in log["written"]} == {5, 6}
    assert {int(r["eclink.cci"]) for r in rows if r["eclink.image"] == "input"} >= {6, 7}
