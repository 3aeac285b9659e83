"""EG-Link: a second pass (tshark -2) shows exactly what one pass shows for every
field and expert info of the packet dissector, for every EG-Link capture.

Links to later frames of the conversation analysis (acknowledged in, reassembled
in) can only appear once the whole capture has been read; they are left out here
and covered by the analysis tests."""
import pytest

from conftest import CAPTURES
from eglink_testlib import DISSECTOR_EXPERTS

NAMES = sorted(p.name for p in CAPTURES.glob("eglink_*.pcap"))
ANALYSIS_PREFIXES = ("eglink.analysis", "eglink.fragment", "eglink.reassembled")


def own(node):
    """The dissector's part of a -T json tree: without the analysis subtrees."""
    if isinstance(node, list):
        kept = [own(n) for n in node]
        return [n for n in kept if n is not None]
    if not isinstance(node, dict):
        return node
    if "_ws.expert.message" in node and not DISSECTOR_EXPERTS.intersection(node):
        return None
    out = {}
    for key, value in node.items():
        if key.startswith(ANALYSIS_PREFIXES):
            continue
        value = own(value)
        if value is not None and value != [] and value != {}:
            out[key] = value
    return out


def dissection(tshark, path, **kw):
    return [(p["_source"]["layers"]["frame"]["frame.number"], own(p["_source"]["layers"].get("eglink")))
            for p in tshark.json(path, **kw)]


def test_all_captures_listed():
    assert len(NAMES) >= 13


@pytest.mark.parametrize("name", NAMES)
def test_two_pass_identical(tshark, capture_file, name):
    one = dissection(tshark, capture_file(name))
    two = dissection(tshark, capture_file(name), two_pass=True)
    assert any(layer for _, layer in one)
    assert one == two


@pytest.mark.parametrize("name", NAMES)
def test_tree_and_no_tree_agree(tshark, capture_file, name):
    """Info column without a tree (plain tshark -r) equals the one with -V."""
    plain = tshark.run(["-n", "-r", str(capture_file(name))]).stdout.splitlines()
    with_tree = tshark.run(["-n", "-r", str(capture_file(name)), "-P", "-V"]).stdout
    for line in plain:
        assert line in with_tree
