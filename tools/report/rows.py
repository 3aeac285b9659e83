"""Run tshark once per capture with a fixed field list and yield its rows.

tshark reads the capture from its standard input, an open file of ours: a
tshark that runs as another user (tools/tshark as root) still reads it, and
the file offset it shares with us tells how far it has got (the progress bar).
"-" is our own standard input; a pipe or FIFO is passed on as it is (no
progress: its size is unknown).
Rows are read line by line, so memory does not grow with the capture.
"""
import errno
import os
import re
import stat
import subprocess
import tempfile
from pathlib import Path

from . import catalog

PACKAGE_DIR = Path(__file__).resolve().parent

# Protocol and address fields, in column order; the expert fields follow.
FIELDS = [
    "frame.number", "frame.time_epoch", "frame.encap_type",
    "eth.src", "eth.dst", "ip.src", "ip.dst", "udp.srcport", "udp.dstport", "tcp.srcport", "tcp.dstport",
    # EG-Link
    "eglink.type", "eglink.origin", "eglink.crc.status",
    "eglink.bu_state", "eglink.ru_state", "eglink.armed_ru",
    "eglink.joystick1", "eglink.joystick2", "eglink.joystick3", "eglink.joystick4",
    "eglink.command_id",
    "eglink.analysis.bu_stream", "eglink.analysis.bu_origin", "eglink.analysis.joined_alone",
    "eglink.analysis.lost",
    "eglink.analysis.time_since_prev_vrpi", "eglink.analysis.time_since_prev_vrpo",
    "eglink.analysis.failed_command", "eglink.analysis.ack_time",
    # EC-Link images (Modbus/TCP and PROFINET)
    "eclink.image", "eclink.bu_state", "eclink.ru_state", "eclink.armed_ru",
    "eclink.joystick1", "eclink.joystick2", "eclink.joystick3", "eclink.joystick4",
    "eclink.pci", "eclink.pco",
    "eclink_modbus.table", "eclink_modbus.request_in", "eclink_modbus.accepted_in", "eclink_modbus.server",
    "eclink_modbus.pci_age", "eclink_modbus.pco_age",
    "eclink_pnio.layout", "eclink_pnio.pci_age", "eclink_pnio.pco_age",
    # MC-MB2-PN
    "mcmb2.system", "mcmb2.direction", "mcmb2.layout", "mcmb2.status", "mcmb2.terminal",
    "mcmb2.uplink_watchdog", "mcmb2.downlink_watchdog", "mcmb2.watchdog_age",
    "mcmb2.slot", "mcmb2.slot.status", "mcmb2.slot.terminal",
    # failed commands: the command's frame
    "eclink_modbus.cmd_from_ru_in", "eclink_modbus.cmd_to_ru_in",
    "eclink_modbus.cmd_from_ru_latency", "eclink_modbus.cmd_to_ru_latency",
    "eclink_pnio.cmd_from_ru_in", "eclink_pnio.cmd_to_ru_in",
    # candidates: the setting that decodes them, the PROFINET run's FrameID
    "eclink_modbus.candidate_setting", "mcmb2.candidate_setting", "pn_rt.frame_id",
    # the values findings name (details.py)
    "udp.length", "eglink.size", "eglink.revision", "eglink.spare", "eglink.payload_spare",
    "eglink.vlaps", "eglink.eg_link_status", "eglink.ec_link_status", "eglink.c_link_status",
    "eglink.ru_battery", "eglink.ru_rssi", "eglink.ru_cable", "eglink.ru_docked",
    "eglink.encoder_switch", "eglink.ru_disabled",
    "mcmb2.iops", "mcmb2.iocs", "mcmb2.reserved", "mcmb2.uplink_size", "mcmb2.downlink_size",
    "eglink.analysis.retransmission_of", "eglink.analysis.corrupted_in",
    "eclink.vlaps", "eclink.eg_link_status", "eclink.ec_link_status", "eclink.c_link_status",
    "eclink.ru_battery", "eclink.ru_rssi", "eclink.ru_cable", "eclink.ru_docked",
    "eclink.encoder_switch", "eclink.ru_disabled", "eclink.spare", "eclink.periodic_size",
    "eclink.periodic_block", "eclink_pnio.iops",
    # what the capture holds: a frame cut by the snaplen (its caplen below
    # its length), and the expert infos of a PROFINET run's frames that
    # formed no device (the mcmb2 protocol item: a cut Connect, too few
    # cyclic frames), read by their message as tshark gives it
    "frame.len", "frame.cap_len", "eth.type", "vlan.etype", "mcmb2", "_ws.expert.message", "_ws.expert.severity",
    # the health rows (health.py): the Modbus unit of a stream, the end of a
    # BU's TCP connection
    "mbtcp.unit_id", "tcp.flags.fin", "tcp.flags.reset",
    # a PROFINET stream that stopped, said on another frame: the stream's last frame
    "mcmb2.missing_since", "eclink_pnio.missing_since",
]
EXPERT_FIELDS = list(catalog.EXPERTS)
ALL_FIELDS = FIELDS + EXPERT_FIELDS
COL = {name: i for i, name in enumerate(ALL_FIELDS)}


class CaptureError(Exception):
    """A capture that cannot be read (one line of text)."""


def in_checkout():
    """True when running from a checkout (tools/report beside tools/tshark and lua/)."""
    return (PACKAGE_DIR.parent / "tshark").is_file() and (PACKAGE_DIR.parent.parent / "lua").is_dir()


def tshark_command(explicit=None):
    """(argv, environment) of the tshark to run: --tshark, else the checkout's
    tools/tshark (which runs $TSHARK, default tshark, with the checkout's
    plugins), else $TSHARK, else tshark. A $TSHARK used here is not passed on,
    so that a wrapper that reads it (tools/tshark) does not start itself."""
    env = dict(os.environ)
    if explicit:
        return [explicit], env
    if in_checkout():
        return [str(PACKAGE_DIR.parent / "tshark")], env
    return [env.pop("TSHARK", "") or "tshark"], env


def first_line(text):
    lines = [ln.strip() for ln in text.splitlines() if ln.strip()]
    return lines[0] if lines else "no message"


def explain(stderr, last_frame):
    """One line for what tshark said about an unreadable capture."""
    if "cut short" in stderr and not last_frame:
        return "truncated: the file ends before its first packet"
    if "cut short" in stderr:
        return "truncated: the capture ends in the middle of a packet (after frame %d)" % last_frame
    if "isn't a capture file" in stderr or "unknown file format" in stderr:
        return "not a capture file (pcap or pcapng expected)"
    if "damaged or corrupt" in stderr:
        return "damaged capture file (after frame %d): %s" % (last_frame, first_line(stderr))
    return first_line(stderr).replace("tshark: ", "")


def inherited_fd(name):
    """The open descriptor a name stands for: "-" standard input, /dev/fd/N
    (the shell's <(...)) N itself, used as it is rather than opened again
    (a pipe of another user cannot be); else None."""
    if name == "-":
        return 0
    match = re.fullmatch(r"/(?:dev|proc/self)/fd/(\d+)", name)
    if match:
        try:
            os.fstat(int(match.group(1)))
            return int(match.group(1))
        except OSError:
            return None
    return None


def open_capture(path):
    """The capture file opened for reading, or CaptureError with the reason:
    every way a path cannot be read (no such file, a folder on the way the
    user may not enter, a file without read permission, a directory, a
    symbolic link loop, ...) is one line, never a traceback. The open itself
    decides, not a check before it (Path.exists raises on a folder without
    search permission)."""
    try:
        return open(path, "rb")
    except IsADirectoryError:
        raise CaptureError("is a directory, not a capture file")
    except FileNotFoundError:
        raise CaptureError("no such file")
    except OSError as exc:
        reason = exc.strerror or str(exc)
        if exc.errno == errno.EACCES:
            reason = "permission denied (the file, or a folder on its path, is closed to this user)"
        raise CaptureError("cannot open: %s" % reason)


class Rows:
    """The rows (lists of column strings, see COL) of one capture.

    Iterate once; afterwards `error` holds a one-line description when the
    capture could not be read to its end (rows read before it still count).
    A field this tshark does not know (an older plugin) is left out and its
    column stays empty; a tshark without the vrshark plugins is an error.
    """

    def __init__(self, path, cmd, extra_args=(), env=None, two_pass=None):
        self.path = Path(path)
        # (a copy of the capture that tshark may open itself: read in two
        # passes, which a capture on standard input cannot be)
        self.two_pass = two_pass
        self.cmd = list(cmd)
        self.env = env
        self.extra_args = list(extra_args)
        self.error = None
        self.size = 0
        self.unknown = []   # fields tshark did not know
        self._file = None

    def argv(self):
        source = ["-2", "-r", str(self.two_pass)] if self.two_pass else ["-r", "-"]
        argv = self.cmd + ["-n"] + source + ["-T", "fields", "-E", "separator=/t",
                           "-E", "occurrence=a", "-E", "aggregator=,", "-E", "quote=n"]
        argv += self.extra_args
        for name in ALL_FIELDS:
            if name not in self.unknown:
                argv += ["-e", name]
        return argv

    def open(self):
        p = self.path
        fd = inherited_fd(str(p))
        if fd is not None:
            self._file = os.fdopen(os.dup(fd), "rb")
        else:
            self._file = open_capture(p)
        st = os.fstat(self._file.fileno())
        if not stat.S_ISREG(st.st_mode):
            return  # a pipe, FIFO or device: read as it comes, size unknown
        self.size = st.st_size
        if self.size == 0:
            self._file.close()
            raise CaptureError("empty file, not a capture")

    def fraction(self):
        """How much of the file tshark has read, 0..1 (0 for a pipe)."""
        if not self.size:
            return 0.0
        try:
            return min(1.0, os.lseek(self._file.fileno(), 0, os.SEEK_CUR) / self.size)
        except (OSError, ValueError, AttributeError):
            return 0.0

    def __iter__(self):
        if self._file is None:
            self.open()
        with self._file:
            while True:
                stderr, last = yield from self._run()
                unknown = unknown_fields(stderr) if last == 0 else []
                if not unknown:
                    break
                if {"eglink.type", "eclink.image", "mcmb2.direction"} <= set(unknown):
                    raise CaptureError(
                        "%s does not know the eglink, eclink and mcmb2 fields: install the "
                        "vrshark plugins (cmake --install) or choose a tshark with --tshark"
                        % " ".join(self.cmd))
                self.unknown += unknown
                if self._file.seekable():  # (tshark checks its fields before it reads)
                    self._file.seek(0)
        if self.returncode != 0 or "cut short" in stderr:
            self.error = explain(stderr, last)

    def _run(self):
        """One tshark run: yields rows, returns (its stderr, the last frame number)."""
        missing = [i for i, name in enumerate(ALL_FIELDS) if name in self.unknown]
        # Most rows carry no expert field: their tail of empty columns is cut
        # off unsplit (the model reads a short row as "no expert").
        experts = [n for n in EXPERT_FIELDS if n not in self.unknown]
        empty_tail = "\t" * len(experts) + "\n"
        keep = -len(empty_tail)
        last = 0
        with tempfile.TemporaryFile() as err:
            try:
                proc = subprocess.Popen(self.argv(), stdin=self._file, stdout=subprocess.PIPE,
                                        stderr=err, bufsize=1 << 20, encoding="utf-8",
                                        errors="replace", env=self.env)
            except OSError as exc:
                raise CaptureError("cannot run %s: %s" % (self.cmd[0], exc.strerror))
            with proc:
                for line in proc.stdout:
                    if line.endswith(empty_tail):
                        cols = line[:keep].split("\t")
                    else:
                        cols = line[:-1].split("\t")
                    for i in missing:
                        if i < len(cols):
                            cols.insert(i, "")
                    last = cols[0]
                    yield cols
            self.returncode = proc.returncode
            err.seek(0)
            return err.read().decode("utf-8", "replace"), int(last or 0)


def unknown_fields(stderr):
    """The names in tshark's "Some fields aren't valid" message."""
    if "fields aren't valid" not in stderr:
        return []
    return [ln.strip() for ln in stderr.splitlines() if ln.startswith("\t") and ln.strip()]
