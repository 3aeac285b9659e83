"""JUnit XML for CI systems: one test suite per capture, one test case per device.

A device's test case fails when it has a timeline entry at or above the gate
severity (--fail-on, warning when not given); an unreadable capture is a test
case with an <error>. Each failure lists the entries with their frame numbers.
"""
import xml.etree.ElementTree as ET

from .catalog import severity_at_least


def document(reports, threshold):
    root = ET.Element("testsuites", name="vrshark-report")
    totals = {"tests": 0, "failures": 0, "errors": 0}
    for rep in reports:
        suite = ET.SubElement(root, "testsuite", name=rep["capture"])
        counts = {"tests": 0, "failures": 0, "errors": 0}
        if rep["error"]:
            case = ET.SubElement(suite, "testcase", name="read capture", classname=rep["capture"])
            ET.SubElement(case, "error", message=rep["error"], type="capture").text = rep["error"]
            counts["tests"] += 1
            counts["errors"] += 1
        for dev in rep["devices"]:
            case = ET.SubElement(suite, "testcase", name=dev["name"], classname=rep["capture"],
                                 time="%.3f" % max(0.0, dev["end"] - dev["start"]))
            counts["tests"] += 1
            bad = [e for e in rep["timeline"]
                   if e["device"] == dev["id"] and severity_at_least(e["severity"], threshold)]
            if bad:
                counts["failures"] += 1
                first = bad[0]
                message = "%d finding(s) at or above %s; first in frame %d: %s" % (
                    len(bad), threshold, first["frame"], first["text"])
                failure = ET.SubElement(case, "failure", message=message, type=first["severity"])
                failure.text = "\n".join("frame %d  %.3f s  %s  %s" % (
                    e["frame"], e["time"], e["severity"], e["text"]) for e in bad)
        if not rep["devices"] and not rep["error"]:
            ET.SubElement(suite, "testcase", name="no vrshark traffic", classname=rep["capture"])
            counts["tests"] += 1
        for key, value in counts.items():
            suite.set(key, str(value))
            totals[key] += value
    for key, value in totals.items():
        root.set(key, str(value))
    return ET.ElementTree(root)


def write(reports, path, threshold):
    tree = document(reports, threshold)
    ET.indent(tree)
    tree.write(path, encoding="utf-8", xml_declaration=True)
