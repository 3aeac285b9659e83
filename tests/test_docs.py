"""Documentation hygiene: the reference pages (docs/*.md, linked from the
README) and the registered fields agree, and every name promised in
DECISIONS.md exists."""
import re

import pytest

from conftest import ROOT, SHARED

PROTOCOLS = ("eglink", "eclink", "eclink_modbus", "eclink_pnio", "mcmb2")
# A reference row: the first table cell is a backticked field name.
ROW = re.compile(r"^\|\s*`((?:%s)(?:\.[a-z0-9_]+)+)`\s*\|" % "|".join(PROTOCOLS), re.M)


@pytest.fixture(scope="module")
def registered(tshark):
    """Fields of our protocols, expert fields included (-G fields lists both)."""
    names = set()
    for line in tshark.run(["-G", "fields"], allow_errors=True).stdout.splitlines():
        cols = line.split("\t")
        if cols[0] == "F" and cols[4] in PROTOCOLS:
            names.add(cols[2])
    return names


@pytest.fixture(scope="module")
def preferences(tshark):
    """Preference names of our protocols: their tables use the same row form."""
    out = tshark.run(["-G", "defaultprefs"], allow_errors=True).stdout
    return set(re.findall(r"^#\s*((?:%s)\.[a-z0-9_.]+):" % "|".join(PROTOCOLS), out, re.M))


@pytest.fixture(scope="module")
def documented():
    """Names in the first column of the reference tables (README and docs/)."""
    pages = [ROOT / "README.md"] + sorted((ROOT / "docs").glob("*.md"))
    return set(ROW.findall("\n".join(p.read_text() for p in pages)))


def test_every_field_is_documented(registered, documented):
    """Every field and expert field appears as a row of a reference table."""
    missing = sorted(registered - documented)
    assert not missing, "fields missing from the docs reference: %s" % missing


def test_every_documented_name_exists(registered, preferences, documented):
    """Every field or preference the docs name exists (preference tables share the row form)."""
    unknown = sorted(documented - registered - preferences)
    assert not unknown, "the docs name what tshark does not know: %s" % unknown


def test_contract_names_registered(registered):
    """Every display-filter name DECISIONS.md promises users is registered."""
    decisions = SHARED / "spec" / "DECISIONS.md"
    if not decisions.exists():
        pytest.skip("../shared/spec/DECISIONS.md is not here")
    text = decisions.read_text().split("## Display filter names", 1)[1]
    want = set(re.findall(r"`([a-z0-9_]+\.[a-z0-9_.]+)`", text))
    for stem, a, b in re.findall(r"`([a-z0-9_.]+?)(\d+)`\.\.`[a-z0-9_.]+?(\d+)`", text):
        want |= {"%s%d" % (stem, i) for i in range(int(a), int(b) + 1)}
    # `eclink.bu_state` .. `eclink.encoder_switch`: the status block under eclink
    # carries the same names as under eglink.
    if "`eclink.bu_state` .. `eclink.encoder_switch`" in text:
        status = ["bu_state", "vlaps", "unarmed_rus", "eg_link_status", "ec_link_status",
                  "c_link_status", "armed_ru", "ru_state", "ru_battery", "ru_rssi", "ru_cable",
                  "ru_docked", "ru_disabled"] + ["joystick%d" % i for i in range(1, 5)] + \
                 ["switch%d" % i for i in range(1, 9)] + ["encoder", "encoder_switch"]
        want |= {"eclink." + s for s in status}
    missing = sorted(n for n in want if n.split(".")[0] in PROTOCOLS and n not in registered)
    assert not missing, "DECISIONS.md names not registered: %s" % missing


def test_local_links_resolve():
    """Every relative link and picture of the README and docs/ points to a file
    of the checkout (screenshots are made by tools/screenshots and committed)."""
    broken = []
    for page in [ROOT / "README.md"] + sorted((ROOT / "docs").glob("*.md")):
        for target in re.findall(r"\]\(([^)#\s]+)(?:#[^)]*)?\)", page.read_text()):
            if "://" in target:
                continue
            if not (page.parent / target).exists():
                broken.append("%s -> %s" % (page.relative_to(ROOT), target))
    assert not broken, broken
