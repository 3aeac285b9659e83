"""vrshark-report --html: a self-contained page that headless Chromium opens
without script errors and whose plots render (the screenshot has their
colours); text and JSON need no plotly; the installed command finds its package."""
import os
import subprocess
import sys

import pytest

from conftest import ROOT

REPORT = ROOT / "tools" / "vrshark-report"
sys.path.insert(0, str(ROOT / "tools"))
from report import browser  # noqa: E402
from report.cli import plotly_step  # noqa: E402

CAPTURES = ["captures/eglink_analysis_session.pcap", "captures/mcmb2_polled_connect.pcap",
            "captures/eclink_modbus_faults.pcap"]


def run(args, env=None, **kw):
    environ = dict(os.environ, TZ="UTC", LC_ALL="C.UTF-8")
    environ.update(env or {})
    return subprocess.run([str(a) for a in args], cwd=str(ROOT), capture_output=True, text=True,
                          env=environ, timeout=300, **kw)


@pytest.fixture(scope="module")
def page(tmp_path_factory, conf_dir):
    pytest.importorskip("plotly", reason="plotly is not installed (tools/setup installs it)")
    path = tmp_path_factory.mktemp("report-html") / "report.html"
    proc = run([REPORT, "--html", path] + CAPTURES, env={"WIRESHARK_CONFIG_DIR": str(conf_dir)})
    assert proc.returncode == 0, proc.stderr
    return path


@pytest.fixture(scope="module")
def needs_chromium():
    if browser.chromium() is None:
        pytest.skip("chromium is not installed (tools/setup installs it)")


def test_self_contained(page):
    text = page.read_text()
    assert "<script src=" not in text and "<link " not in text
    assert "Plotly.newPlot" in text  # plotly.js itself is inline
    for name in CAPTURES:
        assert "<h2>%s</h2>" % name in text
    assert "ES-Link relays open (BU state Stopped) for 0.500 s, closed in frame 52" in text


def test_opens_without_script_errors(page, needs_chromium):
    dom, log = browser.dump_dom(page)
    assert browser.script_errors(log) == []
    # One rendered figure per device (plotly draws its SVG into each plot div).
    for plot in ("plot-1-1", "plot-2-1", "plot-3-1"):
        assert 'id="%s"' % plot in dom
    assert dom.count('class="main-svg"') >= 3
    assert dom.count('class="scatterlayer mlayer"') >= 3
    assert "fieldbus update failure (E010)" in dom  # a state axis label of the MC-MB2-PN plot


def ppm_pixels(png):
    """(width, height, RGB bytes) of a PNG, through pngtopnm (netpbm)."""
    data = subprocess.run(["pngtopnm", str(png)], capture_output=True, check=True).stdout
    fields, pos = [], 0
    while len(fields) < 4:  # P6, width, height, maxval, separated by whitespace
        while data[pos:pos + 1].isspace():
            pos += 1
        end = pos
        while not data[end:end + 1].isspace():
            end += 1
        fields.append(data[pos:end])
        pos = end
    assert fields[0] == b"P6" and fields[3] == b"255"
    return int(fields[1]), int(fields[2]), data[pos + 1:]


def test_screenshot_shows_plots(page, needs_chromium, tmp_path):
    if subprocess.run(["sh", "-c", "command -v pngtopnm"], capture_output=True).returncode:
        pytest.skip("pngtopnm is not installed (tools/setup installs netpbm)")
    png = tmp_path / "shot.png"
    log = browser.screenshot(page, png, 1280, 1700)
    assert browser.script_errors(log) == []
    width, height, rgb = ppm_pixels(png)
    assert (width, height) == (1280, 1700)
    # The plot area of the first device (below the title and the device table).
    counts = {}
    for y in range(350, 1200, 2):
        row = rgb[y * width * 3:(y + 1) * width * 3]
        for x in range(0, 1100 * 3, 3):
            px = row[x:x + 3]
            counts[px] = counts.get(px, 0) + 1
    assert len(counts) > 20, "the plot area is nearly blank"
    for name, colour in (("BU state line", "1f77b4"), ("RU state line", "d62728"),
                         ("warning marker", "e08a00")):
        assert counts.get(bytes.fromhex(colour), 0) > 20, "no %s in the screenshot" % name


def test_text_and_json_need_no_plotly(tmp_path, conf_dir):
    blocker = tmp_path / "plotly"
    blocker.mkdir()
    (blocker / "__init__.py").write_text("raise ImportError('plotly is blocked in this test')\n")
    env = {"PYTHONPATH": str(tmp_path), "WIRESHARK_CONFIG_DIR": str(conf_dir)}
    assert run([REPORT, CAPTURES[0]], env).returncode == 0
    assert run([REPORT, "--json", CAPTURES[0]], env).returncode == 0
    proc = run([REPORT, "--html", tmp_path / "x.html", CAPTURES[0]], env)
    assert proc.returncode == 2
    # the step for the python3 that ran it (on PATH: here not Debian's own)
    python = subprocess.run(["python3", "-c", "import sys; print(sys.executable)"], capture_output=True,
                            text=True).stdout.strip()
    assert proc.stderr == ("vrshark-report: the HTML report needs plotly (plotly is blocked in "
                           "this test): %s\n" % plotly_step(python))
    # Debian's own python3: pip refuses to install into it, Debian's package is the step
    if os.path.exists("/etc/debian_version") and os.path.exists("/usr/bin/python3"):
        proc = run(["/usr/bin/python3", REPORT, "--html", tmp_path / "x.html", CAPTURES[0]], env)
        assert proc.returncode == 2
        assert proc.stderr.endswith("(plotly is blocked in this test): sudo apt-get install python3-plotly\n")


def test_plotly_step():
    assert plotly_step("/usr/bin/python3", apt=True) == "sudo apt-get install python3-plotly"
    assert plotly_step("/home/u/venv/bin/python3", apt=True) == "/home/u/venv/bin/python3 -m pip install plotly"
    assert plotly_step("/usr/bin/python3", apt=False) == "/usr/bin/python3 -m pip install plotly"


def _install_report(home):
    """The report as `cmake --install` puts it for a user whose HOME is home:
    the installed command."""
    build = home / "build"
    for cmd in (["cmake", "-S", ROOT, "-B", build],
                ["cmake", "--install", build, "--component", "report"]):
        proc = run(cmd, {"HOME": str(home)})
        assert proc.returncode == 0, proc.stdout + proc.stderr
    return home / ".local" / "bin" / "vrshark-report"


def test_installed_html_with_the_system_python(tmp_path, conf_dir):
    """The installed command run by Debian's own python3 (no pip packages:
    what `/usr/bin/env python3` is for a user without a venv) writes the HTML
    report with Debian's python3-plotly, which tools/setup installs."""
    python = "/usr/bin/python3"
    if not os.path.exists(python):
        pytest.skip("no system python3")
    if subprocess.run([python, "-c", "import plotly"], capture_output=True).returncode:
        pytest.skip("the system python3 has no plotly (tools/setup installs python3-plotly)")
    installed = _install_report(tmp_path)
    page = tmp_path / "report.html"
    proc = run([python, installed, "--html", page, ROOT / "captures" / "eglink_analysis_session.pcap"],
               {"TSHARK": str(ROOT / "tools" / "tshark"), "WIRESHARK_CONFIG_DIR": str(conf_dir)},
               stdin=subprocess.DEVNULL)
    assert proc.returncode == 0, proc.stderr
    text = page.read_text()
    assert "Plotly.newPlot" in text and 'id="plot-1-1"' in text
    assert "ES-Link relays open (BU state Stopped) for 0.500 s, closed in frame 52" in text
    if browser.chromium() is not None:
        dom, log = browser.dump_dom(page)
        assert browser.script_errors(log) == []
        assert 'class="main-svg"' in dom


def test_installed_command(tmp_path, conf_dir):
    """cmake --install puts bin/vrshark-report and its package in lib/vrshark; the
    installed command runs $TSHARK (here tools/tshark, for this checkout's plugins)."""
    installed = _install_report(tmp_path)
    assert (tmp_path / ".local" / "lib" / "vrshark" / "report" / "model.py").is_file()
    proc = run([installed, "--json", ROOT / "captures" / "eglink_analysis_vrpi_gap.pcap"],
               {"TSHARK": str(ROOT / "tools" / "tshark"), "WIRESHARK_CONFIG_DIR": str(conf_dir)},
               stdin=subprocess.DEVNULL)
    assert proc.returncode == 0, proc.stderr
    assert '"no VRPI for 0.875 s (after frame 10, limit 500 ms), received again in frame 20"' \
        in proc.stdout
    # Without $TSHARK the installed command runs the plain tshark on PATH.
    environ = {"TSHARK": "", "WIRESHARK_CONFIG_DIR": str(conf_dir)}
    proc = run([installed, ROOT / "captures" / "eglink_armed.pcap"], environ)
    assert proc.returncode in (0, 2)
    if proc.returncode == 2:  # no plugins for this user: the plain tshark says so
        assert "tshark does not know the eglink, eclink and mcmb2 fields" in proc.stderr
