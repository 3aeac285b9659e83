"""The sparse display of the Lua plugins alone in each pass of tshark
(lua/vrshark/frontends.luam, lua_view()).

In tshark every frame of a pass is dissected once, primed by the same
filter, fields and taps, so the Lua decoders work out what is referenced on
the first frame of a pass and keep it for the pass. With -2 the passes are
primed differently: -R in the first, -Y in the second. A view kept from
the first pass would leave out the fields the second pass's filter asks
for, and -Y would select other frames than with the full tree. Under
another program name (Wireshark, sharkd: what is referenced changes from
one dissection to the next) the view is worked out on every frame.
"""
import re

import pytest

from conftest import CAPTURES
from test_sparse_view import LUA_ONLY, _run

# (capture, a field of ours for one pass, a filter on another for the
# other pass, the frames that filter selects in one pass and in two: two
# passes show a Modbus connection's ADUs from before it was recognised)
CASES = [
    ("mcmb2_duplex_connect.pcap", "mcmb2.slot.status", "mcmb2.status == 1", (3, 3)),
    ("eclink_pnio_connect.pcap", "eclink.pci", "eclink.bu_state == 0x11", (38, 38)),
    ("eclink_modbus_basic.pcap", "eclink.pci", "eclink.bu_state == 0x11", (8, 10)),
    ("eglink_analysis_spec_rules.pcap", "eglink.serial", "eglink.bu_state == 0x11", (66, 66)),
]
# A read filter every frame passes (the frames keep their numbers), whether
# or not it names a field of ours.
EVERY = "frame.number > 0"


def _frames(out):
    """The packet lines of tshark's output (not those of -z expert)."""
    return [line for line in out.splitlines() if re.match(r"\s*\d+\s+\d+\.\d+ ", line)]


@pytest.mark.parametrize("name, first, second, count", CASES)
@pytest.mark.parametrize("order", ["ours in both", "ours in the second only"])
def test_each_pass_has_the_view_of_its_own_filter(tshark, name, first, second, count, order):
    """tshark -2 -R A -Y B, A priming a field of ours in the first pass and
    passing every frame: the frames, Info and expert statistics of the full
    tree, and as many frames as -2 -Y B."""
    read = first + " || " + EVERY if order == "ours in both" else EVERY
    args = ["-n", "-2", "-r", str(CAPTURES / name), "-R", read, "-Y", second, "-z", "expert"]
    sparse = _run(tshark, args, extra_env=LUA_ONLY)
    assert sparse == _run(tshark, args, full=True, extra_env=LUA_ONLY)
    assert len(_frames(sparse)) == count[1]


@pytest.mark.parametrize("name, first, second, count", CASES)
def test_a_column_of_the_second_pass_only(tshark, name, first, second, count):
    """The first pass primes field A (-R, and -Y: tshark primes its first
    pass with both), a custom column of field B only the second: B's column
    is that of the full tree. (A view kept from the first pass would leave
    it empty.)"""
    field = second.split()[0]
    cols = '"No.","%m","Info","%i","B","%Cus:{}:0:R"'.format(field)
    args = ["-n", "-2", "-r", str(CAPTURES / name), "-R", first + " || " + EVERY,
            "-o", "gui.column.format:" + cols]
    sparse = _run(tshark, args, extra_env=LUA_ONLY)
    assert sparse == _run(tshark, args, full=True, extra_env=LUA_ONLY)
    plain = _run(tshark, ["-n", "-2", "-r", str(CAPTURES / name), "-Y", field, "-o", "gui.column.format:" + cols],
                 extra_env=LUA_ONLY)
    rows = [line for line in plain.splitlines() if line.strip()]
    assert len(rows) >= count[1]
    assert set(rows) <= set(sparse.splitlines())


@pytest.mark.parametrize("name, first, second, count", CASES)
def test_under_another_program_name_the_view_is_that_of_each_frame(keeping_tshark, name, first, second, count):
    """The same filters run by a program that is not tshark (the view is
    worked out on every frame): the frames of the full tree, in one pass
    and two."""
    for passes, extra in enumerate(([], ["-2", "-R", first + " || " + EVERY])):
        args = ["-n", "-r", str(CAPTURES / name), "-Y", second] + extra
        sparse = _run(keeping_tshark, args, extra_env=LUA_ONLY)
        assert sparse == _run(keeping_tshark, args, full=True, extra_env=LUA_ONLY)
        assert len(_frames(sparse)) == count[passes], (name, extra)
