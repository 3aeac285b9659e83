"""The report's expert catalog (tools/report/catalog.py) against the plugins:
every name is registered, every expert field of our protocols is either in it
or known to be chat-level, and its severities are those the dissectors raise."""
import sys

import pytest

from conftest import CAPTURES, ROOT

sys.path.insert(0, str(ROOT / "tools"))
from report import catalog  # noqa: E402

PROTOCOLS = ("eglink", "eclink", "eclink_modbus", "eclink_pnio", "mcmb2")
# FT_NONE fields of our protocols the report does not ask for: subtree labels
# and chat-level experts (commands acknowledged, layouts learned, partial access).
NOT_FINDINGS = {
    "eglink.payload", "eglink.analysis", "eglink.fragments", "eclink.partial",
    "eglink.analysis.command", "eglink.analysis.ack", "eglink.analysis.unknown_ack",
    "eclink_modbus.cmd_from_ru", "eclink_modbus.cmd_from_ru.ack", "eclink_modbus.cmd_to_ru",
    "eclink_modbus.cmd_to_ru.ack", "eclink_modbus.periodic.reassembled",
    "eclink_pnio.cmd_from_ru", "eclink_pnio.cmd_from_ru.ack", "eclink_pnio.cmd_to_ru",
    "eclink_pnio.cmd_to_ru.ack", "eclink_pnio.layout.learned", "mcmb2.layout.learned",
    # on the command's own frame, second pass only: the report (one pass) reads
    # the deadline notes that stand for them (COMMAND_FAILED)
    "eglink.analysis.vrci_unacked", "eglink.analysis.vrco_unacked",
    "eclink_modbus.cmd_from_ru.late", "eclink_modbus.cmd_to_ru.late",
    "eclink_pnio.cmd_from_ru.late", "eclink_pnio.cmd_to_ru.late",
    # not a finding of the traffic but of its recognition; one pass (as the
    # report reads) also notes the frames of a BU recognised later
    "eclink_modbus.candidate",
}
# The note at a command's deadline stands in the report for the command's
# failure: the report rates it as the dissector rates the command's warning.
COMMAND_FAILED = {
    "eglink.analysis.vrci_deadline": "eglink.analysis.vrci_unacked",
    "eglink.analysis.vrco_deadline": "eglink.analysis.vrco_unacked",
    "eclink_modbus.cmd_from_ru.deadline": "eclink_modbus.cmd_from_ru.late",
    "eclink_modbus.cmd_to_ru.deadline": "eclink_modbus.cmd_to_ru.late",
    "eclink_pnio.cmd_from_ru.deadline": "eclink_pnio.cmd_from_ru.late",
    "eclink_pnio.cmd_to_ru.deadline": "eclink_pnio.cmd_to_ru.late",
}
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
    assert [n for n in catalog.EXPERTS if registered.get(n) != "FT_NONE"] == []


def test_every_expert_field_known(registered):
    """A new expert field of a dissector must be added to the catalog (or here)."""
    new = sorted(n for n, t in registered.items()
                 if t == "FT_NONE" and n not in catalog.EXPERTS and n not in NOT_FINDINGS)
    assert new == []


def test_severities_match_the_dissectors(tshark):
    """On frames with exactly one expert info, that one's severity is the catalog's
    (for a deadline note: the one of the command's warning it stands for)."""
    names = sorted(set(catalog.EXPERTS) - set(COMMAND_FAILED)) + sorted(COMMAND_FAILED.values())
    seen = {}
    for cap in sorted(CAPTURES.glob("*.pcap")):
        for row in tshark.fields(cap, ["_ws.expert.severity"] + names, two_pass=True):
            severities = [s for s in row[0].split(",") if s]
            present = [n for n, flag in zip(names, row[1:]) if flag]
            if len(severities) == 1 and len(present) == 1:
                seen.setdefault(present[0], set()).add(SEVERITY[int(severities[0])])
    rated = dict((n, catalog.EXPERTS[n][0]) for n in catalog.EXPERTS)
    rated.update((warning, catalog.EXPERTS[note][0]) for note, warning in COMMAND_FAILED.items())
    wrong = {n: s for n, s in seen.items() if s != {rated[n]}}
    assert wrong == {}
    assert len(seen) >= 40  # most of the catalog is checked by the captures
