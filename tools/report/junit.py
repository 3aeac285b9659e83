"""JUnit XML for CI systems: one test suite per capture, one test case per device.

A device's test case fails when it has a timeline entry at or above the gate
severity (--fail-on, warning when not given); an unreadable capture is a test
case with an <error>; an --expect protocol the capture does not hold is a
failing test case of its own. Each failure lists the entries with their frame
numbers. A suite's `time` is how long the report took for the capture (what
JUnit readers take it for); a device's traffic span is in its properties.
"""
import sys
import xml.etree.ElementTree as ET

from . import health, held
from .catalog import severity_at_least
from .expect import summary, title


def properties(case, values):
    props = ET.SubElement(case, "properties")
    for name, value in values:
        ET.SubElement(props, "property", name=name, value=str(value))


def device_case(suite, rep, dev, threshold):
    """The device's test case; True when it fails."""
    case = ET.SubElement(suite, "testcase", name=dev["name"], classname=rep["capture"])
    properties(case, [("kind", dev["kind"]), ("frames", dev["frames"]),
                      ("first_frame", dev["first_frame"]), ("last_frame", dev["last_frame"]),
                      ("traffic_start_s", "%.3f" % dev["start"]),
                      ("traffic_end_s", "%.3f" % dev["end"]),
                      ("traffic_span_s", "%.3f" % max(0.0, dev["end"] - dev["start"]))]
               + [("not_captured", "%s from frame %d" % (name, r["first_frame"]))
                  for name, r in dev.get("not_captured", {}).items()]
               + [("health " + row["stream"], health.summary(row)) for row in dev.get("streams", [])])
    return failures(case, rep, dev["id"], threshold)


def failures(case, rep, device, threshold):
    """The failure of a test case: its entries at or above threshold; True when any."""
    bad = [e for e in rep["timeline"]
           if e["device"] == device and severity_at_least(e["severity"], threshold)]
    if not bad:
        return False
    first = bad[0]
    message = "%d finding(s) at or above %s; first in frame %d: %s" % (
        len(bad), threshold, first["frame"], first["text"])
    failure = ET.SubElement(case, "failure", message=message, type=first["severity"])
    failure.text = "\n".join("frame %d  %.3f s  %s  %s" % (
        e["frame"], e["time"], e["severity"], e["text"]) for e in bad)
    return True


def document(results, threshold):
    """results: [(report, seconds the report took)]."""
    root = ET.Element("testsuites", name="vrshark-report")
    totals = {"tests": 0, "failures": 0, "errors": 0, "skipped": 0}
    for rep, seconds in results:
        suite = ET.SubElement(root, "testsuite", name=rep["capture"])
        counts = {"tests": 0, "failures": 0, "errors": 0, "skipped": 0}
        if rep["error"]:
            case = ET.SubElement(suite, "testcase", name="read capture", classname=rep["capture"])
            ET.SubElement(case, "error", message=rep["error"], type="capture").text = rep["error"]
            counts["tests"] += 1
            counts["errors"] += 1
        for dev in rep["devices"]:
            counts["tests"] += 1
            counts["failures"] += device_case(suite, rep, dev, threshold)
        for name in rep.get("missing", []):
            case = ET.SubElement(suite, "testcase", name="expected " + title(name),
                                 classname=rep["capture"])
            message = summary(rep, [name])   # (the line stderr gives, the setting with it)
            ET.SubElement(case, "failure", message=message, type="expect").text = message
            counts["tests"] += 1
            counts["failures"] += 1
        if any(e["device"] is None for e in rep["timeline"]):
            # (tshark's notes on frames of no device: a Connect the capture cut)
            case = ET.SubElement(suite, "testcase", name="notes of no device", classname=rep["capture"])
            counts["tests"] += 1
            counts["failures"] += failures(case, rep, None, threshold)
        if not rep["devices"] and not rep["error"] and not rep.get("missing"):
            lines = held.no_device(rep)
            if lines[0].startswith("no device decoded"):
                # what the capture shows of traffic it did not decode: not a pass
                case = ET.SubElement(suite, "testcase", name="no device decoded", classname=rep["capture"])
                ET.SubElement(case, "skipped", message="; ".join(lines[1:]) or lines[0])
                counts["skipped"] += 1
            else:
                ET.SubElement(suite, "testcase", name="no vrshark traffic", classname=rep["capture"])
            counts["tests"] += 1
        for key, value in counts.items():
            suite.set(key, str(value))
            totals[key] += value
        suite.set("time", "%.3f" % seconds)
    for key, value in totals.items():
        root.set(key, str(value))
    return ET.ElementTree(root)


def write(results, path, threshold):
    """Into the file path, or onto standard output for "-"."""
    tree = document(results, threshold)
    ET.indent(tree)
    if path == "-":
        tree.write(sys.stdout.buffer, encoding="utf-8", xml_declaration=True)
        sys.stdout.buffer.write(b"\n")
    else:
        tree.write(path, encoding="utf-8", xml_declaration=True)
