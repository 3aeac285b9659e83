"""Wireshark's GUI as a user has it after the README's personal install
(installed_testlib), with the vrshark profile, on one capture per protocol
and transport: the rows that show the danger (relays open, E010, watchdog
or PCI stalled) have the danger colour in the picture, and every other row
the colour its first matching rule gives it, as Wireshark applies the
rules. What each frame should look like comes from tools/tshark (the
harness) with the profile's rules; what it does look like, from the
screenshot. A frame that the installed plugins left undecoded (a plain PNIO
row where E010 should be red) has the wrong colour and fails the test.

The pictures stay in build/gui-artefacts/ for a look."""
import shutil

import pytest

from conftest import BUILD, CAPTURES, ROOT, Tshark, _world_dir, profile_rules
from gui_testlib import Gui, have_gui, rows_of, rule_colours
from installed_testlib import Installed

pytestmark = pytest.mark.skipif(not have_gui(), reason="wireshark, Xvfb or imagemagick missing (tools/setup)")

PROFILE = ROOT / "profile" / "vrshark" / "colorfilters"
ARTEFACTS = BUILD / "gui-artefacts"
MAX_ROWS = 20       # rows the packet list shows at 1600 x 1000 with room to spare

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
