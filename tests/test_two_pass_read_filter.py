"""tshark -2 -R: the read filter applied on the first pass selects the frames
a one-pass -Y selects, with the C plugin and with the Lua plugins alone.

On that first pass tshark keeps only the frames that pass the read filter and
numbers each frame one more than the count kept so far: a dropped frame gives
its number to the next one (lua/vrshark/passes.luam). The decoders keep their
first-pass records by frame number; a frame with a dropped frame's number
works out its own (docs/quality.md, "tshark -2 -R"). The selected frames are
compared by time (-R renumbers them), their Info with the same frames of a
plain -2 -Y (or of one pass where the second pass changes nothing)."""
import pytest

F = ["frame.time_relative", "_ws.col.Info"]

# (capture, -R filter, -Y filter or None, frames selected, Info as in: "one" or "two" passes)
CASES = [
    ("eclink_modbus_basic.pcap", "eclink.pci", None, 10, "one"),
    ("eclink_modbus_basic.pcap", "eclink_modbus", "eclink.pci >= 15", 8, "one"),
    ("eclink_modbus_commands.pcap", "eclink.pci", None, 22, "one"),
    ("eclink_modbus_faults.pcap", "eclink.pci", None, 8, "two"),
    ("eclink_modbus_late_accept.pcap", "eclink", None, 4, "one"),
    ("eglink_analysis_lost.pcap", "eglink.analysis.lost", None, 2, "one"),
    ("eglink_analysis_session.pcap", "eglink.analysis.time_since_prev_vrpi > 0.015", None, 22, "one"),
    ("eglink_analysis_session.pcap", "eglink.analysis.time_since_prev_vrpi > 0.015", "eglink.analysis.lost", 1,
     "one"),
    ("eglink_analysis_repeated.pcap", "eglink.analysis.repeat_of", None, 1, "one"),
    ("eglink_analysis_vrci_retransmission.pcap", "eglink.analysis.retransmission_of", None, 2, "one"),
    ("mcmb2_duplex_midsession.pcap", "mcmb2.status", None, 23, "one"),
    ("mcmb2_duplex_midsession.pcap", "mcmb2.layout.inferred", None, 1, "one"),
    ("mcmb2_duplex_midsession.pcap", "mcmb2", "mcmb2.watchdog_age", 46, "one"),
    ("mcmb2_duplex_reopen_noconnect.pcap", "mcmb2.status", None, 2, "one"),
    ("mcmb2_duplex_reopen_noconnect.pcap", "mcmb2.layout.inferred", None, 2, "one"),
    ("eclink_pnio_noconnect.pcap", "eclink.pci", None, 1, "one"),
]


@pytest.fixture(params=["c", "lua"])
def modes(request, tshark):
    if request.param == "lua":
        tshark.env = dict(tshark.env, VRSHARK_NO_C_PLUGIN="1")
        tshark._cache = {}
    yield request.param
    tshark.env.pop("VRSHARK_NO_C_PLUGIN", None)
    tshark._cache = {}


@pytest.mark.parametrize("cap,rfilter,yfilter,count,ref", CASES)
def test_read_filter_selects_as_display_filter(tshark, capture_file, modes, cap, rfilter, yfilter, count, ref):
    path = capture_file(cap)
    both = rfilter if yfilter is None else "(%s) && (%s)" % (rfilter, yfilter)
    one = tshark.fields(path, F, display_filter=both)
    extra = ["-R", rfilter]
    got = tshark.fields(path, F, two_pass=True, display_filter=yfilter, extra=extra)
    assert len(one) == count
    assert [r[0] for r in got] == [r[0] for r in one]
    if ref == "one":
        assert got == one
    else:
        two = tshark.fields(path, F, two_pass=True, display_filter=both)
        assert all(r in two for r in got)


def test_repeated_numbers_on_the_first_pass(tshark, capture_file):
    """What the fix rests on: tshark -2 -R numbers a first-pass frame one more
    than the frames kept so far (frame.number == 5 never matches)."""
    path = capture_file("eclink_modbus_basic.pcap")
    assert tshark.fields(path, ["frame.number"], two_pass=True, extra=["-R", "frame.number == 5"]) == []
    assert len(tshark.fields(path, ["frame.number"], two_pass=True, extra=["-R", "frame.number <= 5"])) == 5


@pytest.mark.parametrize("words,want", [
    (["tshark", "-2", "-R", "eclink", "-r", "x"], True),
    (["tshark", "-2R", "eclink"], True),
    (["tshark", "-n2", "-Reclink"], True),
    (["tshark", "-R", "eclink"], False),
    (["tshark", "-2", "-Y", "-R"], False),
    (["wireshark", "-2", "-R", "x"], False),
])
def test_renumbers_args(lua_probe, words, want):
    """passes.renumbers_args reads the command line as tshark's getopt() does."""
    script = """package.path = %(lua)r .. "/?.luam;" .. package.path
local passes = require("vrshark.passes")
local f = io.open(%(out)r, "w")
f:write(tostring(passes.renumbers_args({""" + ", ".join('"%s"' % w for w in words) + """})))
f:close()
"""
    assert lua_probe(script) == [str(want).lower()]
