"""Fixtures for running tshark with the vrshark plugins, after Wireshark's
test/fixtures_ws.py: a tshark command, capture paths, a hermetic configuration
folder, TZ=UTC, and helpers for -T fields / -T json / expert-info assertions.

Every run goes through tools/tshark, so the freshly built C plugin and the Lua
plugins of this checkout are the ones tested. Runs are cached per session by
their arguments: many tests look at the same capture.
"""
import copy
import json
import os
import re
import shutil
import struct
import subprocess
import tempfile
from pathlib import Path

import pytest

import tshark_runs

ROOT = Path(__file__).resolve().parent.parent
# The build tools/tshark uses (tools/matrix gives each Wireshark version its own).
BUILD = Path(os.environ.get("VRSHARK_BUILD_DIR") or ROOT / "build").resolve()
CAPTURES = ROOT / "captures"
SHARED = ROOT.parent / "shared"
PUBLIC_CAPTURES = SHARED / "captures" / "public"

# Text that must never appear in tshark's output for our captures.
FORBIDDEN = ("Lua Error", "Lua: Error during loading", "Dissector bug", "dissector bug",
             "[Malformed Packet: eglink]")


def _world_dir(prefix, mode=0o755):
    """A temporary folder tshark can use when tools/tshark drops root to nobody."""
    path = Path(tempfile.mkdtemp(prefix=prefix))
    path.chmod(mode)
    return path


# Wireshark 4.2 and later print a boolean field as True/False in -T fields and
# -T json, 4.0 as 1/0; the fixture gives 1/0 on every version.
_BOOL_TEXT = {"True": "1", "False": "0"}


def _bool_as_number(cell, aggregator):
    if aggregator and aggregator in cell:
        return aggregator.join(_BOOL_TEXT.get(v, v) for v in cell.split(aggregator))
    return _BOOL_TEXT.get(cell, cell)


def _json_bools_as_numbers(value):
    if isinstance(value, dict):
        return {k: _json_bools_as_numbers(v) for k, v in value.items()}
    if isinstance(value, list):
        return [_json_bools_as_numbers(v) for v in value]
    if isinstance(value, str):
        return _BOOL_TEXT.get(value, value)
    return value


# tshark -G fields' union of fields, per way of running tshark (Tshark.union_fields).
_UNION = {}


class Tshark:
    """tools/tshark with a hermetic environment, and ways to read its output."""

    def __init__(self, conf_dir):
        self.cmd = str(ROOT / "tools" / "tshark")
        self.env = dict(os.environ)
        self.env.update({
            "TZ": "UTC",
            "LC_ALL": "C.UTF-8",
            "WIRESHARK_CONFIG_DIR": str(conf_dir),
        })
        self._cache = {}

    @staticmethod
    def _opts(prefs=None, decode_as=None, two_pass=False, display_filter=None, extra=None):
        args = []
        if two_pass:
            args.append("-2")
        for name, value in sorted((prefs or {}).items()):
            args += ["-o", "%s:%s" % (name, value)]
        for rule in decode_as or ():
            args += ["-d", rule]
        if display_filter:
            args += ["-Y", display_filter]
        args += list(extra or ())
        return args

    def run(self, args, check=True, allow_errors=False, cache=True):
        """Run tools/tshark ARGS; returns the CompletedProcess (text mode).
        Cached runs are shared by every test of the session (tshark_runs).

        Unless allow_errors, a "Lua Error" or dissector bug in the output fails the test.
        """
        key = tuple(args)
        if cache and key in self._cache:
            proc = self._cache[key]
        else:
            def make():
                return subprocess.run([self.cmd] + list(args), env=self.env, capture_output=True,
                                      text=True, errors="replace", timeout=600)
            store = tshark_runs.RunStore.of_session() if cache else None
            proc = store.get(tshark_runs.run_key(args, self.env), make) if store else make()
            if cache:
                self._cache[key] = proc
        if check and proc.returncode != 0:
            raise AssertionError("tshark %s failed (%d):\n%s" % (" ".join(args), proc.returncode,
                                                                 proc.stderr[-4000:]))
        if not allow_errors:
            for bad in FORBIDDEN:
                assert bad not in proc.stdout and bad not in proc.stderr, \
                    "%r in the output of tshark %s" % (bad, " ".join(args))
        return proc

    def union_fields(self):
        """The fields of the union run (tshark_runs.union_fields), for this
        tshark's plugins (with or without the C plugin, the build dir)."""
        mode = tuple(self.env.get(k, "") for k in ("VRSHARK_NO_C_PLUGIN", "VRSHARK_BUILD_DIR", "TSHARK"))
        if mode not in _UNION:
            proc = self.run(["-G", "fields"], allow_errors=True)   # lists the field "Lua Error"
            names = tshark_runs.union_fields(proc.stdout) if proc.returncode == 0 else []
            _UNION[mode] = (names, set(names))
        return _UNION[mode]

    def _field_table(self, base):
        """The union run of base (-n -r CAPTURE OPTIONS -T fields): ({field:
        column}, rows of cells), or None where it cannot answer (it failed)."""
        names, _ = self.union_fields()
        if not names:
            return None
        args = list(base)
        for n in names:
            args += ["-e", n]
        args += ["-E", "separator=" + tshark_runs.SEP, "-E", "occurrence=a", "-E", "aggregator=" + tshark_runs.AGG]
        proc = self.run(args, check=False)
        if proc.returncode != 0:
            return None
        return {n: i for i, n in enumerate(names)}, tshark_runs.parse_table(proc.stdout)

    def fields(self, capture, fields, sep="\t", occurrence="a", aggregator=",", **kw):
        """Rows of -T fields output, one list of strings per displayed frame."""
        base = ["-n", "-r", str(capture)] + self._opts(**kw) + ["-T", "fields"]
        if fields and tshark_runs.union_may_answer(capture, occurrence):
            _, names = self.union_fields()
            if all(f in names for f in fields):
                table = self._field_table(base)
                if table is not None:
                    index, rows = table
                    cols = [index[f] for f in fields]
                    return [[_bool_as_number(tshark_runs.pick(cells[i], occurrence, aggregator), aggregator)
                             for i in cols] for cells in rows]
        args = list(base)
        for f in fields:
            args += ["-e", f]
        args += ["-E", "separator=" + sep, "-E", "occurrence=" + occurrence,
                 "-E", "aggregator=" + aggregator]
        out = self.run(args).stdout
        return [[_bool_as_number(cell, aggregator) for cell in line.split(sep)]
                for line in out.splitlines()]

    def field(self, capture, name, **kw):
        """One field's value per displayed frame (joined with ',' if repeated)."""
        return [row[0] for row in self.fields(capture, [name], **kw)]

    def json(self, capture, fields=None, **kw):
        """-T json output (with --no-duplicate-keys: repeated fields become lists)."""
        args = ["-n", "-r", str(capture)] + self._opts(**kw) + ["-T", "json", "--no-duplicate-keys"]
        for f in fields or ():
            args += ["-e", f]
        return _json_bools_as_numbers(json.loads(self.run(args).stdout or "[]"))

    def experts(self, capture, **kw):
        """{frame number: [expert messages]} for every frame that has expert info."""
        rows = self.fields(capture, ["frame.number", "_ws.expert.message"], aggregator="\x1f", **kw)
        return {int(r[0]): r[1].split("\x1f") for r in rows if len(r) > 1 and r[1]}

    def frames(self, capture, names, **kw):
        """{frame number: {field name: text}} of the displayed frames, for the
        given fields (an absent field reads ""; repeats are joined with ",")."""
        rows = self.fields(capture, ["frame.number"] + list(names), **kw)
        return {int(r[0]): dict(zip(names, r[1:] + [""] * (len(names) + 1 - len(r))))
                for r in rows}

    def frame(self, capture, number, names, **kw):
        """{field name: text} of one frame (see frames())."""
        got = self.frames(capture, names, **kw)
        assert number in got, "frame %d is not displayed (%s)" % (number, capture)
        return got[number]

    def expect(self, capture, number, expected, **kw):
        """Assert the fields of one frame by name: expect(cap, 5, {"eclink.pci": 11,
        "eclink.image": "input", "eclink.cut": None}). See same_value() for how
        an expected value is compared; a failure lists every field that differs."""
        assert_fields(self.frame(capture, number, list(expected), **kw), expected,
                      "frame %d of %s" % (number, Path(capture).name))

    def verbose(self, capture, **kw):
        """The -V text of all displayed frames."""
        return self.run(["-n", "-r", str(capture)] + self._opts(**kw) + ["-V"]).stdout


def expert_infos(packets):
    """The expert infos of -T json packets (Tshark.json()), in tree order:
    [(frame, expert field name, severity, group, message, the field it hangs
    on or None)]; severity and group as the numbers tshark prints."""
    out = []

    def walk(node, frame, parent):
        if isinstance(node, list):
            for item in node:
                walk(item, frame, parent)
        elif isinstance(node, dict):
            for key, value in node.items():
                if key == "_ws.expert":
                    for e in value if isinstance(value, list) else [value]:
                        names = [k for k in e if not k.startswith("_ws.expert")]
                        if names:
                            out.append((frame, names[0], e["_ws.expert.severity"], e["_ws.expert.group"],
                                        e["_ws.expert.message"], parent))
                else:
                    walk(value, frame, key[:-5] if key.endswith("_tree") else parent)

    for pkt in packets:
        layers = pkt["_source"]["layers"]
        walk(layers, int(layers["frame"]["frame.number"]), None)
    return out


PROFILE_DIR = ROOT / "profile" / "vrshark"


def profile_rules():
    """[(rule name, display filter)] of the vrshark profile's colouring rules, in
    order (the first that matches colours a row)."""
    return [tuple(line[1:].split("@", 2)[:2]) for line in (PROFILE_DIR / "colorfilters").read_text().splitlines()
            if line.startswith("@")]


def uat_buttons(path):
    """[(label, display filter)] of a dfilter_buttons file, in order (the
    escapes \\xNN of Wireshark's UAT files read as the characters)."""
    found = re.findall(r'^"TRUE","([^"]+)","([^"]+)"', Path(path).read_text(), re.M)
    unesc = lambda text: re.sub(r"\\x([0-9a-fA-F]{2})", lambda m: chr(int(m.group(1), 16)), text)  # noqa: E731
    return [(unesc(label), unesc(expr)) for label, expr in found]


def profile_buttons():
    """[(label, display filter)] of the vrshark profile's filter buttons, in order."""
    return uat_buttons(PROFILE_DIR / "dfilter_buttons")


def profile_column_widths():
    """[(column key as Wireshark writes it, width in pixels)] of profile/vrshark/recent."""
    recent = (PROFILE_DIR / "recent").read_text()
    return [(k, int(w)) for k, w in re.findall(r'^\t("[^"]+"|%\w+), (\d+)', recent, re.M)]


def same_value(text, want):
    """Does a -T fields cell match an expected value?
    None: the field is absent; True/False: 1/0; int: the number, whatever the
    base the field prints in (0x11 == 17); float: within 1e-6; list: the
    repeated values in order; str: the exact text."""
    if want is None:
        return text == ""
    if isinstance(want, bool):
        return text == ("1" if want else "0")
    if isinstance(want, int):
        try:
            return int(text, 0) == want
        except ValueError:
            return False
    if isinstance(want, float):
        try:
            return abs(float(text) - want) < 1e-6
        except ValueError:
            return False
    if isinstance(want, (list, tuple)):
        parts = text.split(",") if text else []
        return len(parts) == len(want) and all(same_value(p, w) for p, w in zip(parts, want))
    return text == want


def assert_fields(got, expected, where=""):
    """Assert {field: value} by name; the message names each field that differs."""
    wrong = ["  %s: got %r, want %r" % (k, got.get(k), v) for k, v in expected.items()
             if not same_value(got.get(k, ""), v)]
    assert not wrong, "fields differ%s:\n%s" % (" in " + where if where else "", "\n".join(wrong))


def pytest_configure(config):
    """Once a session, in the controller (xdist workers inherit its
    environment): build the plugin and lay out both plugin folders, so that
    tools/tshark need not check them before every run (VRSHARK_PREPARED), and
    make the store of shared runs (tshark_runs.RunStore) unless the caller
    gives one (VRSHARK_TEST_STORE: tools/test, for both of its phases)."""
    if os.environ.get("PYTEST_XDIST_WORKER"):
        return
    subprocess.run([str(ROOT / "tools" / "build"), "--quiet", str(BUILD)], check=True,
                   env=dict(os.environ, VRSHARK_NO_C_PLUGIN="1"))
    subprocess.run([str(ROOT / "tools" / "reachable")], check=True)
    os.environ["VRSHARK_PREPARED"] = str(BUILD)
    # (tools/test makes one store for both of its phases)
    if not os.path.isdir(os.environ.get(tshark_runs.STORE_ENV, "")):
        config.vrshark_store = tempfile.mkdtemp(prefix="vrshark-runs-")
        os.environ[tshark_runs.STORE_ENV] = config.vrshark_store


def pytest_unconfigure(config):
    store = getattr(config, "vrshark_store", None)
    if store:
        shutil.rmtree(store, ignore_errors=True)


@pytest.fixture(scope="session")
def conf_dir():
    """A hermetic, empty Wireshark configuration folder (readable by nobody)."""
    path = _world_dir("vrshark-conf-")
    yield path
    shutil.rmtree(path, ignore_errors=True)


@pytest.fixture(scope="session")
def tshark(conf_dir):
    return Tshark(conf_dir)


@pytest.fixture
def keeping_tshark(tshark, work_dir):
    """A Tshark that runs the system tshark under another program name: one
    pass, with every per-frame record kept as in Wireshark (lua/vrshark/
    passes.luam: only a process named tshark without -2 keeps none)."""
    link = work_dir / "vrshark-keeps"
    os.symlink(shutil.which(os.environ.get("TSHARK", "tshark")), link)
    keeping = copy.copy(tshark)
    keeping.env = dict(tshark.env, TSHARK=str(link))
    keeping._cache = {}
    return keeping


@pytest.fixture(scope="session")
def capture_file():
    """capture_file("name.pcap") -> path of a committed capture under captures/."""
    def resolve(name):
        path = CAPTURES / name
        assert path.exists(), "missing capture %s (run tools/gen-captures)" % name
        return path
    return resolve


def pcap_frame_count(path):
    """The number of records of a pcap file (little- or big-endian, micro- or
    nanosecond timestamps)."""
    data = Path(path).read_bytes()
    order = "<" if data[:4] in (b"\xd4\xc3\xb2\xa1", b"\x4d\x3c\xb2\xa1") else ">"
    count, at = 0, 24
    while at + 16 <= len(data):
        at += 16 + struct.unpack(order + "I", data[at + 8:at + 12])[0]
        count += 1
    return count


class Merged:
    """Captures one after the other in one file (mergecap -a): one tshark run
    covers them all where a test compares two ways of running tshark on each
    frame (tshark's start-up is most of a run's time). .path, and .capture_of(
    frame number) names the capture a frame of the merged file comes from."""

    def __init__(self, folder, names):
        self.names = list(names)
        self.path = folder / ("merged-%d.pcap" % abs(hash(tuple(self.names))))
        subprocess.run(["mergecap", "-a", "-F", "pcap", "-w", str(self.path)] + [str(CAPTURES / n) for n in names],
                       check=True)
        self.path.chmod(0o644)
        self.ends, end = [], 0
        for n in self.names:
            end += pcap_frame_count(CAPTURES / n)
            self.ends.append(end)

    def capture_of(self, frame):
        for name, end in zip(self.names, self.ends):
            if frame <= end:
                return "%s frame %d" % (name, frame - (end - pcap_frame_count(CAPTURES / name)))
        return "beyond the merged captures"

    def first_difference(self, got, want):
        """Where two outputs of the merged file first differ: the line, and the
        capture its frame comes from (a packet-list line starts with it)."""
        a, b = got.splitlines(), want.splitlines()
        for i, (x, y) in enumerate(zip(a, b)):
            if x != y:
                words = x.split()
                where = self.capture_of(int(words[0])) if words and words[0].isdigit() else "line %d" % (i + 1)
                return "%s:\n  got  %r\n  want %r" % (where, x, y)
        return "line counts %d and %d" % (len(a), len(b))


@pytest.fixture(scope="session")
def merged_captures():
    """merged_captures([names under captures/]) -> a Merged file of them
    (one per list and session)."""
    folder = _world_dir("vrshark-merged-")
    made = {}

    def merge(names):
        key = tuple(names)
        if key not in made:
            made[key] = Merged(folder, key)
        return made[key]
    yield merge
    shutil.rmtree(folder, ignore_errors=True)


@pytest.fixture(scope="session")
def public_capture():
    """public_capture("name") -> path under ../shared/captures/public; skips if absent."""
    def resolve(name):
        path = PUBLIC_CAPTURES / name
        if not path.exists():
            pytest.skip("../shared/captures/public is not here")
        return path
    return resolve


@pytest.fixture
def work_dir():
    """A scratch folder tshark (maybe running as nobody) can read and write."""
    path = _world_dir("vrshark-work-", 0o777)
    yield path
    shutil.rmtree(path, ignore_errors=True)


@pytest.fixture
def lua_probe(tshark, work_dir):
    """lua_probe(script) -> the lines a Lua script run inside tshark (-X
    lua_script, over one frame) wrote to the file named by %(out)r; %(lua)r
    names lua/, for the script's package.path. capture and args: another
    capture, and tshark arguments instead of -q -c 1."""
    def run(script, capture=None, args=("-q", "-c", "1")):
        out = work_dir / "probe.txt"
        out.touch()
        out.chmod(0o666)
        path = work_dir / "probe.lua"
        path.write_text(script % {"lua": str(ROOT / "lua"), "out": str(out)})
        path.chmod(0o644)
        proc = subprocess.run([tshark.cmd, "-n", "-r", str(capture or CAPTURES / "eclink_pnio_connect.pcap")]
                              + list(args) + ["-X", "lua_script:%s" % path], env=tshark.env, capture_output=True,
                              text=True, timeout=300)
        assert proc.returncode == 0, proc.stderr
        assert "Lua Error" not in proc.stdout + proc.stderr
        return out.read_text().splitlines()
    return run
