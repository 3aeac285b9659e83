"""Helpers of the tests/test_io_*.py tests: a tshark that loads the machine
descriptions of one folder (VRSHARK_IO_DIR)."""
import shutil

import pytest

from conftest import ROOT, Tshark, _world_dir

CRANE_CSV = ROOT / "examples" / "crane" / "crane.csv"


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
