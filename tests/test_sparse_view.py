"""The sparse view: in an invisible tree (the packet list, -Y, -z taps) the C
front end tells the Lua decoders what is looked at (columns, expert info, the
referenced fields; plugins/vrshark/vrshark-frontends.c lua_view), and the
MC-MB2-PN and EC-Link over Modbus/TCP decoders add only that (lua/mcmb2.lua
sparse(), lua/eclink_modbus.lua sparse_plan()).

What a user sees must not change: every field as a custom column (all
occurrences), Protocol and Info, and the expert statistics are compared with
the full tree (VRSHARK_FULL_TREE=1) on every capture that carries these
frames, ours and the public ones. Probes check what the front end sends and
that the sparse display really serves the frames.
"""
import copy
import os
import subprocess

import pytest

from conftest import CAPTURES, PUBLIC_CAPTURES

needs_c = pytest.mark.skipif(bool(os.environ.get("VRSHARK_NO_C_PLUGIN")), reason="runs without the C plugin")

MCMB2_CAPTURES = sorted(p.name for p in CAPTURES.glob("*.pcap") if "mcmb2" in p.name)
MODBUS_CAPTURES = sorted(p.name for p in CAPTURES.glob("*.pcap") if "modbus" in p.name)
ECLINK_PNIO_CAPTURES = sorted(p.name for p in CAPTURES.glob("*.pcap") if "eclink_pnio" in p.name)
PUBLIC = ["pnio_connect_and_cyclic.pcap", "pnio_connect_many.pcapng"]
# Prefs that make the no-Connect captures decode (layouts from the table).
PREFS = {
    "mcmb2_duplex_noconnect.pcap": {"mcmb2.layouts": "0xC010/0xC011=duplex:8/4"},
    "eclink_pnio_noconnect.pcap": {"mcmb2.layouts": "0xC020/0xC021=eclink:/20"},
    "eclink_modbus_port5020.pcap": {"eclink_modbus.port": "5020"},
    "eclink_modbus_noswap.pcap": {"eclink_modbus.swap": "FALSE"},
    "eclink_modbus_excerpt.pcap": {"eclink_modbus.servers": "192.168.2.41"},
}
# The EC-Link over Modbus/TCP fields the sparse display adds itself (the
# others, and every expert, mean the full tree).
MODBUS_SPARSE = ["eclink_modbus.accepted_in", "eclink_modbus.request_in", "eclink_modbus.time",
                 "eclink_modbus.response_in", "eclink_modbus.pci_age", "eclink_modbus.pco_age",
                 "eclink_modbus.poll_gap_time", "eclink_modbus.poll_gap_from", "eclink_modbus.bu_state_prev",
                 "eclink_modbus.pci_since", "eclink_modbus.pco_since", "eclink_modbus.cmd_from_ru_in",
                 "eclink_modbus.cao_in", "eclink_modbus.cmd_to_ru_in", "eclink_modbus.cai_in",
                 "eclink_modbus.cmd_from_ru_latency", "eclink_modbus.cmd_to_ru_latency"]
# The EC-Link over PROFINET fields the sparse display adds itself (lua/eclink_pnio.lua sparse()).
ECLINK_PNIO_SPARSE = ["eclink_pnio.layout", "eclink_pnio.layout_entry", "eclink_pnio.frame_id", "eclink_pnio.iops",
                      "eclink_pnio.iocs", "eclink_pnio.pci_age", "eclink_pnio.pci_age_ms", "eclink_pnio.pco_age",
                      "eclink_pnio.pco_age_ms"]

# Writes "served FRAME" for every frame the MC-MB2-PN sparse display served,
# and "hook MATCH_STRING" for every frame the front end hands the carrier.
PROBE = r"""
local out = assert(io.open(os.getenv("VRSHARK_PROBE_OUT"), "w"))
local systems = package.loaded["vrshark.pnio_systems"]
for _, name in ipairs({ "duplex", "polled" }) do
    local dec = systems.decoder(name)
    local sparse = dec.sparse
    if sparse and not dec.probed then
        dec.probed = true
        dec.sparse = function(rec, tvb, pinfo, tree, view)
            local ok = sparse(rec, tvb, pinfo, tree, view)
            if ok then out:write("served ", pinfo.number, "\n") out:flush() end
            return ok
        end
    end
end
local carrier = Dissector.get("mcmb2")
local spy = Proto("vrshark_view_probe", "sparse view probe")
-- The carrier registers FrameID 0x8001 when it learns it from the Connect:
-- the spy takes it back after every frame (as a postdissector).
function spy.dissector(tvb, pinfo, tree)
    if pinfo.match_string == nil then
        DissectorTable.get("vrshark.pn.frame_id"):add(0x8001, spy)
        return 0
    end
    out:write("hook ", tostring(pinfo.match_string), "\n") out:flush()
    return carrier:call(tvb, pinfo, tree)
end
register_postdissector(spy)
"""


def _fields(tshark, proto="mcmb2"):
    """The fields (not the experts) of a protocol, from tshark -G fields."""
    out = tshark.run(["-G", "fields"], allow_errors=True).stdout   # lists the field "Lua Error"
    names = []
    for line in out.splitlines():
        cols = line.split("\t")
        if len(cols) > 4 and cols[0] == "F" and cols[4] == proto and cols[3] != "FT_NONE":
            names.append(cols[2])
    assert names, proto
    return sorted(names)


def _columns(names):
    cols = ['"No."', '"%m"', '"Protocol"', '"%p"', '"Info"', '"%i"']
    for n in names:
        cols += ['"%s"' % n, '"%%Cus:%s:0:R"' % n]
    return ",".join(cols)


def _run(tshark, args, full=False, extra_env=None):
    env = dict(tshark.env)
    env.pop("VRSHARK_FULL_TREE", None)
    if full:
        env["VRSHARK_FULL_TREE"] = "1"
    env.update(extra_env or {})
    proc = subprocess.run([tshark.cmd] + args, env=env, capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert "Lua Error" not in proc.stdout + proc.stderr
    return proc.stdout


def _capture(name):
    if name in PUBLIC:
        path = PUBLIC_CAPTURES / name
        if not path.exists():
            pytest.skip("../shared is absent")
        return path
    return CAPTURES / name


def _prefs(name):
    args = []
    for k, v in PREFS.get(name, {}).items():
        args += ["-o", "%s:%s" % (k, v)]
    return args


@pytest.fixture(scope="module")
def mcmb2_inputs(merged_captures):
    """(path, preference args) covering every MC-MB2-PN capture: those that
    need no preference merged into one file (one run a filter covers them;
    tshark's start-up is most of a run's time), then each capture with a
    preference."""
    return [(merged_captures([n for n in MCMB2_CAPTURES if n not in PREFS]).path, [])] \
        + [(CAPTURES / n, _prefs(n)) for n in MCMB2_CAPTURES if n in PREFS]


@pytest.fixture(scope="module")
def merged_eclink(merged_captures):
    """The EC-Link captures of each carrier that need no preference, one
    after the other in one file: one run a filter covers them."""
    return {proto: merged_captures([n for n in names if n not in PREFS]).path
            for proto, names in (("eclink_pnio", ECLINK_PNIO_CAPTURES), ("eclink_modbus", MODBUS_CAPTURES))}


# The EC-Link column comparisons run on the merged file of each carrier and
# on each capture that needs a preference (one run each instead of one a
# capture: tshark's start-up is most of a run's time). name None: the merged
# file.
def _eclink_groups(names):
    return [None] + [n for n in names if n in PREFS]


def _eclink_input(merged_eclink, proto, name):
    """(path, preference args) of a comparison: the merged file of proto, or one capture."""
    if name is None:
        return merged_eclink[proto], []
    return CAPTURES / name, _prefs(name)


def _groups(names):
    """The captures of names as compared: None (those that need no
    preference, one after the other in one file: one run covers them, and
    tshark's start-up is most of a run's time), each capture with a
    preference, and the public ones."""
    return [None] + [n for n in names if n in PREFS or n in PUBLIC]


def _group_input(merged_captures, name, names):
    """(path, preference args, Merged or None) of a comparison: the merged
    file of names (name None), or one capture."""
    if name is None:
        merged = merged_captures([n for n in names if n not in PREFS and n not in PUBLIC])
        return merged.path, [], merged
    return _capture(name), _prefs(name), None


def _same(sparse, full, merged, name):
    """Assert two outputs equal; a difference names the capture (and, in a
    merged file, the frame) it comes from."""
    assert sparse.splitlines() == full.splitlines(), merged.first_difference(sparse, full) if merged else name


@needs_c
@pytest.mark.parametrize("name", _groups(MCMB2_CAPTURES + PUBLIC))
@pytest.mark.parametrize("two_pass", [False, True])
def test_columns_are_those_of_the_full_tree(tshark, merged_captures, name, two_pass):
    """Every MC-MB2-PN field as a column (all occurrences), Protocol and Info:
    the sparse display gives what the full tree gives, frame by frame (every
    capture: _groups)."""
    path, prefs, merged = _group_input(merged_captures, name, MCMB2_CAPTURES)
    args = ["-n", "-r", str(path), "-o", "gui.column.format:" + _columns(_fields(tshark))]
    args += prefs + (["-2"] if two_pass else [])
    sparse = _run(tshark, args)
    _same(sparse, _run(tshark, args, full=True), merged, name)
    # (a base whose layout is not inferred stays PN-RT, with the candidate note)
    if name is None or ("mcmb2" in name and "e010_noconnect" not in name):
        assert "MC-MB2" in sparse


@needs_c
@pytest.mark.parametrize("name", _groups(MCMB2_CAPTURES + PUBLIC))
def test_expert_statistics_are_those_of_the_full_tree(tshark, merged_captures, name):
    path, prefs, _ = _group_input(merged_captures, name, MCMB2_CAPTURES)
    args = ["-n", "-q", "-r", str(path), "-z", "expert"] + prefs
    assert _run(tshark, args) == _run(tshark, args, full=True)


@needs_c
@pytest.mark.parametrize("flt", ["mcmb2.status == 1", "mcmb2.slot.status == 1", "mcmb2.watchdog_age > 0.5",
                                 "mcmb2.status.e010", "mcmb2.iops", "mcmb2.slot.uplink_data[0] == 0"])
def test_filters_select_the_frames_of_the_full_tree(tshark, mcmb2_inputs, flt):
    matched = 0
    for path, prefs in mcmb2_inputs:
        args = ["-n", "-r", str(path), "-Y", flt] + prefs
        sparse = _run(tshark, args)
        assert sparse == _run(tshark, args, full=True), (path.name, flt)
        matched += len(sparse.splitlines())
    assert matched > 0, flt


# Without the C plugin (VRSHARK_NO_C_PLUGIN=1) the carrier makes the view
# itself for MC-MB2-PN (lua/vrshark/frontends.luam lua_view(), from
# TreeItem:referenced()); VRSHARK_FULL_TREE=1 turns it off there too.
LUA_ONLY = {"VRSHARK_NO_C_PLUGIN": "1"}


@pytest.mark.parametrize("name", _groups(MCMB2_CAPTURES + PUBLIC))
@pytest.mark.parametrize("two_pass", [False, True])
def test_lua_only_columns_are_those_of_the_full_tree(tshark, merged_captures, name, two_pass):
    """Lua plugins alone: every MC-MB2-PN field as a column, Protocol and
    Info are those of the full tree, frame by frame (every capture: _groups)."""
    path, prefs, merged = _group_input(merged_captures, name, MCMB2_CAPTURES)
    args = ["-n", "-r", str(path), "-o", "gui.column.format:" + _columns(_fields(tshark))]
    args += prefs + (["-2"] if two_pass else [])
    sparse = _run(tshark, args, extra_env=LUA_ONLY)
    _same(sparse, _run(tshark, args, full=True, extra_env=LUA_ONLY), merged, name)
    if name is None or ("mcmb2" in name and "e010_noconnect" not in name):
        assert "MC-MB2" in sparse


@pytest.mark.parametrize("name", _groups(MCMB2_CAPTURES + PUBLIC))
def test_lua_only_expert_statistics_are_those_of_the_full_tree(tshark, merged_captures, name):
    path, prefs, _ = _group_input(merged_captures, name, MCMB2_CAPTURES)
    args = ["-n", "-q", "-r", str(path), "-z", "expert"] + prefs
    assert _run(tshark, args, extra_env=LUA_ONLY) == _run(tshark, args, full=True, extra_env=LUA_ONLY)


@pytest.mark.parametrize("flt", ["mcmb2.status == 1", "mcmb2.slot.status == 1", "mcmb2.watchdog_age > 0.5",
                                 "mcmb2.status.e010", "mcmb2.iops", "mcmb2.slot.uplink_data[0] == 0",
                                 "mcmb2", "mcmb2.status == 1 && mcmb2"])
def test_lua_only_filters_select_the_frames_of_the_full_tree(tshark, mcmb2_inputs, flt):
    matched = 0
    for path, prefs in mcmb2_inputs:
        args = ["-n", "-r", str(path), "-Y", flt] + prefs
        sparse = _run(tshark, args, extra_env=LUA_ONLY)
        assert sparse == _run(tshark, args, full=True, extra_env=LUA_ONLY), (path.name, flt)
        matched += len(sparse.splitlines())
    assert matched > 0, flt


# Writes "served FRAME" for every frame the MC-MB2-PN sparse display served
# (the first part of PROBE: no front-end tables without the C plugin).
LUA_ONLY_PROBE = PROBE.split("local carrier = ")[0]


@pytest.mark.parametrize("args, served", [
    (["-Y", "mcmb2.status == 1"], True),
    (["-Y", "pn_rt.frame_id == 0x1234"], True),    # nothing of ours referenced: Protocol and Info only
    (["-V"], False),                               # a visible tree
    (["-Y", "mcmb2"], False),                      # the protocol itself
    (["-Y", "mcmb2.status.e010"], False),          # an expert of it
])
def test_lua_only_sparse_display_serves_the_frames(tshark, work_dir, args, served):
    cyclic = tshark.field(DUPLEX, "frame.number", display_filter="mcmb2 && pn_rt")
    assert len(cyclic) > 10
    got = _script_lines(tshark, work_dir, LUA_ONLY_PROBE, DUPLEX, args, extra_env=LUA_ONLY)
    assert [line.split(" ", 1)[1] for line in got] == (cyclic if served else [])
    assert _script_lines(tshark, work_dir, LUA_ONLY_PROBE, DUPLEX, args, full=True, extra_env=LUA_ONLY) == []


def _script_lines(tshark, work_dir, script_text, capture, args, full=False, extra_env=None):
    """Runs tshark with a probe script (-X lua_script); the lines it wrote."""
    script = work_dir / "probe.lua"
    script.write_text(script_text)
    script.chmod(0o644)
    out = work_dir / "probe.txt"
    out.write_text("")
    out.chmod(0o666)
    env = {"VRSHARK_PROBE_OUT": str(out)}
    env.update(extra_env or {})
    _run(tshark, ["-n", "-r", str(capture), "-X", "lua_script:%s" % script] + args, full=full, extra_env=env)
    return out.read_text().splitlines()


def _probe(tshark, work_dir, capture, args, full=False, extra_env=None):
    lines = _script_lines(tshark, work_dir, PROBE, capture, args, full=full, extra_env=extra_env)
    hooks, served = [], []
    for line in lines:
        kind, value = line.split(" ", 1)
        (hooks if kind == "hook" else served).append(value)
    return hooks, served


DUPLEX = CAPTURES / "mcmb2_duplex_connect.pcap"


@needs_c
def test_what_the_front_end_sends(tshark, work_dir):
    """The view strings of FrameID 0x8001 (the duplex uplink) in each way of
    running tshark."""
    def view(args, **kw):
        hooks, _ = _probe(tshark, work_dir, DUPLEX, args, **kw)
        assert hooks, "the probe saw no frame"
        assert len(set(hooks)) == 1, hooks
        return hooks[0]

    assert view(["-V"]) == "frame_id"
    assert view(["-T", "pdml"]) == "frame_id"
    # -T fields prints only what -e names: the tree is visible on 4.0 (not on
    # 4.6), the -e fields unmarked; the front end reads them from the command
    # line (plugins/vrshark/vrshark-output.c), the same view on every version
    assert view(["-T", "fields", "-e", "mcmb2.status"]) == "frame_id.sparse::mcmb2.status"
    assert view(["-Tfields", "-e", "mcmb2.status", "-e", "frame.number"]) == "frame_id.sparse::mcmb2.status"
    assert view(["-nqT", "fields", "-emcmb2.status"]) == "frame_id.sparse::mcmb2.status"
    assert view(["-T", "fields", "-e", "frame.number"]) == "frame_id.quiet"
    assert view(["-T", "fields", "-e", "_ws.col.Info"]) == "frame_id.sparse:c:"
    assert view(["-T", "fields", "-e", "_ws.expert.message"]) == "frame_id.sparse:e:"
    assert view(["-T", "fields", "-e", "mcmb2"]) == "frame_id.sparse::mcmb2"
    assert view(["-T", "fields", "-e", "mcmb2.status"], full=True) == "frame_id"
    assert view(["-Y", "mcmb2.status == 1"]) == "frame_id.sparse:c:mcmb2.status"
    assert view(["-q", "-z", "expert"]) == "frame_id.sparse:e:"
    # (a tap that wants the protocol tree may walk its top level: -z io,phs
    # counts the protocol items; io,stat asks for the tree too. tshark 4.6
    # dissects for io,phs with no protocol faked: everything there)
    assert view(["-q", "-z", "io,phs"]) in ("frame_id.sparse:p:", "frame_id")
    assert view(["-q", "-z", "io,stat,0"]) == "frame_id.sparse:p:"
    assert view(["-Y", "mcmb2.status == 1", "-z", "io,phs"]) in ("frame_id.sparse:cp:mcmb2.status", "frame_id")
    # (tshark -q alone does not dissect at all; a tap that wants no tree
    # does, with nothing looked at)
    assert view(["-q", "-z", "conv,eth"]) == "frame_id.quiet"
    assert view(["-Y", "mcmb2.status == 1"], full=True) == "frame_id"
    both = view(["-Y", "mcmb2.status == 1 || mcmb2.uplink_watchdog > 3"])
    assert both.startswith("frame_id.sparse:c:")
    assert sorted(both.split(":")[2].split(",")) == ["mcmb2.status", "mcmb2.uplink_watchdog"]


@needs_c
def test_the_sparse_display_serves_the_frames(tshark, work_dir):
    cyclic = tshark.field(DUPLEX, "frame.number", display_filter="mcmb2 && pn_rt")
    assert len(cyclic) > 10
    _, served = _probe(tshark, work_dir, DUPLEX, ["-Y", "mcmb2.status == 1"])
    assert served == cyclic
    _, served = _probe(tshark, work_dir, DUPLEX, ["-Y", "mcmb2.status == 1"], full=True)
    assert served == []


@needs_c
@pytest.mark.parametrize("flt", ["mcmb2", "vrshark_io", "mcmb2.status && mcmb2"])
def test_the_full_tree_when_the_protocol_itself_is_asked_for(tshark, work_dir, flt):
    """A filter on the protocol (or on machine data) needs items the sparse
    display does not make: the decoder shows the full tree."""
    _, served = _probe(tshark, work_dir, DUPLEX, ["-Y", flt])
    assert served == []


@needs_c
def test_the_full_tree_when_machine_data_is_described(tshark, work_dir):
    """Machine data adds Info tags and findings of its own: with a description
    for MC-MB2-PN and the columns wanted, the full tree is shown."""
    desc = work_dir / "io"
    desc.mkdir(exist_ok=True)
    desc.chmod(0o755)
    (desc / "m.csv").write_text("area,byte,bit,type,name,label\nmcmb2.up,0,,u8,first_byte,First byte\n")
    (desc / "m.csv").chmod(0o644)
    _, served = _probe(tshark, work_dir, DUPLEX, ["-Y", "mcmb2.status == 1"],
                       extra_env={"VRSHARK_IO_DIR": str(desc)})
    assert served == []


# Writes "only FRAME" for every image the EC-Link decoder shows sparsely.
IMAGE_PROBE = r"""
local out = assert(io.open(os.getenv("VRSHARK_PROBE_OUT"), "w"))
local image = package.loaded["vrshark.eclink_image"]
local dissect = image.dissect
image.dissect = function(tvb, pinfo, tree, opts)
    if opts.only then out:write("only ", pinfo.number, "\n") out:flush() end
    return dissect(tvb, pinfo, tree, opts)
end
"""


def _image_probe(tshark, work_dir, capture, args, full=False):
    """The frames whose EC-Link images were shown sparsely."""
    lines = _script_lines(tshark, work_dir, IMAGE_PROBE, capture, args, full=full)
    return sorted({int(line.split()[1]) for line in lines})


def _same_columns(tshark, path, prefs, extra, proto, two_pass):
    """Every EC-Link image field, extra and (if given) every field of proto as
    columns: the sparse display's output (returned) is the full tree's."""
    names = _fields(tshark, "eclink") + extra + (_fields(tshark, proto) if proto else [])
    args = ["-n", "-r", str(path), "-o", "gui.column.format:" + _columns(sorted(set(names)))]
    args += prefs + (["-2"] if two_pass else [])
    sparse = _run(tshark, args)
    assert sparse.splitlines() == _run(tshark, args, full=True).splitlines()
    return sparse


@needs_c
@pytest.mark.parametrize("name", _eclink_groups(MODBUS_CAPTURES))
@pytest.mark.parametrize("fieldset", ["sparse", "all"])
@pytest.mark.parametrize("two_pass", [False, True])
def test_modbus_columns_are_those_of_the_full_tree(tshark, merged_eclink, name, fieldset, two_pass):
    """The EC-Link image fields and the ADU facts the sparse display adds
    (fieldset "sparse"), or every EC-Link field (most of them mean the full
    tree): the same columns as the full tree, frame by frame (every capture:
    the merged file, and those with a preference)."""
    path, prefs = _eclink_input(merged_eclink, "eclink_modbus", name)
    sparse = _same_columns(tshark, path, prefs, MODBUS_SPARSE, "eclink_modbus" if fieldset == "all" else None,
                           two_pass)
    if two_pass:
        assert "EC-Link" in sparse


# EC-Link's captures by carrier, as compared (_groups).
ECLINK_GROUPS = [(names, n) for names in (MODBUS_CAPTURES, ECLINK_PNIO_CAPTURES) for n in _groups(names)]
ECLINK_GROUP_IDS = ["%s-%s" % ("modbus" if names is MODBUS_CAPTURES else "pnio", n or "merged")
                    for names, n in ECLINK_GROUPS]


@needs_c
@pytest.mark.parametrize("names, name", ECLINK_GROUPS, ids=ECLINK_GROUP_IDS)
def test_ec_link_expert_statistics_are_those_of_the_full_tree(tshark, merged_captures, names, name):
    """EC-Link over Modbus/TCP and over PROFINET: -z expert as with the full
    tree (every capture: _groups)."""
    path, prefs, _ = _group_input(merged_captures, name, names)
    args = ["-n", "-q", "-r", str(path), "-z", "expert"] + prefs
    assert _run(tshark, args) == _run(tshark, args, full=True)


MODBUS_BASIC = CAPTURES / "eclink_modbus_basic.pcap"


@needs_c
def test_the_sparse_display_serves_the_modbus_frames(tshark, work_dir):
    decoded = [int(n) for n in tshark.field(MODBUS_BASIC, "frame.number", display_filter="eclink.image", two_pass=True)]
    assert len(decoded) > 10
    shown = _image_probe(tshark, work_dir, MODBUS_BASIC, ["-2", "-Y", "eclink.bu_state == 0x11"])
    assert shown == decoded
    assert _image_probe(tshark, work_dir, MODBUS_BASIC, ["-2", "-Y", "eclink.bu_state == 0x11"], full=True) == []


@needs_c
@pytest.mark.parametrize("flt", ["eclink_modbus", "eclink_modbus.table", "eclink.relays_open",
                                 "eclink_modbus.bits"])
def test_modbus_full_tree_for_what_the_sparse_display_does_not_add(tshark, work_dir, flt):
    assert _image_probe(tshark, work_dir, MODBUS_BASIC, ["-2", "-Y", flt]) == []


@needs_c
@pytest.mark.parametrize("name", _eclink_groups(ECLINK_PNIO_CAPTURES))
@pytest.mark.parametrize("fieldset", ["sparse", "all"])
@pytest.mark.parametrize("two_pass", [False, True])
def test_eclink_pnio_columns_are_those_of_the_full_tree(tshark, merged_eclink, name, fieldset, two_pass):
    """EC-Link over PROFINET: the image fields and the frame facts the sparse
    display adds (fieldset "sparse"), or every field of both protocols: the
    same columns as the full tree, frame by frame (the merged file, and each
    capture with a preference)."""
    path, prefs = _eclink_input(merged_eclink, "eclink_pnio", name)
    assert "EC-Link" in _same_columns(tshark, path, prefs, ECLINK_PNIO_SPARSE,
                                      "eclink_pnio" if fieldset == "all" else None, two_pass)


ECLINK_PNIO = CAPTURES / "eclink_pnio_connect.pcap"


@needs_c
@pytest.mark.parametrize("flt", ["eclink.bu_state == 0x11", "eclink_pnio.pci_age > 0.5", "eclink.pco > 10",
                                 "eclink_pnio.pco_age_ms > 500", "eclink.cmd_from_ru[0] == 0x41"])
def test_eclink_pnio_filters_select_the_frames_of_the_full_tree(tshark, flt):
    matched = 0
    for name in ECLINK_PNIO_CAPTURES:
        args = ["-n", "-r", str(CAPTURES / name), "-Y", flt] + _prefs(name)
        sparse = _run(tshark, args)
        assert sparse == _run(tshark, args, full=True), (name, flt)
        matched += len(sparse.splitlines())
    assert matched > 0, flt


@needs_c
def test_the_sparse_display_serves_the_eclink_pnio_frames(tshark, work_dir):
    decoded = [int(n) for n in tshark.field(ECLINK_PNIO, "frame.number", display_filter="eclink.image", two_pass=True)]
    assert len(decoded) > 10
    shown = _image_probe(tshark, work_dir, ECLINK_PNIO, ["-2", "-Y", "eclink.bu_state == 0x11"])
    assert shown == decoded
    for flt in ["eclink_pnio", "eclink.relays_open", "eclink_pnio.cmd_from_ru_in"]:
        assert _image_probe(tshark, work_dir, ECLINK_PNIO, ["-2", "-Y", flt]) == [], flt


# -T fields prints only what -e names; on 4.0 its tree is visible, and the
# front end reads the -e fields from tshark's command line
# (plugins/vrshark/vrshark-output.c). Per protocol, the fields its sparse
# display adds itself, and the captures that carry it.
FIELDS_CASES = {
    "mcmb2": (MCMB2_CAPTURES + PUBLIC, lambda tshark: _fields(tshark)),
    "eclink_pnio": (ECLINK_PNIO_CAPTURES, lambda tshark: _fields(tshark, "eclink") + ECLINK_PNIO_SPARSE),
    "eclink_modbus": (MODBUS_CAPTURES, lambda tshark: _fields(tshark, "eclink") + MODBUS_SPARSE),
}
COLUMNS_AND_EXPERTS = ["_ws.col.Protocol", "_ws.col.Info", "_ws.expert.message", "_ws.expert.severity"]


@needs_c
@pytest.mark.parametrize("proto,name", [(p, n) for p, (names, _) in FIELDS_CASES.items()
                                        for n in _groups(names)])
@pytest.mark.parametrize("what", ["fields", "fields+columns+experts", "fields+columns+experts -2"])
def test_fields_output_is_that_of_the_full_tree(tshark, merged_captures, proto, name, what):
    """tshark -T fields with the fields the sparse display adds (and the
    columns and expert messages): every line as with the full tree (every
    capture of the protocol: those that need no preference merged into one
    file, the others one by one)."""
    names = sorted(set(FIELDS_CASES[proto][1](tshark)))
    if "columns" in what:
        names += COLUMNS_AND_EXPERTS
    path, prefs, merged = _group_input(merged_captures, name, FIELDS_CASES[proto][0])
    args = ["-n", "-r", str(path), "-T", "fields", "-E", "header=y", "-e", "frame.number"]
    for n in names:
        args += ["-e", n]
    args += prefs + (["-2"] if what.endswith("-2") else [])
    _same(_run(tshark, args), _run(tshark, args, full=True), merged, name)


@needs_c
def test_fields_output_is_served_sparsely(tshark, work_dir):
    """tshark -T fields -e mcmb2.status: the sparse display serves every
    cyclic frame (on 4.0 too, where the tree is visible); -T pdml does not."""
    cyclic = tshark.field(DUPLEX, "frame.number", display_filter="mcmb2 && pn_rt")
    _, served = _probe(tshark, work_dir, DUPLEX, ["-T", "fields", "-e", "mcmb2.status", "-e", "_ws.col.Info"])
    assert served == cyclic
    _, served = _probe(tshark, work_dir, DUPLEX, ["-T", "pdml"])
    assert served == []


@needs_c
@pytest.mark.parametrize("name", ["mcmb2_duplex_connect.pcap", "eclink_pnio_connect.pcap", "eclink_modbus_basic.pcap"])
def test_protocol_hierarchy_is_that_of_the_full_tree(tshark, name):
    """Protocol Hierarchy (-z io,phs) counts the protocol items at the
    tree's top level: the sparse display adds its protocol's item there."""
    args = ["-n", "-q", "-r", str(CAPTURES / name), "-z", "io,phs"] + _prefs(name)
    sparse = _run(tshark, args)
    assert sparse == _run(tshark, args, full=True)
    # (the protocol under the cyclic frames' or the Modbus/TCP branch)
    carrier, proto = {"mcmb2_duplex_connect.pcap": ("pn_rt", "mcmb2"),
                      "eclink_pnio_connect.pcap": ("pn_rt", "eclink_pnio"),
                      "eclink_modbus_basic.pcap": ("mbtcp", "eclink_modbus")}[name]
    words = [line.split()[0] for line in sparse.splitlines() if line.strip()]
    assert proto in words[words.index(carrier):], sparse


# EC-Link without the C plugin: the PROFINET carrier and eclink_modbus make
# the view themselves from what is referenced, over the fields of two Protos
# (eclink_pnio or eclink_modbus, and eclink: frontends.lua_view()), and the
# sparse display adds the expert info itself (Lua cannot tell whether it is
# looked at).
ECLINK_LUA_CASES = [("eclink_pnio", n) for n in _eclink_groups(ECLINK_PNIO_CAPTURES)] \
    + [("eclink_modbus", n) for n in _eclink_groups(MODBUS_CAPTURES)]


# The fields the sparse display adds itself, per carrier (eclink.lcd, the
# BU display beside a finding, means the full tree).
ECLINK_LUA_SPARSE = {"eclink_pnio": ECLINK_PNIO_SPARSE, "eclink_modbus": MODBUS_SPARSE}


def _eclink_lua_fields(tshark, proto, fieldset):
    if fieldset == "all":
        return sorted(set(_fields(tshark, "eclink") + _fields(tshark, proto)))
    return sorted(set(_fields(tshark, "eclink")) - {"eclink.lcd"}) + ECLINK_LUA_SPARSE[proto]


@pytest.mark.parametrize("proto,name", ECLINK_LUA_CASES)
@pytest.mark.parametrize("fieldset", ["sparse", "all"])
@pytest.mark.parametrize("two_pass", [False, True])
def test_lua_only_eclink_columns_are_those_of_the_full_tree(tshark, merged_eclink, proto, name, fieldset, two_pass):
    """Lua plugins alone: the fields the sparse display adds (fieldset
    "sparse") or every field of eclink and of the carrier's EC-Link protocol
    as columns (all occurrences), Protocol and Info are those of the full
    tree, frame by frame (the merged file, and each capture with a preference)."""
    names = _eclink_lua_fields(tshark, proto, fieldset)
    path, prefs = _eclink_input(merged_eclink, proto, name)
    args = ["-n", "-r", str(path), "-o", "gui.column.format:" + _columns(names)]
    args += prefs + (["-2"] if two_pass else [])
    sparse = _run(tshark, args, extra_env=LUA_ONLY)
    assert sparse.splitlines() == _run(tshark, args, full=True, extra_env=LUA_ONLY).splitlines()
    assert "EC-Link" in sparse


@pytest.mark.parametrize("proto,name", ECLINK_LUA_CASES)
@pytest.mark.parametrize("two_pass", [False, True])
def test_lua_only_eclink_fields_output_is_that_of_the_full_tree(tshark, merged_eclink, proto, name, two_pass):
    """Lua plugins alone, tshark -T fields with every field of eclink and of
    the carrier's EC-Link protocol, the columns and the expert messages:
    every line as with the full tree (the merged file, and each capture with
    a preference)."""
    names = _eclink_lua_fields(tshark, proto, "all") + COLUMNS_AND_EXPERTS
    path, prefs = _eclink_input(merged_eclink, proto, name)
    args = ["-n", "-r", str(path), "-T", "fields", "-E", "header=y", "-e", "frame.number"]
    for n in names:
        args += ["-e", n]
    args += prefs + (["-2"] if two_pass else [])
    sparse = _run(tshark, args, extra_env=LUA_ONLY)
    assert sparse.splitlines() == _run(tshark, args, full=True, extra_env=LUA_ONLY).splitlines()


@pytest.mark.parametrize("names, name", ECLINK_GROUPS, ids=ECLINK_GROUP_IDS)
def test_lua_only_ec_link_expert_statistics_are_those_of_the_full_tree(tshark, merged_captures, names, name):
    """Lua plugins alone: -z expert as with the full tree (the sparse display
    adds every finding, in the full tree's order; every capture: _groups)."""
    path, prefs, _ = _group_input(merged_captures, name, names)
    args = ["-n", "-q", "-r", str(path), "-z", "expert"] + prefs
    assert _run(tshark, args, extra_env=LUA_ONLY) == _run(tshark, args, full=True, extra_env=LUA_ONLY)


FILTER_CHUNKS = 4


def _full_tree_lines(tshark, capture, names, two_pass):
    """{field: the lines `tshark -Y FIELD` prints with the columns No.,
    Protocol, Info and FIELD} on the full tree, for every field of names, from
    one run (-T fields with each field as a custom column, and the field
    itself for its presence; lines as tshark writes them: the number right
    aligned in 5 characters, the columns apart by a space). The run is shared
    by the tests of each chunk."""
    cols = ['"No."', '"%m"', '"Protocol"', '"%p"', '"Info"', '"%i"']
    for i, n in enumerate(names):
        cols += ['"c%d"' % i, '"%%Cus:%s:0:R"' % n]
    args = ["-n", "-r", str(capture), "-o", "gui.column.format:" + ",".join(cols)] + (["-2"] if two_pass else [])
    args += ["-T", "fields", "-E", "occurrence=f", "-e", "frame.number", "-e", "_ws.col.Protocol",
             "-e", "_ws.col.Info"]
    for i, n in enumerate(names):
        args += ["-e", "_ws.col.c%d" % i, "-e", n]
    full = copy.copy(tshark)
    full.env = dict(tshark.env, VRSHARK_FULL_TREE="1", **LUA_ONLY)
    full._cache = {}
    rows = [line.split("\t") for line in full.run(args).stdout.splitlines()]
    return {n: "".join("%5s %s %s %s\n" % (r[0], r[1], r[2], r[3 + 2 * i]) for r in rows if r[4 + 2 * i] != "")
            for i, n in enumerate(names)}


@pytest.mark.parametrize("chunk", range(FILTER_CHUNKS))
@pytest.mark.parametrize("two_pass", [False, True])
@pytest.mark.parametrize("proto", ["eclink_pnio", "eclink_modbus"])
def test_lua_only_eclink_filters_select_the_frames_of_the_full_tree(tshark, merged_eclink, proto, two_pass, chunk):
    """Lua plugins alone: every field of eclink and of the carrier's EC-Link
    protocol, alone as the -Y filter and as a column: the frames and values
    of the full tree (each field alone is a view of its own; the fields in
    FILTER_CHUNKS tests; the full tree's lines from one run)."""
    capture = merged_eclink[proto]
    names = _eclink_lua_fields(tshark, proto, "all")
    want = _full_tree_lines(tshark, capture, names, two_pass)
    matched = {}
    for name in names[chunk::FILTER_CHUNKS]:
        args = ["-n", "-r", str(capture), "-Y", name, "-o", "gui.column.format:" + _columns([name])]
        args += ["-2"] if two_pass else []
        sparse = _run(tshark, args, extra_env=LUA_ONLY)
        assert sparse == want[name], name
        matched[name] = len(sparse.splitlines())
    assert sum(matched.values()) > 0


@pytest.mark.parametrize("capture, args, served", [
    (ECLINK_PNIO, ["-Y", "eclink.bu_state == 0x11"], True),
    (ECLINK_PNIO, ["-2", "-Y", "eclink_pnio.pci_age > 0.5"], True),
    (ECLINK_PNIO, ["-Y", "pn_rt.frame_id == 0x1234"], True),    # nothing of ours referenced
    (ECLINK_PNIO, ["-V"], False),                               # a visible tree
    (ECLINK_PNIO, ["-Y", "eclink_pnio"], False),                # the protocol itself
    (ECLINK_PNIO, ["-Y", "eclink.relays_open"], False),         # an expert
    (ECLINK_PNIO, ["-Y", "eclink.lcd"], False),                 # a field the sparse display does not add
    (MODBUS_BASIC, ["-Y", "eclink.bu_state == 0x11"], True),
    (MODBUS_BASIC, ["-2", "-Y", "eclink_modbus.response_in"], True),
    (MODBUS_BASIC, ["-Y", "modbus.func_code == 99"], True),
    (MODBUS_BASIC, ["-V"], False),
    (MODBUS_BASIC, ["-Y", "eclink_modbus"], False),
    (MODBUS_BASIC, ["-Y", "eclink_modbus.bits"], False),
])
def test_lua_only_sparse_display_serves_the_eclink_frames(tshark, work_dir, capture, args, served):
    """Lua plugins alone: which ways of running show the EC-Link images
    sparsely (every decoded image), and none with VRSHARK_FULL_TREE."""
    decoded = sorted(int(n) for n in tshark.field(capture, "frame.number", display_filter="eclink.image",
                                                  two_pass="-2" in args))
    assert len(decoded) > 10
    lines = _script_lines(tshark, work_dir, IMAGE_PROBE, capture, args, extra_env=LUA_ONLY)
    assert sorted({int(line.split()[1]) for line in lines}) == (decoded if served else [])
    assert _script_lines(tshark, work_dir, IMAGE_PROBE, capture, args, full=True, extra_env=LUA_ONLY) == []


@pytest.mark.parametrize("name, flt, count", [
    ("eclink_modbus_basic.pcap", "eclink && eclink.pci", 10),
    ("eclink_modbus_basic.pcap", "eclink_modbus && eclink && eclink.bu_state == 0x11", 8),
    ("eclink_pnio_connect.pcap", "eclink && eclink.pci", 40),
    ("eclink_pnio_connect.pcap", "eclink_pnio && eclink && eclink.bu_state == 0x11", 38),
])
def test_lua_only_the_eclink_protocol_with_one_of_its_fields(tshark, name, flt, count):
    """Lua plugins alone: the eclink protocol and one of its fields in one
    filter. Wireshark's Lua API answers the same for the protocol asked for
    as for one of its fields asked for, so the sparse display adds the
    eclink protocol item whenever the protocol items may be looked at (as
    the full tree does, under eclink_modbus or eclink_pnio): the frames of
    the full tree, none lost."""
    args = ["-n", "-r", str(CAPTURES / name), "-Y", flt]
    sparse = _run(tshark, args, extra_env=LUA_ONLY)
    assert sparse == _run(tshark, args, full=True, extra_env=LUA_ONLY)
    assert len(sparse.splitlines()) == count
