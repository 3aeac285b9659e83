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
    """{frame number: the dissector's eglink tree, by field name}."""
    return {int(p["_source"]["layers"]["frame"]["frame.number"]):
            own(p["_source"]["layers"].get("eglink")) for p in tshark.json(path, **kw)}


def differences(one, two, path=""):
    """The field paths (eglink.serial, eglink.payload/eglink.command_id ...) where
    two trees differ, with both values."""
    if isinstance(one, dict) and isinstance(two, dict):
        out = []
        for key in sorted(set(one) | set(two)):
            out += differences(one.get(key), two.get(key), path + "/" + key if path else key)
        return out
    if isinstance(one, list) and isinstance(two, list) and len(one) == len(two):
        return [d for i, (a, b) in enumerate(zip(one, two))
                for d in differences(a, b, "%s[%d]" % (path, i))]
    return [] if one == two else ["%s: %r != %r" % (path, one, two)]


def test_all_captures_listed():
    assert len(NAMES) >= 13


@pytest.mark.parametrize("name", NAMES)
def test_two_pass_identical(tshark, capture_file, name):
    one = dissection(tshark, capture_file(name))
    two = dissection(tshark, capture_file(name), two_pass=True)
    assert any(one.values())
    assert sorted(one) == sorted(two)
    wrong = {f: differences(one[f], two[f]) for f in one if one[f] != two[f]}
    assert not wrong, "one pass and -2 differ (frame: fields): %r" % wrong


def info_lines(text):
    """{frame number: the summary line} of plain tshark output."""
    return {int(line.split()[0]): line for line in text.splitlines()
            if line.strip() and line.split()[0].isdigit()}


@pytest.mark.parametrize("name", NAMES)
def test_tree_and_no_tree_agree(tshark, capture_file, name):
    """Info column without a tree (plain tshark -r) equals the one with -V."""
    plain = info_lines(tshark.run(["-n", "-r", str(capture_file(name))]).stdout)
    with_tree = set(tshark.run(["-n", "-r", str(capture_file(name)), "-P", "-V"]).stdout.splitlines())
    assert plain
    assert {f: line for f, line in plain.items() if line not in with_tree} == {}
