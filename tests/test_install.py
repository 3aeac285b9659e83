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
        if cmd[1] == "--install":
            # an install over an earlier one, whose library was eglink.so
            version = next((build / "wsplugins").glob("*/epan")).parent.name
            old = home / ".local/lib/wireshark/plugins" / version / "epan" / "eglink.so"
            old.parent.mkdir(parents=True)
            old.write_bytes(b"an earlier build")
        proc = subprocess.run(cmd, env=env, capture_output=True, text=True)
        assert proc.returncode == 0, proc.stdout + proc.stderr
    shutil.rmtree(build)
    if os.getuid() == 0:  # Wireshark ignores personal binary plugins for root
        subprocess.run(["chown", "-R", "65534:65534", str(home)], check=True)
    yield home
    shutil.rmtree(home, ignore_errors=True)


def plain_tshark(home, args, personal_config=False):
    """tshark as installed; personal_config: with the configuration under
    ~/.config/wireshark (where the profile is installed) instead of an empty one."""
    env = dict(os.environ, HOME=str(home), TZ="UTC")
    env.pop("WIRESHARK_PLUGIN_DIR", None)
    env["WIRESHARK_CONFIG_DIR"] = str(home / (".config/wireshark" if personal_config else "config"))
    cmd = ["tshark"] + args
    if os.getuid() == 0:
        cmd = ["setpriv", "--reuid=65534", "--regid=65534", "--clear-groups"] + cmd
    return subprocess.run(cmd, env=env, capture_output=True, text=True, cwd=str(home))


def test_install_layout(installed_home):
    plugins = installed_home / ".local" / "lib" / "wireshark" / "plugins"
    assert len(list(plugins.glob("*/epan/vrshark.so"))) == 1
    # the earlier build's library is gone: Wireshark would load both
    assert list(plugins.glob("*/epan/eglink.so")) == []
    def lua_tree(top):
        return sorted(p.relative_to(top).as_posix() for p in top.rglob("*") if p.suffix in (".lua", ".luam"))
    assert lua_tree(plugins / "vrshark") == lua_tree(ROOT / "lua")
    assert "vrshark/version.luam" in lua_tree(ROOT / "lua")


def test_installed_plugins_decode(installed_home):
    out = plain_tshark(installed_home, ["-G", "plugins"]).stdout
    assert "vrshark.so" in out
    for name in ("eclink_modbus.lua", "eclink_pnio.lua", "mcmb2.lua", "vrshark_pnio.lua"):
        assert name in out
    proc = plain_tshark(installed_home, ["-n", "-r", str(ROOT / "captures" / "eglink_armed.pcap"),
                                         "-c", "1", "-T", "fields", "-e", "eglink.type",
                                         "-e", "eglink.armed_ru", "-e", "eglink.crc.status"])
    assert proc.stdout.splitlines() == ["VRPI\t0xbeef\t1"], proc.stderr


def test_install_profile(installed_home):
    profile = installed_home / ".config" / "wireshark" / "profiles" / "vrshark"
    assert sorted(p.name for p in profile.iterdir()) == ["colorfilters", "dfilter_buttons", "preferences", "recent"]
    colours = (profile / "colorfilters").read_text()
    # ours first, then Wireshark's own default rules
    assert colours.index("@vrshark: ES-Link relays open@") < colours.index("@TCP@")
    proc = plain_tshark(installed_home, ["-C", "vrshark", "-n", "-r", str(ROOT / "captures" / "eglink_states.pcap"),
                                         "-c", "2"], personal_config=True)
    assert proc.stdout.splitlines()[1].split()[4:8] == ["0x1001", "Stopped", "Stopped", "0xbeef"], proc.stderr


@pytest.mark.skipif(os.getuid() != 0, reason="needs root to configure as one user and install as another")
def test_install_by_user_after_root_configured():
    """tools/setup configures build/ as root; a user then installs from it into
    their own home (the destination is read when cmake --install runs)."""
    top = Path(tempfile.mkdtemp(prefix="vrshark-install-user-"))
    try:
        root_home, user_home, build = top / "root-home", top / "user-home", top / "build"
        root_home.mkdir()
        user_home.mkdir()
        env = dict(os.environ, HOME=str(root_home))
        for cmd in (["cmake", "-S", str(ROOT), "-B", str(build)], ["cmake", "--build", str(build), "-j", "2"]):
            proc = subprocess.run(cmd, env=env, capture_output=True, text=True)
            assert proc.returncode == 0, proc.stdout + proc.stderr
        top.chmod(0o755)
        subprocess.run(["chown", "-R", "65534:65534", str(build), str(user_home)], check=True)
        proc = subprocess.run(["setpriv", "--reuid=65534", "--regid=65534", "--clear-groups",
                               "cmake", "--install", str(build)],
                              env=dict(os.environ, HOME=str(user_home)), capture_output=True, text=True)
        assert proc.returncode == 0, proc.stdout + proc.stderr
        # every installed file is reported, and all of them are in the user's home
        installed = [line.split(": ", 1)[1] for line in proc.stdout.splitlines()
                     if line.startswith("-- Installing: ")]
        assert str(user_home / ".local/lib/wireshark/plugins/4.0/epan/vrshark.so") in installed \
            or any(p.endswith("/epan/vrshark.so") for p in installed)
        assert installed and all(p.startswith(str(user_home) + "/") for p in installed), installed
        assert (user_home / ".config/wireshark/profiles/vrshark/colorfilters").exists()
        assert not list(root_home.rglob("*"))
    finally:
        shutil.rmtree(top, ignore_errors=True)
