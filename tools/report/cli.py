"""vrshark-report CAPTURE...: the command line.

Exit status: 0 clean (or no --fail-on), 1 a finding at or above --fail-on or
an --expect protocol not found, 2 a usage error or a capture that could not
be read (this wins over 1); 128 + the signal when stopped by SIGTERM, SIGINT
or SIGHUP. Everything that can be checked before tshark runs is (output
folders, plotly, -j, the tshark and its -o/-d options): one line, exit 2.
"""
import argparse
import concurrent.futures
import multiprocessing
import os
import shutil
import stat
import subprocess
import sys
import tempfile
import time

from . import catalog, expect, filetype, jsonout, junit, model, stop, text
from .rows import COL, CaptureError, Rows, first_line, tshark_command

GATES = {"note": catalog.NOTE, "warn": catalog.WARNING, "warning": catalog.WARNING,
         "error": catalog.ERROR}
PROGRESS_AFTER = 1.0  # s: the bar appears only for captures that take longer
ENCAP = COL["frame.encap_type"]
# A pcap file header without packets: what the tshark check reads.
EMPTY_PCAP = bytes.fromhex("d4c3b2a1020004000000000000000000ffff000001000000")

_progress = None  # shared array of per-capture fractions, in the worker processes


def positive(text):
    try:
        value = int(text)
    except ValueError:
        value = 0
    if value < 1:
        raise argparse.ArgumentTypeError("%r is not a number of captures (1 or more)" % text)
    return value


def protocols(text):
    try:
        return expect.names(text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc))


def parse_args(argv):
    ap = argparse.ArgumentParser(
        prog="vrshark-report",
        description="What devices an EG-Link, EC-Link or MC-MB2-PN capture holds, and the "
                    "safety timeline of each: state changes, relays, stalls, findings.",
        epilog="Exit status: 0 clean, 1 a finding at or above --fail-on or an --expect "
               "protocol not found, 2 usage error or unreadable capture (wins over 1), 128+N "
               "ended by signal N. See docs/report.md.")
    ap.add_argument("captures", nargs="+", metavar="CAPTURE",
                    help="capture file (pcap, pcapng, ...), a pipe, or - for standard input")
    ap.add_argument("--json", action="store_true", help="write JSON to standard output instead of text")
    ap.add_argument("--html", metavar="FILE",
                    help="write a self-contained HTML report with plots (- for standard output)")
    ap.add_argument("--junit", metavar="FILE",
                    help="write JUnit XML, one test case per device (- for standard output)")
    ap.add_argument("--fail-on", choices=sorted(GATES), metavar="{note,warn,error}",
                    help="exit 1 when a finding of this severity or higher is present")
    ap.add_argument("--expect", type=protocols, action="extend", default=[],
                    metavar="eglink,eclink,mcmb2",
                    help="exit 1 when a capture holds no device of one of these protocols")
    ap.add_argument("--tshark", metavar="CMD",
                    help="tshark to run (default: tools/tshark in a checkout, else $TSHARK or tshark)")
    ap.add_argument("-o", dest="prefs", action="append", default=[], metavar="NAME:VALUE",
                    help="tshark preference, e.g. -o eglink.vrpi_gap_ms:300 (repeatable)")
    ap.add_argument("-d", dest="decode_as", action="append", default=[], metavar="RULE",
                    help="tshark Decode As rule, e.g. -d tcp.port==5020,eclink_modbus (repeatable)")
    ap.add_argument("-j", "--jobs", type=positive, default=os.cpu_count() or 1,
                    help="captures processed in parallel (default: one per core)")
    ap.add_argument("--no-progress", action="store_true", help="never show the progress bar")
    args = ap.parse_args(argv)
    args.expect = list(dict.fromkeys(args.expect))
    if args.captures.count("-") > 1:
        ap.error("standard input (-) can be read only once")
    if [args.json, args.html == "-", args.junit == "-"].count(True) > 1:
        ap.error("only one of --json, --html - and --junit - can write to standard output")
    return args


def _init_worker(progress):
    global _progress
    _progress = progress
    stop.leave_to_parent()


def read_capture(index, path, tshark, extra, limits, two_pass=None):
    """One tshark run over a capture into its model: (the model, an error)."""
    rows = Rows(path, tshark[0], extra, tshark[1], two_pass)
    cap = model.Capture(path, limits)
    error = None
    try:
        rows.open()
        n = 0
        for cols in rows:
            if n == 0:
                error = filetype.refusal(cols[ENCAP]) if len(cols) > ENCAP else None
                if error:
                    break  # (tshark ends on the closed pipe)
            cap.add(cols)
            n += 1
            if n & 0x1FFF == 0 and _progress is not None:
                _progress[index] = rows.fraction()
        error = error or rows.error
    except CaptureError as exc:
        error = str(exc)
    except OSError as exc:  # (a read that fails after the open)
        error = "cannot read: %s" % (exc.strerror or exc)
    if error and error.startswith("not a network capture"):
        cap = model.Capture(path, limits)
    return cap, error


# A capture read again in two passes (below) is copied first: up to this size.
TWO_PASS_MAX = 16 << 20


def two_pass_copy(path, folder):
    """A copy of a regular capture file of at most TWO_PASS_MAX bytes that
    any user may read (tools/tshark runs tshark as another user), or None."""
    try:
        with open(path, "rb") as src:
            st = os.fstat(src.fileno())
            if not stat.S_ISREG(st.st_mode) or st.st_size > TWO_PASS_MAX:
                return None
            copy = os.path.join(folder, "capture")
            with open(copy, "wb") as dst:
                shutil.copyfileobj(src, dst)
    except OSError:
        return None
    os.chmod(folder, 0o755)
    os.chmod(copy, 0o644)
    return copy


def report_one(index, path, tshark, extra, limits, keep_series):
    """Run tshark on one capture and build its report dict (in a worker
    process); returns (the report, the seconds it took). A capture of which
    no device formed but that holds a short PROFINET run is read again in
    two passes: only after the whole capture does tshark say whether such a
    run has the shape of a base or a BU (an excerpt too short to decide)."""
    start = time.monotonic()
    cap, error = read_capture(index, path, tshark, extra, limits)
    if not error and cap.short_profinet():
        with tempfile.TemporaryDirectory() as folder:
            copy = two_pass_copy(path, folder)
            if copy:
                cap, error = read_capture(index, path, tshark, extra, limits, copy)
    rep = cap.finish(error)
    if not keep_series:
        for dev in rep["devices"]:
            dev.pop("series", None)
    return rep, time.monotonic() - start


class ProgressBar:
    """One line on stderr for the whole run, only on a terminal: the captures
    as tshark reads them, then the HTML report as its plots are built."""

    def __init__(self, progress, names, enabled):
        self.progress, self.names, self.enabled = progress, names, enabled
        self.start = time.monotonic()
        self.shown = False

    def draw(self, done):
        total = sum(1.0 if i in done else self.progress[i] for i in range(len(self.names)))
        self.show(total / len(self.names), "%d/%d captures" % (len(done), len(self.names)))

    def show(self, frac, what):
        if not self.enabled or time.monotonic() - self.start < PROGRESS_AFTER:
            return
        line = "vrshark-report [%-30s] %3d%%  %s" % ("#" * int(frac * 30), frac * 100, what)
        sys.stderr.write("\r" + line[:79].ljust(79))
        sys.stderr.flush()
        self.shown = True

    def clear(self):
        if self.shown:
            sys.stderr.write("\r" + " " * 79 + "\r")
            sys.stderr.flush()


def tshark_options(args):
    extra = []
    for pref in args.prefs:
        extra += ["-o", pref]
    for rule in args.decode_as:
        extra += ["-d", rule]
    return extra


def run_all(args, tshark, bar, progress):
    """[(report, seconds)] of every capture, in the order of the command line."""
    extra = tshark_options(args)
    limits = model.limits_from_prefs(args.prefs)
    ctx = multiprocessing.get_context("fork")
    results = [None] * len(args.captures)
    jobs = max(1, min(args.jobs, len(args.captures)))
    with concurrent.futures.ProcessPoolExecutor(jobs, mp_context=ctx, initializer=_init_worker,
                                                initargs=(progress,)) as pool:
        futures = {pool.submit(report_one, i, path, tshark, extra, limits, bool(args.html)): i
                   for i, path in enumerate(args.captures)}
        done = set()
        pending = set(futures)
        while pending:
            finished, pending = concurrent.futures.wait(pending, timeout=0.2)
            for fut in finished:
                results[futures[fut]] = fut.result()
                done.add(futures[fut])
            bar.draw(done)
    return results


def _die(message):
    sys.stderr.write("vrshark-report: %s\n" % message)
    sys.exit(2)


def check_output(option, path):
    """The file an option writes must be creatable: else one line, exit 2."""
    folder = os.path.dirname(os.path.abspath(path))
    if not os.path.isdir(folder):
        _die("%s %s: no such folder %s" % (option, path, folder))
    if os.path.isdir(path):
        _die("%s %s: is a folder, not a file" % (option, path))
    if not os.access(folder, os.W_OK | os.X_OK) or (os.path.exists(path)
                                                    and not os.access(path, os.W_OK)):
        _die("%s %s: not writable" % (option, path))


def check_tshark(tshark, extra):
    """Run the tshark once on an empty capture with the -o and -d options: a
    tshark that does not run, or refuses an option, is one usage error (exit
    2) instead of the same error on every capture."""
    cmd, env = tshark
    argv = cmd + ["-n", "-r", "-"] + extra
    try:
        proc = subprocess.run(argv, input=EMPTY_PCAP, capture_output=True, env=env)
    except OSError as exc:
        _die("cannot run %s: %s" % (cmd[0], exc.strerror))
    if proc.returncode == 0:
        return
    said = proc.stderr.decode("utf-8", "replace")
    if said.strip():
        _die("%s: %s" % (os.path.basename(cmd[0]), first_line(said).replace("tshark: ", "")))
    _die("%s ended with exit status %d and no message on an empty capture: is it tshark?"
         % (" ".join(cmd), proc.returncode))


def write_stdout(write):
    """The report on standard output. A reader that goes away (| head -1)
    ends the writing, not the run: the gate's lines on stderr, the JUnit
    file and the exit status stay what they would be, so that a pipeline
    under `set -o pipefail` fails as the report alone would. Returns the
    line for output that could not be written otherwise (a full disk), or
    None."""
    try:
        write(sys.stdout)
        sys.stdout.flush()
        return None
    except BrokenPipeError:
        error = None
    except OSError as exc:  # (a full disk, ...: the report is lost, exit 2)
        error = "cannot write the report: %s" % (exc.strerror or exc)
    # (what is still buffered must not be flushed at exit either)
    os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
    return error


def gate(reports, threshold):
    """(findings at or above threshold, the first of them with its capture)."""
    count, first = 0, None
    for rep in reports:
        for e in rep["timeline"]:
            if catalog.severity_at_least(e["severity"], threshold):
                count += 1
                if first is None:
                    first = (rep["capture"], e)
    return count, first


def plotly_step(python=None, apt=None):
    """The one step that gives this python3 plotly: Debian's package for
    Debian's own python3 (pip refuses to install into it), else pip for the
    python3 that runs the report (a venv, another OS)."""
    python = python or sys.executable
    apt = os.path.exists("/etc/debian_version") if apt is None else apt
    if apt and os.path.dirname(python) in ("/usr/bin", "/bin"):
        return "sudo apt-get install python3-plotly"
    return "%s -m pip install plotly" % python


def main(argv=None):
    args = parse_args(sys.argv[1:] if argv is None else argv)
    stop.install()
    # What can fail before any tshark runs, fails first.
    for option, path in (("--html", args.html), ("--junit", args.junit)):
        if path and path != "-":
            check_output(option, path)
    if args.html:
        try:
            from . import html  # plotly is needed for this output only
        except ImportError as exc:
            _die("the HTML report needs plotly (%s): %s" % (exc, plotly_step()))
    tshark = tshark_command(args.tshark)
    check_tshark(tshark, tshark_options(args))

    progress = multiprocessing.get_context("fork").Array("d", len(args.captures), lock=False)
    bar = ProgressBar(progress, args.captures, sys.stderr.isatty() and not args.no_progress)
    results = run_all(args, tshark, bar, progress)
    reports = [rep for rep, _ in results]
    for rep in reports:
        rep["missing"] = expect.missing(rep, args.expect)

    threshold = GATES[args.fail_on] if args.fail_on else None
    count, first = gate(reports, threshold) if threshold else (0, None)
    absent = [rep for rep in reports if rep["missing"]]
    status = 2 if any(rep["error"] for rep in reports) else 1 if count or absent else 0

    page = None
    if args.html:
        page = html.document(reports, lambda done, total: bar.show(done / total,
                                                                   "HTML: plots %d/%d" % (done, total)))
        if args.html != "-":
            html.write(page, args.html)
    bar.clear()
    # Standard output carries one report: the one given "-", else JSON or text.
    if args.html == "-":
        unwritten = write_stdout(lambda out: out.write(page))
    elif args.junit == "-":
        unwritten = write_stdout(lambda out: junit.write(results, "-", threshold or catalog.WARNING))
    else:
        unwritten = write_stdout(lambda out: jsonout.write(reports, out, threshold, status, args.expect)
                                 if args.json else text.write(reports, out))
    if args.junit and args.junit != "-":
        junit.write(results, args.junit, threshold or catalog.WARNING)
    lines = ["%s: %s" % (rep["capture"], rep["error"]) for rep in reports if rep["error"]]
    if unwritten:
        lines.append(unwritten)
        status = 2
    lines += [expect.line(rep) for rep in absent]
    if count:
        lines.append("FAIL (--fail-on %s): %d finding(s) at %s or above; first: %s frame %d: %s" % (
            args.fail_on, count, threshold, first[0], first[1]["frame"], first[1]["text"]))
    try:
        for line in lines:
            sys.stderr.write("vrshark-report: %s\n" % line)
        sys.stderr.flush()
    except BrokenPipeError:  # (2>&1 | head -1: the status still tells)
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stderr.fileno())
    return status
