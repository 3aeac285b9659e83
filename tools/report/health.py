"""The health rows: one per stream of a device (a device and direction), and
the streams that never come back before the capture ends.

A stream is the frames one side of a device sends at its own pace:

  mcmb2          uplink (the base's), downlink (the controller's), by FrameID
  eclink_pnio    input (the BU's), output (the controller's), by FrameID
  eclink_modbus  input image read, output image written (the PLC's polls)
  eglink         BU VRPI, controller VRPO

Each row gives the stream's frames, its cycle (the intervals between its
frames: min / median / max), its longest silence with the frame that ended
it, and the timeline entries that belong to it: stalls, failed commands and
findings by severity. Memory grows with the distinct intervals (kept to
0.1 ms), not with the frames.

The limit of a stream is the spec limit its dissector uses (the names of
model.DEFAULT_LIMITS, which `-o` changes): a stream whose last frame is
followed by more capture than its limit stopped, an error entry of its
device. A stream cut by the capture's own end within its limit is no
finding: what the capture does not hold is unknown.
"""
from .catalog import ERROR, EXPERTS, NOTE, WARNING

# stream name: (label, limit preference); the label's FrameID or unit follows
STREAMS = {
    "mcmb2": {"uplink": ("uplink", "mcmb2.uplink_timeout"),
              "downlink": ("downlink", "mcmb2.downlink_timeout")},
    "eclink_pnio": {"input": ("input", "eclink.pci"), "output": ("output", "eclink.pco")},
    "eclink_modbus": {"input": ("input image read", "eclink.pci"),
                      "output": ("output image written", "eclink.pco")},
    "eglink": {"VRPI": ("BU VRPI", "eglink.vrpi_gap_ms"), "VRPO": ("controller VRPO", "eglink.vrpo_gap_ms")},
}

# The findings of a stream that stopped or a counter that stalled, by name:
# those the dissectors give now and those being added (counted once they
# exist). The report's own end-of-capture entries (kind "stopped") and its
# Modbus/TCP poll gaps (kind "poll_gap", eclink_modbus.poll_gap measured by
# the model) count too.
STALLS = frozenset([
    "mcmb2.uplink_missing", "mcmb2.downlink_missing",
    "mcmb2.uplink_watchdog.stalled", "mcmb2.downlink_watchdog.stalled", "mcmb2.data_hold_exceeded",
    "eclink_pnio.input_missing", "eclink_pnio.output_missing", "eclink_pnio.data_hold_exceeded",
    "eclink_modbus.input_missing", "eclink_modbus.output_missing", "eclink_modbus.poll_gap",
    "eclink_modbus.pci_stalled", "eclink_modbus.pco_stalled", "eclink_modbus.pco_stalled.guessed",
    "eclink_pnio.pci_stalled", "eclink_pnio.pco_stalled",
    "eglink.analysis.vrpi_gap", "eglink.analysis.vrpi_missing",
    "eglink.analysis.vrpo_gap", "eglink.analysis.vrpo_missing",
])
# A command not acknowledged in time (its warning, or the note that its
# deadline passed: one timeline entry per command).
FAILED = frozenset(name for name, (_, role, _) in EXPERTS.items() if role in ("failed", "deadline"))

# Which stream a finding speaks of, by the words of its name (after the
# protocol): a stream's own counter, a command sent in it, the stream
# missing. A finding whose name has none of them belongs to the stream of
# the frame that carries it.
WORDS = {
    "mcmb2": [("uplink", "uplink"), ("downlink", "downlink")],
    "eclink": [("input", "input"), ("pci", "input"), ("poll_gap", "input"), ("cmd_from_ru", "input"),
               ("output", "output"), ("pco", "output"), ("cmd_to_ru", "output")],
    "eglink": [("vrpi", "VRPI"), ("vrci", "VRPI"), ("vrpo", "VRPO"), ("vrco", "VRPO")],
}

BUCKET = 1e4   # intervals kept to 0.1 ms


class Stream:
    """The frames of one stream: their count, intervals and longest silence."""
    __slots__ = ("name", "label", "limit", "frames", "first_frame", "last_frame", "last_time",
                 "intervals", "low", "high", "silence", "silence_frame", "stopped")

    def __init__(self, name, label, limit):
        self.name, self.label, self.limit = name, label, limit
        self.frames = 0
        self.first_frame = self.last_frame = self.last_time = None
        self.intervals = {}   # interval in 0.1 ms: how many
        self.low = self.high = None
        self.silence, self.silence_frame = 0.0, None
        self.stopped = None   # the capture's time after the last frame, when past the limit

    def add(self, frame, t):
        self.frames += 1
        if self.last_frame is None:
            self.first_frame = frame
        else:
            gap = round(t - self.last_time, 6)   # (capture times are microseconds: no float noise)
            key = round(gap * BUCKET)
            self.intervals[key] = self.intervals.get(key, 0) + 1
            self.low = gap if self.low is None else min(self.low, gap)
            self.high = gap if self.high is None else max(self.high, gap)
            if gap > self.silence:
                self.silence, self.silence_frame = gap, frame
        self.last_frame, self.last_time = frame, t

    def median(self):
        n = sum(self.intervals.values())
        if not n:
            return None
        middle, seen, values = {(n - 1) // 2, n // 2}, 0, []
        for key in sorted(self.intervals):
            count = self.intervals[key]
            values += [key / BUCKET for i in middle if seen <= i < seen + count]
            seen += count
        return sum(values) / len(values)


def stream(dev, name, limits, suffix=""):
    """The device's stream of that name, made at its first frame."""
    s = dev.streams.get(name)
    if s is None:
        label, limit = STREAMS[dev.kind][name]
        s = dev.streams[name] = Stream(name, label + suffix, limits[limit])
    return s


def stream_of(dev, entry):
    """The stream of the device a timeline entry belongs to, or None."""
    field = entry.field or ""
    protocol, _, rest = field.partition(".")
    for word, name in WORDS.get(protocol.split("_")[0], ()):
        if word in rest and name in dev.streams:
            return dev.streams[name]
    s = entry.stream
    return s if s is not None and dev.streams.get(s.name) is s else None


def rows(dev, entries):
    """The health rows of a device (JSON, see docs/report.md)."""
    counts = {id(s): {"stalls": 0, "commands_failed": 0, ERROR: 0, WARNING: 0, NOTE: 0}
              for s in dev.streams.values()}
    late = set()   # streams with a stall entry after their last frame (a dissector's of the stop)
    for entry in entries:
        if entry.device is not dev or entry.kind == "state":
            continue
        s = stream_of(dev, entry)
        if s is None:
            continue
        c = counts[id(s)]
        c[entry.severity] += 1
        if entry.field in STALLS or entry.kind == "poll_gap" and dev.kind == "eclink_modbus":
            c["stalls"] += 1
            if entry.frame > s.last_frame:
                late.add(id(s))
        if entry.field in FAILED:
            c["commands_failed"] += 1
    for entry in entries:
        # the end-of-capture entry is a stall of its own only where no
        # finding of the dissector (a gap still open, a stream missing)
        # already counts the same stop
        if entry.device is dev and entry.kind == "stopped" and entry.stream is not None:
            if id(entry.stream) in counts and id(entry.stream) not in late:
                counts[id(entry.stream)]["stalls"] += 1
    out = []
    for s in dev.streams.values():
        c = counts[id(s)]
        silence = {"s": round(s.silence, 6), "frame": s.silence_frame}
        if s.stopped is not None and s.stopped > s.silence:
            silence = {"s": round(s.stopped, 6), "frame": None}   # (to the end of the capture)
        out.append({
            "stream": s.label, "frames": s.frames, "first_frame": s.first_frame, "last_frame": s.last_frame,
            "limit_ms": round(s.limit * 1000),
            "cycle_ms": None if s.low is None else {
                "min": round(s.low * 1000, 3), "median": round(s.median() * 1000, 3),
                "max": round(s.high * 1000, 3)},
            "longest_silence": silence,
            "stalls": c["stalls"], "commands_failed": c["commands_failed"],
            "findings": {ERROR: c[ERROR], WARNING: c[WARNING], NOTE: c[NOTE]},
        })
    return out


def stopped_text(s, tail):
    return "%s: last frame %d at %.3f s; the capture goes on %.3f s without it (limit %d ms)" % (
        s.label, s.last_frame, s.last_time, tail, round(s.limit * 1000))


# --- how a row reads (text, JUnit, HTML) -----------------------------------------------

def cycle(row):
    c = row["cycle_ms"]
    return "-" if c is None else "%.1f / %.1f / %.1f" % (c["min"], c["median"], c["max"])


def silence(row):
    s = row["longest_silence"]
    if s["frame"] is None and s["s"] == 0:
        return "-"
    return "%.3f s %s" % (s["s"], "to the end" if s["frame"] is None else "to frame %d" % s["frame"])


def findings(row):
    f = row["findings"]
    return "%d/%d/%d" % (f[ERROR], f[WARNING], f[NOTE])


HEADER = ("stream", "frames", "cycle ms min / median / max", "longest silence", "stalls", "failed",
          "findings E/W/N")


def cells(row):
    return (row["stream"], str(row["frames"]), cycle(row), silence(row), str(row["stalls"]),
            str(row["commands_failed"]), findings(row))


def summary(row):
    """One line of a row (JUnit's property value)."""
    return ("frames %d; cycle %s ms; longest silence %s; stalls %d; commands failed %d; "
            "findings %d error, %d warning, %d note" % (
                row["frames"], cycle(row), silence(row), row["stalls"], row["commands_failed"],
                row["findings"][ERROR], row["findings"][WARNING], row["findings"][NOTE]))
