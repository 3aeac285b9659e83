"""docs/findings.md "How findings read" is the source: every row, on every protocol it
names, read as a user reads the capture (two passes, as the GUI), against
the independent list of where each fault happened (findings_faults.py):

- the expert field sits on exactly the frames of the fault, with the row's
  severity and group;
- the Info column of those frames carries one of the row's tags;
- the row's colour rule colours them (or a rule of greater danger above it
  in the profile), and the row's filter button shows them.
"""
import re

import pytest

from conftest import ROOT, expert_infos, profile_buttons, profile_rules
from findings_faults import FAULTS

SEVERITY = {"2097152": "chat", "4194304": "note", "6291456": "warning", "8388608": "error"}
GROUP = {"16777216": "Checksum", "33554432": "Sequence", "50331648": "Response code",
         "83886080": "Undecoded", "117440512": "Malformed", "150994944": "Protocol"}
PROTOCOLS = ["EG-Link", "EC-Link", "MC-MB2-PN"]


def table_rows():
    text = (ROOT / "docs" / "findings.md").read_text()
    section = text[text.index("## How findings read"):]
    section = section[:section.index("\n## ", 4)]
    lines = [ln for ln in section.splitlines() if ln.startswith("|")]
    header = [c.strip() for c in lines[0].strip("|").split("|")]
    rows = []
    for ln in lines[2:]:
        cells = dict(zip(header, [c.strip() for c in ln.strip("|").split("|")]))
        fields = {}
        for proto in PROTOCOLS:
            names = re.findall(r"`([^`]+)`", cells[proto])
            # eclink_* is both EC-Link transports
            fields[proto] = [n.replace("*", t) for n in names
                             for t in (("modbus", "pnio") if "*" in n else ("",))]
        rows.append({"finding": cells["finding"], "severity": cells["severity, group"].split(", ")[0],
                     "group": cells["severity, group"].split(", ")[1],
                     "tags": re.findall(r"`(\[[^`]+\])`", cells["Info tag"]),
                     # the profile names its rules "vrshark: <the name the table gives>"
                     "colour": cells["colour rule"] and "vrshark: " + cells["colour rule"],
                     "button": cells["button"], "fields": fields})
    return rows


ROWS = table_rows()


def tag_pattern(tag):
    """[PCI stalled 0.700 s] -> a pattern for any time: numbers vary."""
    return re.compile(re.sub(r"\d+(?:\.\d+)?", r"\\d+(?:\\.\\d+)?", re.escape(tag).replace("\\ ", " ")))


def test_table_is_complete():
    """Every row names at least one expert field; every field has its fault
    in the independent list; colour rules and buttons exist."""
    rules = dict(profile_rules())
    assert len(ROWS) >= 15
    for row in ROWS:
        names = [n for proto in PROTOCOLS for n in row["fields"][proto]]
        assert names, row["finding"]
        assert [n for n in names if n not in FAULTS] == [], row["finding"]
        assert row["severity"] in SEVERITY.values() and row["group"] in GROUP.values(), row["finding"]
        assert not row["colour"] or row["colour"] in rules, row["finding"]
        assert not row["button"] or row["button"] in dict(profile_buttons()), row["finding"]
    # the kinds every protocol has read alike on all three
    for finding in ("Uplink watchdog, PCI or PCO stalled", "Undefined state or status",
                    "Contract deviation that does not force the safe state (spare not 0, IOPS/IOCS not GOOD)"):
        row = next(r for r in ROWS if r["finding"] == finding)
        assert [p for p in PROTOCOLS if not row["fields"][p]] in ([], ["EG-Link"]), finding


@pytest.fixture(scope="module")
def matching(tshark):
    """matching(capture, filter): the set of frames the display filter shows (two passes)."""
    cache = {}

    def get(capture, flt):
        if (capture, flt) not in cache:
            cache[capture, flt] = set(tshark.frames(ROOT / "captures" / capture, [], two_pass=True,
                                                    display_filter=flt))
        return cache[capture, flt]
    return get


@pytest.fixture(scope="module")
def experts(tshark):
    """{capture: {frame: [(expert name, severity, group)]}} (two passes)."""
    cache = {}

    def get(capture):
        if capture not in cache:
            out = {}
            for frame, name, severity, group, _, _ in expert_infos(
                    tshark.json(ROOT / "captures" / capture, two_pass=True)):
                out.setdefault(frame, []).append((name, SEVERITY.get(severity), GROUP.get(group, group)))
            cache[capture] = out
        return cache[capture]
    return get


def _cases():
    for row in ROWS:
        for proto in PROTOCOLS:
            for name in row["fields"][proto]:
                yield pytest.param(row, name, id=name)


@pytest.mark.parametrize("row,name", list(_cases()))
def test_finding_reads_as_the_table_says(tshark, experts, matching, row, name):
    capture, frames = FAULTS[name]
    found = experts(capture)
    on = sorted(f for f, es in found.items() if any(e[0] == name for e in es))
    assert on == frames, "%s in %s" % (name, capture)
    for f in frames:
        kinds = {(s, g) for n, s, g in found[f] if n == name}
        assert kinds == {(row["severity"], row["group"])}, (name, f)
    if row["tags"]:
        info = tshark.frames(ROOT / "captures" / capture, ["_ws.col.Info"], two_pass=True)
        patterns = [tag_pattern(t) for t in row["tags"]]
        for f in frames:
            assert any(p.search(info[f]["_ws.col.Info"]) for p in patterns), (name, f, info[f])
    if row["colour"]:
        rules = profile_rules()
        rank = [n for n, _ in rules].index(row["colour"])
        for f in frames:
            first = next((i for i, (_, flt) in enumerate(rules) if f in matching(capture, flt)), None)
            assert first is not None and first <= rank, (name, f, first is not None and rules[first][0])
    if row["button"]:
        shown = matching(capture, dict(profile_buttons())[row["button"]])
        assert [f for f in frames if f not in shown] == [], (name, row["button"])
