"""The report's expert catalog (tools/report/catalog.py) against the plugins
and the one source of severities, docs/findings.md "How findings read": every name is
registered, every expert field of our protocols is either in it or known to
be chat-level, its severities are the findings table's and those the
dissectors raise (except the documented promotion of candidates), and
docs/report.md says the same (its severities table is the catalog's, its
kinds and its text example are what the report gives)."""
import re
import sys

import pytest

from conftest import CAPTURES, ROOT
from test_findings_table import PROTOCOLS as TABLE_PROTOCOLS, ROWS

sys.path.insert(0, str(ROOT / "tools"))
from report import catalog  # noqa: E402

PROTOCOLS = ("eglink", "eclink", "eclink_modbus", "eclink_pnio", "mcmb2")
# FT_NONE fields of our protocols the report does not ask for: subtree labels
# and chat-level experts (commands acknowledged, layouts learned, partial access),
# and the one-pass note of an EG-Link controller not joined to a BU yet (the
# report joins it itself, as two passes do).
NOT_FINDINGS = {
    "eglink.analysis.not_joined",
    "eglink.payload", "eglink.analysis", "eglink.fragments", "eclink.partial",
    "eglink.analysis.command", "eglink.analysis.ack", "eglink.analysis.unknown_ack",
    "eclink_modbus.cmd_from_ru", "eclink_modbus.cmd_from_ru.ack", "eclink_modbus.cmd_to_ru",
    "eclink_modbus.cmd_to_ru.ack", "eclink_modbus.periodic.reassembled",
    "eclink_pnio.cmd_from_ru", "eclink_pnio.cmd_from_ru.ack", "eclink_pnio.cmd_to_ru",
    "eclink_pnio.cmd_to_ru.ack", "eclink_pnio.layout.learned", "mcmb2.layout.learned",
    "eclink_pnio.periodic.reassembled",
}
# Candidate notes come with plugins newer than some installs: the report asks
# for them only when the tshark knows them.
OPTIONAL = set(catalog.CANDIDATE_SETTINGS)
SEVERITY = {0x00200000: "chat", 0x00400000: catalog.NOTE, 0x00600000: catalog.WARNING,
            0x00800000: catalog.ERROR}


@pytest.fixture(scope="module")
def registered(tshark):
    out = tshark.run(["-G", "fields"], allow_errors=True).stdout
    names = {}
    for line in out.splitlines():
        parts = line.split("\t")
        if parts[0] == "F" and parts[4] in PROTOCOLS:
            names[parts[2]] = parts[3]
    return names


def test_names_registered(registered):
    assert [n for n in catalog.EXPERTS if registered.get(n) != "FT_NONE" and n not in OPTIONAL] == []


def test_every_expert_field_known(registered):
    """A new expert field of a dissector must be added to the catalog (or here)."""
    new = sorted(n for n, t in registered.items()
                 if t == "FT_NONE" and n not in catalog.EXPERTS and n not in NOT_FINDINGS)
    assert new == []


def dissector_severity(name):
    """The severity the dissector gives: the catalog's, but for a promoted finding."""
    return catalog.PROMOTED.get(name, catalog.EXPERTS[name][0])


def test_severities_match_the_dissectors(tshark, registered):
    """On frames with exactly one expert info, that one's severity is the catalog's
    (for a promoted candidate: the dissector's note)."""
    names = sorted(n for n in catalog.EXPERTS if n in registered)
    seen = {}
    for cap in sorted(CAPTURES.glob("*.pcap")):
        for row in tshark.fields(cap, ["_ws.expert.severity"] + names, two_pass=True):
            severities = [s for s in row[0].split(",") if s]
            present = [n for n, flag in zip(names, row[1:]) if flag]
            if len(severities) == 1 and len(present) == 1:
                seen.setdefault(present[0], set()).add(SEVERITY[int(severities[0])])
    wrong = {n: s for n, s in seen.items() if s != {dissector_severity(n)}}
    assert wrong == {}
    assert len(seen) >= 40  # most of the catalog is checked by the captures


# --- docs/findings.md "How findings read", the one source ---------------------------

def table_severities():
    """{expert field: severity} of the findings table (docs/findings.md)."""
    return {name: row["severity"] for row in ROWS for proto in TABLE_PROTOCOLS
            for name in row["fields"][proto]}


def test_catalog_is_the_findings_table():
    """Every catalog entry the findings table names has the table's severity; the
    only exception is the promotion of a candidate (a note in the dissector, a
    warning in the report), which must itself be the table's severity."""
    table = table_severities()
    checked = {n: (catalog.EXPERTS[n][0], table[n]) for n in catalog.EXPERTS if n in table}
    assert {n: s for n, s in checked.items() if s[1] != dissector_severity(n)} == {}
    assert len(checked) >= 40
    # the entries whose severity the table fixed in issue 29
    assert {n: catalog.EXPERTS[n][0] for n in (
        "eglink.analysis.vrpi_gap", "eglink.analysis.vrpo_missing", "eclink_modbus.pci_stalled",
        "eclink_pnio.pco_stalled", "eglink.analysis.vrci_unacked", "eglink.analysis.vrci_deadline",
        "eclink_modbus.cmd_from_ru.late", "eclink_modbus.cmd_from_ru.deadline")} == {
        "eglink.analysis.vrpi_gap": "error", "eglink.analysis.vrpo_missing": "error",
        "eclink_modbus.pci_stalled": "error", "eclink_pnio.pco_stalled": "error",
        "eglink.analysis.vrci_unacked": "warning", "eglink.analysis.vrci_deadline": "note",
        "eclink_modbus.cmd_from_ru.late": "warning", "eclink_modbus.cmd_from_ru.deadline": "note"}


def test_promotion_is_only_the_candidates():
    assert set(catalog.PROMOTED) == {"eclink_modbus.candidate", "mcmb2.candidate"}
    for name, severity in catalog.PROMOTED.items():
        assert (catalog.EXPERTS[name][0], severity) == ("warning", "note")
        assert name in catalog.CANDIDATE_SETTINGS


def test_findings_table_against_a_wrong_catalog(monkeypatch):
    """The check above fails on a catalog that drifts from the table."""
    monkeypatch.setitem(catalog.EXPERTS, "eglink.analysis.vrpo_gap", ("warning", "gap", "VRPO"))
    table = table_severities()
    assert table["eglink.analysis.vrpo_gap"] != dissector_severity("eglink.analysis.vrpo_gap")


# --- docs/report.md --------------------------------------------------------------------

DOCS = ROOT / "docs" / "report.md"


def docs_section(begin, end="<!-- END"):
    text = DOCS.read_text()
    start = text.index(begin)
    start = text.index("\n", start) + 1
    return text[start:text.index(end, start)]


def test_docs_severities_are_the_catalog():
    """docs/report.md's severities table is generated from the catalog
    (python3 tools/report/catalog.py prints it)."""
    assert docs_section("<!-- BEGIN severities") == catalog.markdown()


def kinds_table():
    """{kind: severity cell} of docs/report.md's timeline kinds table."""
    text = DOCS.read_text()
    section = text[text.index("## Safety timeline"):]
    out = {}
    for line in section.splitlines()[1:]:
        if line.startswith("## "):
            break
        cells = [c.strip() for c in line.strip("|").split("|")]
        if line.startswith("| `") and len(cells) == 4:
            out[cells[0].strip("`")] = cells[2]
    return out


def test_docs_kinds_have_the_catalog_severities():
    """Each kind's severity in the docs is that of the catalog entries of its role."""
    kinds = kinds_table()
    assert set(kinds) == {"state", "relays", "stall", "gap", "poll_gap", "stopped", "finding"}
    for kind in ("relays", "stall", "gap", "poll_gap"):
        severities = {s for s, role, _ in catalog.EXPERTS.values() if role == kind}
        assert set(re.findall(r"\b(note|warning|error)\b", kinds[kind])) == severities, kind
    assert kinds["state"] == "note"
    # (the report's own: a stream that never came back, the severity of a stall)
    assert kinds["stopped"] == "error"

