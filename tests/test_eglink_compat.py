"""EG-Link C sources: one compat header. Every difference between Wireshark 4.0
and 4.6 is decided in plugins/vrshark/eglink-compat.h; the other files include
it, write the new API names and never compare versions themselves."""
import os
import re

import pytest

from conftest import ROOT

# Source checks of the C plugin: nothing to run again with the Lua plugins alone.
pytestmark = pytest.mark.skipif(bool(os.environ.get("VRSHARK_NO_C_PLUGIN")),
                                reason="reads the C plugin's sources; the Lua EG-Link has none")

PLUGIN = ROOT / "plugins" / "vrshark"
COMPAT = PLUGIN / "eglink-compat.h"
SOURCES = sorted(p for p in PLUGIN.glob("*.[ch]") if p != COMPAT)
C_FILES = [p for p in SOURCES if p.suffix == ".c"]

# A preprocessor condition that looks at the Wireshark version or at the
# results of CMakeLists.txt's API checks.
VERSION_TEST = re.compile(r"^\s*#\s*(?:if|elif|ifdef|ifndef)\b.*"
                          r"(WIRESHARK_VERSION_|VRSHARK_WS_|EGLINK_WS_AT_LEAST)", re.M)
# Names deprecated from 4.4 / 4.6 (-Werror makes them build failures there):
# only eglink-compat.h may name them.
OLD_NAMES = re.compile(r"\b(tvb_get_g(?:u?int(?:8|16|24|32|40|48|56|64))|"
                       r"tvb_(?:find|skip)_guint(?:8|16)|"
                       r"dissector_try_(?:uint|string|payload)_new)\b")
# Compat names the header defines: nobody else defines them again.
COMPAT_NAMES = re.compile(r"^\s*(?:#\s*define\s+|typedef\s+\w+\s+)"
                          r"(EGLINK_WS_AT_LEAST|EGLINK_HAVE_\w+|eglink_\w*bool_t|eglink_get_u\d+|"
                          r"tvb_get_u?int\d+|tvb_find_uint\d+|dissector_try_\w+_with_data)\b", re.M)
# Files allowed to keep a version test of their own (none: every shim is in
# eglink-compat.h).
PENDING = set()


def test_sources_found():
    assert {p.name for p in C_FILES} >= {"packet-eglink.c", "plugin.c", "eglink-analysis.c", "eglink-records.c",
                                          "eglink-channels.c", "eglink-serials.c", "eglink-timing.c",
                                          "eglink-commands.c", "eglink-bursts.c", "eglink-findings.c",
                                          "eglink-stats.c", "vrshark-frontends.c"}


@pytest.mark.parametrize("path", C_FILES, ids=lambda p: p.name)
def test_includes_the_compat_header(path):
    assert re.search(r'^#include "eglink-compat.h"$', path.read_text(), re.M), path.name


def test_no_version_tests_outside_the_header():
    found = {p.name: VERSION_TEST.findall(p.read_text()) for p in SOURCES}
    found = {name: names for name, names in found.items() if names}
    assert set(found) <= PENDING, found


@pytest.mark.parametrize("path", SOURCES, ids=lambda p: p.name)
def test_no_old_api_names(path):
    assert OLD_NAMES.findall(path.read_text()) == []


@pytest.mark.parametrize("path", SOURCES, ids=lambda p: p.name)
def test_no_compat_names_defined_elsewhere(path):
    assert COMPAT_NAMES.findall(path.read_text()) == []


def test_header_defines_what_the_sources_use():
    header = COMPAT.read_text()
    for name in ("EGLINK_WS_AT_LEAST", "EGLINK_HAVE_PLUGIN_DESCRIBE", "eglink_heur_bool_t",
                 "eglink_pref_bool_t", "eglink_ret_bool_t", "tvb_get_uint8",
                 "dissector_try_uint_with_data"):
        assert re.search(r"\b%s\b" % name, header), name
    packet = (PLUGIN / "packet-eglink.c").read_text()
    assert "eglink_heur_bool_t\ndissect_eglink_heur" in packet
    assert "static eglink_pref_bool_t eglink_heuristic" in packet
