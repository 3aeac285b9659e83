"""IO lists read again when dissection starts afresh (a capture opened or
reloaded), without a Lua reload (docs/io.md, "When a list changes"); the
filter `vrshark.io`; the demo list, left installed, touches no other
machine's capture.

tshark cannot reopen a capture, so the folder is changed between plugin
load (where the lists are read and the fields registered) and the capture's
opening (Proto.init, where they are read again) by a script run with
-X lua_script, which Wireshark loads after the plugins. The GUI's File >
Reload is tests/test_gui_io_reload.py."""
import copy

import pytest

from conftest import CAPTURES
from io_testlib import ASCII, CRANE_CSV, NAMES, crane, io_tshark, same, write  # noqa: F401 (crane is a fixture)

CAP = CAPTURES / "crane_eglink.pcap"

# Run inside tshark after the plugins loaded: the IO list folder becomes a
# copy of the folder VRSHARK_TEST_NEXT_IO.
SWAP = """
local io_dir, next_dir = os.getenv("VRSHARK_IO_DIR"), os.getenv("VRSHARK_TEST_NEXT_IO")
local old = {}
for name in Dir.open(io_dir, ".csv") do old[#old + 1] = name end
for _, name in ipairs(old) do assert(os.remove(io_dir .. "/" .. name)) end
for name in Dir.open(next_dir, ".csv") do
    local src = assert(io.open(next_dir .. "/" .. name, "rb"))
    local text = src:read("*a")
    src:close()
    local dst = assert(io.open(io_dir .. "/" .. name, "wb"))
    dst:write(text)
    dst:close()
end
"""


class Swap:
    """A tshark whose IO list folder holds the files of .start at start-up
    and those of .later when the capture opens."""

    def __init__(self, conf_dir, work_dir):
        self.start, self.later = work_dir / "io", work_dir / "later"
        for f in (self.start, self.later):
            f.mkdir()
            f.chmod(0o777)
        self.script = write(work_dir, "swap.lua", SWAP)
        self.t = io_tshark(conf_dir, self.start)
        self.t.env["VRSHARK_TEST_NEXT_IO"] = str(self.later)
        self.at_start = {}   # file name -> text

    def run(self, args, capture=CAP, lua_only=False):
        for old in self.start.glob("*.csv"):
            old.unlink()
        for name, text in self.at_start.items():
            write(self.start, name, text).chmod(0o666)
        t = variant(self.t, lua_only)
        return t.run(["-n", "-2", "-r", str(capture), "-X", "lua_script:%s" % self.script] + args, cache=False)


@pytest.fixture
def swap(conf_dir, work_dir):
    return Swap(conf_dir, work_dir)


def variant(t, lua_only):
    """t, or a copy of it without the C plugin (its own run cache)."""
    if not lua_only:
        return t
    other = copy.copy(t)
    other.env = dict(t.env, VRSHARK_NO_C_PLUGIN="1")
    other._cache = {}
    return other


def generic_values(swap, capture=CAP, lua_only=False):
    """{frame: {name: value text}} from the generic fields (vrshark_io.name,
    .value, .text; values in tree order)."""
    out = swap.run(["-T", "fields", "-e", "frame.number", "-e", "vrshark_io.name", "-e", "vrshark_io.value",
                    "-e", "vrshark_io.text", "-E", "aggregator=\x1f"], capture, lua_only).stdout
    frames = {}
    for line in out.splitlines():
        number, names, values, texts = (line.split("\t") + ["", "", ""])[:4]
        values, texts = [v for v in values.split("\x1f") if v], [v for v in texts.split("\x1f") if v]
        got = {}
        for name in [n for n in names.split("\x1f") if n]:
            got[name] = texts.pop(0) if name in ASCII else values.pop(0)
        assert not values and not texts, line
        if got:
            frames[int(number)] = got
    return frames


def typed_values(t, capture=CAP):
    """{frame: {name: value text}} from the typed fields vrshark.io.<name> (the list present at start-up)."""
    frames = t.frames(capture, ["vrshark.io." + n for n in NAMES], two_pass=True)
    return {n: {k[len("vrshark.io."):]: v for k, v in f.items() if v} for n, f in frames.items()
            if any(f.values())}


@pytest.mark.parametrize("lua_only", [False, True], ids=["c", "lua-only"])
def test_list_added_after_startup_is_read_at_capture_open(swap, crane, lua_only):
    """No list at start-up, the demo list in the folder when the capture
    opens: every row named with the generic fields, the same values as the
    typed fields of a start with the list; labels, faults and Info as the
    list says. Without the C plugin: the MC-MB2-PN capture."""
    write(swap.later, "crane.csv", CRANE_CSV.read_text())
    capture = CAPTURES / ("crane_mcmb2.pcap" if lua_only else "crane_eglink.pcap")
    got = generic_values(swap, capture, lua_only)
    want = typed_values(variant(crane, lua_only), capture)
    assert want and len(want) >= 8
    same(got, want)
    marked = swap.run(["-Y", "vrshark.io", "-T", "fields", "-e", "frame.number"], capture, lua_only).stdout
    assert [int(n) for n in marked.split()] == sorted(got)
    proc = swap.run(["-V"], capture, lua_only)
    assert "IO lists read again" in proc.stderr
    text = proc.stdout
    if lua_only:
        assert "Speed range: High (2)" in text and "Message to the operator: Wind alarm (2)" in text
        assert "Hoist joystick (%): -50 (raw -500)" in text and "Message text: WIND 21 M/S " in text
        return
    for line in ("Load on the hook (t): 52.3 (raw 5230)", "Overload: Yes (1)", "Hoist mode: Holding (3)",
                 "Wind speed (m/s): 12.75", "Status text: OVERLOAD", "Horn button: Pressed (1)",
                 "Speed range: High (2)", "Message to the operator: Wind alarm (2)"):
        assert line in text, line
    info = dict(r.split("\t") for r in swap.run(["-T", "fields", "-e", "frame.number", "-e",
                                                 "_ws.col.Info"]).stdout.splitlines())
    assert info["10"].endswith("[overload]") and info["15"].endswith("[wind_alarm]")
    experts = swap.run(["-Y", "vrshark_io.fault.error", "-T", "fields", "-e", "frame.number"]).stdout.split()
    assert experts == ["10", "13"]


def test_changed_row_keeps_the_others_typed(swap):
    """A row whose label changed and a new row are shown with the generic
    fields under their new label; every unchanged row keeps its typed field."""
    swap.at_start["crane.csv"] = CRANE_CSV.read_text()
    text = CRANE_CSV.read_text().replace(",horn,Horn button,", ",horn,Horn,")
    write(swap.later, "crane.csv", text + "cmd.from_ru,7,,u8,spare,Spare byte,,,,,,,origin=0x2C01\n")
    row = swap.run(["-Y", "frame.number == 8", "-T", "fields", "-e", "vrshark.io.horn", "-e", "vrshark.io.start",
                    "-e", "vrshark.io.operator_id", "-e", "vrshark_io.name",
                    "-e", "vrshark_io.value"]).stdout.rstrip("\n").split("\t")
    assert row[0] == "" and row[1] in ("0", "False") and row[2] == "7"
    assert row[3] == "horn,spare" and row[4] == "1,0"
    tree = swap.run(["-Y", "frame.number == 8", "-V"]).stdout
    assert "Horn: Pressed (1)" in tree and "Spare byte: 0" in tree and "Horn button" not in tree
    assert ".... ..0. = Start button: Released" in tree


def test_list_removed_after_startup_decodes_as_without(swap):
    """The list removed before the capture opens: the decode is that of a
    start without any list (EG-Link hooks taken out of eglink.data too)."""
    swap.at_start["crane.csv"] = CRANE_CSV.read_text()
    removed = swap.run(["-V"]).stdout
    swap.at_start = {}
    assert removed == swap.run(["-V"]).stdout
    assert "Machine data" not in removed and "vrshark_io" not in removed


def test_unchanged_folder_is_not_parsed_again(swap):
    swap.at_start["crane.csv"] = CRANE_CSV.read_text()
    write(swap.later, "crane.csv", CRANE_CSV.read_text())
    proc = swap.run(["-Y", "frame.number == 8", "-T", "fields", "-e", "vrshark.io.horn"])
    assert proc.stdout.strip() in ("1", "True") and "read again" not in proc.stderr


def test_vrshark_io_filter(crane, tshark):
    """`vrshark.io` (the list's file name, hidden) is in every frame the IO
    list named data in, and in no other; accepted without any list."""
    for two_pass in (False, True):
        frames = crane.frames(CAP, ["vrshark.io"] + ["vrshark.io." + n for n in NAMES], two_pass=two_pass)
        named = sorted(n for n, f in frames.items() if any(v for k, v in f.items() if k != "vrshark.io"))
        assert named == sorted(n for n, f in frames.items() if f["vrshark.io"] == "crane.csv")
        assert crane.field(CAP, "frame.number", display_filter="vrshark.io", two_pass=two_pass) == \
            [str(n) for n in named]
        # frame 1 (the controller's, before any packet of the BU) only once the BU is known (-2)
        assert named == [1] * two_pass + [2, 4, 5, 7, 8, 10, 11, 13, 15, 16]
    assert tshark.field(CAP, "frame.number", display_filter="vrshark.io") == []


NOT_CRANE = sorted(p.name for p in CAPTURES.glob("*.pcap") if not p.name.startswith("crane_"))


@pytest.mark.parametrize("lua_only", [False, True], ids=["c", "lua-only"])
def test_demo_list_names_no_other_machine(crane, merged_captures, lua_only):
    """The demo list is limited to the demo crane's devices (its device
    column): left installed, it names nothing in any other capture (all of
    them one after the other in one file), one pass and -2, with the C plugin
    and without."""
    t = variant(crane, lua_only)
    merged = merged_captures(NOT_CRANE)
    for two in ([], ["-2"]):
        proc = t.run(["-n", "-r", str(merged.path), "-Y", "vrshark_io || vrshark.io", "-T", "fields",
                      "-e", "frame.number", "-e", "_ws.expert.message"] + two, cache=False)
        assert proc.stdout == "", [merged.capture_of(int(line.split()[0])) for line in proc.stdout.splitlines()][:20]
        assert "vrshark-io:" not in proc.stderr, proc.stderr
