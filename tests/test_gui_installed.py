"""Wireshark's GUI as a user has it after the README's personal install
(installed_testlib), with the vrshark profile, on one capture per protocol
and transport: the rows that show the danger (relays open, E010, watchdog
or PCI stalled) have the danger colour in the picture, and every other row
the colour its first matching rule gives it, as Wireshark applies the
rules. What each frame should look like comes from tools/tshark (the
harness) with the profile's rules; what it does look like, from the
screenshot. A frame that the installed plugins left undecoded (a plain PNIO
row where E010 should be red) has the wrong colour and fails the test.
On a capture of a million frames that lasts hours, the profile's column
widths hold the frame number, the time and the source (no cell cut).

The pictures stay in build/gui-artefacts/ for a look."""
import functools
import math
import re
import shutil
import struct

import pytest

from conftest import BUILD, CAPTURES, ROOT, Tshark, _world_dir, profile_column_widths, profile_rules
from gui_testlib import WIDTH, Gui, column, have_gui, rows_of, rule_colours, runs
from installed_testlib import Installed

pytestmark = pytest.mark.skipif(not have_gui(), reason="wireshark, Xvfb or imagemagick missing (tools/setup)")

PROFILE = ROOT / "profile" / "vrshark" / "colorfilters"
ARTEFACTS = BUILD / "gui-artefacts"
MAX_ROWS = 20       # rows the packet list shows at 1680 x 1000 with room to spare

# capture -> the danger colour rules that must show in it
CASES = {
    "eglink_analysis_session.pcap": ["vrshark: ES-Link relays open"],
    # the unacknowledged commands (17, 18) coloured on their own frames: known
    # from a later frame, drawn once the file is read
    "eclink_modbus_faults.pcap": ["vrshark: watchdog stalled", "vrshark: command not acknowledged"],
    "eglink_analysis_vrci_unacked.pcap": ["vrshark: command not acknowledged"],
    "eclink_pnio_connect.pcap": ["vrshark: watchdog stalled"],
    "mcmb2_duplex_watchdog.pcap": ["vrshark: watchdog stalled"],
    # no Connect: the layout is inferred in frame 6; the GUI shows frames 1-5 decoded too
    "mcmb2_duplex_midsession.pcap": ["vrshark: watchdog stalled"],
    "mcmb2_polled_connect.pcap": ["vrshark: E010 / fieldbus failure"],
}


def rules():
    """[(name, filter, background)] of the profile, in order."""
    colours = rule_colours(PROFILE)
    return [(name, filt, colours[name]) for name, filt in profile_rules()]


@pytest.fixture(scope="module")
def harness():
    conf = _world_dir("vrshark-conf-")
    yield Tshark(conf)
    shutil.rmtree(conf, ignore_errors=True)


@pytest.fixture(scope="module")
def gui():
    inst = Installed("personal")
    g = Gui(inst, ARTEFACTS)
    yield g
    g.close()
    inst.remove()


def expected_colours(harness, capture):
    """{frame: rule name} as Wireshark colours them: the first rule that
    matches (frames no rule of ours matches are left out)."""
    colour = {}
    for name, filt, _ in rules():
        rows = harness.run(["-n", "-2", "-r", str(capture), "-Y", filt, "-T", "fields",
                            "-e", "frame.number"]).stdout.split()
        for n in map(int, rows):
            colour.setdefault(n, name)
    return colour


@pytest.mark.parametrize("capture", sorted(CASES))
def test_danger_rows_coloured(gui, harness, capture):
    path = CAPTURES / capture
    want_by_frame = expected_colours(harness, path)
    danger = [n for n, name in sorted(want_by_frame.items()) if name in CASES[capture]]
    assert danger, "the harness finds none of %s in %s" % (CASES[capture], capture)
    # Frame 1 (selected when the file opens, so its colour is hidden), the
    # first danger frames, and the first other frames of ours to fill the list.
    danger = [n for n in danger if n != 1][:MAX_ROWS // 2]
    others = [n for n in sorted(want_by_frame) if n != 1 and n not in danger]
    shown = sorted(danger + others[:MAX_ROWS - 1 - len(danger)])
    view = "frame.number == 1 || " + " || ".join("frame.number == %d" % n for n in shown)
    ppm, output = gui.shot(capture.replace(".pcap", ""), ["-C", "vrshark", "-r", str(path), "-Y", view])
    for bad in ("Lua Error", "Dissector bug", "dissector bug"):
        assert bad not in output, output
    colours = {name: rgb for name, _, rgb in rules()}
    # rules that share a background are one colour in the picture
    by_rgb = {}
    for name, rgb in colours.items():
        by_rgb.setdefault(rgb, []).append(name)
    got, row = rows_of(ppm, {names[0]: rgb for rgb, names in by_rgb.items()})
    want = {names[0]: sum(1 for n in shown if want_by_frame[n] in names) for rgb, names in by_rgb.items()}
    assert row and 12 <= row <= 30, "no packet-list rows found in the picture (%s)" % row
    assert all(want[names[0]] for rgb, names in by_rgb.items() if set(names) & set(CASES[capture]))
    assert got == want, "%s: rows of each colour in the picture (see %s)\n got  %s\n want %s" % (
        capture, ARTEFACTS, {k: v for k, v in got.items() if v}, {k: v for k, v in want.items() if v})


# -- the packet list's columns on a long capture ------------------------------
# A field capture has 10^5 to 10^7 frames and lasts hours: the last frames
# of this one are numbered 1000001.., start at 12345.678901 s and come from
# MAC addresses Wireshark names (Siemens_00:00:01, HMSIndus_00:00:02) and IPv4
# addresses; frames before them are a plain filler Wireshark reads fast.
LONG_FILLER = 1000000
LONG_TAIL = CAPTURES / "crane_eclink_pnio.pcap"
LONG_SHIFT_US = 12345678901
LONG_COLUMNS = ("No.", "Time", "Source")


def long_capture(path):
    """LONG_FILLER filler frames (10 us apart, from a Siemens MAC, EtherType
    0x88b5), then the frames of LONG_TAIL shifted by LONG_SHIFT_US."""
    src = LONG_TAIL.read_bytes()
    assert struct.unpack_from("<I", src)[0] == 0xA1B2C3D4
    tail, pos = [], 24
    while pos < len(src):
        sec, usec, incl, orig = struct.unpack_from("<IIII", src, pos)
        tail.append((sec * 1000000 + usec, src[pos + 16:pos + 16 + incl], orig))
        pos += 16 + incl
    filler = bytes.fromhex("ffffffffffff" "000e8c000009" "88b5") + bytes(46)
    parts = [src[:24]]

    def put(t, data, orig):
        parts.append(struct.pack("<IIII", t // 1000000, t % 1000000, len(data), orig))
        parts.append(data)
    t0 = tail[0][0]
    for i in range(LONG_FILLER):
        put(t0 + 10 * i, filler, len(filler))
    for t, data, orig in tail:
        put(t + LONG_SHIFT_US, data, orig)
    path.write_bytes(b"".join(parts))
    path.chmod(0o644)
    return len(tail)


SELECTED = (48, 140, 198)   # the selected row's background


def _selected_top(ppm, x):
    """The top of the selected row in pixel column x, or None."""
    y = 0
    for c, n in runs(column(ppm, x)):
        if n >= 8 and all(abs(a - b) <= 12 for a, b in zip(c, SELECTED)):
            return y
        y += n
    return None


def _row_height(ppm, x, end):
    """The height of a row: the greatest common divisor of the runs of row
    colours (not grey) above the selected row (rows of one colour touch)."""
    heights, y = [], 0
    for c, n in runs(column(ppm, x)):
        if y >= end:
            break
        if n >= 14 and max(c) - min(c) > 12:
            heights.append(n)
        y += n
    return functools.reduce(math.gcd, heights)


def elided(ppm, x0, x1, y0, y1):
    """Whether the text in the box ends with Qt's ellipsis: the last glyph's
    pixels (the rightmost 6 px of dark pixels) all sit on the baseline (the
    bottom 3 pixel rows of the text), where the text ends with a digit or a
    letter otherwise. None: no text in the box."""
    width, _, pixels = ppm
    dark = [(x, y) for y in range(y0, y1) for x in range(x0, x1)
            if max(pixels[(y * width + x) * 3:(y * width + x) * 3 + 3]) < 110]
    if not dark:
        return None
    right = max(x for x, _ in dark)
    near_end = [(x, y) for x, y in dark if x >= right - 30]
    bottom = max(y for _, y in near_end)
    return all(y >= bottom - 2 for x, y in near_end if x > right - 6)


def test_long_capture_columns_not_cut(gui):
    """At 1680 px with the profile's widths (profile/vrshark/recent), No.
    holds 7 digits, Time `12345.678901` and Source a resolved MAC name or an
    IPv4 address: in the rows shown at the end of a capture of a million
    frames, none of these cells ends with Qt's ellipsis."""
    cap = gui.installed.top / "long.pcap"   # (where the user Wireshark runs as reads it)
    n_tail = long_capture(cap)
    last = LONG_FILLER + n_tail
    ppm, output = gui.shot("long_capture", ["-C", "vrshark", "-r", str(cap), "-g", str(last)], settle=400,
                           ready=lambda p: _selected_top(p, 30) is not None)
    assert "Dissector bug" not in output and "Lua Error" not in output, output
    top = _selected_top(ppm, 30)
    assert top, "the last frame is not selected in the picture (see %s)" % ARTEFACTS
    row = _row_height(ppm, 30, top)
    assert 14 <= row <= 30, row
    widths = [w for _, w in profile_column_widths()]
    titles = [t for t, _ in re.findall(r'^\t"([^"]+)", "([^"]+)"', (PROFILE.parent / "preferences").read_text(),
                                       re.M)]
    starts = [sum(widths[:i]) for i in range(len(widths))]
    cut = []
    # the rows above the selected one: the tail's frames last - 1, last - 2, ...
    for k in range(1, n_tail):
        y0 = top - k * row
        for title in LONG_COLUMNS:
            i = titles.index(title)
            state = elided(ppm, starts[i] + 2, starts[i] + widths[i] - 1, y0 + 1, y0 + row - 1)
            assert state is not None, "no text in %s of frame %d (see %s)" % (title, last - k, ARTEFACTS)
            if state:
                cut.append("%s of frame %d" % (title, last - k))
    assert not cut, "cut with the profile's widths at %d px: %s (see %s)" % (WIDTH, ", ".join(cut), ARTEFACTS)
