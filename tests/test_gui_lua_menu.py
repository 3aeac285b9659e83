"""Statistics > EG-Link (Lua) in the GUI of the Lua-only install (README's
lines, no C plugin): Wireshark 4.0 never shows a Lua menu item of
MENU_STAT_GENERIC, so the item is registered in the unsorted group, which
4.0 and 4.6 both show. The test opens the Statistics menu with the
keyboard, as a user without a mouse would, picks the item and finds the
text window it opens by its title: no window "EG-Link" opens unless the
item is there."""
import subprocess
import time

import pytest

from conftest import BUILD
from gui_testlib import Gui, Session, have_gui, have_keys
from installed_testlib import Installed

pytestmark = pytest.mark.skipif(not (have_gui() and have_keys()),
                                reason="wireshark, Xvfb, imagemagick or xdotool missing (tools/setup)")

# Wireshark 4.0 with no file open: the Statistics menu opens on Resolved
# Addresses; Down steps over the enabled items (Conversations, Endpoints,
# Packet Lengths, Service Response Time), then the unsorted group in
# alphabetical order: DHCP (BOOTP) Statistics, EG-Link (Lua).
DOWNS = 6


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
        session = Session(gui, ["-C", "vrshark"])
        deadline = time.time() + 30
        while time.time() < deadline and not windows_named(gui, "Wireshark"):
            time.sleep(0.5)
        time.sleep(2)
        assert not windows_named(gui, "EG-Link")
        session.press("alt+s")
        time.sleep(1)
        session.xdotool("key", *(["Down"] * DOWNS), "Return")
        deadline = time.time() + 10
        while time.time() < deadline and not windows_named(gui, "EG-Link"):
            time.sleep(0.5)
        subprocess.run(["convert", "ppm:-", str(gui.artefacts / "lua_only_statistics.png")],
                       input=gui.screenshot(), check=True)
        assert windows_named(gui, "EG-Link"), session.output()
    finally:
        if session is not None:
            session.close()
        gui.close()
        inst.remove()
