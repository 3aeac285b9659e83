"""`cmake --install` puts the plugins where Wireshark finds them: the C plugin
into the versioned personal plugin folder and the Lua plugins beside it, and a
plain tshark (not tools/tshark) then decodes our captures."""
import os
import shutil
import subprocess
import tempfile
from pathlib import Path

import pytest

from conftest import ROOT


@pytest.fixture(scope="module")
def installed_home():
    home = Path(tempfile.mkdtemp(prefix="vrshark-install-"))
    build = home / "build"
    env = dict(os.environ, HOME=str(home))
    for cmd in (["cmake", "-S", str(ROOT), "-B", str(build)],
                ["cmake", "--build", str(build), "-j", "2"],
                ["cmake", "--install", str(build)]):
        proc = subprocess.run(cmd, env=env, capture_output=True, text=True)
        assert proc.returncode == 0, proc.stdout + proc.stderr
    shutil.rmtree(build)
    if os.getuid() == 0:  # Wireshark ignores personal binary plugins for root
        subprocess.run(["chown", "-R", "65534:65534", str(home)], check=True)
    yield home
    shutil.rmtree(home, ignore_errors=True)


def plain_tshark(home, args):
    env = dict(os.environ, HOME=str(home), TZ="UTC")
    env.pop("WIRESHARK_PLUGIN_DIR", None)
    env["WIRESHARK_CONFIG_DIR"] = str(home / "config")
    cmd = ["tshark"] + args
    if os.getuid() == 0:
        cmd = ["setpriv", "--reuid=65534", "--regid=65534", "--clear-groups"] + cmd
    return subprocess.run(cmd, env=env, capture_output=True, text=True, cwd=str(home))


def test_install_layout(installed_home):
    plugins = installed_home / ".local" / "lib" / "wireshark" / "plugins"
    assert len(list(plugins.glob("*/epan/eglink.so"))) == 1
    lua = sorted(p.relative_to(plugins / "vrshark").as_posix()
                 for p in (plugins / "vrshark").rglob("*.lua"))
    assert lua == sorted(p.relative_to(ROOT / "lua").as_posix() for p in (ROOT / "lua").rglob("*.lua"))


def test_installed_plugins_decode(installed_home):
    out = plain_tshark(installed_home, ["-G", "plugins"]).stdout
    assert "eglink.so" in out
    assert "eclink_modbus.lua" in out and "mcmb2_pnio.lua" in out
    proc = plain_tshark(installed_home, ["-n", "-r", str(ROOT / "captures" / "eglink_armed.pcap"),
                                         "-c", "1", "-T", "fields", "-e", "eglink.type",
                                         "-e", "eglink.armed_ru", "-e", "eglink.crc.status"])
    assert proc.stdout.splitlines() == ["VRPI\t0xbeef\t1"], proc.stderr
