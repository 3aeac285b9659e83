"""The watchdog timeout preferences of MC-MB2-PN: mcmb2.uplink_timeout and
mcmb2.downlink_timeout move the stall finding, its Info tag and its link
to the first frame past the limit set, in one pass and with -2.

SP-14-023 section 3.1.2: the IO controller brings the system to a safe
state when the uplink watchdog has not been updated for 1 second (the
default 1000 ms); section 2.4: the base flags E010 when the downlink
watchdog is not updated "within a timeout (default 2000ms)", a timeout the
base can be set to, so the preference follows it.

mcmb2_duplex_watchdog.pcap (a simplex base, from its Connect): an uplink
and a downlink frame every 200 ms from 0.2 s; the uplink watchdog keeps 5
from frame 11 (1.0 s) to frame 25 (2.4 s), the downlink watchdog keeps 5
from frame 12 (1.001 s) to frame 36 (3.401 s).
"""
import pytest

CAP = "mcmb2_duplex_watchdog.pcap"
UP = "Uplink watchdog unchanged for %s (value 5): bring the system to a safe state"
DOWN = "Downlink watchdog unchanged for %s (value 5): the base shows E010"
PASSES = [pytest.param(False, id="one-pass"), pytest.param(True, id="two-pass")]


def stalls(tshark, cap, prefs, two_pass):
    """{frame: [watchdog stall messages]}"""
    ex = tshark.experts(cap, prefs=prefs, two_pass=two_pass)
    return {n: [m for m in ms if "watchdog unchanged" in m] for n, ms in ex.items()
            if any("watchdog unchanged" in m for m in ms)}


@pytest.mark.parametrize("two_pass", PASSES)
@pytest.mark.parametrize("prefs,want", [
    # the defaults of section 3.1.2 (1 s) and 2.4 (2000 ms), given or not
    ({}, {23: [UP % "1.200 s"], 34: [DOWN % "2.200 s"]}),
    ({"mcmb2.uplink_timeout": 1000, "mcmb2.downlink_timeout": 2000}, {23: [UP % "1.200 s"], 34: [DOWN % "2.200 s"]}),
    # a longer uplink limit: the first uplink frame past it, or none within the 1.4 s stall
    ({"mcmb2.uplink_timeout": 1300}, {25: [UP % "1.400 s"], 34: [DOWN % "2.200 s"]}),
    ({"mcmb2.uplink_timeout": 1500}, {34: [DOWN % "2.200 s"]}),
    # a shorter one: sooner
    ({"mcmb2.uplink_timeout": 500}, {17: [UP % "0.600 s"], 34: [DOWN % "2.200 s"]}),
    # the downlink limit as the base is set: 2300 ms, 3000 ms (the 2.4 s stall is within it)
    ({"mcmb2.downlink_timeout": 2300}, {23: [UP % "1.200 s"], 36: [DOWN % "2.400 s"]}),
    ({"mcmb2.downlink_timeout": 3000}, {23: [UP % "1.200 s"]}),
    ({"mcmb2.downlink_timeout": 1500}, {23: [UP % "1.200 s"], 28: [DOWN % "1.600 s"]}),
])
def test_timeouts_move_the_stall(tshark, capture_file, prefs, want, two_pass):
    assert stalls(tshark, capture_file(CAP), prefs, two_pass) == want


@pytest.mark.parametrize("two_pass", PASSES)
def test_tag_link_and_colour_fields_follow_the_limit(tshark, capture_file, two_pass):
    """Every frame past the limit carries the tag and the link to the frame
    the value dates from (mcmb2.watchdog_since, which the profile's colour
    rule and Safety button read); frames within it do not."""
    cap = capture_file(CAP)
    got = tshark.frames(cap, ["mcmb2.watchdog_since", "mcmb2.watchdog_age", "_ws.col.Info"],
                        prefs={"mcmb2.uplink_timeout": 1300, "mcmb2.downlink_timeout": 2300}, two_pass=two_pass)
    tagged = sorted(n for n, f in got.items() if "[watchdog stalled" in f["_ws.col.Info"])
    assert tagged == [25, 36]
    assert sorted(n for n, f in got.items() if f["mcmb2.watchdog_since"]) == [25, 36]
    assert got[25]["mcmb2.watchdog_since"] == "11" and got[36]["mcmb2.watchdog_since"] == "12"
    assert got[25]["_ws.col.Info"].endswith("watchdog 5 [watchdog stalled 1.400 s]")
    assert got[23]["_ws.col.Info"] == "Uplink duplex: Terminal present, terminal 1, watchdog 5"
    assert got[23]["mcmb2.watchdog_age"] == "1.200000000"  # the age is shown whatever the limit
    safety = "mcmb2.watchdog_since"
    assert sorted(tshark.frames(cap, [], display_filter=safety, two_pass=two_pass,
                                prefs={"mcmb2.uplink_timeout": 1300, "mcmb2.downlink_timeout": 2300})) == [25, 36]

