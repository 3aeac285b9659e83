"""Helpers of the tests/test_io_*.py tests: a tshark that loads the machine
descriptions of one folder (VRSHARK_IO_DIR)."""
import shutil

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
