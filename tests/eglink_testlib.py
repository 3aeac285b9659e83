"""Helpers for the EG-Link dissector tests: its own expert names, and expert info
read from -T json so that findings of other EG-Link modules do not get in the way."""
import sys

from conftest import ROOT

if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from tools.capgen import eglink as gen  # noqa: E402  (the capture generator)

# Every expert field packet-eglink.c registers.
DISSECTOR_EXPERTS = {
    "eglink.too_short", "eglink.size.mismatch", "eglink.size.invalid", "eglink.type.unknown",
    "eglink.revision.unknown", "eglink.origin.nonzero", "eglink.origin.zero",
    "eglink.spare.nonzero", "eglink.payload_spare.nonzero", "eglink.crc.bad",
    "eglink.crc.variant", "eglink.bu_state.relays_open", "eglink.bu_state.unknown",
    "eglink.link_status.unknown", "eglink.vlaps.range", "eglink.ru_state.stopped",
    "eglink.ru_state.unknown", "eglink.ru_battery.range", "eglink.ru_rssi.range",
    "eglink.flag.invalid", "eglink.ru_disabled.unknown", "eglink.joystick.range",
    "eglink.armed_ru.unarmed_data",
}


def _walk(node, found):
    if isinstance(node, list):
        for item in node:
            _walk(item, found)
    elif isinstance(node, dict):
        if "_ws.expert.message" in node:
            names = [k for k in node if k in DISSECTOR_EXPERTS]
            if names:
                found.append((names[0], node["_ws.expert.message"]))
        for value in node.values():
            _walk(value, found)


def dissector_experts(tshark, capture, **kw):
    """{frame number: [(expert name, message), ...]} of the dissector's own expert info."""
    out = {}
    for pkt in tshark.json(capture, **kw):
        layers = pkt["_source"]["layers"]
        found = []
        _walk(layers.get("eglink", {}), found)
        if found:
            out[int(layers["frame"]["frame.number"])] = found
    return out


def messages(tshark, capture, **kw):
    """{frame number: [message, ...]} of the dissector's own expert info."""
    return {n: [m for _, m in v] for n, v in dissector_experts(tshark, capture, **kw).items()}
