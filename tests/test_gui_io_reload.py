"""The IO list picked up by Wireshark's GUI on View > Reload (Ctrl+R),
without a Lua reload or a restart (docs/io.md, "When a list changes"), as a
user has it after the README's personal install (the demo crane's EG-Link
capture) and the Lua-only copy (its MC-MB2-PN capture): Wireshark opens
the capture with no IO list; the demo list is copied into
~/.config/wireshark/vrshark-io/; Ctrl+R (xdotool) reloads the capture.

The oracle is a Lua postdissector of the user's (a third party's plugin)
that writes, per frame and per start of dissection, the machine data the
tree holds: the names and values of the generic fields. What they must be
comes from tshark started with the list in place (the typed fields
vrshark.io.<name>), as the same user."""
import shutil
import subprocess
import time

import pytest

from conftest import BUILD, CAPTURES, ROOT
from gui_testlib import Gui, have_gui
from installed_testlib import Installed
from io_testlib import ASCII, NAMES, same

pytestmark = pytest.mark.skipif(not (have_gui() and shutil.which("xdotool")),
                                reason="wireshark, Xvfb, imagemagick or xdotool missing (tools/setup)")

ARTEFACTS = BUILD / "gui-artefacts"

# Each start of dissection (Proto.init) begins a generation "init N"; each
# frame's first dissection in it writes "N<TAB>frame<TAB>name=value ...".
PROBE = r"""
local f_name, f_value, f_text = Field.new("vrshark_io.name"), Field.new("vrshark_io.value"),
    Field.new("vrshark_io.text")
local probe = Proto("vrshark_io_probe", "IO list probe (test)")
local out = os.getenv("HOME") .. "/io-probe.txt"
local generation, seen = 0, {}

local function write(line)
    local f = assert(io.open(out, "a"))
    f:write(line, "\n")
    f:close()
end

function probe.init()
    generation = generation + 1
    seen = {}
    write("init " .. generation)
end

function probe.dissector(_, pinfo)
    if seen[pinfo.number] then return end
    seen[pinfo.number] = true
    local names, values, texts = { f_name() }, { f_value() }, { f_text() }
    local parts = {}
    for _, fi in ipairs(names) do parts[#parts + 1] = tostring(fi.value) end
    local vs, ts = {}, {}
    for _, fi in ipairs(values) do vs[#vs + 1] = string.format("%.12g", fi.value) end
    for _, fi in ipairs(texts) do ts[#ts + 1] = tostring(fi.value) end
    write(string.format("%d\t%d\t%s\t%s\t%s", generation, pinfo.number, table.concat(parts, "\31"),
        table.concat(vs, "\31"), table.concat(ts, "\31")))
end

register_postdissector(probe)
"""


def generations(path):
    """{generation: {frame: {name: value text}}} of the probe's file."""
    gens = {}
    if not path.exists():
        return gens
    for line in path.read_text(errors="replace").splitlines():
        if line.startswith("init "):
            gens.setdefault(int(line[5:]), {})
            continue
        gen, number, names, values, texts = (line.split("\t") + ["", "", ""])[:5]
        values = [v for v in values.split("\x1f") if v]
        texts = [t for t in texts.split("\x1f") if t]
        got = {}
        for name in [n for n in names.split("\x1f") if n]:
            got[name] = texts.pop(0) if name in ASCII else values.pop(0)
        gens.setdefault(int(gen), {})[int(number)] = got
    return gens


def wait_for(what, timeout=120):
    deadline = time.time() + timeout
    while time.time() < deadline:
        got = what()
        if got:
            return got
        time.sleep(1)
    return what()


def complete(path, count, after=0):
    """The last generation after `after` in which all count frames were dissected, or None."""
    gens = generations(path)
    done = [g for g, frames in gens.items() if g > after and len(frames) == count]
    return (max(done), gens[max(done)]) if done else None


# install -> (capture, frames in it, frames the demo list names in one pass)
CASES = {"personal": ("crane_eglink.pcap", 17, 10), "lua-only": ("crane_mcmb2.pcap", 10, 8)}


@pytest.fixture(params=sorted(CASES))
def user(request):
    inst = Installed(request.param)
    inst.add_lua_plugin("zz-io-probe/io_probe.lua", PROBE)
    yield inst
    inst.remove()


def test_io_list_picked_up_on_reload(user):
    name, count, named = CASES[user.kind]
    title = name.replace(".pcap", "")
    cap = CAPTURES / name
    probe = user.home / "io-probe.txt"
    gui = Gui(user, ARTEFACTS)
    env = user.env(DISPLAY=gui.display, XDG_RUNTIME_DIR=str(gui.run_dir))
    ws = subprocess.Popen(user.command("wireshark", ["-r", str(cap)]), env=env, stdout=subprocess.PIPE,
                          stderr=subprocess.STDOUT, cwd=str(user.home))
    try:
        first = wait_for(lambda: complete(probe, count))
        assert first, "the probe saw no complete dissection: %s" % (probe.read_text() if probe.exists() else "")
        gen, frames = first
        assert not any(frames.values()), "machine data named before any IO list: %s" % frames
        user.add_io_list(ROOT / "examples" / "crane" / "crane.csv")
        window = subprocess.run(["xdotool", "search", "--sync", "--onlyvisible", "--name", title],
                                env=env, capture_output=True, text=True, timeout=60).stdout.split()
        assert window, "no Wireshark window"
        subprocess.run(["xdotool", "windowfocus", "--sync", window[0]], env=env, check=True, timeout=30)
        subprocess.run(["xdotool", "key", "--clearmodifiers", "ctrl+r"], env=env, check=True, timeout=30)
        reloaded = wait_for(lambda: complete(probe, count, gen))
        assert reloaded, "no complete dissection after Ctrl+R: %s" % probe.read_text()[-3000:]
        picture = gui.screenshot()
        png = gui.artefacts / ("io_reload_%s.png" % user.kind)
        subprocess.run(["convert", "ppm:-", str(png)], input=picture, check=True)
    finally:
        ws.kill()
        output = ws.communicate()[0].decode(errors="replace")
        gui.close()
    for bad in ("Lua Error", "Dissector bug", "dissector bug"):
        assert bad not in output, output
    # What tshark, started with the list in place, names in each frame in
    # one pass, as the GUI's first pass that the probe saw (on EG-Link,
    # frame 1, the controller's before any packet of the BU, gets its names
    # in a later dissection, once the BU is known).
    fields = ["frame.number"] + ["vrshark.io." + n for n in NAMES]
    args = ["-n", "-r", str(cap), "-T", "fields", "-E", "occurrence=f"]
    for f in fields:
        args += ["-e", f]
    proc = user.tshark(args)
    assert proc.returncode == 0, proc.stderr
    want = {}
    for line in proc.stdout.splitlines():
        cells = line.split("\t")
        row = {n: {"True": "1", "False": "0"}.get(v, v) for n, v in zip(NAMES, cells[1:]) if v}
        if row:
            want[int(cells[0])] = row
    assert len(want) == named
    got = {n: f for n, f in reloaded[1].items() if f}
    same(got, want)
