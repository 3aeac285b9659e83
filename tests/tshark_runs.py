"""How the suite shares tshark runs: most of a test's time is tshark starting
(about 0.2 s of CPU for a capture of a few hundred frames), so a run is
made once and read by every test that asks for it.

- RunStore: the output of every cached run, on disk for the whole pytest
  session, shared by the xdist workers (the first asks tshark, the others
  wait for it and read its answer). A run's key is its arguments, its
  environment (but for the per-worker names of the hermetic configuration
  folder), the contents of that folder, the size and time of every file
  the arguments or environment name (a file written anew is a new run), and
  those of the plugins' own files.
- The union run: -T fields asks for the same capture and options many
  times with different -e lists. One run with every field the suite can ask
  for (union_fields(): every field of vrshark's protocols and every field
  name written in tests/) answers them all (conftest's Tshark.fields picks
  the columns): a field's -T fields value does not depend on the other -e
  fields (tests/test_sparse_view.py, tests/test_lua_fields_output.py and
  tests/test_eglink_sparse_view.py check that for every field, with narrow
  -e lists, against the full tree). A request on a capture over
  UNION_MAX_BYTES, naming a field outside the union, or with an occurrence
  other than f, l or a, runs as asked.

VRSHARK_TEST_EXACT_RUNS=1 turns both off: every request is its own run, as
written (to tell a sharing fault from a decoding one).
"""
import fcntl
import hashlib
import json
import os
import re
import subprocess
from pathlib import Path

TESTS = Path(__file__).resolve().parent
EXACT = bool(os.environ.get("VRSHARK_TEST_EXACT_RUNS"))
# The environment variable naming the session's store (set by conftest's
# pytest_configure in the controller, inherited by the xdist workers).
STORE_ENV = "VRSHARK_TEST_STORE"
# vrshark's protocols: all of their fields are in the union.
OUR_PROTOCOLS = ("eglink", "eclink", "eclink_modbus", "eclink_pnio", "mcmb2", "vrshark_io", "vrshark_pnio")
# Columns the default (hermetic) profile has, as -T fields names them.
COLUMNS = ("_ws.col.Protocol", "_ws.col.Info")
# Separator and aggregator of the union run: never in a value (tshark escapes
# tabs; the unit separator is what experts() already aggregates with).
SEP, AGG = "\t", "\x1f"
# The largest capture a union run answers for (see union_may_answer).
UNION_MAX_BYTES = 64 * 1024
# Environment variables that name folders but are no input of a run (the
# store itself, and the build tools/test checked before the session).
NOT_INPUTS = (STORE_ENV, "VRSHARK_PREPARED", "VRSHARK_BUILD_DIR")


def _stat(path):
    try:
        st = os.stat(path)
    except OSError:
        return None
    if os.path.isdir(path):
        entries = []
        for e in os.scandir(path):
            try:
                if e.is_file():
                    entries.append((e.name, e.stat().st_size, e.stat().st_mtime_ns))
            except OSError:     # (gone meanwhile)
                pass
        return ("dir", tuple(sorted(entries)))
    return (st.st_size, st.st_mtime_ns)


_PATHS = re.compile(r"(/[^:=,\s\"']+)")


def _files_named(text):
    """(path, stat) of each existing absolute path in text (an argument such
    as -r FILE or -X lua_script:FILE, or an environment value)."""
    out = []
    for p in _PATHS.findall(text):
        s = _stat(p)
        if s is not None and p != "/":
            out.append((p, s))
    return out


_code = None


def code_fingerprint():
    """The plugins a run loads, as their files' sizes and times (Lua plugins,
    the built C plugins): a store kept across sessions (VRSHARK_TEST_STORE
    given by hand) never answers for other code. Read once a process."""
    global _code
    if _code is None:
        root = TESTS.parent
        build = Path(os.environ.get("VRSHARK_BUILD_DIR") or root / "build")
        files = sorted(p for p in (root / "lua").rglob("*") if p.is_file())
        files += sorted(build.glob("wsplugins/*/epan/*.so"))
        _code = tuple((str(p), _stat(p)) for p in files)
    return _code


def run_key(args, env):
    """What makes two runs the same run (see the module comment)."""
    conf = env.get("WIRESHARK_CONFIG_DIR", "")
    envs = []
    for k, v in sorted(env.items()):
        if k.startswith("PYTEST_") or k == "WIRESHARK_CONFIG_DIR":
            continue
        envs.append((k, v, tuple(_files_named(v)) if k.startswith(("VRSHARK", "WIRESHARK"))
                     and k not in NOT_INPUTS else ()))
    files = [f for a in args for f in _files_named(a)]
    return repr((tuple(args), tuple(envs), _stat(conf) if conf else None, tuple(files), code_fingerprint()))


class RunStore:
    """Finished runs on disk, shared by the xdist workers of one session."""

    def __init__(self, folder):
        self.folder = Path(folder)

    @classmethod
    def of_session(cls):
        folder = os.environ.get(STORE_ENV)
        return cls(folder) if folder and not EXACT and os.path.isdir(folder) else None

    def get(self, key, make):
        """The stored answer of key, or make()'s (a CompletedProcess, stored).
        One worker makes it; another asking meanwhile waits for it."""
        name = hashlib.sha256(key.encode()).hexdigest()
        path = self.folder / (name + ".json")
        with open(self.folder / (name + ".lock"), "a") as lock:
            fcntl.flock(lock, fcntl.LOCK_EX)
            if path.exists():
                d = json.loads(path.read_text())
                return subprocess.CompletedProcess(d["args"], d["returncode"], d["stdout"], d["stderr"])
            proc = make()
            tmp = path.with_suffix(".tmp")
            tmp.write_text(json.dumps({"args": proc.args, "returncode": proc.returncode,
                                       "stdout": proc.stdout, "stderr": proc.stderr}))
            os.replace(tmp, path)
            return proc


_literal_names = None


def literal_field_names():
    """Every dotted name written as a string in tests/*.py (a superset of the
    fields the tests ask for by name)."""
    global _literal_names
    if _literal_names is None:
        names = set()
        for p in TESTS.glob("*.py"):
            names |= set(re.findall(r'["\']((?:_ws|[a-z][a-z0-9_]*)(?:\.[A-Za-z0-9_]+)+)["\']', p.read_text()))
        _literal_names = names
    return _literal_names


def union_fields(g_fields_text):
    """The union's field names, from tshark -G fields: every field of our
    protocols and every field name the tests write, in a fixed order."""
    literal = literal_field_names()
    names = set()
    for line in g_fields_text.splitlines():
        c = line.split("\t")
        if len(c) > 4 and c[0] == "F" and (c[4] in OUR_PROTOCOLS or c[2] in literal):
            names.add(c[2])
    return sorted(names) + [c for c in COLUMNS]


def pick(occurrences, occurrence, aggregator):
    """A -T fields cell as tshark prints it with -E occurrence/aggregator."""
    if occurrence == "a":
        return aggregator.join(occurrences)
    if not occurrences:
        return ""
    if occurrence == "f":
        return occurrences[0]
    return occurrences[-1]      # "l"


def union_may_answer(capture, occurrence):
    """Whether a union run is worth making for this request: a small capture
    (the union shows every field, which a decoder's full tree costs on each
    frame: on a large capture that outweighs the runs it saves) and an
    occurrence tshark takes (f, l or a; anything else fails there)."""
    if EXACT or occurrence not in ("a", "f", "l"):
        return False
    try:
        size = os.path.getsize(capture)
    except OSError:
        return False
    return size <= UNION_MAX_BYTES


def parse_table(stdout):
    """Union -T fields output: one list of cells a frame, each cell the list
    of its occurrences."""
    return [[cell.split(AGG) if cell else [] for cell in line.split(SEP)] for line in stdout.splitlines()]
