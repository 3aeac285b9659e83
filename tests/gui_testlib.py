"""Wireshark's GUI under Xvfb for the GUI tests: start it on a capture as the
installed layout's user (installed_testlib), wait until the packet list is
drawn, take a screenshot, and read the colours of the packet-list rows from
the picture.

Rows are read along one column of pixels in the left part of the
"Age ms" column, where its right-aligned numbers leave the row
background bare. Runs of one colour are rows of that colour; the height of one row is
that of the shortest run (the selected first row is one)."""
import os
import shutil
import subprocess
import time
from pathlib import Path

from conftest import profile_column_widths
from installed_testlib import IS_ROOT, RUN_UID

WIDTH, HEIGHT = 1680, 1000     # the width the profile's columns are made for


def _probe_x():
    """The blank left part of the "Age ms" column (its numbers sit on the
    right), from the column widths of the profile (profile/vrshark/recent)."""
    return sum(w for _, w in profile_column_widths()[:8]) + 12


PROBE_X = _probe_x()          # in pixels
TOLERANCE = 6               # per channel, 0..255
# The display filter bar's backgrounds (valid, invalid, deprecated filter).
FILTER_BAR = ((175, 255, 175), (255, 175, 175), (255, 255, 175))

RECENT = """gui.geometry_main_x: 0
gui.geometry_main_y: 0
gui.geometry_main_width: %d
gui.geometry_main_height: %d
gui.geometry_main_maximized: FALSE
privs.warn_if_elevated: FALSE
""" % (WIDTH, HEIGHT)


def have_gui():
    return all(shutil.which(p) for p in ("wireshark", "Xvfb", "import"))


def read_ppm(data):
    """(width, height, pixel rows) of a binary PPM (P6, maxval 255)."""
    parts, pos = [], 0
    while len(parts) < 4:
        while data[pos:pos + 1].isspace():
            pos += 1
        if data[pos:pos + 1] == b"#":
            pos = data.index(b"\n", pos)
            continue
        end = pos
        while not data[end:end + 1].isspace():
            end += 1
        parts.append(data[pos:end])
        pos = end
    pos += 1
    assert parts[0] == b"P6" and parts[3] == b"255", parts
    width, height = int(parts[1]), int(parts[2])
    pixels = data[pos:pos + width * height * 3]
    return width, height, pixels


def column(ppm, x):
    """The colours (r, g, b) of pixel column x, top to bottom."""
    width, height, pixels = ppm
    return [tuple(pixels[(y * width + x) * 3:(y * width + x) * 3 + 3]) for y in range(height)]


def rule_colours(colorfilters):
    """{rule name: background (r, g, b) in 0..255} of a colorfilters file."""
    rules = {}
    for line in Path(colorfilters).read_text().splitlines():
        if not line.startswith("@"):
            continue
        name, _filter, colours = line[1:].split("@", 2)
        bg = colours[1:colours.index("]")].split(",")
        rules[name] = tuple(round(int(c) / 257) for c in bg)
    return rules


def near(a, b):
    return all(abs(x - y) <= TOLERANCE for x, y in zip(a, b))


def runs(pixels):
    """[(colour, length)] of the runs of equal colour in a pixel column."""
    out = []
    for p in pixels:
        if out and near(out[-1][0], p):
            out[-1][1] += 1
        else:
            out.append([p, 1])
    return [(tuple(c), n) for c, n in out]


def rows_of(ppm, colours):
    """{colour name: rows} of the packet list, for the named colours, and
    the height of one row. The shortest run of any named colour or of the
    selection (a colour that is not grey) below the top of the list is one
    row."""
    def grey(c):
        return max(c) - min(c) <= 12
    col_runs = [(c, n) for c, n in runs(column(ppm, PROBE_X)) if n >= 3]
    # The list starts with the selected first row: the first run of colour
    # tall enough to be a row, not the display filter bar above it; it ends
    # where white or grey begins (rows touch each other).
    first = next((i for i, (c, n) in enumerate(col_runs)
                  if not grey(c) and n >= 14 and not any(near(c, f) for f in FILTER_BAR)), len(col_runs))
    end = next((i for i in range(first, len(col_runs)) if grey(col_runs[i][0])), len(col_runs))
    col_runs = col_runs[first:end]
    named = {name: rgb for name, rgb in colours.items()}
    # rows: the named colours and the selection
    lengths = [n for c, n in col_runs if any(near(c, rgb) for rgb in named.values()) or not grey(c)]
    if not lengths:
        return {name: 0 for name in named}, None
    row = min(lengths)
    counts = {}
    for name, rgb in named.items():
        total = sum(n for c, n in col_runs if near(c, rgb))
        counts[name] = round(total / row)
    return counts, row


# The Statistics menu: a pixel column inside it (the menu bar's "Statistics"
# is at the same place at WIDTH in every install) and its highlight colour.
MENU_X = 305
MENU_HIGHLIGHT = (48, 140, 198)


def menu_highlight(ppm):
    """The top of the highlighted item of an open menu (a run of the
    highlight colour as tall as an item, below the menu bar's own), or None."""
    y = 0
    for c, n in runs(column(ppm, MENU_X)):
        if near(c, MENU_HIGHLIGHT) and n >= 15 and y > 10:
            return y
        y += n
    return None


class Gui:
    """An X server and Wireshark runs on it for one installed layout."""

    def __init__(self, installed, artefacts, on=None):
        """on: another Gui whose X server this one uses (it stops it)."""
        self.installed = installed
        self.artefacts = Path(artefacts)
        self.artefacts.mkdir(parents=True, exist_ok=True)
        (installed.config / "recent_common").write_text(RECENT)
        self.run_dir = installed.top / "xdg-run"
        self.run_dir.mkdir(mode=0o700, exist_ok=True)
        if IS_ROOT:
            for p in (installed.config / "recent_common", self.run_dir):
                os.chown(p, RUN_UID, RUN_UID)
        if on is not None:
            self.display, self.xvfb = on.display, None
            return
        self.display = ":%d" % (100 + os.getpid() % 400)
        self.xvfb = subprocess.Popen(["Xvfb", self.display, "-screen", "0", "%dx%dx24" % (WIDTH, HEIGHT),
                                      "-nolisten", "tcp"], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        time.sleep(1.5)

    def screenshot(self):
        return subprocess.run(["import", "-display", self.display, "-window", "root", "-depth", "8", "ppm:-"],
                              capture_output=True, check=True).stdout

    def shot(self, name, args, settle=30, ready=None):
        """Wireshark with args until its picture stops changing (bounded),
        and, with ready, until ready(parsed picture) is true too (a long file
        loads with a picture that stands still for seconds): the last
        screenshot as PPM bytes (also kept as NAME.png), and Wireshark's
        output."""
        env = self.installed.env(DISPLAY=self.display, XDG_RUNTIME_DIR=str(self.run_dir))
        ws = subprocess.Popen(self.installed.command("wireshark", args), env=env, stdout=subprocess.PIPE,
                              stderr=subprocess.STDOUT, cwd=str(self.installed.home))
        try:
            last, same, deadline = None, 0, time.time() + settle
            time.sleep(3)
            while time.time() < deadline:
                pic = self.screenshot()
                same = same + 1 if pic == last else 0
                last = pic
                if same >= 2 and (ready is None or ready(read_ppm(pic))):
                    break
                time.sleep(1)
        finally:
            ws.kill()
            out = ws.communicate()[0].decode(errors="replace")
        png = self.artefacts / (name + ".png")
        subprocess.run(["convert", "ppm:-", str(png)], input=last, check=True)
        return read_ppm(last), out

    def close(self):
        if self.xvfb is not None:
            self.xvfb.kill()
            self.xvfb.wait()


def add_probe(installed, name, probe):
    """A Lua postdissector (probe: its text, with %r for the file it writes)
    in the installed layout's personal plugins, and the file it writes,
    writable by the layout's user."""
    out = installed.top / "probe.txt"
    out.touch()
    if IS_ROOT:
        os.chown(out, RUN_UID, RUN_UID)
    installed.add_lua_plugin(name, probe % str(out))
    return out


def have_keys():
    """xdotool, to press Wireshark's keys (tools/setup installs it)."""
    return shutil.which("xdotool") is not None


class Session:
    """One Wireshark run on a Gui's display that stays open for keys and
    screenshots: the mouse pointer rests on the status bar (a row under it
    would be drawn highlighted), and a click there gives the window the
    keyboard (no window manager runs)."""

    STATUS_BAR = (WIDTH // 2, HEIGHT - 12)

    def __init__(self, gui, args):
        self.gui = gui
        self.log = gui.installed.top / ("wireshark-%d.log" % time.monotonic_ns())
        env = gui.installed.env(DISPLAY=gui.display, XDG_RUNTIME_DIR=str(gui.run_dir))
        with open(self.log, "wb") as log:
            self.proc = subprocess.Popen(gui.installed.command("wireshark", args), env=env, stdout=log,
                                         stderr=subprocess.STDOUT, cwd=str(gui.installed.home))

    def xdotool(self, *args):
        subprocess.run(["xdotool"] + list(args), env=dict(os.environ, DISPLAY=self.gui.display),
                       capture_output=True, check=True)

    def focus(self):
        x, y = self.STATUS_BAR
        self.xdotool("mousemove", str(x), str(y), "click", "1")

    def press(self, keys):
        """keys (xdotool's names, e.g. "ctrl+shift+l") to the main window."""
        self.focus()
        self.xdotool("key", keys)

    def output(self):
        return self.log.read_text(errors="replace")

    def statistics_item(self, offset, name="statistics"):
        """Opens the Statistics menu and picks the item `offset` places below
        the first item of its unsorted group (Wireshark's own "DHCP (BOOTP)
        Statistics" on 4.0, then the other items of the group in
        alphabetical order, Lua plugins' among them). The group is found on
        the screen, not by a count of the items above it: Down moves the
        highlight one item at a time, and the first step longer than one
        item (with a file open no item is disabled) crosses the separator
        above the group. Screenshots of the open menu: NAME-menu.png."""
        self.press("alt+s")
        time.sleep(1)
        tops = [menu_highlight(read_ppm(self.gui.screenshot()))]
        for _ in range(40):
            self.xdotool("key", "Down")
            time.sleep(0.3)
            tops.append(menu_highlight(read_ppm(self.gui.screenshot())))
            assert None not in tops, "no highlighted item in the Statistics menu: %s" % tops
            row = tops[1] - tops[0]
            if len(tops) > 2 and row < tops[-1] - tops[-2] < 2 * row:
                break
        else:
            raise AssertionError("no separator in the Statistics menu: highlight at %s" % tops)
        if offset:
            self.xdotool("key", *(["Down"] * offset))
            time.sleep(0.3)
        subprocess.run(["convert", "ppm:-", str(self.gui.artefacts / (name + "-menu.png"))],
                       input=self.gui.screenshot(), check=True)
        self.xdotool("key", "Return")

    def open_statistics_item(self, found, tries=12, name="statistics"):
        """Picks the items of the Statistics menu's unsorted group in turn
        until found() (polled for 4 s) is true: the group's order changes
        (Analyze > Reload Lua Plugins puts the Lua items after Wireshark's
        own), the item is found by what it opens. Escape closes what another
        item opened. Returns the item's place in the group, or None."""
        for offset in range(tries):
            self.statistics_item(offset, "%s-%d" % (name, offset))
            deadline = time.time() + 4
            while time.time() < deadline:
                if found():
                    return offset
                time.sleep(0.5)
            self.xdotool("key", "Escape", "Escape")
            time.sleep(0.5)
        return None

    def close(self):
        self.proc.kill()
        self.proc.wait()
        return self.output()
