"""tools/package: the Lua-only install as one archive for any OS
(docs/install.md). It holds the Lua plugins, the profile with Wireshark's
default colouring rules after ours, the IO-list folder and vrshark-report;
unpacked into a fresh home on Linux by the commands of its INSTALL.txt, the
system tshark (as a user, no WIRESHARK_PLUGIN_DIR) decodes every protocol
with the profile."""
import shutil
import subprocess
import tarfile
import tempfile
import textwrap
import zipfile
from pathlib import Path

import pytest

from conftest import CAPTURES, ROOT
from installed_testlib import Installed

CRANE_CSV = ROOT / "examples" / "crane" / "crane.csv"


@pytest.fixture(scope="module")
def archives():
    out = Path(tempfile.mkdtemp(prefix="vrshark-package-"))
    proc = subprocess.run([str(ROOT / "tools" / "package"), "-o", str(out)], capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    paths = [Path(p) for p in proc.stdout.split()]
    assert [p.name for p in paths] == ["vrshark-0.1.0.zip", "vrshark-0.1.0.tar.gz"]
    yield paths
    shutil.rmtree(out, ignore_errors=True)


@pytest.fixture(scope="module")
def installed():
    inst = Installed("archive")
    inst.add_io_list(CRANE_CSV)
    yield inst
    inst.remove()


def test_archive_contents(archives):
    zipped, tarred = archives
    with zipfile.ZipFile(zipped) as z:
        names = z.namelist()
        modes = {i.filename: i.external_attr >> 16 for i in z.infolist()}
    with tarfile.open(tarred) as t:
        assert sorted(m.name for m in t.getmembers()) == sorted(names)
    top = "vrshark-0.1.0/"
    assert all(n.startswith(top) for n in names)
    names = {n[len(top):] for n in names}
    lua = {"wireshark/plugins/vrshark/" + p.relative_to(ROOT / "lua").as_posix()
           for p in (ROOT / "lua").rglob("*") if p.suffix in (".lua", ".luam")}
    assert lua and lua <= names
    assert {"wireshark/plugins/vrshark/vrshark_io.lua", "wireshark/plugins/vrshark/vrshark/version.luam"} <= lua
    report = {"vrshark-report/report/" + p.name for p in (ROOT / "tools" / "report").iterdir()
              if p.suffix == ".py" or p.name.startswith("plotly-basic.")}
    profile = {"wireshark/profiles/vrshark/" + n for n in ("colorfilters", "dfilter_buttons", "preferences", "recent")}
    assert names == lua | report | profile | {"INSTALL.txt", "wireshark/vrshark-io/README.txt",
                                               "vrshark-report/vrshark-report"}
    assert modes[top + "vrshark-report/vrshark-report"] & 0o777 == 0o755


def test_install_txt_names_the_folders_of_each_os(archives):
    with zipfile.ZipFile(archives[0]) as z:
        text = z.read("vrshark-0.1.0/INSTALL.txt").decode()
    for words in ('xcopy /e /i /y wireshark "%APPDATA%\\Wireshark"', "~/.local/lib/wireshark/plugins/",
                  "~/.config/wireshark/", "Help > About Wireshark > Folders", "python3 vrshark-report/vrshark-report"):
        assert words in text, words
    # docs/install.md gives the same commands
    doc = (ROOT / "docs" / "install.md").read_text().split("## The archive", 1)[1].split("\n## ", 1)[0]
    linux = text.split("Linux and macOS", 1)[1].split("\n\n")[1]
    assert textwrap.dedent(linux).strip() in doc
    windows = [ln.strip() for ln in text.splitlines() if ln.strip().startswith("xcopy ")]
    assert len(windows) == 1 and windows[0] in doc


def test_installed_where_install_txt_says(installed):
    plugins = installed.home / ".local" / "lib" / "wireshark" / "plugins" / "vrshark"
    assert (plugins / "mcmb2.lua").is_file() and (plugins / "vrshark" / "version.luam").is_file()
    assert (installed.config / "profiles" / "vrshark" / "preferences").is_file()
    assert (installed.config / "vrshark-io" / "README.txt").is_file()


# capture, frame -> the Protocol column and one key field of the protocol there
DECODED = {
    "eclink_modbus_basic.pcap": (45, "Modbus/TCP", "eclink.bu_state", "0x03"),
    "eclink_pnio_connect.pcap": (31, "EC-Link", "eclink.ru_state", "3"),
    "mcmb2_duplex_connect.pcap": (10, "MC-MB2", "mcmb2.system", "duplex"),
    "mcmb2_polled_connect.pcap": (13, "MC-MB2", "mcmb2.system", "polled"),
    "eglink_armed.pcap": (1, "EG-Link", "eglink.armed_ru", "0xbeef"),
}


@pytest.mark.parametrize("capture", sorted(DECODED))
def test_every_protocol_decoded_with_the_profile(installed, capture):
    frame, protocol, field, value = DECODED[capture]
    proc = installed.tshark(["-C", "vrshark", "-n", "-r", str(CAPTURES / capture), "-Y", "frame.number == %d" % frame,
                             "-T", "fields", "-e", "_ws.col.Protocol", "-e", field])
    assert proc.returncode == 0, proc.stderr
    assert "Lua Error" not in proc.stdout + proc.stderr
    assert proc.stdout.splitlines() == ["%s\t%s" % (protocol, value)], proc.stderr


def test_machine_data_from_the_io_folder(installed):
    """The IO-list folder of the archive is where the plugins read the lists."""
    proc = installed.tshark(["-C", "vrshark", "-n", "-r", str(CAPTURES / "crane_mcmb2.pcap"), "-Y", "vrshark_io",
                             "-T", "fields", "-e", "frame.number"])
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.split(), proc.stderr


def test_report_from_the_archive(installed):
    """vrshark-report as unpacked runs the tshark on PATH with the installed plugins."""
    report = installed.archive_folder / "vrshark-report" / "vrshark-report"
    shutil.copy(CAPTURES / "eclink_modbus_basic.pcap", installed.home / "capture.pcap")
    subprocess.run(["chown", "-R", "--reference", str(installed.home), str(installed.home / "capture.pcap")],
                   check=True)
    proc = subprocess.run(installed.command("python3", [str(report), "capture.pcap"]), env=installed.env(),
                          capture_output=True, text=True, cwd=str(installed.home))
    assert proc.returncode in (0, 1), proc.stderr
    assert "192.168.2.41" in proc.stdout, proc.stdout + proc.stderr
