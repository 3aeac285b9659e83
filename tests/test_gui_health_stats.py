"""Statistics > MC-MB2-PN and Statistics > EC-Link in the GUI of both installs
(the full install with the C plugin and the Lua-only one) on Wireshark 4.0
under Xvfb: the items sit in the unsorted group of the Statistics menu
(4.0 never shows a Lua item of MENU_STAT_GENERIC), open a text window with
the health rows of the capture (lua/vrshark/health.luam), and still do after
Analyze > Reload Lua Plugins. The menu is walked with the keyboard
(gui_testlib.Session.statistics_item); what the window shows is read by a
probe plugin that records the text each Lua text window is given."""
import time

import pytest

from conftest import BUILD, ROOT
from gui_testlib import Gui, Session, have_gui, have_keys
from installed_testlib import Installed
from test_gui_lua_menu import windows_named

pytestmark = pytest.mark.skipif(not (have_gui() and have_keys()),
                                reason="wireshark, Xvfb, imagemagick or xdotool missing (tools/setup)")

# A third party's plugin in the personal plugin folder: every Lua TextWindow
# made after load is wrapped, and the text it is given written to a file
# (through _G: a plugin's own globals are its own).
PROBE = r"""
local real = _G.TextWindow
local path = os.getenv("HOME") .. "/textwindows.log"
local function log(title, text)
    local f = io.open(path, "a")
    f:write("=== " .. title .. "\n" .. text .. "\n")
    f:close()
end
_G.TextWindow = setmetatable({ new = function(title)
    local w = real.new(title)
    local p = {}
    function p.set(_, text) log(title, text) return w:set(text) end
    function p.append(_, text) log(title, text) return w:append(text) end
    function p.set_atclose(_, fn) return w:set_atclose(fn) end
    return p
end }, { __index = real })
"""

MCMB2_ROW = ("HMSIndus_00:00:02 FrameIDs 0x8003/0x8004  uplink        25         200.000  200.000  200.000"
             "               200.000         5       1       0       1         1      0")
ECLINK_ROW = ("PROFINET HMSIndus_00:00:02 FrameIDs 0x8010/0x8011  input       40         125.000  125.000  "
              "125.000               125.000         5       1       1       1         1      2")


def _wait_for(gui, title, seconds=15):
    deadline = time.time() + seconds
    while time.time() < deadline and not windows_named(gui, title):
        time.sleep(0.5)
    return windows_named(gui, title)


def _texts(inst, title):
    log = inst.home / "textwindows.log"
    text = log.read_text() if log.exists() else ""
    return [part.split("\n", 1)[1] for part in text.split("=== ")[1:] if part.startswith(title + "\n")]


def _open(session, gui, title, name):
    """Statistics > title: its place in the group."""
    offset = session.open_statistics_item(lambda: windows_named(gui, title), name=name)
    assert offset is not None, "no Statistics > %s: %s" % (title, session.output()[-3000:])
    time.sleep(1)
    return offset


def _close(session, gui, title):
    for w in windows_named(gui, title):
        session.xdotool("windowclose", w)
    time.sleep(1)


@pytest.mark.parametrize("kind", ["lua-only", "personal"])
def test_health_items_open_their_windows(kind):
    inst = Installed(kind)
    inst.add_lua_plugin("zz_textwindow_probe.lua", PROBE)
    gui = Gui(inst, BUILD / "gui-artefacts")
    session = None
    # the unsorted group on 4.0: DHCP (BOOTP) Statistics, then in alphabetical
    # order EC-Link, EG-Link (Lua) in the Lua-only install (the C plugin's
    # EG-Link is in the upper group), MC-MB2-PN
    places = {"EC-Link": 1, "MC-MB2-PN": 3 if kind == "lua-only" else 2}
    try:
        for cap, title, row in (("mcmb2_duplex_watchdog.pcap", "MC-MB2-PN", MCMB2_ROW),
                                ("eclink_pnio_connect.pcap", "EC-Link", ECLINK_ROW)):
            session = Session(gui, ["-C", "vrshark", "-r", str(ROOT / "captures" / cap)])
            assert _wait_for(gui, "Wireshark", 40)
            time.sleep(4)
            assert not windows_named(gui, title)
            assert _open(session, gui, title, "%s-%s" % (kind, title)) == places[title]
            texts = _texts(inst, title)
            assert texts and row in texts[-1], (texts, session.output()[-3000:])
            _close(session, gui, title)
            if title == "MC-MB2-PN":
                # Analyze > Reload Lua Plugins: the capture is dissected anew, the
                # item is there again and its rows with it
                session.press("ctrl+shift+l")
                time.sleep(6)
                before = len(_texts(inst, title))
                _open(session, gui, title, "%s-%s-reloaded" % (kind, title))
                texts = _texts(inst, title)
                assert len(texts) > before and row in texts[-1], texts
            session.close()
            session = None
    finally:
        if session is not None:
            session.close()
        gui.close()
        inst.remove()
