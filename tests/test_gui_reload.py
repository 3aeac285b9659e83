"""Analyze > Reload Lua Plugins (Ctrl+Shift+L) in Wireshark's GUI, as a user
does it after the README's installs (installed_testlib): the full install
(the C plugin and the Lua plugins) and the Lua-only copy. A capture is
opened, the Lua plugins are reloaded twice, and every frame must decode as
right after the start: the same Protocol and Info columns, the same expert
findings, the same packet list in the picture (the rows' colours included), and no "Dissector bug" or
"Lua Error" anywhere.

The reload deregisters every Lua protocol, field and dissector and registers
them anew, and what was looked up of them before names nothing then. A full
tree would hide that (the front ends hand a decoder everything when the
tree is visible): the packet list works on an invisible tree, with the
profile's colour rules and columns. So the probe (a Lua postdissector
installed beside the plugins, reloaded with them) references no field of
ours: it writes, each time it is loaded, "LOAD", and for every frame
dissected the columns (when the frame is dissected for the packet list) and
the expert messages (_ws.expert.message, which the decoders add on an
invisible tree too). What it wrote after each load is compared with what it
wrote after the start.

The pictures stay in build/gui-artefacts/ when they differ."""
import subprocess
import time

import pytest

from conftest import BUILD, CAPTURES
from gui_testlib import Gui, Session, add_probe, have_gui, have_keys, read_ppm
from installed_testlib import Installed

pytestmark = pytest.mark.skipif(not (have_gui() and have_keys()),
                                reason="wireshark, Xvfb, imagemagick or xdotool missing (tools/setup)")

ARTEFACTS = BUILD / "gui-artefacts"
RELOADS = 2
SETTLE = 2.0        # seconds without a new line from the probe: Wireshark is done
WAIT = 120          # at most, for one load

# capture -> the Protocol column its decoded frames show after the start,
# per install ("lua-only" has no EG-Link decoder: the capture must simply
# stay as it was)
CASES = {
    "mcmb2_duplex_watchdog.pcap": {"personal": "MC-MB2", "lua-only": "MC-MB2"},
    "eclink_pnio_connect.pcap": {"personal": "EC-Link", "lua-only": "EC-Link"},
    "eclink_modbus_basic.pcap": {"personal": "Modbus/TCP", "lua-only": "Modbus/TCP"},
    "eglink_analysis_session.pcap": {"personal": "EG-Link", "lua-only": None},
}
BAD = ("Dissector bug", "dissector bug", "Lua Error", "Unregistered hf")

PROBE = """-- vrshark reload test probe: columns and expert messages of every frame
local out = assert(io.open(%r, "a"))
out:write("LOAD\\n")
out:flush()
local probe = Proto("vrshark_reload_probe", "vrshark reload test probe")
local expert_message = Field.new("_ws.expert.message")
function probe.dissector(tvb, pinfo, tree)
    local msgs = {}
    for _, f in ipairs({ expert_message() }) do msgs[#msgs + 1] = tostring(f.value) end
    out:write(pinfo.number, "\\t", tostring(pinfo.cols.protocol), "\\t", tostring(pinfo.cols.info), "\\t",
        table.concat(msgs, "|"), "\\n")
    out:flush()
end
register_postdissector(probe)
"""


@pytest.fixture(scope="module", params=["personal", "lua-only"])
def gui(request):
    inst = Installed(request.param)
    probe_out = add_probe(inst, "vrshark_reload_probe.lua", PROBE)
    g = Gui(inst, ARTEFACTS)
    g.probe_out = probe_out
    yield g
    g.close()
    inst.remove()


def loads(text):
    """What the probe wrote after each load: [{"cols": {frame: (protocol,
    info)}, "experts": {frame: messages}}]; the last dissection of a frame
    counts (frames the packet list did not draw have no columns)."""
    out = []
    for line in text.splitlines():
        if line == "LOAD":
            out.append({"cols": {}, "experts": {}})
            continue
        parts = line.split("\t", 3)
        if len(parts) < 4 or not out:
            continue
        frame = int(parts[0])
        out[-1]["experts"][frame] = parts[3]
        if parts[1] != "(protocol)":        # dissected without column information
            out[-1]["cols"][frame] = (parts[1], parts[2])
    return out


def settle(gui, n_loads, frames=None):
    """Waits until the probe has been loaded n_loads times, has seen every
    frame since (frames: their number, when known) and then writes nothing
    more for SETTLE seconds."""
    deadline = time.time() + WAIT
    last, since = None, time.time()
    while time.time() < deadline:
        time.sleep(0.5)
        text = gui.probe_out.read_text(errors="replace")
        if text != last:
            last, since = text, time.time()
            continue
        got = loads(text)
        if len(got) == n_loads and got[-1]["experts"] and (frames is None or len(got[-1]["experts"]) >= frames) \
                and time.time() - since >= SETTLE:
            return got
    raise AssertionError("the probe did not settle at load %d:\n%s" % (n_loads, (last or "")[-2000:]))


def packet_list(ppm_bytes):
    """The packet list's part of a screenshot: the top half (the list, its
    header and the toolbars above it), without the right edge, where the
    intelligent scroll bar (a minimap of the rows' colours) appears when
    Wireshark gets round to it, narrowing the list."""
    width, height, pixels = read_ppm(ppm_bytes)
    return [pixels[y * width * 3:(y * width + width - 60) * 3] for y in range(height // 2)]


def steady_picture(gui):
    """A screenshot once two in a row are the same (bounded)."""
    last = None
    for _ in range(20):
        pic = gui.screenshot()
        if pic == last:
            break
        last = pic
        time.sleep(1)
    return last


def save(gui, name, ppm_bytes):
    subprocess.run(["convert", "ppm:-", str(ARTEFACTS / (name + ".png"))], input=ppm_bytes, check=True)


@pytest.mark.parametrize("capture", sorted(CASES))
def test_reload_decodes_as_fresh_start(gui, capture):
    kind = gui.installed.kind
    gui.probe_out.write_text("")
    session = Session(gui, ["-C", "vrshark", "-r", str(CAPTURES / capture)])
    try:
        fresh = settle(gui, 1)[-1]
        # (the pointer off the packet list: a row under it is drawn highlighted)
        session.focus()
        frames = len(fresh["experts"])
        fresh_pic = steady_picture(gui)
        for n in range(2, RELOADS + 2):
            session.press("ctrl+shift+l")
            settle(gui, n, frames)
        reloaded_pic = steady_picture(gui)
    finally:
        output = session.close()
    text = gui.probe_out.read_text(errors="replace")
    got = loads(text)
    for what, lines in (("Wireshark's output", output), ("the frames", text)):
        bad = [line for line in lines.splitlines() if any(b in line for b in BAD)]
        assert not bad, "%s, %s: %d lines of %s name a bug:\n%s" % (kind, capture, len(bad), what,
                                                                    "\n".join(bad[:3]))
    # the start decoded the capture (else nothing would be compared)
    want_proto = CASES[capture][kind]
    if want_proto:
        assert any(p == want_proto for p, _ in fresh["cols"].values()), (kind, capture, fresh["cols"])
    assert len(fresh["cols"]) >= 10, "the packet list drew too few rows: %s" % fresh["cols"]
    assert len(got) == RELOADS + 1, "Analyze > Reload Lua Plugins did not run %d times" % RELOADS
    for n, load in enumerate(got[1:], 1):
        assert load["experts"] == fresh["experts"], "%s, %s: expert findings after reload %d differ" % (
            kind, capture, n)
        assert load["cols"] == fresh["cols"], "%s, %s: columns after reload %d differ:\n%s" % (
            kind, capture, n, {f: (fresh["cols"].get(f), c) for f, c in load["cols"].items()
                               if fresh["cols"].get(f) != c})
    if packet_list(fresh_pic) != packet_list(reloaded_pic):
        name = "reload-%s-%s" % (kind, capture.replace(".pcap", ""))
        save(gui, name + "-fresh", fresh_pic)
        save(gui, name + "-reloaded", reloaded_pic)
        pytest.fail("%s, %s: the window after %d reloads differs from the fresh start (see %s)" % (
            kind, capture, RELOADS, ARTEFACTS))
