"""Headless Chromium for the HTML report: screenshots and the rendered page.

Used by tools/report/screenshot (the picture in docs/) and by the tests. As
root Chromium needs --no-sandbox; every run gets a fresh profile folder and
never touches the network.
"""
import shutil
import subprocess
import tempfile
from pathlib import Path

FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--no-first-run",
         "--disable-background-networking", "--disable-component-update", "--disable-sync",
         "--hide-scrollbars", "--enable-logging=stderr", "--v=0"]


def chromium():
    """The Chromium binary, or None."""
    for name in ("chromium", "chromium-browser", "google-chrome"):
        path = shutil.which(name)
        if path:
            return path
    return None


def run(html, args, timeout=120):
    """Open html (a file) with extra args; returns the CompletedProcess."""
    binary = chromium()
    if binary is None:
        raise RuntimeError("chromium is not installed (tools/setup installs it)")
    with tempfile.TemporaryDirectory(prefix="vrshark-chromium-") as profile:
        argv = [binary] + FLAGS + ["--user-data-dir=" + profile] + list(args)
        argv.append(Path(html).resolve().as_uri())
        return subprocess.run(argv, capture_output=True, text=True, errors="replace",
                              timeout=timeout)


def screenshot(html, png, width=1280, height=1600):
    """Write a PNG of the page's top width x height pixels; returns Chromium's log."""
    proc = run(html, ["--window-size=%d,%d" % (width, height), "--screenshot=%s" % png,
                      "--virtual-time-budget=5000"])
    if not Path(png).exists():
        raise RuntimeError("chromium wrote no screenshot:\n" + proc.stderr[-2000:])
    return proc.stderr


def dump_dom(html):
    """(the DOM after the scripts ran, Chromium's log with console messages)."""
    proc = run(html, ["--dump-dom", "--virtual-time-budget=5000"])
    return proc.stdout, proc.stderr


def script_errors(log):
    """Console errors of the page in Chromium's log (uncaught exceptions, failed loads)."""
    return [line for line in log.splitlines()
            if "CONSOLE" in line and ("Uncaught" in line or "Error" in line)]
