"""A simplex MC-MB2-PN base whose controller does not write the downlink
watchdog.

SP-14-023 section 3.2.2: "On simplex systems with no multiple-select
functionality, the IO-Controller does not report any data to the
MC-MB2-PN. Then the MC-MB2-PN may be configured to not monitor the
downlink watchdog counter." Section 2.4: a base that monitors it shows
E010 (uplink status 0xA, section 3.1.1) when it is not updated within its
timeout. So a downlink watchdog that stands on a simplex base is a fault
only where the base monitors it: vrshark says so with a note while the
base reports no E010 (mcmb2.downlink_watchdog.unwritten, naming the
setting), the error where the base reports E010 or once the watchdog has
moved, and follows the preference mcmb2.simplex_downlink (auto, monitored,
unmonitored) or the layout table's simplex+monitored / simplex+unmonitored
for one base.

The traffic is built with scapy's PROFINET layers (tests/pnio_testlib.py),
not by the capture generator: a simplex base (DAP of 4, an 8-byte uplink
module, the downlink its 2-byte header only), an uplink and a downlink
frame every 150 ms, with its Connect and without it (the layout inferred).
"""
import pytest

from conftest import assert_fields
from pnio_testlib import CaptureFile, Device, mac, mcmb2_submodules

IN_FID, OUT_FID = 0x8020, 0x8021
PERIOD = 0.150
CYCLES = 24
STALLED = "mcmb2.downlink_watchdog.stalled"
NOTE = "mcmb2.downlink_watchdog.unwritten"


def simplex_capture(work_dir, name, connect, e010_from=None, down_moves=0):
    """Cycle i: the uplink at i * 150 ms (status Terminal present, terminal
    1, or E010 from cycle e010_from on), the downlink 1 ms later, its
    watchdog counting for the first down_moves cycles, then standing."""
    d = Device(mcmb2_submodules("duplex", 4, 8, 0, 0, 1), mac(0x20), IN_FID, OUT_FID)
    cap = CaptureFile()
    if connect:
        for p in d.connect():
            cap.add(p)
    for i in range(CYCLES):
        e010 = e010_from is not None and i >= e010_from
        status = 0x1A if e010 else 0x11
        data = bytes(8) if e010 else bytes((i + k) % 31 + 1 for k in range(8))
        cap.add(d.cyclic("in", {1: bytes([status, i & 0xFF]), 2: data}), PERIOD - 0.001 if i else 0.001)
        cap.add(d.cyclic("out", {3: bytes([0, min(i, down_moves)])}), 0.001)
    return cap.write(work_dir / ("%s_%s.pcap" % (name, "connect" if connect else "noconnect"))), 2 if connect else 0


def down(base, i):
    """The frame number of cycle i's downlink."""
    return base + 2 * i + 2


def findings(tshark, cap, prefs, two_pass):
    """{frame: [downlink watchdog expert names]}"""
    got = tshark.frames(cap, [STALLED, NOTE], prefs=prefs, two_pass=two_pass,
                        display_filter="%s || %s" % (STALLED, NOTE))
    return {n: [k for k in (STALLED, NOTE) if f[k]] for n, f in got.items()}


PASSES = [pytest.param(False, id="one-pass"), pytest.param(True, id="two-pass")]
# (two passes without the Connect decode from the first frame, as with it)
SOURCES = [pytest.param(True, False, id="connect-one-pass"), pytest.param(True, True, id="connect-two-pass"),
           pytest.param(False, True, id="inferred-two-pass")]


@pytest.mark.parametrize("connect,two_pass", SOURCES)
def test_unwritten_and_no_e010_is_a_note(tshark, work_dir, connect, two_pass):
    """Section 3.2.2: the watchdog stands from the first downlink (0.001 s),
    the base keeps reporting Terminal present: a note at the first downlink
    past 2000 ms (cycle 14, 2.100 s), no error, no tag, no link, no colour."""
    cap, base = simplex_capture(work_dir, "quiet", connect)
    assert findings(tshark, cap, {}, two_pass) == {down(base, 14): [NOTE]}
    got = tshark.frames(cap, ["_ws.expert.message", "_ws.expert.severity", "_ws.expert.group",
                              "mcmb2.watchdog_since", "mcmb2.watchdog_age", "_ws.col.Info"], two_pass=two_pass)
    assert_fields(got[down(base, 14)], {
        "_ws.expert.message": "Simplex downlink watchdog unchanged for 2.100 s (value 0), not seen moving, and the "
                              "base reports no E010: it may not monitor it (SP-14-023 3.2.2). To decide: "
                              "mcmb2.simplex_downlink",
        "_ws.expert.severity": 0x00400000, "_ws.expert.group": 0x02000000,  # note, Sequence
        "mcmb2.watchdog_since": None, "mcmb2.watchdog_age": "2.100000000",
        "_ws.col.Info": "Downlink duplex: base unit 0, watchdog 0"})
    assert not any("[watchdog stalled" in f["_ws.col.Info"] or f["mcmb2.watchdog_since"] for f in got.values())
    # the profile's Safety button and colour rules read these
    assert tshark.frames(cap, [], two_pass=two_pass,
                         display_filter="mcmb2.watchdog_since || mcmb2.downlink_watchdog.stalled") == {}


@pytest.mark.parametrize("connect,two_pass", SOURCES)
def test_preference_decides(tshark, work_dir, connect, two_pass):
    cap, base = simplex_capture(work_dir, "pref", connect)
    # monitored: the error of any downlink, with its tag and link
    assert findings(tshark, cap, {"mcmb2.simplex_downlink": "monitored"}, two_pass) == {down(base, 14): [STALLED]}
    tshark.expect(cap, down(base, 15), {"mcmb2.watchdog_since": down(base, 0),
                                        "_ws.col.Info": "Downlink duplex: base unit 0, watchdog 0 "
                                                        "[watchdog stalled 2.250 s]"},
                  prefs={"mcmb2.simplex_downlink": "monitored"}, two_pass=two_pass)
    # unmonitored: not checked, its age still shown
    assert findings(tshark, cap, {"mcmb2.simplex_downlink": "unmonitored"}, two_pass) == {}
    tshark.expect(cap, down(base, 20), {"mcmb2.watchdog_age": "3.000000000", "mcmb2.watchdog_since": None},
                  prefs={"mcmb2.simplex_downlink": "unmonitored"}, two_pass=two_pass)


@pytest.mark.parametrize("connect,two_pass", SOURCES)
def test_layout_table_option_per_base(tshark, work_dir, connect, two_pass):
    """simplex+unmonitored / simplex+monitored in mcmb2.layouts set it for
    the base of that entry's FrameIDs (whatever decodes its layout), over
    the preference; an entry of other FrameIDs does not."""
    cap, base = simplex_capture(work_dir, "table", connect)
    entry = "0x%04x/0x%04x=simplex+%s:8@4"
    prefs = {"mcmb2.simplex_downlink": "monitored", "mcmb2.layouts": entry % (IN_FID, OUT_FID, "unmonitored")}
    assert findings(tshark, cap, prefs, two_pass) == {}
    prefs = {"mcmb2.layouts": entry % (IN_FID, OUT_FID, "monitored")}
    assert findings(tshark, cap, prefs, two_pass) == {down(base, 14): [STALLED]}
    prefs = {"mcmb2.simplex_downlink": "monitored", "mcmb2.layouts": entry % (0x8030, 0x8031, "unmonitored")}
    assert findings(tshark, cap, prefs, two_pass) == {down(base, 14): [STALLED]}


@pytest.mark.parametrize("connect,two_pass", SOURCES)
def test_base_reporting_e010_monitors_it(tshark, work_dir, connect, two_pass):
    """Section 2.4 / 3.1.1: a base that reports E010 monitors the downlink
    watchdog. In E010 from the start: the error, as on any base. In E010
    only after the note (cycle 15 on): the error on the next downlink,
    once."""
    cap, base = simplex_capture(work_dir, "e010", connect, e010_from=0)
    assert findings(tshark, cap, {}, two_pass) == {down(base, 14): [STALLED]}
    cap, base = simplex_capture(work_dir, "late_e010", connect, e010_from=15)
    assert findings(tshark, cap, {}, two_pass) == {down(base, 14): [NOTE], down(base, 15): [STALLED]}
    tshark.expect(cap, down(base, 15), {
        "_ws.expert.message": "Downlink watchdog unchanged for 2.250 s (value 0): the base shows E010",
        "mcmb2.watchdog_since": down(base, 0)}, two_pass=two_pass)


@pytest.mark.parametrize("connect,two_pass", SOURCES)
def test_watchdog_that_moved_then_stands_is_an_error(tshark, work_dir, connect, two_pass):
    """A controller that wrote the watchdog (cycles 0-4) and stopped: the base
    may monitor it, the error as before (first downlink past 2000 ms after
    cycle 4: cycle 18)."""
    cap, base = simplex_capture(work_dir, "moved", connect, down_moves=4)
    assert findings(tshark, cap, {}, two_pass) == {down(base, 18): [STALLED]}


def test_inferred_one_pass_reads_the_same_kind(tshark, work_dir):
    """Without the Connect, one pass decodes from the frame the layout is
    inferred in: the note (not the error) still, its age counted from there."""
    cap, _ = simplex_capture(work_dir, "quiet1", False)
    got = findings(tshark, cap, {}, False)
    assert [v for v in got.values()] == [[NOTE]]
    assert tshark.frames(cap, [], display_filter="mcmb2.layout.inferred")


def test_bad_table_option_is_said(tshark, work_dir):
    """An option on another system, or an unknown one, makes the entry
    malformed: skipped, as any malformed entry (docs/profinet.md)."""
    cap, base = simplex_capture(work_dir, "badopt", False)
    for entry in ("0x%04x/0x%04x=duplex+unmonitored:8/2@4", "0x%04x/0x%04x=simplex+sometimes:8@4"):
        got = tshark.frames(cap, ["mcmb2.layout"], prefs={"mcmb2.layouts": entry % (IN_FID, OUT_FID)},
                            two_pass=True)
        assert "preference" not in got[down(base, 3)]["mcmb2.layout"]
