"""Devices, safety timeline and plot series of one capture, built row by row.

Capture.add() takes the rows of rows.Rows in frame order; Capture.finish()
closes what is still open and returns a plain dict (see docs/report.md, JSON
schema) that every output format reads. Memory grows with the number of
devices, timeline entries and plot buckets, never with the number of frames.
"""
import datetime
import re

from . import catalog, health
from .catalog import ERROR, NOTE, WARNING
from .details import DETAILS
from .rows import COL, EXPERT_FIELDS

BU_STATES = {0x00: "Initial", 0x01: "Stopped", 0x02: "External link error", 0x03: "Blocked",
             0x04: "Failed", 0x10: "Disarmed", 0x11: "Armed"}
RU_STATES = {0: "Initial", 1: "Disarmed", 2: "Armed", 3: "Enabled", 4: "Stopped"}
DUPLEX_STATUS = {0x0: "absent", 0x1: "present", 0x2: "blocked", 0x7: "active stop",
                 0xA: "fieldbus update failure (E010)"}
POLLED_STATUS = {0xA: "fieldbus update failure (E010)", 0xF: "normal mode"}
SLOT_STATUS = {0x0: "absent", 0x1: "present", 0x2: "blocked", 0x7: "active stop", 0xF: "not used"}
# A state the capture does not hold (the frame cut before its byte): unknown,
# never read as 0.
NOT_CAPTURED = "not captured"

BURST_GAP = 2.0     # s: the same finding again within this time joins its burst
PLOT_BUCKETS = 2000  # points kept per plotted series (min/max per time bucket)

# Limits in seconds; the names are the tshark preferences that change them.
DEFAULT_LIMITS = {
    "eglink.vrpi_gap_ms": 0.5, "eglink.vrpo_gap_ms": 2.0,
    "mcmb2.uplink_timeout": 1.0, "mcmb2.downlink_timeout": 2.0,
    "eclink.pci": 0.5, "eclink.pco": 2.0,
    # not a limit: the EG-Link input ports (each + 2 is an output port), to
    # tell a device found on its ports from one found by the heuristic
    "eglink.input_port": "5825",
    # nor this: the Modbus/TCP servers decoded as BUs without evidence
    "eclink_modbus.servers": "",
    # nor these: the Modbus/TCP ports, to tell a server from its client
    "eclink_modbus.port": "502", "mbtcp.tcp.port": "502",
}

EXPERT_START = len(COL) - len(EXPERT_FIELDS)
C = {name.replace(".", "_"): i for name, i in COL.items()}
# Columns read on every EG-Link row (the busiest protocol).
EG_TYPE, EG_STREAM, EG_CRC = C["eglink_type"], C["eglink_analysis_bu_stream"], C["eglink_crc_status"]
EG_ALONE = C["eglink_analysis_joined_alone"]
EG_BU, EG_RU, EG_ARMED = C["eglink_bu_state"], C["eglink_ru_state"], C["eglink_armed_ru"]
EG_JOYSTICKS = [(i, C["eglink_joystick%d" % i]) for i in range(1, 5)]
EG_INTERVALS = [("VRPI", C["eglink_analysis_time_since_prev_vrpi"], "eglink.vrpi_gap_ms"),
                ("VRPO", C["eglink_analysis_time_since_prev_vrpo"], "eglink.vrpo_gap_ms")]
EG_DPORT = C["udp_dstport"]
TCP_SPORT = C["tcp_srcport"]
TCP_FIN, TCP_RST = C["tcp_flags_fin"], C["tcp_flags_reset"]
MODBUS_CANDIDATE, PNIO_CANDIDATE = C["eclink_modbus_candidate_setting"], C["mcmb2_candidate_setting"]
CONNECT_CUT = C["mcmb2_connect_cut"]  # (an expert field: a Connect the capture cut)
FRAME_LEN, CAP_LEN, PN_FRAME_ID = C["frame_len"], C["frame_cap_len"], C["pn_rt_frame_id"]
MCMB2_ITEM, MESSAGES, SEVERITIES = C["mcmb2"], C["_ws_expert_message"], C["_ws_expert_severity"]
# Findings the shared clock (lua/vrshark/deadlines.luam) puts on the first
# frame after a deadline, whosever frame it is: a BU's image stream that
# stopped, its TCP connection that ended. Their message names the BU; the
# finding is filed under that device, not under the frame's.
ABOUT_BU = [EXPERT_START + EXPERT_FIELDS.index(name) for name in (
    "eclink_modbus.input_missing", "eclink_modbus.output_missing",
    "eclink_modbus.connection_closed", "eclink_modbus.connection_reset") if name in EXPERT_FIELDS]
# ... and a PROFINET stream that stopped: its link names the stream's last
# frame, which is the last frame of that stream in the report too.
ABOUT_PN = [EXPERT_START + EXPERT_FIELDS.index(name) for name in (
    "mcmb2.uplink_missing", "mcmb2.downlink_missing", "mcmb2.data_hold_exceeded",
    "eclink_pnio.input_missing", "eclink_pnio.output_missing", "eclink_pnio.data_hold_exceeded")
    if name in EXPERT_FIELDS]
PN_SINCE = (C["mcmb2_missing_since"], C["eclink_pnio_missing_since"])
BU_NAMED = re.compile(r"\bBU (\d+\.\d+\.\d+\.\d+|[0-9a-fA-F:]+):(\d+)\b")
# tshark's expert severities (_ws.expert.severity), note and above
SEVERITY_CODES = {0x00400000: NOTE, 0x00600000: WARNING, 0x00800000: ERROR}
# PROFINET RT FrameIDs of cyclic data (classes 3, 2 and 1); above: alarms, DCP
CYCLIC_IDS = range(0x0100, 0xFC00)
PNIO_CM_PORT = "34964"
PROFINET_TYPE = "0x8892"
# The longest a run of a base or a BU may take to show what makes it one
# (lua/vrshark/pnio_infer.luam's need_of: an EC-Link BU's PCO moving twice,
# TS-0007 8.4, 4 s), with a margin for the frames' pace.
SHORT_RUN = 4.5
# tshark's words on the frames of such a run that has the shape of ours
SHORT_NOTE = re.compile(r"too few frames to decide: [^;]*")   # (the EtherType; a frame the capture cut may have no FrameID)
# (an expert field: TCP data from inside an ADU of a BU's connection, a frame with no image)
MID_ADU = C["eclink_modbus_mid_adu"]
LAYOUT_INFERRED = ("mcmb2.layout.inferred", "eclink_pnio.layout.inferred")
# A failed command (its warning, or the note that its deadline passed): the
# field that links to the command's frame.
FAILED_LINKS = {
    "eglink.analysis.vrci": "eglink.analysis.failed_command",
    "eglink.analysis.vrco": "eglink.analysis.failed_command",
    "eclink_modbus.cmd_from_ru": "eclink_modbus.cmd_from_ru_in",
    "eclink_modbus.cmd_to_ru": "eclink_modbus.cmd_to_ru_in",
    "eclink_pnio.cmd_from_ru": "eclink_pnio.cmd_from_ru_in",
    "eclink_pnio.cmd_to_ru": "eclink_pnio.cmd_to_ru_in",
}


def limits_from_prefs(prefs):
    """DEFAULT_LIMITS with the `-o name:value` preferences (milliseconds) applied."""
    limits = dict(DEFAULT_LIMITS)
    for pref in prefs:
        name, _, value = pref.partition(":")
        if name in ("eglink.input_port", "eclink_modbus.servers", "eclink_modbus.port", "mbtcp.tcp.port"):
            limits[name] = value
        elif name in limits:
            try:
                limits[name] = float(value) / 1000.0
            except ValueError:
                pass
    return limits


def num(text):
    """An integer as tshark prints it (decimal or 0x..); the last of several."""
    if "," in text:
        text = text.rsplit(",", 1)[1]
    return int(text, 0)


def last(text):
    return text.rsplit(",", 1)[-1]


def port_range(text):
    """The ports of a Wireshark range preference ("5825,6000-6010")."""
    ports = set()
    for part in text.split(","):
        low, _, high = part.strip().partition("-")
        try:
            ports.update(range(int(low), int(high or low) + 1))
        except ValueError:
            pass
    return ports


def is_multicast(address):
    first = address.split(".", 1)[0]
    return first.isdigit() and 224 <= int(first) <= 239


def command_of(field):
    """The command a failed-command field speaks of, as in FAILED_LINKS."""
    return field.rsplit("_", 1)[0] if field.startswith("eglink") else field.rsplit(".", 1)[0]


def fmt_s(seconds):
    return "%.3f s" % seconds


def fmt_ms(seconds):
    return "%d ms" % round(seconds * 1000)


def named(table):
    return lambda v: table.get(v, "undefined 0x%02X" % v)


def slot_text(value):
    status, terminal = value
    if status == 0xF:
        return SLOT_STATUS[0xF]
    return "terminal %d %s" % (terminal, named(SLOT_STATUS)(status))


def ru_change(old, new):
    if old[1] == new[1] and new[1]:
        return "RU 0x%04x state %s -> %s" % (new[1], named(RU_STATES)(old[0]), named(RU_STATES)(new[0]))
    return "RU state %s -> %s" % (ru_text(old), ru_text(new))


def ru_text(value):
    state, armed = value
    return "%s (%s)" % (named(RU_STATES)(state), "RU 0x%04x" % armed if armed else "no RU armed")


class Series:
    """Points of one plotted value, at most PLOT_BUCKETS time buckets.

    Each bucket keeps its first, lowest, highest and last value, so a short
    blip (a BU Blocked for one packet in an hour) still shows; when the
    buckets run out, the bucket width doubles and neighbours merge.
    """

    def __init__(self, group, limit=None, labels=None):
        self.group, self.limit, self.labels = group, limit, labels
        self.width = 0.0
        self.buckets = []   # [t, first, low, high, last]
        self.value = self.pending = None

    def add(self, t, v):
        """A point; a run of equal values keeps only its first and last point."""
        if v == self.value:
            self.pending = t
            return
        if self.pending is not None:
            self._add(self.pending, self.value)
            self.pending = None
        self.value = v
        self._add(t, v)

    def flush(self):
        if self.pending is not None:
            self._add(self.pending, self.value)
            self.pending = None

    def _add(self, t, v):
        b = self.buckets
        if b and (t - b[-1][0] < self.width or t == b[-1][0]):
            cur = b[-1]
            cur[2] = min(cur[2], v)
            cur[3] = max(cur[3], v)
            cur[4] = v
            return
        b.append([t, v, v, v, v])
        if len(b) > PLOT_BUCKETS:
            self._merge()

    def _merge(self):
        t0 = self.buckets[0][0]
        self.width = max(self.width * 2, (self.buckets[-1][0] - t0) / (PLOT_BUCKETS / 2))
        merged = []
        for bucket in self.buckets:
            if merged and bucket[0] - merged[-1][0] < self.width:
                cur = merged[-1]
                cur[2] = min(cur[2], bucket[2])
                cur[3] = max(cur[3], bucket[3])
                cur[4] = bucket[4]
            else:
                merged.append(list(bucket))
        self.buckets = merged

    def points(self):
        ts, vs = [], []
        for t, first, low, high, end in self.buckets:
            for v in (first, low, high, end) if low != high else (first,):
                if not vs or vs[-1] != v or ts[-1] != t:
                    ts.append(round(t, 6))
                    vs.append(v)
        return ts, vs

    def to_dict(self):
        self.flush()
        ts, vs = self.points()
        out = {"group": self.group, "t": ts, "v": vs}
        if self.limit is not None:
            out["limit"] = self.limit
        if self.labels:
            out["labels"] = {str(k): v for k, v in sorted(self.labels.items())}
        return out


class Entry:
    """One timeline line: a state change, a condition with its length, or a
    finding (a burst of the same finding counts its occurrences)."""
    __slots__ = ("time", "frame", "device", "severity", "kind", "field", "what", "detail",
                 "count", "last_frame", "last_time", "duration", "end_frame", "end_time", "at_least",
                 "lost", "since", "values", "stream")

    def __init__(self, device, frame, t, severity, kind, what, field=None, detail=""):
        self.device, self.frame, self.time = device, frame, t
        self.severity, self.kind, self.what, self.field = severity, kind, what, field
        self.detail = detail
        self.count, self.last_frame, self.last_time = 1, frame, t
        self.duration = self.end_frame = self.end_time = None
        self.at_least = False
        self.lost = 0
        self.since = t   # when the condition began (a stall or gap: before it was flagged)
        self.values = []  # a finding: the distinct values it named (details.py)
        self.stream = None  # the stream of the frame that carries it (health.py)

    def close(self, frame, t, duration=None):
        self.end_frame, self.end_time = frame, t
        self.duration = t - self.time if duration is None else duration

    def text(self):
        what = self.what
        if self.lost:
            what = "%d packet%s lost" % (self.lost, "" if self.lost == 1 else "s")
        if self.values:
            what += self.values[0]
            if len(self.values) > 1:
                what += " and %d other value%s" % (len(self.values) - 1, "" if len(self.values) == 2 else "s")
        if self.duration is not None and self.kind != "stopped":   # (its text names the time itself)
            length = fmt_s(self.duration) + (" or more" if self.at_least else "")
            what += (" (after %s)" if self.kind == "state" else " for %s") % length
        if self.detail:
            what += " (%s)" % self.detail
        if self.count > 1:
            what += " (%dx, frames %d-%d over %s)" % (
                self.count, self.frame, self.last_frame, fmt_s(self.last_time - self.time))
        if self.kind in ENDED:
            what += (", until the end of the capture" if self.end_frame is None
                     else ", " + ENDED[self.kind] % self.end_frame)
        return what

    def to_dict(self):
        return {"time": round(self.time, 6), "frame": self.frame, "device": self.device.id,
                "severity": self.severity, "kind": self.kind, "field": self.field,
                "text": self.text(), "count": self.count, "last_frame": self.last_frame,
                "duration": None if self.duration is None else round(self.duration, 6),
                "end_frame": self.end_frame,
                "end_time": None if self.end_time is None else round(self.end_time, 6)}


class CaptureLevel:
    """The "device" of an entry that belongs to no device: a note tshark
    gave on frames of which no device formed (a cut Connect)."""
    id = None


ENDED = {"relays": "closed in frame %d", "stall": "moving again in frame %d",
         "gap": "received again in frame %d"}


class Device:
    def __init__(self, ident, kind, frame, t):
        self.id, self.kind = ident, kind
        self.name = self.layout = ""
        self.address = {}
        self.first_frame = self.last_frame = frame
        self.first_time = self.last_time = t
        self.frames = 0
        self.states = {}      # name: [value, since_time, since_frame, first]
        self.initial = {}     # name: text of the first value seen
        self.formats = {}     # name: value -> text
        self.counters = {}    # name: [value, since_time, since_frame]
        self.open = {}        # condition name: open Entry (relays, stalls, gaps)
        self.bursts = {}      # expert field: its latest Entry
        self.last_seen = {}   # what: (frame, time), for gaps
        self.series = {}
        self.terminals = {}   # MC-MB2: number: [first_frame, last_frame, first_t, last_t, frames, slots]
        self.raw_state = None   # EG-Link: the last VRPI's state columns
        self.stream = None      # EG-Link: the analysis stream of the BU, once known
        self.ports = set()      # EG-Link: the UDP destination ports of its packets
        self.uncaptured = {}    # state name: [first, last, count] of the frames without it since
                                # its last captured value (a cut frame)
        self.streams = {}       # name: health.Stream, in the order first seen
        self.closed = None      # Modbus/TCP: (frame, time, text) of a FIN or RST of its connection

    def not_captured(self, name, frame):
        """A frame that should carry the state but was cut before it."""
        rec = self.uncaptured.get(name)
        if rec is None:
            rec = self.uncaptured[name] = [frame, frame, 0]
            self.initial.setdefault(name, NOT_CAPTURED)
        rec[1] = frame
        rec[2] += 1

    def final(self, name):
        """The state at the end: its last value, or what was not captured after it."""
        state, rec = self.states.get(name), self.uncaptured.get(name)
        if rec is None:
            return self.formats[name](state[0])
        if state is None:
            return NOT_CAPTURED
        return "%s from frame %d on (before: %s)" % (NOT_CAPTURED, rec[0], self.formats[name](state[0]))

    def plot(self, name, group, t, v, limit=None, labels=None):
        s = self.series.get(name)
        if s is None:
            s = self.series[name] = Series(group, limit, labels)
        s.add(t, v)

    def to_dict(self, series=True, streams=()):
        out = {"id": self.id, "kind": self.kind, "name": self.name, "address": self.address,
               "layout": self.layout, "frames": self.frames,
               "first_frame": self.first_frame, "last_frame": self.last_frame,
               "start": round(self.first_time, 6), "end": round(self.last_time, 6),
               "initial": self.initial,
               "final": {k: self.final(k) for k in self.initial},
               "not_captured": {k: {"first_frame": r[0], "last_frame": r[1], "frames": r[2]}
                                for k, r in self.uncaptured.items()},
               "streams": list(streams)}
        if self.kind == "mcmb2":
            out["terminals"] = [
                {"terminal": n, "first_frame": v[0], "last_frame": v[1], "start": round(v[2], 6),
                 "end": round(v[3], 6), "frames": v[4], "slots": sorted(v[5])}
                for n, v in sorted(self.terminals.items())]
        if series:
            out["series"] = {k: s.to_dict() for k, s in self.series.items()}
        return out


class Capture:
    """The report model of one capture; add() every row, then finish()."""

    def __init__(self, path, limits=None):
        self.path = str(path)
        self.limits = limits or dict(DEFAULT_LIMITS)
        self.frames = 0
        self.tcp_frames = 0         # (none: the capture holds no Modbus/TCP at all)
        self.first_epoch = None
        # where the capture's time steps back, the step counts as no time,
        # as in the dissectors (vrshark/handshake.luam clock()): the seconds
        # every later frame is moved forward, and the previous frame's time
        self._clock_shift, self._prev_epoch = 0.0, None
        self.last_time = 0.0
        self.last_frame = 0
        self.devices = {}
        self.entries = []
        self._ids = 0
        self._eglink_channels = {}  # EG-Link channel: its first BU (see _eglink_device)
        self._eglink_apart = {}     # EG-Link controller not joined to a BU: [device, BU it joined later]
        self._eglink_orphans = {}   # (group, controller) on a port of its own: its _eglink_apart key
        # EG-Link controller whose packets are its BU's only for the two being alone on the
        # channel so far: what they gave that BU (_eglink_withdraw)
        self._eglink_alone = {}
        self._failed = {}           # (device, command field, command frame): its entry
        self.candidates = {}        # connection or PROFINET run: what its candidate notes say
        self._pnio_decoded = {}     # PROFINET run (pair of MAC addresses): last frame decoded
        self._connect_cut = None    # the first Connect the capture cut (snaplen): its frame
        self._cut = False           # the current frame was cut by the capture (snaplen)
        # what the capture holds, for the hints (expect.py): frames and cut
        # frames per transport, the cut frames' TCP server ports, the
        # PROFINET cyclic frames that formed no device and no candidate
        self.held = {name: {"frames": 0, "cut": 0} for name in ("udp", "pnio_cm", "tcp", "profinet")}
        self._undecoded = {}        # PROFINET run (pair of MAC addresses): [frames, FrameIDs] of no device
        self.snaplen = None         # the longest cut frame's captured length
        self._cut_ports = set()
        self._notes = {}            # (severity, message without its numbers): latest Entry
        self._stream = None         # the stream of the current frame (health.py)
        self._about = ()            # this frame's columns of findings filed under another BU

    # --- rows ---------------------------------------------------------------

    def add(self, c):
        # Any file tshark opens gives rows, some without a time or even a
        # number (a text file read as one frame): such a frame takes the
        # time of the frame before it.
        frame = int(c[0]) if c[0].isdigit() else self.last_frame + 1
        epoch = float(c[1]) if c[1] else (self.first_epoch or 0.0) + self.last_time
        if self.first_epoch is None:
            self.first_epoch = epoch
        if self._prev_epoch is not None and epoch < self._prev_epoch:
            self._clock_shift += self._prev_epoch - epoch
        self._prev_epoch = epoch
        t = epoch - self.first_epoch + self._clock_shift
        self.frames += 1
        self.last_time, self.last_frame = t, frame
        if c[TCP_SPORT]:
            self.tcp_frames += 1
        self._cut = bool(c[FRAME_LEN] and c[CAP_LEN]) and int(c[CAP_LEN]) < int(c[FRAME_LEN])
        held = self._held(c)
        self._about = self._about_bu(c, frame, t) if any(len(c) > i and c[i] for i in ABOUT_BU) else ()
        if any(len(c) > i and c[i] for i in ABOUT_PN):
            self._about = frozenset(self._about) | self._about_pn(c, frame, t)
        formed = True
        self._stream, entries = None, len(self.entries)
        if c[C["eglink_type"]]:
            self._eglink(c, frame, t)
        elif c[C["mcmb2_direction"]]:
            self._mcmb2(c, frame, t)
        elif c[C["eclink_pnio_layout"]]:
            self._eclink_pnio(c, frame, t)
        elif c[C["eclink_modbus_table"]] or c[C["eclink_image"]] or (len(c) > MID_ADU and c[MID_ADU]):
            self._eclink_modbus(c, frame, t)
        else:
            formed = False
        if c[MODBUS_CANDIDATE] or c[PNIO_CANDIDATE]:
            self._candidate(c, frame, t)
        elif not formed:
            frame_id = num(c[PN_FRAME_ID]) if c[PN_FRAME_ID] else None
            if held == "profinet" and (frame_id in CYCLIC_IDS or frame_id is None and self._cut):
                run = self._undecoded.setdefault(frozenset((c[C["eth_src"]], c[C["eth_dst"]])), [0, set(), t, t])
                run[0] += 1
                run[1].update([frame_id] if frame_id is not None else [])
                run[3] = t
            # (a frame of no device that carries only a device's stream that
            # stopped: filed under that device above, no note of no device)
            if c[MCMB2_ITEM] and c[MESSAGES] and not self._about:
                self._capture_notes(c, frame, t)
        if len(c) > CONNECT_CUT and c[CONNECT_CUT] and self._connect_cut is None:
            self._connect_cut = frame
        if self._stream is not None:
            for entry in self.entries[entries:]:
                entry.stream = entry.stream or self._stream
        if c[TCP_FIN] == "1" or c[TCP_RST] == "1" or c[TCP_FIN] == "True" or c[TCP_RST] == "True":
            self._tcp_close(c, frame, t)

    def _tcp_close(self, c, frame, t):
        """A FIN or RST of a connection to a recognised BU: the first after
        its last image is kept (a connection that ends while the capture goes
        on without the BU's images is a finding, see finish)."""
        ends = ((c[C["ip_src"]], int(c[TCP_SPORT])), (c[C["ip_dst"]], int(c[C["tcp_dstport"]] or 0)))
        for i, server in enumerate(ends):
            dev = self.devices.get(("eclink_modbus",) + server)
            if dev is None:
                continue
            if dev.closed is None or dev.closed[0] < dev.last_frame:
                how = "reset (RST)" if c[TCP_RST] in ("1", "True") else "closed (FIN)"
                client = "%s:%d" % ends[1 - i]
                dev.closed = (frame, t, "connection %s to %s:%d %s by the %s in frame %d at %.3f s" % (
                    client, server[0], server[1], how, "BU" if i == 0 else "PLC", frame, t))
            return

    def _held(self, c):
        """Counts the frame by its transport; the transport's name."""
        # (PROFINET's PNIO-CM, UDP port 34964 either way, is no UDP that EG-Link could be on)
        name = ("pnio_cm" if PNIO_CM_PORT in (c[EG_DPORT], c[C["udp_srcport"]]) else "udp" if c[EG_DPORT]
                else "tcp" if c[TCP_SPORT]
                else "profinet" if PROFINET_TYPE in (c[C["eth_type"]], c[C["vlan_etype"]]) else None)
        if name is None:
            return None
        self.held[name]["frames"] += 1
        if self._cut:
            self.held[name]["cut"] += 1
            self.snaplen = max(self.snaplen or 0, int(c[CAP_LEN]))
            if name == "tcp":
                ports = {int(c[TCP_SPORT]), int(c[C["tcp_dstport"]] or 0xFFFF)}
                decoded = ports & port_range(self.limits["eclink_modbus.port"])
                self._cut_ports.add(min(decoded or ports))
        return name

    def _capture_notes(self, c, frame, t):
        """tshark's expert infos (note and above) on a frame that formed no
        device, as tshark words them: what the capture shows of a run no
        device came from (a Connect it cut)."""
        severities = [SEVERITY_CODES.get(int(v)) for v in c[SEVERITIES].split(",") if v]
        messages = re.split(r",(?=[A-Z])", c[MESSAGES])
        if len(messages) != len(severities):   # (a comma of the messages' own)
            messages = [c[MESSAGES]]
            severities = [max(filter(None, severities), key=catalog.LEVELS.get, default=None)]
        for severity, text in zip(severities, messages):
            if severity is None:
                continue
            key = (severity, re.sub(r"\d+", "#", text))
            entry = self._notes.get(key)
            if entry is not None and t - entry.last_time <= BURST_GAP:
                entry.count += 1
                entry.last_frame, entry.last_time = frame, t
                continue
            entry = self._notes[key] = Entry(CaptureLevel, frame, t, severity, "finding", text)
            self.entries.append(entry)

    def _new_device(self, key, kind, frame, t):
        self._ids += 1
        dev = self.devices[key] = Device(self._ids, kind, frame, t)
        return dev

    def _device(self, key, kind, frame, t):
        dev = self.devices.get(key)
        if dev is None:
            dev = self._new_device(key, kind, frame, t)
        dev.frames += 1
        dev.last_frame, dev.last_time = frame, t
        return dev

    def _eglink(self, c, frame, t):
        typ = c[EG_TYPE]
        stream = c[EG_STREAM]
        dev = self.devices.get(stream) if stream else None
        if dev is None:
            dev = self._eglink_device(c, typ, stream, frame, t)
        alone = None
        if typ.endswith("O") and (c[EG_ALONE] or not stream) and dev.address.get("bu", "") is not None:
            alone = self._eglink_alone.setdefault(self._eglink_controller_key(c, typ),
                                                  {"bu": dev, "frames": 0, "first": (frame, t),
                                                   "ports": set(), "entries": []})
            alone["frames"] += 1
            alone["ports"].add(c[EG_DPORT])
            entries = len(self.entries)
        if self._eglink_apart and stream and typ.endswith("O"):
            apart = self._eglink_apart.get(self._eglink_controller_key(c, typ))
            if apart is None:  # first seen on a port of its own (see _eglink_device)
                apart = self._eglink_apart.get(self._eglink_orphans.get((c[C["ip_dst"]], c[C["ip_src"]])))
            if apart is not None and apart[1] is None and apart[0] is not dev:
                apart[1] = dev  # joined now: its packets before are this BU's
        dev.ports.add(c[EG_DPORT])
        dev.frames += 1
        dev.last_frame, dev.last_time = frame, t
        good = c[EG_CRC] != "0"
        if typ == "VRPI" and good:
            raw = (c[EG_BU], c[EG_RU], c[EG_ARMED])
            if raw != dev.raw_state or not all(raw):  # most VRPI repeat the state: nothing to do
                dev.raw_state = raw
                self._safety(dev, frame, t, *[num(v) if v else None for v in raw])
            for i, col in EG_JOYSTICKS:
                if c[col]:
                    dev.plot("joystick %d" % i, "value", t, num(c[col]))
        for what, col, limit in EG_INTERVALS:
            if c[col]:
                dev.plot(what + " interval", "age", t, float(c[col]), self.limits[limit])
        self._experts(dev, c, frame, t)
        if alone is not None:
            alone["entries"] += self.entries[entries:]
        if typ == "VRPI" or typ == "VRPO":
            if good:
                dev.last_seen[typ] = (frame, t)
            # (a packet with a bad CRC is a frame of its stream all the same:
            # its sender is not silent, the CRC is a finding of its own)
            self._stream = health.stream(dev, typ, self.limits)
            self._stream.add(frame, t)
        if "bu" not in dev.address and typ.endswith("I"):  # the BU's own packets
            dev.address.update(bu=c[C["ip_src"]], group=c[C["ip_dst"]], port=int(c[EG_DPORT] or 0))
        elif "controller" not in dev.address and typ.endswith("O"):
            dev.address["controller"] = c[C["ip_src"]]
        if "origin" not in dev.address:  # the BU's, or as the analysis learned it
            origin = c[C["eglink_origin"]] if typ.endswith("I") else c[C["eglink_analysis_bu_origin"]]
            if origin and num(origin):
                dev.address["origin"] = "0x%04x" % num(origin)

    def _eglink_device(self, c, typ, stream, frame, t):
        """The BU a packet belongs to: by its analysis stream (the BU's origin
        and address on its channel). A packet without one, a controller's
        before the analysis joined it to its BU (in one pass every packet
        before the BU's first VRPI), goes to the first BU of its channel
        (multicast group, or the address pair, and input port); the first
        stream seen on a channel takes over the packets that came before it.
        A controller the analysis does not join to a BU while its channel
        has one (several BUs or controllers share it, and no command was
        acknowledged between them) is a device of its own: the capture does
        not tell which BU it serves, and the report does not guess: once
        the analysis withdraws a join that rested only on the controller
        being alone with the channel's BU, its packets from before are its
        own too (_eglink_withdraw). Joined later (an acknowledgement), its
        packets go to that BU after all (_eglink_join_apart)."""
        port = int(c[EG_DPORT] or 0)
        dst, src = c[C["ip_dst"]], c[C["ip_src"]]
        channel = self._eglink_channel(c, typ)
        dev = self._eglink_channels.get(channel)
        if not stream and typ.endswith("O") and dev is not None and dev.stream is not None:
            key = self._eglink_controller_key(c, typ)
            ctrl = self.devices.get(key)
            if ctrl is None:
                ctrl = self._new_device(key, "eglink", frame, t)
                ctrl.address = {"group": dst, "port": port, "controller": src, "bu": None}
                self._eglink_apart[key] = [ctrl, None]
            if key in self._eglink_alone:
                self._eglink_withdraw(self._eglink_alone.pop(key), ctrl)
            return ctrl
        if dev is None or (stream and dev.stream is not None):
            dev = self._new_device(stream or ("eglink", channel), "eglink", frame, t)
            dev.address = {"group": dst, "port": port}
            self._eglink_channels.setdefault(channel, dev)
            if not stream and typ.endswith("O") and channel[1] not in port_range(
                    self.limits.get("eglink.input_port", "5825")):
                # A controller on a port that fits no BU (yet): the analysis
                # joins it to the BU of its group it turns up with later (an
                # excerpt starting with a packet sent to a wrong port), and
                # so does the report.
                self._eglink_apart[("eglink", channel)] = [dev, None]
                self._eglink_orphans[(dst, src)] = ("eglink", channel)
        if stream:
            dev.stream = stream
            self.devices[stream] = dev
        return dev

    @staticmethod
    def _eglink_channel(c, typ):
        """(multicast group or address pair, input port) of an EG-Link row."""
        port = int(c[EG_DPORT] or 0)
        dst, src = c[C["ip_dst"]], c[C["ip_src"]]
        return (dst if is_multicast(dst) else frozenset((src, dst)),
                port if typ.endswith("I") else port - 2)

    def _eglink_controller_key(self, c, typ):
        return ("eglink controller", self._eglink_channel(c, typ), c[C["ip_src"]])

    @staticmethod
    def _eglink_withdraw(alone, ctrl):
        """A controller joined to its BU only for the two being alone on the
        channel, whose join the analysis withdrew (a second BU or controller
        there): its packets before are its own too, as two passes show, not
        that BU's (its frames, ports, VRPO intervals and findings)."""
        bu = alone["bu"]
        bu.frames -= alone["frames"]
        ctrl.frames += alone["frames"]
        ctrl.first_frame, ctrl.first_time = alone["first"]
        bu.ports -= alone["ports"] - {str(bu.address.get("port"))}
        ctrl.ports |= alone["ports"]
        if bu.address.get("controller") == ctrl.address["controller"]:
            del bu.address["controller"]
        for name in ("VRPO interval",):
            if name in bu.series:
                ctrl.series[name] = bu.series.pop(name)
        if "VRPO" in bu.last_seen:
            ctrl.last_seen["VRPO"] = bu.last_seen.pop("VRPO")
        if "VRPO" in bu.streams:
            ctrl.streams["VRPO"] = bu.streams.pop("VRPO")
        for entry in alone["entries"]:
            entry.device = ctrl
            for field, latest in list(bu.bursts.items()):
                if latest is entry:
                    ctrl.bursts[field] = bu.bursts.pop(field)

    def _eglink_join_apart(self):
        """A controller listed apart that the analysis joined to a BU later
        (a command acknowledged between them): its packets before are that
        BU's too."""
        for key, (ctrl, bu) in self._eglink_apart.items():
            if bu is None:
                continue
            bu.frames += ctrl.frames
            if (ctrl.first_frame, ctrl.first_time) < (bu.first_frame, bu.first_time):
                bu.first_frame, bu.first_time = ctrl.first_frame, ctrl.first_time
            bu.ports |= ctrl.ports
            bu.address.setdefault("controller", ctrl.address["controller"])
            for name, s in ctrl.streams.items():
                bu.streams.setdefault(name, s)   # (a stream of both: the BU's own is kept)
            for entry in self.entries:
                if entry.device is ctrl:
                    entry.device = bu
            for name, series in ctrl.series.items():
                mine = bu.series.get(name)
                if mine is None:
                    bu.series[name] = series
                    continue
                series.flush()
                mine.flush()
                joined = Series(mine.group, mine.limit, mine.labels)
                for ts, vs in (series.points(), mine.points()):
                    for point in zip(ts, vs):
                        joined.add(*point)
                bu.series[name] = joined
            del self.devices[key]

    def _eglink_layout(self, dev):
        """Which ports it was seen on, and how: on the input ports of the
        preference (or 2 above), or found by the heuristic on other ports."""
        inputs = port_range(self.limits.get("eglink.input_port", "5825"))
        ports = sorted(int(p) for p in dev.ports if p)
        how = ["by port" if p in inputs or p - 2 in inputs else "heuristic" for p in ports]
        dev.address["ports"] = ports
        if len(set(how)) == 1:
            listed = ", ".join(map(str, ports)) + ": " + how[0]
        else:
            listed = ", ".join("%d (%s)" % ph for ph in zip(ports, how))
        return "TS-0006 on UDP port%s %s" % ("s" if len(ports) > 1 else "", listed)

    def _modbus_server(self, c):
        named = c[C["eclink_modbus_server"]]
        if named:
            # (the dissector's "address:port", the first of a frame's ADUs)
            addr, port = named.split(",")[0].rsplit(":", 1)
            return addr, int(port)
        sport, dport = int(c[C["tcp_srcport"]] or 0), int(c[C["tcp_dstport"]] or 0)
        # (a frame with no server named, a candidate's: the side on a Modbus/TCP
        # port, else the lower port, a client's being ephemeral)
        ports = port_range(self.limits["eclink_modbus.port"]) | port_range(self.limits["mbtcp.tcp.port"])
        if (sport in ports) != (dport in ports):
            return (c[C["ip_src"]], sport) if sport in ports else (c[C["ip_dst"]], dport)
        if c[C["eclink_modbus_request_in"]] or (sport and sport < dport):
            return c[C["ip_src"]], sport
        return c[C["ip_dst"]], dport

    def _candidate(self, c, frame, t):
        """A frame the dissector says looks like a device's it did not decode."""
        if c[MODBUS_CANDIDATE]:
            server = self._modbus_server(c)
            # (two noted ADUs in one frame: the values joined by commas, and
            # a port list has commas of its own: the last value)
            value = c[MODBUS_CANDIDATE]
            setting = value[value.rfind("eclink_modbus."):]
            key = ("eclink_modbus",) + server
        else:
            macs = (c[C["eth_src"]], c[C["eth_dst"]])
            key, setting = ("pnio", frozenset(macs)), c[PNIO_CANDIDATE]
        rec = self.candidates.get(key)
        if rec is None:
            rec = self.candidates[key] = {"first_frame": frame, "start": t, "frames": 0,
                                          "frame_ids": set()}
            if key[0] == "pnio":
                rec["macs"] = macs
        if key[0] == "pnio" and "short" not in rec:
            # (an excerpt too short to decide: tshark's note says how short)
            short = SHORT_NOTE.search(c[MESSAGES]) if len(c) > MESSAGES else None
            if short:
                rec["short"] = short.group(0)
        rec.update(last_frame=frame, end=t, setting=setting)  # (a layouts entry has commas)
        rec["frames"] += 1
        if c[C["pn_rt_frame_id"]]:
            rec["frame_ids"].add(num(c[C["pn_rt_frame_id"]]))

    def _pnio_run(self, c, frame):
        self._pnio_decoded[frozenset((c[C["eth_src"]], c[C["eth_dst"]]))] = frame

    def _eclink_modbus(self, c, frame, t):
        server = self._modbus_server(c)
        dev = self._device(("eclink_modbus",) + server, "eclink_modbus", frame, t)
        if not dev.name:
            dev.name = "EC-Link BU, Modbus/TCP server %s:%d" % server
            dev.address = {"server": server[0], "port": server[1]}
        accepted = c[C["eclink_modbus_accepted_in"]]
        if not dev.layout and c[C["eclink_image"]]:
            # (an entry may name the BU's mode after "=": 192.168.2.41:502=standard)
            listed = [e.split("=")[0] for e in self.limits.get("eclink_modbus.servers", "").replace(" ", "").split(",")]
            dev.layout = ("heuristic, recognised in frame %s" % last(accepted) if accepted
                          else "listed in eclink_modbus.servers"
                          if server[0] in listed or "%s:%d" % server in listed
                          else "detection always")
        self._eclink_image(dev, c, frame, t, "eclink_modbus")

    def _eclink_pnio(self, c, frame, t):
        images = c[C["eclink_image"]]
        mac = c[C["eth_dst"]] if images.startswith("output") else c[C["eth_src"]]
        dev = self._device(("eclink_pnio", mac), "eclink_pnio", frame, t)
        if not dev.name:
            dev.name = "EC-Link BU, PROFINET device %s" % mac
            dev.address = {"mac": mac}
            dev.layout = c[C["eclink_pnio_layout"]]
        self._pnio_run(c, frame)
        self._eclink_image(dev, c, frame, t, "eclink_pnio")

    def _eclink_image(self, dev, c, frame, t, transport):
        images = c[C["eclink_image"]]
        for name in ("input", "output"):
            if name in images:
                self._stream = health.stream(dev, name, self.limits, self._stream_suffix(c, transport))
                self._stream.add(frame, t)
        if "input" in images:
            self._poll(dev, "input image", frame, t, self.limits["eclink.pci"])
            self._safety(dev, frame, t, *[num(c[C[name]]) if c[C[name]] else None
                                          for name in ("eclink_bu_state", "eclink_ru_state",
                                                       "eclink_armed_ru")])
            for i in range(1, 5):
                value = c[C["eclink_joystick%d" % i]]
                if value:
                    dev.plot("joystick %d" % i, "value", t, num(value))
            if c[C["eclink_pci"]]:
                self._counter(dev, "PCI", num(c[C["eclink_pci"]]), frame, t)
        if "output" in images and c[C["eclink_pco"]]:
            self._counter(dev, "PCO", num(c[C["eclink_pco"]]), frame, t)
        for name, limit in (("pci", "eclink.pci"), ("pco", "eclink.pco")):
            age = c[C["%s_%s_age" % (transport, name)]]
            if last(age):
                dev.plot("%s age" % name.upper(), "age", t, float(last(age)), self.limits[limit])
        self._experts(dev, c, frame, t)

    @staticmethod
    def _stream_suffix(c, transport):
        """What names a stream beside its direction: its FrameID, the Modbus unit."""
        if transport == "eclink_modbus":
            unit = c[C["mbtcp_unit_id"]]
            return " (unit %d)" % num(unit) if unit else ""
        return " 0x%04x" % num(c[PN_FRAME_ID]) if c[PN_FRAME_ID] else ""

    def _mcmb2(self, c, frame, t):
        uplink = c[C["mcmb2_direction"]] == "uplink"
        mac = c[C["eth_src"]] if uplink else c[C["eth_dst"]]
        dev = self._device(("mcmb2", mac), "mcmb2", frame, t)
        self._stream = health.stream(dev, "uplink" if uplink else "downlink", self.limits,
                                     self._stream_suffix(c, "mcmb2"))
        self._stream.add(frame, t)
        system = c[C["mcmb2_system"]]
        if not dev.name:
            dev.name = "MC-MB2-PN %s base %s" % (system, mac)
            dev.address = {"mac": mac, "system": system}
            dev.layout = c[C["mcmb2_layout"]]
        self._pnio_run(c, frame)
        age = c[C["mcmb2_watchdog_age"]]
        if uplink:
            self._poll(dev, "uplink frame", frame, t, self.limits["mcmb2.uplink_timeout"])
            if c[C["mcmb2_uplink_watchdog"]]:
                self._counter(dev, "uplink watchdog", num(c[C["mcmb2_uplink_watchdog"]]), frame, t)
            if age:
                dev.plot("uplink watchdog age", "age", t, float(age), self.limits["mcmb2.uplink_timeout"])
            self._mcmb2_status(dev, c, frame, t, system)
        else:
            if c[C["mcmb2_downlink_watchdog"]]:
                self._counter(dev, "downlink watchdog", num(c[C["mcmb2_downlink_watchdog"]]), frame, t)
            if age:
                dev.plot("downlink watchdog age", "age", t, float(age),
                         self.limits["mcmb2.downlink_timeout"])
        self._experts(dev, c, frame, t)

    def _mcmb2_status(self, dev, c, frame, t, system):
        if not c[C["mcmb2_status"]]:
            if self._cut:
                dev.not_captured("status", frame)
            return
        status = num(c[C["mcmb2_status"]])
        table = POLLED_STATUS if system == "polled" else DUPLEX_STATUS
        self._transition(dev, "status", status, frame, t, named(table), table)
        if system != "polled":
            terminal = num(c[C["mcmb2_terminal"]] or "0")
            if terminal:
                self._terminal(dev, terminal, None, frame, t)
            return
        slots = c[C["mcmb2_slot"]].split(",")
        statuses = c[C["mcmb2_slot_status"]].split(",")
        terminals = c[C["mcmb2_slot_terminal"]].split(",")
        for slot, st, term in zip(slots, statuses, terminals):
            if not (slot and st and term):
                continue
            st, term = int(st, 0), int(term, 0)
            name = "slot %s" % slot
            self._transition(dev, name, (st, term), frame, t, slot_text)
            dev.plot(name + " status", "state", t, st, labels=SLOT_STATUS)
            if st != 0xF:
                self._terminal(dev, term, int(slot), frame, t)

    @staticmethod
    def _terminal(dev, number, slot, frame, t):
        rec = dev.terminals.get(number)
        if rec is None:
            rec = dev.terminals[number] = [frame, frame, t, t, 0, set()]
        rec[1], rec[3] = frame, t
        rec[4] += 1
        if slot is not None:
            rec[5].add(slot)

    # --- states, conditions, counters -------------------------------------------

    def _transition(self, dev, name, value, frame, t, fmt, labels=None, change=None):
        state = dev.states.get(name)
        if labels is not None:
            dev.plot(name, "state", t, value, labels=labels)
        dev.uncaptured.pop(name, None)
        if state is None:
            dev.states[name] = [value, t, frame, True]
            dev.formats[name] = fmt
            dev.initial.setdefault(name, fmt(value))
            return
        if state[0] == value:
            return
        what = (change(state[0], value) if change
                else "%s %s -> %s" % (name, fmt(state[0]), fmt(value)))
        entry = Entry(dev, frame, t, NOTE, "state", what)
        entry.duration, entry.at_least, entry.end_time = t - state[1], state[3], t
        self.entries.append(entry)
        dev.states[name] = [value, t, frame, False]

    def _safety(self, dev, frame, t, bu, ru, armed):
        """BU and RU state of a BU, and the ES-Link relays they imply. A
        value None is not in the frame: on a frame the capture cut
        (self._cut) it is not captured, and the state it belongs to stays
        what it was, never 0 (no invented change); the armed RU goes with
        the RU state, so a state without it is not captured either."""
        if bu is not None:
            self._transition(dev, "BU state", bu, frame, t, named(BU_STATES), BU_STATES)
        elif self._cut:
            dev.not_captured("BU state", frame)
        if ru is not None and armed is not None:
            self._transition(dev, "RU state", (ru, armed), frame, t, ru_text, change=ru_change)
            dev.plot("RU state", "state", t, ru, labels=RU_STATES)
        elif self._cut:
            dev.not_captured("RU state", frame)
        bu = dev.states.get("BU state", [bu])[0]
        ru = dev.states.get("RU state", [(ru, armed)])[0][0]
        if bu is None:
            return
        cause = ("BU state %s" % named(BU_STATES)(bu) if bu < 0x10
                 else "RU stopped" if ru == 4 else None)
        entry = dev.open.get("relays")
        if cause and entry is None:
            entry = Entry(dev, frame, t, WARNING, "relays", "ES-Link relays open (%s)" % cause)
            self.entries.append(entry)
            dev.open["relays"] = entry
        elif not cause and entry is not None:
            entry.close(frame, t)
            del dev.open["relays"]

    def _counter(self, dev, name, value, frame, t):
        """A counter that must keep moving (watchdog, PCI, PCO); ends its stall."""
        cur = dev.counters.get(name)
        if cur is None or cur[0] != value:
            dev.counters[name] = [value, t, frame]
            stall = dev.open.pop(name, None)
            if stall is not None:
                stall.close(frame, t, t - cur[1])

    def _poll(self, dev, what, frame, t, limit):
        """A gap between two frames of the same kind longer than limit."""
        prev = dev.last_seen.get(what)
        dev.last_seen[what] = (frame, t)
        if prev and t - prev[1] > limit:
            entry = Entry(dev, frame, t, WARNING, "poll_gap", "no " + what,
                          detail="after frame %d, limit %s" % (prev[0], fmt_ms(limit)))
            entry.close(frame, t, t - prev[1])
            self.entries.append(entry)

    # --- expert fields -----------------------------------------------------------

    def _about_bu(self, c, frame, t):
        """The findings of this frame that name a BU's stream or connection,
        filed under that BU (the first BU the messages name that the report
        knows); the columns it filed (the frame's own device skips them)."""
        for m in BU_NAMED.finditer(c[MESSAGES] if len(c) > MESSAGES else ""):
            dev = self.devices.get(("eclink_modbus", m.group(1), int(m.group(2))))
            if dev is None:
                continue
            done = []
            for i in ABOUT_BU:
                if len(c) > i and c[i]:
                    field = EXPERT_FIELDS[i - EXPERT_START]
                    severity, _, what = catalog.EXPERTS[field]
                    before = len(self.entries)
                    self._finding(dev, c, frame, t, field, severity, what)
                    for entry in self.entries[before:]:
                        entry.stream = health.stream_of(dev, entry)
                    done.append(i)
            return frozenset(done)
        return ()

    def _about_pn(self, c, frame, t):
        """The findings of this frame that a PROFINET stream of ours stopped
        (or passed its data hold time), filed under the device whose stream
        ended in the frame their link names; the columns it filed."""
        owners = []
        for col in PN_SINCE:
            for ref in (c[col].split(",") if len(c) > col and c[col] else ()):
                for dev in self.devices.values():
                    for s in dev.streams.values():
                        if s.last_frame == int(ref) and (dev, s) not in owners:
                            owners.append((dev, s))
        done = []
        for i in ABOUT_PN:
            if not (len(c) > i and c[i]):
                continue
            field = EXPERT_FIELDS[i - EXPERT_START]
            words = field.split(".", 1)[1]
            match = [o for o in owners if o[1].name in words] or owners
            if not match:
                continue
            dev, stream = match[0]
            severity, _, what = catalog.EXPERTS[field]
            before = len(self.entries)
            self._finding(dev, c, frame, t, field, severity, what)
            for entry in self.entries[before:]:
                entry.stream = stream
            done.append(i)
        return frozenset(done)

    def _experts(self, dev, c, frame, t):
        tail = c[EXPERT_START:]
        if not any(tail):
            return
        about = self._about
        for i, flag in enumerate(tail):
            if flag and EXPERT_START + i not in about:
                field = EXPERT_FIELDS[i]
                severity, role, what = catalog.EXPERTS[field]
                if role == "finding":
                    self._finding(dev, c, frame, t, field, severity, what)
                elif role == "stall":
                    self._stall(dev, frame, t, field, severity, what)
                elif role == "gap":
                    self._gap(dev, c, frame, t, field, severity, what)
                elif role == "failed" or role == "deadline":
                    self._command_failed(dev, c, frame, t, field, severity, what)

    def _finding(self, dev, c, frame, t, field, severity, what):
        entry = dev.bursts.get(field)
        if entry is not None and t - entry.last_time <= BURST_GAP:
            entry.count += 1
            entry.last_frame, entry.last_time = frame, t
        else:
            if field.endswith("late_ack"):
                what = self._late_ack(c, field, what)
            elif field in LAYOUT_INFERRED and self._connect_cut is not None:
                what = ("layout inferred from the cyclic frames (the capture cut the Connect in frame %d: "
                        "snaplen)" % self._connect_cut)
            entry = dev.bursts[field] = Entry(dev, frame, t, severity, "finding", what, field)
            self.entries.append(entry)
        if field.endswith("serial_gap"):
            entry.lost += int(c[C["eglink_analysis_lost"]] or 0)
        detail = DETAILS.get(field)
        value = detail(c) if detail else ""
        if value and value not in entry.values:
            entry.values.append(value)

    @staticmethod
    def _late_ack(c, field, what):
        """An acknowledgement after the deadline: which command, how late."""
        if field.startswith("eglink"):
            if not c[C["eglink_analysis_ack_time"]]:
                return what
            return "command %s acknowledged after %s (late)" % (
                c[C["eglink_command_id"]], fmt_s(float(c[C["eglink_analysis_ack_time"]])))
        cmd = command_of(field[:-len("_ack")])
        link = c[COL[FAILED_LINKS[cmd]]]
        latency = c[COL[cmd + "_latency"]] if cmd + "_latency" in COL else ""
        if link:
            what = what.replace(" echoed", " of frame %s echoed" % last(link))
        if latency:
            what += " (after %s)" % fmt_s(float(last(latency)))
        if cmd.endswith(".cmd_from_ru"):
            what += ": " + catalog.BAD_DATA
        return what

    def _command_failed(self, dev, c, frame, t, field, severity, what):
        """A command not acknowledged in time: one entry per command. The
        warning stands for it; the note that its deadline passed only when
        the warning is not there (an older plugin's one pass)."""
        cmd = command_of(field)
        link = c[COL[FAILED_LINKS[cmd]]]
        command = int(last(link)) if link else frame  # the warning on the command itself
        key = (dev.id, cmd, command)
        entry = self._failed.get(key)
        text = what.format(of=" of frame %d" % command)
        if entry is None:
            entry = self._failed[key] = Entry(dev, frame, t, severity, "finding", text, field)
            self.entries.append(entry)
        elif catalog.LEVELS[severity] > catalog.LEVELS[entry.severity]:
            entry.severity, entry.what, entry.field = severity, text, field

    def _stall(self, dev, frame, t, field, severity, counter):
        if counter in dev.open:
            return
        cur = dev.counters.get(counter)
        limit = {"PCI": "eclink.pci", "PCO": "eclink.pco", "uplink watchdog": "mcmb2.uplink_timeout",
                 "downlink watchdog": "mcmb2.downlink_timeout"}[counter]
        detail = "limit " + fmt_ms(self.limits[limit])
        what, since = counter + " stalled", t
        if cur is not None:
            what += " at %d" % cur[0]
            since = cur[1]
            detail = "unchanged since frame %d, %s" % (cur[2], detail)
        if counter == "downlink watchdog":
            detail += ": the base shows E010"
        elif counter == "PCO":
            detail += ": " + catalog.BAD_DATA
        entry = Entry(dev, frame, t, severity, "stall", what, field, detail)
        entry.since = since
        dev.open[counter] = entry
        self.entries.append(entry)

    def _gap(self, dev, c, frame, t, field, severity, what):
        name = "gap " + what
        entry = dev.open.get(name)
        if entry is None:
            prev = dev.last_seen.get(what)
            limit = self.limits["eglink.%s_gap_ms" % what.lower()]
            detail = ("after frame %d, " % prev[0] if prev else "") + "limit " + fmt_ms(limit)
            entry = Entry(dev, frame, t, severity, "gap", "no " + what, field, detail)
            entry.since = prev[1] if prev else t
            dev.open[name] = entry
            self.entries.append(entry)
        if field.endswith("_gap"):
            since = c[C["eglink_analysis_time_since_prev_" + what.lower()]]
            entry.close(frame, t, float(since) if since else None)
            del dev.open[name]

    # --- the end -------------------------------------------------------------------

    def _candidates(self):
        """The candidates to list: those whose connection or run was not
        decoded after them (in one pass, a BU's first frames are candidates
        until it is recognised). Each is a device of its own, with a warning."""
        for key, rec in self.candidates.items():
            if key[0] == "eclink_modbus":
                dev = self.devices.get(key)
                if dev is not None and dev.last_frame > rec["last_frame"]:
                    continue
                field = "eclink_modbus.candidate"
                name = "Modbus/TCP server %s:%d" % key[1:]
                address = {"server": key[1], "port": key[2]}
                what = "%s looks like an EC-Link BU but was not recognised" % name
            else:
                if self._pnio_decoded.get(key[1], 0) > rec["last_frame"]:
                    continue
                field = "mcmb2.candidate"
                ids = ", ".join("0x%04x" % i for i in sorted(rec["frame_ids"]))
                name = "PROFINET IO %s to %s%s" % (rec["macs"] + ((" (FrameID %s)" % ids) if ids else "",))
                address = {"macs": sorted(key[1]), "frame_ids": sorted(rec["frame_ids"])}
                what = ("cyclic frames of %s look like an MC-MB2-PN or EC-Link device but were "
                        "not recognised%s" % (name, ": " + rec["short"] if "short" in rec else ""))
            dev = self._new_device(("candidate",) + key, "candidate", rec["first_frame"], rec["start"])
            dev.name = name + ", not decoded"
            dev.address = dict(address, setting=rec["setting"])
            dev.layout = "not recognised; to decode it: -o " + rec["setting"]
            dev.frames, dev.last_frame, dev.last_time = rec["frames"], rec["last_frame"], rec["end"]
            entry = Entry(dev, rec["first_frame"], rec["start"], catalog.EXPERTS[field][0], "finding",
                          "%s; to decode it: -o %s" % (what, rec["setting"]), field)
            entry.last_frame, entry.last_time = rec["last_frame"], rec["end"]
            self.entries.append(entry)

    def _profinet_undecoded(self):
        """The cyclic frames of the PROFINET runs that never formed a device
        or a candidate (a run's first frames before its layout is inferred
        are its device's)."""
        runs = [run for key, run in self._undecoded.items()
                if key not in self._pnio_decoded and ("pnio", key) not in self.candidates]
        return {"undecoded": sum(run[0] for run in runs),
                "frame_ids": sorted(set().union(*[run[1] for run in runs]))}

    def short_profinet(self):
        """True when no device formed and a PROFINET run of no device spans
        less time than the evidence of a base or a BU may take (SHORT_RUN):
        tshark says whether it has their shape only once it has seen the
        whole capture (its second pass), which one pass cannot know."""
        return not self.devices and any(run[3] - run[2] < SHORT_RUN for run in self._undecoded.values())

    def _stopped(self, dev):
        """The streams whose last frame is followed by more capture than their
        limit, and a BU's connection closed or reset while the capture goes
        on without its images: error entries of the device, at the stream's
        last frame (the closing frame)."""
        for s in dev.streams.values():
            tail = self.last_time - s.last_time
            if tail > s.limit:
                s.stopped = tail
                entry = Entry(dev, s.last_frame, s.last_time, ERROR, "stopped", health.stopped_text(s, tail))
                entry.stream, entry.duration, entry.end_time = s, tail, self.last_time
                self.entries.append(entry)
        if dev.closed is not None and dev.closed[0] >= dev.last_frame:
            frame, t, text = dev.closed
            tail = self.last_time - t
            limit = min((s.limit for s in dev.streams.values()), default=self.limits["eclink.pci"])
            if tail > limit:
                entry = Entry(dev, frame, t, ERROR, "stopped",
                              "%s; the capture goes on %.3f s without it" % (text, tail))
                entry.duration, entry.end_time = tail, self.last_time
                self.entries.append(entry)

    def finish(self, error=None):
        """Close what is still open at the end; the report as a plain dict."""
        self._candidates()
        self._eglink_join_apart()
        devices = sorted({id(d): d for d in self.devices.values()}.values(), key=lambda d: d.id)
        for number, dev in enumerate(devices, 1):
            dev.id = number  # (numbers stay consecutive when a device was joined to another)
            for entry in dev.open.values():
                entry.duration = self.last_time - entry.since
                entry.end_time, entry.at_least = self.last_time, True
            for series in dev.series.values():
                if series.group == "state" and series.value is not None:
                    series.pending = dev.last_time
            if dev.kind == "eglink":
                a = dev.address
                sender = a.get("bu") or "controller %s" % a.get("controller", "?")
                if "bu" in a and a["bu"] is None:   # a controller whose BU the capture does not tell
                    dev.name = ("EG-Link controller %s to %s:%d, BU not known (no command acknowledged "
                                "between it and a BU of the group: pairing unknown)"
                                % (a["controller"], a["group"], a["port"]))
                else:
                    dev.name = "EG-Link BU %s (%s to %s:%d)" % (
                        a["origin"] if "origin" in a else "of unknown origin", sender, a["group"], a["port"])
                dev.layout = self._eglink_layout(dev)
        for dev in devices:
            self._stopped(dev)
        entries = sorted(self.entries, key=lambda e: (e.frame, e.time))
        start = (datetime.datetime.fromtimestamp(self.first_epoch, datetime.timezone.utc)
                 if self.first_epoch is not None else None)
        counts = {NOTE: 0, WARNING: 0, ERROR: 0}
        for entry in entries:
            counts[entry.severity] += 1
        return {
            "capture": self.path,
            "error": error,
            "frames": self.frames,
            "tcp_frames": self.tcp_frames,
            "held": {"udp": self.held["udp"], "pnio_cm": self.held["pnio_cm"], "tcp": dict(self.held["tcp"], cut_ports=sorted(self._cut_ports)),
                     "profinet": dict(self.held["profinet"], connect_cut=self._connect_cut,
                                      **self._profinet_undecoded()),
                     "snaplen": self.snaplen},
            "start": start.strftime("%Y-%m-%d %H:%M:%S.%f")[:-3] + " UTC" if start else None,
            "start_epoch": self.first_epoch,
            "duration": round(self.last_time, 6),
            "devices": [d.to_dict(streams=health.rows(d, entries)) for d in devices],
            "timeline": [e.to_dict() for e in entries],
            "counts": counts,
        }
