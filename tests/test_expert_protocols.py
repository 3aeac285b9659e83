"""Expert Information names the protocol that found it: in `tshark -z
expert` (and the GUI's Expert Information dialog, which groups the same
way) each finding of ours is listed under the protocol whose expert field
carries it, in the full install and with the Lua plugins alone.

Wireshark files a finding under the protocol that is dissecting when it is
added (pinfo's current protocol), so the PROFINET carrier shows an EC-Link
BU's frames through eclink_pnio's dissector and, without the C plugin, an
MC-MB2-PN base's through mcmb2's (lua/vrshark/pnio_systems.luam through())."""
import json
import os
import re

import pytest

from conftest import CAPTURES

ROW = re.compile(r"^\s+(\d+)\s+(\S+)\s+(\S+)\s+(.*)$")

# capture -> {expert field prefix: protocol}: every finding whose field has
# the prefix is listed under the protocol, and nothing else of ours is listed
# (the first: the capture's own). The EC-Link image's findings (eclink.*,
# the same over both transports) are listed under the transport's EC-Link.
MODBUS = {"eclink_modbus": "ECLINK_MODBUS", "eclink": "ECLINK_MODBUS"}
PNIO = {"eclink_pnio": "ECLINK_PNIO", "eclink": "ECLINK_PNIO"}
# (the Lua EG-Link, without the C plugin, is short-named EGLINK: a Lua
# protocol's short name is its name in capitals, docs/eglink.md)
EGLINK = "EGLINK" if os.environ.get("VRSHARK_NO_C_PLUGIN") else "EG-Link"
CASES = {
    "eglink_analysis_session.pcap": {"eglink": EGLINK},
    "eglink_analysis_vrco_unacked.pcap": {"eglink": EGLINK},
    "eclink_modbus_faults.pcap": MODBUS,
    "crane_eclink_modbus.pcap": MODBUS,
    "eclink_pnio_connect.pcap": PNIO,
    "crane_eclink_pnio.pcap": PNIO,
    "eclink_pnio_noconnect.pcap": dict(PNIO, mcmb2="MCMB2"),
    "mcmb2_duplex_watchdog.pcap": {"mcmb2": "MCMB2"},
    "mcmb2_polled_connect.pcap": {"mcmb2": "MCMB2"},
    "crane_mcmb2.pcap": {"mcmb2": "MCMB2"},
}
OURS = ("EG-Link", "EGLINK", "ECLINK_MODBUS", "ECLINK_PNIO", "MCMB2", "VRSHARK_PNIO", "VRSHARK_MBTCP", "ECLINK")


def expert_rows(tshark, capture, two_pass):
    """[(protocol, summary)] of `tshark -q -z expert`."""
    args = ["-q", "-r", str(CAPTURES / capture), "-z", "expert"] + (["-2"] if two_pass else [])
    return [(m.group(3), m.group(4)) for m in map(ROW.match, tshark.run(args).stdout.splitlines()) if m]


def expert_fields(tshark, capture, two_pass):
    """{message: expert field name} of the capture's findings."""
    args = ["-r", str(CAPTURES / capture), "-T", "json", "--no-duplicate-keys"] + (["-2"] if two_pass else [])
    found = {}

    def walk(node):
        if isinstance(node, dict):
            for k, v in node.items():
                if k == "_ws.expert":
                    # (several findings in one subtree: a list)
                    for ex in v if isinstance(v, list) else [v]:
                        for name in ex:
                            if not name.startswith("_ws.expert."):
                                found[ex.get("_ws.expert.message")] = name
                walk(v)
        elif isinstance(node, list):
            for v in node:
                walk(v)
    walk(json.loads(tshark.run(args).stdout))
    return found


@pytest.mark.parametrize("two_pass", [False, True])
@pytest.mark.parametrize("capture", sorted(CASES))
def test_findings_listed_under_their_protocol(tshark, capture, two_pass):
    rows = expert_rows(tshark, capture, two_pass)
    fields = expert_fields(tshark, capture, two_pass)
    ours = [(proto, text) for proto, text in rows if proto in OURS or any(
        (fields.get(text) or "").startswith(p + ".") for p in CASES[capture])]
    assert ours, "no finding of ours in %s" % capture
    wrong = []
    for proto, text in ours:
        field = fields.get(text)
        want = next((CASES[capture][p] for p in CASES[capture] if field and field.startswith(p + ".")), None)
        if proto != want:
            wrong.append("%s (%s) under %s, not %s" % (text, field, proto, want))
    assert not wrong, "\n".join(wrong)
    # the protocol of the capture's own findings is among them
    assert next(iter(CASES[capture].values())) in {proto for proto, _ in ours}
