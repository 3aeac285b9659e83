"""Run the system tshark the way tools/tshark does, from Python.

tools/fuzz and tools/bench start thousands of tshark processes; this module
spares each of them the shell wrapper and lets a caller choose the plugin
folder (the normal build, the sanitizer build, or a folder with only
Wireshark's own plugins) and extra environment (LD_PRELOAD of a sanitizer
runtime). As in tools/tshark: Wireshark ignores WIRESHARK_PLUGIN_DIR when it
runs as root, so as root tshark runs as nobody (VRSHARK_RUN_UID) with a
private HOME, and every file it reads must be readable by that user.
"""
import fcntl
import glob
import os
import shutil
import subprocess
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
RUN_UID = int(os.environ.get("VRSHARK_RUN_UID", "65534"))


def build(build_dir, cmake_args="", lua_only=False):
    """tools/build into build_dir (cheap when nothing changed); returns build_dir/wsplugins,
    or with lua_only build_dir/wsplugins-lua-only (the Lua plugins without vrshark.so)."""
    env = dict(os.environ)
    if cmake_args:
        env["VRSHARK_CMAKE_ARGS"] = cmake_args
    if lua_only:
        env["VRSHARK_NO_C_PLUGIN"] = "1"
    build_dir = Path(build_dir)
    build_dir.mkdir(parents=True, exist_ok=True)
    # One build at a time per folder (the test suite and a manual run may overlap).
    with open(build_dir / ".build-lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        subprocess.run([str(ROOT / "tools" / "build"), "--quiet", str(build_dir)], env=env,
                       check=True)
    return build_dir / ("wsplugins-lua-only" if lua_only else "wsplugins")


def system_plugin_dir(dest):
    """A plugin folder with links to Wireshark's own plugins only (none of ours).

    Running tshark with it is "Wireshark without vrshark": same binary, same
    way of starting, only our C and Lua plugins missing.
    """
    dest = Path(dest)
    sysdirs = sorted(glob.glob("/usr/lib/*/wireshark/plugins/[0-9]*"))
    if not sysdirs:
        raise RuntimeError("no system Wireshark plugin folder found")
    sysdir = Path(sysdirs[-1])
    if dest.exists():
        shutil.rmtree(dest)
    for kind in sorted(p for p in sysdir.iterdir() if p.is_dir()):
        out = dest / sysdir.name / kind.name
        out.mkdir(parents=True)
        for so in sorted(kind.glob("*.so")):
            if so.name != "vrshark.so":
                (out / so.name).symlink_to(so)
    make_world_readable(dest)
    return dest


def make_world_readable(path):
    """Let user nobody read path (and, for a folder, everything in it)."""
    path = Path(path)
    paths = [path] + (list(path.rglob("*")) if path.is_dir() else [])
    for p in paths:
        if p.is_symlink():
            continue
        mode = p.stat().st_mode
        p.chmod(mode | (0o755 if p.is_dir() else 0o644))


def world_dir(prefix):
    """A scratch folder that user nobody can write to."""
    d = Path(tempfile.mkdtemp(prefix=prefix))
    d.chmod(0o777)
    return d


def home_dir():
    """The private HOME tools/tshark uses (no installed plugins, no profile)."""
    uid = RUN_UID if os.getuid() == 0 else os.getuid()
    home = Path(os.environ.get("TMPDIR", "/tmp")) / ("vrshark-home-%d" % uid)
    if not home.is_dir():
        home.mkdir(parents=True)
        if os.getuid() == 0:
            os.chown(home, RUN_UID, RUN_UID)
    return home


def command(args, plugin_dir, env=None, preload=None):
    """(argv, environ) to run tshark ARGS with plugin_dir as WIRESHARK_PLUGIN_DIR.

    preload: a shared library to LD_PRELOAD into tshark only (not setpriv).
    """
    environ = dict(os.environ)
    environ.update(env or {})
    environ["HOME"] = str(home_dir())
    environ["WIRESHARK_PLUGIN_DIR"] = str(plugin_dir)
    tshark = environ.pop("TSHARK", None) or "tshark"
    argv = [tshark] + [str(a) for a in args]
    if preload:
        argv = ["env", "LD_PRELOAD=" + str(preload)] + argv
    if os.getuid() == 0:
        argv = ["setpriv", "--reuid=%d" % RUN_UID, "--regid=%d" % RUN_UID,
                "--clear-groups", "--"] + argv
    return argv, environ
