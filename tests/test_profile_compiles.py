"""The `vrshark` profile as each install gives it (installed_testlib): the
full install (`cmake --install`, personal folders), the Lua plugins alone
(README.md's Lua-only lines) and the archive of tools/package, run by the
system tshark as a user with a fresh HOME and no WIRESHARK_PLUGIN_DIR.

Every filter of the profile compiles there: each custom column's fields,
each filter button, each colouring rule (ours and Wireshark's own defaults,
which follow ours in every install), with nothing on stderr; and the
columns show their values on every protocol's captures.

The columns, buttons and rules name EG-Link fields (`eglink.*`), which only
the C plugin registers until the Lua EG-Link is in: the Lua-only installs
fail on them, marked xfail (strict, so that the mark goes when they pass)."""
import re
from pathlib import Path

import pytest

from conftest import CAPTURES, PROFILE_DIR, uat_buttons
from installed_testlib import Installed, _folders

KINDS = ["personal", "lua-only", "archive"]


@pytest.fixture(scope="module")
def installed(request):
    inst = Installed(request.param)
    yield inst
    inst.remove()


def profile_of(inst):
    return inst.config / "profiles" / "vrshark"


def custom_columns(inst):
    """[(title, fields as a display filter)] of the installed profile's custom columns."""
    text = (profile_of(inst) / "preferences").read_text()
    return [(title, fmt[len("%Cus:"):].rsplit(":", 2)[0])
            for title, fmt in re.findall(r'^\t"([^"]+)", "([^"]+)"', text, re.M) if fmt.startswith("%Cus:")]


def buttons(inst):
    return uat_buttons(profile_of(inst) / "dfilter_buttons")


def colour_rules(path):
    """[(name, filter)] of a colorfilters file, in order (disabled rules start with !)."""
    return [tuple(line.lstrip("!")[1:].split("@", 2)[:2]) for line in path.read_text().splitlines()
            if line.lstrip("!").startswith("@")]


def compile_error(inst, expr):
    """"" when tshark with the profile compiles the display filter with nothing
    on stderr, else what it said."""
    proc = inst.tshark(["-C", "vrshark", "-n", "-r", str(CAPTURES / "eglink_armed.pcap"), "-c", "1",
                        "-Y", expr])
    if proc.returncode == 0 and not proc.stderr:
        return ""
    return "exit %d: %s" % (proc.returncode, proc.stderr.strip())


def errors(inst, named_filters):
    return {name: err for name, err in ((n, compile_error(inst, f)) for n, f in named_filters) if err}


@pytest.mark.parametrize("installed", KINDS, indirect=True)
def test_default_colour_rules_follow_ours(installed):
    """Wireshark's own colouring rules (its global colorfilters) follow ours in
    every install: a profile's colorfilters replaces the defaults."""
    path = profile_of(installed) / "colorfilters"
    ours = colour_rules(PROFILE_DIR / "colorfilters")
    theirs = colour_rules(Path(_folders()["Global configuration"]) / "colorfilters")
    assert theirs and ours[0][0].startswith("vrshark: ")
    assert colour_rules(path) == ours + theirs
    assert sorted(p.name for p in profile_of(installed).iterdir()) == [
        "colorfilters", "dfilter_buttons", "preferences", "recent"]
    for name in ("preferences", "dfilter_buttons", "recent"):
        assert (profile_of(installed) / name).read_text() == (PROFILE_DIR / name).read_text(), name


@pytest.mark.parametrize("installed", KINDS, indirect=True)
def test_columns_compile(installed):
    columns = custom_columns(installed)
    assert [t for t, _ in columns] == ["Device", "BU state", "RU state", "Armed RU", "Age ms"]
    assert errors(installed, columns) == {}


@pytest.mark.parametrize("installed", KINDS, indirect=True)
def test_buttons_compile(installed):
    found = buttons(installed)
    assert [label for label, _ in found] == ["Safety", "Faults", "Commands", "EG-Link", "EC-Link", "MC-MB2"]
    assert errors(installed, found) == {}


@pytest.mark.parametrize("installed", KINDS, indirect=True)
def test_colour_rules_compile(installed):
    """Each rule's filter compiles, and tshark --color reads the whole file
    without a word on stderr (a rule that does not compile is said there only)."""
    rules = colour_rules(profile_of(installed) / "colorfilters")
    assert len(rules) > 12
    assert errors(installed, rules) == {}
    proc = installed.tshark(["-C", "vrshark", "--color", "-n", "-r", str(CAPTURES / "eglink_armed.pcap"), "-c", "1"])
    assert proc.returncode == 0 and proc.stderr == ""


COLUMNS = ["No.", "Time", "Source", "Protocol", "Device", "BU state", "RU state", "Armed RU", "Age ms", "Info"]

# capture, frame -> the profile's columns Device, BU state, RU state, Armed RU,
# Age ms there (tshark -C vrshark, one pass)
SHOWN = {
    ("eclink_modbus_basic.pcap", 45): ["192.168.2.41:502", "Blocked", "Initial", "0x1234", "0"],
    ("eglink_states.pcap", 2): ["0x1001", "Stopped", "Stopped", "0xbeef", ""],
    ("eclink_pnio_connect.pcap", 31): ["0x8010", "Armed", "Enabled", "0x1234", "625"],
    ("mcmb2_duplex_watchdog.pcap", 23): ["0x8003", "", "", "", "1200"],
}


def columns_shown(inst, capture, frame):
    proc = inst.tshark(["-C", "vrshark", "-T", "tabs", "-n", "-r", str(CAPTURES / capture)])
    assert proc.returncode == 0, proc.stderr
    for line in proc.stdout.splitlines():
        cells = [c.strip() for c in line.split("\t")]
        if cells[0] == str(frame):
            return dict(zip(COLUMNS, cells))
    raise AssertionError("no frame %d in %s" % (frame, capture))


@pytest.mark.parametrize("installed", KINDS, indirect=True)
def test_frame_45_columns(installed):
    """The BU's input image on Modbus/TCP: its server, BU and RU state and
    armed RU in the columns (eclink_modbus_basic.pcap frame 45)."""
    row = columns_shown(installed, "eclink_modbus_basic.pcap", 45)
    assert [row[c] for c in ("Device", "BU state", "RU state", "Armed RU")] == [
        "192.168.2.41:502", "Blocked", "Initial", "0x1234"]


@pytest.mark.parametrize("installed", KINDS, indirect=True)
def test_every_protocol_shows_its_columns(installed):
    got = {}
    for (capture, frame), want in SHOWN.items():
        row = columns_shown(installed, capture, frame)
        got[(capture, frame)] = [row[c] for c in COLUMNS[4:9]]
    assert got == SHOWN
