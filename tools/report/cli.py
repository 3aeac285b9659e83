"""vrshark-report CAPTURE...: the command line.

Exit status: 0 clean (or no --fail-on), 1 a finding at or above --fail-on,
2 a usage error or a capture that could not be read (this wins over 1).
"""
import argparse
import concurrent.futures
import multiprocessing
import os
import sys
import time

from . import catalog, jsonout, junit, model, text
from .rows import CaptureError, Rows, tshark_command

GATES = {"note": catalog.NOTE, "warn": catalog.WARNING, "warning": catalog.WARNING,
         "error": catalog.ERROR}
PROGRESS_AFTER = 1.0  # s: the bar appears only for captures that take longer

_progress = None  # shared array of per-capture fractions, in the worker processes


def parse_args(argv):
    ap = argparse.ArgumentParser(
        prog="vrshark-report",
        description="What devices an EG-Link, EC-Link or MC-MB2-PN capture holds, and the "
                    "safety timeline of each: state changes, relays, stalls, findings.",
        epilog="Exit status: 0 clean, 1 a finding at or above --fail-on, 2 usage error or "
               "unreadable capture. See docs/report.md.")
    ap.add_argument("captures", nargs="+", metavar="CAPTURE", help="pcap or pcapng file")
    ap.add_argument("--json", action="store_true", help="write JSON to standard output instead of text")
    ap.add_argument("--html", metavar="FILE", help="write a self-contained HTML report with plots")
    ap.add_argument("--junit", metavar="FILE", help="write JUnit XML (one test case per device)")
    ap.add_argument("--fail-on", choices=sorted(GATES), metavar="{note,warn,error}",
                    help="exit 1 when a finding of this severity or higher is present")
    ap.add_argument("--tshark", metavar="CMD",
                    help="tshark to run (default: tools/tshark in a checkout, else $TSHARK or tshark)")
    ap.add_argument("-o", dest="prefs", action="append", default=[], metavar="NAME:VALUE",
                    help="tshark preference, e.g. -o eglink.vrpi_gap_ms:300 (repeatable)")
    ap.add_argument("-d", dest="decode_as", action="append", default=[], metavar="RULE",
                    help="tshark Decode As rule, e.g. -d tcp.port==5020,eclink_modbus (repeatable)")
    ap.add_argument("-j", "--jobs", type=int, default=os.cpu_count() or 1,
                    help="captures processed in parallel (default: one per core)")
    ap.add_argument("--no-progress", action="store_true", help="never show the progress bar")
    return ap.parse_args(argv)


def _init_worker(progress):
    global _progress
    _progress = progress


def report_one(index, path, tshark, extra, limits, keep_series):
    """Run tshark on one capture and build its report dict (in a worker process)."""
    rows = Rows(path, tshark[0], extra, tshark[1])
    cap = model.Capture(path, limits)
    try:
        rows.open()
        n = 0
        for cols in rows:
            cap.add(cols)
            n += 1
            if n & 0x1FFF == 0 and _progress is not None:
                _progress[index] = rows.fraction()
        error = rows.error
    except CaptureError as exc:
        error = str(exc)
    rep = cap.finish(error)
    if not keep_series:
        for dev in rep["devices"]:
            dev.pop("series", None)
    return rep


class ProgressBar:
    """One line on stderr while captures are read; only on a terminal."""

    def __init__(self, progress, names, enabled):
        self.progress, self.names, self.enabled = progress, names, enabled
        self.start = time.monotonic()
        self.shown = False

    def draw(self, done):
        if not self.enabled or time.monotonic() - self.start < PROGRESS_AFTER:
            return
        total = sum(1.0 if i in done else self.progress[i] for i in range(len(self.names)))
        frac = total / len(self.names)
        bar = "#" * int(frac * 30)
        sys.stderr.write("\rvrshark-report [%-30s] %3d%%  %d/%d captures" % (
            bar, frac * 100, len(done), len(self.names)))
        sys.stderr.flush()
        self.shown = True

    def clear(self):
        if self.shown:
            sys.stderr.write("\r" + " " * 79 + "\r")
            sys.stderr.flush()


def run_all(args, tshark):
    extra = []
    for pref in args.prefs:
        extra += ["-o", pref]
    for rule in args.decode_as:
        extra += ["-d", rule]
    limits = model.limits_from_prefs(args.prefs)
    ctx = multiprocessing.get_context("fork")
    progress = ctx.Array("d", len(args.captures), lock=False)
    bar = ProgressBar(progress, args.captures, sys.stderr.isatty() and not args.no_progress)
    reports = [None] * len(args.captures)
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
                reports[futures[fut]] = fut.result()
                done.add(futures[fut])
            bar.draw(done)
    bar.clear()
    return reports


def _die(message):
    sys.stderr.write("vrshark-report: %s\n" % message)
    sys.exit(2)


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


def main(argv=None):
    args = parse_args(sys.argv[1:] if argv is None else argv)
    reports = run_all(args, tshark_command(args.tshark))

    threshold = GATES[args.fail_on] if args.fail_on else None
    count, first = gate(reports, threshold) if threshold else (0, None)
    status = 2 if any(rep["error"] for rep in reports) else 1 if count else 0

    if args.json:
        jsonout.write(reports, sys.stdout, threshold, status)
    else:
        text.write(reports, sys.stdout)
    sys.stdout.flush()
    if args.junit:
        junit.write(reports, args.junit, threshold or catalog.WARNING)
    if args.html:
        try:
            from . import html  # plotly is needed for this output only
        except ImportError as exc:
            _die("the HTML report needs plotly (%s): pip install -r requirements.txt" % exc)
        html.write(reports, args.html)
    for rep in reports:
        if rep["error"]:
            sys.stderr.write("vrshark-report: %s: %s\n" % (rep["capture"], rep["error"]))
    if count:
        sys.stderr.write("vrshark-report: FAIL (--fail-on %s): %d finding(s) at %s or above; "
                         "first: %s frame %d: %s\n" % (args.fail_on, count, threshold, first[0],
                                                       first[1]["frame"], first[1]["text"]))
    return status
