"""Statistics > EG-Link (Lua) in the GUI of the Lua-only install (README's
lines, no C plugin): Wireshark 4.0 never shows a Lua menu item of
MENU_STAT_GENERIC, so the item is registered in the unsorted group, which
4.0 and 4.6 both show. The test opens the Statistics menu with the
keyboard, as a user without a mouse would, picks the items of that group in
turn (gui_testlib.Session.open_statistics_item: the group is found on the
screen, not by counting the items above it) and finds the text window the
item opens by its title: no window "EG-Link" opens unless the item is
there."""
import subprocess
import time

import pytest

from conftest import BUILD, ROOT
from gui_testlib import Gui, Session, have_gui, have_keys
from installed_testlib import Installed

pytestmark = pytest.mark.skipif(not (have_gui() and have_keys()),
                                reason="wireshark, Xvfb, imagemagick or xdotool missing (tools/setup)")

# Wireshark 4.0: the unsorted group in alphabetical order, DHCP (BOOTP)
# Statistics, EC-Link, EG-Link (Lua).
PLACE = 2


def windows_named(gui, pattern):
    """The X windows whose title matches pattern (Wireshark adds its own name to a
    TextWindow's title)."""
    out = subprocess.run(["xdotool", "search", "--name", pattern], capture_output=True, text=True,
                         env={"DISPLAY": gui.display, "PATH": "/usr/bin:/bin"}).stdout
    return out.split()


def test_lua_only_statistics_item_opens_its_window():
    inst = Installed("lua-only")
    gui = Gui(inst, BUILD / "gui-artefacts")
    session = None
    try:
        # (a file open: no item of the menu is disabled)
        session = Session(gui, ["-C", "vrshark", "-r", str(ROOT / "captures" / "eglink_analysis_session.pcap")])
        deadline = time.time() + 30
        while time.time() < deadline and not windows_named(gui, "Wireshark"):
            time.sleep(0.5)
        time.sleep(2)
        assert not windows_named(gui, "EG-Link")
        place = session.open_statistics_item(lambda: windows_named(gui, "EG-Link"), name="lua_only_eglink")
        subprocess.run(["convert", "ppm:-", str(gui.artefacts / "lua_only_statistics.png")],
                       input=gui.screenshot(), check=True)
        assert place == PLACE and windows_named(gui, "EG-Link"), (place, session.output())
    finally:
        if session is not None:
            session.close()
        gui.close()
        inst.remove()
