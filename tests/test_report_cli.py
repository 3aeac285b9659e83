"""vrshark-report as a command: --expect, what is no network capture, standard
input and pipes, output folders and plotly checked before tshark runs, the
tshark and its options checked once, SIGTERM, JUnit times.

Every test runs twice: through the checkout's tools/vrshark-report (and so
tools/tshark) and through the command `cmake --install` puts into a fresh
HOME, run as that unprivileged user with the tshark on PATH (installed_testlib).
Paths are absolute and temporary files sit in a folder that user can reach,
so both give the same lines.
"""
import json
import os
import pty
import select
import shlex
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

from conftest import CAPTURES, ROOT
from installed_testlib import IS_ROOT, RUN_UID, Installed

PUBLIC = ROOT.parent / "shared" / "captures" / "public"
PORT5020 = str(CAPTURES / "eclink_modbus_port5020.pcap")
VRPO_GAP = str(CAPTURES / "eglink_analysis_vrpo_gap.pcap")
BAD_CRC = str(CAPTURES / "eglink_bad_crc.pcap")
MCMB2 = str(CAPTURES / "mcmb2_duplex_watchdog.pcap")
NO_MODBUS = "the capture holds no Modbus/TCP (no TCP frame at all)"


class Checkout:
    """tools/vrshark-report of this checkout."""
    name = "checkout"

    def __init__(self, conf_dir):
        self.conf_dir = conf_dir

    def argv(self, args):
        return [str(ROOT / "tools" / "vrshark-report")] + [str(a) for a in args]

    def env(self, **extra):
        env = dict(os.environ, TZ="UTC", LC_ALL="C.UTF-8", WIRESHARK_CONFIG_DIR=str(self.conf_dir))
        env.update(extra)
        return env

    cwd = ROOT


class InstalledCommand:
    """~/.local/bin/vrshark-report of a personal install, as its user."""
    name = "installed"

    def __init__(self, inst):
        self.inst = inst
        self.path = inst.home / ".local" / "bin" / "vrshark-report"
        assert self.path.is_file()

    def argv(self, args):
        return self.inst.command(str(self.path), [str(a) for a in args])

    def env(self, **extra):
        return self.inst.env(**extra)

    @property
    def cwd(self):
        return self.inst.home


@pytest.fixture(scope="module")
def installed():
    inst = Installed("personal")
    yield InstalledCommand(inst)
    inst.remove()


@pytest.fixture(params=["checkout", "installed"])
def cmd(request, conf_dir):
    if request.param == "checkout":
        return Checkout(conf_dir)
    return request.getfixturevalue("installed")


def run(cmd, *args, env=None, **kw):
    kw.setdefault("stdin", subprocess.DEVNULL)
    return subprocess.run(cmd.argv(args), env=cmd.env(**(env or {})), cwd=str(cmd.cwd),
                          capture_output=True, text=True, timeout=300, **kw)


def start(cmd, *args, **kw):
    return subprocess.Popen(cmd.argv(args), env=cmd.env(), cwd=str(cmd.cwd), stdin=subprocess.DEVNULL,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, **kw)


@pytest.fixture
def work(work_dir):
    """A folder the installed command's user can read and write."""
    return Path(work_dir)


def put(folder, name, data):
    path = folder / name
    path.write_bytes(data)
    path.chmod(0o666)
    return path


def fifo(folder, name="fifo"):
    path = folder / name
    os.mkfifo(path)
    path.chmod(0o666)
    return path


def captures(proc):
    return json.loads(proc.stdout)["captures"]


def summary(cap):
    """What a capture's report says, without its name."""
    return (cap["frames"], cap["error"], [(d["kind"], d["name"], d["frames"]) for d in cap["devices"]],
            [(e["frame"], e["severity"], e["text"]) for e in cap["timeline"]])


# --- --expect ------------------------------------------------------------------------

def test_expect_missing_protocol(cmd):
    """The plant on port 5020: without the rule no EC-Link device, exit 1, one
    line naming the setting its candidate notes give: the port with the one
    already decoded (502), so that a BU there still decodes."""
    proc = run(cmd, "--json", "--expect", "eclink", PORT5020)
    assert proc.returncode == 1
    assert proc.stderr.splitlines() == [
        "vrshark-report: %s: expected EC-Link, none found (19 frames read; not recognised, to decode: "
        "-o eclink_modbus.port:502,5020)" % PORT5020]
    cap = captures(proc)[0]
    assert ([d["kind"] for d in cap["devices"]], cap["missing"]) == (["candidate"], ["eclink"])
    assert json.loads(proc.stdout)["expect"] == ["eclink"]
    # With the rule the BU is there: one device, clean.
    proc = run(cmd, "--json", "--expect", "eclink", "-d", "tcp.port==5020,eclink_modbus", PORT5020)
    assert (proc.returncode, proc.stderr) == (0, "")
    assert [d["name"] for d in captures(proc)[0]["devices"]] == [
        "EC-Link BU, Modbus/TCP server 192.168.2.41:5020"]


def test_expect_excerpt_and_subsets(cmd, work):
    """A Modbus excerpt that ends before the BU is recognised (its candidate
    note names the setting), and several
    protocols: each capture names the ones it lacks, with what the capture
    holds (no UDP, no PROFINET: no port or layout hint); EC-Link over
    PROFINET counts as EC-Link."""
    excerpt = work / "excerpt.pcap"
    subprocess.run(["editcap", "-r", str(CAPTURES / "eclink_modbus_faults.pcap"), str(excerpt), "1-8"],
                   check=True)
    excerpt.chmod(0o666)
    pnio = str(CAPTURES / "eclink_pnio_connect.pcap")
    proc = run(cmd, "--expect", "eglink,eclink", "--expect", "mcmb2", excerpt, pnio, MCMB2)
    assert proc.returncode == 1
    assert proc.stderr.splitlines() == [
        "vrshark-report: %s: expected EG-Link, EC-Link and MC-MB2-PN, none found (8 frames read; "
        "the capture holds no UDP (no UDP frame at all); not recognised, to decode: "
        "-o eclink_modbus.servers:192.168.2.41; the capture holds no PROFINET cyclic frame)" % excerpt,
        # (their only UDP is the Connect, PNIO-CM: no UDP port to try)
        "vrshark-report: %s: expected EG-Link and MC-MB2-PN, none found (82 frames read; the capture "
        "holds no UDP but PROFINET's PNIO-CM (2 frames, UDP port 34964); its PROFINET frames are all "
        "another device's)" % pnio,
        "vrshark-report: %s: expected EG-Link and EC-Link, none found (52 frames read; the capture "
        "holds no UDP but PROFINET's PNIO-CM (2 frames, UDP port 34964); %s)" % (MCMB2, NO_MODBUS)]
    proc = run(cmd, "--expect", "eclink", pnio)
    assert (proc.returncode, proc.stderr) == (0, "")


@pytest.mark.parametrize("capture, protocol, setting, device", [
    ("eclink_modbus_excerpt.pcap", "eclink", "eclink_modbus.servers:192.168.2.41",
     "EC-Link BU, Modbus/TCP server 192.168.2.41:502"),
    ("mcmb2_duplex_e010_noconnect.pcap", "mcmb2", "mcmb2.layouts:0xc014/0xc015=duplex:8/4@4",
     "MC-MB2-PN duplex base 00:30:11:00:00:02"),
])
def test_expect_names_the_candidate(cmd, capture, protocol, setting, device):
    """A BU or base the dissectors saw but could not recognise (a short
    Modbus excerpt; a base in E010 without its Connect): the candidate is a
    device with a warning, the --expect line names the exact setting of its
    note; with that setting the device is there and the capture passes."""
    path = str(CAPTURES / capture)
    proc = run(cmd, "--json", "--expect", protocol, path)
    assert proc.returncode == 1
    title = {"eclink": "EC-Link", "mcmb2": "MC-MB2-PN"}[protocol]
    frames = captures(proc)[0]["frames"]
    assert proc.stderr.splitlines() == [
        "vrshark-report: %s: expected %s, none found (%d frames read; not recognised, to decode: -o %s)" % (
            path, title, frames, setting)]
    cap = captures(proc)[0]
    assert [(d["kind"], d["address"]["setting"]) for d in cap["devices"]] == [("candidate", setting)]
    assert [(e["severity"], e["text"].endswith("to decode it: -o " + setting)) for e in cap["timeline"]] == [
        ("warning", True)]
    proc = run(cmd, "--json", "--expect", protocol, "-o", setting, path)
    assert proc.stderr == ""
    assert [d["name"] for d in captures(proc)[0]["devices"]] == [device]


@pytest.mark.parametrize("args, status, lines", [
    (["--fail-on", "error", "--expect", "eglink", VRPO_GAP], 1, 1),       # the gate fails, expect holds
    (["--fail-on", "error", "--expect", "eclink", BAD_CRC], 1, 2),        # both fail
    (["--fail-on", "error", "--expect", "eglink", MCMB2], 1, 2),          # both fail, other protocol
    (["--expect", "eglink", "MISSING", BAD_CRC], 2, 1),                   # unreadable wins
    (["--expect", "eglink", "--fail-on", "error", PORT5020], 1, 1),       # expect alone fails
])
def test_expect_with_gate(cmd, args, status, lines):
    args = [str(CAPTURES / "no-such.pcap") if a == "MISSING" else a for a in args]
    proc = run(cmd, *args)
    assert proc.returncode == status, proc.stderr
    assert len(proc.stderr.splitlines()) == lines, proc.stderr


def test_expect_junit(cmd, work):
    out = work / "expect.xml"
    proc = run(cmd, "--junit", out, "--expect", "eclink", PORT5020, BAD_CRC)
    assert proc.returncode == 1
    suites = ET.parse(out).getroot().findall("testsuite")
    for suite, capture in zip(suites, (PORT5020, BAD_CRC)):
        assert suite.get("name") == capture
        case = suite.find("testcase[@name='expected EC-Link']")
        assert case.find("failure").get("message").startswith("expected EC-Link, none found (")
    # the message names the setting, as the line on stderr does
    lines = proc.stderr.splitlines()
    assert [s.find("testcase[@name='expected EC-Link']/failure").get("message") for s in suites] == [
        "expected EC-Link, none found (19 frames read; not recognised, to decode: -o eclink_modbus.port:502,5020)",
        "expected EC-Link, none found (%s frames read; %s)" % (
            lines[1].split("(", 1)[1].split(" ")[0], NO_MODBUS)]
    assert lines == ["vrshark-report: %s: %s" % (c, s.find("testcase[@name='expected EC-Link']/failure").get(
        "message")) for c, s in zip((PORT5020, BAD_CRC), suites)]
    # (the plant on port 5020 is a candidate: its own failing case, with the setting)
    assert [c.get("name") for c in suites[0].findall("testcase")] == [
        "Modbus/TCP server 192.168.2.41:5020, not decoded", "expected EC-Link"]
    assert [(s.get("tests"), s.get("failures")) for s in suites] == [("2", "2"), ("2", "2")]


def test_expect_usage(cmd):
    proc = run(cmd, "--expect", "eglink,profibus", BAD_CRC)
    assert proc.returncode == 2 and proc.stdout == ""
    assert proc.stderr.splitlines()[-1] == ("vrshark-report: error: argument --expect: "
                                            "'eglink,profibus': a list of eglink, eclink, mcmb2")


# --- what is a network capture ---------------------------------------------------------

def test_text_file_is_no_capture(cmd, work):
    six = put(work, "notes.txt", b"hello\n")   # tshark: "MP4 media", one frame
    proc = run(cmd, "--fail-on", "note", six, BAD_CRC)
    assert proc.returncode == 2
    assert proc.stderr.splitlines() == [
        "vrshark-report: %s: not a network capture: tshark reads it as MP4 media" % six,
        "vrshark-report: FAIL (--fail-on note): 1 finding(s) at note or above; first: %s frame 1: "
        "bad CRC (6x, frames 1-6 over 0.050 s)" % BAD_CRC]
    assert proc.stdout.startswith("== %s\n  not a network capture: tshark reads it as MP4 media\n\n"
                                  % six)
    # The same bytes on standard input: refused (2) as well. Wireshark 4.0
    # names the format; 4.6 reads a pipe as pcap or pcapng only and
    # stop at the 6 bytes, before a first packet.
    proc = run(cmd, "--json", "-", input="hello\n", stdin=None)
    assert proc.returncode == 2
    assert proc.stderr in ("vrshark-report: -: not a network capture: tshark reads it as MP4 media\n",
                           "vrshark-report: -: truncated: the file ends before its first packet\n")
    assert captures(proc)[0]["frames"] == 0 and captures(proc)[0]["devices"] == []


@pytest.mark.parametrize("kind", ["image", "executable"])
def test_other_files_are_no_capture(cmd, work, kind):
    data = {"image": bytes.fromhex("89504e470d0a1a0a0000000d49484452") + bytes(64),
            "executable": Path("/bin/true").read_bytes()}[kind]
    path = put(work, kind, data)
    proc = run(cmd, path)
    assert proc.returncode == 2
    assert proc.stderr == ("vrshark-report: %s: not a network capture: tshark reads it as MIME File "
                           "Format (an image, an executable, ...)\n" % path)


@pytest.mark.parametrize("fmt", ["pcap", "pcapng", "snoop", "nettl", "5views"])
def test_capture_formats_are_read(cmd, work, fmt):
    """Every format whose records are packets gives the same report."""
    path = work / ("crc." + fmt)
    subprocess.run(["editcap", "-F", fmt, BAD_CRC, str(path)], check=True)
    path.chmod(0o666)
    proc = run(cmd, "--json", path)
    assert (proc.returncode, proc.stderr) == (0, "")
    frames, error, devices, timeline = summary(captures(proc)[0])
    assert (frames, error, [d[0] for d in devices], timeline) == (
        7, None, ["eglink"], [(1, "error", "bad CRC (6x, frames 1-6 over 0.050 s)")])


def test_public_pcapng(cmd):
    path = PUBLIC / "pnio_connect_many.pcapng"
    if not path.is_file():
        pytest.skip("the public captures (../shared) are absent")
    proc = run(cmd, "--json", path)
    assert (proc.returncode, proc.stderr) == (0, "")
    cap = captures(proc)[0]
    assert (cap["frames"], cap["error"], cap["devices"]) == (328, None, [])


# --- standard input and pipes ------------------------------------------------------------

def test_stdin_pipe_and_fifo(cmd, work):
    """`-`, a FIFO and `<(cat x)` read as tshark reads them: the file's report."""
    want = summary(captures(run(cmd, "--json", VRPO_GAP))[0])
    assert want[0] == 56 and len(want[2]) == 1
    with open(VRPO_GAP, "rb") as f:
        proc = run(cmd, "--json", "-", stdin=f)
    assert proc.returncode == 0, proc.stderr
    assert [c["capture"] for c in captures(proc)] == ["-"]
    assert summary(captures(proc)[0]) == want
    path = fifo(work)

    def writer():
        with open(path, "wb") as w:
            w.write(Path(VRPO_GAP).read_bytes())
    thread = threading.Thread(target=writer)
    thread.start()
    proc = run(cmd, "--json", path)
    thread.join()
    assert proc.returncode == 0, proc.stderr
    assert summary(captures(proc)[0]) == want
    # Process substitution: a pipe named /dev/fd/N, given by the shell.
    script = 'exec "$@" <(cat %s)' % VRPO_GAP
    proc = subprocess.run(["bash", "-c", script, "bash"] + cmd.argv(["--json"]), env=cmd.env(),
                          cwd=str(cmd.cwd), capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    assert captures(proc)[0]["capture"].startswith("/dev/fd/")
    assert summary(captures(proc)[0]) == want


def test_stdin_once(cmd):
    proc = run(cmd, "-", "-")
    assert proc.returncode == 2
    assert proc.stderr.splitlines()[-1] == "vrshark-report: error: standard input (-) can be read only once"


# --- checked before tshark runs -------------------------------------------------------------

@pytest.mark.parametrize("option", ["--html", "--junit"])
def test_output_into_missing_folder(cmd, work, option):
    """One line, exit 2, before any capture is opened (a FIFO without a writer
    would block)."""
    if option == "--html":
        pytest.importorskip("plotly", reason="plotly is not installed (tools/setup installs it)")
    target = work / "no-such-folder" / "out"
    proc = run(cmd, option, target, fifo(work))
    assert (proc.returncode, proc.stdout) == (2, "")
    assert proc.stderr == "vrshark-report: %s %s: no such folder %s\n" % (option, target, target.parent)
    proc = run(cmd, option, work, fifo(work, "fifo2"))
    assert proc.returncode == 2
    assert proc.stderr == "vrshark-report: %s %s: is a folder, not a file\n" % (option, work)


def test_plotly_checked_first(cmd, work):
    blocker = work / "plotly"
    blocker.mkdir()
    (blocker / "__init__.py").write_text("raise ImportError('plotly is blocked in this test')\n")
    os.chmod(blocker, 0o755)
    os.chmod(blocker / "__init__.py", 0o644)
    proc = run(cmd, "--html", work / "x.html", fifo(work), env={"PYTHONPATH": str(work)})
    assert proc.returncode == 2
    # the one step for the Python that runs the command (Debian's own: its package)
    step = ("sudo apt-get install python3-plotly" if cmd.name == "installed" and os.path.exists("/etc/debian_version")
            else "%s -m pip install plotly" % sys.executable)
    assert proc.stderr == ("vrshark-report: the HTML report needs plotly (plotly is blocked in "
                           "this test): %s\n" % step)
    assert not (work / "x.html").exists()


@pytest.mark.parametrize("args, line", [
    (["--tshark", "/bin/false"], "/bin/false ended with exit status 1 and no message on an empty "
     "capture: is it tshark?"),
    (["--tshark", "/no/such/tshark"], "cannot run /no/such/tshark: No such file or directory"),
    (["-o", "eglink.no_such_pref:1"], 'tshark: -o flag "eglink.no_such_pref:1" specifies unknown '
     'preference'),
    (["-o", "eglink.vrpi_gap_ms:soon"], 'tshark: Invalid -o flag "eglink.vrpi_gap_ms:soon"'),
    (["-d", "tcp.port==x,eclink_modbus"], 'tshark: Invalid selector number "x"'),
])
def test_tshark_and_options_checked_once(cmd, work, args, line):
    """Said once as a usage error, not once per capture; no capture is opened."""
    proc = run(cmd, *args, BAD_CRC, VRPO_GAP, fifo(work))
    assert (proc.returncode, proc.stdout, proc.stderr) == (2, "", "vrshark-report: %s\n" % line)


@pytest.mark.parametrize("jobs", ["0", "-3", "two"])
def test_jobs_must_be_positive(cmd, jobs):
    proc = run(cmd, "-j", jobs, BAD_CRC)
    assert proc.returncode == 2 and proc.stdout == ""
    assert proc.stderr.splitlines()[-1] == ("vrshark-report: error: argument -j/--jobs: %r is not a "
                                            "number of captures (1 or more)" % jobs)


def read_until(fd, text, seen):
    """Bytes from a pty master until text appears (or the other side closes)."""
    while text not in seen:
        ready, _, _ = select.select([fd], [], [], 120)
        assert ready, "nothing on the terminal: %r" % seen[-300:]
        try:
            chunk = os.read(fd, 4096)
        except OSError:   # EIO: every slave side closed
            return seen
        if not chunk:
            return seen
        seen += chunk
    return seen


def test_progress_through_html(cmd, work):
    """On a terminal the bar shows the capture being read, then the plots
    being built: nothing silent between 100 % and the end. The capture comes
    through a FIFO held open until the bar is up (it shows after a second)."""
    pytest.importorskip("plotly", reason="plotly is not installed (tools/setup installs it)")
    path = fifo(work)
    data = Path(VRPO_GAP).read_bytes()
    master, slave = pty.openpty()
    proc = subprocess.Popen(cmd.argv(["--html", work / "p.html", path]), env=cmd.env(),
                            cwd=str(cmd.cwd), stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                            stderr=slave)
    os.close(slave)
    hold = os.open(path, os.O_RDWR)
    try:
        os.write(hold, data[:1000])
        seen = read_until(master, b"0/1 captures", b"")
        os.write(hold, data[1000:])
        os.close(hold)
        hold = None
        seen = read_until(master, b"\0", seen)   # (to the end)
        proc.wait(timeout=120)
    finally:
        if hold is not None:
            os.close(hold)
        os.close(master)
        if proc.poll() is None:
            proc.kill()
    if b"needs plotly" in seen:   # (the Python the installed command's user runs)
        pytest.skip("no plotly for this Python: %r" % seen)
    assert proc.returncode == 0, seen
    assert b"vrshark-report [" in seen and b"0/1 captures" in seen
    assert b"HTML: plots 1/1" in seen
    assert seen.endswith(b"\r" + b" " * 79 + b"\r")   # the line is cleared at the end
    assert (work / "p.html").stat().st_size > 0


def test_html_basic_bundle(cmd, work, monkeypatch):
    """The page inlines plotly.js's basic bundle, the version plotly writes
    for (Chromium renders it: tests/test_report_html.py); another plotly
    version gets plotly's own full bundle."""
    offline = pytest.importorskip("plotly.offline", reason="plotly is not installed")
    if cmd.name == "installed":  # cmake --install copies the bundle beside the package
        lib = cmd.inst.home / ".local" / "lib" / "vrshark" / "report"
        assert (lib / "plotly-basic.min.js.gz").is_file() and (lib / "plotly-basic.LICENSE").is_file()
    proc = run(cmd, "--html", work / "b.html", VRPO_GAP)
    if "needs plotly" in proc.stderr:
        pytest.skip("no plotly for the Python of this command")
    assert proc.returncode == 0, proc.stderr
    page = (work / "b.html").read_text()
    if cmd.name == "checkout":
        assert "plotly.js (basic - minified) v%s" % offline.get_plotlyjs_version() in page
        assert len(page) < 1.5e6
    else:  # (the installed command runs Debian's python3 and its plotly: another version, its full bundle)
        assert "plotly.js" in page
    assert "Plotly.newPlot" in page
    proc = run(cmd, "--html", work / "e.html", "--expect", "eclink,mcmb2", VRPO_GAP)
    assert proc.returncode == 1
    assert '<p class="error-line">expected EC-Link and MC-MB2-PN, none found</p>' in \
        (work / "e.html").read_text()
    sys.path.insert(0, str(ROOT / "tools"))
    from report import html
    monkeypatch.setattr(html, "get_plotlyjs_version", lambda: "0.0.1")
    assert html.plotly_js() == offline.get_plotlyjs()


# --- SIGTERM ---------------------------------------------------------------------------------

def processes():
    """{pid: (ppid, command name)} of every process, from ps (not the code under test)."""
    out = subprocess.run(["ps", "-e", "-o", "pid=,ppid=,comm="], capture_output=True, text=True,
                         check=True).stdout
    table = {}
    for line in out.splitlines():
        pid, ppid, name = line.split(None, 2)
        table[int(pid)] = (int(ppid), name.strip())
    return table


def tree(root):
    table = processes()
    found, todo = {}, [root]
    while todo:
        parent = todo.pop()
        for pid, (ppid, name) in table.items():
            if ppid == parent:
                found[pid] = name
                todo.append(pid)
    return found


def living(pids):
    table = processes()
    left = []
    for pid in pids:
        try:
            with open("/proc/%d/stat" % pid) as f:
                state = f.read().rsplit(")", 1)[1].split()[0]
        except OSError:
            continue
        if pid in table and state != "Z":
            left.append(pid)
    return left


@pytest.mark.parametrize("signum, group", [(signal.SIGTERM, False), (signal.SIGINT, False),
                                           (signal.SIGINT, True), (signal.SIGHUP, True)])
@pytest.mark.parametrize("writer", [True, False])
def test_signal_ends_everything(cmd, work, signum, group, writer):
    """A capture that never ends (a FIFO whose writer stays, after half a
    capture; or no writer at all): the signal to the report alone (a CI
    timeout), or to its whole process group (Ctrl-C, a hangup: the terminal
    signals every process of the group) ends the report, its workers and
    their tshark, with 128 + the signal and no traceback."""
    path = fifo(work)
    proc = start(cmd, path, BAD_CRC, start_new_session=group)
    hold = None
    waits = set()
    if writer:
        hold = os.open(path, os.O_RDWR)   # a writer that never closes
        os.write(hold, Path(VRPO_GAP).read_bytes()[:1000])
    try:
        # Wait until what must be stopped runs: the worker's tshark reading the
        # FIFO, or the worker blocked opening it.
        for _ in range(600):
            found = tree(proc.pid)
            if writer and "tshark" in found.values():
                break
            waits.update(wchan(pid) for pid in found)
            if not writer and waits & {"wait_for_partner", "fifo_open"}:
                break
            assert proc.poll() is None, proc.communicate()
            threading.Event().wait(0.05)
        else:
            if not writer and waits <= {"0", ""}:
                pytest.skip("this kernel does not say where a process waits (/proc/PID/wchan)")
            pytest.fail("never started: %s" % found)
        if group:
            os.killpg(proc.pid, signum)
        else:
            proc.send_signal(signum)
        out, err = proc.communicate(timeout=30)
        assert (proc.returncode, err) == (128 + signum, "")
        assert living(found) == [], found
    finally:
        if hold is not None:
            os.close(hold)
        if proc.poll() is None:
            proc.kill()
            proc.communicate()


def wchan(pid):
    """Where a process waits in the kernel: "wait_for_partner" in open() of a
    FIFO without a writer; "0" when the kernel does not say."""
    try:
        with open("/proc/%d/wchan" % pid) as f:
            return f.read()
    except OSError:
        return ""


# --- JUnit -------------------------------------------------------------------------------------

def test_junit_time_and_span(cmd, work):
    """A suite's time is the report's own run time; the device's traffic span
    (4.440 s here) is a property, not a time."""
    out = work / "times.xml"
    proc = run(cmd, "--junit", out, VRPO_GAP)
    assert proc.returncode == 0, proc.stderr
    suite = ET.parse(out).getroot().find("testsuite")
    assert float(suite.get("time")) > 0
    case = suite.find("testcase")
    assert case.get("time") is None
    props = {p.get("name"): p.get("value") for p in case.findall("properties/property")}
    assert props == {"kind": "eglink", "frames": "56", "first_frame": "1", "last_frame": "56",
                     "traffic_start_s": "0.000", "traffic_end_s": "4.440", "traffic_span_s": "4.440",
                     "health BU VRPI": "frames 36; cycle 125.0 / 125.0 / 125.0 ms; longest silence 0.125 s to "
                     "frame 3; stalls 0; commands failed 0; findings 0 error, 1 warning, 0 note",
                     "health controller VRPO": "frames 20; cycle 100.0 / 100.0 / 2600.0 ms; longest silence "
                     "2.600 s to frame 40; stalls 1; commands failed 0; findings 1 error, 0 warning, 0 note"}



# --- a gate that a pipe or a folder cannot turn green ------------------------------------

FAULTS = [str(CAPTURES / "eclink_modbus_faults.pcap"), VRPO_GAP, BAD_CRC]


def shell(cmd, args, tail, user=False):
    """The report in a bash pipeline under `set -o pipefail`: (status, stderr)."""
    argv = cmd.argv(args)
    if user and isinstance(cmd, Checkout) and IS_ROOT:
        argv = ["setpriv", "--reuid=%d" % RUN_UID, "--regid=%d" % RUN_UID, "--clear-groups"] + argv
    proc = subprocess.run(["bash", "-c", "set -o pipefail; %s %s" % (shlex.join(argv), tail)],
                          env=cmd.env(), cwd=str(cmd.cwd), stdin=subprocess.DEVNULL, capture_output=True,
                          text=True, timeout=300)
    return proc.returncode, proc.stderr


@pytest.mark.parametrize("tail", ["| head -1", "| true", "> /dev/full", ""])
@pytest.mark.parametrize("args, status", [(["--fail-on", "warn"], 1), (["--fail-on", "error", "--json"], 1),
                                          (["--expect", "mcmb2"], 1), ([], 0)])
def test_closed_output_keeps_the_gate(cmd, tail, args, status):
    """The reader of the report goes away (| head -1, | true): the report
    stops writing, says the gate's line on stderr and exits with the gate's
    status, never 0 for a failed gate and never a traceback. Output that
    cannot be written (a full disk) is exit 2 with one line."""
    got, err = shell(cmd, args + FAULTS, tail)
    if tail == "> /dev/full":
        assert (got, "Traceback" in err) == (2, False), err
        assert "vrshark-report: cannot write the report: No space left on device" in err.splitlines()
        return
    assert (got, "Traceback" in err) == (status, False), err
    if "--fail-on" in args:
        assert err.splitlines()[-1].startswith("vrshark-report: FAIL (--fail-on %s): " % args[1]), err


def test_closed_output_with_junit(cmd, work):
    """The JUnit file is written whole although standard output was closed."""
    out = work / "closed.xml"
    got, err = shell(cmd, ["--junit", out, "--fail-on", "warn"] + FAULTS, "| true")
    assert got == 1, err
    assert ET.parse(out).getroot().get("failures") != "0"


def unreadable_paths(folder):
    """path -> the reason the report gives, for every way a path cannot be read."""
    closed = folder / "closed"          # a folder without search permission (mode 644)
    closed.mkdir()
    shutil.copy(BAD_CRC, closed / "eglink.pcap")
    closed.chmod(0o644)
    private = folder / "private.pcap"   # a file only its owner (root) reads
    shutil.copy(BAD_CRC, private)
    private.chmod(0o600)
    (folder / "loop").symlink_to(folder / "loop")
    plain = put(folder, "plain.pcap", Path(BAD_CRC).read_bytes())
    sub = folder / "a-folder"
    sub.mkdir()
    denied = "cannot open: permission denied (the file, or a folder on its path, is closed to this user)"
    return {closed / "eglink.pcap": denied, private: denied,
            sub: "is a directory, not a capture file",
            folder / "missing.pcap": "no such file",
            folder / "loop": "cannot open: Too many levels of symbolic links",
            plain / "inside.pcap": "cannot open: Not a directory"}


@pytest.mark.skipif(not IS_ROOT, reason="the paths are made closed to uid %d as root" % RUN_UID)
def test_unreadable_paths_one_line_exit_2(cmd, work):
    """Run as a user (uid 65534): every way a path cannot be read is one line
    naming the path and the reason, exit 2 (never 1, the gate's failure,
    and never a traceback), alone and beside a readable capture."""
    for path, reason in unreadable_paths(work).items():
        for args in (["--fail-on", "warn", path], ["--fail-on", "warn", "--expect", "eglink", path, BAD_CRC]):
            got, err = shell(cmd, args, "", user=True)
            assert got == 2 and "Traceback" not in err, (path, err)
            assert err.splitlines()[0] == "vrshark-report: %s: %s" % (path, reason), err


def test_suggested_setting_decodes_and_keeps_port_502(cmd):
    """The setting the --expect line names for the BU on port 5020, applied
    in a second run with the BU on port 502 (eclink_modbus_faults.pcap: 1
    error, 3 warnings): both BUs decoded, the gate still fails on 502's
    findings. Wireshark's own port setting (mbtcp.tcp.port) adds too."""
    on502 = str(CAPTURES / "eclink_modbus_faults.pcap")
    proc = run(cmd, "--expect", "eclink", PORT5020)
    setting = proc.stderr.split("to decode: -o ", 1)[1].rstrip(")\n")
    assert setting == "eclink_modbus.port:502,5020"
    alone = captures(run(cmd, "--json", on502))[0]
    assert [d["name"] for d in alone["devices"]] == ["EC-Link BU, Modbus/TCP server 192.168.2.41:502"]
    for prefs in (["-o", setting], ["-o", "eclink_modbus.port:5020"], ["-o", "mbtcp.tcp.port:5020"]):
        proc = run(cmd, "--json", "--expect", "eclink", "--fail-on", "warn", *prefs, PORT5020, on502)
        assert proc.returncode == 1, proc.stderr
        got = captures(proc)
        assert [d["name"] for d in got[0]["devices"]] == ["EC-Link BU, Modbus/TCP server 192.168.2.41:5020"]
        assert summary(got[1]) == summary(alone), prefs
        assert [line.split(":")[1] for line in proc.stderr.splitlines()] == [" FAIL (--fail-on warn)"], proc.stderr


def test_no_tcp_says_no_modbus(cmd):
    proc = run(cmd, "--expect", "eclink", MCMB2)
    assert proc.returncode == 1
    assert proc.stderr == "vrshark-report: %s: expected EC-Link, none found (52 frames read; %s)\n" % (
        MCMB2, NO_MODBUS)


@pytest.fixture(scope="module")
def plant_excerpt():
    """The first 17 frames of a real plant's connection (test_eclink_modbus_realstack:
    a pymodbus BU on 127.0.0.1, on a port other than 502), its PLC reading
    the input image and writing the output image every 50 ms."""
    import test_eclink_modbus_realstack as rs

    def plc(log):
        bu = rs._client(rs.BU)
        for pco in range(20):
            assert not bu.read_input_registers(0, count=32, device_id=1).isError()
            assert not bu.write_registers(0, rs._output_registers(pco, 5), device_id=1).isError()
            time.sleep(0.05)
        bu.close()
    gen = rs.captured("commands", plc)
    cap, _ = next(gen)
    # from the SYN of the connection the server accepted (the client's tries
    # before the server listened are refused: SYN, RST)
    synack = subprocess.run(["tshark", "-n", "-r", str(cap), "-Y", "tcp.flags.syn == 1 && tcp.flags.ack == 1",
                             "-T", "fields", "-e", "frame.number"], capture_output=True, text=True,
                            env={"PATH": "/usr/bin:/bin", "HOME": str(cap.parent)}).stdout.split()
    first = int(synack[0]) - 1
    excerpt = cap.parent / "plant-17.pcapng"
    subprocess.run(["editcap", "-r", str(cap), str(excerpt), "%d-%d" % (first, first + 16)], check=True)
    excerpt.chmod(0o644)
    yield excerpt, rs.PORT
    gen.close()


def test_plant_excerpt_first_suggestion_decodes(cmd, plant_excerpt):
    """Too short for the heuristic: the first suggestion is the server with
    its port, and it decodes the BU in the second run."""
    excerpt, port = plant_excerpt
    proc = run(cmd, "--expect", "eclink", excerpt)
    assert proc.returncode == 1 and "to decode: -o " in proc.stderr, proc.stderr
    first = proc.stderr.split("to decode: -o ", 1)[1].split(", ")[0].rstrip(")\n")
    assert first == "eclink_modbus.servers:127.0.0.1:%d" % port, proc.stderr
    proc = run(cmd, "--json", "--expect", "eclink", "-o", first, excerpt)
    assert (proc.returncode, proc.stderr) == (0, "")
    assert "EC-Link BU, Modbus/TCP server 127.0.0.1:%d" % port in [d["name"] for d in captures(proc)[0]["devices"]]


@pytest.mark.parametrize("capture, devices, lost", [
    # a serial that arrived with a bad CRC is not lost (issue: "serial 103 expected")
    ("eglink_analysis_corrupted.pcap", [("EG-Link BU 0x1001 (192.168.32.10 to 239.255.42.20:5825)", 18)], False),
    # a controller's packets on a wrong port are its conversation's, not a device of their own
    ("eglink_analysis_wrong_port.pcap", [("EG-Link BU 0x1001 (192.168.32.10 to 239.255.42.20:5825)", 22)], False),
    # two BUs, two controllers that acknowledge nothing: pairing unknown, listed apart
    ("eglink_analysis_unpaired.pcap", [
        ("EG-Link BU 0x1001 (10.0.0.1 to 239.255.42.20:5825)", 40),
        ("EG-Link BU 0x2002 (10.0.0.2 to 239.255.42.20:5825)", 40),
        ("EG-Link controller 10.0.0.11 to 239.255.42.20:5827, BU not known (no command acknowledged "
         "between it and a BU of the group: pairing unknown)", 40),
        ("EG-Link controller 10.0.0.12 to 239.255.42.20:5827, BU not known (no command acknowledged "
         "between it and a BU of the group: pairing unknown)", 40)], False),
])
def test_eglink_devices_and_frame_counts(cmd, capture, devices, lost):
    """The EG-Link device model as the checkout's and the installed command
    give it: which device each packet is, and no loss counted for packets
    that are in the capture."""
    proc = run(cmd, "--json", str(CAPTURES / capture))
    assert proc.returncode == 0, proc.stderr
    cap = captures(proc)[0]
    assert [(d["name"], d["frames"]) for d in cap["devices"]] == devices
    assert any("packets lost" in e["text"] or "packet lost" in e["text"] for e in cap["timeline"]) == lost


# --- what the capture does not hold: frames cut by the snaplen, short excerpts -------------

def editcap(work, name, *args):
    """A capture cut as a user cuts one (editcap -s, -r), readable by the installed command's user."""
    out = work / name
    subprocess.run(["editcap"] + [str(a) for a in args[:-1]] + [str(out)] + ([args[-1]] if args[-1] else []),
                   check=True)
    out.chmod(0o666)
    return out


def test_cut_state_is_not_captured(cmd, work, tshark):
    """The second half of an EG-Link capture cut at 64 bytes: tshark leaves the
    RU state and armed RU of those VRPIs empty, in one pass and with -2; the
    report says the RU state was not captured from there on and invents no
    change (before: "RU state Enabled (RU 0xbeef) -> Initial (no RU armed)")."""
    src = CAPTURES / "eglink_armed.pcap"
    first, second = editcap(work, "a.pcap", "-r", src, "1-29"), editcap(work, "b.pcap", "-s", 64, "-r", src, "30-58")
    path = work / "half_cut.pcap"
    subprocess.run(["mergecap", "-a", "-w", str(path), str(first), str(second)], check=True)
    path.chmod(0o666)
    for two_pass in (False, True):
        tshark.expect(path, 30, {"eglink.type": "VRPI", "eglink.bu_state": 0x11, "eglink.ru_state": None,
                                 "eglink.armed_ru": None, "eglink.cut": True}, two_pass=two_pass)
    proc = run(cmd, "--json", "--fail-on", "warn", path)
    assert (proc.returncode, proc.stderr) == (0, "")
    cap = captures(proc)[0]
    (dev,) = cap["devices"]
    assert dev["initial"] == {"BU state": "Armed", "RU state": "Enabled (RU 0xbeef)"}
    assert dev["final"] == {"BU state": "Armed",
                            "RU state": "not captured from frame 30 on (before: Enabled (RU 0xbeef))"}
    assert dev["not_captured"] == {"RU state": {"first_frame": 30, "last_frame": 57, "frames": 12}}
    assert [e["kind"] for e in cap["timeline"]] == ["finding"]   # the cut note, no state change
    assert (cap["held"]["snaplen"], cap["held"]["udp"]["cut"]) == (64, 28)  # (frame 45 is 64 bytes long)
    text = run(cmd, path).stdout.splitlines()
    assert "      last:  BU state Armed, RU state not captured from frame 30 on (before: Enabled (RU 0xbeef))" in text
    assert "  %d of 58 frames cut by the capture at 64 bytes (snaplen): what they do not hold is not " \
           "captured" % cap["held"]["udp"]["cut"] in text
    out = work / "cut.xml"
    run(cmd, "--junit", out, path)
    assert [(p.get("name"), p.get("value")) for p in ET.parse(out).getroot().iter("property")
            if p.get("name") == "not_captured"] == [("not_captured", "RU state from frame 30")]


@pytest.fixture(scope="module")
def scapy_bu_cut():
    """An EC-Link BU over PROFINET built by scapy's layers, its Connect and
    cyclic frames, captured with a 100-byte snaplen (editcap -s 100), in a
    folder the installed command's user can read."""
    from pnio_testlib import CaptureFile, Device, eclink_submodules, mac
    from test_pnio_midsession import eclink_image_in, eclink_image_out
    folder = Path(tempfile.mkdtemp(prefix="vrshark-scapy-bu-"))
    folder.chmod(0o777)
    d = Device(eclink_submodules(4, 224), mac(41), 0x8042, 0x8043)
    cap = CaptureFile()
    for p in d.connect():
        cap.add(p)
    for i in range(20):
        cap.add(d.cyclic("in", {1: eclink_image_in(i)}), 0.045)
        cap.add(d.cyclic("out", {2: eclink_image_out(i)}), 0.005)
    whole = cap.write(folder / "bu.pcap")
    yield whole, editcap(folder, "bu_s100.pcap", "-s", 100, whole, None)
    shutil.rmtree(folder)


def test_no_device_carries_tshark_notes(cmd, tshark, scapy_bu_cut):
    """The Connect and the output frames cut at 100 bytes (the cut frames
    carry no FrameID): no device forms.
    tshark notes the cut Connect (one pass and -2); the report carries those
    notes (device null, [-] in the text), says no device was decoded and
    why, and its hints name the cut instead of a port or a missing UDP."""
    whole, path = scapy_bu_cut
    assert [d["kind"] for d in captures(run(cmd, "--json", whole))[0]["devices"]] == ["eclink_pnio"]
    for two_pass in (False, True):
        notes = tshark.experts(path, two_pass=two_pass)
        assert [n for n, msgs in sorted(notes.items()) if any("cut by the capture" in m for m in msgs)][:2] == [1, 2]
        tshark.expect(path, 1, {"mcmb2.connect_cut": True}, two_pass=two_pass)
    proc = run(cmd, "--json", "--expect", "eclink", path)
    assert proc.returncode == 1
    cap = captures(proc)[0]
    assert cap["devices"] == []
    assert [(e["frame"], e["device"], e["severity"], e["text"].split(" at ")[0]) for e in cap["timeline"]] == [
        (1, None, "note", "PNIO-CM request cut by the capture"), (2, None, "note", "PNIO-CM response cut by the capture")]
    assert all("its layout cannot be read" in e["text"] for e in cap["timeline"])
    assert (cap["held"]["profinet"]["undecoded"], cap["held"]["profinet"]["connect_cut"]) == (40, 1)
    assert proc.stderr == (
        "vrshark-report: %s: expected EC-Link, none found (42 frames read; the capture holds no Modbus/TCP "
        "(no TCP frame at all); 40 PROFINET cyclic frames (FrameID 0x8042) formed no device: the "
        "capture cut the Connect in frame 1 and 20 of 40 PROFINET frames cut by the capture at 100 bytes "
        "(snaplen); a known layout decodes them: -o mcmb2.layouts, docs/profinet.md)\n" % path)
    text = run(cmd, path).stdout.splitlines()
    assert text[3] == "  no device decoded: tshark's notes in the timeline"
    assert text[-1].startswith("     0.001       2  note      [-]  PNIO-CM response cut by the capture at 100 of ")
    # the gate counts them: not a silent pass
    assert run(cmd, "--fail-on", "note", path).returncode == 1


def test_short_profinet_excerpt_says_so(cmd, work):
    """Four cyclic frames of a base (editcap -r): too few to decide. Only
    tshark's second pass knows the capture ends there, so the report reads
    such a capture again in two passes: a candidate with the frame count and
    the setting, instead of "no traffic"."""
    path = editcap(work, "four.pcap", "-r", CAPTURES / "mcmb2_duplex_noconnect.pcap", "1-4")
    setting = "mcmb2.layouts:0xc010/0xc011=duplex:8/4@4"
    short = ("too few frames to decide: 4 of 0xc010/0xc011 in 0.101 s, about 31 needed (watchdogs moving "
             "twice: 1 s, SP-14-023 2.4)")
    proc = run(cmd, "--expect", "eglink,mcmb2", path)
    assert proc.returncode == 1
    assert proc.stdout.splitlines()[-1] == (
        "     0.000       1  warning   [1]  cyclic frames of PROFINET IO 00:30:11:00:00:02 to 00:1b:1b:00:00:01 "
        "(FrameID 0xc010, 0xc011) look like an MC-MB2-PN or EC-Link device but were not recognised: %s; "
        "to decode it: -o %s" % (short, setting))
    # (no UDP at all: no hint about UDP ports)
    assert proc.stderr == (
        "vrshark-report: %s: expected EG-Link and MC-MB2-PN, none found (4 frames read; the capture holds no UDP "
        "(no UDP frame at all); not recognised, to decode: -o %s)\n" % (path, setting))
    out = work / "four.xml"
    run(cmd, "--junit", out, path)
    names = [case.get("name") for case in ET.parse(out).getroot().iter("testcase")]
    assert "no vrshark traffic" not in names and "no device decoded" not in names


def test_pnio_cm_is_no_udp_for_eglink(cmd):
    """A PROFINET capture whose only UDP is its Connect (PNIO-CM, port
    34964): no hint that EG-Link may be on another UDP port."""
    path = CAPTURES / "eclink_pnio_connect.pcap"
    proc = run(cmd, "--expect", "eglink", path)
    assert proc.returncode == 1
    assert proc.stderr == (
        "vrshark-report: %s: expected EG-Link, none found (82 frames read; the capture holds no UDP but "
        "PROFINET's PNIO-CM (2 frames, UDP port 34964))\n" % path)


def test_foreign_profinet_is_no_traffic(cmd):
    """Another vendor's PROFINET with its Connect (a public capture): whole
    frames tshark did not find shaped like ours are nobody's of ours, and the
    report says so, as before, with no hint to decode them."""
    path = PUBLIC / "pnio_connect_and_cyclic.pcap"
    if not path.exists():
        pytest.skip("../shared/captures/public is not beside the checkout")
    proc = run(cmd, path)
    assert (proc.returncode, proc.stdout.splitlines()[2:]) == (0, ["  no EG-Link, EC-Link or MC-MB2-PN traffic found"])


@pytest.fixture(scope="module")
def plant():
    """The pymodbus plant of test_eclink_modbus_realstack.py under dumpcap."""
    from test_eclink_modbus_realstack import captured
    yield from captured()


def test_cut_modbus_names_the_cut(cmd, work, plant):
    """The pymodbus plant cut at 100 bytes with its port already set: the
    ADUs were cut, not missed; the hint says so, never to set the port."""
    from test_eclink_modbus_realstack import PORT
    path = editcap(work, "plant_s100.pcapng", "-s", 100, plant[0], None)
    setting = "eclink_modbus.port:%d" % PORT
    whole = captures(run(cmd, "--json", "-o", setting, plant[0]))[0]
    assert "eclink_modbus" in [d["kind"] for d in whole["devices"]]
    proc = run(cmd, "--json", "--expect", "eclink", "-o", setting, path)
    assert proc.returncode == 1
    cap = captures(proc)[0]
    assert PORT in cap["held"]["tcp"]["cut_ports"]
    line = proc.stderr.splitlines()[0]
    assert "the capture cut its Modbus/TCP ADUs: %d of %d TCP frames cut by the capture at 100 bytes (snaplen), " \
           "on port " % (cap["held"]["tcp"]["cut"], cap["held"]["tcp"]["frames"]) in line
    assert "no port setting reads them, capture without a snaplen" in line
    assert "-o eclink_modbus.port" not in line


# --- "-": standard output -----------------------------------------------------------------

@pytest.mark.parametrize("option", ["--junit", "--html"])
def test_dash_is_standard_output(cmd, work, option):
    """`--junit -` and `--html -` write onto standard output (no file named -),
    instead of the text report; two outputs there are a usage error."""
    if option == "--html":
        pytest.importorskip("plotly", reason="plotly is not installed (tools/setup installs it)")
    proc = run(cmd, option, "-", "--fail-on", "error", BAD_CRC)
    assert proc.returncode == 1
    assert not (Path(cmd.cwd) / "-").exists()
    if option == "--junit":
        root = ET.fromstring(proc.stdout.encode())
        assert (root.tag, root.get("failures")) == ("testsuites", "1")
    else:
        assert proc.stdout.startswith("<!DOCTYPE html>") and "bad CRC" in proc.stdout
    proc = run(cmd, option, "-", "--json", BAD_CRC)
    assert (proc.returncode, proc.stdout) == (2, "")
    assert proc.stderr.splitlines()[-1] == ("vrshark-report: error: only one of --json, --html - and --junit - "
                                            "can write to standard output")
