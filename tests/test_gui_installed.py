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
import subprocess

import pytest

from conftest import BUILD, CAPTURES, ROOT, Tshark, _world_dir, profile_column_widths, profile_rules
from gui_testlib import WIDTH, Gui, column, have_gui, near, rows_of, rule_colours, runs
from installed_testlib import Installed

pytestmark = pytest.mark.skipif(not have_gui(), reason="wireshark, Xvfb or imagemagick missing (tools/setup)")

PROFILE = ROOT / "profile" / "vrshark" / "colorfilters"
ARTEFACTS = BUILD / "gui-artefacts"
MAX_ROWS = 20       # rows the packet list shows at 1680 x 1000 with room to spare

# capture -> the danger colour rules that must show in it
CASES = {
    "eglink_analysis_session.pcap": ["vrshark: ES-Link relays open"],
    # the unacknowledged commands (17, 18) coloured where their deadline passed
    # (28), as a live capture colours them
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


# -- the Expert Information dialog's Protocol column ---------------------------
# Read without OCR: the dialog's font is DejaVu Sans (fc-match sans-serif);
# its size is found from the header "Protocol", rendered by ImageMagick until
# its width matches, and each cell of the Protocol column is the name whose
# rendered width is nearest to the cell's (the names differ by 10 px and more).
PROTOCOL_NAMES = ("ECLINK_PNIO", "MCMB2", "VRSHARK_PNIO", "PNIO", "TCP")  # (those of PROFINET captures)
EXPERT_CASES = {  # capture -> the protocol of every finding in the dialog
    "eclink_pnio_connect.pcap": "ECLINK_PNIO",
    "mcmb2_duplex_watchdog.pcap": "MCMB2",
}


def _dark_extent(ppm, x0, x1, y0, y1):
    width, _, pixels = ppm
    xs = [x for y in range(y0, y1) for x in range(x0, x1)
          if max(pixels[(y * width + x) * 3:(y * width + x) * 3 + 3]) < 110]
    return (min(xs), max(xs)) if xs else None


@functools.lru_cache(maxsize=None)
def _rendered_width(text, size):
    out = subprocess.run(["convert", "-font", "DejaVu-Sans", "-pointsize", "%.2f" % size, "label:" + text,
                          "-trim", "-format", "%w", "info:"], capture_output=True, text=True, check=True)
    return int(out.stdout)


SEVERITY_COLOURS = ((255, 92, 92), (247, 242, 83), (160, 255, 255), (128, 183, 247))  # error .. chat


def _severity_bands(ppm, x):
    """[(top, height)] of the runs of the dialog's severity colours in pixel column x."""
    out, y = [], 0
    for c, n in runs(column(ppm, x)):
        if n >= 14 and any(near(c, s) for s in SEVERITY_COLOURS):
            out.append((y, n))
        y += n
    return out


def _expert_rows_shown(ppm):
    """Whether the dialog shows rows (it fills after the file is read)."""
    return sum(len(_severity_bands(ppm, x)) for x in range(0, ppm[0], 16)) >= 8


def expert_dialog_protocols(ppm):
    """The Protocol column of the Expert Information dialog in the picture,
    one name per row, top to bottom."""
    width, height, _ = ppm
    # the rows: bands of the severity colours, read in the pixel column of
    # the dialog's first column that has the most of them (past its texts)
    def bands(x):
        return _severity_bands(ppm, x)
    x_sev = max(range(0, width, 4), key=lambda x: sum(n for _, n in bands(x)))
    found = bands(x_sev)
    assert found, "no Expert Information rows in the picture"
    first = x_sev
    while first > 0 and bands(first - 1):
        first -= 1
    row = functools.reduce(math.gcd, [n for _, n in found])
    assert 14 <= row <= 30, row
    rows = [(y + k * row, y + (k + 1) * row) for y, n in found for k in range(n // row)]
    # the header above the first row: its text clusters (Severity, Summary, Group, Protocol, Count)
    def dark_xs(yy):
        return {x for x in range(first - 8, width) if max(ppm[2][(yy * width + x) * 3:(yy * width + x) * 3 + 3]) < 110}
    y = rows[0][0] - 1
    while y > 0 and not dark_xs(y):
        y -= 1
    band_end = y + 1
    while y > 0 and dark_xs(y):
        y -= 1
    band = range(y + 1, band_end)
    per_x = {}
    for yy in band:
        for x in dark_xs(yy):
            per_x[x] = per_x.get(x, 0) + 1
    # (the column separators run the whole height of the header)
    xs = sorted(x for x, n in per_x.items() if n < len(band))
    clusters = [[xs[0], xs[0]]]
    for x in xs[1:]:
        if x - clusters[-1][1] > 12:
            clusters.append([x, x])
        else:
            clusters[-1][1] = x
    starts = [c[0] for c in clusters if c[1] - c[0] >= 20]
    proto_hdr = next(c for c in clusters if c[0] == starts[3])
    hdr_w = proto_hdr[1] - proto_hdr[0] + 1
    size = min((s / 4 for s in range(36, 64)), key=lambda s: abs(_rendered_width("Protocol", s) - hdr_w))
    names = []
    for y0, y1 in rows:
        ext = _dark_extent(ppm, starts[3] - 4, starts[4] - 6, y0 + 1, y1 - 1)
        assert ext, "an empty Protocol cell"
        w = ext[1] - ext[0] + 1
        names.append(min(PROTOCOL_NAMES, key=lambda t: abs(_rendered_width(t, size) - w)))
    return names


@pytest.mark.parametrize("kind", ["personal", "lua-only"])
@pytest.mark.parametrize("capture", sorted(EXPERT_CASES))
def test_expert_dialog_names_the_protocol(gui, kind, capture):
    """*Analyze > Expert Information* (opened by `wireshark -z expert`) lists
    every finding of a device under its own protocol, with the C plugin and
    with the Lua plugins alone (tests/test_expert_protocols.py: the same in
    `tshark -z expert`)."""
    inst = None if kind == "personal" else Installed(kind)
    g = gui if inst is None else Gui(inst, ARTEFACTS, on=gui)
    try:
        name = "expert_%s_%s" % (kind, capture.replace(".pcap", ""))
        ppm, output = g.shot(name, ["-C", "vrshark", "-r", str(CAPTURES / capture), "-z", "expert"], settle=60,
                             ready=_expert_rows_shown)
    finally:
        if inst is not None:
            g.close()
            inst.remove()
    assert "Lua Error" not in output and "Dissector bug" not in output, output
    names = expert_dialog_protocols(ppm)
    assert names and set(names) == {EXPERT_CASES[capture]}, "%s (see %s)" % (names, ARTEFACTS)
