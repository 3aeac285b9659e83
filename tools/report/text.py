"""The text report: per capture its devices, then its timeline, one line per entry."""
from . import health, held


def plural(n, word):
    return "%d %s%s" % (n, word, "" if n == 1 else "s")


def device_lines(dev):
    yield "  [%d] %s" % (dev["id"], dev["name"])
    yield "      frames %d-%d (%d), %.3f s to %.3f s; layout: %s" % (
        dev["first_frame"], dev["last_frame"], dev["frames"], dev["start"], dev["end"],
        dev["layout"] or "unknown")
    if dev["initial"]:
        yield "      first: %s" % ", ".join("%s %s" % kv for kv in dev["initial"].items())
        if dev["final"] != dev["initial"]:
            yield "      last:  %s" % ", ".join("%s %s" % kv for kv in dev["final"].items())
    for term in dev.get("terminals", []):
        slots = ", slot %s" % "/".join(map(str, term["slots"])) if term["slots"] else ""
        yield "      terminal %d%s: frames %d-%d (%d), %.3f s to %.3f s" % (
            term["terminal"], slots, term["first_frame"], term["last_frame"], term["frames"],
            term["start"], term["end"])


def health_lines(rep):
    """The health rows: a table of the streams of every device, columns as wide as their cells."""
    table = [("device",) + health.HEADER]
    table += [("[%d]" % dev["id"],) + health.cells(row) for dev in rep["devices"] for row in dev["streams"]]
    if len(table) == 1:
        return
    widths = [max(len(r[i]) for r in table) for i in range(len(table[0]))]
    yield "health (per stream; cycle: the intervals between its frames):"
    for r in table:
        # (the names left-aligned, the numbers right-aligned)
        yield "  " + "  ".join(cell.ljust(w) if i in (0, 1, 4) else cell.rjust(w)
                               for i, (cell, w) in enumerate(zip(r, widths))).rstrip()


def device(entry):
    """[1], or [-] for a note that belongs to no device (a cut Connect)."""
    return "[%s]" % ("-" if entry["device"] is None else entry["device"])


def capture_lines(rep):
    yield "== %s" % rep["capture"]
    if rep["frames"] == 0 and rep["error"]:
        yield "  %s" % rep["error"]
        return
    yield "%s, %.3f s from %s" % (plural(rep["frames"], "frame"), rep["duration"], rep["start"])
    if rep["error"]:
        yield "  %s: the report covers the frames before it" % rep["error"]
    if held.cut(rep):
        yield "  %s: what they do not hold is not captured" % held.cut(rep)
    if rep["devices"]:
        yield "%s:" % plural(len(rep["devices"]), "device")
    else:
        for line in held.no_device(rep):
            yield "  " + line
        if not rep["timeline"]:
            return
    for dev in rep["devices"]:
        yield from device_lines(dev)
    yield from health_lines(rep)
    counts = rep["counts"]
    if not rep["timeline"]:
        yield "timeline: no state change and no finding"
        return
    yield "timeline (%s: %d error, %d warning, %d note; seconds from the first frame):" % (
        plural(len(rep["timeline"]), "entry").replace("entrys", "entries"),
        counts["error"], counts["warning"], counts["note"])
    yield "      time   frame  severity  device"
    for e in rep["timeline"]:
        yield "%10.3f %7d  %-8s  %s  %s" % (e["time"], e["frame"], e["severity"], device(e), e["text"])


def write(reports, out):
    for i, rep in enumerate(reports):
        if i:
            out.write("\n")
        for line in capture_lines(rep):
            out.write(line + "\n")
