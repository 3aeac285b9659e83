"""The product as a user has it after the README's own install, for the
installed-layout tests (test_installed_layouts.py) and the GUI test.

tools/tshark puts every plugin into one folder (WIRESHARK_PLUGIN_DIR); no
user has that layout, and the order in which Wireshark hands off plugins
depends on the folders they sit in. These layouts are the documented ones:

  personal   `cmake -S . -B build && cmake --build build && cmake --install
             build` as an unprivileged user with a fresh HOME: vrshark.so in
             ~/.local/lib/wireshark/plugins/<version>/epan/, the Lua plugins
             in ~/.local/lib/wireshark/plugins/vrshark/, the profile in
             ~/.config/wireshark/profiles/vrshark/; Wireshark's own plugins
             (profinet.so ...) stay in the global folder.
  system     configured with -DVRSHARK_INSTALL_SYSTEM=ON and installed into
             a staging folder (DESTDIR); the run sees Wireshark's real global
             folders with the staged files added, bind-mounted in a private
             mount namespace (needs root: `unshare -m`), as that user.
  lua-only   README.md's lines, run as they stand there: the contents of lua/
             copied into ~/.local/lib/wireshark/plugins/vrshark/ (no C plugin,
             no compiler), the profile written by tools/profile into
             ~/.config/wireshark/profiles/vrshark/.
  archive    the zip of tools/package unpacked and copied into that home by
             the Linux lines of its INSTALL.txt (the Lua plugins, the profile,
             the IO-list folder).

Every run is the system tshark (or wireshark) as an unprivileged user (uid
65534 when the tests run as root), HOME the layout's home, no
WIRESHARK_PLUGIN_DIR, no WIRESHARK_CONFIG_DIR: the personal configuration
folder ~/.config/wireshark is the one Wireshark finds by itself.
"""
import os
import re
import shutil
import subprocess
import tempfile
import zipfile
from pathlib import Path

from conftest import ROOT

RUN_UID = 65534
IS_ROOT = os.getuid() == 0
KINDS = ("personal", "system", "lua-only", "archive")


def _folders():
    """Wireshark's own folders, as `tshark -G folders` names them."""
    out = subprocess.run(["tshark", "-G", "folders"], capture_output=True, text=True).stdout
    return {k.strip(): v.strip() for k, v in (line.split(":", 1) for line in out.splitlines() if ":" in line)}


def _as_user(cmd):
    if IS_ROOT:
        return ["setpriv", "--reuid=%d" % RUN_UID, "--regid=%d" % RUN_UID, "--clear-groups"] + cmd
    return cmd


def _run(cmd, env, cwd=None):
    proc = subprocess.run(cmd, env=env, capture_output=True, text=True, cwd=cwd)
    assert proc.returncode == 0, "%s\n%s%s" % (" ".join(map(str, cmd)), proc.stdout, proc.stderr)
    return proc


def _user_env(home):
    env = {k: v for k, v in os.environ.items()
           if not k.startswith("WIRESHARK_") and not k.startswith("VRSHARK_")}
    env.update(HOME=str(home), TZ="UTC", LC_ALL="C.UTF-8")
    return env


class Installed:
    """One documented install in a fresh folder; .tshark() runs it."""

    def __init__(self, kind):
        assert kind in KINDS
        self.kind = kind
        self.top = Path(tempfile.mkdtemp(prefix="vrshark-%s-" % kind))
        self.top.chmod(0o755)
        self.home = self.top / "home"
        self.home.mkdir()
        self.mounts = []        # (real folder, staged copy) bound in the run's namespace
        getattr(self, "_install_" + kind.replace("-", "_"))()
        self.config = self.home / ".config" / "wireshark"
        self.config.mkdir(parents=True, exist_ok=True)
        if IS_ROOT:
            subprocess.run(["chown", "-R", "%d:%d" % (RUN_UID, RUN_UID), str(self.home)], check=True)

    # -- the installs, as README.md gives them ---------------------------------

    def _cmake_build(self, build, env, *options):
        for cmd in (["cmake", "-S", str(ROOT), "-B", str(build)] + list(options),
                    ["cmake", "--build", str(build), "-j", "2"]):
            _run(_as_user(cmd), env)

    def _install_personal(self):
        build = self.top / "build"
        build.mkdir()
        if IS_ROOT:
            subprocess.run(["chown", "-R", "%d:%d" % (RUN_UID, RUN_UID), str(self.top)], check=True)
        env = _user_env(self.home)
        self._cmake_build(build, env)
        _run(_as_user(["cmake", "--install", str(build)]), env)
        shutil.rmtree(build)

    def _install_system(self):
        assert IS_ROOT, "the system install needs root (unshare -m, mount --bind)"
        build, stage = self.top / "build", self.top / "stage"
        env = _user_env(self.top)
        for cmd in (["cmake", "-S", str(ROOT), "-B", str(build), "-DVRSHARK_INSTALL_SYSTEM=ON"],
                    ["cmake", "--build", str(build), "-j", "2"]):
            _run(cmd, env)
        _run(["cmake", "--install", str(build)], dict(env, DESTDIR=str(stage)))
        shutil.rmtree(build)
        folders = _folders()
        # The folders the install wrote into, each a copy of the real one with
        # the staged files added: the plugin folder (C and Lua) and the global
        # configuration folder (the profile).
        for real in (Path(folders["Global Lua Plugins"]), Path(folders["Global configuration"])):
            staged = stage / real.relative_to("/")
            assert staged.is_dir(), "nothing installed under %s" % real
            copy = self.top / ("root" + str(real).replace("/", "_"))
            shutil.copytree(real, copy, symlinks=True)
            shutil.copytree(staged, copy, symlinks=True, dirs_exist_ok=True)
            self.mounts.append((real, copy))

    def _install_lua_only(self):
        """README's Lua-only lines (its sh block that runs tools/profile), from
        the top of the checkout."""
        blocks = re.findall(r"```sh\n(.*?)```", (ROOT / "README.md").read_text(), re.S)
        lines = [b for b in blocks if "tools/profile " in b and "cp -r lua/" in b]
        assert len(lines) == 1, "README.md: no single sh block of the Lua-only install"
        _run(["sh", "-ec", lines[0]], _user_env(self.home), cwd=str(ROOT))

    def _install_archive(self):
        dist = self.top / "dist"
        out = _run([str(ROOT / "tools" / "package"), "-o", str(dist)], _user_env(self.top)).stdout.split()
        archive = [p for p in out if p.endswith(".zip")][0]
        with zipfile.ZipFile(archive) as z:     # as unzip does, with the files' modes
            for info in z.infolist():
                z.extract(info, dist)
                (dist / info.filename).chmod((info.external_attr >> 16) & 0o777 or 0o644)
        folder = next(p for p in dist.iterdir() if p.is_dir())
        text = (folder / "INSTALL.txt").read_text()
        lines = text.split("Linux and macOS", 1)[1].split("\n\n")[1]
        _run(["sh", "-ec", lines], _user_env(self.home), cwd=str(folder))
        self.archive_folder = folder

    # -- running it --------------------------------------------------------------

    def command(self, program, args):
        """program (tshark, wireshark) with args, as the layout's user; the
        system layout's folders bound over the real ones in a private mount
        namespace."""
        cmd = _as_user([program] + list(args))
        if not self.mounts:
            return cmd
        script = "mount --make-rprivate / && " + " && ".join(
            "mount --bind %s %s" % (copy, real) for real, copy in self.mounts) + ' && exec "$@"'
        return ["unshare", "-m", "sh", "-c", script, "sh"] + cmd

    def env(self, **extra):
        env = _user_env(self.home)
        env.update(extra)
        return env

    def tshark(self, args, **kw):
        return subprocess.run(self.command("tshark", args), env=self.env(), capture_output=True, text=True,
                              cwd=str(self.home), **kw)

    def add_io_list(self, csv_path):
        """A machine-data IO list where the README puts it (the personal
        configuration folder's vrshark-io/)."""
        folder = self.config / "vrshark-io"
        folder.mkdir(exist_ok=True)
        shutil.copy(csv_path, folder / csv_path.name)
        if IS_ROOT:
            subprocess.run(["chown", "-R", "%d:%d" % (RUN_UID, RUN_UID), str(self.config)], check=True)

    def add_lua_plugin(self, name, text):
        """A third party's Lua plugin in the personal plugin folder."""
        path = self.home / ".local" / "lib" / "wireshark" / "plugins" / name
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text)
        if IS_ROOT:
            subprocess.run(["chown", "-R", "%d:%d" % (RUN_UID, RUN_UID), str(self.home / ".local")], check=True)
        return path

    def remove(self):
        shutil.rmtree(self.top, ignore_errors=True)
