"""Every protocol decoded after each documented install (installed_testlib):
the personal install, the system install and the Lua plugins alone, run by
the system tshark as a user, with no WIRESHARK_PLUGIN_DIR. Each decodes one
capture of every protocol and transport exactly as tools/tshark does (the
whole -V text, two passes, and the packet list in one pass), and the
protocol really is there (a layout that decodes nothing fails, even if the
harness decoded nothing too).

The front ends own their table entries whatever order plugins are handed
off in: a plugin that puts PN-RT or Modbus/TCP back on EtherType 0x8892 or
the Modbus port changes nothing; one that puts its own dissector there is
named once on stderr and on the Connect whose cyclic frames it costs."""
import shutil
import subprocess

import pytest

from conftest import CAPTURES, ROOT, Tshark, _world_dir
from installed_testlib import IS_ROOT, Installed

CRANE_CSV = ROOT / "examples" / "crane" / "crane.csv"

# capture -> a display filter that matches its frames of that protocol:
# every protocol and transport, and machine data from an IO list.
CASES = {
    "eglink_analysis_session.pcap": "eglink",
    "eclink_modbus_basic.pcap": "eclink_modbus",
    "eclink_pnio_connect.pcap": "eclink_pnio",
    "mcmb2_duplex_connect.pcap": "mcmb2.system == \"duplex\"",
    "mcmb2_polled_connect.pcap": "mcmb2.system == \"polled\"",
    # PROFINET without the Connect: slot order, PC WORX, IOCS first / data
    # first, and a base whose layout is not inferred (the candidate note)
    "mcmb2_duplex_noconnect.pcap": "mcmb2.layout_entry",
    "mcmb2_duplex_pcworx.pcap": "mcmb2.layout_entry",
    "eclink_pnio_noconnect.pcap": "eclink_pnio.layout_entry",
    "eclink_pnio_data_first.pcap": "eclink_pnio.layout_entry",
    "mcmb2_duplex_e010_noconnect.pcap": "mcmb2.candidate",
    # a BU on a port no setting names: the note on its image requests
    # (a TCP heuristic: asked before Wireshark's own in every layout)
    "eclink_modbus_port5020.pcap": "eclink_modbus.candidate_setting == \"eclink_modbus.port:502,5020\"",
    "crane_eglink.pcap": "vrshark_io",
    "crane_mcmb2.pcap": "vrshark_io",
    "crane_eclink_modbus.pcap": "vrshark_io",
}


@pytest.fixture(scope="module", params=["personal", "system", "lua-only"])
def installed(request):
    if request.param == "system" and not IS_ROOT:
        pytest.skip("the system install is tried as root (unshare -m, mount --bind)")
    inst = Installed(request.param)
    inst.add_io_list(CRANE_CSV)
    yield inst
    inst.remove()


@pytest.fixture(scope="module")
def harness():
    """tools/tshark with the crane's IO list, and the same without the C plugin."""
    conf = _world_dir("vrshark-conf-")
    io = _world_dir("vrshark-io-")
    shutil.copy(CRANE_CSV, io / "crane.csv")
    (io / "crane.csv").chmod(0o644)
    full, lua_only = Tshark(conf), Tshark(conf)
    for t in (full, lua_only):
        t.env["VRSHARK_IO_DIR"] = str(io)
    lua_only.env["VRSHARK_NO_C_PLUGIN"] = "1"
    yield {"full": full, "lua-only": lua_only}
    shutil.rmtree(conf, ignore_errors=True)
    shutil.rmtree(io, ignore_errors=True)


def run_installed(inst, args):
    proc = inst.tshark(args)
    assert proc.returncode == 0, proc.stderr
    for bad in ("Lua Error", "Dissector bug", "dissector bug", "Lua: Error"):
        assert bad not in proc.stdout + proc.stderr, "%s in the %s install" % (bad, inst.kind)
    return proc


@pytest.mark.parametrize("capture", sorted(CASES))
def test_decodes_as_the_harness(installed, harness, capture):
    _as_the_harness(installed, harness, capture, CASES[capture], whole=False)


def test_every_capture_reads_as_the_harness(installed, harness, merged_captures):
    """The captures of CASES one after the other in one file (one run covers
    them): the packet list of one pass and the whole tree of two, as through
    tools/tshark."""
    _reads_as_the_harness(installed, harness, merged_captures(sorted(CASES)))


# The short Modbus/TCP excerpt: unpinned, the note on the BU's frames;
# pinned (eclink_modbus.servers, with -o), the BU decoded from its first frame.
MODBUS_EXCERPT = {"unpinned": ([], "eclink_modbus.candidate"),
                  "pinned": (["-o", "eclink_modbus.servers:192.168.2.41"], "eclink_modbus")}


@pytest.mark.parametrize("how", sorted(MODBUS_EXCERPT))
def test_modbus_excerpt_as_the_harness(installed, harness, how):
    prefs, filt = MODBUS_EXCERPT[how]
    _as_the_harness(installed, harness, "eclink_modbus_excerpt.pcap", filt, prefs)


def _as_the_harness(installed, harness, capture, filt, prefs=(), whole=True):
    """The protocol is there (filt) on the frames where the harness has it;
    whole: and the capture reads as through tools/tshark (_reads_as_the_harness)."""
    ref = harness["lua-only" if installed.kind == "lua-only" else "full"]
    path = str(CAPTURES / capture)
    prefs = list(prefs)
    # the protocol is there at all, on the frames where the harness has it
    for two_pass in ([], ["-2"]):
        args = ["-n", "-r", path, "-Y", filt] + prefs + two_pass
        listed = run_installed(installed, args).stdout
        assert listed, "%s: nothing matches %r in the %s install" % (
            capture, filt, installed.kind)
        assert listed == ref.run(args).stdout, "%s: other frames match %r in the %s install" % (
            capture, filt, installed.kind)
    if whole:
        _reads_as_the_harness(installed, harness, None, capture, prefs)


def _reads_as_the_harness(installed, harness, merged, capture=None, prefs=()):
    """Everything reads as through tools/tshark: the packet list of one pass,
    and the whole tree of two (of a capture, or of a Merged file)."""
    ref = harness["lua-only" if installed.kind == "lua-only" else "full"]
    path = str(merged.path if merged else CAPTURES / capture)
    prefs = list(prefs)
    for args in (["-n", "-r", path, "-T", "fields", "-e", "frame.number", "-e", "frame.protocols",
                  "-e", "_ws.col.Protocol", "-e", "_ws.col.Info"] + prefs,
                 ["-n", "-2", "-r", path, "-V"] + prefs):
        got = run_installed(installed, args).stdout
        want = ref.run(args).stdout
        assert got == want, "%s differs in the %s install from tools/tshark (%s): %s" % (
            capture or "a merged capture", installed.kind, " ".join(args[3:]),
            merged.first_difference(got, want) if merged else "")


# capture -> (the failed commands' expert fields, the frames that carry them
# in one pass (first frame past the deadline), with -2 (the commands)).
FAILED_COMMANDS = {
    "eglink_analysis_vrco_unacked.pcap": ("eglink.analysis.vrci_unacked || eglink.analysis.vrco_unacked",
                                          [61, 123], [5, 67]),
    "eclink_modbus_faults.pcap": ("eclink_modbus.cmd_from_ru.late || eclink_modbus.cmd_to_ru.late", [28], [17, 18]),
    "eclink_pnio_connect.pcap": ("eclink_pnio.cmd_from_ru.late || eclink_pnio.cmd_to_ru.late", [76], [43]),
}


@pytest.mark.parametrize("capture", sorted(FAILED_COMMANDS))
def test_failed_commands_are_warnings_in_one_pass(installed, capture):
    """As CI runs the system tshark on an installed vrshark (issue 27): a
    severity filter finds every failed command in one pass, on the first
    frame past its deadline with [unacked], and with -2 on the command."""
    fields, one_pass, two_pass = FAILED_COMMANDS[capture]
    for extra, frames in (([], one_pass), (["-2"], two_pass)):
        out = run_installed(installed, ["-n", "-r", str(CAPTURES / capture), "-Y",
                                        "_ws.expert.severity >= warning && (%s)" % fields, "-T", "fields",
                                        "-e", "frame.number", "-e", "_ws.col.Info"] + extra).stdout
        rows = [line.split("\t") for line in out.splitlines()]
        assert [int(n) for n, _ in rows] == frames, (installed.kind, extra, out)
        assert all("[unacked]" in i for _, i in rows), (installed.kind, extra, out)


def test_installed_files(installed):
    """What each install put where Wireshark looks, and that Wireshark lists it."""
    plugins = installed.tshark(["-G", "plugins"]).stdout
    for name in ("eclink_modbus.lua", "eclink_pnio.lua", "mcmb2.lua", "vrshark_pnio.lua", "vrshark_io.lua"):
        assert name in plugins, "%s not loaded in the %s install" % (name, installed.kind)
    assert ("vrshark.so" in plugins) == (installed.kind != "lua-only")
    # Lua modules (.luam) are not run as plugins
    assert ".luam" not in plugins


PN_RT_BACK = """-- a plugin handed off after vrshark that puts PN-RT back
DissectorTable.get("ethertype"):add(0x8892, Dissector.get("pn_rt"))
DissectorTable.get("tcp.port"):add(502, Dissector.get("mbtcp"))
"""

OWN_WRAPPER = """-- somebody's own PN-RT wrapper on EtherType 0x8892
local p = Proto("otherpn", "Another PROFINET wrapper")
local pn_rt = Dissector.get("pn_rt")
function p.dissector(tvb, pinfo, tree) return pn_rt:call(tvb, pinfo, tree) end
DissectorTable.get("ethertype"):add(0x8892, p)
"""


@pytest.fixture
def personal_pair():
    """A personal install and a Lua-only one, each used by one test."""
    made = []

    def make(kind):
        inst = Installed(kind)
        made.append(inst)
        return inst
    yield make
    for inst in made:
        inst.remove()


@pytest.mark.parametrize("kind", ["personal", "lua-only"])
def test_entries_taken_back_from_a_later_plugin(personal_pair, harness, kind):
    inst = personal_pair(kind)
    inst.add_io_list(CRANE_CSV)     # as the harness has it
    # (Lua plugins run in folder-listing order: one beside vrshark/, one in a
    # folder of its own)
    inst.add_lua_plugin("zz_pn_rt_back.lua", PN_RT_BACK)
    inst.add_lua_plugin("zz-later/pn_rt_back.lua", PN_RT_BACK)
    ref = harness["lua-only" if kind == "lua-only" else "full"]
    for capture, filt in (("mcmb2_duplex_connect.pcap", "pn_rt && mcmb2"),
                          ("eclink_modbus_basic.pcap", "eclink_modbus")):
        args = ["-n", "-2", "-r", str(CAPTURES / capture), "-Y", filt]
        proc = run_installed(inst, args)
        assert proc.stdout and proc.stdout == ref.run(args).stdout, (kind, capture, proc.stderr)
        assert "taken by" not in proc.stderr


@pytest.mark.parametrize("kind", ["personal", "lua-only"])
def test_a_foreign_wrapper_is_named(personal_pair, kind):
    inst = personal_pair(kind)
    inst.add_lua_plugin("zz_other_wrapper.lua", OWN_WRAPPER)
    path = str(CAPTURES / "mcmb2_duplex_connect.pcap")
    proc = run_installed(inst, ["-n", "-r", path, "-2", "-T", "fields", "-e", "frame.number",
                                "-e", "_ws.expert.message", "-E", "aggregator=|",
                                "-Y", "_ws.expert.severity == error"])
    lines = [line.split("\t") for line in proc.stdout.splitlines()]
    message = ('Cyclic frames of this Connect are not decoded: EtherType 0x8892 is taken by "OTHERPN", '
               'not by vrshark_pnio')
    on_connect = [int(n) for n, m in lines if message in m.split("|")]
    assert on_connect == [1, 2], proc.stdout   # the Connect request and its response
    # said once on stderr, whatever the number of passes and files
    assert proc.stderr.count('EtherType 0x8892 (PROFINET RT) is taken by "OTHERPN"') == 1, proc.stderr
    # the wrapper decodes PN-RT as before; nothing of ours
    assert run_installed(inst, ["-n", "-r", path, "-Y", "pn_rt && mcmb2"]).stdout == ""


CM_PORT_TAKEN = """-- somebody's own dissector on the PNIO-CM port
local p = Proto("othercm", "Another PNIO-CM reader")
function p.dissector(tvb) return tvb:len() end
DissectorTable.get("udp.port"):add(34964, p)
"""


def test_a_foreign_connect_port_is_named(personal_pair):
    inst = personal_pair("personal")
    inst.add_lua_plugin("zz_other_cm.lua", CM_PORT_TAKEN)
    proc = run_installed(inst, ["-n", "-2", "-r", str(CAPTURES / "mcmb2_duplex_connect.pcap")])
    assert proc.stderr.count('UDP port 34964 (PNIO-CM) is taken by "OTHERCM"') == 1, proc.stderr


# Writes "sparse" or "full" for every EG-Link packet the Lua analysis sees
# (only when VRSHARK_PROBE_OUT is set: the plugin stays for the module's
# other tests).
EGLINK_VIEW_PROBE = r"""
local path = os.getenv("VRSHARK_PROBE_OUT")
local analysis = package.loaded["vrshark.eglink_analysis"]
if path and analysis then
    local out = assert(io.open(path, "w"))
    local dissect = analysis.dissect
    analysis.dissect = function(tvb, pinfo, tree, item, info, sparse)
        out:write(sparse and "sparse\n" or "full\n")
        out:flush()
        return dissect(tvb, pinfo, tree, item, info, sparse)
    end
end
"""


def test_fields_output_of_the_lua_only_install(installed):
    """The Lua plugins alone as the README installs them, tshark -T fields
    with fields of every protocol (docs/quality.md, "tshark -T fields
    without the C plugin"): every line as with the whole tree
    (VRSHARK_FULL_TREE=1), and on Wireshark 4.0, where tshark makes the tree
    visible, every EG-Link packet served by the sparse display all the same
    (the command line read by the installed plugins; 4.4 and 4.6 make the
    tree invisible)."""
    if installed.kind != "lua-only":
        pytest.skip("the C plugin's front ends read the command line themselves (test_sparse_view.py)")
    probe = installed.add_lua_plugin("zz_view_probe.lua", EGLINK_VIEW_PROBE)
    out = installed.home / "probe.txt"
    try:
        names = ["frame.number", "eglink.serial", "eglink.bu_state", "eclink.pci", "eclink.bu_state",
                 "mcmb2.status", "_ws.expert.message"]
        for capture in ["eglink_analysis_session.pcap", "eclink_pnio_connect.pcap", "eclink_modbus_basic.pcap",
                        "mcmb2_duplex_connect.pcap"]:
            args = ["-n", "-r", str(CAPTURES / capture), "-T", "fields"]
            for n in names:
                args += ["-e", n]
            out.write_text("")
            out.chmod(0o666)
            sparse = subprocess.run(installed.command("tshark", args), env=installed.env(VRSHARK_PROBE_OUT=str(out)),
                                    capture_output=True, text=True, cwd=str(installed.home))
            assert sparse.returncode == 0 and "Lua Error" not in sparse.stderr, sparse.stderr
            served = out.read_text().split()
            full = subprocess.run(installed.command("tshark", args), env=installed.env(VRSHARK_FULL_TREE="1"),
                                  capture_output=True, text=True, cwd=str(installed.home))
            assert sparse.stdout == full.stdout, capture
            # (the protocol's own fields are there: not an empty decode on both sides)
            assert any(set(line.split("\t")[1:6]) != {""} for line in sparse.stdout.splitlines()), capture
            if capture.startswith("eglink"):
                frames = run_installed(installed, ["-n", "-r", str(CAPTURES / capture), "-Y", "eglink", "-T",
                                                   "fields", "-e", "frame.number"]).stdout.split()
                assert len(served) == len(frames) > 10
                # (4.4 and 4.6 dissect -T fields on an invisible tree: sparse there too)
                assert set(served) == {"sparse"}, served[:5]
    finally:
        probe.unlink()
