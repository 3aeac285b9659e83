"""Helpers of the tests/test_io_*.py tests: a tshark that loads the machine
descriptions of one folder (VRSHARK_IO_DIR)."""
import shutil

import pytest

from conftest import CAPTURES, ROOT, Tshark, _world_dir

CRANE_CSV = ROOT / "examples" / "crane" / "crane.csv"
# The names of the demo list's rows, and those of its ascii:N rows.
NAMES = [line.split(",")[4] for line in CRANE_CSV.read_text().splitlines()[1:]]
ASCII = {line.split(",")[4] for line in CRANE_CSV.read_text().splitlines()[1:] if ",ascii:" in line}


def io_tshark(conf_dir, folder):
    """tools/tshark with the descriptions of folder (a world-readable folder)."""
    t = Tshark(conf_dir)
    t.env["VRSHARK_IO_DIR"] = str(folder)
    return t


def write(folder, name, text):
    """A description file tshark (maybe running as nobody) can read."""
    path = folder / name
    path.write_text(text)
    path.chmod(0o644)
    return path


def crane_folder(folder):
    """folder with the demo crane's description in it."""
    shutil.copy(CRANE_CSV, folder / "crane.csv")
    (folder / "crane.csv").chmod(0o644)
    return folder


def world_folder():
    """An empty folder readable by the user tshark runs as."""
    return _world_dir("vrshark-io-", 0o755)


@pytest.fixture(scope="module")
def crane(conf_dir):
    """A tshark with the demo crane's description (import this fixture)."""
    folder = crane_folder(world_folder())
    yield io_tshark(conf_dir, folder)
    shutil.rmtree(folder, ignore_errors=True)


def expect_all(t, capture, expected, names, two_pass=False):
    """Every frame of expected {frame: {short name: value}}: those values, and
    the other fields of names absent."""
    for number, values in expected.items():
        want = {"vrshark.io." + k: v for k, v in values.items()}
        want.update({name: None for name in names if name not in want})
        t.expect(capture, number, want, two_pass=two_pass)


def assert_nothing_added(conf_dir, work_dir, captures):
    """With an empty description folder nothing of vrshark_io is shown, and
    the -V text is the same as with no folder at all."""
    empty = io_tshark(conf_dir, work_dir)
    missing = io_tshark(conf_dir, work_dir / "not-there")
    for name in captures:
        text = empty.verbose(CAPTURES / name)
        assert "vrshark_io" not in text and "Machine data" not in text, name
        assert text == missing.verbose(CAPTURES / name), name


def described(conf_dir, folder, name, rows):
    """A tshark with one description file made of rows (CSV lines, the header first)."""
    write(folder, name, "\n".join(rows) + "\n")
    return io_tshark(conf_dir, folder)


def problems(proc):
    """The description problems a tshark run printed (stderr lines 'vrshark-io: ...'), prefix cut."""
    return [ln[len("vrshark-io: "):] for ln in proc.stderr.splitlines() if ln.startswith("vrshark-io: ")]


def same(a, b):
    """Two {frame: {name: text}}: numbers compared as numbers (a double and a u8 print alike otherwise)."""
    assert sorted(a) == sorted(b)
    for n in a:
        assert sorted(a[n]) == sorted(b[n]), n
        for k in a[n]:
            if k in ASCII:
                assert a[n][k] == b[n][k], (n, k)
            else:
                assert float(a[n][k]) == float(b[n][k]), (n, k, a[n][k], b[n][k])
